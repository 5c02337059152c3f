"""teleop_node: record demonstrations from a terminal keyboard (the paper's teleoperated fine-tuning data).

A thin adapter over :class:`actaim2.control.teleop.TeleopSession` (the key map, the jogged
target, the rules of marking): it reads single keys from the terminal it runs in, prints the
key map at start, and carries out each key's effect:
  * jog: the target's IK solution (checked by control_node's IK and collision checks) goes to
    the arm controller as a one-point trajectory timed for the speed bound (FollowJointTrajectory,
    or the JTC topic when the action is absent: a new one replaces the running one);
  * gripper: a GripperCommand, open or closed, as control_node sends it;
  * mark INIT / REACH / GRASP / MANIPULATE: the target (gripper open for INIT and REACH, closed
    for GRASP and MANIPULATE) goes to /execute_keypose; control_node executes it and publishes
    it on /keypose; the target then follows the arm to where it really stopped;
  * mode label and episode START / END (the operator's verdict): /interaction_mode, /episode.
Keys typed while a keypose executes are discarded. Ctrl-C cancels a running keypose and ends an
open episode as a failure. Run it in a terminal (``ros2 run actaim2_control teleop_node``)
beside control_node and the robot (or sim_node), and record with bag_recorder.
"""
from __future__ import annotations

import sys
import threading
import time

import numpy as np
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node

from actaim2.control.collision import CollisionChecker, Workspace
from actaim2.control.ik import IKOptions, IKSolver
from actaim2.control.model import RobotModel
from actaim2.control.teleop import (
    AskLabel,
    End,
    Gripper,
    Jog,
    JogSettings,
    Label,
    Mark,
    Message,
    Quit,
    Start,
    TeleopSession,
    format_pose,
)
from actaim2.control.trajectory import JointTrajectory, Limits
from actaim2.keypose import PHASE_NAMES
from actaim2.robots import load_robot_spec
from actaim2_control.ros_executor import ExecutionSettings, RosExecutor
from actaim2_control.teleop_io import TeleopOutput
from actaim2_control.terminal import KeyboardTerminal, NotATerminal
from actaim2_ros.main import run_client
from actaim2_ros.params import declare_parameters

_WS, _JOG = Workspace(), JogSettings()
KEY_POLL = 0.1  # s: the longest the key loop waits before it looks at its stop flag

PARAMETERS = {
    # name: (default, description)
    "robot": ("panda", "robot preset (panda, kinova_j2s6s200) or a robot YAML file: the same as control_node's"),
    "world_frame": ("world", "frame of the marked keyposes and of the events' headers"),
    "arm_action": ("/joint_trajectory_controller/follow_joint_trajectory", "FollowJointTrajectory action the jogs go to"),
    "jtc_topic": ("/joint_trajectory_controller/joint_trajectory", "JTC topic used when the arm action server is absent"),
    "gripper_action": ("/gripper_controller/gripper_cmd", "GripperCommand action of the gripper controller"),
    "gripper_max_effort": (0.0, "GripperCommand max_effort (N); 0 = the robot's default grip force"),
    "gripper_position_unit": ("gap_width", "what the gripper driver's GripperCommand position means: gap_width | "
                                           "finger_joint (as control_node's parameter)"),
    "gripper_timeout": (8.0, "s for a GripperCommand result"),
    "server_wait": (3.0, "s to wait for an action server (arm: then jogs go to the JTC topic)"),
    "joint_states_wait": (30.0, "s to wait at start for /joint_states with the arm joints (the target starts there)"),
    "joint_states_timeout": (1.0, "s: older /joint_states count as missing"),
    "table_height": (_WS.table_height, "m, world z of the support plane: jog targets whose arm would go below are refused"),
    "workspace_min": (list(_WS.box_min), "m, world: lower corner of the safety box (as control_node's)"),
    "workspace_max": (list(_WS.box_max), "m, world: upper corner of the safety box"),
    "translation_step": (_JOG.translation_step, "m the target moves per key press ([ and ] halve and double it)"),
    "rotation_step": (float(np.degrees(_JOG.rotation_step)), "deg the target turns per key press"),
    "max_speed": (_JOG.max_speed, "m/s: the target never moves faster (keys arriving sooner are dropped)"),
    "max_angular_speed": (float(np.degrees(_JOG.max_angular_speed)), "deg/s: the target never turns faster"),
    "joint_speed_fraction": (_JOG.joint_speed_fraction, "jogs move each joint at most this fraction of its velocity limit"),
    "max_joint_step": (_JOG.max_joint_step, "rad: a jog whose IK solution is farther from the last one (another arm "
                                            "configuration) is refused"),
    "velocity_scaling": (0.0, "ExecuteKeypose velocity_scaling of marked keyposes; 0 = control_node's default"),
    "goal_timeout": (120.0, "s (wall) for one marked keypose to execute; then it is cancelled"),
    "object_id": ("", "EpisodeEvent object_id: what the demonstrations manipulate (e.g. three_drawer_shelf)"),
    "first_episode": (0, "number of the first episode (EpisodeEvent.episode); the next ones count up"),
}


class TeleopNode(Node):
    def __init__(self) -> None:
        super().__init__("teleop_node")
        self.p = p = declare_parameters(self, PARAMETERS)
        self.spec = load_robot_spec(p["robot"])
        robot = RobotModel(self.spec)
        checker = CollisionChecker(robot, Workspace(float(p["table_height"]), tuple(p["workspace_min"]), tuple(p["workspace_max"])))
        # control_node's solver and checks, seeded from the last target's joints without random
        # restarts: a restart's answer is another arm configuration, never a small jog
        solver = IKSolver(robot, checker, IKOptions(restarts=0))
        settings = JogSettings(
            translation_step=float(p["translation_step"]), rotation_step=float(np.radians(p["rotation_step"])),
            max_speed=float(p["max_speed"]), max_angular_speed=float(np.radians(p["max_angular_speed"])),
            joint_speed_fraction=float(p["joint_speed_fraction"]), max_joint_step=float(p["max_joint_step"]),
        )
        self.session = TeleopSession(solver.solve, robot.fk, self.spec.max_velocity, settings, int(p["first_episode"]))
        self.arm = RosExecutor(self, self.spec, Limits.of(robot), ExecutionSettings(
            arm_action=p["arm_action"], jtc_topic=p["jtc_topic"], gripper_action=p["gripper_action"],
            gripper_max_effort=float(p["gripper_max_effort"]), gripper_position_unit=str(p["gripper_position_unit"]),
            server_wait=float(p["server_wait"]), goal_tolerance=0.01, settle_timeout=2.0, timeout_factor=3.0,
            timeout_margin=5.0, gripper_timeout=float(p["gripper_timeout"]),
            joint_states_timeout=float(p["joint_states_timeout"]), stopped_velocity=0.02, sample_period=0.02,
        ), ReentrantCallbackGroup())
        self.out = TeleopOutput(self, p["world_frame"])

    # -- the key loop (main thread) ------------------------------------------------------------
    def run(self, keys: KeyboardTerminal, stop: threading.Event) -> int:
        keys.write(f"teleop_node ({self.spec.name}): waiting for /joint_states ...")
        if not self.arm.wait_for_joint_states(float(self.p["joint_states_wait"])):
            keys.write(f"no /joint_states with the arm joints {list(self.spec.arm_joints)} within "
                       f"{self.p['joint_states_wait']:g} s: is the robot (or sim_node) running?")
            return 1
        self.session.sync(self.arm.arm_state().position)
        keys.write(self.session.keymap())
        keys.write(f"target: {format_pose(self.session.target)}")
        if not self.out.wait_for_control(float(self.p["server_wait"])):
            keys.write("no /execute_keypose yet: marking keyposes needs control_node")
        while not stop.is_set():
            key = keys.read_key(KEY_POLL)
            if key is None:
                continue
            effect = self.session.press(key, time.monotonic())
            if effect is not None and self._apply(effect, keys, stop):
                break
        if stop.is_set() and self.session.episode is not None:  # Ctrl-C
            self._apply(self.session.press("q", time.monotonic()), keys, stop)
        self.out.flush()
        return 0

    def _apply(self, effect, keys: KeyboardTerminal, stop: threading.Event) -> bool:
        """Carry out one effect; True when the operator quits."""
        object_id = str(self.p["object_id"])
        if isinstance(effect, Jog):
            n = len(self.spec.arm_joints)
            self.arm.send(JointTrajectory(tuple(self.spec.arm_joints), np.array([effect.duration]), effect.joints[None],
                                          np.zeros((1, n)), np.zeros((1, n))))
            keys.write(f"target: {format_pose(effect.T)}" + (f"  ({effect.note})" if effect.note else ""))
        elif isinstance(effect, Gripper):
            keys.write(self.arm.set_gripper(effect.closed).message)
        elif isinstance(effect, Mark):
            k = effect.keypose
            name = PHASE_NAMES[k.phase]
            keys.write(f"{name} (gripper {'closed' if k.gripper_closed else 'open'}): executing ...")
            ok, message = self.out.execute(k, float(self.p["velocity_scaling"]), float(self.p["goal_timeout"]), stop)
            self.session.marked(k, ok)
            try:
                self.session.sync(self.arm.arm_state().position)
                synced = ""
            except RuntimeError as exc:  # no fresh joint states: the target stays the marked one
                synced = str(exc)
            # Discard before saying so: the operator reads "executed" as "keys count again", so a key
            # typed once it shows must not be thrown away with those typed while the arm moved.
            dropped = keys.discard_typed()
            keys.write(f"{name} {'executed' if ok else 'FAILED (mark it again)'}: {message}")
            if synced:
                keys.write(synced)
            if dropped:
                keys.write(f"({dropped} keys typed while the arm moved were discarded)")
        elif isinstance(effect, Label):
            self.out.mode(effect.label)
            keys.write(f"mode label '{effect.label}' published")
        elif isinstance(effect, Start):
            self.out.episode_event(effect.episode, True, object_id, note="keyboard teleop")
            if effect.label:
                self.out.mode(effect.label)
            keys.write(f"episode {effect.episode} started (mode label: {effect.label or 'none yet, m sets it'})")
        elif isinstance(effect, End):
            self.out.episode_event(effect.episode, False, object_id, effect.success, effect.note)
            keys.write(f"episode {effect.episode} ended: {'SUCCESS' if effect.success else 'failure'} ({effect.note})")
        elif isinstance(effect, AskLabel):
            text = keys.read_line("mode label (1 push, 2 pull, 3 open, 4 close, or any text), then Enter: ")
            return self._apply(self.session.set_label(text), keys, stop)
        elif isinstance(effect, Message):
            keys.write(effect.text)
        elif isinstance(effect, Quit):
            if effect.end is not None:
                self._apply(effect.end, keys, stop)
            keys.write("bye")
            return True
        return False


def at_terminal(node: TeleopNode, stop: threading.Event) -> int:
    """The key loop on this process's terminal: its exit code, 2 without a terminal, 1 at end of input."""
    try:
        with KeyboardTerminal(sys.stdin, sys.stdout) as keys:
            return node.run(keys, stop)
    except NotATerminal as exc:
        node.get_logger().error(str(exc))
        return 2
    except EOFError as exc:
        node.get_logger().error(str(exc))
        return 1


def main(args: list[str] | None = None) -> int:
    # SIGINT / SIGTERM only set stop: Ctrl-C must cancel a running keypose and end the episode first.
    return run_client(lambda _stop: TeleopNode(), at_terminal, "teleop_node", args)


if __name__ == "__main__":
    raise SystemExit(main())
