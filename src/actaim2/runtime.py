"""Process-wide runtime defaults that must hold before any middleware starts.

ROS 2 Jazzy's default discovery range is the whole subnet (multicast leaves the machine).
This project keeps DDS on the local host unless the user explicitly asks for more, so every
entry point that starts rclpy calls :func:`apply_ros_defaults` *before* ``rclpy.init()``.
It only touches environment variables, so the library stays importable without ROS.
"""
from __future__ import annotations

import os

DISCOVERY_RANGE_VAR = "ROS_AUTOMATIC_DISCOVERY_RANGE"
DEFAULT_DISCOVERY_RANGE = "LOCALHOST"


def apply_ros_defaults() -> None:
    """Keep DDS discovery on loopback unless the environment already chose a range."""
    os.environ.setdefault(DISCOVERY_RANGE_VAR, DEFAULT_DISCOVERY_RANGE)
