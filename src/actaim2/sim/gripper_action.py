"""GripperCommand goals with the semantics of ros2_control's gripper_action_controller.

A goal ends when the finger position is within ``goal_tolerance`` of the command (reached), or
when the fingers have stopped making progress (stalled: closed on a handle, or blocked).

Stopped is judged on position progress over a window, never on a velocity: over the last
``stall_timeout`` seconds the finger position must have stayed within a band of
``stall_velocity * stall_timeout`` (a mean speed below ``stall_velocity``). PhysX reports a
non-zero joint velocity (1-3 mm/s) for fingers squeezing a handle or pressing against their
joint limit while the position does not change, and the position itself jitters by
micrometres between samples: neither an instantaneous velocity nor a difference of two samples
tells a squeeze from slow motion, the travel over a whole window does.

With ``allow_stalling`` a stall is a success - a gripper closed on a handle is exactly what a
grasp looks like - otherwise it aborts. Positions are in whatever unit the caller uses
throughout (the sim node: gap width in metres, or finger joint positions; see its
``gripper_position_unit``).
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass


@dataclass(frozen=True)
class GripperOutcome:
    succeeded: bool
    reached_goal: bool
    stalled: bool


class GripperGoal:
    """One gripper goal being executed (positions in one unit throughout, times in seconds)."""

    def __init__(
        self,
        target: float,
        now: float,
        position: float,
        goal_tolerance: float,
        stall_velocity: float,
        stall_timeout: float,
        allow_stalling: bool,
    ) -> None:
        self.target = float(target)
        self.goal_tolerance = goal_tolerance
        self.stall_timeout = stall_timeout
        self.stall_band = stall_velocity * stall_timeout  # finger travel that still counts as stopped
        self.allow_stalling = allow_stalling
        # (time, position) samples covering the last stall_timeout seconds (plus the one before)
        self._samples: deque[tuple[float, float]] = deque([(float(now), float(position))])

    def update(self, now: float, position: float) -> GripperOutcome | None:
        """The goal's outcome given the finger position at ``now``, or None while it runs."""
        if abs(position - self.target) < self.goal_tolerance:
            return GripperOutcome(succeeded=True, reached_goal=True, stalled=False)
        samples = self._samples
        samples.append((float(now), float(position)))
        window_start = now - self.stall_timeout
        while len(samples) > 1 and samples[1][0] <= window_start:
            samples.popleft()
        if samples[0][0] > window_start:
            return None  # not watched for a whole window yet
        positions = [p for _, p in samples]
        if max(positions) - min(positions) <= self.stall_band:
            return GripperOutcome(succeeded=self.allow_stalling, reached_goal=False, stalled=True)
        return None
