"""GripperCommand goals with the semantics of ros2_control's gripper_action_controller.

A goal ends when the finger position is within ``goal_tolerance`` of the command (reached), or
when the fingers have not moved faster than ``stall_velocity`` for ``stall_timeout`` seconds
(stalled: closed on a handle, or blocked). The speed is measured from successive positions:
PhysX reports a finger pressing against its joint limit with a non-zero joint velocity.
With ``allow_stalling`` a stall is a success - a gripper closed on a handle is exactly what a
grasp looks like - otherwise it aborts. Positions are finger joint positions, as the
ros2_control controller commands its joint (not the gap the GripperCommand comment mentions).
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class GripperOutcome:
    succeeded: bool
    reached_goal: bool
    stalled: bool


class GripperGoal:
    """One GripperCommand goal being executed (positions in finger joint units)."""

    def __init__(
        self, target: float, now: float, goal_tolerance: float, stall_velocity: float, stall_timeout: float, allow_stalling: bool
    ) -> None:
        self.target = float(target)
        self.goal_tolerance = goal_tolerance
        self.stall_velocity = stall_velocity
        self.stall_timeout = stall_timeout
        self.allow_stalling = allow_stalling
        self._last_movement = now
        self._last: tuple[float, float] | None = None  # (time, position) of the previous update

    def update(self, now: float, position: float) -> GripperOutcome | None:
        """The goal's outcome given the finger position at ``now``, or None while it runs."""
        if abs(position - self.target) < self.goal_tolerance:
            return GripperOutcome(succeeded=True, reached_goal=True, stalled=False)
        previous, self._last = self._last, (now, position)
        if previous is None or now <= previous[0]:
            return None
        if abs(position - previous[1]) / (now - previous[0]) > self.stall_velocity:
            self._last_movement = now
            return None
        if now - self._last_movement > self.stall_timeout:
            return GripperOutcome(succeeded=self.allow_stalling, reached_goal=False, stalled=True)
        return None
