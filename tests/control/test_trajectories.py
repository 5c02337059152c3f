"""Ruckig segments, straight lines and keypose plans: every sampled limit holds, lines are straight."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.control.collision import CollisionChecker
from actaim2.control.ik import IKSolver
from actaim2.control.model import RobotModel
from actaim2.control.planner import KeyposePlanner, PlannerOptions, PlanningError
from actaim2.control.trajectory import JointPlanner, Limits, State
from actaim2.keypose import GRASP, INIT, MANIPULATE, REACH
from actaim2.robots import load_robot_spec

ROBOTS = ("panda", "kinova_j2s6s200")
TOL = 1.0 + 1e-6
# tcp pointing forward (+x) at a drawer handle, fingers closing vertically
FORWARD = np.column_stack([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
P1 = np.array([0.6, 0.0, 0.6])


def pose(position, rotation=FORWARD) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rotation, position
    return T


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request) -> RobotModel:
    return RobotModel(load_robot_spec(request.param))


def assert_within_limits(times, positions, velocities, accelerations, limits: Limits):
    """Every sample within position, velocity, acceleration limits; jerk from finite differences."""
    assert np.all(positions >= limits.lower - 1e-9) and np.all(positions <= limits.upper + 1e-9)
    assert np.all(np.abs(velocities) <= limits.velocity * TOL)
    assert np.all(np.abs(accelerations) <= limits.acceleration * TOL)
    dt = np.diff(times)[:, None]
    jerk = np.diff(accelerations, axis=0) / dt
    assert np.all(np.abs(jerk) <= limits.jerk * (1 + 1e-3)), np.max(np.abs(jerk) / limits.jerk)
    # the states are consistent: positions integrate the velocities
    np.testing.assert_allclose(np.diff(positions, axis=0), 0.5 * (velocities[1:] + velocities[:-1]) * dt,
                               atol=float(np.max(limits.jerk)) * float(np.max(dt)) ** 3 + 1e-9)


@pytest.mark.parametrize("scaling", [1.0, 0.3])
def test_ruckig_segments_respect_every_limit(robot, scaling):
    limits = Limits.of(robot, scaling)
    planner = JointPlanner(robot.n)
    rng = np.random.default_rng(7)
    for _ in range(10):
        start, goal = robot.random_angles(rng), robot.random_angles(rng)
        moving = State(start, rng.uniform(-0.5, 0.5, robot.n) * limits.velocity, np.zeros(robot.n))
        segment = planner.plan(moving, State.at_rest(goal), limits)
        t = np.linspace(0.0, segment.duration, 4000)
        states = [segment.at(ti) for ti in t]
        q = np.array([s.position for s in states])
        assert_within_limits(t, q, np.array([s.velocity for s in states]), np.array([s.acceleration for s in states]),
                             Limits(np.full(robot.n, -np.inf), np.full(robot.n, np.inf), limits.velocity, limits.acceleration, limits.jerk))
        np.testing.assert_allclose(q[0], start, atol=1e-9)
        np.testing.assert_allclose(q[-1], goal, atol=1e-9)


def test_stop_brakes_within_half_a_second(robot):
    limits = Limits.of(robot)
    planner = JointPlanner(robot.n)
    rng = np.random.default_rng(1)
    for _ in range(10):
        state = State(robot.spec.home, rng.choice([-1.0, 1.0], robot.n) * limits.velocity, rng.uniform(-0.5, 0.5, robot.n) * limits.acceleration)
        stop = planner.stop(state, limits)
        assert stop.duration < 0.5
        np.testing.assert_allclose(stop.at(stop.duration).velocity, 0.0, atol=1e-9)


@pytest.fixture(scope="module")
def planner(robot) -> KeyposePlanner:
    checker = CollisionChecker(robot)
    # points every 2 ms: dense enough to check jerk on the sampled trajectory itself
    return KeyposePlanner(robot, checker, IKSolver(robot, checker), PlannerOptions(sample_period=0.002))


def line_deviation(robot: RobotModel, positions: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    worst = 0.0
    for q in positions:
        p = robot.fk(q)[:3, 3]
        s = np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0)
        worst = max(worst, float(np.linalg.norm(p - (a + s * ab))))
    return worst


def test_four_phases_sampled_within_limits_and_straight(robot, planner):
    limits = Limits.of(robot, 0.5)
    rng = np.random.default_rng(0)
    p0, p2 = P1 - 0.12 * FORWARD[:, 2], P1 - 0.15 * FORWARD[:, 2]
    q = robot.spec.home
    init = planner.plan(INIT, pose(p0), False, State.at_rest(q), 0.5, rng)
    assert init.gripper_closed is False and init.line_deviation is None
    q = init.trajectory.positions[-1]
    np.testing.assert_allclose(robot.fk(q)[:3, 3], p0, atol=1e-4)

    # REACH from off the approach axis: joint segment to the pre-grasp via point, chained
    # (moving) into the straight approach
    off_axis = robot.fk(q)
    off_axis[:3, 3] += [0.0, 0.08, 0.05]
    q_off = IKSolver(robot, planner.checker).solve(off_axis, q).angles
    reach = planner.plan(REACH, pose(P1), False, State.at_rest(q_off), 0.5, rng)
    tr = reach.trajectory
    assert_within_limits(np.concatenate([[0.0], tr.times]), np.vstack([q_off, tr.positions]),
                         np.vstack([np.zeros(robot.n), tr.velocities]), np.vstack([np.zeros(robot.n), tr.accelerations]), limits)
    tcp = np.array([robot.fk(p)[:3, 3] for p in tr.positions])
    along = (tcp - P1) @ FORWARD[:, 2]
    last = along > -planner.options.approach_distance + 1e-4  # the straight last segment
    assert 0 < last.sum() < len(tr)
    assert line_deviation(robot, tr.positions[last], P1 - planner.options.approach_distance * FORWARD[:, 2], P1) < 2e-4
    speed = np.linalg.norm(np.diff(tcp, axis=0), axis=1) / np.diff(tr.times)
    assert speed[np.argmax(last) - 1] > 0.01  # no stop at the via point
    np.testing.assert_allclose(tcp[-1], P1, atol=1e-4)
    assert reach.line_deviation < 2e-4

    grasp = planner.plan(GRASP, pose(P1), True, State.at_rest(tr.positions[-1]), 0.5, rng)
    assert grasp.trajectory is None and grasp.gripper_closed is True

    manipulate = planner.plan(MANIPULATE, pose(p2), True, State.at_rest(tr.positions[-1]), 0.5, rng)
    tr = manipulate.trajectory
    assert_within_limits(tr.times, tr.positions, tr.velocities, tr.accelerations, limits)
    assert line_deviation(robot, tr.positions, P1, p2) < 2e-4
    np.testing.assert_allclose(robot.fk(tr.positions[-1])[:3, 3], p2, atol=1e-4)


def test_plans_fail_with_the_reason(robot, planner):
    with pytest.raises(PlanningError) as info:
        planner.plan(INIT, pose([0.5, 0.0, -0.1]), False, State.at_rest(robot.spec.home))
    assert info.value.reason == "environment_collision" and "table" in str(info.value)
    with pytest.raises(PlanningError) as info:
        planner.plan(REACH, pose([1.8, 0.0, 0.5]), False, State.at_rest(robot.spec.home))
    assert info.value.reason == "unreachable"
    with pytest.raises(PlanningError) as info:  # pulling the tcp 60 cm down through the table
        planner.plan(MANIPULATE, pose([0.5, 0.0, -0.3], np.diag([1.0, -1.0, -1.0])), True, State.at_rest(robot.spec.home))
    assert info.value.reason == "straight_line" and "table" in str(info.value)
