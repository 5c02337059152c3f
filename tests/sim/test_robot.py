"""The simulated robots: loading (presets and a URDF given by path), PD drives, gravity compensation, TCP, gripper."""
from __future__ import annotations

import numpy as np
import pytest
import sapien
import yaml

from actaim2.control.model import RobotModel
from actaim2.robots import load_robot_spec
from actaim2.sim.robot import SimRobot


def _scene() -> sapien.Scene:
    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    scene.set_timestep(1.0 / 240.0)
    scene.add_ground(0.0, render=False)
    return scene


@pytest.mark.parametrize("name", ["panda", "kinova_j2s6s200"])
def test_robot_holds_home_and_its_tcp_matches_pinocchio(name):
    """Gravity-compensated PD drives hold the home pose; SAPIEN's tcp (flange link pose x
    T_flange_tcp) is the same frame as control's Pinocchio model's."""
    spec = load_robot_spec(name)
    scene = _scene()
    robot = SimRobot(scene, spec)
    assert robot.joint_names == list(spec.arm_joints + spec.gripper_joints)
    for _ in range(240):
        scene.step()
    assert np.abs(robot.arm_positions() - spec.home).max() < 1e-3
    model = RobotModel(spec)
    np.testing.assert_allclose(robot.tcp_pose(), model.fk(robot.arm_positions()), atol=1e-4)
    q = spec.home + 0.2
    model_tcp = model.fk(q)
    robot.reset(q, spec.gripper_open)
    np.testing.assert_allclose(robot.tcp_pose(), model_tcp, atol=1e-4)


@pytest.mark.parametrize("name", ["panda", "kinova_j2s6s200"])
def test_gripper_fingers_move(name):
    """Panda's prismatic fingers and the Jaco2's fingers (fixed in the published URDF) open and close."""
    spec = load_robot_spec(name)
    scene = _scene()
    robot = SimRobot(scene, spec)
    assert robot.gripper_position() == pytest.approx(spec.gripper_open, abs=1e-4)
    robot.set_gripper_target(spec.gripper_closed)
    for _ in range(360):
        scene.step()
    travelled = abs(robot.gripper_position() - spec.gripper_open)
    assert travelled > 0.75 * abs(spec.gripper_closed - spec.gripper_open)
    assert robot.finger_links() and all(link.disable_gravity for link in robot.links)


def test_robot_from_urdf_path_with_custom_tcp(tmp_path):
    """Any URDF given by path, with its arm joints, gripper joints and TCP offset as parameters."""
    panda = load_robot_spec("panda")
    cfg = {
        "name": "my_arm", "urdf": str(panda.urdf_path), "package_dirs": [str(p) for p in panda.package_dirs],
        "root_link": "panda_link0", "arm_joints": list(panda.arm_joints), "gripper_joints": list(panda.gripper_joints),
        "flange_frame": "panda_link8", "tcp_offset_xyz": [0.0, 0.0, 0.2], "home": panda.home.tolist(),
        "gripper_open": 0.04, "gripper_closed": 0.0,
    }
    (tmp_path / "my_arm.yaml").write_text(yaml.safe_dump(cfg))
    spec = load_robot_spec(str(tmp_path / "my_arm.yaml"))
    robot = SimRobot(_scene(), spec)
    flange = next(link for link in robot.links if link.name == "panda_link8").entity_pose.to_transformation_matrix()
    np.testing.assert_allclose(robot.tcp_pose()[:3, 3], flange[:3, 3] + 0.2 * flange[:3, 2], atol=1e-6)
    bad = dict(cfg, gripper_joints=["no_such_joint"])
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump(bad))
    with pytest.raises(ValueError, match="no_such_joint"):
        SimRobot(_scene(), load_robot_spec(str(tmp_path / "bad.yaml")))
