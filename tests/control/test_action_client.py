"""LockedActionClient keeps the answer to a goal that arrives before rclpy has registered the request
(ros2/rclpy#1123): widened here to 0.3 s, the plain ActionClient loses it, the locked one does not."""
from __future__ import annotations

import time

import pytest
from control_msgs.action import GripperCommand
from rclpy.action import ActionClient, ActionServer
from rclpy.node import Node

from actaim2_ros.action_client import LockedActionClient
from actaim2_ros.main import BackgroundSpinner
from harness import wait_for


class SlowRegistration:
    """The client's rcl handle, sending as before, then pausing before rclpy registers the request:
    the window in which an executor thread takes the server's answer."""

    def __init__(self, handle) -> None:
        self._handle = handle

    def send_goal_request(self, request):
        sequence_number = self._handle.send_goal_request(request)
        time.sleep(0.3)
        return sequence_number

    def __getattr__(self, name):
        return getattr(self._handle, name)


@pytest.fixture
def server_and_client_node(ros_context):
    server_node, client_node = Node("gripper_server"), Node("gripper_client")

    def execute(handle):
        handle.succeed()
        return GripperCommand.Result(reached_goal=True)

    ActionServer(server_node, GripperCommand, "/race_test/gripper_cmd", execute)
    spinner = BackgroundSpinner(server_node, client_node)
    yield client_node
    spinner.stop()
    spinner.executor.shutdown()
    server_node.destroy_node()
    client_node.destroy_node()


@pytest.mark.parametrize("client_class, answered", [(ActionClient, False), (LockedActionClient, True)])
def test_an_early_goal_answer_is_kept(server_and_client_node, client_class, answered):
    client = client_class(server_and_client_node, GripperCommand, "/race_test/gripper_cmd")
    assert client.wait_for_server(timeout_sec=10.0)
    client._client_handle = SlowRegistration(client._client_handle)
    future = client.send_goal_async(GripperCommand.Goal())
    assert wait_for(future.done, 3.0) == answered
    if answered:
        assert future.result().accepted
