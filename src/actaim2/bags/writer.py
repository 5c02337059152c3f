"""A rosbag2 bag directory: storage files, splitting by size or duration, metadata.yaml.

Files are named like ``ros2 bag record`` names them, ``<bag>/<bag>_<n>.mcap`` (or ``.db3``).
metadata.yaml is (re)written whenever a file is finished, so a recording that dies later still
describes its finished files; each MCAP file also carries the metadata in its summary. What the
current file holds reaches the disk by size (``chunk_size``) and, through
:meth:`BagWriter.flush_aged`, by age (``max_chunk_age``); after a process dies, ``actaim2
bag-reindex`` (actaim2.bags.reindex) finishes the file and rewrites metadata.yaml.

Use from one thread (the recorder's writer thread). A write error (a full disk, a vanished
directory) raises out of :meth:`BagWriter.write`; :meth:`BagWriter.recover` then finishes the
current file with what is completely on disk and writes metadata.yaml for it.
"""
from __future__ import annotations

import time
from collections import defaultdict
from pathlib import Path
from typing import BinaryIO, Callable

from actaim2.bags import metadata as md
from actaim2.bags import yaml_emit
from actaim2.bags.mcap_file import COMPRESSORS, McapFile
from actaim2.bags.metadata import FileStats, TopicSpec
from actaim2.bags.sqlite_file import SqliteFile

STORAGES = ("mcap", "sqlite3")
COMPRESSIONS = tuple(COMPRESSORS)
DEFAULT_CHUNK_SIZE = 786432  # rosbag2's MCAP default (768 KiB)
DEFAULT_MAX_CHUNK_AGE = 1.0  # s a written message may wait in memory before it goes to disk


class BagWriter:
    def __init__(
        self,
        path: str | Path,
        storage: str = "mcap",
        compression: str = "lz4",
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        max_file_size: int = 0,
        max_file_duration_ns: int = 0,
        ros_distro: str = md.DEFAULT_ROS_DISTRO,
        open_file: Callable[[Path], BinaryIO] | None = None,
        max_chunk_age: float = DEFAULT_MAX_CHUNK_AGE,
    ) -> None:
        """``max_file_size`` (bytes) and ``max_file_duration_ns`` split the bag (0 = never).
        ``open_file`` opens each MCAP file (tests inject a disk that fills up).
        ``max_chunk_age`` (s): :meth:`flush_aged` writes the pending chunk (sqlite3: commits the
        pending batch) once its oldest message has waited this long; 0 = by size only."""
        if storage not in STORAGES:
            raise ValueError(f"unknown storage '{storage}' (use one of {list(STORAGES)})")
        if compression not in COMPRESSIONS:
            raise ValueError(f"unknown compression '{compression}' (use one of {list(COMPRESSIONS)})")
        if storage == "sqlite3" and compression != "none":
            raise ValueError("sqlite3 bags are written uncompressed: use compression 'none' (or storage 'mcap')")
        self.path = Path(path)
        self.path.mkdir(parents=True, exist_ok=False)
        self.storage = storage
        self._compression = compression
        self._chunk_size = chunk_size
        self._max_size = max_file_size
        self._max_duration = max_file_duration_ns
        self._ros_distro = ros_distro
        self._open_file = open_file
        self._max_chunk_age = max_chunk_age
        self.topics: list[TopicSpec] = []
        self._done_files: list[FileStats] = []
        self._done_counts: dict[int, int] = defaultdict(int)
        self._file_first_ns: int | None = None
        self._file = self._open(0)
        self._write_metadata_yaml(self._file.stats())

    # --- public ------------------------------------------------------------------------------
    def add_topic(self, spec: TopicSpec) -> int:
        """Register a topic; returns its id for :meth:`write`."""
        self.topics.append(spec)
        topic_id = len(self.topics)
        self._file.add_topic(topic_id, spec)
        return topic_id

    def write(self, topic_id: int, timestamp: int, data: bytes) -> None:
        if self._file_first_ns is not None and self._split_due(timestamp):
            self._next_file()
        if self._file_first_ns is None:
            self._file_first_ns = timestamp
        self._file.write(topic_id, timestamp, data)

    def flush_aged(self) -> float | None:
        """Put the current file's pending messages on disk if the oldest has waited
        ``max_chunk_age``. Returns when that will be due (``time.monotonic()``), None when no
        message waits (or ages are not looked at)."""
        since = self._file.pending_since
        if since is None or self._max_chunk_age <= 0:
            return None
        due = since + self._max_chunk_age
        if time.monotonic() < due:
            return due
        self._file.flush()
        return None

    def close(self) -> None:
        self._file.close()
        self._finish_file()

    def recover(self) -> None:
        """After a write error: keep what is completely on disk, describe it in metadata.yaml."""
        try:
            self._file.recover()
        finally:
            self._finish_file()

    def counts(self) -> dict[int, int]:
        """Messages per topic id that are on disk now (closed files + complete chunks)."""
        counts = defaultdict(int, self._done_counts)
        for topic_id, count in (self._file.stats()[1] if self._file else {}).items():
            counts[topic_id] += count
        return dict(counts)

    @property
    def files(self) -> list[Path]:
        return [self.path / f.path for f in self._done_files] + ([self._file.path] if self._file else [])

    # --- internals -------------------------------------------------------------------------
    def _open(self, index: int) -> McapFile | SqliteFile:
        name = f"{self.path.name}_{index}"
        if self.storage == "mcap":
            return McapFile(self.path / f"{name}.mcap", self._compression, self._chunk_size, self._describe, self._open_file)
        return SqliteFile(self.path / f"{name}.db3", self._ros_distro, self._describe)

    def _split_due(self, timestamp: int) -> bool:
        return bool(
            (self._max_size and self._file.size >= self._max_size)
            or (self._max_duration and timestamp - self._file_first_ns >= self._max_duration)
        )

    def _next_file(self) -> None:
        self._file.close()
        index = len(self._done_files) + 1
        self._finish_file()
        self._file = self._open(index)
        self._file_first_ns = None
        for topic_id, spec in enumerate(self.topics, start=1):
            self._file.add_topic(topic_id, spec)

    def _finish_file(self) -> None:
        stats, counts = self._file.stats()
        self._done_files.append(stats)
        for topic_id, count in counts.items():
            self._done_counts[topic_id] += count
        self._file = None
        self._write_metadata_yaml(None)

    def _document(self, current: tuple[FileStats, dict[int, int]] | None) -> dict:
        files, counts = list(self._done_files), defaultdict(int, self._done_counts)
        if current is not None:
            files.append(current[0])
            for topic_id, count in current[1].items():
                counts[topic_id] += count
        return md.document(
            self.storage, self.topics, [counts[i] for i in range(1, len(self.topics) + 1)], files, self._ros_distro
        )

    def _describe(self, stats: FileStats, counts: dict[int, int]) -> str:
        """The metadata a storage file stores about the bag (as of this file's end)."""
        return yaml_emit.dump(self._document((stats, counts)))

    def _write_metadata_yaml(self, current: tuple[FileStats, dict[int, int]] | None) -> None:
        md.write_metadata_yaml(self.path, self._document(current))
