"""control_node speaks each gripper driver's position unit: with ``gripper_position_unit:
finger_joint`` on both sides (a ros2_control gripper_action_controller takes joint positions),
the open and closed keyposes still open and close the fingers fully. On the Jaco2 the two units
differ everywhere (gap 0.122 m open is joint 0 rad; closed, 0.009 m is 1.3 rad), so a position
sent in the wrong unit shows. The default (gap width, as GripperCommand says and franka_gripper
takes it) is exercised by test_control_node."""
from __future__ import annotations

import numpy as np

from actaim2.control.model import RobotModel
from actaim2.geometry import matrix_to_pose
from actaim2.robots import load_robot_spec
from harness import wait_for
from test_control_node import KeyposeClient, Recorder

ROBOT = "kinova_j2s6s200"
SPEC = load_robot_spec(ROBOT)
SIM = {"robot": ROBOT, "camera_rate": 0.0, "render_path": "raycast", "category": "switch", "instance": 0,
       "gripper_position_unit": "finger_joint"}


def test_finger_joint_unit_opens_and_closes_the_fingers(start_node, ros_node):
    from action_msgs.msg import GoalStatus

    start_node("actaim2_sim", "sim_node", SIM)
    control = start_node("actaim2_control", "control_node", {"robot": ROBOT, "gripper_position_unit": "finger_joint"})
    recorder, client = Recorder(ros_node), KeyposeClient(ros_node)
    assert client.client.wait_for_server(timeout_sec=30.0), control.output()
    assert wait_for(lambda: len(recorder.joints) > 5, 30.0), "no /joint_states from the sim"
    position, quat = matrix_to_pose(RobotModel(SPEC).fk(SPEC.home))  # where the hand is: only the fingers move

    def fingers() -> np.ndarray:
        with recorder.lock:
            positions = recorder.joints[-1][1]
        return np.array([positions[j] for j in SPEC.gripper_joints])

    for closed, expected in ((True, SPEC.gripper_closed), (False, SPEC.gripper_open)):
        status, result = client.execute(client.goal(2 if closed else 0, position, quat, closed))
        assert status == GoalStatus.STATUS_SUCCEEDED and result.success, result.message
        assert wait_for(lambda: np.allclose(fingers(), expected, atol=0.03), 5.0), (closed, fingers())
