"""`actaim2 validate`'s action figures decode each predictor as it serves: a single-view one
through its view's heatmap and depth cells, a five-view one through all five views. Its outcome
figures tell keyposes that follow eps's outcome from keyposes placed by the scene alone, and fed
another outcome's eps, a predictor that reads eps from one that ignores it."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from actaim2.artifact.checkpoint import perception_record
from actaim2.data.storage import trajectory_outcome
from actaim2.data.trajectory import PHASES
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import Trainer
from actaim2.train.validation import (
    DRAWN_FOLLOWING_PHASES,
    EMBEDDINGS,
    action_figures,
    drawn_following,
    label_mode_ssr,
    mode_chain_figures,
    outcome_figures,
    outcome_rates,
    placement_rows,
    predict_keyframes,
    swap_rates,
    swapped_following,
)
from synthetic import PLACEMENT, make_dataset
from test_stop_gradient import TINY


@pytest.mark.parametrize("view", ["all", "back"])
def test_action_figures_of_five_view_and_single_view_predictors(tmp_path, view):
    data, _ = make_dataset(4, resolution=32, seed=5)
    config = dataclasses.replace(TINY, predictor={**TINY.predictor, "view": view})
    trainer = Trainer(config, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", tmp_path,
                      init_distributed("cpu"), show_progress=False)
    assert (trainer.predictor.config.view_index is None) == (view == "all")
    figures = action_figures(predict_keyframes(trainer.selector, trainer.predictor, data, PLACEMENT, torch.device("cpu")))
    assert set(figures) == set(EMBEDDINGS)
    for by_phase in figures.values():
        f = by_phase["all"]
        assert f.keyframes == len(data.keyframes()) == sum(by_phase[p].keyframes for p in by_phase if p != "all")
        assert 0.0 <= f.translation_median_mm <= f.translation_p90_mm < 2000.0 * PLACEMENT.half_extent
        assert 0.0 <= f.rotation_median_deg <= f.rotation_p90_deg <= 180.0


def _follow_case() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One object, six trajectories with REACH keyframes only: outcomes "0+" x4 (reach at x = 0) and
    "0-" x2 (reach at x = 1); a second object with one outcome only (never counted)."""
    frames = np.array([[t, 1] for t in range(8)])
    target = np.zeros((8, 3))
    target[[4, 5], 0] = 1.0
    objects = np.array(["a"] * 6 + ["b"] * 2)
    outcomes = np.array(["0+"] * 4 + ["0-"] * 2 + ["0+"] * 2)
    return frames, target, objects, outcomes


def test_outcome_rates_reward_points_that_follow_the_outcome_and_not_the_majority():
    frames, target, objects, outcomes = _follow_case()
    following = outcome_rates(target + 0.1, target, frames, objects, outcomes)["reach"]
    assert following.keyframes == 6  # object b shows one outcome: left out
    assert following.nearest_demo_same_outcome == 1.0 == following.demonstrated_point
    assert following.majority_outcome == pytest.approx(4 / 6)  # the others' majority is "0+" for every trajectory
    scene_only = outcome_rates(np.zeros((8, 3)), target, frames, objects, outcomes)["reach"]  # always the majority's place
    assert scene_only.nearest_demo_same_outcome == pytest.approx(4 / 6) == scene_only.majority_outcome
    assert scene_only.demonstrated_point == 1.0  # the demonstrations themselves tell the outcomes apart
    assert set(outcome_rates(target, target, frames, objects, outcomes)) == {"reach"}


def test_trajectory_outcome_is_the_dof_that_moved_most_and_its_direction():
    assert trajectory_outcome([0.1, -0.5, 0.3]) == "1-" and trajectory_outcome([0.4]) == "0+"


def test_outcome_figures_run_the_predictor_on_every_keyframe(tmp_path):
    data, _ = make_dataset(4, resolution=32, seed=5)
    trainer = Trainer(TINY, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", tmp_path,
                      init_distributed("cpu"), show_progress=False)
    objects, outcomes = ["o"] * len(data), ["0+", "0-"] * (len(data) // 2)
    predictions = predict_keyframes(trainer.selector, trainer.predictor, data, PLACEMENT, torch.device("cpu"))
    figures = outcome_figures(predictions, objects, outcomes)
    per_phase = np.bincount(data.keyframes()[:, 1], minlength=4)
    assert {name: f.keyframes for name, f in figures.items()} == {n: int(c) for n, c in zip(PHASES, per_phase) if c}
    assert all(0.0 <= f.nearest_demo_same_outcome <= 1.0 for f in figures.values())


@pytest.mark.parametrize("kind", ["cgmvae", "cvae"])
def test_mode_chain_finds_the_mode_in_eps_and_tests_clusters_where_there_are_some(tmp_path, kind):
    data, modes = make_dataset(24, resolution=32, seed=7)  # z carries each trajectory's mode (synthetic.py)
    config = dataclasses.replace(TINY, selector=dataclasses.replace(TINY.selector, kind=kind))
    trainer = Trainer(config, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", tmp_path,
                      init_distributed("cpu"), show_progress=False)
    objects = ["a"] * 12 + ["b"] * 12
    outcomes = ["0+" if m else "0-" for m in modes]
    chain = mode_chain_figures(trainer.selector, data, objects, outcomes, torch.device("cpu"), draws=2)
    assert chain.trajectories == 24
    assert chain.eps_nearest_same_outcome > 0.9 > chain.majority_outcome
    if kind == "cvae":
        assert chain.clusters is None and chain.second_mode_ceiling is None
    else:
        assert (chain.clusters.objects, chain.clusters.samples) == (2, 2 * 2 * trainer.selector.config.clusters)
        assert 0.0 < chain.clusters.p_value <= 1.0
        # The 2nd mode of each object is measured on one group's half B: 1 of 2 draws, 2 objects.
        for rate in (chain.second_mode_ceiling, chain.second_mode_shuffled):
            assert rate.trials == 2 and 0 <= rate.successes <= 2
        assert chain.true_spread > 0.0 and chain.drawn_spread > 0.0
    one_outcome = mode_chain_figures(trainer.selector, data, objects, ["0+"] * 24, torch.device("cpu"))
    assert one_outcome.trajectories == 0 and one_outcome.clusters is None


def test_a_clusters_draws_are_made_on_the_objects_placements_in_turn():
    assert placement_rows(5, 4).tolist() == [0, 1, 2, 3]  # four resets, as four evaluation samples
    assert placement_rows(3, 4).tolist() == [0, 1, 2, 0]  # fewer trajectories: round again


def test_label_mode_ssr_chooses_each_modes_cluster_on_half_a_and_scores_half_b():
    # Cluster 0 draws "0-" four times; cluster 1 draws "0+" at repetitions 0, 1, 2 and "1-" at 3.
    first, second = label_mode_ssr([0] * 4 + [1] * 4, ["0-"] * 4 + ["0+"] * 3 + ["1-"], draws=4, obj="o")
    assert (first.mode, first.group, first.rate.successes, first.rate.trials) == (("0", -1), 0, 2, 2)
    assert (second.mode, second.group, second.rate.successes, second.rate.trials) == (("0", 1), 1, 1, 2)


@pytest.mark.parametrize("kind", ["cgmvae", "cvae"])
def test_drawn_following_feeds_each_keyframe_one_draw_per_cluster(tmp_path, kind):
    data, modes = make_dataset(24, resolution=32, seed=7)
    config = dataclasses.replace(TINY, selector=dataclasses.replace(TINY.selector, kind=kind))
    trainer = Trainer(config, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", tmp_path,
                      init_distributed("cpu"), show_progress=False)
    objects, outcomes = ["o"] * len(data), ["0+" if m else "0-" for m in modes]
    predictions = predict_keyframes(trainer.selector, trainer.predictor, data, PLACEMENT, torch.device("cpu"))
    drawn = drawn_following(trainer.selector, trainer.predictor, data, PLACEMENT, predictions, objects, outcomes,
                            torch.device("cpu"))
    if kind == "cvae":  # no clusters to draw from
        assert drawn == {}
        return
    phases = predictions.frames[:, 1]
    assert set(drawn) <= set(DRAWN_FOLLOWING_PHASES) and drawn
    for name, f in drawn.items():
        assert f.keyframes == int((phases == PHASES.index(name)).sum())
        assert 0.0 <= f.follows_named_outcome <= 1.0 and 0.0 <= f.shuffled <= 1.0
        assert 1.0 <= f.distinct_outcomes <= 2.0  # two outcomes in the data


def test_swap_rates_count_a_point_that_moves_to_the_partners_outcome():
    frames, target, objects, outcomes = _follow_case()
    partner = np.array([4, 4, 5, 5, 0, 1, -1, -1])  # object b has no partner: not scored
    swapped = target[partner]  # each point lands on its partner's demonstration
    reads = swap_rates(target, swapped, target, frames, objects, outcomes, partner)["reach"]
    assert reads.keyframes == 6 and reads.moved_median_mm == pytest.approx(1000.0)
    assert (reads.own_outcome_own_eps, reads.own_outcome_swapped) == (1.0, 0.0)
    assert (reads.partner_outcome_own_eps, reads.partner_outcome_swapped) == (0.0, 1.0)
    ignores = swap_rates(target, target, target, frames, objects, outcomes, partner)["reach"]  # the point stays
    assert ignores.moved_median_mm == 0.0 and ignores.partner_outcome_swapped == ignores.partner_outcome_own_eps == 0.0
    assert swap_rates(target, swapped, target, frames, objects, outcomes, np.full(8, -1)) == {}


@pytest.mark.parametrize("blind", [False, True])
def test_swapped_following_feeds_a_partners_eps_and_a_blind_predictor_does_not_move(tmp_path, blind):
    data, modes = make_dataset(24, resolution=32, seed=7)
    trainer = Trainer(TINY, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", tmp_path,
                      init_distributed("cpu"), show_progress=False)
    if blind:  # eps no longer reaches the tokens: the same point whatever eps is fed
        with torch.no_grad():
            trainer.predictor.condition[0].weight[:, :trainer.predictor.config.embedding_dim] = 0.0
    objects, outcomes = ["o"] * len(data), ["0+" if m else "0-" for m in modes]
    predictions = predict_keyframes(trainer.selector, trainer.predictor, data, PLACEMENT, torch.device("cpu"))
    swapped = swapped_following(trainer.selector, trainer.predictor, data, PLACEMENT, predictions, objects, outcomes,
                                torch.device("cpu"))
    phases = predictions.frames[:, 1]
    assert set(swapped) == {name for name in DRAWN_FOLLOWING_PHASES if (phases == PHASES.index(name)).any()}
    for name, f in swapped.items():
        assert f.keyframes == int((phases == PHASES.index(name)).sum())
        if blind:
            assert f.moved_median_mm == 0.0
            assert (f.partner_outcome_swapped, f.own_outcome_swapped) == (f.partner_outcome_own_eps, f.own_outcome_own_eps)
        else:  # an untrained predictor reads eps a little: its point moves
            assert f.moved_median_mm > 0.0
