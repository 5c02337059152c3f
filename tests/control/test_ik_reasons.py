"""IK: FK/IK round trips and failures that say why (unreachable, self-collision, table, ...)."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.control.collision import CollisionChecker, Workspace
from actaim2.control.ik import IKFailure, IKSolver
from actaim2.control.model import RobotModel
from actaim2.geometry import rotation_angle
from actaim2.robots import load_robot_spec

ROBOTS = ("panda", "kinova_j2s6s200")
DOWN = np.diag([1.0, -1.0, -1.0])  # tcp pointing down, as at home
# Configurations folded onto themselves (found by sampling): their tcp poses can only be
# reached with the arm in self-collision.
FOLDED = {
    "panda": [-1.359, -1.083, -0.768, -3.024, -0.357, 0.161, -1.479],
    "kinova_j2s6s200": [-1.161, 4.161, 0.53, -2.916, 0.759, 2.315],
}


def pose(position, rotation=DOWN) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rotation, position
    return T


@pytest.fixture(scope="module", params=ROBOTS)
def arm(request):
    robot = RobotModel(load_robot_spec(request.param))
    checker = CollisionChecker(robot, Workspace())
    return robot, checker, IKSolver(robot, checker)


def test_fk_ik_round_trip_from_home_never_from_the_target(arm):
    robot, checker, solver = arm
    rng = np.random.default_rng(42)
    solved = 0
    for _ in range(40):
        target_angles = robot.random_angles(rng)
        if checker.check(target_angles) is not None:
            continue
        target = robot.fk(target_angles)
        result = solver.solve(target, robot.spec.home, rng=rng)
        assert result.success, result.message
        reached = robot.fk(result.angles)
        assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 1e-4
        assert rotation_angle(reached[:3, :3], target[:3, :3]) < 1e-3
        assert robot.within_limits(result.angles) and checker.check(result.angles) is None
        solved += 1
    assert solved >= 20


def test_seeded_solution_stays_near_the_current_joints(arm):
    robot, _, solver = arm
    current = robot.spec.home + 0.05
    result = solver.solve(robot.fk(current + 0.02), current)
    assert result.success and result.attempts == 1
    assert np.max(np.abs(result.angles - current)) < 0.2


def test_unreachable_target(arm):
    robot, _, solver = arm
    result = solver.solve(pose([2.0, 0.0, 0.5]), robot.spec.home)
    assert not result.success and result.failure == IKFailure.UNREACHABLE
    assert "reach" in result.message


def test_self_colliding_target(arm):
    robot, checker, solver = arm
    folded = np.array(FOLDED[robot.spec.name])
    assert robot.within_limits(folded) and checker.check(folded).kind == "self"
    result = solver.solve(robot.fk(folded), robot.spec.home, rng=np.random.default_rng(0))
    assert not result.success and result.failure == IKFailure.SELF_COLLISION, result.message
    assert result.message.startswith("self_collision")


def test_table_colliding_target(arm):
    """The tcp 3 cm under the table surface, pointing down: the fingers would go through it
    (Kinova's open fingertips end 17 mm short of its tcp, Panda's 9 mm beyond it)."""
    robot, _, solver = arm
    result = solver.solve(pose([0.5, 0.0, -0.03]), robot.spec.home, rng=np.random.default_rng(0))
    assert not result.success and result.failure == IKFailure.ENVIRONMENT_COLLISION, result.message
    assert "table" in result.message
    assert solver.solve(pose([0.5, 0.0, 0.10]), robot.spec.home).success  # well above it: fine


def test_workspace_box_rejects_targets_outside(arm):
    robot, _, _ = arm
    boxed = IKSolver(robot, CollisionChecker(robot, Workspace(box_max=(0.4, 0.9, 1.5))))
    result = boxed.solve(pose([0.5, 0.0, 0.3]), robot.spec.home, rng=np.random.default_rng(0))
    assert result.failure == IKFailure.ENVIRONMENT_COLLISION and "workspace_max_x" in result.message


def test_joint_limits_reason_for_a_pose_only_reached_outside_them():
    """A Panda cannot point its hand horizontally this low and close (joint 6 would pass its limit)."""
    robot = RobotModel(load_robot_spec("panda"))
    solver = IKSolver(robot, CollisionChecker(robot))
    horizontal = np.column_stack([[0, 1, 0], [0, 0, 1], [1, 0, 0]]).astype(float)  # approach +x
    result = solver.solve(pose([0.48, 0.0, 0.35], horizontal), robot.spec.home, rng=np.random.default_rng(0))
    assert result.failure == IKFailure.JOINT_LIMITS, result.message


def test_cloud_obstacle_except_near_the_grasp_point(arm):
    from actaim2.control.collision import points_away_from

    robot, _, _ = arm
    checker = CollisionChecker(robot)
    solver = IKSolver(robot, checker)
    target = pose([0.5, 0.0, 0.3])
    # a 20 cm square wall of points right where the hand is
    g = np.linspace(-0.1, 0.1, 21)
    wall = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    cloud = np.column_stack([0.5 + wall[:, 0], wall[:, 1], np.full(len(wall), 0.33)])
    checker.set_cloud(cloud)
    assert solver.solve(target, robot.spec.home).failure == IKFailure.ENVIRONMENT_COLLISION
    checker.set_cloud(points_away_from(cloud, target[:3, 3], 0.15))
    assert solver.solve(target, robot.spec.home).success
    assert solver.solve(target, robot.spec.home, use_cloud=False).success
