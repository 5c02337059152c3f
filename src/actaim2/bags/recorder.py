"""The recording pipeline between the subscriptions and the bag: a byte-bounded queue drained by
one writer thread that does the MCAP chunk compression and the disk writes.

Why a writer thread: the ROS executor must take each message off DDS as soon as it arrives
(best-effort clouds overwrite each other in the reader's history otherwise); compressing and
writing 120 MB/s of clouds in the same thread would stall it. lz4, zstd and file writes release
the GIL, so the executor thread keeps receiving while the writer works.

What happens to each message is counted per topic: ``received`` by :meth:`Recorder.put`,
``dropped`` when the queue was full, ``outside_bag`` when no bag took it (episode mode: received
between END and START, earlier than the grace window below), ``recorded`` = what the bags hold
on disk. DDS losses (best-effort samples that never arrived) are counted by the ROS adapter and
added via :meth:`add_lost`.

The start grace window: messages of different topics reach the recorder in no guaranteed order,
so a message published right after START (the INIT keypose control_node publishes once the
teleoperator has sent START and the INIT goal) can be received just before it. While no bag is
open, messages are therefore held, the last ``start_grace_ns`` of receive time and at most
``start_grace_bytes`` (the oldest go first); :meth:`start_bag` writes those received at most
``start_grace_ns`` before its timestamp into the new bag, each with its receive time, so a bag's
messages begin at most the window before its START. The rest are counted ``outside_bag``.
Readers tell by header stamp which of them belong to the episode (actaim2.finetune.bag_episodes:
stamped at or after START).

Bags are opened and closed through the same queue as the messages (:meth:`start_bag`,
:meth:`end_bag`), so an episode boundary falls exactly between the messages that came before
and after it. Messages of latched (transient-local) topics other than the trigger are
remembered and written at the start of every later bag, stamped with its first message's
time: each episode bag then carries its own /tf_static. A write error (full disk) ends the
recording: the bag keeps what is complete on disk (BagWriter.recover), ``error`` says why,
``on_error`` is called from the writer thread.

The writer thread also wakes when the open bag's oldest pending message is due on disk
(BagWriter's ``max_chunk_age``), so a recorder that is killed loses at most that much even when
no further message arrives.
"""
from __future__ import annotations

import threading
import time
from collections import OrderedDict, deque
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, TypeVar

from actaim2.bags.metadata import TopicSpec
from actaim2.bags.writer import BagWriter

T = TypeVar("T")
LATCHED_KEPT = 100  # distinct messages kept per latched topic (tf2's /tf_static listener depth)


@dataclass
class TopicCounts:
    received: int = 0
    recorded: int = 0
    dropped: int = 0  # writer queue full
    outside_bag: int = 0  # no bag open (episode mode)
    lost: int = 0  # never arrived (DDS message-lost events)
    bytes: int = 0
    reliable: bool = True


@dataclass
class RecordSummary:
    bags: list[str] = field(default_factory=list)
    topics: dict[str, TopicCounts] = field(default_factory=dict)
    seconds: float = 0.0  # from the first to the last message received (their timestamps)
    error: str | None = None

    @property
    def recorded_bytes(self) -> int:
        return sum(c.bytes for c in self.topics.values())

    def as_dict(self) -> dict:
        return {"bags": self.bags, "seconds": self.seconds, "error": self.error,
                "topics": {name: asdict(c) for name, c in self.topics.items()}}

    def lines(self) -> list[str]:
        mb = self.recorded_bytes / 1e6
        rate = mb / self.seconds if self.seconds > 0 else 0.0
        out = [f"{len(self.bags)} bag(s), {mb:.1f} MB of messages over {self.seconds:.1f} s ({rate:.1f} MB/s)"
               + (f"; stopped by a write error: {self.error}" if self.error else "")]
        for name, c in sorted(self.topics.items()):
            losses = c.dropped + c.lost
            out.append(
                f"  {name} ({'reliable' if c.reliable else 'best effort'}): received {c.received}, recorded {c.recorded}"
                f", lost in DDS {c.lost}, dropped (queue full) {c.dropped}"
                + (f", outside episodes {c.outside_bag}" if c.outside_bag else "")
                + (f" -> {100.0 * losses / max(1, c.received + c.lost):.2f}% loss" if losses else "")
            )
        return out


def unique_path(path: Path) -> Path:
    """``path``, or ``path_2``, ``path_3``... when it exists (a bag is never overwritten)."""
    candidate, n = path, 1
    while candidate.exists():
        n += 1
        candidate = path.with_name(f"{path.name}_{n}")
    return candidate


class Recorder:
    def __init__(
        self,
        make_writer: Callable[[str], BagWriter],
        queue_limit_bytes: int = 256 * 2**20,
        on_error: Callable[[str], None] | None = None,
        start_grace_ns: int = 0,
        start_grace_bytes: int = 0,
    ) -> None:
        """``make_writer(name)`` opens a new bag (name as given to :meth:`start_bag`);
        ``start_grace_ns`` / ``start_grace_bytes``: the start grace window (module docstring;
        0 bytes holds nothing)."""
        self._make_writer = make_writer
        self._limit = queue_limit_bytes
        self._on_error = on_error
        self._grace_ns, self._grace_bytes = start_grace_ns, start_grace_bytes
        self._queue: deque[tuple] = deque()
        self._queued_bytes = 0
        self._held: deque[tuple[str, int, bytes]] = deque()  # (topic, timestamp, data) received while no bag is open
        self._held_bytes = 0
        self._cond = threading.Condition()
        self._counts: dict[str, TopicCounts] = {}
        self._topics: dict[str, tuple[TopicSpec, bool]] = {}  # name -> (spec, latched); writer thread
        self._latched_topics: set[str] = set()  # as the producers see it
        self._latched: dict[str, OrderedDict[bytes, None]] = {}  # writer thread: the messages kept
        self._bag_open = False  # as the producers see it (after the queued start/end)
        self._writer: BagWriter | None = None
        self._ids: dict[str, int] = {}
        self._bags: list[BagWriter] = []
        self._recorded: dict[str, int] = {}
        self._span = [None, None]  # first and last timestamp put
        self.error: str | None = None
        self._thread = threading.Thread(target=self._run, name="bag_writer", daemon=True)
        self._thread.start()

    # --- producers (any thread) ----------------------------------------------------------
    def add_topic(self, spec: TopicSpec, reliable: bool, latched: bool) -> None:
        with self._cond:
            self._counts.setdefault(spec.name, TopicCounts(reliable=reliable))
            if latched:
                self._latched_topics.add(spec.name)
            self._push(("topic", spec, latched))

    def start_bag(self, name: str, timestamp: int) -> None:
        """Close the open bag (if any) and open a new one: the latched messages first, then the
        held ones received at most the grace window before ``timestamp``."""
        with self._cond:
            self._bag_open = self.error is None
            while self._held and self._held[0][1] < timestamp - self._grace_ns:
                self._release_oldest()
            taken, self._held, self._held_bytes = self._held, deque(), 0
            self._push(("start", name, min([timestamp] + [stamp for _, stamp, _ in taken])))
            for topic, stamp, data in taken:
                self._enqueue(topic, stamp, data)

    def end_bag(self) -> None:
        with self._cond:
            self._bag_open = False
            self._push(("end",))

    def put(self, topic: str, timestamp: int, data: bytes) -> bool:
        """Queue one message; False when it was not queued: dropped (queue full), or no bag is open
        (held for the next START's grace window, else counted outside a bag)."""
        with self._cond:
            counts = self._counts[topic]
            counts.received += 1
            self._span = [timestamp if self._span[0] is None else self._span[0], timestamp]
            if self.error is not None:
                return False
            if not self._bag_open and topic not in self._latched_topics:
                self._hold(topic, timestamp, data)
                return False
            return self._enqueue(topic, timestamp, data)

    def add_lost(self, topic: str, count: int) -> None:
        with self._cond:
            self._counts[topic].lost += count

    def stop(self) -> RecordSummary:
        """Write everything queued, close the bag, and say what was recorded."""
        with self._cond:
            while self._held:
                self._release_oldest()
            self._push(("stop",))
        self._thread.join()
        counts = self.counts()
        for name, c in counts.items():
            c.recorded = self._recorded.get(name, 0)
        first, last = self._span
        seconds = (last - first) / 1e9 if first is not None else 0.0
        return RecordSummary([str(b.path) for b in self._bags], counts, seconds, self.error)

    def counts(self) -> dict[str, TopicCounts]:
        """A copy of the per-topic counters so far (``recorded`` is filled in by :meth:`stop`)."""
        with self._cond:
            return {name: TopicCounts(**asdict(c)) for name, c in self._counts.items()}

    @property
    def queued_bytes(self) -> int:
        return self._queued_bytes

    def _push(self, item: tuple) -> None:
        self._queue.append(item)
        self._cond.notify()

    def _enqueue(self, topic: str, timestamp: int, data: bytes) -> bool:
        if self._queued_bytes + len(data) > self._limit:
            self._counts[topic].dropped += 1
            return False
        self._queued_bytes += len(data)
        self._push(("msg", topic, timestamp, data))
        return True

    def _hold(self, topic: str, timestamp: int, data: bytes) -> None:
        """Keep a message received while no bag is open for the next START's grace window."""
        self._held.append((topic, timestamp, data))
        self._held_bytes += len(data)
        while self._held and (self._held[0][1] < timestamp - self._grace_ns or self._held_bytes > self._grace_bytes):
            self._release_oldest()

    def _release_oldest(self) -> None:
        """Give up the oldest held message: it is outside any bag."""
        topic, _, data = self._held.popleft()
        self._held_bytes -= len(data)
        self._counts[topic].outside_bag += 1

    # --- writer thread -------------------------------------------------------------------
    def _run(self) -> None:
        flush_at: float | None = None  # time.monotonic() when pending messages are due on disk
        while True:
            with self._cond:
                timeout = None if flush_at is None else max(0.0, flush_at - time.monotonic())
                self._cond.wait_for(lambda: bool(self._queue), timeout)
                item = self._queue.popleft() if self._queue else None  # None: woken by flush_at
                if item is not None and item[0] == "msg":
                    self._queued_bytes -= len(item[3])
            if item is not None and item[0] == "stop":
                self._guarded(self._close_bag)
                return
            if self.error is None:
                if item is not None:
                    self._guarded(lambda: self._handle(item))
                flush_at = self._guarded(self._flush_aged)

    def _guarded(self, action: Callable[[], T]) -> T | None:
        try:
            return action()
        except Exception as exc:  # noqa: BLE001 - a write error (or a bug) must end the recording visibly, not the thread silently
            self._fail(exc)
            return None

    def _flush_aged(self) -> float | None:
        return self._writer.flush_aged() if self._writer is not None else None

    def _handle(self, item: tuple) -> None:
        kind = item[0]
        if kind == "msg":
            _, topic, timestamp, data = item
            if topic in self._latched:
                kept = self._latched[topic]
                kept.pop(data, None)
                kept[data] = None
                while len(kept) > LATCHED_KEPT:
                    kept.popitem(last=False)
            if self._writer is not None:
                self._writer.write(self._ids[topic], timestamp, data)
                self._count_bytes(topic, len(data))
            else:  # a latched message remembered for the next bag
                with self._cond:
                    self._counts[topic].outside_bag += 1
        elif kind == "topic":
            _, spec, latched = item
            self._topics[spec.name] = (spec, latched)
            if latched:
                self._latched.setdefault(spec.name, OrderedDict())
            if self._writer is not None:
                self._ids[spec.name] = self._writer.add_topic(spec)
        elif kind == "start":
            _, name, timestamp = item
            self._close_bag()
            self._writer = self._make_writer(name)
            self._bags.append(self._writer)
            self._ids = {topic: self._writer.add_topic(spec) for topic, (spec, _) in self._topics.items()}
            for topic, kept in self._latched.items():
                for data in kept:
                    self._writer.write(self._ids[topic], timestamp, data)
                    self._count_bytes(topic, len(data))
        elif kind == "end":
            self._close_bag()

    def _count_bytes(self, topic: str, n: int) -> None:
        with self._cond:
            self._counts[topic].bytes += n

    def _close_bag(self) -> None:
        writer, self._writer = self._writer, None
        if writer is None:
            return
        try:
            writer.close()
        except Exception:
            self._writer = writer  # _fail recovers it
            raise
        self._add_recorded(writer)

    def _add_recorded(self, writer: BagWriter) -> None:
        counts = writer.counts()
        for topic_id, spec in enumerate(writer.topics, start=1):
            self._recorded[spec.name] = self._recorded.get(spec.name, 0) + counts.get(topic_id, 0)

    def _fail(self, exc: BaseException) -> None:
        reason = f"{type(exc).__name__}: {exc}"
        writer, self._writer = self._writer, None
        if writer is not None:
            try:
                writer.recover()
            except Exception as again:  # noqa: BLE001 - reported with the first error
                reason += f" (and finishing the file failed too: {again}; open it with actaim2.bags.salvage)"
            self._add_recorded(writer)
        with self._cond:
            self.error = reason
            self._bag_open = False
        if self._on_error is not None:
            self._on_error(reason)
