"""SimEnv, the ROS-free Python API: reset, DoF state and limits, success check, trajectories, bad input."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.sim.env import SimEnv
from actaim2.sim.objects import catalog
from actaim2.sim.objects.loader import ObjectLoadError


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    return SimEnv("panda", cache_dir=tmp_path_factory.mktemp("objects"))


def test_reset_sets_dof_fraction_and_reports_limits(env):
    info = env.reset("storage_furniture", 2, seed=3)
    assert info.object_id == "storage_furniture_002" and info.category == "storage_furniture"
    lower, upper = env.object_limits()
    np.testing.assert_allclose(info.dof_initial, (lower + upper) / 2, atol=1e-5)  # half-open by default
    np.testing.assert_allclose(env.object_dof(), info.dof_initial, atol=1e-5)
    assert len(info.dof_names) == len(lower) >= 2
    info = env.reset("storage_furniture", 2, seed=3, dof_fraction=[0.0, 0.8, 0.5])
    np.testing.assert_allclose(info.dof_initial[:2], [lower[0], lower[1] + 0.8 * (upper[1] - lower[1])], atol=1e-5)
    np.testing.assert_allclose(env.robot.arm_positions(), env.spec.home, atol=1e-6)
    assert env.robot.gripper_position() == pytest.approx(env.spec.gripper_open, abs=1e-5)


def test_placement_jitter_follows_the_seed(env):
    poses = []
    for seed in (1, 1, 2):
        env.reset("door", 1, seed=seed)
        poses.append(env.object.pose())
    np.testing.assert_allclose(poses[0], poses[1])
    assert not np.allclose(poses[0], poses[2])
    env.reset("door", 1, seed=2, dof_fraction=0.0, jitter=False)  # placement is measured closed
    lo = min(link.compute_global_aabb_tight()[0][0] for link in env.object_links)
    assert lo == pytest.approx(catalog.generate("door", 1).params["front_distance"], abs=1e-3)


def test_success_is_any_dof_moved_more_than_30_percent(env):
    info = env.reset("refrigerator", 3, seed=0)
    assert not env.success()
    span = info.dof_upper - info.dof_lower
    q = info.dof_initial.copy()
    q[-1] -= 0.25 * span[-1]
    env.object.set_qpos(q)
    assert not env.success()
    q[-1] = info.dof_initial[-1] - 0.31 * span[-1]
    env.object.set_qpos(q)
    assert env.success() and env.success(info.dof_initial)
    assert not env.success(env.object_dof())


def test_follow_trajectory_tracks_and_ends_at_the_last_point(env):
    env.reset("switch", 0, seed=0)
    q0 = env.robot.arm_positions()
    q1 = q0 + np.array([0.3, -0.2, 0.2, 0.3, -0.2, 0.3, 0.4])
    times = np.linspace(0.1, 1.5, 15)
    s = (times / times[-1])[:, None]
    positions = q0 + (3 * s**2 - 2 * s**3) * (q1 - q0)
    velocities = (6 * s - 6 * s**2) / times[-1] * (q1 - q0)
    t0 = env.time
    errors = []
    orig = env.robot.set_arm_target

    def record(q, qd=None):  # tracking error of the physics against the commanded trajectory
        errors.append(np.abs(env.robot.arm_positions() - q).max())
        orig(q, qd)

    env.robot.set_arm_target = record
    try:
        env.follow_trajectory(times, positions, velocities, settle=0.2)
    finally:
        del env.robot.set_arm_target
    assert env.time - t0 == pytest.approx(1.7, abs=2 * env.timestep)
    np.testing.assert_allclose(env.robot.arm_positions(), q1, atol=2e-3)
    assert max(errors) < 0.02
    names, position, velocity = env.joint_state()
    assert names == list(env.spec.arm_joints + env.spec.gripper_joints) and len(position) == len(velocity) == 9


def test_bad_requests_are_refused_clearly(env, tmp_path):
    with pytest.raises(ValueError, match="unknown object category"):
        env.reset("teapot", 0)
    with pytest.raises(ValueError, match="dof_fraction"):
        env.reset("door", 0, dof_fraction=1.5)
    with pytest.raises(ValueError, match="category"):
        env.reset()
    with pytest.raises(ObjectLoadError, match="mobility.urdf"):
        env.reset(folder=tmp_path)
    with pytest.raises(RuntimeError, match="no cameras"):
        env.observe()


def test_robot_at_home_touches_no_half_open_object(env):
    """Placement keeps every catalogued object, half-open, clear of the robot's home pose."""
    touching = []
    for category in catalog.list_categories():
        for instance in catalog.category_instances(category):
            env.reset(category, instance, seed=instance)
            env.step()
            robot = {link.entity.per_scene_id for link in env.robot_links}
            for contact in env.scene.get_contacts():
                ids = {body.entity.per_scene_id for body in contact.bodies}
                if ids & robot and not ids <= robot and any(p.separation < 0.0 for p in contact.points):
                    touching.append(env.info.object_id)
    assert not touching, f"robot at home touches {sorted(set(touching))}"
