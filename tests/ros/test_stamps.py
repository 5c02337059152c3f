"""Stamp and duration conversions (actaim2_ros.stamps): whole seconds carried, one helper for all."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from actaim2.control.trajectory import JointTrajectory
from actaim2_control.ros_executor import _trajectory_msg
from actaim2_ros.stamps import (
    duration_msg,
    duration_seconds,
    seconds_stamp,
    stamp_msg,
    stamp_ns,
    stamp_seconds,
)

REPO = Path(__file__).resolve().parents[2]
ALMOST_ONE = 0.9999999996  # rounds up to the next whole second


def test_a_fraction_that_rounds_up_carries_into_the_seconds():
    assert (seconds_stamp(ALMOST_ONE).sec, seconds_stamp(ALMOST_ONE).nanosec) == (1, 0)
    assert (duration_msg(ALMOST_ONE).sec, duration_msg(ALMOST_ONE).nanosec) == (1, 0)
    assert (duration_msg(2 + ALMOST_ONE).sec, duration_msg(2 + ALMOST_ONE).nanosec) == (3, 0)


def test_a_trajectory_point_at_almost_one_second_is_not_sent_a_second_early():
    trajectory = JointTrajectory(("j1",), np.array([0.5, ALMOST_ONE]), np.zeros((2, 1)), np.zeros((2, 1)),
                                 np.zeros((2, 1)))
    points = _trajectory_msg(trajectory).points
    assert [(p.time_from_start.sec, p.time_from_start.nanosec) for p in points] == [(0, 500_000_000), (1, 0)]


def test_round_trips():
    ns = 1_765_000_000_123_456_789
    assert stamp_ns(stamp_msg(ns)) == ns
    assert stamp_seconds(stamp_msg(ns)) == pytest.approx(ns / 1e9)
    assert stamp_seconds(seconds_stamp(12.345)) == pytest.approx(12.345, abs=1e-9)
    assert duration_seconds(duration_msg(0.25)) == 0.25


def test_stamps_are_converted_only_by_actaim2_ros_and_the_librarys_one_helper():
    handwritten = re.compile(r"\.nanosec\b|nanosec=|\.sec\b|\bsec=")
    helper = REPO / "src" / "actaim2" / "stamps.py"
    found = [f"{path.relative_to(REPO)}:{number}: {line.strip()}"
             for package in ("actaim2_control", "actaim2_perception", "actaim2_policy", "actaim2_sim", "src")
             for path in sorted((REPO / package).rglob("*.py"))
             for number, line in enumerate(path.read_text().splitlines(), 1)
             if path != helper and handwritten.search(line)]
    assert not found, "\n".join(found)
