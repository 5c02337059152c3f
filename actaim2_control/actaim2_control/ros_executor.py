"""The control node's executor: FollowJointTrajectory (or the JTC topic) and GripperCommand.

Implements :class:`actaim2.control.executor.Executor` over ROS 2 the way a real cell works:
  * arm: a FollowJointTrajectory goal to the controller named by a parameter; when no such
    action server appears within ``server_wait`` the JointTrajectory goes to the JTC topic
    instead (no result there: completion comes from /joint_states alone);
  * completion: the action result, then /joint_states still and within ``goal_tolerance`` of
    the last point, each with a timeout (wall clock, so a dead simulator cannot hang a goal);
    a tolerance of 0 is not checked, as in ros2_control's trajectory controller: the result
    (on the topic, the trajectory's end) completes the motion wherever the object stopped the
    arm, which is what the library's executor and data collection do;
  * cancel: a Ruckig stop from the measured state at full limits replaces the running
    trajectory (the controller's "new goal replaces the running one"), then the arm must be
    still - well within 0.5 s;
  * gripper: a GripperCommand to the open or closed gap, in the driver's position unit
    (gap width or finger joint, :mod:`actaim2.gripper`), with the grip force as
    ``max_effort``; a gripper stalled on an object counts as success.
Waiting happens in the action server's execute thread; subscriptions and action-client
responses are handled by the node's other executor threads.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
from control_msgs.action import FollowJointTrajectory, GripperCommand
from rclpy.callback_groups import CallbackGroup
from rclpy.node import Node
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory as JointTrajectoryMsg
from trajectory_msgs.msg import JointTrajectoryPoint

from actaim2.control.executor import StepResult
from actaim2.control.trajectory import JointPlanner, JointTrajectory, Limits, State, sample
from actaim2.gripper import gripper_geometry
from actaim2.robots import RobotSpec
from actaim2_ros.action_client import LockedActionClient
from actaim2_ros.stamps import duration_msg, stamp_seconds

POLL = 0.01  # s between checks while waiting
FEEDBACK_PERIOD = 0.1  # s between progress reports while the arm moves


@dataclass(frozen=True)
class ExecutionSettings:
    arm_action: str
    jtc_topic: str
    gripper_action: str
    gripper_max_effort: float  # N; 0 = the robot's default grip force
    gripper_position_unit: str  # actaim2.gripper.POSITION_UNITS
    server_wait: float  # s to wait for an action server before giving up (arm: before the topic fallback)
    goal_tolerance: float  # rad: /joint_states this close to the last point (and still) = reached; 0: not checked
    settle_timeout: float  # s after the controller's result (or the trajectory's end) to get there
    timeout_factor: float  # the controller gets duration * factor + margin to report a result
    timeout_margin: float
    gripper_timeout: float
    joint_states_timeout: float  # s: /joint_states older than this count as missing
    stopped_velocity: float  # rad/s: every arm joint slower than this = the arm stands still
    sample_period: float


class RosExecutor:
    """Arm and gripper of one robot through ROS 2 controllers, for :class:`KeyposeRunner`."""

    def __init__(self, node: Node, spec: RobotSpec, limits: Limits, settings: ExecutionSettings, group: CallbackGroup):
        self._node = node
        self._spec = spec
        self._full_limits = limits
        self._settings = settings
        self._gripper_geometry = gripper_geometry(spec)
        self._gripper_geometry.to_unit(0.0, settings.gripper_position_unit)  # refuses an unknown unit at start-up
        self._arm = LockedActionClient(node, FollowJointTrajectory, settings.arm_action, callback_group=group)
        self._gripper = LockedActionClient(node, GripperCommand, settings.gripper_action, callback_group=group)
        self._topic = node.create_publisher(JointTrajectoryMsg, settings.jtc_topic, 10)
        node.create_subscription(JointState, "/joint_states", self._on_joint_states, 10, callback_group=group)
        self._stopper = JointPlanner(len(spec.arm_joints))
        self._lock = threading.Lock()
        self._positions: dict[str, float] = {}
        self._velocities: dict[str, float] = {}
        self._received = -np.inf
        self._stamp = float("nan")  # s (sim): header stamp of the newest /joint_states
        self.cancel_requested: Callable[[], bool] = lambda: False

    # -- state ----------------------------------------------------------------------------
    def _on_joint_states(self, msg: JointState) -> None:
        with self._lock:
            self._positions.update(zip(msg.name, msg.position))
            if len(msg.velocity) == len(msg.name):
                self._velocities.update(zip(msg.name, msg.velocity))
            self._received = time.monotonic()
            self._stamp = stamp_seconds(msg.header.stamp)

    def wait_for_joint_states(self, timeout: float) -> bool:
        return _wait(lambda: self._fresh_arm_state() is not None, timeout)

    def _fresh_arm_state(self) -> State | None:
        with self._lock:
            if time.monotonic() - self._received > self._settings.joint_states_timeout:
                return None
            if any(j not in self._positions for j in self._spec.arm_joints):
                return None
            q = np.array([self._positions[j] for j in self._spec.arm_joints])
            v = np.array([self._velocities.get(j, 0.0) for j in self._spec.arm_joints])
        return State(q, v, np.zeros_like(q))

    def arm_state(self) -> State:
        """The latest arm state; a stale one waits up to ``joint_states_timeout`` for the next
        message (on a busy machine delivery can pause), then the goal fails."""
        state = self._fresh_arm_state()
        if state is None and self.wait_for_joint_states(self._settings.joint_states_timeout):
            state = self._fresh_arm_state()
        if state is None:
            raise RuntimeError(
                f"no fresh /joint_states with the arm joints {list(self._spec.arm_joints)} "
                f"(none within {self._settings.joint_states_timeout:g} s)"
            )
        return state

    # -- arm ------------------------------------------------------------------------------
    def follow(self, trajectory: JointTrajectory, on_progress: Callable[[float], None]) -> StepResult:
        s = self._settings
        msg = _trajectory_msg(trajectory)
        use_action = self._arm.server_is_ready() or self._arm.wait_for_server(timeout_sec=s.server_wait)
        if use_action:
            goal = FollowJointTrajectory.Goal(trajectory=msg)
            sent = self._arm.send_goal_async(goal)
            if not _wait(sent.done, s.server_wait) or not sent.result().accepted:
                return StepResult(False, f"{s.arm_action} did not accept the trajectory")
            handle = sent.result()
            result_future = handle.get_result_async()
            done = result_future.done
        else:
            self._node.get_logger().warning(
                f"no action server {s.arm_action} within {s.server_wait:g} s: sending to the JTC topic {s.jtc_topic}",
                throttle_duration_sec=30.0,
            )
            self._topic.publish(msg)
            end_of_motion = time.monotonic() + trajectory.duration
            done = lambda: time.monotonic() >= end_of_motion  # noqa: E731 (no result on the topic)
        start = reported = time.monotonic()
        deadline = start + trajectory.duration * s.timeout_factor + s.timeout_margin
        while not done():
            if self.cancel_requested():
                return self._stop()
            now = time.monotonic()
            if now > deadline:
                self._stop()
                return StepResult(False, f"no result from {s.arm_action} within {deadline - start:.1f} s")
            if now - reported >= FEEDBACK_PERIOD:
                on_progress(min(1.0, (now - start) / max(trajectory.duration, 1e-6)))
                reported = now
            time.sleep(POLL)
        if use_action:
            result = result_future.result().result
            if result.error_code != FollowJointTrajectory.Result.SUCCESSFUL:
                return StepResult(False, f"controller error {result.error_code}: {result.error_string}")
        return self._settled(trajectory.positions[-1])

    def _settled(self, goal: np.ndarray) -> StepResult:
        """/joint_states still and within tolerance of the goal before the settle timeout (tolerance 0: not checked)."""
        s = self._settings
        if s.goal_tolerance <= 0:
            return StepResult(True, "trajectory ended (goal tolerance 0: not checked)")

        def there() -> bool:
            state = self.arm_state()
            return bool(np.max(np.abs(state.position - goal)) <= s.goal_tolerance
                        and np.max(np.abs(state.velocity)) < s.stopped_velocity)

        if _wait(there, s.settle_timeout):
            return StepResult(True, "reached")
        state = self.arm_state()
        return StepResult(False, f"arm not settled at the goal: {np.max(np.abs(state.position - goal)):.4f} rad away "
                                 f"(tolerance {s.goal_tolerance:g}), moving at {np.max(np.abs(state.velocity)):.3f} rad/s")

    def send(self, trajectory: JointTrajectory) -> None:
        """Start ``trajectory`` now without waiting for it (a stop, a teleop jog): the controller
        replaces the running one with it."""
        msg = _trajectory_msg(trajectory)
        if self._arm.server_is_ready():
            self._arm.send_goal_async(FollowJointTrajectory.Goal(trajectory=msg))
        else:
            self._topic.publish(msg)

    def _stop(self) -> StepResult:
        """Brake to a standstill within the full limits, replacing the running trajectory.

        The message names the sim-time stamp of the state the brake starts from, so that a client
        can time the stop from the moment this node acted, whatever its own delivery delays.
        """
        s = self._settings
        with self._lock:  # read before the state: the stamp is never newer than the state braked from
            braked_from = self._stamp
        state = self.arm_state()
        stop = sample([self._stopper.stop(state, self._full_limits)], self._spec.arm_joints, s.sample_period)
        self.send(stop if len(stop) else _hold(self._spec, state.position))
        still = _wait(lambda: np.all(np.abs(self.arm_state().velocity) < s.stopped_velocity), stop.duration + s.settle_timeout)
        outcome = "arm stopped" if still else "the arm did not come to rest"
        return StepResult(False, f"cancelled: {outcome} (braking from /joint_states stamped {braked_from:.4f} s)")

    # -- gripper --------------------------------------------------------------------------
    def set_gripper(self, closed: bool) -> StepResult:
        s = self._settings
        if not (self._gripper.server_is_ready() or self._gripper.wait_for_server(timeout_sec=s.server_wait)):
            return StepResult(False, f"no GripperCommand action server {s.gripper_action}")
        goal = GripperCommand.Goal()
        geometry = self._gripper_geometry
        gap = geometry.gap_from_joint(self._spec.gripper_closed if closed else self._spec.gripper_open)
        goal.command.position = geometry.to_unit(gap, s.gripper_position_unit)
        goal.command.max_effort = float(s.gripper_max_effort or geometry.default_force)
        sent = self._gripper.send_goal_async(goal)
        if not _wait(sent.done, s.server_wait) or not sent.result().accepted:
            return StepResult(False, f"{s.gripper_action} did not accept the command")
        result_future = sent.result().get_result_async()
        if not _wait(result_future.done, s.gripper_timeout):
            sent.result().cancel_goal_async()
            return StepResult(False, f"no gripper result within {s.gripper_timeout:g} s")
        result = result_future.result().result
        word = "closed" if closed else "opened"
        if result.reached_goal:
            return StepResult(True, f"gripper {word}")
        if result.stalled:
            return StepResult(True, f"gripper {word}, stalled at {result.position:.4f} (holding an object)")
        return StepResult(False, f"gripper neither reached {goal.command.position:g} nor stalled (at {result.position:.4f})")


def _trajectory_msg(trajectory: JointTrajectory) -> JointTrajectoryMsg:
    """A JointTrajectory message; a zero header stamp means "start now"."""
    msg = JointTrajectoryMsg(joint_names=list(trajectory.joint_names))
    for t, q, v, a in zip(trajectory.times, trajectory.positions, trajectory.velocities, trajectory.accelerations):
        msg.points.append(
            JointTrajectoryPoint(
                positions=q.tolist(), velocities=v.tolist(), accelerations=a.tolist(),
                time_from_start=duration_msg(t),
            )
        )
    return msg


def _hold(spec: RobotSpec, position: np.ndarray) -> JointTrajectory:
    """One point at the current position, shortly from now: the controller holds there."""
    n = len(position)
    return JointTrajectory(spec.arm_joints, np.array([0.05]), position[None], np.zeros((1, n)), np.zeros((1, n)))


def _wait(predicate: Callable[[], bool], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(POLL)
    return bool(predicate())
