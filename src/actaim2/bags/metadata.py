"""The rosbag2 version-9 metadata document: what metadata.yaml holds and what every MCAP file
carries in its ``rosbag2`` metadata record.

Key order and value forms follow the files Jazzy's rosbag2 writes (see
../shared/bags-reference/README.md): QoS as a list of maps with enum names, infinite durations
as ``sec: 9223372036, nsec: 854775807``, ``starting_time`` of an empty bag = 2**63 - 1.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from rosbags.interfaces import Qos
from rosbags.rosbag2.metadata import dump_qos_v9, parse_qos

from actaim2.bags import yaml_emit

VERSION = 9
DEFAULT_ROS_DISTRO = "jazzy"  # what the bags are written for (sqlite3 files store theirs)
NO_MESSAGES_START = 2**63 - 1  # rosbag2's starting_time while a file holds no message yet


@dataclass
class TopicSpec:
    """One recorded topic: what readers need to decode and re-publish it."""

    name: str
    msgtype: str  # "sensor_msgs/msg/PointCloud2"
    definition: str  # rosbag2's concatenated .msg text (definitions.py)
    type_hash: str  # "RIHS01_..."; "" when unknown, as rosbag2 writes it then
    offered_qos: list[Qos] = field(default_factory=list)
    serialization_format: str = "cdr"


@dataclass
class FileStats:
    """Time range and count of the messages one storage file holds."""

    path: str  # relative to the bag directory
    start_ns: int = NO_MESSAGES_START
    end_ns: int = 0
    message_count: int = 0

    def add(self, timestamp: int, count: int = 1) -> None:
        self.start_ns = min(self.start_ns, timestamp)
        self.end_ns = max(self.end_ns, timestamp)
        self.message_count += count

    @property
    def duration_ns(self) -> int:
        return self.end_ns - self.start_ns if self.message_count else 0


def qos_list(profiles: list[Qos]) -> list[dict]:
    return [dict(p) for p in dump_qos_v9(profiles)]


def qos_text(profiles: list[Qos]) -> str:
    """QoS as the YAML string MCAP channels carry in ``offered_qos_profiles``."""
    return yaml_emit.dump(qos_list(profiles))


def qos_from_text(text: str) -> list[Qos]:
    """The QoS of a channel's or topic row's ``offered_qos_profiles`` text; [] when absent or
    unreadable (QoS is advisory: a player falls back to defaults)."""
    try:
        return parse_qos(text) if text else []
    except Exception:  # noqa: BLE001 - rosbags raises several types for a bad QoS text
        return []


def document(
    storage: str,
    topics: list[TopicSpec],
    topic_counts: list[int],
    files: list[FileStats],
    ros_distro: str,
) -> dict:
    """The body of ``rosbag2_bagfile_information`` for a bag made of ``files``."""
    total = FileStats("")
    for f in files:
        if f.message_count:
            total.add(f.start_ns)
            total.add(f.end_ns, f.message_count - 1)
    return {
        "version": VERSION,
        "storage_identifier": storage,
        "duration": {"nanoseconds": total.duration_ns},
        "starting_time": {"nanoseconds_since_epoch": total.start_ns},
        "message_count": total.message_count,
        "topics_with_message_count": [
            {
                "topic_metadata": {
                    "name": t.name,
                    "type": t.msgtype,
                    "serialization_format": t.serialization_format,
                    "offered_qos_profiles": qos_list(t.offered_qos),
                    "type_description_hash": t.type_hash,
                },
                "message_count": count,
            }
            for t, count in zip(topics, topic_counts)
        ],
        # Chunk compression is internal to the MCAP files: readers must not decompress anything.
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [f.path for f in files],
        "files": [
            {
                "path": f.path,
                "starting_time": {"nanoseconds_since_epoch": f.start_ns},
                "duration": {"nanoseconds": f.duration_ns},
                "message_count": f.message_count,
            }
            for f in files
        ],
        "custom_data": None,
        "ros_distro": ros_distro,
    }


def metadata_yaml(body: dict) -> str:
    """metadata.yaml text (rosbag2 writes no final newline)."""
    return yaml_emit.dump({"rosbag2_bagfile_information": body})


def write_metadata_yaml(bag: Path, body: dict) -> None:
    """(Re)write ``bag``/metadata.yaml with ``body``; a reader never sees half a file."""
    target = bag / "metadata.yaml"
    tmp = target.with_suffix(".yaml.tmp")
    tmp.write_text(metadata_yaml(body))
    os.replace(tmp, target)
