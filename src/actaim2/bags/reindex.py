"""``actaim2 bag-reindex DIR...``: rebuild a bag's metadata.yaml from its storage files, as
``ros2 bag reindex`` does, after its recorder died (SIGKILL, out of memory, a power cut) or when
metadata.yaml was lost.

A recorder that dies leaves its current storage file unfinished, and a metadata.yaml (written
when the bag opened and whenever a split file was finished) that describes less than the bag
holds, if any. Each unfinished file is finished in place first, as its writer would have at
close; files their writer finished are only read:

* MCAP without summary and footer, which indexed readers (rosbags, the mcap package) refuse:
  what follows its last complete chunk is cut, the rest is kept and indexed
  (:func:`actaim2.bags.salvage.finish`);
* sqlite3 without the ``metadata`` row stored at close: a rollback journal the crash left is
  rolled back, the row is stored (:mod:`actaim2.bags.sqlite_file`).

metadata.yaml then describes every file, in the order of the split index in its name
(``<bag>_<n>``), exactly as the writer writes it. Run it on a bag whose recorder has ended.
"""
from __future__ import annotations

import argparse
import sqlite3
import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from actaim2.bags import metadata as md
from actaim2.bags import salvage, sqlite_file, yaml_emit
from actaim2.bags.mcap_file import McapFile, chunk_stats
from actaim2.bags.metadata import FileStats, TopicSpec, qos_from_text
from actaim2.bags.sqlite_file import SqliteFile

STORAGE_OF_SUFFIX = {McapFile.suffix: McapFile.storage, SqliteFile.suffix: SqliteFile.storage}


@dataclass
class _Contents:
    """One storage file as read back: what metadata.yaml needs, and how to finish it."""

    topics: dict[int, TopicSpec]  # by the file's topic (channel) id
    stats: FileStats
    counts: dict[int, int]  # messages per topic id
    ros_distro: str
    finish: Callable[[str], str] | None  # metadata text -> what was done; None: finished already


def _read_mcap(path: Path) -> _Contents:
    scanned = salvage.scan(path)
    topics = {
        cid: TopicSpec(c.topic, c.msgtype, c.definition, c.metadata.get("topic_type_hash", ""),
                       qos_from_text(c.metadata.get("offered_qos_profiles", "")),
                       c.message_encoding)
        for cid, c in sorted(scanned.channels.items())
    }
    stats, counts = chunk_stats(path.name, scanned.chunks)

    def finish(text: str) -> str:
        cut = salvage.finish(path, scanned, text)
        after = f"the {cut} byte(s) after them cut" if cut else "nothing after them"
        return (f"not finished by its writer ({scanned.reason or 'no footer'}): "
                f"{stats.message_count} message(s) in {len(scanned.chunks)} complete chunk(s) "
                f"kept, {after}, summary written")

    return _Contents(topics, stats, counts, md.DEFAULT_ROS_DISTRO,
                     None if scanned.finished else finish)


def _read_sqlite(path: Path) -> _Contents:
    contents = sqlite_file.read(path)

    def finish(text: str) -> str:
        sqlite_file.store_metadata(path, text)
        return (f"not finished by its writer: {contents.stats.message_count} committed message(s) "
                "kept, metadata stored")

    return _Contents(contents.topics, contents.stats, contents.counts, contents.ros_distro,
                     None if contents.has_metadata else finish)


def _split_index(path: Path) -> tuple[int, str]:
    number = path.stem.rsplit("_", 1)[-1]
    return (int(number) if number.isdigit() else -1, path.name)


def reindex(bag: Path, report: Callable[[str], None]) -> dict:
    """Finish the unfinished storage files of the bag directory ``bag`` and write its
    metadata.yaml; returns the metadata document. ``report`` gets one line per file."""
    if not bag.is_dir():
        raise FileNotFoundError(f"{bag}: no such bag directory")
    paths = sorted((p for p in bag.iterdir() if p.suffix in STORAGE_OF_SUFFIX), key=_split_index)
    storages = {STORAGE_OF_SUFFIX[p.suffix] for p in paths}
    if len(storages) != 1:
        found = "both .mcap and .db3 files" if storages else "no .mcap or .db3 file"
        raise ValueError(f"{bag}: {found}: not one rosbag2 bag")
    (storage,) = storages
    topics: dict[str, TopicSpec] = {}  # by name, in the order they first appear
    counts: dict[str, int] = defaultdict(int)
    files: list[FileStats] = []
    body: dict = {}
    for path in paths:
        contents = _read_mcap(path) if storage == McapFile.storage else _read_sqlite(path)
        for topic_id, spec in contents.topics.items():
            topics.setdefault(spec.name, spec)
            counts[spec.name] += contents.counts.get(topic_id, 0)
        files.append(contents.stats)
        # each file stores the bag as of its own end, as the writer does
        body = md.document(storage, list(topics.values()), [counts[n] for n in topics], files,
                           contents.ros_distro)
        if contents.finish is None:
            report(f"{path.name}: {contents.stats.message_count} message(s), finished by its "
                   "writer (only read)")
        else:
            report(f"{path.name}: {contents.finish(yaml_emit.dump(body))}")
    md.write_metadata_yaml(bag, body)
    return body


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bags", nargs="+", type=Path, metavar="DIR",
                        help="bag directories (each holds the .mcap or .db3 files of one bag)")


def main(args: argparse.Namespace) -> int:
    failed = 0
    for bag in args.bags:
        print(f"{bag}:")
        try:
            body = reindex(bag, lambda line: print(f"  {line}"))
        except (OSError, ValueError, sqlite3.Error) as exc:
            print(f"  cannot be reindexed: {exc}", file=sys.stderr)
            failed += 1
            continue
        print(f"  metadata.yaml written: {body['message_count']} message(s) in "
              f"{len(body['files'])} file(s)")
    return 1 if failed else 0
