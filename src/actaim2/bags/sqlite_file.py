"""One sqlite3 storage file of a rosbag2 bag, in the layout of Jazzy's rosbag2 (schema version 4).

Messages are committed every ``commit_bytes`` of payload (and at close), so a crash or a full
disk loses at most the last uncommitted batch: sqlite's rollback journal keeps the committed
part consistent. ``stats()`` counts committed messages only, which is what a reader will find.
"""
from __future__ import annotations

import sqlite3
from collections import defaultdict
from pathlib import Path

from actaim2.bags.metadata import VERSION, FileStats, TopicSpec, qos_text

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

    def add_topic(self, topic_id: int, spec: TopicSpec) -> None:
        self._commit()
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
        self._batch.append((topic_id, timestamp, data))
        self._pending_bytes += len(data)
        if self._pending_bytes >= self._commit_bytes:
            self._commit()

    def _commit(self) -> None:
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

    @property
    def size(self) -> int:
        return self.path.stat().st_size + self._pending_bytes

    def stats(self) -> tuple[FileStats, dict[int, int]]:
        return self._committed, dict(self._committed_counts)

    def close(self) -> None:
        self._commit()
        stats, counts = self.stats()
        self._conn.execute("INSERT INTO metadata(metadata_version, metadata) VALUES (?, ?)", (VERSION, self._describe(stats, counts)))
        self._conn.close()

    def recover(self) -> None:
        """After a write error: drop the uncommitted batch; the committed messages stay readable."""
        self._batch = []
        self._pending_bytes = 0
        try:
            if self._conn.in_transaction:
                self._conn.execute("ROLLBACK")
        finally:
            self._conn.close()
