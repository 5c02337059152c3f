"""Backoff for servers that went away: short waits first (a restart is usually quick), then longer
ones up to a cap, never past a deadline - a client that waits this way cannot hang."""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

BACKOFF_FIRST = 0.25  # s
BACKOFF_FACTOR = 2.0
BACKOFF_CAP = 4.0  # s


@dataclass(frozen=True)
class Backoff:
    first: float = BACKOFF_FIRST
    factor: float = BACKOFF_FACTOR
    cap: float = BACKOFF_CAP

    def delays(self, total: float) -> list[float]:
        """The waits between attempts, summing to ``total`` (the last one shortened to fit)."""
        out, left, delay = [], total, self.first
        while left > 1e-9:
            out.append(min(delay, left))
            left -= out[-1]
            delay = min(delay * self.factor, self.cap)
        return out


def wait_until(ready: Callable[[], bool], total: float, stop: Callable[[], bool] = lambda: False,
               backoff: Backoff = Backoff(), sleep: Callable[[float], bool] | None = None) -> bool:
    """Ask ``ready()`` with backoff for up to ``total`` s; False when time ran out or ``stop()``.

    ``sleep(seconds)`` may return early (True) when the caller is stopping, e.g. an Event's wait.
    """
    pause = sleep or (lambda s: time.sleep(s) or False)
    for delay in [0.0, *backoff.delays(total)]:
        if stop():
            return False
        if delay and pause(delay):
            return False
        if ready():
            return True
    return False
