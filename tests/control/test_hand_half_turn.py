"""PlannerOptions.hand_half_turn: a keypose and its half turn about the approach axis as one goal.

The policy's rotation targets keep one of each pair (``rotation_bins.canonical_grasp``) while data
collection executed both, so a served keypose the arm can only take half-turned is refused without
the option. These tests use a real Panda model whose last joint is narrowed to [0.3, 2.6] rad, so
that half of the hand's turns about a downward approach are out of reach and their half turns are not.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from actaim2.control.collision import CollisionChecker
from actaim2.control.ik import IKSolver
from actaim2.control.model import RobotModel
from actaim2.control.planner import KeyposePlanner, PlannerOptions, PlanningError
from actaim2.control.trajectory import State
from actaim2.keypose import INIT, MANIPULATE, REACH
from actaim2.robots import load_robot_spec

DOWN = np.diag([1.0, -1.0, -1.0])  # tcp pointing down, as at home


def pose(position, yaw_deg: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = DOWN @ Rotation.from_euler("z", yaw_deg, degrees=True).as_matrix(), position
    return T


def half_turn(T: np.ndarray) -> np.ndarray:
    return T @ np.diag([-1.0, -1.0, 1.0, 1.0])  # Rz(180) in the tcp frame


@pytest.fixture(scope="module")
def robot() -> RobotModel:
    model = RobotModel(load_robot_spec("panda"))
    model.lower[6], model.upper[6] = 0.3, 2.6  # the wrist turns through 132 deg only
    return model


def planners(robot: RobotModel) -> tuple[KeyposePlanner, KeyposePlanner]:
    checker = CollisionChecker(robot)
    return (KeyposePlanner(robot, checker, IKSolver(robot, checker)),
            KeyposePlanner(robot, checker, IKSolver(robot, checker), PlannerOptions(hand_half_turn=True)))


def test_init_plans_the_half_turn_when_the_pose_is_refused(robot) -> None:
    plain, symmetric = planners(robot)
    home = State.at_rest(robot.spec.home)
    out_of_reach = pose([0.5, 0.0, 0.3], 180.0)
    with pytest.raises(PlanningError) as refused:
        plain.plan(INIT, out_of_reach, False, home, 1.0, np.random.default_rng(0))
    assert refused.value.reason == "joint_limits"
    motion = symmetric.plan(INIT, out_of_reach, False, home, 1.0, np.random.default_rng(0))
    np.testing.assert_allclose(motion.T_goal, half_turn(out_of_reach), atol=1e-12)
    reached = robot.fk(motion.trajectory.positions[-1])
    np.testing.assert_allclose(reached, motion.T_goal, atol=1e-4)
    assert robot.within_limits(motion.trajectory.positions[-1])

    in_reach = pose([0.5, 0.0, 0.3], 0.0)  # planned as given: the option changes nothing the arm accepts
    assert np.array_equal(symmetric.plan(INIT, in_reach, False, home, 1.0, np.random.default_rng(0)).T_goal, in_reach)


def test_reach_and_manipulate_follow_a_half_turned_hand(robot) -> None:
    """After INIT went half-turned, REACH comes in straight along the axis with the hand as it is, and
    MANIPULATE keeps that orientation (never a half turn of the held part)."""
    _, symmetric = planners(robot)
    p1 = np.array([0.5, 0.0, 0.3])
    init = symmetric.plan(INIT, pose(p1 + [0.0, 0.0, 0.12], 180.0), False, State.at_rest(robot.spec.home), 1.0,
                          np.random.default_rng(0))
    q = init.trajectory.positions[-1]
    reach = symmetric.plan(REACH, pose(p1, 180.0), False, State.at_rest(q), 1.0, np.random.default_rng(0))
    np.testing.assert_allclose(reach.T_goal, half_turn(pose(p1, 180.0)), atol=1e-12)
    assert reach.line_deviation < 2e-4  # the straight approach from where INIT left the hand
    q = reach.trajectory.positions[-1]
    manipulate = symmetric.plan(MANIPULATE, pose(p1 + [0.0, 0.0, 0.1], 180.0), True, State.at_rest(q), 1.0)
    np.testing.assert_allclose(manipulate.T_goal[:3, :3], robot.fk(q)[:3, :3], atol=1e-4)
    path_turn = max(Rotation.from_matrix(robot.fk(q)[:3, :3].T @ robot.fk(a)[:3, :3]).magnitude()
                    for a in manipulate.trajectory.positions)
    assert path_turn < 1e-3


def test_both_refused_reports_the_pose_as_given(robot) -> None:
    _, symmetric = planners(robot)
    with pytest.raises(PlanningError) as refused:
        symmetric.plan(INIT, pose([1.8, 0.0, 0.5], 180.0), False, State.at_rest(robot.spec.home), 1.0,
                       np.random.default_rng(0))
    assert refused.value.reason == "unreachable" and "[1.8, 0.0, 0.5]" in str(refused.value)
