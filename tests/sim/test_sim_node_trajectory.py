"""The sim node's trajectory following (joint_trajectory_controller semantics), without ROS."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.sim.joint_trajectory import (
    INVALID_GOAL,
    INVALID_JOINTS,
    OLD_HEADER_TIMESTAMP,
    ActiveTrajectory,
    InvalidTrajectory,
    command_from_points,
    validate,
)

JOINTS = ("j1", "j2")


def refused(names, points, start=None, now=0.0) -> InvalidTrajectory:
    with pytest.raises(InvalidTrajectory) as info:
        validate(command_from_points(names, points, start), JOINTS, now)
    return info.value


def test_bad_trajectories_get_jtc_error_codes():
    ok_point = (1.0, [0.1, 0.2], [], [])
    assert refused(["j1", "j3"], [ok_point]).error_code == INVALID_JOINTS
    assert "j3" in str(refused(["j1", "j3"], [ok_point]))
    assert refused(["j1"], [(1.0, [0.1], [], [])]).error_code == INVALID_JOINTS  # j2 missing
    assert refused(["j1", "j1"], [ok_point]).error_code == INVALID_JOINTS
    assert refused(JOINTS, [(1.0, [0.1, float("nan")], [], [])]).error_code == INVALID_GOAL
    assert refused(JOINTS, [(1.0, [0.1, 0.2], [0.0, float("inf")], [])]).error_code == INVALID_GOAL
    bad_time = refused(JOINTS, [ok_point, (1.0, [0.2, 0.3], [], [])])
    assert bad_time.error_code == INVALID_GOAL and "strictly increasing" in str(bad_time)
    assert refused(JOINTS, [ok_point, (0.5, [0.2, 0.3], [], [])]).error_code == INVALID_GOAL
    assert refused(JOINTS, [(1.0, [0.1], [], [])]).error_code == INVALID_GOAL  # wrong length
    assert refused(JOINTS, [(1.0, [0.1, 0.2], [0.0, 0.0], []), (2.0, [0.1, 0.2], [], [])]).error_code == INVALID_GOAL
    assert refused(JOINTS, [ok_point], start=2.0, now=5.0).error_code == OLD_HEADER_TIMESTAMP
    validate(command_from_points(JOINTS, [], None), JOINTS, 0.0)  # empty: hold position


def test_sampling_starts_from_the_current_state_and_ends_on_the_last_point():
    # joints given in another order than the controller's: reordered
    command = command_from_points(["j2", "j1"], [(1.0, [2.0, 1.0], [], []), (2.0, [4.0, 3.0], [], [])], None)
    traj = ActiveTrajectory(command, JOINTS, now=10.0, q_now=np.zeros(2), qd_now=np.zeros(2))
    np.testing.assert_allclose(traj.sample(10.0)[0], [0.0, 0.0])
    np.testing.assert_allclose(traj.sample(10.5)[0], [0.5, 1.0])  # linear to the first point
    q, qd = traj.sample(11.5)
    np.testing.assert_allclose(q, [2.0, 3.0])
    np.testing.assert_allclose(qd, [2.0, 2.0])
    assert traj.end_time == 12.0
    np.testing.assert_allclose(traj.sample(20.0)[0], [3.0, 4.0])


def test_future_stamp_holds_then_cubic_and_quintic_hit_their_knots():
    points = [(1.0, [1.0, -1.0], [0.5, 0.0], []), (2.0, [2.0, 0.0], [0.0, 0.0], [])]
    traj = ActiveTrajectory(command_from_points(JOINTS, points, 5.0), JOINTS, now=3.0, q_now=np.zeros(2), qd_now=np.zeros(2))
    np.testing.assert_allclose(traj.sample(4.0)[0], [0.0, 0.0])  # before the stamp: hold
    q, qd = traj.sample(6.0)
    np.testing.assert_allclose(q, [1.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(qd, [0.5, 0.0], atol=1e-12)
    # cubic is smooth: velocity continuous across the knot
    eps = 1e-6
    np.testing.assert_allclose(traj.sample(6.0 - eps)[1], traj.sample(6.0 + eps)[1], atol=1e-4)
    with_acc = [(1.0, [1.0, 1.0], [0.0, 0.0], [1.0, -1.0]), (2.0, [0.0, 0.0], [0.0, 0.0], [0.0, 0.0])]
    traj = ActiveTrajectory(command_from_points(JOINTS, with_acc, None), JOINTS, now=0.0, q_now=np.zeros(2), qd_now=np.zeros(2))
    np.testing.assert_allclose(traj.sample(1.0)[0], [1.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(traj.sample(2.0)[0], [0.0, 0.0], atol=1e-12)
    # the acceleration at the knot is the requested one, from either side
    h = 1e-6
    for side in (-h, h):
        acc = (traj.sample(1.0 + side)[1] - traj.sample(1.0)[1]) / side
        np.testing.assert_allclose(acc, [1.0, -1.0], atol=1e-3)
