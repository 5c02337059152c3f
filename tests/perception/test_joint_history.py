"""Joint positions at a cloud's stamp: interpolated between the bracketing JointStates, refused
(with the reason) where they are not known."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.perception.joint_history import JointStateHistory, JointStateUnavailable

MS = 1_000_000


def test_interpolates_each_joint_between_its_bracketing_messages():
    history = JointStateHistory()
    history.add(100 * MS, ["a", "b"], [0.0, 1.0])
    history.add(120 * MS, ["a", "b"], [1.0, 0.0])
    history.add(110 * MS + 1, ["gripper"], [0.02])  # published on its own, at another rate
    history.add(130 * MS, ["gripper"], [0.04])
    at = history.at(115 * MS)
    assert at["a"] == pytest.approx(0.75) and at["b"] == pytest.approx(0.25)
    assert at["gripper"] == pytest.approx(0.02 + 0.02 * (5 * MS - 1) / (20 * MS - 1))
    assert history.at(120 * MS)["a"] == 1.0  # a sample exactly at the stamp
    assert history.covers(120 * MS) and not history.covers(121 * MS)


def test_extrapolates_only_within_the_window():
    history = JointStateHistory(max_extrapolation=0.025)
    history.add(100 * MS, ["a"], [0.0])
    history.add(120 * MS, ["a"], [2.0])
    assert history.at(140 * MS)["a"] == pytest.approx(4.0)  # 20 ms ahead: the last velocity continues
    with pytest.raises(JointStateUnavailable, match=r"joint 'a': stamp 30.0 ms after its newest JointState"):
        history.at(150 * MS)
    with pytest.raises(JointStateUnavailable, match=r"joint 'a': stamp 1.0 ms older than its oldest"):
        history.at(99 * MS)


def test_history_is_bounded_and_restarts_when_time_goes_back():
    history = JointStateHistory(history=0.1)
    for k in range(20):
        history.add(k * 10 * MS, ["a"], [float(k)])
    with pytest.raises(JointStateUnavailable, match="older than its oldest"):
        history.at(50 * MS)  # dropped: more than 0.1 s before the newest sample
    assert history.at(185 * MS)["a"] == pytest.approx(18.5)
    history.add(5 * MS, ["a"], [-1.0])  # a bag restarted: only the new timeline counts
    assert history.at(5 * MS)["a"] == -1.0
    with pytest.raises(JointStateUnavailable):
        history.at(185 * MS)


def test_nothing_received_and_bad_messages():
    history = JointStateHistory()
    with pytest.raises(JointStateUnavailable, match="no JointState received yet"):
        history.at(0)
    assert not history.covers(0)
    with pytest.raises(ValueError, match="2 joint names but 1 positions"):
        history.add(1, ["a", "b"], [0.0])
    with pytest.raises(ValueError):
        JointStateHistory(history=0.0)


def test_interpolation_error_on_a_smooth_motion_is_tiny():
    """A 1.57 rad/s sine sampled at 50 Hz: linear interpolation is within 1 mrad of the truth,
    holding the newest sample is up to 31 mrad off (2 cm at 0.7 m from the shoulder)."""
    history = JointStateHistory()
    truth = lambda t: 0.5 * np.sin(np.pi * t)  # noqa: E731 - seconds -> rad
    for k in range(101):
        history.add(k * 20 * MS, ["a"], [truth(k * 0.02)])
    stamps = np.arange(0.011, 1.99, 0.0371)
    interpolated = np.array([history.at(int(round(t * 1e9)))["a"] for t in stamps])
    newest = truth(np.floor(stamps / 0.02) * 0.02)
    assert np.abs(interpolated - truth(stamps)).max() < 1e-3
    assert np.abs(newest - truth(stamps)).max() > 0.02
