"""A bag opened for replay: its topics and their recorded QoS, then its messages, checked one by one.

Nothing in a bag is fatal. Each problem is reported (``report(text)``) with the topic and the
message index it concerns, and only that part is skipped:

* a topic whose type definition ``rosbags`` cannot parse (the service events of Jazzy-era
  rosbag2 store the raw .srv text), or whose definition the bag lacks;
* a message that does not deserialize with its topic's definition (index = its position
  among that topic's messages, 0-based);
* a storage file that rosbags cannot open: an MCAP file that ends early is read up to the
  damage (:mod:`actaim2.bags.salvage`); any other such file is skipped;
* a storage file listed in metadata.yaml but missing, or there but not listed (skipped);
* an error in the middle of a file: the rest of that file is skipped.

A bag directory without a readable metadata.yaml is refused with the command that rebuilds it
(``actaim2 bag-reindex``, :mod:`actaim2.bags.reindex`).

Files are read one at a time, in the order of metadata.yaml (split bags are sequential), each
in timestamp order. A path may also name a single .mcap or .db3 file.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import yaml
from rosbags.interfaces import Connection, MessageDefinitionFormat, Qos
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

from actaim2.bags import salvage
from actaim2.bags.metadata import qos_from_text
from actaim2.bags.reindex import STORAGE_OF_SUFFIX


@dataclass
class PlayTopic:
    name: str
    msgtype: str
    offered_qos: list[Qos]
    count: int
    problem: str | None = None  # why this topic cannot be played


@dataclass(frozen=True)
class BagMessage:
    topic: str
    index: int  # among this topic's messages in the bag, 0-based
    timestamp: int  # ns, as recorded
    data: bytes


@dataclass
class _File:
    path: Path
    connections: list[Connection] | None = None  # None: read with the salvage scanner
    salvaged: salvage.SalvageScan | None = None


class BagSource:
    def __init__(self, path: str | Path, report: Callable[[str], None]) -> None:
        self.path = Path(path)
        self._report = report
        self.topics: dict[str, PlayTopic] = {}
        self._typestore = get_typestore(Stores.EMPTY)
        self._definitions: dict[str, tuple[str, str]] = {}  # msgtype -> (text, format)
        self._starts: list[int] = []
        self._files = [self._open_file(p) for p in self._storage_paths()]
        self._register_types()
        self.start_ns = min(self._starts, default=0)  # the first recorded timestamp

    # --- opening ----------------------------------------------------------------------------
    def _storage_paths(self) -> list[Path]:
        if not self.path.exists():
            raise FileNotFoundError(f"no bag at {self.path}")
        if self.path.is_file():
            return [self.path]
        meta = self.path / "metadata.yaml"
        try:
            info = yaml.safe_load(meta.read_text())["rosbag2_bagfile_information"]
            paths = [self.path / Path(p.strip()).name for p in info["relative_file_paths"]]
        except (OSError, yaml.YAMLError, KeyError, TypeError) as exc:
            what = f"unreadable ({type(exc).__name__}: {exc})" if meta.exists() else "missing"
            raise FileNotFoundError(
                f"{meta} is {what} (its recorder died, or the bag was copied without it): "
                f"`actaim2 bag-reindex {self.path}` rebuilds it from the storage files"
            ) from None
        missing = [p for p in paths if not p.exists()]
        for p in missing:
            self._report(f"{p}: listed in metadata.yaml but missing; skipped")
        for p in sorted(set(self.path.iterdir()) - set(paths)):
            if p.suffix in STORAGE_OF_SUFFIX:  # a split recording's file when its recorder died
                self._report(f"{p}: not listed in metadata.yaml; skipped (`actaim2 bag-reindex "
                             f"{self.path}` adds it)")
        return [p for p in paths if p.exists()]

    def _open_file(self, path: Path) -> _File:
        try:
            with Reader(path) as reader:
                connections = list(reader.connections)
                if reader.message_count:
                    self._starts.append(reader.start_time)
        except Exception as exc:  # noqa: BLE001 - any unreadable file is reported, never fatal
            if path.suffix != ".mcap":
                self._report(f"{path}: cannot be opened ({type(exc).__name__}: {exc}); skipped")
                return _File(path, connections=[])
            scan = salvage.scan(path)
            kept = sum(scan.counts.values())
            bag = self.path if self.path.is_dir() else path.parent
            self._report(f"{path}: damaged ({exc}); {scan.reason}: playing the {kept} message(s) "
                         f"before byte {scan.stopped_at} (`actaim2 bag-reindex {bag}` finishes "
                         "the file if its recorder died)")
            if scan.start_ns is not None:
                self._starts.append(scan.start_ns)
            for cid, channel in scan.channels.items():
                qos = qos_from_text(channel.metadata.get("offered_qos_profiles", ""))
                self._add_topic(channel.topic, channel.msgtype, channel.definition, "ros2msg", qos, scan.counts.get(cid, 0))
            return _File(path, salvaged=scan)
        for c in connections:
            fmt = "ros2idl" if c.msgdef.format == MessageDefinitionFormat.IDL else "ros2msg"
            self._add_topic(c.topic, c.msgtype, c.msgdef.data, fmt, list(c.ext.offered_qos_profiles), c.msgcount)
        return _File(path, connections=connections)

    def _add_topic(self, topic: str, msgtype: str, definition: str, fmt: str, qos: list[Qos], count: int) -> None:
        if topic in self.topics:
            self.topics[topic].count += count
            return
        self.topics[topic] = PlayTopic(topic, msgtype, qos, count)
        self._definitions.setdefault(msgtype, (definition, fmt))

    def _register_types(self) -> None:
        for topic in self.topics.values():
            definition, fmt = self._definitions.get(topic.msgtype, ("", "ros2msg"))
            if topic.msgtype in self._typestore.fielddefs:
                continue
            if not definition:
                topic.problem = f"the bag holds no definition of {topic.msgtype}"
            else:
                try:
                    parse = get_types_from_idl if fmt == "ros2idl" else get_types_from_msg
                    types = parse(definition, topic.msgtype)
                    self._typestore.register({k: v for k, v in types.items() if k not in self._typestore.fielddefs})
                except Exception as exc:  # noqa: BLE001 - rosbags raises several types for a bad schema
                    first_line = str(exc).splitlines()[0] if str(exc) else ""
                    topic.problem = f"rosbags cannot parse the definition of {topic.msgtype} ({type(exc).__name__}: {first_line})"
            if topic.problem:
                self._report(f"topic {topic.name}: {topic.problem}; its {topic.count} message(s) are skipped")
        for topic in self.topics.values():  # topics sharing a type that failed above
            if topic.problem is None and topic.msgtype not in self._typestore.fielddefs:
                topic.problem = f"no usable definition of {topic.msgtype}"

    # --- reading -----------------------------------------------------------------------------
    def playable(self) -> list[PlayTopic]:
        return [t for t in self.topics.values() if t.problem is None]

    def messages(self, topics: set[str], start_ns: int = 0) -> Iterator[BagMessage]:
        """Valid messages of ``topics`` at or after ``start_ns``, file by file, in time order."""
        index = {t: 0 for t in topics}
        for f in self._files:
            try:
                for topic, timestamp, data in self._raw(f, topics):
                    i = index[topic]
                    index[topic] += 1
                    if timestamp < start_ns:
                        continue
                    msgtype = self.topics[topic].msgtype
                    try:
                        self._typestore.deserialize_cdr(data, msgtype)
                    except Exception as exc:  # noqa: BLE001 - any decoding failure means a bad message
                        self._report(f"topic {topic} message {i}: does not deserialize as {msgtype} ({exc}); skipped")
                        continue
                    yield BagMessage(topic, i, timestamp, data)
            except Exception as exc:  # noqa: BLE001 - a damaged file ends its own part of the replay only
                self._report(f"{f.path}: reading failed ({type(exc).__name__}: {exc}); the rest of this file is skipped")

    def deserialize(self, message: BagMessage) -> object:
        """A message of :meth:`messages` as a rosbags object, by the definition the bag holds for
        its topic (readers of a bag's content: ``actaim2 bag2dataset``)."""
        return self._typestore.deserialize_cdr(message.data, self.topics[message.topic].msgtype)

    def _raw(self, f: _File, topics: set[str]) -> Iterator[tuple[str, int, bytes]]:
        if f.salvaged is not None:
            names = {cid: c.topic for cid, c in f.salvaged.channels.items()}
            for cid, timestamp, data in salvage.messages(f.path):
                if names.get(cid) in topics:
                    yield names[cid], timestamp, data
            return
        wanted = [c for c in f.connections if c.topic in topics]
        if not wanted:
            return
        with Reader(f.path) as reader:
            by_key = {(c.topic, c.msgtype): c for c in reader.connections}
            selected = [by_key[(c.topic, c.msgtype)] for c in wanted if (c.topic, c.msgtype) in by_key]
            for connection, timestamp, data in reader.messages(connections=selected):
                yield connection.topic, timestamp, bytes(data)

