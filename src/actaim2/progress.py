"""Progress of the long commands: a bar with rate and ETA on a terminal, plain lines in a log.

:func:`progress` gives a ``tqdm`` bar when its stream (stderr by default) is a terminal; when the
stream is a file or a pipe (``actaim2 collect ... 2> collect.log``, CI) it gives a
:class:`PlainProgress`, which writes one whole line at most every ``interval`` seconds and one at
the end, each with the count, the rate and the ETA, instead of a bar redrawn with carriage
returns. Both take the same calls (``update``, ``set_postfix``, ``write``, ``close``, iteration).
"""
from __future__ import annotations

import sys
import time
from typing import Any, Iterable, Iterator, TextIO

PLAIN_INTERVAL = 30.0  # s between two plain progress lines


def progress(iterable: Iterable | None = None, *, total: int | None = None, desc: str = "",
             unit: str = "it", initial: int = 0, disable: bool = False,
             stream: TextIO | None = None, interval: float = PLAIN_INTERVAL) -> Any:
    """A progress display for ``total`` steps (or the length of ``iterable``) on ``stream``."""
    stream = stream if stream is not None else sys.stderr
    if total is None and iterable is not None and hasattr(iterable, "__len__"):
        total = len(iterable)
    if _is_terminal(stream) or disable:
        from tqdm import tqdm

        return tqdm(iterable, total=total, desc=desc, unit=unit, initial=initial, disable=disable,
                    file=stream, dynamic_ncols=True)
    return PlainProgress(iterable, total, desc, unit, initial, stream, interval)


def _is_terminal(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):  # closed or not a real stream
        return False


class PlainProgress:
    """Progress as log lines:
    ``<desc>: <n>/<total> <unit> (<rate> <unit>/s, ETA <m:ss>) <postfix>``."""

    def __init__(self, iterable: Iterable | None, total: int | None, desc: str, unit: str,
                 initial: int, stream: TextIO, interval: float):
        self.iterable, self.total, self.desc, self.unit = iterable, total, desc, unit
        self.n, self.stream, self.interval = initial, stream, interval
        self._initial = initial
        self._started = self._last = time.monotonic()
        self._postfix = ""
        self._closed = False

    def __iter__(self) -> Iterator:
        for item in self.iterable or ():
            yield item
            self.update(1)
        self.close()

    def __enter__(self) -> PlainProgress:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def update(self, n: int = 1) -> None:
        self.n += n
        now = time.monotonic()
        if now - self._last >= self.interval:
            self._last = now
            self._line(now)

    def set_postfix(self, **values: Any) -> None:
        self._postfix = ", ".join(f"{k}={v}" for k, v in values.items())

    def set_postfix_str(self, text: str) -> None:
        self._postfix = text

    def write(self, text: str) -> None:
        print(text, file=self.stream, flush=True)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._line(time.monotonic(), done=True)

    def _line(self, now: float, done: bool = False) -> None:
        elapsed = max(now - self._started, 1e-9)
        rate = (self.n - self._initial) / elapsed
        count = f"{self.n}/{self.total}" if self.total is not None else f"{self.n}"
        if done:
            timing = f"{rate:.3g} {self.unit}/s, done in {_clock(elapsed)}"
        elif self.total is not None and rate > 0:
            timing = f"{rate:.3g} {self.unit}/s, ETA {_clock((self.total - self.n) / rate)}"
        else:
            timing = f"{rate:.3g} {self.unit}/s, ETA unknown"
        postfix = f" {self._postfix}" if self._postfix else ""
        print(f"{self.desc}: {count} {self.unit} ({timing}){postfix}", file=self.stream,
              flush=True)


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes = f"{rest // 60:02d}" if hours else f"{rest // 60}"
    return f"{hours}:{minutes}:{rest % 60:02d}" if hours else f"{minutes}:{rest % 60:02d}"
