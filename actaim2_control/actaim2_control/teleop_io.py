"""What a teleoperator puts on the graph, for the keyboard ``teleop_node`` and ``scripted_teleop`` alike.

Both produce the same messages, through this one class: ``/episode`` (START / END with the
operator's verdict), ``/interaction_mode`` (the mode label) and the marked keyposes, sent to
``/execute_keypose``. ``control_node`` publishes every keypose it is sent on ``/keypose``
(DESIGN.md), so a recorded bag holds each marked keypose once, stamped when it was marked;
a keypose that failed to execute and was marked again appears twice (the later one counts).

QoS as the other publishers of these topics: ``/episode`` like the episode runner (reliable,
transient local, depth 10: a recorder that starts late still gets the START), and
``/interaction_mode`` like ``policy_node`` (reliable, transient local, depth 1: the mode in use).
"""
from __future__ import annotations

import threading
import time

from actaim2_msgs.action import ExecuteKeypose
from actaim2_msgs.msg import EpisodeEvent, InteractionMode
from actaim2_msgs.msg import Keypose as KeyposeMsg
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from actaim2.keypose import Keypose
from actaim2_ros.action_client import LockedActionClient

EPISODE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
MODE_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
POLL = 0.05  # s between looks at a stop flag while waiting
ACCEPT_TIMEOUT = 10.0  # s for /execute_keypose to accept a goal
ACK_TIMEOUT = 2.0  # s a closing teleoperator waits for subscribers to acknowledge its last events


class TeleopOutput:
    """Publishers and the /execute_keypose client of one teleoperating node (stamps: its clock)."""

    def __init__(self, node: Node, world_frame: str = "world"):
        self._node = node
        self._world = world_frame
        self._episode_pub = node.create_publisher(EpisodeEvent, "/episode", EPISODE_QOS)
        self._mode_pub = node.create_publisher(InteractionMode, "/interaction_mode", MODE_QOS)
        self._execute = LockedActionClient(node, ExecuteKeypose, "/execute_keypose")

    def episode_event(self, episode: int, start: bool, object_id: str, success: bool = False, note: str = "") -> None:
        msg = EpisodeEvent(episode=int(episode), event=EpisodeEvent.START if start else EpisodeEvent.END,
                           object_id=object_id, success=bool(success), note=note)
        msg.header.stamp = self._node.get_clock().now().to_msg()
        msg.header.frame_id = self._world
        self._episode_pub.publish(msg)

    def mode(self, label: str) -> None:
        """The operator's mode label; no cluster (-1) and no embedding: a person chose it."""
        msg = InteractionMode(cluster=-1, label=label)
        msg.header.stamp = self._node.get_clock().now().to_msg()
        msg.header.frame_id = self._world
        self._mode_pub.publish(msg)

    def wait_for_control(self, timeout: float) -> bool:
        return self._execute.wait_for_server(timeout_sec=timeout)

    def execute(self, keypose: Keypose, velocity_scaling: float, timeout: float,
                stop: threading.Event | None = None) -> tuple[bool, str]:
        """Execute a marked keypose (stamped now) and wait for the result; (success, message).
        ``stop`` set while it runs (Ctrl-C) cancels the goal. Call from a thread the node's
        executor does not need (the callbacks answer on it)."""
        msg = KeyposeMsg(phase=int(keypose.phase), gripper_closed=bool(keypose.gripper_closed))
        msg.header.stamp = self._node.get_clock().now().to_msg()
        msg.header.frame_id = self._world
        p, q = msg.pose.position, msg.pose.orientation
        p.x, p.y, p.z = (float(v) for v in keypose.position)
        q.x, q.y, q.z, q.w = (float(v) for v in keypose.quat_xyzw)
        if not self._execute.server_is_ready() and not self._execute.wait_for_server(timeout_sec=min(timeout, 5.0)):
            return False, "/execute_keypose is not available (is control_node running?)"
        sent = self._execute.send_goal_async(ExecuteKeypose.Goal(keypose=msg, velocity_scaling=float(velocity_scaling)))
        handle = _wait(sent, min(timeout, ACCEPT_TIMEOUT), stop)
        if handle is None or not handle.accepted:
            if stop is not None and stop.is_set():
                return False, "interrupted"
            return False, "/execute_keypose did not accept the goal"
        response = _wait(handle.get_result_async(), timeout, stop)
        if response is None:
            _wait(handle.cancel_goal_async(), 2.0)  # the arm is not left moving
            if stop is not None and stop.is_set():
                return False, "interrupted (goal cancelled)"
            return False, f"no result from /execute_keypose within {timeout:g} s (goal cancelled)"
        return bool(response.result.success), response.result.message

    def flush(self) -> None:
        """Wait (bounded) until subscribers have the last /episode events: transient local keeps
        them only while this node lives."""
        self._episode_pub.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT))


def _wait(future, timeout: float, stop: threading.Event | None = None):
    """The future's result, or None when it is not done within ``timeout`` s (or ``stop`` is set)."""
    done = threading.Event()
    future.add_done_callback(lambda _: done.set())
    deadline = time.monotonic() + timeout
    while not done.wait(min(POLL, max(0.0, deadline - time.monotonic()))):
        if time.monotonic() >= deadline or (stop is not None and stop.is_set()):
            return None
    return future.result()
