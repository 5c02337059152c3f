"""Test harness: real rclpy nodes in real processes, talking over real DDS on loopback.

Helpers importable by test modules (``from harness import wait_for``); the fixtures built on
them are in conftest.py. Importing this module (conftest does, first) sets the environment.

Set at import time, before any test can call ``rclpy.init()``:
  * ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST - no DDS packet leaves the machine;
  * ROS_DOMAIN_ID - one random domain per test run, so parallel runs never see each other.
Child processes started by :class:`NodeProcess` inherit both.
"""
from __future__ import annotations

import os
import random
import signal
import subprocess
import time
from pathlib import Path
from typing import Callable

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("ACTAIM2_TEST_DOMAIN_ID", str(random.SystemRandom().randint(1, 100)))
os.environ["ROS_DOMAIN_ID"] = os.environ["ACTAIM2_TEST_DOMAIN_ID"]
from actaim2.runtime import apply_ros_defaults  # noqa: E402  (after the variables above)

apply_ros_defaults()

REPO = Path(__file__).resolve().parents[1]


def wait_for(predicate: Callable[[], bool], timeout: float, interval: float = 0.05) -> bool:
    """Poll ``predicate`` until it is true or ``timeout`` seconds pass; returns its last value."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return bool(predicate())


def matched(subscription) -> Callable[[], bool]:
    """A predicate for :func:`wait_for`: ``subscription`` has matched a publisher. A volatile
    subscription misses what is published before the match, and discovery lags on a loaded machine."""
    return lambda: subscription.get_publisher_count() >= 1


class NodeProcess:
    """A node started through `ros2 run`, its output captured in a log file."""

    def __init__(self, package: str, executable: str, params: dict | None, args: list[str], log_dir: Path,
                 env: dict[str, str] | None = None):
        import yaml

        self.name = f"{package}/{executable}"
        self.params = dict(params or {})
        cmd = ["ros2", "run", package, executable, *args, "--ros-args"]
        if params:
            params_file = log_dir / f"{executable}_params.yaml"
            params_file.write_text(yaml.safe_dump({"/**": {"ros__parameters": params}}))
            cmd += ["--params-file", str(params_file)]
        self.log_path = log_dir / f"{executable}.log"
        self._log = open(self.log_path, "w")
        self.proc = subprocess.Popen(cmd, stdout=self._log, stderr=subprocess.STDOUT, start_new_session=True,
                                     env={**os.environ, **(env or {})})

    def output(self) -> str:
        if not self._log.closed:
            self._log.flush()
        return self.log_path.read_text(errors="replace")

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self, timeout: float = 10.0) -> int:
        """Ctrl-C (SIGINT), as a user would; kill only if it does not exit in time."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        self._log.close()
        return self.proc.returncode
