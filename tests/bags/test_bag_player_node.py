"""bag_player in its own process over real DDS: timing, QoS, /clock, remapping, problems reported."""
from __future__ import annotations

import importlib.util
import json
import threading
import time

import numpy as np
from rclpy.qos import qos_profile_sensor_data
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState
from tf2_msgs.msg import TFMessage

from actaim2.bags.metadata import TopicSpec
from actaim2.bags.writer import BagWriter
from actaim2_ros.transforms import TF_STATIC_LISTENER_QOS
from bagtools import REFERENCE, joint_state, spec, tf_static
from harness import wait_for

T0 = 1_700_000_000 * 10**9
PERIOD_NS = 40_000_000


class Inbox:
    def __init__(self, node, msg_type, topic, qos):
        self.messages, self.times = [], []
        self._lock = threading.Lock()
        node.create_subscription(msg_type, topic, self._store, qos)

    def _store(self, msg):
        with self._lock:
            self.messages.append(msg)
            self.times.append(time.monotonic())


def write_test_bag(path):
    """/joint_states (message 7 broken), /tf_static from two publishers, and two topics the player
    cannot play: a type with no Python class here, a definition rosbags cannot parse."""
    writer = BagWriter(path)
    js = writer.add_topic(spec("/joint_states", "sensor_msgs/msg/JointState"))
    tf = writer.add_topic(spec("/tf_static", "tf2_msgs/msg/TFMessage", latched=True))
    unknown = writer.add_topic(TopicSpec("/exotic", "nonexistent_msgs/msg/Foo", "int32 x\n", ""))
    broken = writer.add_topic(TopicSpec("/broken", "broken_msgs/msg/Bad", "this ] is not [ a definition\n", ""))
    writer.write(tf, T0, tf_static("camera_base"))
    writer.write(tf, T0 + 1, tf_static("depth_camera_link"))
    writer.write(unknown, T0 + 2, b"\x00\x01\x00\x00\x07\x00\x00\x00")
    writer.write(broken, T0 + 3, b"\x00\x01\x00\x00")
    for i in range(100):
        writer.write(js, T0 + 10 + i * PERIOD_NS, joint_state(i)[:20] if i == 7 else joint_state(i))
    writer.close()


def test_player_times_remaps_relatches_and_reports(ros_node, start_node, tmp_path):
    write_test_bag(tmp_path / "bag")
    replayed = Inbox(ros_node, JointState, "/replayed", 200)
    clock = Inbox(ros_node, Clock, "/clock", 10)
    player = start_node("actaim2_policy", "bag_player", {
        "bag": str(tmp_path / "bag"), "rate": 2.0, "remap": ["/joint_states:=/replayed"], "clock_rate": 20.0,
        "start_delay": 0.5, "wait_for_subscribers": ["/replayed", "/clock"], "summary_file": str(tmp_path / "summary.json"),
    })
    assert wait_for(lambda: len(replayed.messages) >= 5, 30.0), player.output()
    late = Inbox(ros_node, TFMessage, "/tf_static", TF_STATIC_LISTENER_QOS)  # joins after /tf_static was sent
    assert wait_for(lambda: len(late.messages) >= 2, 10.0), player.output()
    assert player.proc.wait(timeout=30) == 0, player.output()  # ends by itself

    assert sorted(m.transforms[0].child_frame_id for m in late.messages) == ["camera_base", "depth_camera_link"]
    # Every message was acknowledged before the player exited; this process's executor may still be taking them.
    assert wait_for(lambda: len(replayed.messages) >= 99, 5.0), len(replayed.messages)
    positions = [m.position[0] for m in replayed.messages]
    assert positions == [float(i) for i in range(100) if i != 7]
    spacing = np.diff(replayed.times).mean()
    assert 0.01 < spacing < 0.05  # 40 ms recorded at rate 2 = 20 ms (a loaded machine stretches it)
    stamps = [m.clock.sec * 10**9 + m.clock.nanosec for m in clock.messages]
    assert len(stamps) >= 10 and stamps == sorted(stamps) and T0 <= stamps[0] and stamps[-1] <= T0 + 100 * PERIOD_NS

    log = player.output()
    assert "topic /joint_states message 7: does not deserialize as sensor_msgs/msg/JointState" in log
    assert "topic /exotic: unknown message type nonexistent_msgs/msg/Foo" in log
    assert "topic /broken: rosbags cannot parse the definition of broken_msgs/msg/Bad" in log
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["published"] == {"/joint_states": 99, "/tf_static": 2}
    assert summary["timing_error_ms"]["p99"] >= 0.0


def test_player_plays_the_jazzy_reference_bag(ros_node, start_node, tmp_path):
    """Recorded by `ros2 bag record` on Jazzy: 1866 JointState (transient local) and 4712 Imu over 95 s.
    Only /joint_states is selected, played at rate 25 under another name."""
    imu = Inbox(ros_node, Imu, "/imu/data", qos_profile_sensor_data)
    joints = Inbox(ros_node, JointState, "/abitobot/joint_states", 2000)
    player = start_node("actaim2_policy", "bag_player", {
        "bag": str(REFERENCE / "jazzy_mcap_abitobot"), "rate": 25.0, "topics": ["/joint_states"],
        "remap": ["/joint_states:=/abitobot/joint_states"], "wait_for_subscribers": ["/abitobot/joint_states"],
        "summary_file": str(tmp_path / "summary.json"),
    })
    assert player.proc.wait(timeout=60) == 0, player.output()
    assert json.loads((tmp_path / "summary.json").read_text())["published"] == {"/joint_states": 1866}
    assert wait_for(lambda: len(joints.messages) == 1866, 5.0), len(joints.messages)  # reliable, as recorded
    assert len(joints.messages[0].name) == len(joints.messages[0].position) > 0 and imu.messages == []


def test_player_skips_what_it_cannot_play_in_a_rosbag2_test_bag(start_node, tmp_path):
    player = start_node("actaim2_policy", "bag_player", {
        "bag": str(REFERENCE / "rosbag2_v8_sqlite3_topics_services"), "start_delay": 0.0,
        "summary_file": str(tmp_path / "summary.json"),
    })
    assert player.proc.wait(timeout=30) == 0, player.output()
    log = player.output()
    for topic in ("/test_service1/_service_event", "/test_service2/_service_event"):
        assert f"topic {topic}: the bag holds no definition of test_msgs/srv/BasicTypes_Event" in log
    published = json.loads((tmp_path / "summary.json").read_text())["published"]
    # Python classes for test_msgs and rosbag2_interfaces are not installed here: reported, not fatal.
    playable = {t: 1 for t in ("/test_topic1", "/test_topic2") if importlib.util.find_spec("test_msgs")}
    assert published == playable
    if not playable:
        assert "topic /test_topic1: unknown message type test_msgs/msg/Strings" in log
    if importlib.util.find_spec("rosbag2_interfaces") is None:
        assert "topic /events/write_split: unknown message type rosbag2_interfaces/msg/WriteSplitEvent" in log


def test_player_refuses_a_bag_without_metadata_yaml_and_names_the_command(start_node, tmp_path):
    write_test_bag(tmp_path / "bag")
    (tmp_path / "bag" / "metadata.yaml").unlink()  # as after a copy that left it behind
    player = start_node("actaim2_policy", "bag_player", {"bag": str(tmp_path / "bag")})
    assert player.proc.wait(timeout=30) == 1, player.output()
    log = player.output()
    assert "metadata.yaml is missing" in log and f"`actaim2 bag-reindex {tmp_path / 'bag'}`" in log
    assert "Traceback" not in log
