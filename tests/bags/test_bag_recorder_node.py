"""bag_recorder in its own process over real DDS, fed by publishers in this process."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import time

import numpy as np
import pytest
import yaml
from actaim2_msgs.msg import EpisodeEvent, Keypose
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rosbags.highlevel import AnyReader
from sensor_msgs.msg import JointState, PointCloud2
from std_msgs.msg import Header
from tf2_msgs.msg import TFMessage

from actaim2_ros.transforms import TF_STATIC_QOS, matrix_to_transform
from bagtools import TYPESTORE
from harness import wait_for

EPISODE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
START_GRACE = 0.5  # s: bag_recorder's default start_grace


def read(path):
    out = {}
    with AnyReader([path], default_typestore=TYPESTORE) as reader:
        for connection, _, raw in reader.messages():
            out.setdefault(connection.topic, []).append(reader.deserialize(raw, connection.msgtype))
    return out


def log_times(path, topic) -> list[int]:
    with AnyReader([path], default_typestore=TYPESTORE) as reader:
        return [timestamp for connection, timestamp, _ in reader.messages() if connection.topic == topic]


def topics_of(path) -> dict:
    info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    return {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}


def wait_subscribed(process, *topics, timeout=30.0):
    assert wait_for(lambda: all(f"{t} [" in process.output() for t in topics), timeout), process.output()


def test_records_every_reliable_message_latched_tf_and_counts_cloud_losses(ros_node, start_node, tmp_path):
    tf_pub = ros_node.create_publisher(TFMessage, "/tf_static", TF_STATIC_QOS)
    tf_pub.publish(TFMessage(transforms=[matrix_to_transform(np.eye(4), "world", "camera_base")]))  # before the recorder
    js_pub = ros_node.create_publisher(JointState, "/joint_states", 10)
    cloud_pub = ros_node.create_publisher(PointCloud2, "/cameras/cam0/points", qos_profile_sensor_data)
    summary_file = tmp_path / "summary.json"
    recorder = start_node("actaim2_policy", "bag_recorder",
                          {"output": str(tmp_path / "bag"), "summary_file": str(summary_file), "discovery_period": 0.2})
    wait_subscribed(recorder, "/tf_static", "/joint_states", "/cameras/cam0/points")
    assert wait_for(lambda: js_pub.get_subscription_count() and cloud_pub.get_subscription_count(), 10.0)

    cloud = PointCloud2(height=240, width=320, point_step=32, row_step=320 * 32, data=bytes(240 * 320 * 32))
    for i in range(300):  # 3 s: joint states at 100 Hz, ring5-sized clouds at 10 Hz
        js_pub.publish(JointState(name=["j1"], position=[float(i)]))
        if i % 10 == 0:
            cloud.header.stamp.sec = i
            cloud_pub.publish(cloud)
        time.sleep(0.01)
    time.sleep(1.0)
    assert recorder.stop() == 0, recorder.output()

    bag = tmp_path / "bag"
    messages = read(bag)
    assert [m.position[0] for m in messages["/joint_states"]] == list(range(300))  # zero loss, in order
    assert messages["/tf_static"][0].transforms[0].child_frame_id == "camera_base"
    summary = json.loads(summary_file.read_text())
    clouds = summary["topics"]["/cameras/cam0/points"]
    assert clouds["received"] == clouds["recorded"] + clouds["dropped"] == len(messages["/cameras/cam0/points"]) + clouds["dropped"]
    assert 0 < clouds["recorded"] <= 30 and clouds["reliable"] is False
    assert summary["topics"]["/joint_states"]["recorded"] == 300 and summary["error"] is None
    assert "/cameras/cam0/points (best effort): received" in recorder.output()

    with open(bag / "bag_0.mcap", "rb") as f:  # the mcap package decodes every message too
        decoded = [(c.topic, m) for _, c, _, m in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages()]
    assert len(decoded) == sum(len(v) for v in messages.values())
    recorded = topics_of(bag)
    tf_qos = recorded["/tf_static"]["topic_metadata"]["offered_qos_profiles"]
    assert [(q["reliability"], q["durability"]) for q in tf_qos] == [("reliable", "transient_local")]
    assert recorded["/cameras/cam0/points"]["topic_metadata"]["offered_qos_profiles"][0]["reliability"] == "best_effort"
    endpoint_hash = str(ros_node.get_publishers_info_by_topic("/joint_states")[0].topic_type_hash)
    assert recorded["/joint_states"]["topic_metadata"]["type_description_hash"] == endpoint_hash


def test_sigterm_leaves_a_readable_split_sqlite3_bag(ros_node, start_node, tmp_path):
    js_pub = ros_node.create_publisher(JointState, "/joint_states", 10)
    recorder = start_node("actaim2_policy", "bag_recorder", {
        "output": str(tmp_path / "bag"), "storage": "sqlite3", "compression": "none",
        "max_bag_duration": 0.5, "topics": ["/joint_states"], "topic_patterns": [""], "discovery_period": 0.2,
    })
    wait_subscribed(recorder, "/joint_states")
    assert wait_for(lambda: js_pub.get_subscription_count() > 0, 10.0)
    for i in range(200):
        js_pub.publish(JointState(name=["j1"], position=[float(i)]))
        time.sleep(0.01)
    time.sleep(0.5)
    os.killpg(recorder.proc.pid, signal.SIGTERM)
    assert recorder.proc.wait(timeout=20) == 0, recorder.output()
    files = sorted(p.name for p in (tmp_path / "bag").glob("*.db3"))
    assert len(files) >= 3 and files[0] == "bag_0.db3"
    assert [m.position[0] for m in read(tmp_path / "bag")["/joint_states"]] == list(range(200))


def test_one_bag_per_episode_with_its_own_tf_static_and_the_keypose_received_just_before_start(ros_node, start_node, tmp_path):
    tf_pub = ros_node.create_publisher(TFMessage, "/tf_static", TF_STATIC_QOS)
    tf_pub.publish(TFMessage(transforms=[matrix_to_transform(np.eye(4), "world", "panda_link0")]))
    js_pub = ros_node.create_publisher(JointState, "/joint_states", 10)
    keypose_pub = ros_node.create_publisher(Keypose, "/keypose", QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    episode_pub = ros_node.create_publisher(EpisodeEvent, "/episode", EPISODE_QOS)
    recorder = start_node("actaim2_policy", "bag_recorder", {
        "output": str(tmp_path / "episodes"), "split_by_episode": True, "discovery_period": 0.2,
    })
    wait_subscribed(recorder, "/tf_static", "/joint_states", "/keypose", "/episode")
    assert wait_for(lambda: all(p.get_subscription_count() for p in (js_pub, keypose_pub, episode_pub)), 10.0)

    def joint_states(n, offset):
        for i in range(n):
            js_pub.publish(JointState(name=["j1"], position=[float(offset + i)]))
            time.sleep(0.01)
        time.sleep(0.3)

    joint_states(5, 1000)  # before any episode: not recorded
    for episode, frames in ((1, 20), (2, 10)):
        time.sleep(START_GRACE)  # what came before was received longer than the grace window before START
        # the INIT keypose reaches the recorder before START, as in runs/teleop's episode 48; stamped as START
        stamp = ros_node.get_clock().now().to_msg()
        keypose_pub.publish(Keypose(header=Header(stamp=stamp, frame_id="world"), phase=Keypose.PHASE_INIT))
        time.sleep(0.2)
        episode_pub.publish(EpisodeEvent(header=Header(stamp=stamp), episode=episode, event=EpisodeEvent.START,
                                         object_id="drawer/0"))
        time.sleep(0.3)
        joint_states(frames, 100 * episode)
        episode_pub.publish(EpisodeEvent(episode=episode, event=EpisodeEvent.END, success=True))
        time.sleep(0.3)
        joint_states(5, 1000)  # between episodes: not recorded
    assert recorder.stop() == 0, recorder.output()

    for episode, frames in ((1, 20), (2, 10)):
        bag = tmp_path / "episodes" / f"episode_{episode:04d}"
        messages = read(bag)
        assert [m.position[0] for m in messages["/joint_states"]] == [100.0 * episode + i for i in range(frames)]
        assert [(e.episode, e.event) for e in messages["/episode"]] == [(episode, EpisodeEvent.START), (episode, EpisodeEvent.END)]
        assert [k.phase for k in messages["/keypose"]] == [Keypose.PHASE_INIT]
        assert messages["/keypose"][0].header.stamp == messages["/episode"][0].header.stamp
        (keypose_ns,), start_ns = log_times(bag, "/keypose"), log_times(bag, "/episode")[0]
        assert start_ns - START_GRACE * 1e9 <= keypose_ns < start_ns  # received before START, written with its receive time
        assert log_times(bag, "/tf_static")[0] == keypose_ns  # the latched topics open the bag
        assert messages["/tf_static"][0].transforms[0].child_frame_id == "panda_link0"
    assert sorted(p.name for p in (tmp_path / "episodes").iterdir()) == ["episode_0001", "episode_0002"]
    assert "outside episodes 15" in recorder.output()


PANDA_ARM = [f"panda_joint{i}" for i in range(1, 8)]


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_after_sigkill_and_reindex_both_readers_read_every_message_older_than_1_5_s(
        ros_node, start_node, tmp_path, storage):
    """A new user's experiment: /joint_states (7 joints, 236 bytes: 10 s fit in one 768 kB
    chunk) at 200 Hz for 10 s, the recorder killed with SIGKILL, `actaim2 bag-reindex`, then
    rosbags and (MCAP) the mcap package read the bag."""
    js_pub = ros_node.create_publisher(JointState, "/joint_states", 10)
    bag = tmp_path / "bag"
    recorder = start_node("actaim2_policy", "bag_recorder", {
        "output": str(bag), "storage": storage,
        "compression": "lz4" if storage == "mcap" else "none",
        "topics": ["/joint_states"], "topic_patterns": [""], "discovery_period": 0.2,
    })
    wait_subscribed(recorder, "/joint_states")
    assert wait_for(lambda: js_pub.get_subscription_count() > 0, 10.0)
    published = []  # time.monotonic() of each publish
    start = time.monotonic()
    for i in range(2000):
        time.sleep(max(0.0, start + i / 200 - time.monotonic()))
        js_pub.publish(JointState(name=PANDA_ARM, position=[float(i)] * 7))
        published.append(time.monotonic())
    os.killpg(recorder.proc.pid, signal.SIGKILL)
    killed = time.monotonic()
    recorder.proc.wait(timeout=10)
    older = sum(t < killed - 1.5 for t in published)

    reindex = subprocess.run(["actaim2", "bag-reindex", str(bag)], capture_output=True, text=True,
                             timeout=60)
    assert reindex.returncode == 0, reindex.stdout + reindex.stderr
    positions = [m.position[0] for m in read(bag).get("/joint_states", [])]  # rosbags
    assert positions == list(range(len(positions))), positions[:10]
    assert len(positions) >= older, (len(positions), older)
    assert topics_of(bag)["/joint_states"]["message_count"] == len(positions)
    if storage == "mcap":  # the mcap package reads the same messages
        with open(bag / "bag_0.mcap", "rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            assert [m.position[0] for _, _, _, m in reader.iter_decoded_messages()] == positions
    print(f"{storage}: {len(positions)} of 2000 kept, {older} older than 1.5 s; {reindex.stdout}")


@pytest.mark.parametrize("params, message", [
    ({"storage": "rosbag1"}, "storage must be one of"),
    ({"topic_patterns": ["(unclosed"]}, "topic_patterns"),
])
def test_bad_parameters_stop_the_node_with_a_clear_message(start_node, tmp_path, params, message):
    recorder = start_node("actaim2_policy", "bag_recorder", dict(params, output=str(tmp_path / "bag")))
    assert recorder.proc.wait(timeout=30) == 1
    assert message in recorder.output() and "Traceback" not in recorder.output()
