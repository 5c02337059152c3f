"""Robot self-filter: a Panda in a known pose disappears, a handle 2 cm from its gripper stays."""
from __future__ import annotations

import numpy as np
import open3d as o3d
import pinocchio as pin
import pytest

from actaim2.perception.self_filter import RobotSelfFilter
from actaim2.perception.synthetic import robot_collision_meshes
from actaim2.robots import load_robot_spec

MARGIN = 0.01


@pytest.fixture(scope="module")
def panda():
    spec = load_robot_spec("panda")
    # A pose away from home, so the filter must really follow the joint states.
    joints = dict(zip(spec.arm_joints, [0.3, -0.2, 0.1, -2.2, 0.2, 2.0, 0.5]))
    joints.update({name: 0.04 for name in spec.gripper_joints})
    self_filter = RobotSelfFilter(spec, MARGIN)
    self_filter.set_joint_positions(list(joints), list(joints.values()))
    meshes = robot_collision_meshes(spec, joints)
    return spec, joints, self_filter, meshes


def surface_distance(meshes, points):
    scene = o3d.t.geometry.RaycastingScene()
    for mesh in meshes:
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    return scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()


def test_robot_in_a_known_pose_is_removed(panda):
    _, _, self_filter, meshes = panda
    rng = np.random.default_rng(0)
    o3d.utility.random.seed(1)
    surface = np.concatenate([np.asarray(m.sample_points_uniformly(800).points) for m in meshes])
    noisy = surface + np.clip(rng.normal(0.0, 0.002, surface.shape), -0.004, 0.004)  # depth-sensor noise
    assert not self_filter.keep_mask(noisy).any()


def test_filter_follows_the_joint_states(panda):
    spec, joints, _, meshes = panda
    at_home = RobotSelfFilter(spec, MARGIN)  # neutral configuration: the arm is elsewhere
    hand = np.asarray(meshes[-9].sample_points_uniformly(500).points)  # panda_hand in the test pose
    assert at_home.keep_mask(hand).mean() > 0.9
    at_home.set_joint_positions(list(joints) + ["not_a_joint"], list(joints.values()) + [1.0])
    assert not at_home.keep_mask(hand).any()


def test_handle_two_centimetres_from_the_gripper_is_kept(panda):
    spec, _, self_filter, meshes = panda
    model, data = self_filter.model, self_filter.model.createData()
    pin.framesForwardKinematics(model, data, self_filter._q)
    T_tcp = data.oMf[model.getFrameId(spec.flange_frame)].homogeneous @ spec.T_flange_tcp
    # A bar of radius 1 cm across the approach axis, in front of the fingertips.
    angle, along = np.meshgrid(np.linspace(0, 2 * np.pi, 24, endpoint=False), np.linspace(-0.06, 0.06, 25))
    local = np.stack([along.ravel(), 0.01 * np.cos(angle.ravel()), 0.01 * np.sin(angle.ravel())], axis=1)

    def handle(offset: float) -> np.ndarray:
        return (local + [0.0, 0.0, offset]) @ T_tcp[:3, :3].T + T_tcp[:3, 3]

    lo, hi = -0.05, 0.1  # bisection on the offset along the approach axis: gap of exactly 2 cm
    for _ in range(30):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if surface_distance(meshes, handle(mid)).min() < 0.02 else (lo, mid)
    points = handle(hi)
    assert 0.0195 < surface_distance(meshes, points).min() < 0.0205
    assert self_filter.keep_mask(points).all()
