"""The self-filter against what cameras really see: SAPIEN's rasterised *visual* meshes of the
Panda (not the collision geometry the filter is built from), in 20 random poses and along a
fast trajectory, with the joint state interpolated at each cloud's stamp.

Ground truth comes from the renderer's segmentation: a pixel is the robot's when it shows a
robot link, the object's when it shows the articulated object. Every valid pixel of the five
ring5 cameras (its world point through the published extrinsics) goes through the filter, so
the figures are per camera pixel: robot pixels the filter keeps ("left") and object pixels it
removes must each stay within 1%.

SAPIEN's renderer is required (Vulkan; on this machine Mesa lavapipe, see scripts/env.sh):
``resolve_render_path("sapien")`` raises when it is missing, so this test errors out instead of
quietly measuring the ray-cast collision meshes, which would make it pass by construction.
"""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.perception.joint_history import JointStateHistory
from actaim2.perception.self_filter import DEFAULT_MARGIN, RobotSelfFilter
from actaim2.sim.env import SimEnv

BOUND = 0.01
JOINT_STATE_PERIOD = 0.02  # s: /joint_states at 50 Hz, as sim_node publishes them
NS = 1_000_000_000


@pytest.fixture(scope="module")
def sapien_env():
    env = SimEnv("panda", cameras="ring5", render_path="sapien")  # raises without a Vulkan device
    assert env.render_path == "sapien"
    env.reset("storage_furniture", 0, seed=0)
    robot = np.array(sorted(env.sim.robot_entity_ids()))
    obj = np.array(sorted(link.entity.per_scene_id for link in env.object_links))
    return env, robot, obj


def count(env, robot_ids, object_ids, self_filter) -> np.ndarray:
    """(robot pixels, robot pixels kept, object pixels, object pixels removed) over every camera."""
    obs = env.observe(with_robot=True)
    totals = np.zeros(4, dtype=np.int64)
    for name, frame in obs.frames.items():
        points = obs.points_world(name).reshape(-1, 3)
        seg = frame.segmentation.reshape(-1)
        valid = np.isfinite(points).all(axis=1)
        keep = self_filter.keep_mask(points[valid])
        on_robot, on_object = np.isin(seg[valid], robot_ids), np.isin(seg[valid], object_ids)
        totals += [on_robot.sum(), (on_robot & keep).sum(), on_object.sum(), (on_object & ~keep).sum()]
    return totals


def rates(totals: np.ndarray) -> tuple[float, float]:
    return totals[1] / totals[0], totals[3] / totals[2]


def arm_limits(self_filter: RobotSelfFilter, joints) -> tuple[np.ndarray, np.ndarray]:
    model = self_filter.model
    index = [model.joints[model.getJointId(name)].idx_q for name in joints]
    return model.lowerPositionLimit[index], model.upperPositionLimit[index]


def test_random_poses(sapien_env):
    env, robot_ids, object_ids = sapien_env
    spec = env.spec
    self_filter = RobotSelfFilter(spec, DEFAULT_MARGIN)
    lower, upper = arm_limits(self_filter, spec.arm_joints)
    rng = np.random.default_rng(0)
    totals = np.zeros(4, dtype=np.int64)
    for _ in range(20):
        arm = np.clip(spec.home + rng.uniform(-0.8, 0.8, len(spec.arm_joints)), lower, upper)
        env.robot.reset(arm, rng.uniform(spec.gripper_closed, spec.gripper_open))
        names, positions, _ = env.joint_state()
        self_filter.set_joint_positions(list(names), positions)
        totals += count(env, robot_ids, object_ids, self_filter)
    left, removed = rates(totals)
    print(f"\n20 random poses: {totals[0]} robot pixels, {100 * left:.3f}% left; "
          f"{totals[2]} object pixels, {100 * removed:.3f}% removed (margin {DEFAULT_MARGIN} m)")
    assert totals[0] > 100_000 and totals[2] > 100_000  # the arm and the object are really in view
    assert left <= BOUND and removed <= BOUND


def test_moving_arm_with_the_joint_state_interpolated_at_the_cloud_stamp(sapien_env):
    """Every joint swings at up to 1.57 rad/s; /joint_states come every 20 ms and each cloud is
    taken between two of them. Posing the robot from the newest JointState (the old behaviour)
    is measured alongside to show what the interpolation buys."""
    env, robot_ids, object_ids = sapien_env
    spec = env.spec
    phase = np.linspace(0.0, np.pi, len(spec.arm_joints))
    interpolated, newest = RobotSelfFilter(spec, DEFAULT_MARGIN), RobotSelfFilter(spec, DEFAULT_MARGIN)
    lower, upper = arm_limits(interpolated, spec.arm_joints)

    def arm(t: float) -> np.ndarray:
        return np.clip(spec.home + 0.5 * np.sin(np.pi * t + phase), lower, upper)

    def fingers(t: float) -> float:
        return spec.gripper_closed + (spec.gripper_open - spec.gripper_closed) * (0.5 + 0.5 * np.sin(3.0 * t))

    history = JointStateHistory(history=3.0)  # the whole trajectory
    names = list(spec.arm_joints) + list(spec.gripper_joints)
    for k in range(int(2.2 / JOINT_STATE_PERIOD) + 1):
        t = k * JOINT_STATE_PERIOD
        history.add(round(t * NS), names, list(arm(t)) + [fingers(t)] * len(spec.gripper_joints))
    totals = {"interpolated": np.zeros(4, dtype=np.int64), "newest": np.zeros(4, dtype=np.int64)}
    for t in 0.013 + 0.2 * np.arange(10):  # clouds between two joint states
        env.robot.reset(arm(t), fingers(t))
        interpolated.set_configurations([history.at(round(t * NS))])
        last = np.floor(t / JOINT_STATE_PERIOD) * JOINT_STATE_PERIOD
        newest.set_joint_positions(names, list(arm(last)) + [fingers(last)] * len(spec.gripper_joints))
        totals["interpolated"] += count(env, robot_ids, object_ids, interpolated)
        totals["newest"] += count(env, robot_ids, object_ids, newest)
    for name, total in totals.items():
        left, removed = rates(total)
        print(f"\nmoving arm, joints {name}: {total[0]} robot pixels, {100 * left:.3f}% left; "
              f"{total[2]} object pixels, {100 * removed:.3f}% removed")
    left, removed = rates(totals["interpolated"])
    assert totals["interpolated"][0] > 50_000
    assert left <= BOUND and removed <= BOUND
    # the test can tell: the robot where the newest JointState puts it leaves far more behind
    assert rates(totals["newest"])[0] > 3 * max(left, 1e-4)
