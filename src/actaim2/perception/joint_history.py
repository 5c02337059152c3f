"""The robot's joint positions at any recent instant, from a short history of /joint_states.

A cloud shows the robot where it was when the cloud was taken, not where the newest
/joint_states says it is: at 1.5 rad/s a shoulder joint moves the hand ~2 cm in the 20 ms
between two 50 Hz joint-state messages. The self-filter therefore poses the robot at each
cloud's stamp, interpolating every joint linearly between the two messages that bracket it.

Each joint keeps its own time series, so drivers that publish the arm and the gripper in
separate JointState messages (at different rates) are handled alike. A stamp newer than a
joint's newest sample is extrapolated from its last two samples, but only within
``max_extrapolation`` seconds; a stamp older than the history, or further ahead, is refused
with :class:`JointStateUnavailable`, whose message says which joint and by how much: guessing
there would leave the arm in the views or cut the object.
"""
from __future__ import annotations

import bisect
from collections.abc import Sequence

DEFAULT_HISTORY = 2.0  # s of joint states kept: more than a cloud's usual driver + transport latency
DEFAULT_MAX_EXTRAPOLATION = 0.025  # s: a little more than one period of 50 Hz /joint_states


class JointStateUnavailable(LookupError):
    """The joint positions at the requested stamp are not known well enough to use."""


class JointStateHistory:
    """Per-joint (stamp, position) series; stamps are nanoseconds (ROS time)."""

    def __init__(self, history: float = DEFAULT_HISTORY, max_extrapolation: float = DEFAULT_MAX_EXTRAPOLATION) -> None:
        if history <= 0 or max_extrapolation < 0:
            raise ValueError(f"need history > 0 and max_extrapolation >= 0, got {history} and {max_extrapolation}")
        self._history_ns = int(history * 1e9)
        self._max_extrapolation_ns = int(max_extrapolation * 1e9)
        self._stamps: dict[str, list[int]] = {}
        self._positions: dict[str, list[float]] = {}

    def __len__(self) -> int:
        return len(self._stamps)

    def add(self, stamp_ns: int, names: Sequence[str], positions: Sequence[float]) -> None:
        """Record one JointState. A stamp older than a joint's newest sample means time went back
        (a bag restarted, the simulation reset): that joint's history starts over."""
        if len(names) != len(positions):
            raise ValueError(f"{len(names)} joint names but {len(positions)} positions")
        for name, position in zip(names, positions):
            stamps = self._stamps.setdefault(name, [])
            values = self._positions.setdefault(name, [])
            if stamps and stamp_ns < stamps[-1]:
                stamps.clear()
                values.clear()
            if stamps and stamp_ns == stamps[-1]:
                values[-1] = float(position)  # the same instant again: the newer message wins
                continue
            stamps.append(int(stamp_ns))
            values.append(float(position))
            old = bisect.bisect_left(stamps, stamp_ns - self._history_ns)
            if old > 0:
                del stamps[:old]
                del values[:old]

    def covers(self, stamp_ns: int) -> bool:
        """Every joint has a sample at or after ``stamp_ns``: :meth:`at` interpolates, never extrapolates."""
        return bool(self._stamps) and all(stamps[-1] >= stamp_ns for stamps in self._stamps.values())

    def at(self, stamp_ns: int) -> dict[str, float]:
        """Every known joint's position at ``stamp_ns``; raises JointStateUnavailable when one
        cannot be interpolated or safely extrapolated there."""
        if not self._stamps:
            raise JointStateUnavailable("no JointState received yet")
        return {name: self._joint_at(name, stamp_ns) for name in self._stamps}

    def _joint_at(self, name: str, t: int) -> float:
        stamps, values = self._stamps[name], self._positions[name]
        if t < stamps[0]:
            raise JointStateUnavailable(
                f"joint '{name}': stamp {(stamps[0] - t) / 1e6:.1f} ms older than its oldest JointState in the history"
            )
        i = bisect.bisect_left(stamps, t)
        if i < len(stamps) and stamps[i] == t:
            return values[i]
        if i < len(stamps):  # stamps[i - 1] < t < stamps[i]
            t0, t1 = stamps[i - 1], stamps[i]
            return values[i - 1] + (values[i] - values[i - 1]) * (t - t0) / (t1 - t0)
        ahead = t - stamps[-1]
        if ahead > self._max_extrapolation_ns:
            raise JointStateUnavailable(
                f"joint '{name}': stamp {ahead / 1e6:.1f} ms after its newest JointState "
                f"(extrapolation limited to {self._max_extrapolation_ns / 1e6:.1f} ms)"
            )
        if len(stamps) == 1:
            return values[-1]
        t0, t1 = stamps[-2], stamps[-1]
        return values[-1] + (values[-1] - values[-2]) * ahead / (t1 - t0)
