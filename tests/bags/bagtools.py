"""Helpers of the bag tests: messages serialized by rosbags (exact CDR; rclpy's serialize_message
appends stray padding bytes that strict readers refuse), topic specs from the installed
definitions, the two readers we did not write, a disk that fills up, and the Jazzy reference
bags (../shared/bags-reference)."""
from __future__ import annotations

import errno
import io
import os
from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.typesys import Stores, get_typestore

from actaim2.bags.definitions import MessageDefinitions
from actaim2.bags.metadata import TopicSpec
from actaim2.bags.writer import BagWriter
from harness import REPO

REFERENCE = REPO.parent / "shared" / "bags-reference"
REFERENCE_BAGS = {
    # dir: {topic: messages every reader must decode}; service events are unreadable by design
    "jazzy_mcap_abitobot": {"/imu/data": 4712, "/joint_states": 1866},
    "rosbag2_v8_mcap_topics_services": {"/test_topic1": 1, "/test_topic2": 1, "/events/write_split": 0},
    "rosbag2_v8_sqlite3_topics_services": {"/test_topic1": 1, "/test_topic2": 1, "/events/write_split": 0},
}
SERVICE_EVENT_TOPICS = ("/test_service1/_service_event", "/test_service2/_service_event")

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
DEFINITIONS = MessageDefinitions(os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep))
_INFINITE = QosTime(9223372036, 854775807)
T0 = 1_700_000_000 * 10**9  # the first timestamp of the bags written here


def offered(reliable: bool = True, latched: bool = False) -> list[Qos]:
    """One publisher's offer as a ros2 bag record of Jazzy writes it (history unknown, depth 0)."""
    return [Qos(QosHistory.UNKNOWN, 0, QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
                QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE, _INFINITE, _INFINITE,
                QosLiveliness.AUTOMATIC, _INFINITE, False)]


def spec(topic: str, msgtype: str, reliable: bool = True, latched: bool = False) -> TopicSpec:
    return TopicSpec(topic, msgtype, DEFINITIONS.definition(msgtype), DEFINITIONS.type_hash(msgtype), offered(reliable, latched))


def _header(i: int, frame: str):
    T = TYPESTORE.types
    return T["std_msgs/msg/Header"](T["builtin_interfaces/msg/Time"](i, 0), frame)


def joint_state(i: int) -> bytes:
    msg = TYPESTORE.types["sensor_msgs/msg/JointState"](
        _header(i, ""), ["j1", "j2"], np.array([float(i), -float(i)]), np.zeros(0), np.zeros(0))
    return bytes(TYPESTORE.serialize_cdr(msg, "sensor_msgs/msg/JointState"))


def cloud(i: int, width: int = 64, height: int = 48) -> bytes:
    """An organized xyz cloud (point_step 16) whose bytes depend on ``i``."""
    T = TYPESTORE.types
    xyz = np.random.default_rng(i).normal(size=(height * width, 4)).astype(np.float32)
    fields = [T["sensor_msgs/msg/PointField"](name, 4 * k, 7, 1) for k, name in enumerate("xyz")]
    msg = T["sensor_msgs/msg/PointCloud2"](_header(i, "depth_camera_link"), height, width, fields, False, 16,
                                           16 * width, xyz.view(np.uint8).ravel(), False)
    return bytes(TYPESTORE.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2"))


def tf_static(child: str) -> bytes:
    T = TYPESTORE.types
    transform = T["geometry_msgs/msg/TransformStamped"](
        _header(0, "world"), child,
        T["geometry_msgs/msg/Transform"](T["geometry_msgs/msg/Vector3"](1.0, 2.0, 3.0),
                                         T["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0)))
    return bytes(TYPESTORE.serialize_cdr(T["tf2_msgs/msg/TFMessage"]([transform]), "tf2_msgs/msg/TFMessage"))


def write_bag(path: Path, storage: str = "mcap", compression: str = "lz4", frames: int = 40,
              cloud_every: int = 10, cloud_size: tuple[int, int] = (64, 48),
              **kwargs) -> dict[str, int]:
    """Joint states at 100 Hz, a cloud every ``cloud_every``-th, one latched /tf_static, written
    by a BagWriter(``kwargs``) and closed; returns the messages per topic."""
    writer = BagWriter(path, storage, compression, **kwargs)
    js = writer.add_topic(spec("/joint_states", "sensor_msgs/msg/JointState"))
    pc = writer.add_topic(spec("/points2", "sensor_msgs/msg/PointCloud2", reliable=False))
    tf = writer.add_topic(spec("/tf_static", "tf2_msgs/msg/TFMessage", latched=True))
    writer.write(tf, T0, tf_static("camera_base"))
    for i in range(frames):
        writer.write(js, T0 + i * 10**7 + 1, joint_state(i))
        if i % cloud_every == 0:
            writer.write(pc, T0 + i * 10**7 + 2, cloud(i, *cloud_size))
    writer.close()
    clouds = (frames + cloud_every - 1) // cloud_every
    return {"/joint_states": frames, "/points2": clouds, "/tf_static": 1}


def read_anyreader(path: Path) -> dict[str, list]:
    """topic -> [(timestamp, message)] as rosbags' AnyReader reads the bag (or file) ``path``."""
    out = {}
    with AnyReader([path], default_typestore=TYPESTORE) as reader:
        for connection, timestamp, raw in reader.messages():
            message = reader.deserialize(raw, connection.msgtype)
            out.setdefault(connection.topic, []).append((timestamp, message))
    return out


def read_mcap_package(path: Path) -> dict[str, list]:
    """topic -> [(log time, message)] as the mcap package decodes bag ``path``'s .mcap files."""
    out = {}
    for file in sorted(path.glob("*.mcap")):
        with open(file, "rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            for _, channel, message, decoded in reader.iter_decoded_messages():
                out.setdefault(channel.topic, []).append((message.log_time, decoded))
    return out


class FullDisk(io.RawIOBase):
    """A file on a disk with room for ``capacity`` bytes: a write that does not fit writes what
    fits and raises ENOSPC, as a real full disk does; truncating gives the room back."""

    def __init__(self, path: Path, capacity: int) -> None:
        self._file = open(path, "xb", buffering=0)
        self._capacity = capacity
        self.path = path

    def writable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def write(self, data) -> int:
        view = memoryview(data)
        room = self._capacity - self._file.tell()
        if len(view) > room:
            self._file.write(view[: max(room, 0)])
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self.path))
        return self._file.write(view)

    def tell(self) -> int:
        return self._file.tell()

    def seek(self, offset: int, whence: int = 0) -> int:
        return self._file.seek(offset, whence)

    def truncate(self, size: int | None = None) -> int:
        return self._file.truncate(size)

    def close(self) -> None:
        self._file.close()
        super().close()
