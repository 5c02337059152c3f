"""Our bags read by code we did not write: rosbags' AnyReader (both storage formats) and the
`mcap` package's reader with `mcap-ros2-support` decoding; splitting; a disk that fills up;
the recorder's queue and episodes."""
from __future__ import annotations

import threading

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader

from actaim2.bags import salvage
from actaim2.bags.recorder import Recorder
from actaim2.bags.writer import BagWriter
from bagtools import (
    T0,
    TYPESTORE,
    FullDisk,
    cloud,
    joint_state,
    read_anyreader,
    read_mcap_package,
    spec,
    tf_static,
    write_bag,
)


def check_content(messages, expected):
    assert {t: len(m) for t, m in messages.items()} == expected
    positions = [msg.position[0] for _, msg in messages["/joint_states"]]
    np.testing.assert_array_equal(positions, np.arange(expected["/joint_states"], dtype=float))
    for k, (_, msg) in enumerate(messages["/points2"]):
        sent = TYPESTORE.deserialize_cdr(cloud(10 * k), "sensor_msgs/msg/PointCloud2")
        assert (msg.height, msg.width, msg.point_step) == (48, 64, 16)
        assert bytes(msg.data) == bytes(sent.data)
    assert messages["/tf_static"][0][1].transforms[0].child_frame_id == "camera_base"


@pytest.mark.parametrize("storage, compression", [("mcap", "lz4"), ("mcap", "zstd"), ("mcap", "none"), ("sqlite3", "none")])
def test_readers_we_did_not_write_read_every_message(tmp_path, storage, compression):
    expected = write_bag(tmp_path / "bag", storage, compression)
    check_content(read_anyreader(tmp_path / "bag"), expected)
    if storage == "mcap":
        check_content(read_mcap_package(tmp_path / "bag"), expected)
        with open(tmp_path / "bag" / "bag_0.mcap", "rb") as f:
            reader = make_reader(f)
            assert reader.get_header().profile == "ros2"
            summary = reader.get_summary()
            assert {c.compression for c in summary.chunk_indexes} == {"" if compression == "none" else compression}
            assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
            assert all(set(c.metadata) == {"offered_qos_profiles", "topic_type_hash"} for c in summary.channels.values())
            assert [m.name for m in reader.iter_metadata()] == ["rosbag2"]


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
@pytest.mark.parametrize("split", [{"max_file_size": 40_000}, {"max_file_duration_ns": 10**8}], ids=["size", "duration"])
def test_splitting_makes_files_that_each_read_alone(tmp_path, storage, split):
    expected = write_bag(tmp_path / "bag", storage, "lz4" if storage == "mcap" else "none", frames=60, chunk_size=8192, **split)
    info = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    files = info["relative_file_paths"]
    assert len(files) >= 3 and files == [f"bag_{i}.{'mcap' if storage == 'mcap' else 'db3'}" for i in range(len(files))]
    assert sum(f["message_count"] for f in info["files"]) == info["message_count"] == sum(expected.values())
    previous_end = 0
    for entry in info["files"]:
        with AnyReader([tmp_path / "bag" / entry["path"]], default_typestore=TYPESTORE) as reader:
            stamps = [t for _, t, _ in reader.messages()]
        assert len(stamps) == entry["message_count"]
        assert min(stamps) == entry["starting_time"]["nanoseconds_since_epoch"] >= previous_end
        if "max_file_duration_ns" in split:
            assert max(stamps) - min(stamps) < split["max_file_duration_ns"]
        previous_end = max(stamps)
    check_content(read_anyreader(tmp_path / "bag"), expected)


def record_onto_full_disk(tmp_path, capacity, errors):
    recorder = Recorder(
        lambda name: BagWriter(tmp_path / name, "mcap", "none", chunk_size=4096,
                               open_file=lambda path: FullDisk(path, capacity)),
        on_error=errors.append,
    )
    recorder.add_topic(spec("/joint_states", "sensor_msgs/msg/JointState"), reliable=True, latched=False)
    recorder.add_topic(spec("/points2", "sensor_msgs/msg/PointCloud2", reliable=False), reliable=False, latched=False)
    recorder.start_bag("bag", T0)
    for i in range(200):
        recorder.put("/joint_states", T0 + i * 10**7, joint_state(i))
        if i % 10 == 0:
            recorder.put("/points2", T0 + i * 10**7, cloud(i))
    return recorder.stop()


@pytest.mark.parametrize("capacity", [15_000, 20_000, 60_000, 150_000, 300_000])
def test_full_disk_stops_the_recording_and_keeps_the_bag_readable(tmp_path, capacity):
    """ENOSPC after ``capacity`` bytes, while the writer thread is in the middle of a recording."""
    errors = []
    summary = record_onto_full_disk(tmp_path, capacity, errors)
    assert summary.error and "No space left on device" in summary.error and errors == [summary.error]
    assert (tmp_path / "bag" / "bag_0.mcap").stat().st_size <= capacity
    recorded = {t: c.recorded for t, c in summary.topics.items() if c.recorded}
    assert read_anyreader_counts(tmp_path / "bag") == recorded
    assert {t: len(m) for t, m in read_mcap_package(tmp_path / "bag").items()} == recorded
    info = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["message_count"] == sum(recorded.values())
    if capacity >= 60_000:
        assert recorded["/joint_states"] > 0  # what fitted before the disk was full is kept
    positions = [m.position[0] for _, m in read_anyreader(tmp_path / "bag").get("/joint_states", [])]
    assert positions == list(np.arange(len(positions), dtype=float))  # a prefix, in order, nothing torn


def test_a_disk_too_full_for_the_summary_is_reported_and_the_file_still_scans(tmp_path):
    summary = record_onto_full_disk(tmp_path, 3_000, [])
    assert "No space left on device" in summary.error and "finishing the file failed too" in summary.error
    assert salvage.scan(tmp_path / "bag" / "bag_0.mcap").counts == {}


def read_anyreader_counts(path):
    return {t: len(m) for t, m in read_anyreader(path).items()}


class GatedDisk(FullDisk):
    """A disk that stalls until the gate opens (a slow USB stick)."""

    gate = threading.Event()

    def write(self, data) -> int:
        self.gate.wait(10)
        return super().write(data)


def test_a_full_queue_drops_and_counts_instead_of_blocking(tmp_path):
    GatedDisk.gate.clear()
    recorder = Recorder(
        lambda name: BagWriter(tmp_path / name, "mcap", "none", chunk_size=1, open_file=lambda p: GatedDisk(p, 10**9)),
        queue_limit_bytes=5 * len(cloud(0)),
    )
    recorder.add_topic(spec("/points2", "sensor_msgs/msg/PointCloud2", reliable=False), reliable=False, latched=False)
    recorder.start_bag("bag", T0)
    accepted = [recorder.put("/points2", T0 + i, cloud(i)) for i in range(20)]
    GatedDisk.gate.set()
    counts = recorder.stop().topics["/points2"]
    assert counts.received == 20 and counts.dropped == accepted.count(False) >= 10
    assert counts.recorded == accepted.count(True) == read_anyreader_counts(tmp_path / "bag")["/points2"]


def test_episode_bags_each_carry_the_latched_topics(tmp_path):
    recorder = Recorder(lambda name: BagWriter(tmp_path / name))
    recorder.add_topic(spec("/tf_static", "tf2_msgs/msg/TFMessage", latched=True), reliable=True, latched=True)
    recorder.add_topic(spec("/joint_states", "sensor_msgs/msg/JointState"), reliable=True, latched=False)
    recorder.put("/tf_static", T0, tf_static("camera_base"))  # before any episode: remembered, not recorded
    recorder.put("/joint_states", T0 + 1, joint_state(0))  # outside any episode: counted, not recorded
    for episode, frames in ((1, 5), (2, 3)):
        recorder.start_bag(f"episode_{episode:04d}", T0 + episode * 10**9)
        for i in range(frames):
            recorder.put("/joint_states", T0 + episode * 10**9 + (i + 1) * 10**6, joint_state(i))
        recorder.end_bag()
    summary = recorder.stop()
    assert [p.split("/")[-1] for p in summary.bags] == ["episode_0001", "episode_0002"]
    for name, frames in (("episode_0001", 5), ("episode_0002", 3)):
        messages = read_anyreader(tmp_path / name)
        assert len(messages["/joint_states"]) == frames
        (stamp, tf), = messages["/tf_static"]
        assert tf.transforms[0].child_frame_id == "camera_base" and stamp < messages["/joint_states"][0][0]
    assert summary.topics["/joint_states"].outside_bag == 1 and summary.topics["/joint_states"].recorded == 8
    assert summary.topics["/tf_static"].recorded == 2


def test_messages_received_within_the_grace_window_before_start_open_its_bag_with_their_receive_times(tmp_path):
    grace, ms = 500 * 10**6, 10**6
    recorder = Recorder(lambda name: BagWriter(tmp_path / name), start_grace_ns=grace,
                        start_grace_bytes=2 * len(cloud(0)) + len(joint_state(0)))
    recorder.add_topic(spec("/tf_static", "tf2_msgs/msg/TFMessage", latched=True), reliable=True, latched=True)
    recorder.add_topic(spec("/joint_states", "sensor_msgs/msg/JointState"), reliable=True, latched=False)
    recorder.add_topic(spec("/points2", "sensor_msgs/msg/PointCloud2", reliable=False), reliable=False, latched=False)
    recorder.put("/tf_static", T0, tf_static("camera_base"))
    start = T0 + 1000 * ms
    recorder.put("/joint_states", start - 600 * ms, joint_state(1))  # beyond the window: outside
    for i, before in ((1, 400), (2, 300), (3, 200)):  # three clouds in the window, two fit in the bytes: the oldest goes
        recorder.put("/points2", start - before * ms, cloud(i))
    recorder.put("/joint_states", start - 20 * ms, joint_state(2))  # published after START, received before it
    recorder.start_bag("episode_0001", start)
    recorder.put("/joint_states", start + 10 * ms, joint_state(3))
    recorder.end_bag()
    recorder.put("/joint_states", start + 600 * ms, joint_state(4))  # held, no START follows: outside
    summary = recorder.stop()

    messages = read_anyreader(tmp_path / "episode_0001")
    assert [(t - start) // ms for t, _ in messages["/joint_states"]] == [-20, 10]
    assert [msg.position[0] for _, msg in messages["/joint_states"]] == [2.0, 3.0]
    assert [((t - start) // ms, msg.header.stamp.sec) for t, msg in messages["/points2"]] == [(-300, 2), (-200, 3)]
    assert [(t - start) // ms for t, _ in messages["/tf_static"]] == [-300]  # the bag's first message
    info = yaml.safe_load((tmp_path / "episode_0001" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["starting_time"]["nanoseconds_since_epoch"] == start - 300 * ms
    assert len(read_mcap_package(tmp_path / "episode_0001")["/points2"]) == 2
    counts = summary.topics
    assert (counts["/joint_states"].outside_bag, counts["/joint_states"].recorded) == (2, 2)
    assert (counts["/points2"].outside_bag, counts["/points2"].recorded) == (1, 2)
