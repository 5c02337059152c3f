"""Ctrl-C ends sim_node promptly and cleanly in every state, answering the goals it was running.

Each case starts its own node (they serve the same names), connects action clients, puts the
node in a state, sends SIGINT to its process group as a terminal would, and requires exit code
0 within EXIT_WITHIN seconds.
"""
from __future__ import annotations

import os
import signal
import subprocess
import time

import pytest
from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory, GripperCommand
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from actaim2.robots import load_robot_spec
from actaim2_ros.action_client import LockedActionClient
from harness import wait_for

SPEC = load_robot_spec("panda")
# a gripper goal blocked by its limit ends stalled after gripper_stall_timeout: make that long
PARAMS = dict(rig="azure_kinect", render_path="raycast", camera_rate=0.0, gripper_stall_timeout=30.0)
EXIT_WITHIN = 3.0  # s


def slow_trajectory() -> FollowJointTrajectory.Goal:
    """Home -> a pose 30 s away: certainly running when the signal comes."""
    goal = FollowJointTrajectory.Goal()
    goal.trajectory = JointTrajectory(joint_names=list(SPEC.arm_joints))
    target = [q + 0.3 for q in SPEC.home]
    goal.trajectory.points.append(JointTrajectoryPoint(positions=target, time_from_start=Duration(sec=30)))
    return goal


def gripper_beyond_its_limit() -> GripperCommand.Goal:
    """Closing past the limit: the fingers stop there, the goal runs for a whole stall window."""
    goal = GripperCommand.Goal()
    goal.command.position = SPEC.gripper_closed - 0.5 * (SPEC.gripper_open - SPEC.gripper_closed)
    return goal


def accepted(client: LockedActionClient, goal, feedback=None):
    sent = client.send_goal_async(goal, feedback_callback=feedback)
    assert wait_for(sent.done, 30.0) and sent.result().accepted
    return sent.result().get_result_async()


def interrupt(node) -> float:
    """SIGINT the node's process group; seconds until it exited (asserting exit code 0)."""
    sent = time.monotonic()
    os.killpg(node.proc.pid, signal.SIGINT)
    try:
        code = node.proc.wait(timeout=EXIT_WITHIN)
    except subprocess.TimeoutExpired:
        pytest.fail(f"sim_node still running {EXIT_WITHIN} s after SIGINT:\n{node.output()[-3000:]}")
    assert code == 0, node.output()[-3000:]
    output = node.output()
    assert "Traceback" not in output and "never retrieved" not in output, output[-3000:]
    return time.monotonic() - sent


@pytest.mark.parametrize("state", ["idle", "trajectory_and_gripper_goals", "goal_in_flight"])
def test_sigint_ends_the_node_promptly(start_node, ros_node, state):
    node = start_node("actaim2_sim", "sim_node", PARAMS)
    arm = LockedActionClient(ros_node, FollowJointTrajectory, "/joint_trajectory_controller/follow_joint_trajectory")
    gripper = LockedActionClient(ros_node, GripperCommand, "/gripper_controller/gripper_cmd")
    assert arm.wait_for_server(timeout_sec=60.0) and gripper.wait_for_server(timeout_sec=60.0), node.output()
    if state == "idle":
        interrupt(node)
    elif state == "trajectory_and_gripper_goals":
        feedback = []
        trajectory_result = accepted(arm, slow_trajectory(), feedback.append)
        gripper_result = accepted(gripper, gripper_beyond_its_limit())
        assert wait_for(lambda: len(feedback) >= 2, 30.0), "the trajectory never got under way"
        interrupt(node)
        # the clients were answered before the server went away
        assert wait_for(trajectory_result.done, 1.0) and wait_for(gripper_result.done, 1.0)
        assert trajectory_result.result().status == GoalStatus.STATUS_ABORTED
        assert "shutting down" in trajectory_result.result().result.error_string
        assert gripper_result.result().status == GoalStatus.STATUS_ABORTED
    else:  # the goal request is on its way when the signal arrives: it must not keep the node alive
        arm.send_goal_async(slow_trajectory())
        interrupt(node)
