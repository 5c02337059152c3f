"""Joint-trajectory following with ros2_control's joint_trajectory_controller (JTC) semantics.

The simulator's FollowJointTrajectory server and JTC topic behave like the real controller so
that clients written against a robot work unchanged (and vice versa):
  * validation: every controller joint named exactly once and nothing else (INVALID_JOINTS),
    per-point vectors of the right size and finite, time_from_start strictly increasing
    (INVALID_GOAL), a non-zero start stamp whose trajectory already ended (OLD_HEADER_TIMESTAMP);
  * timing: a zero stamp means "start now"; a future stamp holds the current position until then;
  * interpolation ("splines"): from the state when the trajectory starts to the first point,
    then point to point - linear with positions only, cubic with velocities, quintic with
    accelerations too;
  * an empty trajectory means "hold the current position".

ROS-free: the node converts messages to :class:`TrajectoryCommand` and back.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# control_msgs/action/FollowJointTrajectory result error codes.
SUCCESSFUL = 0
INVALID_GOAL = -1
INVALID_JOINTS = -2
OLD_HEADER_TIMESTAMP = -3
PATH_TOLERANCE_VIOLATED = -4
GOAL_TOLERANCE_VIOLATED = -5


class InvalidTrajectory(ValueError):
    """A trajectory the controller refuses; ``error_code`` is a FollowJointTrajectory code."""

    def __init__(self, error_code: int, message: str) -> None:
        super().__init__(message)
        self.error_code = error_code


@dataclass(frozen=True)
class TrajectoryCommand:
    """A trajectory_msgs/JointTrajectory as arrays (times are time_from_start, seconds)."""

    joint_names: tuple[str, ...]
    times: np.ndarray  # (N,)
    positions: np.ndarray  # (N, J)
    velocities: np.ndarray | None  # (N, J) or None when no point has velocities
    accelerations: np.ndarray | None
    start_time: float | None  # absolute (sim) time; None for a zero header stamp ("now")


def command_from_points(
    joint_names: list[str], points: list[tuple[float, list, list, list]], start_time: float | None
) -> TrajectoryCommand:
    """Build a command from (time_from_start, positions, velocities, accelerations) tuples.

    Raises InvalidTrajectory when a point's vectors have the wrong length or velocities /
    accelerations are given for some points only (the controller could not interpolate).
    """
    n_joints = len(joint_names)
    times = np.array([p[0] for p in points], dtype=float)

    def stack(index: int, what: str, required: bool) -> np.ndarray | None:
        sizes = [len(p[index]) for p in points]
        if not required and all(s == 0 for s in sizes):
            return None
        for i, s in enumerate(sizes):
            if s != n_joints:
                raise InvalidTrajectory(INVALID_GOAL, f"point {i} has {s} {what} for {n_joints} joints")
        return np.array([p[index] for p in points], dtype=float).reshape(len(points), n_joints)

    return TrajectoryCommand(
        joint_names=tuple(joint_names),
        times=times,
        positions=stack(1, "positions", True) if points else np.zeros((0, n_joints)),
        velocities=stack(2, "velocities", False) if points else None,
        accelerations=stack(3, "accelerations", False) if points else None,
        start_time=start_time,
    )


def validate(command: TrajectoryCommand, controller_joints: tuple[str, ...], now: float) -> None:
    """Raise InvalidTrajectory with JTC's error code for anything the controller refuses."""
    names = list(command.joint_names)
    if len(command.times) == 0:
        return  # empty trajectory: hold position
    if len(set(names)) != len(names):
        raise InvalidTrajectory(INVALID_JOINTS, f"duplicate joint names in {names}")
    unknown = [n for n in names if n not in controller_joints]
    if unknown:
        raise InvalidTrajectory(INVALID_JOINTS, f"unknown joint(s) {unknown}: this controller has {list(controller_joints)}")
    missing = [n for n in controller_joints if n not in names]
    if missing:
        raise InvalidTrajectory(INVALID_JOINTS, f"joint(s) {missing} missing: every controller joint must be commanded")
    vectors = (("positions", command.positions), ("velocities", command.velocities), ("accelerations", command.accelerations))
    for what, values in vectors:
        if values is not None and not np.all(np.isfinite(values)):
            point = int(np.argwhere(~np.isfinite(values))[0][0])
            raise InvalidTrajectory(INVALID_GOAL, f"point {point} has non-finite {what}")
    if not np.all(np.isfinite(command.times)) or command.times[0] < 0:
        raise InvalidTrajectory(INVALID_GOAL, "time_from_start must be finite and non-negative")
    steps = np.diff(command.times)
    if np.any(steps <= 0):
        i = int(np.argmax(steps <= 0))
        raise InvalidTrajectory(
            INVALID_GOAL,
            f"time_from_start is not strictly increasing between points {i} and {i + 1} "
            f"({command.times[i]:.4f} s, {command.times[i + 1]:.4f} s)",
        )
    if command.start_time is not None and command.start_time + command.times[-1] < now:
        raise InvalidTrajectory(
            OLD_HEADER_TIMESTAMP,
            f"trajectory starting at {command.start_time:.3f} s ends at {command.start_time + command.times[-1]:.3f} s, "
            f"before now ({now:.3f} s)",
        )


class ActiveTrajectory:
    """A validated trajectory being executed, sampled in controller joint order."""

    def __init__(
        self, command: TrajectoryCommand, controller_joints: tuple[str, ...], now: float, q_now: np.ndarray, qd_now: np.ndarray
    ) -> None:
        order = [command.joint_names.index(n) for n in controller_joints] if len(command.times) else []
        self.start_time = now if command.start_time is None else command.start_time
        n = len(controller_joints)
        # Knot 0 is the state when the trajectory starts (JTC's "point before the trajectory").
        self.times = np.concatenate([[0.0], command.times])
        self.positions = np.vstack([q_now, command.positions[:, order]]) if order else q_now[None].copy()
        with_vel = command.velocities is not None
        with_acc = with_vel and command.accelerations is not None
        self.velocities = np.vstack([qd_now, command.velocities[:, order]]) if with_vel else None
        self.accelerations = np.vstack([np.zeros(n), command.accelerations[:, order]]) if with_acc else None
        self.hold = q_now.copy()  # position held before the start time

    @property
    def end_time(self) -> float:
        return self.start_time + float(self.times[-1])

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Desired (positions, velocities) at absolute time ``t``; the last point after the end."""
        tau = t - self.start_time
        if tau <= 0.0:
            return self.hold.copy(), np.zeros_like(self.hold)
        if tau >= self.times[-1]:
            qd = self.velocities[-1] if self.velocities is not None else np.zeros_like(self.hold)
            return self.positions[-1].copy(), qd.copy()
        i = int(np.searchsorted(self.times, tau, side="right")) - 1
        dt = self.times[i + 1] - self.times[i]
        s = tau - self.times[i]
        p0, p1 = self.positions[i], self.positions[i + 1]
        if self.velocities is None:
            return p0 + (p1 - p0) * (s / dt), (p1 - p0) / dt
        v0, v1 = self.velocities[i], self.velocities[i + 1]
        if self.accelerations is None:
            return _cubic(p0, v0, p1, v1, dt, s)
        return _quintic(p0, v0, self.accelerations[i], p1, v1, self.accelerations[i + 1], dt, s)


def _cubic(p0, v0, p1, v1, T: float, s: float) -> tuple[np.ndarray, np.ndarray]:
    a2 = (3.0 * (p1 - p0) - (2.0 * v0 + v1) * T) / T**2
    a3 = (2.0 * (p0 - p1) + (v0 + v1) * T) / T**3
    return p0 + v0 * s + a2 * s**2 + a3 * s**3, v0 + 2.0 * a2 * s + 3.0 * a3 * s**2


def _quintic(p0, v0, acc0, p1, v1, acc1, T: float, s: float) -> tuple[np.ndarray, np.ndarray]:
    h = p1 - p0
    a3 = (20.0 * h - (8.0 * v1 + 12.0 * v0) * T - (3.0 * acc0 - acc1) * T**2) / (2.0 * T**3)
    a4 = (-30.0 * h + (14.0 * v1 + 16.0 * v0) * T + (3.0 * acc0 - 2.0 * acc1) * T**2) / (2.0 * T**4)
    a5 = (12.0 * h - 6.0 * (v1 + v0) * T - (acc0 - acc1) * T**2) / (2.0 * T**5)
    q = p0 + v0 * s + 0.5 * acc0 * s**2 + a3 * s**3 + a4 * s**4 + a5 * s**5
    qd = v0 + acc0 * s + 3.0 * a3 * s**2 + 4.0 * a4 * s**3 + 5.0 * a5 * s**4
    return q, qd


@dataclass(frozen=True)
class Outcome:
    """How an executed trajectory ended (a FollowJointTrajectory result)."""

    error_code: int
    message: str = ""


class ArmController:
    """The joint_trajectory_controller's state machine: follow, check tolerances, hold.

    ``command(t)`` gives the drive targets for time ``t``; ``check(t, q)`` reports an
    :class:`Outcome` once the active trajectory finished (within ``goal_tolerance`` of its last
    point by ``end + goal_time_tolerance``) or violated a path tolerance. After an outcome, or
    :meth:`hold`, the controller holds a fixed position. A tolerance of 0 is not checked.
    """

    def __init__(self, joints: tuple[str, ...], q_hold: np.ndarray, goal_tolerance: float, goal_time_tolerance: float) -> None:
        self.joints = tuple(joints)
        self.default_goal_tolerance = np.full(len(joints), float(goal_tolerance))
        self.default_goal_time_tolerance = float(goal_time_tolerance)
        self.active: ActiveTrajectory | None = None
        self._hold = np.asarray(q_hold, dtype=float).copy()
        self._path_tolerance = np.zeros(len(joints))
        self._goal_tolerance = self.default_goal_tolerance
        self._goal_time_tolerance = self.default_goal_time_tolerance

    def tolerances_from(self, names: list[str], values: list[float], default: np.ndarray) -> np.ndarray:
        """Per-joint tolerances from (name, value) pairs; values <= 0 keep the default (the
        FollowJointTrajectory convention: 0 = server default, -1 = no check is treated as 0)."""
        out = default.copy()
        for name, value in zip(names, values):
            if name not in self.joints:
                raise InvalidTrajectory(INVALID_JOINTS, f"tolerance given for unknown joint '{name}'")
            if value > 0:
                out[self.joints.index(name)] = value
            elif value < 0:
                out[self.joints.index(name)] = 0.0
        return out

    def start(
        self,
        command: TrajectoryCommand,
        now: float,
        q: np.ndarray,
        qd: np.ndarray,
        path_tolerance: np.ndarray | None = None,
        goal_tolerance: np.ndarray | None = None,
        goal_time_tolerance: float | None = None,
    ) -> None:
        """Replace whatever runs with a validated ``command`` (an empty one holds ``q``)."""
        if len(command.times) == 0:
            self.hold(q)
            return
        self.active = ActiveTrajectory(command, self.joints, now, np.asarray(q, float), np.asarray(qd, float))
        self._path_tolerance = np.zeros(len(self.joints)) if path_tolerance is None else path_tolerance
        self._goal_tolerance = self.default_goal_tolerance if goal_tolerance is None else goal_tolerance
        self._goal_time_tolerance = self.default_goal_time_tolerance if goal_time_tolerance is None else goal_time_tolerance

    def hold(self, q: np.ndarray) -> None:
        """Stop following and hold ``q`` (JTC's hold position after an abort or cancel)."""
        self.active = None
        self._hold = np.asarray(q, dtype=float).copy()

    def command(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        if self.active is None:
            return self._hold, np.zeros_like(self._hold)
        return self.active.sample(t)

    def check(self, t: float, q: np.ndarray) -> Outcome | None:
        """The outcome of the active trajectory at time ``t`` with joint positions ``q``, or None
        while it is still running. A finished trajectory's last point is then held."""
        if self.active is None:
            return None
        desired, _ = self.active.sample(t)
        error = np.abs(np.asarray(q, float) - desired)
        checked = self._path_tolerance > 0
        if t < self.active.end_time:
            if np.any(checked & (error > self._path_tolerance)):
                i = int(np.argmax(checked & (error > self._path_tolerance)))
                self.hold(q)
                return Outcome(
                    PATH_TOLERANCE_VIOLATED,
                    f"{self.joints[i]} is {error[i]:.4f} from its path (tolerance {self._path_tolerance[i]:.4f})",
                )
            return None
        checked = self._goal_tolerance > 0
        outside = checked & (error > self._goal_tolerance)
        if not np.any(outside):
            self.hold(desired)
            return Outcome(SUCCESSFUL)
        if t >= self.active.end_time + self._goal_time_tolerance:
            i = int(np.argmax(outside))
            self.hold(q)
            return Outcome(
                GOAL_TOLERANCE_VIOLATED,
                f"{self.joints[i]} ended {error[i]:.4f} from its goal (tolerance {self._goal_tolerance[i]:.4f}) "
                f"{self._goal_time_tolerance:.2f} s after the trajectory end",
            )
        return None
