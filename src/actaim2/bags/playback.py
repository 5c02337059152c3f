"""Replay timing: each message goes out when its recorded time, scaled by ``rate``, comes due.

Pass ``k`` of a replay maps bag time ``t`` to the wall time ``w_k + (t - t_first) / rate``, where
``t_first`` is the first played timestamp (at or after the start offset) and ``w_k`` the wall
time the pass began; with ``loop`` the next pass begins as soon as the last message went out. While
waiting, /clock ticks carry the bag time of the moment, ``t_first + (now - w_k) * rate``.

Reading, decompressing and checking messages happens in a prefetch thread a few messages
ahead (given a head start, and reading on into the next pass of a loop), so a large cloud being
read does not delay the one before it. The timing error of each
message (publish time minus due time) is kept for the p50/p99 the player reports.
"""
from __future__ import annotations

import itertools
import queue
import threading
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from actaim2.bags.source import BagSource

PREFETCH = 32  # messages read ahead of the one being waited for
HEAD_START_S = 1.0  # at most this long, a pass waits for the reader to fill its queue
_END = object()


@dataclass
class PlayOptions:
    rate: float = 1.0
    start_offset_ns: int = 0  # from the bag's first message
    loop: bool = False
    clock_period_ns: int = 0  # /clock tick period in wall time; 0 = no /clock


@dataclass
class PlayStats:
    published: dict[str, int] = field(default_factory=dict)
    lateness_ns: list[int] = field(default_factory=list)
    passes: int = 0
    seconds: float = 0.0

    def timing_ms(self) -> dict[str, float]:
        if not self.lateness_ns:
            return {}
        late = np.asarray(self.lateness_ns, dtype=np.float64) / 1e6
        return {"p50": float(np.percentile(late, 50)), "p99": float(np.percentile(late, 99)), "max": float(late.max())}

    def as_dict(self) -> dict:
        return {"published": self.published, "passes": self.passes, "seconds": self.seconds, "timing_error_ms": self.timing_ms()}


def parse_remaps(rules: list[str]) -> dict[str, str]:
    """["/from:=/to", ...] -> {"/from": "/to"}; a malformed rule raises ValueError."""
    remap = {}
    for rule in rules:
        source, sep, target = rule.partition(":=")
        if not sep or not source.strip() or not target.strip():
            raise ValueError(f"remap rule '{rule}' is not of the form /from:=/to")
        remap[source.strip()] = target.strip()
    return remap


class Player:
    def __init__(
        self,
        source: BagSource,
        options: PlayOptions,
        publishers: dict[str, Callable[[bytes], None]],
        publish_clock: Callable[[int], None] | None = None,
        stop: threading.Event | None = None,
        now_ns: Callable[[], int] = time.monotonic_ns,
    ) -> None:
        """``publishers`` maps each bag topic to play onto its publish function; the rest is skipped."""
        if options.rate <= 0:
            raise ValueError(f"rate must be > 0, got {options.rate}")
        self._source = source
        self._options = options
        self._publishers = publishers
        self._publish_clock = publish_clock if options.clock_period_ns > 0 else None
        self._stop = stop or threading.Event()
        self._now = now_ns
        self.stats = PlayStats({topic: 0 for topic in publishers})

    def run(self) -> PlayStats:
        started = self._now()
        prefetched: queue.Queue = queue.Queue(maxsize=PREFETCH)
        done = threading.Event()  # the replay is over (finished, stopped, or failed)
        reader = threading.Thread(target=self._prefetch, args=(prefetched, done), name="bag_prefetch", daemon=True)
        reader.start()
        # A head start for the reader (its first messages also pay for rosbags' code generation).
        deadline = time.monotonic() + HEAD_START_S
        while not prefetched.full() and reader.is_alive() and time.monotonic() < deadline:
            time.sleep(0.005)
        current, first, wall0 = -1, 0, 0
        next_tick = self._now()
        try:
            while not self._stop.is_set():
                try:
                    item = prefetched.get(timeout=0.1)
                except queue.Empty:
                    continue  # the reader is still reading (or the stop is being seen)
                if item is _END:
                    break
                pass_index, message = item
                if pass_index != current:  # a new pass starts now, right after the previous one
                    current, first, wall0 = pass_index, message.timestamp, self._now()
                    self.stats.passes = pass_index + 1
                due = wall0 + int((message.timestamp - first) / self._options.rate)
                next_tick = self._wait(due, next_tick, first, wall0)
                if self._stop.is_set():
                    break
                self.stats.lateness_ns.append(self._now() - due)
                self._publishers[message.topic](message.data)
                self.stats.published[message.topic] += 1
        finally:
            done.set()
            while reader.is_alive():  # a reader blocked on a full queue must see ``done``
                try:
                    prefetched.get(timeout=0.05)
                except queue.Empty:
                    pass
        self.stats.seconds = (self._now() - started) / 1e9
        return self.stats

    def _wait(self, due: int, next_tick: int, first: int, wall0: int) -> int:
        """Sleep until ``due``, publishing /clock ticks on the way; returns the next tick time."""
        period = self._options.clock_period_ns
        while True:
            now = self._now()
            if self._publish_clock is not None and next_tick <= now:
                self._publish_clock(first + int((now - wall0) * self._options.rate))
                next_tick = max(next_tick + period, now)
                continue
            wake = min(due, next_tick) if self._publish_clock is not None else due
            if now >= due:
                return next_tick
            if self._stop.wait((wake - now) / 1e9):
                return next_tick

    def _prefetch(self, out: queue.Queue, done: threading.Event) -> None:
        """Reads ahead across passes, so a loop restarts without a gap."""
        def put(item: object) -> bool:
            while not (done.is_set() or self._stop.is_set()):
                try:
                    out.put(item, timeout=0.1)
                    return True
                except queue.Full:
                    continue
            return False

        start_ns = self._source.start_ns + self._options.start_offset_ns
        try:
            for pass_index in itertools.count():
                played = 0
                for message in self._source.messages(set(self._publishers), start_ns):
                    if not put((pass_index, message)):
                        return
                    played += 1
                if not self._options.loop or not played:
                    return
        finally:
            put(_END)
