"""Process-wide runtime defaults that must hold before any middleware starts.

ROS 2 Jazzy's default discovery range is the whole subnet (multicast leaves the machine).
This project keeps DDS on the local host unless the user explicitly asks for more, so every
entry point that starts ROS calls :func:`apply_ros_defaults` *before* the ROS client library starts.

Fast DDS's default shared-memory segment (0.5 MB) is too small for this project's clouds
(5 x 2.4 MB at 10 Hz lost 35-66 % of messages under load, 0 % with a 32 MB segment), so the
project's Fast DDS profile (``config/fastdds.xml``: a 32 MB SHM transport plus the builtin
ones) is the default too. Both only set environment variables that the user has not set,
so the library stays importable without ROS and a user's own choice wins.

Shared memory has one known failure, upstream: a node SIGKILLed and restarted while its peers
run can come back deaf to them (Fast DDS 2.14 reuses the dead process's SHM port and deletes its
segment while live writers still write into it; eProsima/Fast-DDS#5053, #4737, no fix released).
``config/fastdds_udp.xml`` (:data:`FASTDDS_UDP_PROFILE`: UDPv4 on 127.0.0.1, no SHM) is the
profile for a node restarted after a crash: its peers then reach it over UDP.
"""
from __future__ import annotations

import os
import signal
from pathlib import Path

DISCOVERY_RANGE_VAR = "ROS_AUTOMATIC_DISCOVERY_RANGE"
DEFAULT_DISCOVERY_RANGE = "LOCALHOST"
FASTDDS_PROFILE_VAR = "FASTRTPS_DEFAULT_PROFILES_FILE"
FASTDDS_PROFILE = Path(__file__).resolve().parent / "config" / "fastdds.xml"
FASTDDS_UDP_PROFILE = FASTDDS_PROFILE.with_name("fastdds_udp.xml")
# A node process writes every thread's stack to stderr on this signal (actaim2_ros.main, faulthandler:
# written even while a thread holds the GIL); the launcher sends it to a node that will not stop.
STACK_DUMP_SIGNAL = signal.SIGUSR1


def apply_ros_defaults() -> None:
    """Keep DDS discovery on loopback and use the project's Fast DDS profile, unless already chosen."""
    os.environ.setdefault(DISCOVERY_RANGE_VAR, DEFAULT_DISCOVERY_RANGE)
    os.environ.setdefault(FASTDDS_PROFILE_VAR, str(FASTDDS_PROFILE))
