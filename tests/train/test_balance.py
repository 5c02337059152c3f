"""Cluster-balanced keyframe draws (train/balance.py): within an object every cluster present carries an
equal share of the object's mass, the object's total is kept, and a balanced predictor phase draws its
batches with those weights, each trajectory's cluster its nearest-centre one."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from actaim2.data.storage import object_of
from actaim2.train.balance import cluster_balanced_weights
from actaim2.train.config import TrainConfig
from actaim2.train.served_eps import nearest_centre_pools
from test_served_eps import _data, _trainer
from torch_threads import single_torch_thread

pytestmark = pytest.mark.timeout(600)


def test_each_cluster_of_an_object_gets_an_equal_share_of_its_mass():
    objects = np.array(["a"] * 5 + ["b"] * 3)
    clusters = np.array([0, 0, 0, 0, 3, 1, 1, 1])
    weights = cluster_balanced_weights(objects, clusters)
    # a: 5 trajectories over 2 clusters -> 2.5 each; b: one cluster -> as collected
    np.testing.assert_allclose(weights, [0.625] * 4 + [2.5] + [1.0] * 3)
    assert weights[:5].sum() == pytest.approx(5) and weights[5:].sum() == pytest.approx(3)


def test_one_cluster_per_trajectory_is_required():
    with pytest.raises(ValueError, match="one cluster per trajectory"):
        cluster_balanced_weights(np.array(["a", "a"]), np.array([0]))


def test_a_balanced_predictor_phase_draws_by_the_nearest_centre_clusters(tmp_path):
    data = _data(12)
    with single_torch_thread():
        trainer = _trainer(data, tmp_path, predictor_balance="cluster")
        items = trainer._items("predictor", trainer.train)
        probabilities = trainer._draw_probabilities("predictor", items)
        trajectories = np.unique(items[:, 0])
        _, chosen = nearest_centre_pools(trainer.selector.eval(), data, trajectories, torch.device("cpu"))
        assert trainer._draw_probabilities("selector", trainer._items("selector", trainer.train)) is None
        plain = _trainer(data, tmp_path / "plain")
        assert plain._draw_probabilities("predictor", plain._items("predictor", plain.train)) is None
        # The phase runs with them: its batches are drawn from the weighted items.
        trainer.config = dataclasses.replace(trainer.config, phases=("predictor",),
                                             predictor_phase=dataclasses.replace(trainer.config.predictor_phase, epochs=0.1))
        trainer._run_phase("predictor")
    assert probabilities.sum() == pytest.approx(1.0)
    # every keyframe of a trajectory has its trajectory's weight; within an object the clusters weigh the same
    per_trajectory = {t: probabilities[items[:, 0] == t] for t in trajectories}
    assert all(np.allclose(p, p[0]) for p in per_trajectory.values())
    objects = np.array([object_of(data.ids[t]) for t in trajectories])
    # some object's clusters hold unequal counts of trajectories: uniform draws would not pass
    assert any(len(set(np.unique(chosen[objects == o], return_counts=True)[1])) > 1 for o in set(objects))
    for obj in set(objects):
        mass = {c: sum(per_trajectory[t][0] for t in trajectories[(objects == obj) & (chosen == c)])
                for c in set(chosen[objects == obj])}
        assert np.allclose(list(mass.values()), next(iter(mass.values())))


def test_an_unknown_balance_is_refused():
    with pytest.raises(ValueError, match="predictor_balance must be one of"):
        TrainConfig.from_dict({"predictor_balance": "outcome"})
