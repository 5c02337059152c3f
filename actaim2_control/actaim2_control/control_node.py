"""control_node: the /execute_keypose action server (Pinocchio IK + Ruckig trajectories).

A thin adapter over ``actaim2.control``: it checks each goal, publishes the keypose on
/keypose, and lets :class:`KeyposeRunner` plan it (IK with collision checks, straight lines,
time-optimal jerk-limited timing) and execute it through :class:`RosExecutor`
(FollowJointTrajectory or the JTC topic, GripperCommand, /joint_states). Feedback carries the
phase and the progress along the trajectory; the result carries the reached tcp's position
and orientation errors and which candidate ran: a goal's ``alternatives`` (policy_node's
fallback rotations for the same point) are planned in turn when the planner refuses the
keypose, and nothing moves for a refused one.

Malformed goals (NaN, a non-unit quaternion, a frame other than `world`, an unknown phase,
a velocity scaling outside (0, 1]) and goals arriving while another runs are accepted and
immediately aborted with ``success = false`` and a message saying what was wrong: a plain
rejection could not tell the client why. One goal runs at a time; cancel brakes the arm.
"""
from __future__ import annotations

import threading

import numpy as np
from actaim2_msgs.action import ExecuteKeypose
from actaim2_msgs.msg import Keypose as KeyposeMsg
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import PointCloud2

from actaim2.control.collision import CollisionChecker, Workspace
from actaim2.control.executor import KeyposeRunner, Outcome
from actaim2.control.ik import IKOptions, IKSolver
from actaim2.control.model import RobotModel
from actaim2.control.planner import POLICY_PLANNER, KeyposePlanner, PlannerOptions
from actaim2.control.trajectory import Limits
from actaim2.keypose import Keypose
from actaim2.perception.cloud_codec import CloudFormatError
from actaim2.robots import load_robot_spec
from actaim2_control.ros_executor import ExecutionSettings, RosExecutor
from actaim2_ros.keypose import keypose_data
from actaim2_ros.main import spin
from actaim2_ros.params import declare_parameters
from actaim2_ros.pointcloud2 import from_msg
from actaim2_ros.stamps import stamp_ns

KEYPOSE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
_WS = Workspace()
_PLAN = PlannerOptions()

PARAMETERS = {
    # name: (default, description)
    "robot": ("panda", "robot preset (panda, kinova_j2s6s200) or a robot YAML file (any URDF: joints, flange, tcp offset)"),
    "world_frame": ("world", "frame keyposes must be given in (the robot's URDF root is accepted too)"),
    "arm_action": ("/joint_trajectory_controller/follow_joint_trajectory", "FollowJointTrajectory action of the arm controller"),
    "jtc_topic": ("/joint_trajectory_controller/joint_trajectory", "JTC topic used when the arm action server is absent"),
    "gripper_action": ("/gripper_controller/gripper_cmd", "GripperCommand action of the gripper controller"),
    "gripper_max_effort": (0.0, "GripperCommand max_effort (N): the grip force limit on a handle; 0 = the robot's "
                                "default (Panda: 70 N continuous, its hand's datasheet)"),
    "gripper_position_unit": ("gap_width", "what the gripper driver's GripperCommand position means: gap_width (m "
                                           "between the fingers, as the message says; franka_gripper, sim_node) | "
                                           "finger_joint (the finger joint position; ros2_control's "
                                           "gripper_action_controller). Open/closed are converted through the "
                                           "robot's finger geometry (actaim2.gripper)"),
    "velocity_scaling": (0.5, "fraction of the velocity/acceleration/jerk limits for goals with velocity_scaling = 0"),
    "server_wait": (3.0, "s to wait for an action server (arm: then fall back to the JTC topic)"),
    "joint_states_wait": (5.0, "s a goal waits for /joint_states when there are none yet (start-up discovery)"),
    "goal_tolerance": (0.01, "rad: /joint_states this close to the last trajectory point, and still, = the arm got there; "
                       "0 = not checked: the controller's result ends the motion (as the library's executor)"),
    "settle_timeout": (2.0, "s after the controller's result for /joint_states to reach the goal tolerance"),
    "timeout_factor": (3.0, "the controller gets duration * factor + timeout_margin s to finish a trajectory"),
    "timeout_margin": (5.0, "s, see timeout_factor"),
    "gripper_timeout": (8.0, "s for a GripperCommand result"),
    "joint_states_timeout": (1.0, "s: older /joint_states count as missing (the goal fails)"),
    "stopped_velocity": (0.02, "rad/s: below this on every arm joint the arm counts as stopped after a cancel"),
    "table_height": (_WS.table_height, "m, world z of the support plane no link may go below"),
    "workspace_min": (list(_WS.box_min), "m, world: lower corner of the safety box every moving link stays in"),
    "workspace_max": (list(_WS.box_max), "m, world: upper corner of the safety box"),
    "use_cloud": (False, "also avoid the fused cloud (INIT and REACH), except near the grasp point; "
                         "the cloud must be free of robot points (fusion_node remove_robot_fused: true)"),
    "cloud_topic": ("/fused_points", "PointCloud2 in world used when use_cloud is true"),
    "cloud_wait": (5.0, "s (wall) a goal planned around the cloud (INIT, REACH, GRASP) waits for a cloud stamped at or "
                        "after its keypose's stamp (the views it was predicted from); none by then: the goal fails "
                        "saying so. An older cloud may show another scene (before a reset) or the object elsewhere"),
    "cloud_clearance": (_PLAN.cloud_clearance, "m: cloud points this close to the grasp point are not obstacles"),
    "approach_distance": (_PLAN.approach_distance, "m: straight last REACH segment when the arm starts off the approach axis"),
    "via_speed_fraction": (_PLAN.via_speed_fraction, "speed at the pre-grasp via point, fraction of the line's top speed"),
    "sample_period": (_PLAN.sample_period, "s between the trajectory points sent to the controller"),
    "ik_restarts": (IKOptions().restarts, "random IK restarts after the attempt seeded from the current joints"),
    "ik_seed": (0, "seed of the generator the random IK restarts draw from (numpy, created at start): the same goals "
                   "from the same joint states plan the same motions, run after run"),
    "hand_half_turn": (POLICY_PLANNER.hand_half_turn, "a keypose and its half turn about the approach axis are one grasp of a "
                                             "two-finger hand: plan whichever the arm can take (INIT as given first, "
                                             "REACH and MANIPULATE as the hand already is; MANIPULATE never turns)"),
}


class ControlNode(Node):
    def __init__(self) -> None:
        super().__init__("control_node")
        p = declare_parameters(self, PARAMETERS)
        spec = load_robot_spec(p["robot"])
        self._frames = {p["world_frame"], spec.root_link}
        self._default_scaling = float(p["velocity_scaling"])
        self._joint_states_wait = float(p["joint_states_wait"])
        robot = RobotModel(spec)
        workspace = Workspace(float(p["table_height"]), tuple(p["workspace_min"]), tuple(p["workspace_max"]))
        checker = CollisionChecker(robot, workspace)
        solver = IKSolver(robot, checker, IKOptions(restarts=int(p["ik_restarts"])))
        options = PlannerOptions(
            approach_distance=float(p["approach_distance"]),
            via_speed_fraction=float(p["via_speed_fraction"]),
            sample_period=float(p["sample_period"]),
            cloud_clearance=float(p["cloud_clearance"]),
            hand_half_turn=bool(p["hand_half_turn"]),
        )
        self._planner = KeyposePlanner(robot, checker, solver, options)
        group = ReentrantCallbackGroup()
        settings = ExecutionSettings(
            arm_action=p["arm_action"], jtc_topic=p["jtc_topic"], gripper_action=p["gripper_action"],
            gripper_max_effort=float(p["gripper_max_effort"]), gripper_position_unit=str(p["gripper_position_unit"]),
            server_wait=float(p["server_wait"]),
            goal_tolerance=float(p["goal_tolerance"]), settle_timeout=float(p["settle_timeout"]),
            timeout_factor=float(p["timeout_factor"]), timeout_margin=float(p["timeout_margin"]),
            gripper_timeout=float(p["gripper_timeout"]), joint_states_timeout=float(p["joint_states_timeout"]),
            stopped_velocity=float(p["stopped_velocity"]), sample_period=options.sample_period,
        )
        self._executor = RosExecutor(self, spec, Limits.of(robot), settings, group)
        self._runner = KeyposeRunner(self._planner, self._executor, np.random.default_rng(int(p["ik_seed"])))
        self._busy = threading.Lock()
        self._keypose_pub = self.create_publisher(KeyposeMsg, "/keypose", KEYPOSE_QOS)
        self._cloud_topic, self._have_cloud, self._use_cloud = p["cloud_topic"], False, bool(p["use_cloud"])
        self._cloud_wait = float(p["cloud_wait"])
        self._cloud_stamp_ns = -1  # header stamp of the planner's cloud (-1: none yet)
        self._cloud_arrived = threading.Condition()
        if self._use_cloud:
            self.create_subscription(PointCloud2, p["cloud_topic"], self._on_cloud, qos_profile_sensor_data, callback_group=group)
        self._server = ActionServer(
            self, ExecuteKeypose, "/execute_keypose", self._execute,
            goal_callback=lambda _: GoalResponse.ACCEPT, cancel_callback=lambda _: CancelResponse.ACCEPT,
            callback_group=group,
        )
        self.get_logger().info(
            f"{spec.name}: /execute_keypose ready (arm {p['arm_action']}, gripper {p['gripper_action']}, "
            f"default velocity scaling {self._default_scaling:g})"
        )

    def _on_cloud(self, msg: PointCloud2) -> None:
        if msg.header.frame_id not in self._frames:
            self.get_logger().warning(f"cloud in '{msg.header.frame_id}', not world: ignored", throttle_duration_sec=10.0)
            return
        try:
            xyz = from_msg(msg).xyz
        except CloudFormatError as exc:
            self.get_logger().warning(f"unreadable cloud: {exc}", throttle_duration_sec=10.0)
            return
        points = xyz[np.all(np.isfinite(xyz), axis=1)]
        if not self._have_cloud:
            self.get_logger().info(f"obstacle cloud from {self._cloud_topic}: {len(points)} points (kept up to date)")
            self._have_cloud = True
        self._planner.set_cloud(points)
        with self._cloud_arrived:
            self._cloud_stamp_ns = stamp_ns(msg.header.stamp)
            self._cloud_arrived.notify_all()

    def _wait_for_cloud(self, k: KeyposeMsg) -> str:
        """Why the goal cannot be planned: "" once the planner's cloud is stamped at or after the keypose
        (the views it was predicted from; a keypose without a stamp takes any cloud).

        A cloud of 1e5 points can reach this node after the views it was fused with have reached the
        policy and its keypose has come back, on a busy machine: planned around the previous cloud,
        the first INIT of a parity run once met the cabinet sim_node starts with instead of the
        faucet it had been reset to (every IK solution "collides")."""
        if not self._use_cloud or k.phase == KeyposeMsg.PHASE_MANIPULATE:  # the planner's cloud phases
            return ""
        wanted = stamp_ns(k.header.stamp)
        with self._cloud_arrived:
            if self._cloud_arrived.wait_for(lambda: self._cloud_stamp_ns >= wanted, self._cloud_wait):
                return ""
            newest = "none yet" if self._cloud_stamp_ns < 0 else f"the newest is stamped {self._cloud_stamp_ns / 1e9:.3f} s"
        return (f"no obstacle cloud on {self._cloud_topic} stamped at or after the keypose ({wanted / 1e9:.3f} s) within "
                f"{self._cloud_wait:g} s ({newest}): not planned around an older scene")

    def _keyposes(self, goal: ExecuteKeypose.Goal) -> tuple[list[Keypose], str]:
        """The goal's keypose and its alternatives, each converted once, or the reason the goal is
        refused ("" when none). Alternatives are fallbacks for the same step: the keypose's phase."""
        keyposes: list[Keypose] = []
        named = [("keypose", goal.keypose), *((f"alternatives[{i}]", alt) for i, alt in enumerate(goal.alternatives))]
        for name, msg in named:
            if msg.header.frame_id not in self._frames:
                return [], f"{name} frame '{msg.header.frame_id}' is not one of {sorted(self._frames)}"
            try:
                keyposes.append(keypose_data(msg))
            except ValueError as exc:
                return [], f"{name} {exc}"
            if msg.phase != goal.keypose.phase:
                return [], (f"{name} is phase {msg.phase}, the keypose phase {goal.keypose.phase}: "
                            "fallbacks are for the same step")
        if not (np.isfinite(goal.velocity_scaling) and 0.0 <= goal.velocity_scaling <= 1.0):
            return [], f"velocity_scaling {goal.velocity_scaling} is not in (0, 1] (0 = the node's default)"
        return keyposes, ""

    def _execute(self, handle: ServerGoalHandle) -> ExecuteKeypose.Result:
        goal = handle.request
        candidates, problem = self._keyposes(goal)
        if problem:
            return self._finish(handle, Outcome(False, f"rejected: {problem}", float("nan"), float("nan"), "invalid"))
        if not self._busy.acquire(blocking=False):
            return self._finish(handle, Outcome(False, "rejected: busy, another keypose is executing", float("nan"), float("nan"), "busy"))
        try:
            k = goal.keypose
            self._keypose_pub.publish(k)
            scaling = float(goal.velocity_scaling) or self._default_scaling
            stale = self._wait_for_cloud(k)
            if stale:
                return self._finish(handle, Outcome(False, stale, float("nan"), float("nan"), "cloud"))
            self._executor.cancel_requested = lambda: handle.is_cancel_requested
            self._executor.wait_for_joint_states(self._joint_states_wait)  # after start-up discovery takes seconds

            def feedback(phase: int, progress: float) -> None:
                handle.publish_feedback(ExecuteKeypose.Feedback(phase=phase, progress=float(progress)))

            try:
                outcome, candidate = self._runner.run_first(candidates, scaling, feedback)
            except RuntimeError as exc:  # no /joint_states: nothing was moved
                outcome, candidate = Outcome(False, str(exc), float("nan"), float("nan"), "joint_states"), -1
            if candidate > 0:
                self.get_logger().info(f"refused by the planner: {outcome.refused}; executing alternatives[{candidate - 1}]")
            return self._finish(handle, outcome, candidate)
        finally:
            self._executor.cancel_requested = lambda: False
            self._busy.release()

    def _finish(self, handle: ServerGoalHandle, outcome: Outcome, candidate: int = -1) -> ExecuteKeypose.Result:
        result = ExecuteKeypose.Result(
            success=outcome.success, message=outcome.message,
            position_error=outcome.position_error, orientation_error=outcome.orientation_error, candidate=candidate,
        )
        if handle.is_cancel_requested and not outcome.success:
            handle.canceled()
        elif outcome.success:
            handle.succeed()
        else:
            handle.abort()
        text = (f"keypose: {outcome.message} (position error {outcome.position_error * 1000:.1f} mm, "
                f"orientation error {np.degrees(outcome.orientation_error):.2f} deg)")
        if outcome.success:
            self.get_logger().info(text)
        else:
            self.get_logger().warning(text)
        return result


def main(args: list[str] | None = None) -> int:
    return spin(ControlNode, "control_node", args, threads=4)
