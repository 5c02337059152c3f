"""Time-optimal, jerk-limited joint trajectories with Ruckig, chained through via points.

A motion is a list of *segments*, each a function of time from its own start: a Ruckig
joint-space segment (:class:`JointSegment`) or a straight line of the tcp
(:class:`actaim2.control.line.LineSegment`). Segments are chained: each starts in the state
(position, velocity, acceleration) the previous one ends in. Ruckig's own waypoint API
(``intermediate_positions``) needs its cloud service, so via points are handled this way
instead, with the velocity at the via point chosen by the caller.

The executor receives the chain sampled at a fixed period (:func:`sample`), with positions,
velocities and accelerations per point, as a FollowJointTrajectory goal carries them.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, Sequence

import numpy as np
from ruckig import ControlInterface, InputParameter, Result, Ruckig, Synchronization, Trajectory

from actaim2.control.model import RobotModel


@dataclass(frozen=True)
class Limits:
    """Per-joint kinematic limits (angles, rad/s, rad/s^2, rad/s^3); +-inf position = continuous."""

    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray

    @classmethod
    def of(cls, robot: RobotModel, scaling: float = 1.0) -> "Limits":
        """The robot's limits with velocity, acceleration and jerk scaled by ``scaling`` in (0, 1]."""
        if not 0.0 < scaling <= 1.0:
            raise ValueError(f"velocity scaling must be in (0, 1], got {scaling}")
        spec = robot.spec
        return cls(robot.lower, robot.upper, scaling * spec.max_velocity, scaling * spec.max_acceleration, scaling * spec.max_jerk)


@dataclass(frozen=True)
class State:
    """Joint position, velocity and acceleration at one instant."""

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray

    @classmethod
    def at_rest(cls, position: np.ndarray) -> "State":
        position = np.asarray(position, dtype=float)
        return cls(position, np.zeros_like(position), np.zeros_like(position))


class Segment(Protocol):
    duration: float

    def at(self, t: float) -> State:
        """State at time t in [0, duration] from the segment's start."""


class TrajectoryError(RuntimeError):
    """No trajectory within the limits (the message says which)."""


class JointSegment:
    """A Ruckig time-optimal, jerk-limited motion between two joint states."""

    def __init__(self, trajectory: Trajectory):
        self._trajectory = trajectory
        self.duration = float(trajectory.duration)

    def at(self, t: float) -> State:
        p, v, a = self._trajectory.at_time(min(max(t, 0.0), self.duration))
        return State(np.asarray(p), np.asarray(v), np.asarray(a))

    def position_extrema(self) -> tuple[np.ndarray, np.ndarray]:
        ext = self._trajectory.position_extrema
        return np.array([e.min for e in ext]), np.array([e.max for e in ext])


class JointPlanner:
    """Ruckig for one number of joints; keeps its buffers between calls (about 20 us each)."""

    def __init__(self, dofs: int):
        self._otg = Ruckig(dofs)
        self._input = InputParameter(dofs)
        self._input.synchronization = Synchronization.Phase  # straight in joint space when possible
        self.dofs = dofs

    def plan(self, start: State, target: State, limits: Limits) -> JointSegment:
        """Fastest motion from ``start`` to ``target`` within ``limits`` (positions included)."""
        for name, state in (("start", start), ("target", target)):
            if np.any(state.position < limits.lower - 1e-9) or np.any(state.position > limits.upper + 1e-9):
                raise TrajectoryError(f"{name} position outside the joint limits")
        inp = self._input
        inp.control_interface = ControlInterface.Position
        inp.current_position = start.position.tolist()
        inp.current_velocity = start.velocity.tolist()
        inp.current_acceleration = start.acceleration.tolist()
        inp.target_position = target.position.tolist()
        inp.target_velocity = target.velocity.tolist()
        inp.target_acceleration = target.acceleration.tolist()
        inp.max_velocity = limits.velocity.tolist()
        inp.max_acceleration = limits.acceleration.tolist()
        inp.max_jerk = limits.jerk.tolist()
        trajectory = Trajectory(self.dofs)
        result = self._otg.calculate(inp, trajectory)
        if result not in (Result.Working, Result.Finished):
            raise TrajectoryError(f"Ruckig could not plan the segment ({result.name})")
        segment = JointSegment(trajectory)
        lo, hi = segment.position_extrema()
        if np.any(lo < limits.lower - 1e-9) or np.any(hi > limits.upper + 1e-9):
            raise TrajectoryError("the time-optimal segment overshoots a joint limit")
        return segment

    def stop(self, start: State, limits: Limits) -> JointSegment:
        """Fastest jerk-limited stop (zero velocity and acceleration) from a moving state:
        what a cancel sends, so the arm brakes within its limits instead of jumping to hold."""
        inp = self._input
        inp.control_interface = ControlInterface.Velocity
        inp.current_position = start.position.tolist()
        inp.current_velocity = start.velocity.tolist()
        inp.current_acceleration = start.acceleration.tolist()
        inp.target_velocity = [0.0] * self.dofs
        inp.target_acceleration = [0.0] * self.dofs
        inp.max_velocity = np.maximum(limits.velocity, np.abs(start.velocity)).tolist()
        inp.max_acceleration = np.maximum(limits.acceleration, np.abs(start.acceleration)).tolist()
        inp.max_jerk = limits.jerk.tolist()
        trajectory = Trajectory(self.dofs)
        result = self._otg.calculate(inp, trajectory)
        if result not in (Result.Working, Result.Finished):
            raise TrajectoryError(f"Ruckig could not plan the stop ({result.name})")
        return JointSegment(trajectory)


@dataclass
class JointTrajectory:
    """Time-stamped joint states from the start of a motion (a FollowJointTrajectory's points)."""

    joint_names: tuple[str, ...]
    times: np.ndarray  # (N,) seconds from the start (the current state, not a point), increasing, > 0
    positions: np.ndarray  # (N, n)
    velocities: np.ndarray
    accelerations: np.ndarray

    @property
    def duration(self) -> float:
        return float(self.times[-1]) if len(self.times) else 0.0

    def __len__(self) -> int:
        return len(self.times)


def sample(segments: Sequence[Segment], joint_names: Sequence[str], period: float) -> JointTrajectory:
    """The chain of segments at a fixed period; each segment's end is always a point, so via
    points and the goal are hit exactly. The start (t = 0, the current state) is not a point:
    a controller starts from where the arm is, as ros2_control's JTC does."""
    times, states, offset = [], [], 0.0
    for segment in segments:
        if segment.duration <= 1e-9:
            continue
        n = max(1, int(np.ceil(segment.duration / period - 1e-9)))
        for t in np.linspace(0.0, segment.duration, n + 1)[1:]:
            times.append(offset + t)
            states.append(segment.at(t))
        offset += segment.duration
    n = len(joint_names)
    return JointTrajectory(
        tuple(joint_names),
        np.asarray(times, dtype=float),
        np.array([s.position for s in states]).reshape(-1, n),
        np.array([s.velocity for s in states]).reshape(-1, n),
        np.array([s.acceleration for s in states]).reshape(-1, n),
    )
