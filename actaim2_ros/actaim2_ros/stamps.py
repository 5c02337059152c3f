"""builtin_interfaces Time and Duration messages <-> integer nanoseconds and float seconds, the
one conversion every node uses (through rclpy.time.Time and rclpy.duration.Duration, which carry
whole seconds: a fraction that rounds up to 1 s becomes the next second, never 0 ns of this one)."""
from __future__ import annotations

from builtin_interfaces.msg import Duration as DurationMsg
from builtin_interfaces.msg import Time as TimeMsg
from rclpy.duration import Duration
from rclpy.time import Time

NS_PER_S = 1_000_000_000


def stamp_ns(stamp: TimeMsg) -> int:
    """A stamp as integer nanoseconds."""
    return Time.from_msg(stamp).nanoseconds


def stamp_seconds(stamp: TimeMsg) -> float:
    """A stamp as float seconds."""
    return stamp_ns(stamp) / NS_PER_S


def stamp_msg(ns: int) -> TimeMsg:
    """Integer nanoseconds (>= 0) as a stamp."""
    return Time(nanoseconds=ns).to_msg()


def seconds_stamp(seconds: float) -> TimeMsg:
    """Float seconds (>= 0) as a stamp, to the nearest nanosecond."""
    return stamp_msg(round(seconds * NS_PER_S))


def duration_msg(seconds: float) -> DurationMsg:
    """Float seconds as a Duration message, to the nearest nanosecond."""
    return Duration(nanoseconds=round(seconds * NS_PER_S)).to_msg()


def duration_seconds(duration: DurationMsg) -> float:
    """A Duration message as float seconds."""
    return Duration.from_msg(duration).nanoseconds / NS_PER_S
