"""The visual success label's threshold, metrics, and the ground-truth criterion."""
from __future__ import annotations

import numpy as np

from actaim2.data.success import calibrate_threshold, change, label_metrics, relative_score
from actaim2.data.trajectory import ObjectState, ground_truth_success


def test_threshold_separates_and_matches_brute_force():
    rng = np.random.default_rng(0)
    s = np.r_[rng.normal(0.0, 1.0, 300), rng.normal(3.0, 1.0, 60)]
    gt = np.r_[np.zeros(300, bool), np.ones(60, bool)]
    t = calibrate_threshold(s, gt)
    best = max(label_metrics(s, gt, c)["accuracy"] for c in np.r_[s - 1e-9, s + 1e-9])
    assert label_metrics(s, gt, t)["accuracy"] == best
    assert label_metrics(np.array([0.1, 0.2, 0.9]), np.array([False, False, True]), calibrate_threshold([0.1, 0.2, 0.9], [False, False, True]))["accuracy"] == 1.0


def test_change_is_rms_of_z_and_the_score_is_relative_to_the_object():
    z = np.array([[3.0, 4.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
    np.testing.assert_allclose(change(z), [2.5, 0.0])
    changes = np.array([0.01, 0.02, 0.10, 1.0, 2.0, 10.0])  # a switch's toggle and a door: different scales
    objects = np.array(["switch"] * 3 + ["door"] * 3)
    rel = relative_score(changes, objects, percentile=100.0)
    np.testing.assert_allclose(rel, [0.1, 0.2, 1.0, 0.1, 0.2, 1.0])


def test_ground_truth_is_thirty_percent_of_the_range():
    state = ObjectState(["door", "drawer"], np.array([0.0, 0.0]), np.array([1.5, 0.4]), np.array([0.75, 0.2]), np.array([0.75, 0.2]))
    assert not ground_truth_success(state)
    state.final = np.array([0.75, 0.2 - 0.13])  # drawer closed by 32.5% of its range
    assert ground_truth_success(state)
    state.final = np.array([0.75 + 0.4, 0.2])  # door opened by 26.7%
    assert not ground_truth_success(state)
