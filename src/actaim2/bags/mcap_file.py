"""One MCAP storage file of a rosbag2 bag (profile ``ros2``), written by the recorder's writer thread.

Why not ``rosbags``' own MCAP writer: it compresses with zstd only, counts a message as written
before its chunk reaches the disk, and cannot finish a file after a write error. This writer
keeps the same record layout (schemas and channels inside the first chunk that needs them,
one message index per channel and chunk, a summary with schemas, channels, statistics, chunk
indexes and the ``rosbag2`` metadata record) and adds:

* chunk compression ``lz4`` (LZ4 frame, fast) or ``zstd`` (level 1), or none;
* ``readable`` statistics that count only messages whose chunk is completely on disk;
* :meth:`McapFile.recover`: after ENOSPC or any other write error, cut the file back to the end
  of the last complete chunk and write the summary there, so every reader opens what was saved.
  If even the summary does not fit, the newest chunks are given up one by one until it does;
* chunks written by age as well as by size (:meth:`McapFile.flush` whenever the caller decides:
  the recorder does once the oldest pending message has waited ``max_chunk_age``), so that a
  process that dies takes at most that much with it.

:func:`summary` and :func:`message_indexes` also finish a file whose writer died
(:func:`actaim2.bags.salvage.finish`).

The file is opened unbuffered, and every record group goes out in one ``write``: a failed
write leaves at most one incomplete record group behind ``_good_end``.
"""
from __future__ import annotations

import struct
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO, Callable

import lz4.frame

try:
    from compression import zstd  # Python >= 3.14
except ImportError:  # pragma: no cover - depends on the Python version
    from backports import zstd

from actaim2.bags.metadata import FileStats, TopicSpec, qos_text

MAGIC = b"\x89MCAP0\r\n"
COMPRESSORS: dict[str, Callable[[bytes], bytes]] = {
    "none": lambda data: data,
    "lz4": lambda data: lz4.frame.compress(data),
    "zstd": lambda data: zstd.compress(data, level=1),
}
_OP_HEADER, _OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
_OP_MESSAGE_INDEX, _OP_CHUNK_INDEX, _OP_STATISTICS = 0x07, 0x08, 0x0B
_OP_METADATA, _OP_METADATA_INDEX, _OP_SUMMARY_OFFSET, _OP_DATA_END = 0x0C, 0x0D, 0x0E, 0x0F


def _string(text: str) -> bytes:
    data = text.encode()
    return struct.pack("<I", len(data)) + data


def _record(op: int, body: bytes) -> bytes:
    return struct.pack("<BQ", op, len(body)) + body


def _string_map(entries: dict[str, str]) -> bytes:
    body = b"".join(_string(k) + _string(v) for k, v in entries.items())
    return struct.pack("<I", len(body)) + body


@dataclass
class Chunk:
    """A chunk on disk: where, what it holds, and the time range of its messages."""

    start: int
    end: int  # end of the chunk record and its message indexes
    chunk_length: int
    index_offsets: dict[int, int]  # channel id -> file offset of its message index record
    compressed_size: int
    uncompressed_size: int
    start_ns: int
    end_ns: int
    channel_counts: dict[int, int]
    compression: str  # "" (none), "lz4" or "zstd", as the chunk record names it


@dataclass
class _Pending:
    pieces: list[bytes] = field(default_factory=list)
    size: int = 0
    start_ns: int = 2**63 - 1
    end_ns: int = 0
    index: dict[int, list[tuple[int, int]]] = field(default_factory=lambda: defaultdict(list))
    since: float | None = None  # time.monotonic() when its first message was added

    def add(self, record: bytes, channel: int | None = None, timestamp: int = 0) -> None:
        if channel is not None:
            if self.since is None:
                self.since = time.monotonic()
            self.index[channel].append((timestamp, self.size))
            self.start_ns = min(self.start_ns, timestamp)
            self.end_ns = max(self.end_ns, timestamp)
        self.pieces.append(record)
        self.size += len(record)


class McapFile:
    """Writes one .mcap file; ``describe(stats, topic_counts)`` returns the rosbag2 metadata text
    stored in the file's summary (the writer knows the whole bag, this file only itself)."""

    storage = "mcap"
    suffix = ".mcap"

    def __init__(
        self,
        path: Path,
        compression: str,
        chunk_size: int,
        describe: Callable[[FileStats, dict[int, int]], str],
        open_file: Callable[[Path], BinaryIO] | None = None,
        library: str = "actaim2",
    ) -> None:
        if compression not in COMPRESSORS:
            raise ValueError(f"unknown MCAP chunk compression '{compression}' (use one of {sorted(COMPRESSORS)})")
        self.path = path
        self.compression = "" if compression == "none" else compression
        self._compress = COMPRESSORS[compression]
        self._chunk_size = chunk_size
        self._describe = describe
        self._bio = (open_file or (lambda p: open(p, "xb", buffering=0)))(path)
        self._schemas: dict[str, int] = {}  # msgtype -> schema id
        self._schema_records: list[bytes] = []
        self._channel_records: list[bytes] = []
        self._channels: dict[int, str] = {}  # channel id -> msgtype
        self._pending = _Pending()
        self._chunks: list[Chunk] = []
        self._write(MAGIC + _record(_OP_HEADER, _string("ros2") + _string(library)))
        self._header_end = self._good_end = self._bio.tell()

    # --- writing -------------------------------------------------------------------------
    def add_topic(self, topic_id: int, spec: TopicSpec) -> None:
        """Schema (once per type) and channel, carried by the next chunk and by the summary."""
        if spec.msgtype not in self._schemas:
            schema_id = len(self._schemas) + 1
            self._schemas[spec.msgtype] = schema_id
            encoding = "ros2idl" if spec.definition.startswith("=" * 80 + "\nIDL: ") else "ros2msg"
            record = _record(
                _OP_SCHEMA, struct.pack("<H", schema_id) + _string(spec.msgtype) + _string(encoding) + _string(spec.definition)
            )
            self._schema_records.append(record)
            self._pending.add(record)
        metadata = {"offered_qos_profiles": qos_text(spec.offered_qos), "topic_type_hash": spec.type_hash}
        record = _record(
            _OP_CHANNEL,
            struct.pack("<HH", topic_id, self._schemas[spec.msgtype])
            + _string(spec.name)
            + _string(spec.serialization_format)
            + _string_map(metadata),
        )
        self._channels[topic_id] = spec.msgtype
        self._channel_records.append(record)
        self._pending.add(record)

    def write(self, topic_id: int, timestamp: int, data: bytes) -> None:
        header = struct.pack("<BQHIQQ", _OP_MESSAGE, 22 + len(data), topic_id, 0, timestamp, timestamp)
        self._pending.add(header, topic_id, timestamp)
        self._pending.pieces.append(data)
        self._pending.size += len(data)
        if self._pending.size >= self._chunk_size:
            self.flush()

    def flush(self) -> None:
        """Compress the pending chunk and put it on disk with its message indexes."""
        pending = self._pending
        if not pending.size:
            return
        raw = b"".join(pending.pieces)
        compressed = self._compress(raw)
        start = self._good_end
        chunk_body = (
            struct.pack("<QQQI", pending.start_ns if pending.index else 0, pending.end_ns, len(raw), 0)
            + _string(self.compression)
            + struct.pack("<Q", len(compressed))
        )
        chunk_head = struct.pack("<BQ", _OP_CHUNK, len(chunk_body) + len(compressed)) + chunk_body
        chunk_length = len(chunk_head) + len(compressed)
        indexes, offsets = message_indexes(start + chunk_length, pending.index)
        self._write(chunk_head, compressed, indexes)
        position = start + chunk_length + len(indexes)
        self._chunks.append(
            Chunk(start, position, chunk_length, offsets, len(compressed), len(raw),
                  pending.start_ns, pending.end_ns, {c: len(e) for c, e in pending.index.items()},
                  self.compression)
        )
        self._good_end = position
        self._pending = _Pending()

    @property
    def pending_since(self) -> float | None:
        """time.monotonic() when the oldest message not on disk yet was written; None: none is."""
        return self._pending.since

    @property
    def size(self) -> int:
        """Bytes on disk plus the uncompressed size of the pending chunk (what splitting looks at)."""
        return self._good_end + self._pending.size

    def stats(self) -> tuple[FileStats, dict[int, int]]:
        """Messages that are completely on disk: file statistics and count per topic id."""
        return chunk_stats(self.path.name, self._chunks)

    def close(self) -> None:
        """Flush, then write the summary and footer."""
        self.flush()
        self._write_summary()
        self._bio.close()

    def recover(self) -> None:
        """After a write error: keep every complete chunk, end the file properly, close it.

        Raises OSError only if not even an empty summary fits, which leaves a file that only
        a scanning reader opens (actaim2.bags.salvage)."""
        self._pending = _Pending()
        try:
            while True:
                end = self._chunks[-1].end if self._chunks else self._header_end
                try:
                    self._bio.truncate(end)
                    self._bio.seek(end)
                    self._good_end = end
                    self._write_summary()
                    return
                except OSError:
                    if not self._chunks:
                        raise
                    self._chunks.pop()  # give up the newest chunk to make room for the summary
        finally:
            self._bio.close()

    # --- internals -------------------------------------------------------------------------
    def _write(self, *parts: bytes) -> None:
        data = b"".join(parts) if len(parts) > 1 else parts[0]
        view = memoryview(data)
        while view:
            written = self._bio.write(view)
            if written is None or written <= 0:
                raise OSError(f"short write to {self.path}")
            view = view[written:]

    def _write_summary(self) -> None:
        stats, counts = self.stats()
        self._write(summary(self._good_end, self._schema_records, self._channel_records,
                            sorted(self._channels), self._chunks, self._describe(stats, counts)))


def message_indexes(
    position: int, index: dict[int, list[tuple[int, int]]]
) -> tuple[bytes, dict[int, int]]:
    """The message index records of one chunk, written at ``position`` (right after the chunk),
    from ``index`` (channel id -> (log time, offset in the uncompressed chunk) of each message);
    and the file offset of each channel's record."""
    records, offsets = [], {}
    for channel, entries in sorted(index.items()):
        body = struct.pack("<HI", channel, 16 * len(entries))
        body += b"".join(struct.pack("<QQ", t, o) for t, o in entries)
        offsets[channel] = position + sum(len(r) for r in records)
        records.append(_record(_OP_MESSAGE_INDEX, body))
    return b"".join(records), offsets


def chunk_stats(name: str, chunks: list[Chunk]) -> tuple[FileStats, dict[int, int]]:
    """File statistics and message count per channel id of the file ``name`` made of ``chunks``."""
    stats, counts = FileStats(name), defaultdict(int)
    for chunk in chunks:
        if chunk.channel_counts:
            stats.add(chunk.start_ns)
            stats.add(chunk.end_ns, sum(chunk.channel_counts.values()) - 1)
        for channel, count in chunk.channel_counts.items():
            counts[channel] += count
    return stats, dict(counts)


def summary(
    position: int,
    schema_records: list[bytes],
    channel_records: list[bytes],
    channel_ids: list[int],
    chunks: list[Chunk],
    metadata_text: str,
) -> bytes:
    """Everything that ends a file whose data section ends at ``position`` after ``chunks``: the
    ``rosbag2`` metadata record (``metadata_text``), data end, the summary (schemas, channels,
    chunk indexes, metadata index, statistics), summary offsets, footer and closing magic."""
    stats, counts = chunk_stats("", chunks)
    data_end = _record(_OP_DATA_END, struct.pack("<I", 0))
    metadata_record = _record(
        _OP_METADATA, _string("rosbag2") + _string_map({"serialized_metadata": metadata_text})
    )
    metadata_start = position
    summary_start = metadata_start + len(metadata_record) + len(data_end)
    schemas = b"".join(schema_records)
    channels = b"".join(channel_records)
    chunk_indexes = b"".join(
        _record(
            _OP_CHUNK_INDEX,
            struct.pack("<QQQQ", c.start_ns if c.channel_counts else 0, c.end_ns, c.start,
                        c.chunk_length)
            + struct.pack("<I", 10 * len(c.index_offsets))
            + b"".join(struct.pack("<HQ", ch, o) for ch, o in sorted(c.index_offsets.items()))
            + struct.pack("<Q", c.end - c.start - c.chunk_length)
            + _string(c.compression)
            + struct.pack("<QQ", c.compressed_size, c.uncompressed_size),
        )
        for c in chunks
    )
    metadata_index = _record(
        _OP_METADATA_INDEX,
        struct.pack("<QQ", metadata_start, len(metadata_record)) + _string("rosbag2"),
    )
    channel_counts = b"".join(struct.pack("<HQ", ch, counts.get(ch, 0)) for ch in channel_ids)
    statistics = _record(
        _OP_STATISTICS,
        struct.pack(
            "<QHIIIIQQI", stats.message_count, len(schema_records), len(channel_records), 0, 1,
            len(chunks), stats.start_ns if stats.message_count else 0, stats.end_ns,
            len(channel_counts),
        )
        + channel_counts,
    )
    groups = [(_OP_SCHEMA, schemas), (_OP_CHANNEL, channels), (_OP_CHUNK_INDEX, chunk_indexes),
              (_OP_METADATA_INDEX, metadata_index), (_OP_STATISTICS, statistics)]
    offset, offsets = summary_start, []
    for op, block in groups:
        if block:
            offsets.append(
                _record(_OP_SUMMARY_OFFSET, struct.pack("<BQQ", op, offset, len(block)))
            )
        offset += len(block)
    footer = _record(_OP_FOOTER, struct.pack("<QQI", summary_start, offset, 0))
    blocks = [block for _, block in groups]
    return b"".join([metadata_record, data_end, *blocks, *offsets, footer, MAGIC])
