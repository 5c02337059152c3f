"""Robot models for control: presets, continuous joints, the canonical tcp, any URDF by path."""
from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest
import yaml

from actaim2.control.model import RobotModel
from actaim2.robots import load_robot_spec, movable_gripper_urdf


@pytest.fixture(scope="module")
def panda() -> RobotModel:
    return RobotModel(load_robot_spec("panda"))


@pytest.fixture(scope="module")
def kinova() -> RobotModel:
    return RobotModel(load_robot_spec("kinova_j2s6s200"))


def test_kinova_continuous_joints_are_angles_outside_pinocchio(kinova):
    assert kinova.model.nq == 9 and kinova.n == 6
    assert kinova.continuous.tolist() == [True, False, False, True, False, True]
    assert np.isinf(kinova.lower[kinova.continuous]).all() and np.isfinite(kinova.lower[~kinova.continuous]).all()
    angles = kinova.random_angles(np.random.default_rng(0))
    np.testing.assert_allclose(kinova.to_angles(kinova.to_q(angles), near=angles), angles, atol=1e-12)
    # a continuous joint comes back next to the current value, not wrapped to [-pi, pi)
    near = angles.copy()
    near[0] += 4 * np.pi
    assert kinova.to_angles(kinova.to_q(angles), near=near)[0] == pytest.approx(angles[0] + 4 * np.pi)


def test_panda_tcp_is_panda_hand_tcp(panda):
    q = np.concatenate([panda.spec.home, [0.04, 0.04]])
    full = pin.buildModelFromUrdf(str(movable_gripper_urdf(panda.spec)))
    data = full.createData()
    pin.framesForwardKinematics(full, data, q)
    np.testing.assert_allclose(panda.fk(panda.spec.home), data.oMf[full.getFrameId("panda_hand_tcp")].homogeneous, atol=1e-12)


def test_kinova_tcp_points_along_the_approach_between_the_fingers(kinova):
    """tcp z = the hand's approach (link_6 -z), y towards finger 1, origin on the fingers' plane."""
    model, data = kinova.model, kinova.model.createData()
    pin.framesForwardKinematics(model, data, kinova.to_q(kinova.spec.home))
    link6 = data.oMf[model.getFrameId("j2s6s200_link_6")]
    tcp = link6.actInv(data.oMf[kinova.tcp_frame])
    np.testing.assert_allclose(tcp.rotation[:, 2], [0, 0, -1], atol=1e-9)
    np.testing.assert_allclose(tcp.rotation[:, 1], [0, 1, 0], atol=1e-9)
    np.testing.assert_allclose(tcp.translation, [-0.0025, 0.0, -0.18], atol=1e-9)
    finger1 = link6.actInv(data.oMf[model.getFrameId("j2s6s200_link_finger_1")]).translation
    finger2 = link6.actInv(data.oMf[model.getFrameId("j2s6s200_link_finger_2")]).translation
    assert finger1[1] > 0 > finger2[1]  # y points from finger 2 to finger 1
    np.testing.assert_allclose(0.5 * (finger1 + finger2)[:2], tcp.translation[:2], atol=1e-9)
    # home: tcp in front of the base pointing down, like the Panda's home
    T = kinova.fk(kinova.spec.home)
    np.testing.assert_allclose(T[:3, 2], [0, 0, -1], atol=1e-3)
    np.testing.assert_allclose(T[:3, 3], [0.35, 0.0, 0.45], atol=2e-3)


def test_movable_gripper_urdf_makes_kinova_fingers_revolute_with_absolute_meshes():
    spec = load_robot_spec("kinova_j2s6s200")
    root = ET.parse(movable_gripper_urdf(spec)).getroot()
    types = {j.get("name"): j.get("type") for j in root.findall("joint")}
    assert [types[j] for j in spec.gripper_joints] == ["revolute", "revolute"]
    assert types["j2s6s200_joint_finger_tip_1"] == "fixed"  # only the actuated joints move
    meshes = [m.get("filename") for m in root.iter("mesh")]
    assert meshes and all(m.startswith("/") for m in meshes)
    assert movable_gripper_urdf(spec) == movable_gripper_urdf(spec)  # content-addressed, written once


def test_any_urdf_by_path_with_joints_and_tcp_offset_as_parameters(tmp_path, panda):
    """The Panda described by a YAML file (URDF path, joints, flange + tcp offset) instead of
    the preset: same kinematics; limits the YAML leaves out come from the URDF."""
    spec = panda.spec
    config = {
        "name": "my_arm",
        "urdf": str(spec.urdf_path),
        "package_dirs": [str(p) for p in spec.package_dirs],
        "root_link": "panda_link0",
        "arm_joints": list(spec.arm_joints),
        "gripper_joints": list(spec.gripper_joints),
        "flange_frame": "panda_link8",  # the wrist flange: the tcp is 0.1034 m further, turned -45 deg
        "tcp_offset_xyz": [0.0, 0.0, 0.1034],
        "tcp_offset_quat_xyzw": [0.0, 0.0, -float(np.sin(np.pi / 8)), float(np.cos(np.pi / 8))],
        "gripper_open": 0.04,
        "gripper_closed": 0.0,
        "home": spec.home.tolist(),
    }
    path = tmp_path / "my_arm.yaml"
    path.write_text(yaml.safe_dump(config))
    custom = RobotModel(load_robot_spec(str(path)))
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = panda.random_angles(rng)
        np.testing.assert_allclose(custom.fk(q), panda.fk(q), atol=1e-9)
    np.testing.assert_allclose(custom.spec.max_velocity, spec.max_velocity)  # from the URDF
    np.testing.assert_allclose(custom.spec.max_acceleration, 4.0 * spec.max_velocity)
