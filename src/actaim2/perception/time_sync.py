"""Approximate time synchronisation of several streams (message_filters is not installable here).

Each stream keeps a short queue of (stamp, item). When an item arrives, the newest item is
paired with the item closest in time from every other stream; if all of them lie within
``slop`` of each other the set is emitted, and it and everything older is dropped from the
queues, so a set is never emitted twice and time never runs backwards. Unlike message_filters'
exhaustive search this is O(streams x queue) per message, which matters at 5 cameras x 30 Hz.
"""
from __future__ import annotations

from collections import deque
from typing import Any


class ApproximateTimeSync:
    """Group items of ``n_streams`` streams whose stamps (nanoseconds) lie within ``slop_ns``."""

    def __init__(self, n_streams: int, slop_ns: int, queue_size: int = 10) -> None:
        if n_streams < 1:
            raise ValueError("need at least one stream")
        self.slop_ns = int(slop_ns)
        self._queues: list[deque[tuple[int, Any]]] = [deque(maxlen=queue_size) for _ in range(n_streams)]
        self.last_spread_ns: int | None = None  # spread of the last rejected candidate set

    def add(self, stream: int, stamp_ns: int, item: Any) -> list[Any] | None:
        """Queue an item; return one item per stream when a synchronised set is complete."""
        queue = self._queues[stream]
        if queue and stamp_ns <= queue[-1][0]:
            queue.clear()  # a stream going back in time (bag restarted, sim reset): start over
        queue.append((stamp_ns, item))
        if any(not q for q in self._queues):
            return None
        chosen = [min(q, key=lambda entry: abs(entry[0] - stamp_ns)) for q in self._queues]
        stamps = [s for s, _ in chosen]
        spread = max(stamps) - min(stamps)
        if spread > self.slop_ns:
            self.last_spread_ns = spread
            return None
        self.last_spread_ns = None
        for q, (s, _) in zip(self._queues, chosen):
            while q and q[0][0] <= s:
                q.popleft()
        return [item for _, item in chosen]
