"""The benchmarks' child processes (actaim2.bench.processes): private domain, logs, stopping, CPU time."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

from actaim2.bench.processes import private_ros_env, ros_run_command, start_logged, stop_group
from actaim2.profiling import cpu_seconds

SPEAK = "import sys; print('out', flush=True); print('err', file=sys.stderr, flush=True)"


def test_the_environment_is_loopback_on_a_domain_away_from_the_tests(tmp_path):
    profile = tmp_path / "profile.xml"
    env = private_ros_env(profile)
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" and 101 <= int(env["ROS_DOMAIN_ID"]) <= 200
    assert env["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(profile.resolve())
    assert env["PATH"] == os.environ["PATH"]


def test_ros_run_passes_lists_as_json_so_an_empty_string_entry_survives():
    assert ros_run_command("pkg", "exe", {"topics": ["/a", "/b"], "patterns": [""], "rate": 0.5, "loop": True}) == [
        "ros2", "run", "pkg", "exe", "--ros-args",
        "-p", 'topics:=["/a", "/b"]', "-p", 'patterns:=[""]', "-p", "rate:=0.5", "-p", "loop:=True"]


def test_the_log_gets_what_the_caller_does_not_take(tmp_path):
    both = start_logged([sys.executable, "-c", SPEAK], dict(os.environ), tmp_path / "both.log")
    assert both.wait(timeout=60) == 0
    assert (tmp_path / "both.log").read_text().split() == ["out", "err"]
    piped = start_logged([sys.executable, "-c", SPEAK], dict(os.environ), tmp_path / "err.log", stdout=subprocess.PIPE, text=True)
    out, _ = piped.communicate(timeout=60)
    assert out.split() == ["out"] and (tmp_path / "err.log").read_text().split() == ["err"]


def test_stop_interrupts_the_group_and_kills_what_ignores_the_interrupt(tmp_path):
    polite = start_logged(["sleep", "60"], dict(os.environ), tmp_path / "polite.log")
    assert stop_group(polite, timeout=10.0) == -signal.SIGINT
    stubborn = start_logged(["sh", "-c", "trap '' INT; sleep 60"], dict(os.environ), tmp_path / "stubborn.log")
    time.sleep(0.5)  # the trap is set
    began = time.monotonic()
    assert stop_group(stubborn, timeout=1.0) == -signal.SIGKILL and time.monotonic() - began >= 1.0
    assert stop_group(stubborn) == -signal.SIGKILL  # an exited process is left as it is


def test_cpu_seconds_counts_the_process_s_user_and_system_time():
    deadline = time.process_time() + 0.3
    while time.process_time() < deadline:
        pass
    assert abs(cpu_seconds(os.getpid()) - time.process_time()) < 0.1
