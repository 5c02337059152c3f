"""Messages from an MCAP file that ends early (a recorder killed with SIGKILL, a copy cut short),
and finishing such a file so that indexed readers open it again.

Indexed readers (rosbags, the mcap package) start from the footer and refuse such a file. This
scanner walks the records from the start instead and stops at the first one that is incomplete
or does not decode; everything before it is returned. :mod:`actaim2.bags.source` plays a file
this way after rosbags has refused it; :func:`finish` (``actaim2 bag-reindex``) cuts the file
after its last complete chunk and writes what its writer would have written at close: the
chunk's message indexes if they were cut short, the summary and the footer. Files are chunked,
as rosbag2 and :mod:`actaim2.bags.mcap_file` write them. The file is mapped, not read, so a
large bag does not have to fit in memory.
"""
from __future__ import annotations

import mmap
import struct
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

from rosbags.rosbag2.errors import ReaderError
from rosbags.rosbag2.storage_mcap import decompress

from actaim2.bags.mcap_file import MAGIC, Chunk, message_indexes, summary

_FOOTER_HEAD = struct.pack("<BQ", 0x02, 20)  # op and length of a footer record


@dataclass
class SalvagedChannel:
    topic: str
    msgtype: str
    definition: str
    metadata: dict[str, str]
    message_encoding: str  # "cdr": rosbag2's serialization format


@dataclass
class SalvageScan:
    channels: dict[int, SalvagedChannel] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)
    start_ns: int | None = None  # earliest message time
    stopped_at: int = 0  # byte offset of the first damaged or missing record
    reason: str = ""
    finished: bool = False  # the file ends with a footer: its writer closed it
    header_end: int = 0  # byte offset after the header record
    # schema / channel id -> the record as written
    schema_records: dict[int, bytes] = field(default_factory=dict)
    channel_records: dict[int, bytes] = field(default_factory=dict)
    chunks: list[Chunk] = field(default_factory=list)  # complete chunk records, in file order
    # the last chunk's message index: channel id -> (log time, offset in the uncompressed chunk)
    last_index: dict[int, list[tuple[int, int]]] = field(default_factory=dict)


def _string(buf: bytes, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, pos)
    return bytes(buf[pos + 4 : pos + 4 + n]).decode(), pos + 4 + n


def _string_map(buf: bytes, pos: int) -> tuple[dict[str, str], int]:
    (n,) = struct.unpack_from("<I", buf, pos)
    end, out, pos = pos + 4 + n, {}, pos + 4
    while pos < end:
        key, pos = _string(buf, pos)
        out[key], pos = _string(buf, pos)
    return out, end


def _records(buf: bytes, start: int = 0) -> Iterator[tuple[int, int, int, int]]:
    """(op, body start, body end, record start) of every complete record in ``buf``."""
    pos = start
    while pos + 9 <= len(buf):
        op, length = struct.unpack_from("<BQ", buf, pos)
        if pos + 9 + length > len(buf):
            return
        yield op, pos + 9, pos + 9 + length, pos
        pos += 9 + length


def _walk(
    path: Path, scan: SalvageScan, want_messages: bool
) -> Iterator[tuple[int, int, bytes]]:
    with open(path, "rb") as f:
        if f.seek(0, 2) < len(MAGIC):
            scan.reason = "not an MCAP file (bad magic)"
            return
        with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as data:
            yield from _walk_data(data, scan, want_messages)


def _walk_data(
    data: mmap.mmap, scan: SalvageScan, want_messages: bool
) -> Iterator[tuple[int, int, bytes]]:
    if data[: len(MAGIC)] != MAGIC:
        scan.reason = "not an MCAP file (bad magic)"
        return
    scan.finished = (len(data) >= 2 * len(MAGIC) + 29 and data[-37:-28] == _FOOTER_HEAD
                     and data[-8:] == MAGIC)
    schemas: dict[int, tuple[str, str]] = {}
    position = len(MAGIC)
    scan.stopped_at, scan.reason = len(data), ""
    for op, body, end, record_start in _records(data, position):
        position = end
        index: dict[int, list[tuple[int, int]]] = defaultdict(list)  # of a chunk, as last_index
        try:
            inner = [(op, body, end, record_start, data)]
            if op == 0x01:
                scan.header_end = end
            elif op == 0x06:  # chunk: decompress and walk its records
                start_ns, end_ns, size, crc = struct.unpack_from("<QQQI", data, body)
                compression, pos = _string(data, body + 28)
                (compressed_size,) = struct.unpack_from("<Q", data, pos)
                raw = decompress(data[pos + 8 : pos + 8 + compressed_size], compression, size, crc)
                inner = [(o, b, e, s, raw) for o, b, e, s in _records(raw)]
            elif op == 0x07 and scan.chunks:  # a message index of the chunk just read
                (cid,) = struct.unpack_from("<H", data, body)
                scan.chunks[-1].index_offsets[cid] = record_start
                scan.chunks[-1].end = end
            for iop, ib, ie, istart, buf in inner:
                if iop == 0x03:
                    (sid,) = struct.unpack_from("<H", buf, ib)
                    name, p = _string(buf, ib + 2)
                    _, p = _string(buf, p)
                    definition, _ = _string(buf, p)
                    schemas[sid] = (name, definition)
                    scan.schema_records.setdefault(sid, bytes(buf[istart:ie]))
                elif iop == 0x04:
                    cid, sid = struct.unpack_from("<HH", buf, ib)
                    topic, p = _string(buf, ib + 4)
                    encoding, p = _string(buf, p)
                    metadata, _ = _string_map(buf, p)
                    name, definition = schemas.get(sid, ("", ""))
                    channel = SalvagedChannel(topic, name, definition, metadata, encoding)
                    scan.channels.setdefault(cid, channel)
                    scan.channel_records.setdefault(cid, bytes(buf[istart:ie]))
                elif iop == 0x05:
                    cid, _, log_time = struct.unpack_from("<HIQ", buf, ib)
                    scan.counts[cid] = scan.counts.get(cid, 0) + 1
                    scan.start_ns = log_time if scan.start_ns is None else min(scan.start_ns, log_time)
                    if op == 0x06:
                        index[cid].append((log_time, istart))
                    if want_messages:
                        yield cid, log_time, bytes(buf[ib + 22 : ie])
        except (struct.error, UnicodeDecodeError, ReaderError, ValueError) as exc:
            scan.stopped_at = record_start
            scan.reason = f"record at byte {record_start} does not decode: {exc}"
            return
        if op == 0x06:
            counts = {c: len(e) for c, e in index.items()}
            scan.chunks.append(Chunk(record_start, end, end - record_start, {}, compressed_size,
                                     size, start_ns, end_ns, counts, compression))
            scan.last_index = dict(index)
        if op == 0x0F:  # data end: the summary follows
            scan.stopped_at = len(data)
            return
    if position < len(data):
        scan.stopped_at, scan.reason = position, f"file ends inside a record at byte {position}"
    else:
        scan.reason = "no summary (the writer did not finish the file)"


def scan(path: Path) -> SalvageScan:
    """Channels and message counts of the readable part (message bytes are not kept)."""
    result = SalvageScan()
    for _ in _walk(path, result, want_messages=False):
        pass
    return result


def messages(path: Path) -> Iterator[tuple[int, int, bytes]]:
    """(channel id, log time ns, CDR bytes) of the readable part, in file order."""
    yield from _walk(path, SalvageScan(), want_messages=True)


def finish(path: Path, scanned: SalvageScan, metadata_text: str) -> int:
    """End the file its writer did not finish (``scanned`` = :func:`scan` of it) as the writer
    would have: cut it after its last complete chunk (and that chunk's message indexes, which are
    written again if they were cut short), then write the summary with ``metadata_text`` as its
    ``rosbag2`` metadata. Returns the number of bytes cut."""
    if not scanned.header_end:
        raise ValueError(f"{path}: no MCAP header ({scanned.reason})")
    chunks, tail = scanned.chunks, b""
    end = chunks[-1].end if chunks else scanned.header_end  # after the last chunk and its indexes
    if chunks and set(chunks[-1].index_offsets) != set(chunks[-1].channel_counts):
        last = chunks[-1]
        end = last.start + last.chunk_length
        tail, last.index_offsets = message_indexes(end, scanned.last_index)
        last.end = end + len(tail)
    with open(path, "r+b") as f:
        size = f.seek(0, 2)
        f.truncate(end)
        f.seek(end)
        schemas = [scanned.schema_records[k] for k in sorted(scanned.schema_records)]
        channels = [scanned.channel_records[k] for k in sorted(scanned.channel_records)]
        f.write(tail + summary(end + len(tail), schemas, channels, sorted(scanned.channel_records),
                               chunks, metadata_text))
    return size - end
