"""Named wall-time sections, recorded only while a :class:`Profile` records (``bench throughput``).

``with section("physics"):`` (or ``@timed("physics")`` on a function) adds the wall time of that
work to the recording profile under its name. Sections nest: a section's time counts in the
innermost one only (exclusive time), so the sections of one profile never overlap and the whole
wall time is their sum plus what no section covered. Without a recording profile, ``section``
returns one shared do-nothing context and ``timed`` adds one global read to a call.
:func:`cpu_seconds` reads a whole process's CPU time, which does not depend on the machine's load.
"""

from __future__ import annotations

import functools
import os
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator, TypeVar

F = TypeVar("F", bound=Callable)


class Profile:
    """Exclusive wall seconds and entries per section name."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.calls: dict[str, int] = {}
        self._stack: list[
            list
        ] = []  # open sections: [name, start, seconds spent in nested sections]

    def _enter(self, name: str) -> None:
        self._stack.append([name, time.perf_counter(), 0.0])

    def _exit(self) -> None:
        name, start, nested = self._stack.pop()
        elapsed = time.perf_counter() - start
        self.seconds[name] = self.seconds.get(name, 0.0) + elapsed - nested
        self.calls[name] = self.calls.get(name, 0) + 1
        if self._stack:
            self._stack[-1][2] += elapsed


class _Section:
    __slots__ = ("profile", "name")

    def __init__(self, profile: Profile, name: str) -> None:
        self.profile, self.name = profile, name

    def __enter__(self) -> None:
        self.profile._enter(self.name)

    def __exit__(self, *exc) -> bool:
        self.profile._exit()
        return False


class _Off:
    __slots__ = ()

    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc) -> bool:
        return False


_OFF = _Off()
_recording: Profile | None = None


def section(name: str) -> _Section | _Off:
    """A context that times its block under ``name`` in the recording profile (none: a no-op)."""
    profile = _recording
    return _OFF if profile is None else _Section(profile, name)


def timed(name: str) -> Callable[[F], F]:
    """Decorator: every call of the function is a :func:`section` ``name``."""

    def wrap(function: F) -> F:
        @functools.wraps(function)
        def inner(*args, **kwargs):
            profile = _recording
            if profile is None:
                return function(*args, **kwargs)
            with _Section(profile, name):
                return function(*args, **kwargs)

        return inner  # type: ignore[return-value]

    return wrap


@contextmanager
def recording(profile: Profile) -> Iterator[Profile]:
    """Sections entered inside this block (in this process) add to ``profile``."""
    global _recording
    previous, _recording = _recording, profile
    try:
        yield profile
    finally:
        _recording = previous


def cpu_seconds(pid: int) -> float:
    """CPU seconds a process has used so far, all threads (user + system, from /proc): load-independent."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime
