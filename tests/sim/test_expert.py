"""The scripted expert moves parts by contact alone: push a drawer shut, grasp and pull it open,
swing a door both ways; a released handle stops following the hand."""
from __future__ import annotations

import numpy as np
import pytest
import sapien

from actaim2.rollout.expert import (
    GRASP,
    INIT,
    MANIPULATE,
    REACH,
    ExpertTask,
    ScriptedExpert,
    expert_tasks,
)
from actaim2.sim.env import SimEnv


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    return SimEnv("panda", cache_dir=tmp_path_factory.mktemp("objects"))


@pytest.fixture(scope="module")
def expert(env):
    return ScriptedExpert(env)


def _constraints(env: SimEnv) -> list:
    """Every joint-like component outside the two articulations (attachments, drives, gears)."""
    return [c for e in env.scene.entities for c in e.components if isinstance(c, sapien.physx.PhysxJointComponent)]


def test_pushes_a_half_open_drawer_shut_then_pulls_it_open(env, expert):
    env.reset("storage_furniture", 2, seed=2)
    lower, upper = env.object_limits()
    push = expert.run(ExpertTask("drawer_0_joint", -1))
    assert push.strategy == "push" and push.success, push.message
    assert env.object_dof()[0] < lower[0] + 0.1 * (upper[0] - lower[0])  # shut
    assert not _constraints(env)
    info = env.reset("storage_furniture", 2, seed=2)
    pull = expert.run(ExpertTask("drawer_0_joint", +1))
    assert pull.strategy == "grasp" and pull.success, pull.message
    assert env.object_dof()[0] > info.dof_initial[0] + 0.3 * (upper[0] - lower[0])
    np.testing.assert_allclose(env.object_dof()[1], info.dof_initial[1], atol=0.01)  # the other drawer untouched
    assert not _constraints(env)
    assert [k[0] for k in pull.keyposes] == [INIT, REACH, GRASP, MANIPULATE]
    assert [k[2] for k in pull.keyposes] == [False, False, True, True]


def test_opening_the_gripper_mid_pull_releases_the_drawer(env, expert):
    """The grasp is friction only: once the fingers open, the drawer stops following the hand."""
    env.reset("storage_furniture", 2, seed=2, dof_fraction=0.3)
    plan = expert.plan(ExpertTask("drawer_0_joint", +1))
    expert.reach(plan)
    q_grasped = env.object_dof()[0]
    half = len(plan.manipulation.joints) // 2
    expert.execute_motion(plan.manipulation[: half + 1], expert.manipulation_speed)
    q_pulled, hand_pulled = env.object_dof()[0], env.tcp_pose()[:3, 3]
    assert q_pulled - q_grasped > 0.05  # the drawer followed the hand while held
    env.grip(closed=False, opening=plan.opening)
    expert.execute_motion(plan.manipulation[half:], expert.manipulation_speed)
    hand_moved = np.linalg.norm(env.tcp_pose()[:3, 3] - hand_pulled)
    assert hand_moved > 0.05
    assert abs(env.object_dof()[0] - q_pulled) < 0.005  # ... and stayed where it was released


def test_swings_a_door_open_and_shut_and_moves_a_faucet_lever(env, expert):
    for category, instance in (("door", 1), ("faucet", 1)):
        env.reset(category, instance, seed=instance)
        for task in expert_tasks(env):
            env.reset(category, instance, seed=instance)
            result = expert.run(task)
            assert result.success, (category, task, result.message)
            assert result.moved * task.direction > 0.3


def test_expert_on_a_partnet_folder_with_meshes(env, expert, tmp_path):
    """An object folder with OBJ meshes, reset by path, is manipulated like a catalogue one."""
    from actaim2.sim.objects import catalog

    folder = catalog.generate("three_drawer_shelf", 0).write_folder(tmp_path / "shelf", meshes=True)
    info = env.reset(folder=folder, seed=5)
    assert info.dof_names == ["drawer_0_joint", "drawer_1_joint", "drawer_2_joint"]
    result = expert.run(ExpertTask("drawer_1_joint", +1))
    assert result.success, result.message


def test_no_handle_annotation_is_a_clear_failure(env, expert, tmp_path):
    from actaim2.sim.objects import catalog

    folder = catalog.generate("safe", 0).write_folder(tmp_path / "safe")
    (folder / "handles.json").unlink()
    env.reset(folder=folder)
    assert expert_tasks(env) == []
    result = expert.run(ExpertTask("door_joint", +1))
    assert not result.success and "no handle annotation" in result.message
