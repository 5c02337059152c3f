"""Served, neighbour and nearest-centre eps (train/served_eps.py): every draw of the selector lands in
the pool of its object's trajectory whose true eps lies nearest, only the predictor's trajectories take
draws, a neighbour pool holds the trajectory's own true eps and its nearest same-object ones, a
nearest-centre pool holds the cluster centre of the trajectory's own O_init nearest its true eps, and a
pooled predictor phase feeds a keyframe an eps of its trajectory's pool (its true eps plus noise where
the pool is empty) in training batches only."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from actaim2.artifact.checkpoint import perception_record
from actaim2.data.storage import object_of
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import Trainer
from actaim2.train.served_eps import (
    nearest_centre_pools,
    neighbour_eps_pools,
    pick_from_pools,
    served_eps_pools,
)
from synthetic import PLACEMENT, make_dataset
from test_stop_gradient import TINY
from torch_threads import single_torch_thread

pytestmark = pytest.mark.timeout(600)


def _trainer(data, tmp_path, **changes) -> Trainer:
    torch.manual_seed(0)
    return Trainer(dataclasses.replace(TINY, **changes), data, None, PLACEMENT, perception_record({"synthetic": 1}),
                   "synthetic", tmp_path, init_distributed("cpu"), show_progress=False)


def _data(n: int = 9):
    data, _ = make_dataset(n, resolution=32, seed=4)
    return dataclasses.replace(data, ids=[f"box{i % 3}-grasp-{i:05d}" for i in range(n)])


def test_each_draw_goes_to_its_objects_nearest_trajectory(tmp_path):
    data = _data()
    with single_torch_thread():
        selector = _trainer(data, tmp_path).selector.eval()
        objects = np.array([object_of(i) for i in data.ids])
        rows = np.array([0, 1, 3, 4, 6, 7])  # trajectories 2, 5, 8 teach no keyposes: they take no draws
        pools = served_eps_pools(selector, data, objects, rows, draws=3, device=torch.device("cpu"))
        true = selector.standardise(torch.from_numpy(data.z)).numpy()
    assert sum(len(p) for p in pools) == len(rows) * selector.config.clusters * 3
    assert [len(pools[r]) for r in (2, 5, 8)] == [0, 0, 0]
    for owner, pool in enumerate(pools):
        candidates = rows[objects[rows] == objects[owner]]
        for eps in pool:
            distance = np.linalg.norm(true[candidates] - eps, axis=1)
            assert candidates[np.argmin(distance)] == owner
    # The pools are the selector's draws, not copies of the true eps.
    assert not any(np.allclose(eps, true[r]) for r, pool in enumerate(pools) for eps in pool)


def test_at_noise_scale_0_the_draws_are_the_clusters_noise_free_eps(tmp_path):
    data = _data()
    with single_torch_thread():
        selector = _trainer(data, tmp_path).selector.eval()
        rows = np.arange(len(data))
        pools = served_eps_pools(selector, data, [object_of(i) for i in data.ids], rows, 2, torch.device("cpu"),
                                 noise_scale=0.0)
        views, _ = data.selector_batch(rows)
        centres = selector.cluster_centres(*selector.condition(views)).detach().numpy()  # (N, K, eps_size)
    drawn = np.concatenate([p for p in pools if len(p)])
    assert len(drawn) == len(data) * selector.config.clusters * 2
    # Every draw is one of the K noise-free eps of some O_init, each twice (the two draws are the same).
    distance = np.linalg.norm(drawn[:, None] - centres.reshape(-1, centres.shape[-1])[None], axis=-1).min(axis=1)
    assert np.all(distance < 1e-4)
    assert len(np.unique(drawn.round(4), axis=0)) == len(data) * selector.config.clusters


def test_a_selector_without_clusters_gives_draws_from_its_one_gaussian(tmp_path):
    data = _data(6)
    with single_torch_thread():
        selector = _trainer(data, tmp_path, selector=dataclasses.replace(TINY.selector, kind="cvae")).selector.eval()
        pools = served_eps_pools(selector, data, [object_of(i) for i in data.ids], np.arange(6), 3, torch.device("cpu"))
    assert sum(len(p) for p in pools) == 6 * 3


def test_no_draws_is_refused(tmp_path):
    data = _data(3)
    with pytest.raises(ValueError, match="at least 1 draw"):
        served_eps_pools(_trainer(data, tmp_path).selector, data, ["a"] * 3, np.arange(3), 0, torch.device("cpu"))


def test_a_neighbour_pool_holds_the_own_eps_and_the_nearest_of_the_same_object():
    true = np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0], [0.5, 0.0], [9.0, 0.0]], np.float32)
    objects = ["a", "a", "a", "b", "a"]  # trajectory 3, nearest to 0 and 1, is another object's
    pools = neighbour_eps_pools(true, objects, np.array([0, 1, 3]), count=2)
    assert pools[0].tolist() == [[0.0, 0.0], [1.0, 0.0], [3.0, 0.0]]
    assert pools[1].tolist() == [[1.0, 0.0], [0.0, 0.0], [3.0, 0.0]]
    assert pools[3].tolist() == [[0.5, 0.0]]  # alone on its object: only its own
    assert [len(pools[r]) for r in (2, 4)] == [0, 0]  # not the predictor's trajectories: no pool, yet neighbours
    with pytest.raises(ValueError, match="at least 1 neighbour"):
        neighbour_eps_pools(true, objects, np.array([0]), count=0)


def test_a_nearest_centre_pool_holds_the_own_o_inits_cluster_eps_nearest_the_true_eps(tmp_path):
    data = _data()
    with single_torch_thread():
        selector = _trainer(data, tmp_path).selector.eval()
        rows = np.array([0, 2, 3, 5, 7])
        pools, chosen = nearest_centre_pools(selector, data, rows, torch.device("cpu"), chunk=2)
        views, z = data.selector_batch(np.arange(len(data)))
        centres = selector.cluster_centres(*selector.condition(views)).detach().numpy()  # (N, K, eps_size)
        true = selector.standardise(z).numpy()
    assert [len(pools[r]) for r in (1, 4, 6, 8)] == [0, 0, 0, 0]
    for row, cluster in zip(rows, chosen):
        distance = np.linalg.norm(centres[row] - true[row], axis=1)  # its own O_init's K centres only
        assert cluster == np.argmin(distance)
        np.testing.assert_allclose(pools[row], centres[row, cluster][None], atol=1e-5)
    with pytest.raises(ValueError, match="need a selector with clusters"):
        cvae = _trainer(data, tmp_path, selector=dataclasses.replace(TINY.selector, kind="cvae")).selector
        nearest_centre_pools(cvae, data, rows, torch.device("cpu"))


def test_picks_come_from_the_rows_own_pools():
    pools = [np.zeros((0, 2), np.float32), np.array([[1.0, 1.0], [2.0, 2.0]], np.float32), np.array([[5.0, 5.0]], np.float32)]
    positions, picked = pick_from_pools(pools, np.array([0, 2, 1, 0]), np.random.default_rng(0))
    assert positions.tolist() == [1, 2]
    assert picked[0].tolist() == [5.0, 5.0] and picked[1].tolist() in ([1.0, 1.0], [2.0, 2.0])


@pytest.mark.parametrize("kind", ["served", "neighbour", "nearest_centre"])
def test_a_pooled_predictor_phase_feeds_pool_eps_in_training_batches_only(tmp_path, kind):
    data = _data()
    with single_torch_thread():
        trainer = _trainer(data, tmp_path, predictor_eps=kind, served_draws=2, eps_noise=0.5)
        eps = trainer.selector.standardise(torch.from_numpy(data.z[[0, 1, 2]]))
        assert torch.equal(trainer.training_eps(eps, np.array([0, 1, 2]), None), eps)  # outside the phase: as given
        trainer.eps_pools = [np.full((1, eps.shape[1]), 7.0, np.float32), np.zeros((0, eps.shape[1]), np.float32),
                             np.full((1, eps.shape[1]), 9.0, np.float32)]
        fed = trainer.training_eps(eps, np.array([0, 1, 2]), np.random.default_rng(1))
        assert torch.all(fed[0] == 7.0) and torch.all(fed[2] == 9.0)
        assert not torch.equal(fed[1], eps[1]) and torch.allclose(fed[1], eps[1], atol=4.0)  # true eps plus noise
        assert torch.equal(trainer.training_eps(eps, np.array([0, 1, 2]), None), eps)  # validation batches: as given
        # The phase builds the pools (from the selector's draws or centres, or from the true eps), then drops them: the
        # joint phase reads the selector's eps.
        trainer.eps_pools = None
        trainer.config = dataclasses.replace(trainer.config, phases=("predictor",),
                                             predictor_phase=dataclasses.replace(trainer.config.predictor_phase, epochs=0.1))
        seen = []
        original = trainer.training_eps
        trainer.training_eps = lambda e, r, g: (seen.append(trainer.eps_pools), original(e, r, g))[1]
        trainer._run_phase("predictor")
        true = trainer.selector.standardise(torch.from_numpy(data.z)).numpy()
    assert seen and all(pools is not None for pools in seen) and trainer.eps_pools is None
    own_first = [np.allclose(pool[0], true[row]) for row, pool in enumerate(seen[0]) if len(pool)]
    assert own_first and all(own_first) == (kind == "neighbour")
    if kind == "nearest_centre":  # one centre for every trajectory the predictor learns from
        assert all(len(pool) == 1 for pool in seen[0]) and len(seen[0]) == len(data)
