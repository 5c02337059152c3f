"""Approximate time synchronisation of camera streams."""
from __future__ import annotations

from actaim2.perception.time_sync import ApproximateTimeSync

MS = 1_000_000


def test_sets_within_slop_are_emitted_once():
    sync = ApproximateTimeSync(3, slop_ns=10 * MS)
    assert sync.add(0, 100 * MS, "a0") is None
    assert sync.add(1, 103 * MS, "b0") is None
    assert sync.add(2, 106 * MS, "c0") == ["a0", "b0", "c0"]
    assert sync.add(2, 140 * MS, "c1") is None  # the emitted items are gone
    assert sync.add(0, 138 * MS, "a1") is None
    assert sync.add(1, 141 * MS, "b1") == ["a1", "b1", "c1"]


def test_stamps_too_far_apart_report_their_spread():
    sync = ApproximateTimeSync(2, slop_ns=10 * MS)
    sync.add(0, 100 * MS, "a")
    assert sync.add(1, 180 * MS, "b") is None
    assert sync.last_spread_ns == 80 * MS
    assert sync.add(0, 175 * MS, "a2") == ["a2", "b"]  # the newer frame of stream 0 pairs up
    assert sync.last_spread_ns is None


def test_closest_item_is_chosen_and_time_reset_restarts():
    sync = ApproximateTimeSync(2, slop_ns=5 * MS)
    for t in (100, 133, 166):
        sync.add(0, t * MS, f"a{t}")
    assert sync.add(1, 131 * MS, "b") == ["a133", "b"]
    sync.add(0, 10 * MS, "a_reset")  # stream restarted (bag loop, sim reset): old items dropped
    assert sync.add(1, 12 * MS, "b_reset") == ["a_reset", "b_reset"]


def test_single_stream_passes_through():
    sync = ApproximateTimeSync(1, slop_ns=0)
    assert sync.add(0, 5, "x") == ["x"]
