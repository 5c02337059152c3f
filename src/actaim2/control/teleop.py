"""Keyboard teleoperation: the key map, the jogged target and the marking of the four keyposes.

A person records a demonstration the way the paper's fine-tuning data was made: they jog the
hand (its ``tcp``) with keys, mark INIT, REACH, GRASP and MANIPULATE where they want them (each
marked keypose is executed by the controller, ``/execute_keypose``, which also publishes it
on ``/keypose`` for the recorder), label the mode ("push", "pull", "open", "close" or free
text) and end the episode with their verdict. This module is that state machine without ROS:
:meth:`TeleopSession.press` turns a key into an effect (a jog to execute, a keypose to mark, an
event to publish, a message to show) that ``teleop_node`` carries out, so every rule here is
tested without a terminal or a robot.

Jogging moves a target pose: translations along the ``world`` axes, rotations about the tcp's
own axes (turning about the approach axis keeps the hand pointing where it points). Every
target is checked by the control package's IK (the solver and collision checks of
``control_node``, seeded from the previous target's joints, no random restarts: a jog must be
a small continuous motion) before the arm is sent there. A target IK cannot reach is clipped
to the largest reachable part of the step (halving down to 1/8), else refused, with IK's reason;
so is one whose solution jumps to another arm configuration. The target moves at a bounded
speed: each step takes at least step / max_speed (and its joint motion at most
``joint_speed_fraction`` of each joint's velocity limit), and keys arriving while a step is
still under way are dropped, so a held key (auto-repeat) moves the hand at the speed limit.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from actaim2.control.ik import IKResult
from actaim2.geometry import matrix_to_pose
from actaim2.keypose import GRASP, INIT, MANIPULATE, PHASE_NAMES, REACH, Keypose

MODES = ("push", "pull", "open", "close")  # the paper's labelled modes; free text is allowed too
PHASE_GRIPPER = {INIT: False, REACH: False, GRASP: True, MANIPULATE: True}  # DESIGN.md: the four phases
CLIP_FRACTIONS = (1.0, 0.5, 0.25, 0.125)
STEP_SCALES = (0.125, 4.0)  # the jog step stays within these multiples of the configured one

# key -> (kind, axis, sign): translations along world x, y, z; rotations about tcp x, y, z
JOG_KEYS = {
    "w": ("translate", 0, +1), "s": ("translate", 0, -1),
    "a": ("translate", 1, +1), "d": ("translate", 1, -1),
    "r": ("translate", 2, +1), "f": ("translate", 2, -1),
    "u": ("rotate", 0, +1), "o": ("rotate", 0, -1),
    "i": ("rotate", 1, +1), "k": ("rotate", 1, -1),
    "j": ("rotate", 2, +1), "l": ("rotate", 2, -1),
}
MARK_KEYS = {"0": INIT, "1": REACH, "2": GRASP, "3": MANIPULATE}
KEYMAP_TEXT = """\
actaim2 teleop: keys (no Enter needed)
  move the hand (world axes)   w/s  forward/back (+x/-x)   a/d  left/right (+y/-y)   r/f  up/down (+z/-z)
  turn the hand (tcp axes)     u/o  roll (x)   i/k  pitch (y)   j/l  yaw about the approach axis (z)
  jog step                     [ / ]  halve / double   (now {translation_mm:.0f} mm, {rotation_deg:.0f} deg per key;
                               at most {speed_mm:.0f} mm/s and {angular_deg:.0f} deg/s)
  gripper                      g  close   h  open
  mark a keypose (executes it) 0 INIT   1 REACH   2 GRASP (closes)   3 MANIPULATE
  mode label                   m  then 1 push, 2 pull, 3 open, 4 close, or any text, and Enter
  episode                      e  start   y  end: success   n  end: failure
  other                        t  show the target   ?  this key map   q  quit
"""


@dataclass(frozen=True)
class JogSettings:
    """How far one key press moves the target, and how fast the target may move."""

    translation_step: float = 0.01  # m per key press
    rotation_step: float = np.radians(5.0)  # rad per key press
    max_speed: float = 0.05  # m/s of the tcp
    max_angular_speed: float = np.radians(30.0)  # rad/s of the tcp
    joint_speed_fraction: float = 0.5  # of each joint's velocity limit
    max_joint_step: float = 0.3  # rad: an IK answer farther from the last one is another arm configuration

    def __post_init__(self) -> None:
        for name in ("translation_step", "rotation_step", "max_speed", "max_angular_speed", "max_joint_step"):
            if not getattr(self, name) > 0:
                raise ValueError(f"jog setting {name} must be > 0, got {getattr(self, name)}")
        if not 0 < self.joint_speed_fraction <= 1:
            raise ValueError(f"joint_speed_fraction must be in (0, 1], got {self.joint_speed_fraction}")


# -- effects: what the node does for a key ---------------------------------------------------
@dataclass(frozen=True)
class Jog:
    """Send the arm to ``joints`` (the target ``T``'s IK solution) in ``duration`` s."""

    T: np.ndarray
    joints: np.ndarray
    duration: float
    note: str  # "" or why the step was clipped


@dataclass(frozen=True)
class Gripper:
    closed: bool


@dataclass(frozen=True)
class Mark:
    """Execute ``keypose`` through /execute_keypose, then call :meth:`TeleopSession.marked`."""

    keypose: Keypose


@dataclass(frozen=True)
class Label:
    """Publish the mode label (only inside an episode; :class:`Start` carries it otherwise)."""

    label: str


@dataclass(frozen=True)
class Start:
    episode: int
    label: str  # the mode label in effect ("" = none yet)


@dataclass(frozen=True)
class End:
    episode: int
    success: bool
    note: str


@dataclass(frozen=True)
class Message:
    """Only text for the operator (a refusal, the target, the key map)."""

    text: str


@dataclass(frozen=True)
class AskLabel:
    """Read a line of text from the operator, then call :meth:`TeleopSession.set_label`."""


@dataclass(frozen=True)
class Quit:
    end: End | None  # the episode still open, ended as a failure


Effect = Jog | Gripper | Mark | Label | Start | End | Message | AskLabel | Quit


def parse_label(text: str) -> str:
    """An operator's mode label: 1-4 pick the paper's modes, anything else is kept as typed."""
    text = text.strip()
    if text in ("1", "2", "3", "4"):
        return MODES[int(text) - 1]
    return text


def format_pose(T: np.ndarray) -> str:
    position, quat = matrix_to_pose(T)
    rpy = Rotation.from_matrix(T[:3, :3]).as_euler("xyz", degrees=True)
    return (f"x {position[0]:+.3f} y {position[1]:+.3f} z {position[2]:+.3f} m, "
            f"rpy {rpy[0]:+.1f} {rpy[1]:+.1f} {rpy[2]:+.1f} deg (quat xyzw {np.round(quat, 4).tolist()})")


@dataclass
class _Episode:
    number: int
    next_phase: int = INIT  # the keypose to mark next (MANIPULATE + 1: all four are marked)


class TeleopSession:
    """The operator's state: the jogged target, the mode label and the episode being recorded.

    ``solve(T, seed)`` is the IK check (an :class:`actaim2.control.ik.IKSolver`'s ``solve``),
    ``fk(joints)`` the tcp pose of a joint configuration and ``max_velocity`` the arm joints'
    velocity limits (rad/s). Call :meth:`sync` with the measured joints before the first key
    and after every executed keypose.
    """

    def __init__(self, solve: Callable[[np.ndarray, np.ndarray], IKResult], fk: Callable[[np.ndarray], np.ndarray],
                 max_velocity: np.ndarray, settings: JogSettings = JogSettings(), first_episode: int = 0):
        self._solve = solve
        self._fk = fk
        self._max_velocity = np.asarray(max_velocity, dtype=float)
        self.settings = settings
        self._scale = 1.0
        self.target: np.ndarray | None = None
        self._joints: np.ndarray | None = None
        self._busy_until = -np.inf
        self.label = ""
        self._episode: _Episode | None = None
        self._next_episode = first_episode

    # -- state -------------------------------------------------------------------------------
    def sync(self, joints: np.ndarray) -> None:
        """The arm is at ``joints``: the target becomes the tcp pose there."""
        self._joints = np.asarray(joints, dtype=float).copy()
        self.target = self._fk(self._joints)

    @property
    def episode(self) -> int | None:
        return None if self._episode is None else self._episode.number

    def keymap(self) -> str:
        s = self.settings
        return KEYMAP_TEXT.format(translation_mm=1000 * s.translation_step * self._scale,
                                  rotation_deg=np.degrees(s.rotation_step * self._scale),
                                  speed_mm=1000 * s.max_speed, angular_deg=np.degrees(s.max_angular_speed))

    # -- keys --------------------------------------------------------------------------------
    def press(self, key: str, now: float) -> Effect | None:
        """The effect of ``key`` pressed at time ``now`` (s, monotonic); None: nothing to do
        (an unknown key, or a jog key while the previous step is still under way)."""
        if key in JOG_KEYS:
            return self._jog(*JOG_KEYS[key], now)
        if key in MARK_KEYS:
            return self._mark(MARK_KEYS[key])
        if key in ("[", "]"):
            self._scale = float(np.clip(self._scale * (0.5 if key == "[" else 2.0), *STEP_SCALES))
            s = self.settings
            return Message(f"jog step {1000 * s.translation_step * self._scale:.1f} mm, "
                           f"{np.degrees(s.rotation_step * self._scale):.1f} deg")
        if key in ("g", "h"):
            return Gripper(closed=key == "g")
        if key == "m":
            return AskLabel()
        if key == "e":
            return self._start()
        if key in ("y", "n"):
            return self._end(success=key == "y", note="judged by the operator")
        if key == "t":
            return Message(f"target: {format_pose(self.target)}" if self.target is not None else "no target yet")
        if key == "?":
            return Message(self.keymap())
        if key == "q":
            return Quit(self._end(False, "operator quit") if self._episode is not None else None)
        return None

    def set_label(self, text: str) -> Effect:
        label = parse_label(text)
        if not label:
            return Message("mode label unchanged (empty)")
        self.label = label
        if self._episode is None:
            return Message(f"mode label '{label}': published when the next episode starts")
        return Label(label)

    def _jog(self, kind: str, axis: int, sign: int, now: float) -> Effect | None:
        if self.target is None or self._joints is None:
            return Message("no joint states yet: cannot jog")
        if now < self._busy_until:
            return None  # the speed bound: the previous step is still under way
        s = self.settings
        step = (s.translation_step if kind == "translate" else s.rotation_step) * self._scale * sign
        first_problem = ""
        for fraction in CLIP_FRACTIONS:
            T = _stepped(self.target, kind, axis, step * fraction)
            result = self._solve(T, self._joints)
            if not result.success:
                first_problem = first_problem or result.message
                continue
            jump = float(np.max(np.abs(result.angles - self._joints)))
            if jump > s.max_joint_step:
                first_problem = first_problem or (f"IK jumps {jump:.2f} rad to another arm configuration "
                                                  f"(limit {s.max_joint_step:g} rad)")
                continue
            distance = abs(step * fraction)
            duration = max(distance / (s.max_speed if kind == "translate" else s.max_angular_speed),
                           float(np.max(np.abs(result.angles - self._joints) / (s.joint_speed_fraction * self._max_velocity))))
            self.target, self._joints = T, result.angles
            self._busy_until = now + duration
            note = "" if fraction == 1.0 else f"clipped to {100 * fraction:g} % of the step: {first_problem}"
            return Jog(T, result.angles, duration, note)
        return Message(f"refused: {first_problem}")

    def _mark(self, phase: int) -> Effect:
        if self._episode is None:
            return Message(f"{PHASE_NAMES[phase]} not marked: start an episode first (e)")
        if self.target is None:
            return Message("no joint states yet: nothing to mark")
        expected = self._episode.next_phase
        if expected > MANIPULATE:
            return Message("all four keyposes are marked: end the episode (y success, n failure)")
        if phase != expected:
            return Message(f"{PHASE_NAMES[phase]} not marked: the next keypose is {PHASE_NAMES[expected]} "
                           f"(key {[k for k, p in MARK_KEYS.items() if p == expected][0]})")
        position, quat = matrix_to_pose(self.target)
        return Mark(Keypose(phase, position, quat, PHASE_GRIPPER[phase]))

    def marked(self, keypose: Keypose, executed: bool) -> None:
        """The outcome of a :class:`Mark`: an executed keypose counts, a failed one may be marked again."""
        if executed and self._episode is not None and keypose.phase == self._episode.next_phase:
            self._episode.next_phase += 1

    def _start(self) -> Effect:
        if self._episode is not None:
            return Message(f"episode {self._episode.number} is running: end it first (y success, n failure)")
        self._episode = _Episode(self._next_episode)
        self._next_episode += 1
        return Start(self._episode.number, self.label)

    def _end(self, success: bool, note: str) -> Effect:
        if self._episode is None:
            return Message("no episode is running (e starts one)")
        missing = [PHASE_NAMES[p] for p in range(self._episode.next_phase, MANIPULATE + 1)]
        if missing:
            note += f"; not marked: {', '.join(missing)}"
        end = End(self._episode.number, success, note)
        self._episode = None
        return end


def _stepped(T: np.ndarray, kind: str, axis: int, amount: float) -> np.ndarray:
    """``T`` moved ``amount`` m along world ``axis`` or turned ``amount`` rad about its own ``axis``."""
    out = T.copy()
    if kind == "translate":
        out[axis, 3] += amount
    else:
        out[:3, :3] = T[:3, :3] @ Rotation.from_rotvec(amount * np.eye(3)[axis]).as_matrix()
    return out
