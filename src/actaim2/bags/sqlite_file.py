"""One sqlite3 storage file of a rosbag2 bag, in the layout of Jazzy's rosbag2 (schema version 4).

Messages are committed every ``commit_bytes`` of payload, at close, and whenever the caller
calls :meth:`SqliteFile.flush` (the recorder does once the oldest uncommitted message has waited
``max_chunk_age``), so a crash or a full disk loses at most the last uncommitted batch: sqlite's
rollback journal keeps the committed part consistent. ``stats()`` counts committed messages
only, which is what a reader will find. A file whose process died has no ``metadata`` row and
maybe a hot journal: :func:`read` (opening it read-write rolls the journal back) and
:func:`store_metadata` finish it (``actaim2 bag-reindex``).
"""
from __future__ import annotations

import sqlite3
import time
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

from actaim2.bags.metadata import VERSION, FileStats, TopicSpec, qos_from_text, qos_text

SCHEMA_VERSION = 4
_TABLES = """
CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL, metadata TEXT NOT NULL);
CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
  serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL, type_description_hash TEXT NOT NULL);
CREATE TABLE message_definitions(id INTEGER PRIMARY KEY, topic_type TEXT NOT NULL, encoding TEXT NOT NULL,
  encoded_message_definition TEXT NOT NULL, type_description_hash TEXT NOT NULL);
CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, timestamp INTEGER NOT NULL, data BLOB NOT NULL);
CREATE INDEX timestamp_idx ON messages (timestamp ASC);
"""


class SqliteFile:
    """Writes one .db3 file; ``describe(stats, topic_counts)`` gives the metadata text stored in it."""

    storage = "sqlite3"
    suffix = ".db3"

    def __init__(self, path: Path, ros_distro: str, describe, commit_bytes: int = 32 * 2**20) -> None:
        if path.exists():
            raise FileExistsError(f"{path} exists already")
        self.path = path
        self._describe = describe
        self._commit_bytes = commit_bytes
        self._conn = sqlite3.connect(path, isolation_level=None, check_same_thread=False)
        self._conn.execute("PRAGMA synchronous=OFF")  # a crashed process is covered by the journal
        self._conn.executescript(_TABLES)
        self._conn.execute("INSERT INTO schema VALUES (?, ?)", (SCHEMA_VERSION, ros_distro))
        self._types: set[str] = set()
        self._committed, self._committed_counts = FileStats(path.name), defaultdict(int)
        self._batch: list[tuple[int, int, bytes]] = []
        self._pending_bytes = 0
        self.pending_since: float | None = None  # time.monotonic(): oldest uncommitted message

    def add_topic(self, topic_id: int, spec: TopicSpec) -> None:
        self.flush()
        if spec.msgtype not in self._types:
            self._types.add(spec.msgtype)
            encoding = "ros2idl" if spec.definition.startswith("=" * 80 + "\nIDL: ") else "ros2msg"
            self._conn.execute(
                "INSERT INTO message_definitions (topic_type, encoding, encoded_message_definition, type_description_hash)"
                " VALUES (?, ?, ?, ?)", (spec.msgtype, encoding, spec.definition, spec.type_hash),
            )
        self._conn.execute(
            "INSERT INTO topics VALUES (?, ?, ?, ?, ?, ?)",
            (topic_id, spec.name, spec.msgtype, spec.serialization_format, qos_text(spec.offered_qos), spec.type_hash),
        )

    def write(self, topic_id: int, timestamp: int, data: bytes) -> None:
        if self.pending_since is None:
            self.pending_since = time.monotonic()
        self._batch.append((topic_id, timestamp, data))
        self._pending_bytes += len(data)
        if self._pending_bytes >= self._commit_bytes:
            self.flush()

    def flush(self) -> None:
        """Commit the messages written since the last commit."""
        if not self._batch:
            return
        batch = self._batch
        self._conn.execute("BEGIN")
        try:
            self._conn.executemany("INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)", batch)
            self._conn.execute("COMMIT")
        except sqlite3.Error:
            self._conn.execute("ROLLBACK")
            raise
        for topic_id, timestamp, _ in batch:
            self._committed.add(timestamp)
            self._committed_counts[topic_id] += 1
        self._batch = []
        self._pending_bytes = 0
        self.pending_since = None

    @property
    def size(self) -> int:
        return self.path.stat().st_size + self._pending_bytes

    def stats(self) -> tuple[FileStats, dict[int, int]]:
        return self._committed, dict(self._committed_counts)

    def close(self) -> None:
        self.flush()
        stats, counts = self.stats()
        _insert_metadata(self._conn, self._describe(stats, counts))
        self._conn.close()

    def recover(self) -> None:
        """After a write error: drop the uncommitted batch; the committed messages stay readable."""
        self._batch = []
        self._pending_bytes = 0
        self.pending_since = None
        try:
            if self._conn.in_transaction:
                self._conn.execute("ROLLBACK")
        finally:
            self._conn.close()


def _insert_metadata(conn: sqlite3.Connection, text: str) -> None:
    conn.execute("INSERT INTO metadata(metadata_version, metadata) VALUES (?, ?)", (VERSION, text))


@dataclass
class SqliteContents:
    """What a .db3 file holds, read back from its tables."""

    topics: dict[int, TopicSpec]  # topic id -> spec
    stats: FileStats
    counts: dict[int, int]  # messages per topic id
    ros_distro: str
    has_metadata: bool  # the ``metadata`` row its writer stores at close


def read(path: Path) -> SqliteContents:
    """Topics, message counts and time range of a rosbag2 schema-4 file. Opened read-write, so
    that a rollback journal left by a process that died is rolled back first."""
    conn = sqlite3.connect(path)
    try:
        definitions = dict(
            conn.execute("SELECT topic_type, encoded_message_definition FROM message_definitions")
        )
        topics = {
            row[0]: TopicSpec(row[1], row[2], definitions.get(row[2], ""), row[5],
                              qos_from_text(row[4]), row[3])
            for row in conn.execute(
                "SELECT id, name, type, serialization_format, offered_qos_profiles,"
                " type_description_hash FROM topics ORDER BY id"
            )
        }
        stats, counts = FileStats(path.name), {}
        for topic_id, count, first, last in conn.execute(
            "SELECT topic_id, COUNT(*), MIN(timestamp), MAX(timestamp) FROM messages"
            " GROUP BY topic_id"
        ):
            counts[topic_id] = count
            stats.add(first)
            stats.add(last, count - 1)
        (ros_distro,) = conn.execute("SELECT ros_distro FROM schema").fetchone()
        (metadata_rows,) = conn.execute("SELECT COUNT(*) FROM metadata").fetchone()
    finally:
        conn.close()
    return SqliteContents(topics, stats, counts, ros_distro, metadata_rows > 0)


def store_metadata(path: Path, text: str) -> None:
    """Store the bag's metadata in a file whose writer died before storing it at close."""
    conn = sqlite3.connect(path, isolation_level=None)
    try:
        _insert_metadata(conn, text)
    finally:
        conn.close()
