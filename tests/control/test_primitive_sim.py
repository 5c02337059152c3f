"""The four-phase primitive without ROS: KeyposeRunner driving SimEnv directly (data collection)."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.control.collision import CollisionChecker
from actaim2.control.executor import KeyposeRunner
from actaim2.control.ik import IKSolver
from actaim2.control.model import RobotModel
from actaim2.control.planner import KeyposePlanner
from actaim2.geometry import matrix_to_pose, rotation_angle
from actaim2.keypose import Keypose
from actaim2.rollout.sim_executor import SimEnvExecutor


@pytest.mark.parametrize("robot", ["kinova_j2s6s200", "panda"])
def test_primitive_pulls_a_drawer_open(robot):
    from actaim2.sim.env import SimEnv

    env = SimEnv(robot, cameras=None)
    info = env.reset("table", instance=4, seed=0)  # a half-open drawer with a bar handle, in both arms' reach
    handle = next(h for h in env.object.handles if h.joint == "drawer_0_joint")
    joint = env.object.joints[env.object.dof_index(handle.joint)]
    T = env.object.link(handle.link).entity_pose.to_transformation_matrix() @ handle.tcp_in_link()
    p1, approach = T[:3, 3], T[:3, 2]
    p2 = p1 + 0.12 * joint.get_global_pose().to_transformation_matrix()[:3, 0]  # pull along the drawer's axis
    _, quat = matrix_to_pose(T)
    keyposes = [Keypose(0, p1 - 0.12 * approach, quat, False), Keypose(1, p1, quat, False),
                Keypose(2, p1, quat, True), Keypose(3, p2, quat, True)]

    model = RobotModel(env.spec)
    checker = CollisionChecker(model)
    runner = KeyposeRunner(KeyposePlanner(model, checker, IKSolver(model, checker)), SimEnvExecutor(env), np.random.default_rng(0))
    before = env.object_dof().copy()
    outcomes = runner.run_primitive(keyposes, velocity_scaling=0.5)
    assert [o.success for o in outcomes] == [True] * 4, [o.message for o in outcomes]
    for keypose, outcome in zip(keyposes, outcomes):
        assert outcome.position_error <= 0.005 and outcome.orientation_error <= np.radians(3.0)
    tcp = env.tcp_pose()  # SAPIEN's own tcp, not the controller's model
    assert np.linalg.norm(tcp[:3, 3] - p2) <= 0.005
    assert rotation_angle(tcp[:3, :3], T[:3, :3]) <= np.radians(3.0)
    assert env.success(before)  # the drawer moved by more than 30% of its range
    i = info.dof_names.index("drawer_0_joint")
    assert env.object_dof()[i] - before[i] > 0.3 * (info.dof_upper[i] - info.dof_lower[i])


def test_primitive_needs_the_four_phases_in_order():
    runner = KeyposeRunner(None, None)
    keypose = Keypose(0, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), False)
    with pytest.raises(ValueError, match="phases"):
        runner.run_primitive([keypose, keypose])


def test_run_first_falls_back_and_moves_nothing_for_a_refused_keypose():
    """A policy's keypose the planner refuses is skipped without motion; the next candidate runs.
    All refused: the first one's refusal (what was asked for), index -1, the arm where it was."""
    from actaim2.sim.env import SimEnv

    env = SimEnv("panda", cameras=None)
    env.reset("table", instance=4, seed=0)
    model = RobotModel(env.spec)
    checker = CollisionChecker(model)
    executor = SimEnvExecutor(env)
    runner = KeyposeRunner(KeyposePlanner(model, checker, IKSolver(model, checker)), executor, np.random.default_rng(0))
    down = np.array([1.0, 0.0, 0.0, 0.0])  # tcp pointing down (x, y, z, w)
    far = Keypose(0, np.array([1.8, 0.0, 0.5]), down, False)  # beyond the arm's reach
    start = executor.arm_state().position

    outcome, index = runner.run_first([far, far], velocity_scaling=0.5)
    assert index == -1 and not outcome.success and outcome.reason == "unreachable"
    assert "[1.8, 0.0, 0.5]" in outcome.message and outcome.refused == ""
    np.testing.assert_allclose(executor.arm_state().position, start, atol=1e-6)

    near = Keypose(0, np.array([0.45, 0.0, 0.45]), down, False)
    outcome, index = runner.run_first([far, near], velocity_scaling=0.5)
    assert index == 1 and outcome.success, outcome.message
    assert outcome.refused.startswith("keypose: ") and "[1.8, 0.0, 0.5]" in outcome.refused  # why it was not executed
    assert np.linalg.norm(env.tcp_pose()[:3, 3] - near.position) <= 0.005

    farther = Keypose(0, np.array([0.0, 1.9, 0.5]), down, False)
    outcome, index = runner.run_first([far, farther, near], velocity_scaling=0.5)
    assert index == 2 and outcome.success, outcome.message
    keypose, fallback = outcome.refused.split("; ")  # every refused candidate, in order, with its own reason
    assert keypose.startswith("keypose: ") and "[1.8, 0.0, 0.5]" in keypose
    assert fallback.startswith("alternatives[0]: ") and "[0.0, 1.9, 0.5]" in fallback
    with pytest.raises(ValueError, match="no keypose"):
        runner.run_first([])
