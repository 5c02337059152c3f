"""The benchmarks' child processes: ROS nodes started on a private domain, logged, stopped, timed.

The through-the-node benchmarks (``bench perception``, ``bench bags``, ``bench services``) run
real nodes as separate processes (``ros2 run``) on loopback, on a random ROS_DOMAIN_ID away from
the tests' 1-100 so that a benchmark and a test suite on the same machine do not see each other.
Each node gets its own process group (``ros2 run`` execs the node, so the group is the node):
stopping sends SIGINT to the group, as Ctrl-C would, and SIGKILL only when it does not exit.
"""
from __future__ import annotations

import json
import os
import random
import signal
import subprocess
from pathlib import Path

from actaim2.runtime import DEFAULT_DISCOVERY_RANGE, DISCOVERY_RANGE_VAR, FASTDDS_PROFILE_VAR


def private_ros_env(fastdds_profile: Path | None = None) -> dict[str, str]:
    """This process's environment with loopback discovery, a random domain in 101-200 and, when
    given, a Fast DDS profile."""
    env = dict(os.environ, **{DISCOVERY_RANGE_VAR: DEFAULT_DISCOVERY_RANGE})
    env["ROS_DOMAIN_ID"] = str(random.SystemRandom().randint(101, 200))  # away from the tests' 1-100
    if fastdds_profile is not None:
        env[FASTDDS_PROFILE_VAR] = str(fastdds_profile.resolve())
    return env


def ros_run_command(package: str, executable: str, params: dict) -> list[str]:
    """``ros2 run`` with ``-p name:=value`` per parameter; lists as JSON (``[""]`` stays a one-string
    list, the way to give a string array with no real entry)."""
    args = []
    for name, value in params.items():
        args += ["-p", f"{name}:={json.dumps(value) if isinstance(value, list) else value}"]
    return ["ros2", "run", package, executable, "--ros-args", *args]


def start_logged(command: list[str], env: dict[str, str], log: Path, **popen) -> subprocess.Popen:
    """``command`` in its own process group; ``log`` gets its stderr, and its stdout unless the
    caller takes it (``stdout=subprocess.PIPE`` or ``DEVNULL`` in ``popen``)."""
    with open(log, "w") as log_file:
        stdout = popen.pop("stdout", log_file)
        stderr = subprocess.STDOUT if stdout is log_file else log_file
        return subprocess.Popen(command, env=env, stdout=stdout, stderr=stderr, start_new_session=True, **popen)


def stop_group(process: subprocess.Popen, timeout: float = 30.0) -> int:
    """SIGINT to the process group, SIGKILL after ``timeout`` seconds; the exit code."""
    if process.poll() is None:
        os.killpg(process.pid, signal.SIGINT)
        try:
            process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    return process.returncode
