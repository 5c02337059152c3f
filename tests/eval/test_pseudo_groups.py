"""Pseudo-clusters: a balanced random partition of an unclustered row's samples, independent of the slot order
that Data Collection's GMM sampler visits its clusters in; results grouped the old way are not mixed in."""
from __future__ import annotations

import json
from collections import Counter

import pytest

from actaim2.eval.methods import PSEUDO_CLUSTERS, PSEUDO_GROUPING
from actaim2.eval.results import RunMismatchError, check_run
from actaim2.eval.sources import pseudo_group

RUN = {"eval_set_version": 1, "robot": "panda", "rig": "ring5", "hand_half_turn": True, "methods": {"random": "random"}}


def test_every_repetition_visits_each_pseudo_cluster_once_in_its_own_order():
    slots = range(8 * PSEUDO_CLUSTERS)
    groups = [pseudo_group("storage_furniture_000", s) for s in slots]
    assert groups == [pseudo_group("storage_furniture_000", s) for s in slots]  # seeded: a rerun groups alike
    for repetition in range(8):
        block = groups[repetition * PSEUDO_CLUSTERS:(repetition + 1) * PSEUDO_CLUSTERS]
        assert sorted(g for g, _ in block) == list(range(PSEUDO_CLUSTERS)) and {r for _, r in block} == {repetition}
    orders = {tuple(g for g, _ in groups[r * 8:(r + 1) * 8]) for r in range(8)}
    assert len(orders) > 4  # not one fixed order (slot mod 8 would give one)
    assert [g for g, _ in groups[:8]] != [g for g, _ in (pseudo_group("table_000", s) for s in range(8))]


def test_a_round_robin_over_four_clusters_spreads_over_every_pseudo_cluster():
    """Data Collection's sample ``slot`` comes from GMM cluster ``slot mod n``; with n = 4 and ``slot mod 8``
    pseudo-cluster g held cluster g mod 4 only; now each holds several."""
    per_group: dict[int, Counter] = {g: Counter() for g in range(PSEUDO_CLUSTERS)}
    for key in ("storage_furniture_000", "door_003", "faucet_001"):
        for slot in range(8 * PSEUDO_CLUSTERS):
            per_group[pseudo_group(key, slot)[0]][slot % 4] += 1
    assert all(len(c) >= 3 for c in per_group.values()), per_group  # slot mod 8: one cluster each


def test_results_grouped_by_slot_mod_8_are_not_resumed(tmp_path):
    (tmp_path / "run.json").write_text(json.dumps(RUN))  # written before pseudo_grouping was recorded
    with pytest.raises(RunMismatchError, match=f"pseudo_grouping 'slot mod 8', this run has '{PSEUDO_GROUPING}'"):
        check_run(tmp_path, {**RUN, "pseudo_grouping": PSEUDO_GROUPING})
    fresh = tmp_path / "fresh"
    assert check_run(fresh, {**RUN, "pseudo_grouping": PSEUDO_GROUPING})["pseudo_grouping"] == PSEUDO_GROUPING
    assert check_run(fresh, {**RUN, "pseudo_grouping": PSEUDO_GROUPING})["methods"] == {"random": "random"}
