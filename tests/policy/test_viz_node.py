"""viz_node over real DDS and a real WebSocket: a client speaking the Foxglove WebSocket protocol
(``foxglove.websocket.v1``, which the Foxglove SDK's server negotiates under its newer name
``foxglove.sdk.v1``: the same messages) subscribes to every channel and decodes what arrives,
with the protobuf schemas the server advertises.

policy_node serves the committed checkpoint from views published here; the cloud, TF, joints,
keyposes and episode events are published here as the graph's nodes publish them.
"""
from __future__ import annotations

import base64
import json
import re
import socket
import struct
import threading
import time

import numpy as np
import pytest
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from websockets.sync.client import connect

from actaim2.perception.config import load_perception_config
from actaim2.perception.ortho_views import VIEWS
from harness import REPO, NodeProcess, wait_for

# The Foxglove app offers both names of the protocol; the SDK's server picks the newer one.
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
MESSAGE_DATA = 0x01  # binary opcode of a message on a subscription
POINTS = 1500  # finite points of the published cloud (plus NaN returns, which are dropped)
PANDA_HOME = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]


class FoxgloveClient:
    """A minimal client of the protocol: server info, advertisements, subscriptions, messages."""

    def __init__(self, ws):
        self.ws = ws
        assert ws.subprotocol in SUBPROTOCOLS
        self.channels: dict[int, dict] = {}
        self.by_subscription: dict[int, dict] = {}
        self.messages: dict[str, list[bytes]] = {}
        self.server_info: dict = {}

    def pump(self, seconds: float) -> None:
        """Read and file everything the server sends for ``seconds``."""
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0:
            try:
                frame = self.ws.recv(timeout=left)
            except TimeoutError:
                return
            if isinstance(frame, bytes):
                assert frame[0] == MESSAGE_DATA, frame[0]
                subscription, _log_time = struct.unpack_from("<IQ", frame, 1)
                topic = self.by_subscription[subscription]["topic"]
                self.messages.setdefault(topic, []).append(frame[13:])
                continue
            op = json.loads(frame)
            if op["op"] == "serverInfo":
                self.server_info = op
            elif op["op"] == "advertise":
                for channel in op["channels"]:
                    self.channels[channel["id"]] = channel

    def subscribe_all(self) -> None:
        subscriptions = []
        for k, channel in enumerate(self.channels.values(), start=1):
            self.by_subscription[k] = channel
            subscriptions.append({"id": k, "channelId": channel["id"]})
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))

    def decode(self, topic: str, payload: bytes):
        channel = next(c for c in self.channels.values() if c["topic"] == topic)
        if channel["encoding"] == "json":
            return json.loads(payload)
        assert channel["encoding"] == "protobuf" and channel["schemaEncoding"] == "protobuf"
        files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"]))
        pool = descriptor_pool.DescriptorPool()
        for file in files.file:
            pool.Add(file)
        message_class = message_factory.GetMessageClass(
            pool.FindMessageTypeByName(channel["schemaName"]))
        return message_class.FromString(payload)

    def latest(self, topic: str):
        return self.decode(topic, self.messages[topic][-1])


@pytest.fixture(scope="module")
def graph(tmp_path_factory):
    logs = tmp_path_factory.mktemp("viz")
    (logs / "policy").mkdir()
    (logs / "viz").mkdir()
    policy = NodeProcess("actaim2_policy", "policy_node", {"torch_threads": 1}, [],
                         logs / "policy")
    viz = NodeProcess("actaim2_policy", "viz_node", {"port": 0, "poll_period": 0.2}, [],
                      logs / "viz")
    yield policy, viz
    assert viz.stop() == 0, viz.output()
    policy.stop()
    assert "Traceback" not in viz.output(), viz.output()


def test_a_foxglove_client_gets_every_channel_decoded(ros_node, graph):
    from actaim2_msgs.msg import EpisodeEvent, OrthoViews
    from actaim2_msgs.msg import Keypose as KeyposeMsg
    from actaim2_msgs.srv import PredictKeypose, SampleMode
    from geometry_msgs.msg import TransformStamped
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import JointState, PointCloud2
    from tf2_msgs.msg import TFMessage

    from actaim2.keypose import Keypose
    from actaim2_policy.viz_node import KEYPOSE_QOS, LATCHED_QOS, VIEWS_QOS
    from actaim2_ros.keypose import keypose_msg
    from actaim2_ros.pointcloud2 import to_msg

    policy, viz = graph
    assert wait_for(lambda: "viz_node ready" in viz.output(), 60.0), viz.output()
    port = int(re.search(r"ws://127\.0\.0\.1:(\d+)", viz.output()).group(1))

    cloud_pub = ros_node.create_publisher(PointCloud2, "/fused_points", qos_profile_sensor_data)
    views_pub = ros_node.create_publisher(OrthoViews, "/ortho_views", VIEWS_QOS)
    tf_pub = ros_node.create_publisher(TFMessage, "/tf_static", LATCHED_QOS)
    joints_pub = ros_node.create_publisher(JointState, "/joint_states", 10)
    keypose_pub = ros_node.create_publisher(KeyposeMsg, "/keypose", KEYPOSE_QOS)
    episode_pub = ros_node.create_publisher(EpisodeEvent, "/episode", LATCHED_QOS)

    static = TransformStamped(child_frame_id="panda_link0")
    static.header.frame_id = "world"
    static.transform.rotation.w = 1.0
    tf_pub.publish(TFMessage(transforms=[static]))

    rng = np.random.default_rng(0)
    xyz = rng.uniform(-0.5, 0.5, (POINTS + 100, 3)).astype(np.float32)
    xyz[POINTS:] = np.nan
    cloud = to_msg(xyz, rng.integers(0, 255, (len(xyz), 3), dtype=np.uint8), "world")
    config = load_perception_config("ring5")
    views = rng.uniform(0.0, 1.0, (5, len(config.channels), config.resolution, config.resolution))
    views_msg = OrthoViews(height=config.resolution, width=config.resolution, views=list(VIEWS),
                           channels=list(config.channels), config_digest=config.digest(),
                           data=views.astype(np.float32).ravel().tolist())
    views_msg.header.frame_id = "world"
    views_msg.header.stamp.sec = 3
    joints = JointState(name=[f"panda_joint{i}" for i in range(1, 8)], position=PANDA_HOME)

    stop = threading.Event()

    def publish_stream() -> None:  # the sensor side of the graph, at a few Hz
        while not stop.is_set():
            cloud_pub.publish(cloud)
            views_pub.publish(views_msg)
            joints_pub.publish(joints)
            stop.wait(0.2)

    # No client yet: viz_node holds none of the large topics.
    time.sleep(1.0)
    assert cloud_pub.get_subscription_count() == 0 and joints_pub.get_subscription_count() == 0
    assert "subscribed to" not in viz.output()  # /ortho_views has policy_node's subscription only
    streamer = threading.Thread(target=publish_stream, daemon=True)
    streamer.start()
    try:
        with connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS, max_size=None) as ws:
            client = FoxgloveClient(ws)
            client.pump(1.0)
            topics = {c["topic"] for c in client.channels.values()}
            expected = {"/fused_points", "/keyposes", "/keyposes/frames", "/tf", "/mode",
                        "/episode", *(f"/views/{v}" for v in VIEWS),
                        *(f"/heatmaps/{v}" for v in VIEWS)}
            assert expected <= topics, topics
            client.subscribe_all()
            assert wait_for(lambda: cloud_pub.get_subscription_count() > 0, 20.0), viz.output()

            sample = ros_node.create_client(SampleMode, "/sample_mode")
            predict = ros_node.create_client(PredictKeypose, "/predict_keypose")
            assert sample.wait_for_service(timeout_sec=120.0), policy.output()

            def call(service, request):
                done = threading.Event()
                future = service.call_async(request)
                future.add_done_callback(lambda _: done.set())
                assert done.wait(30.0), "no answer"
                return future.result()

            episode_pub.publish(EpisodeEvent(episode=0, event=EpisodeEvent.START,
                                             object_id="drawer"))
            mode = None
            deadline = time.monotonic() + 60.0
            while time.monotonic() < deadline and (mode is None or not mode.success):
                mode = call(sample, SampleMode.Request(cluster=-1, seed=1))
                client.pump(0.3)
            assert mode.success, mode.message
            # the heatmaps follow a prediction once policy_node sees viz_node's subscription
            predicted = None
            while time.monotonic() < deadline and "/heatmaps/top" not in client.messages:
                request = PredictKeypose.Request(embedding=mode.embedding, phase=1)
                predicted = call(predict, request)
                assert predicted.success, predicted.message
                client.pump(0.5)
            executed = Keypose(1, np.array([0.6, 0.05, 0.3]), np.array([0.0, 1.0, 0.0, 0.0]), True)
            keypose_pub.publish(keypose_msg(executed, views_msg.header.stamp))
            wanted = expected
            while time.monotonic() < deadline and not wanted <= set(client.messages):
                client.pump(0.5)
            assert wanted <= set(client.messages), sorted(wanted - set(client.messages))
            client.pump(1.5)  # the keyposes again, after /keypose

            cloud_fx = client.latest("/fused_points")
            assert cloud_fx.frame_id == "world"
            assert len(cloud_fx.data) == POINTS * cloud_fx.point_stride
            layout = np.dtype([("xyz", "<f4", 3), ("rgba", "u1", 4)])
            decoded = np.frombuffer(cloud_fx.data, layout)
            np.testing.assert_array_equal(decoded["xyz"], xyz[:POINTS])
            for v in VIEWS:
                for prefix in ("views", "heatmaps"):
                    image = client.latest(f"/{prefix}/{v}")
                    assert (image.width, image.height, image.encoding) == \
                        (config.resolution, config.resolution, "rgb8")
                    assert len(image.data) == 3 * config.resolution ** 2
            frames = {t.child_frame_id: t for t in client.latest("/keyposes/frames").transforms}
            executed_frame = frames["keypose/1_REACH"]
            assert executed_frame.parent_frame_id == "world"
            assert [executed_frame.translation.x, executed_frame.translation.y,
                    executed_frame.translation.z] == pytest.approx(executed.position)
            r = executed_frame.rotation
            assert [r.x, r.y, r.z, r.w] == pytest.approx(executed.quat_xyzw)
            p = frames["keypose/predicted"].translation
            position = predicted.keypose.pose.position
            assert [p.x, p.y, p.z] == pytest.approx([position.x, position.y, position.z])
            labels = [t.text for e in client.latest("/keyposes").entities for t in e.texts]
            assert "1 REACH: REACH closed" in labels, labels
            tf = {t.child_frame_id: t.parent_frame_id for t in client.latest("/tf").transforms}
            assert tf["panda_link0"] == "world" and tf["panda_link1"] == "panda_link0"
            assert tf["panda_hand"] in ("panda_link8", "panda_link7")
            mode_fx = client.latest("/mode")
            assert mode_fx["cluster"] == mode.cluster
            assert mode_fx["probabilities"] == pytest.approx(list(mode.cluster_probabilities))
            assert client.latest("/episode") == {"episode": 0, "event": "START",
                                                 "object_id": "drawer", "success": False,
                                                 "note": ""}
    finally:
        stop.set()
        streamer.join()
    # The client left: viz_node lets go of the large topics again.
    assert wait_for(lambda: cloud_pub.get_subscription_count() == 0, 20.0), viz.output()


def test_a_taken_port_leaves_the_node_up_until_it_is_free(tmp_path):
    """Another graph's viz_node holds the port: this one says so and serves once it is free,
    instead of exiting (which would stop the graph it was launched with)."""
    holder = socket.socket()
    holder.bind(("127.0.0.1", 0))
    holder.listen()
    port = holder.getsockname()[1]
    viz = NodeProcess("actaim2_policy", "viz_node", {"port": port, "robot": ""}, [], tmp_path)
    try:
        assert wait_for(lambda: f"cannot serve Foxglove on 127.0.0.1:{port}" in viz.output(),
                        60.0), viz.output()
        assert viz.alive() and "viz_node ready" not in viz.output()
        holder.close()
        assert wait_for(lambda: f"ready: Foxglove WebSocket ws://127.0.0.1:{port}" in viz.output(),
                        30.0), viz.output()
        with connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS) as ws:
            assert json.loads(ws.recv(timeout=10.0))["op"] == "serverInfo"
    finally:
        holder.close()
        assert viz.stop() == 0, viz.output()


def test_committed_layout_is_the_generated_one_and_names_served_channels():
    from actaim2.viz.layout import COMMITTED, layout_json

    committed = (REPO / COMMITTED).read_text()
    assert committed == layout_json(), "regenerate: python -m actaim2.viz.layout"
    for topic in ("/fused_points", "/keyposes", "/mode", "/episode", "/views/top",
                  "/heatmaps/right"):
        assert f'"{topic}' in committed


def test_golden_bags_open_as_foxglove_reads_them():
    """Foxglove opens an MCAP with the ros2 profile, ros2msg schemas and cdr messages as it is."""
    from mcap.reader import make_reader

    files = sorted((REPO / "bags").glob("*/*.mcap"))
    assert files
    for path in files:
        with open(path, "rb") as stream:
            reader = make_reader(stream)
            summary = reader.get_summary()
            assert reader.get_header().profile == "ros2"
            assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
            assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
            assert all(c.schema_id in summary.schemas for c in summary.channels.values())
