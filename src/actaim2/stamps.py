"""The stamp of a recorded message's header as integer nanoseconds: the library's one stamp
conversion, for messages read from bags (rosbags' types). Nodes convert through actaim2_ros.stamps."""
from __future__ import annotations

from typing import Any

NS_PER_S = 1_000_000_000


def header_stamp_ns(header: Any) -> int:
    """``header.stamp`` (sec, nanosec) as integer nanoseconds."""
    return int(header.stamp.sec) * NS_PER_S + int(header.stamp.nanosec)
