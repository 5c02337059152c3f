"""Messages from an MCAP file that ends early (a recorder killed with SIGKILL, a copy cut short).

Indexed readers (rosbags, the mcap package) start from the footer and refuse such a file. This
scanner walks the records from the start instead and stops at the first one that is incomplete
or does not decode; everything before it is returned. Used by :mod:`actaim2.bags.source` only
after rosbags has refused a file.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

from rosbags.rosbag2.errors import ReaderError
from rosbags.rosbag2.storage_mcap import decompress

from actaim2.bags.mcap_file import MAGIC


@dataclass
class SalvagedChannel:
    topic: str
    msgtype: str
    definition: str
    metadata: dict[str, str]


@dataclass
class SalvageScan:
    channels: dict[int, SalvagedChannel] = field(default_factory=dict)
    counts: dict[int, int] = field(default_factory=dict)
    start_ns: int | None = None  # earliest message time
    stopped_at: int = 0  # byte offset of the first damaged or missing record
    reason: str = ""


def _string(buf: bytes, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, pos)
    return buf[pos + 4 : pos + 4 + n].decode(), pos + 4 + n


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


def _walk(path: Path, scan: SalvageScan, want_messages: bool) -> Iterator[tuple[int, int, bytes]]:
    data = path.read_bytes()
    if not data.startswith(MAGIC):
        scan.reason = "not an MCAP file (bad magic)"
        return
    schemas: dict[int, tuple[str, str]] = {}
    position = len(MAGIC)
    scan.stopped_at, scan.reason = len(data), ""
    for op, body, end, record_start in _records(data, position):
        position = end
        try:
            inner = [(op, body, end, data)]
            if op == 0x06:  # chunk: decompress and walk its records
                _, _, size, crc = struct.unpack_from("<QQQI", data, body)
                compression, pos = _string(data, body + 28)
                (compressed_size,) = struct.unpack_from("<Q", data, pos)
                raw = decompress(data[pos + 8 : pos + 8 + compressed_size], compression, size, crc)
                inner = [(o, b, e, raw) for o, b, e, _ in _records(raw)]
            for iop, ib, ie, buf in inner:
                if iop == 0x03:
                    (sid,) = struct.unpack_from("<H", buf, ib)
                    name, p = _string(buf, ib + 2)
                    _, p = _string(buf, p)
                    definition, _ = _string(buf, p)
                    schemas[sid] = (name, definition)
                elif iop == 0x04:
                    cid, sid = struct.unpack_from("<HH", buf, ib)
                    topic, p = _string(buf, ib + 4)
                    _, p = _string(buf, p)
                    metadata, _ = _string_map(buf, p)
                    name, definition = schemas.get(sid, ("", ""))
                    scan.channels.setdefault(cid, SalvagedChannel(topic, name, definition, metadata))
                elif iop == 0x05:
                    cid, _, log_time = struct.unpack_from("<HIQ", buf, ib)
                    scan.counts[cid] = scan.counts.get(cid, 0) + 1
                    scan.start_ns = log_time if scan.start_ns is None else min(scan.start_ns, log_time)
                    if want_messages:
                        yield cid, log_time, bytes(buf[ib + 22 : ie])
        except (struct.error, UnicodeDecodeError, ReaderError, ValueError) as exc:
            scan.stopped_at, scan.reason = record_start, f"record at byte {record_start} does not decode: {exc}"
            return
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
