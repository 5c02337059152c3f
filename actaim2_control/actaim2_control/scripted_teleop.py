"""scripted_teleop: the scripted teleoperator in simulation, producing what teleop_node produces.

Per episode, through the node graph like a person at teleop_node: /reset_scene, START on
/episode, the mode label on /interaction_mode, the four keyposes to /execute_keypose
(control_node executes them and publishes each on /keypose), then END with the verdict. The
keyposes come from :class:`actaim2.rollout.scripted_teleop.ScriptedTeleoperator` (the scripted
expert with privileged state, grasp point randomised along the handle), planned on a mirror
SimEnv in this process loaded with the same scene (same category, instance and seed: the same
placement) and set to the DoF state the simulator reports after its reset. The verdict is the
privileged /object_state: the part moved the asked way by more than 30 % of its range.

It records demonstrations for fine-tuning with bag_recorder beside it (``split_by_episode``)
and drives the arm while the golden bags are recorded (scripts/record_golden_bags.sh).
Ctrl-C cancels a running keypose, ends the episode as a failure and exits with code 130.
"""
from __future__ import annotations

import threading
import time
from typing import Callable

import numpy as np
from actaim2_msgs.srv import ResetScene
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from actaim2.keypose import PHASE_NAMES
from actaim2.rollout.expert import PlanningError
from actaim2.rollout.scripted_teleop import ScriptedTeleoperator, judged_success, task_for_label
from actaim2.sim.env import SimEnv
from actaim2_control.teleop_io import TeleopOutput
from actaim2_ros.main import run_client
from actaim2_ros.params import declare_parameters
from actaim2_ros.stamps import stamp_ns

INTERRUPTED = 130  # exit code after Ctrl-C, as a shell reports a SIGINT-ended command
POLL = 0.05  # s (wall)

PARAMETERS = {
    "robot": ("panda", "robot preset or YAML file: the simulator's (the mirror scene loads it too)"),
    "episodes": (2, "number of episodes, then exit"),
    "category": ("three_drawer_shelf", "object category passed to /reset_scene"),
    "instance": (0, "object instance (>= 0: the mirror scene loads the same one)"),
    "seed": (0, "placement seed of episode 0; episode k uses seed + k (grasp point too)"),
    "dof_fraction": (0.5, "initial state of the manipulated part (of every part when others_fraction < 0), as a "
                          "fraction of its range"),
    "others_fraction": (-1.0, "initial state of the parts not manipulated; < 0: dof_fraction too (0 with "
                              "dof_fraction 0.5: the paper's one drawer half-open, the others closed)"),
    "modes": (["pull", "push"], "mode labels, episode k uses modes[k mod n]: pull/push (drawers), open/close (hinged parts)"),
    "joints": ([""], "movable parts to manipulate, episode k uses joints[k mod n]; \"\" = a random part with a handle"),
    "grasp_spread": (1.0, "grasp point along the handle: 0 = its centre, 1 = anywhere up to 3 cm from its ends"),
    "pitch": (20.0, "deg: the hand approaches pitched down by this much about the handle's axis"),
    "velocity_scaling": (0.5, "ExecuteKeypose velocity_scaling (0, 1]"),
    "server_timeout": (60.0, "s (wall) to wait for /reset_scene and /execute_keypose"),
    "reset_timeout": (60.0, "s (wall) for the /reset_scene answer"),
    "goal_timeout": (120.0, "s (wall) for one keypose to execute; then it is cancelled"),
    "settle_time": (1.0, "s (sim) after the last keypose before the object state is judged"),
    "first_episode": (0, "number of the first episode (EpisodeEvent.episode)"),
}


class EpisodeFailure(Exception):
    """The episode cannot go on; its END carries the message."""


class ScriptedTeleop(Node):
    def __init__(self, stop: threading.Event) -> None:
        # Object-state stamps are sim time: the verdict's settle time is measured on it.
        super().__init__("scripted_teleop", parameter_overrides=[Parameter("use_sim_time", value=True)])
        self.p = p = declare_parameters(self, PARAMETERS)
        if int(p["instance"]) < 0:
            raise ValueError("instance must be >= 0: the mirror scene must load the simulator's object")
        if not p["modes"] or not p["joints"]:
            raise ValueError("modes and joints need at least one entry each")
        self.stop = stop
        self._started, self._object_id = False, ""  # of the episode running
        self.out = TeleopOutput(self)
        self._reset = self.create_client(ResetScene, "/reset_scene")
        self._lock = threading.Lock()
        self._object_state: JointState | None = None
        self.create_subscription(JointState, "/object_state", self._on_object_state, 10)
        self.mirror = SimEnv(p["robot"], cameras=None)
        self.teleoperator = ScriptedTeleoperator(self.mirror, float(p["grasp_spread"]), float(np.radians(p["pitch"])),
                                                 seed=int(p["seed"]))

    def _on_object_state(self, msg: JointState) -> None:
        with self._lock:
            self._object_state = msg

    def _wait(self, ready: Callable[[], object], timeout: float, what: str):
        """``ready()``'s first non-None value within ``timeout`` s (wall); else EpisodeFailure."""
        deadline = time.monotonic() + timeout
        while not self.stop.is_set():
            value = ready()
            if value is not None:
                return value
            if time.monotonic() > deadline:
                raise EpisodeFailure(f"{what} within {timeout:g} s")
            self.stop.wait(POLL)
        raise EpisodeFailure("interrupted (Ctrl-C)")

    def _state_after(self, after_ns: int) -> JointState | None:
        with self._lock:
            msg = self._object_state
        return msg if msg is not None and stamp_ns(msg.header.stamp) >= after_ns else None

    def run(self) -> tuple[int, int]:
        """Every episode; returns (successes, episodes run)."""
        p = self.p
        self._wait(lambda: self._reset.service_is_ready() or None, float(p["server_timeout"]), "no /reset_scene (sim_node)")
        if not self.out.wait_for_control(float(p["server_timeout"])):
            raise EpisodeFailure("no /execute_keypose (control_node)")
        successes = episodes = 0
        for k in range(int(p["episodes"])):
            if self.stop.is_set():
                break
            number = int(p["first_episode"]) + k
            self._started, self._object_id = False, ""
            try:
                success, note = self._episode(k, number)
            except EpisodeFailure as exc:
                success, note = False, str(exc)
            if self._started:
                self.out.episode_event(number, False, self._object_id, success, note)
            episodes += 1
            successes += success
            self.get_logger().info(f"episode {number} {self._object_id}: {'SUCCESS' if success else 'failure'} ({note})")
        self.get_logger().info(f"{successes}/{episodes} episodes succeeded")
        self.out.flush()
        return successes, episodes

    def _episode(self, k: int, number: int) -> tuple[bool, str]:
        """One episode up to the verdict: (success, note). START goes out once the demonstration is
        planned (``_started``); run() sends the END, also when this raises EpisodeFailure."""
        p = self.p
        seed = int(p["seed"]) + k
        rng = np.random.default_rng(seed)
        # The part and its initial states first, on the mirror (same object, same DoF order).
        info = self.mirror.reset(p["category"], int(p["instance"]), seed=seed, dof_fraction=float(p["dof_fraction"]))
        joint = p["joints"][k % len(p["joints"])] or str(rng.choice([h.joint for h in self.mirror.object.handles]))
        label = p["modes"][k % len(p["modes"])]
        fractions = []  # empty: every DoF at dof_fraction
        if float(p["others_fraction"]) >= 0.0:
            if joint not in info.dof_names:
                raise EpisodeFailure(f"{info.object_id} has no movable part {joint}: it has {info.dof_names}")
            fractions = [float(p["dof_fraction"]) if name == joint else float(p["others_fraction"]) for name in info.dof_names]
            info = self.mirror.reset(p["category"], int(p["instance"]), seed=seed, dof_fraction=fractions)
        request = ResetScene.Request(category=p["category"], instance=int(p["instance"]), seed=seed,
                                     dof_fraction=float(p["dof_fraction"]), dof_fractions=fractions)
        future = self._reset.call_async(request)
        reset = self._wait(lambda: future.result() if future.done() else None, float(p["reset_timeout"]), "no /reset_scene answer")
        if not reset.success:
            raise EpisodeFailure(f"/reset_scene refused: {reset.message}")
        self._object_id = reset.object_id
        if info.object_id != reset.object_id or list(info.dof_names) != list(reset.dof_names):
            raise EpisodeFailure(f"the mirror scene ({info.object_id}, {info.dof_names}) is not the simulator's "
                                 f"({reset.object_id}, {list(reset.dof_names)}): is robot the simulator's?")
        self.mirror.object.set_qpos(np.asarray(reset.dof_initial, float))  # where the simulator's parts came to rest
        try:
            task = task_for_label(self.mirror, joint, label)
            demo = self.teleoperator.demo(task, rng)
        except (KeyError, ValueError, PlanningError) as exc:
            raise EpisodeFailure(f"no demonstration of {label} on {joint}: {exc}") from exc
        demo_note = f"scripted teleop: {label} {joint}, grasp {1000 * demo.grasp_offset:+.0f} mm along the handle"
        self.out.episode_event(number, True, reset.object_id, note=demo_note)
        self._started = True
        self.out.mode(demo.label)
        note = ""
        for keypose in demo.keyposes:
            ok, message = self.out.execute(keypose, float(p["velocity_scaling"]), float(p["goal_timeout"]), self.stop)
            if self.stop.is_set():
                raise EpisodeFailure("interrupted (Ctrl-C)")
            if not ok:
                # The object decides success, not the arm: a drawer at its end stop keeps the hand from p2.
                note = f"stopped at {PHASE_NAMES[keypose.phase]}: {message}"
                break
        settled = self.get_clock().now().nanoseconds + int(float(p["settle_time"]) * 1e9)
        state = self._wait(lambda: self._state_after(settled), float(p["goal_timeout"]), "no /object_state after the motion")
        positions = dict(zip(state.name, state.position))
        final = np.array([positions[name] for name in reset.dof_names])
        success, moved = judged_success(task, list(reset.dof_names), np.asarray(reset.dof_initial), final,
                                        np.asarray(reset.dof_lower), np.asarray(reset.dof_upper))
        verdict = f"{demo.label} {joint}: moved {moved:+.2f} of its range"
        return success, verdict + (f"; {note}" if note else "")


def demonstrate(node: ScriptedTeleop, stop: threading.Event) -> int:
    """The episodes: 0 when some were recorded, INTERRUPTED after Ctrl-C, else 1."""
    try:
        _, episodes = node.run()
    except EpisodeFailure as exc:
        node.get_logger().error(str(exc))
        return 1
    return INTERRUPTED if stop.is_set() else (0 if episodes else 1)


def main(args: list[str] | None = None) -> int:
    # SIGINT / SIGTERM only set stop: the context must stay up until the running goal is cancelled.
    return run_client(ScriptedTeleop, demonstrate, "scripted_teleop", args)


if __name__ == "__main__":
    raise SystemExit(main())
