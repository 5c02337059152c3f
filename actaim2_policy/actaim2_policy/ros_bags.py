"""What the bag nodes need from ROS that the ROS-free ``actaim2.bags`` cannot know: Python message
classes by type name, rclpy QoS <-> rosbags QoS, and where the installed interfaces live."""
from __future__ import annotations

import importlib
import os

from rclpy.duration import Infinite
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)

from actaim2.bags.qos import QosChoice


def message_class(msgtype: str) -> type:
    """``sensor_msgs/msg/PointCloud2`` -> the generated class, imported as rosidl lays packages out
    (``sensor_msgs.msg.PointCloud2``); service event types resolve through their service
    (``pkg/srv/Name_Event`` -> ``pkg.srv.Name.Event``). Raises ImportError when not installed."""
    parts = msgtype.split("/")
    if len(parts) != 3:
        raise ImportError(f"'{msgtype}' is not a ROS 2 type name (pkg/msg/Name)")
    package, kind, name = parts
    try:
        module = importlib.import_module(f"{package}.{kind}")
    except ImportError as exc:
        raise ImportError(f"no Python package for {msgtype} ({exc})") from None
    if hasattr(module, name):
        return getattr(module, name)
    base, _, suffix = name.rpartition("_")
    if base and hasattr(getattr(module, base, None), suffix):
        return getattr(getattr(module, base), suffix)
    raise ImportError(f"{package}.{kind} has no {name}")


def install_prefixes() -> list[str]:
    """The ament prefixes whose share/ folders hold the .msg files (AMENT_PREFIX_PATH)."""
    return [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]


def _duration(d) -> QosTime:
    ns = d.nanoseconds if d != Infinite else 2**63 - 1
    return QosTime(ns // 1_000_000_000, ns % 1_000_000_000)


def bag_qos(profile: QoSProfile) -> Qos:
    """An offered QoS as rosbag2 records it (from a publisher's endpoint info)."""
    return Qos(
        history=QosHistory[profile.history.name],
        depth=int(profile.depth),
        reliability=QosReliability[profile.reliability.name],
        durability=QosDurability[profile.durability.name],
        deadline=_duration(profile.deadline),
        lifespan=_duration(profile.lifespan),
        liveliness=QosLiveliness[profile.liveliness.name],
        liveliness_lease_duration=_duration(profile.liveliness_lease_duration),
        avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions),
    )


def rclpy_qos(choice: QosChoice) -> QoSProfile:
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if choice.depth == 0 else HistoryPolicy.KEEP_LAST,
        depth=max(choice.depth, 1),
        reliability=ReliabilityPolicy.RELIABLE if choice.reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if choice.transient_local else DurabilityPolicy.VOLATILE,
    )
