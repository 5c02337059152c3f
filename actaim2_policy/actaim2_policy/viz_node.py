"""viz_node: the graph, live, in Foxglove (WebSocket protocol ``foxglove.websocket.v1``).

It starts the Foxglove SDK's WebSocket server on 127.0.0.1 (never another interface) and logs
what the graph publishes as Foxglove messages (the channel table of
:mod:`actaim2.viz.foxglove_live`): the fused cloud, the five orthographic views, the predicted
position heatmaps per view, the predicted keypose and the executed ones with their gripper
state, the TF tree (/tf_static and the robot's links from /joint_states), the mode
probabilities and chosen cluster, and the episode events. Connect the Foxglove app to
ws://127.0.0.1:8765 and open ``docs/foxglove/actaim2_layout.json``.

Costs nothing while no client watches: the large topics (/fused_points, /ortho_views,
/policy/heatmaps, /joint_states) are subscribed only while some client subscribes to a channel
made from them (checked every ``poll_period``), and nothing is converted for a channel without a
subscriber. The small ones (/tf_static, /keypose, /episode, the policy's service events) are
always subscribed: they are the state a client sees when it connects, logged again every
``state_period``.
"""
from __future__ import annotations

import threading
from typing import Any, Callable

import foxglove
import numpy as np
from actaim2_msgs.msg import EpisodeEvent, OrthoViews
from actaim2_msgs.msg import Keypose as KeyposeMsg
from actaim2_msgs.srv import PredictKeypose, SampleMode
from foxglove.channels import (
    FrameTransformsChannel,
    PointCloudChannel,
    RawImageChannel,
    SceneUpdateChannel,
)
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState, PointCloud2
from service_msgs.msg import ServiceEventInfo
from tf2_msgs.msg import TFMessage

from actaim2.keypose import PHASE_NAMES, Keypose
from actaim2.perception.cloud_codec import CloudFormatError, Field, decode
from actaim2.perception.ortho_views import VIEWS
from actaim2.viz import foxglove_live as live
from actaim2_ros.keypose import keypose_data
from actaim2_ros.main import spin
from actaim2_ros.params import declare_parameters
from actaim2_ros.stamps import stamp_ns

HOST = "127.0.0.1"  # the server never listens beyond this machine
RETRY_PERIOD = 5.0  # s between two tries to serve on a port another process holds
VIEWS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)  # as fusion_node's
HEATMAPS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)  # as policy_node's
KEYPOSE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)  # as control_node's
LATCHED_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)  # /tf_static, /episode
EVENTS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)  # service events
JOINTS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)  # /joint_states

PARAMETERS = {
    "port": (8765, "TCP port of the Foxglove WebSocket server on 127.0.0.1 (0 = any free port, "
                   "logged at start-up)"),
    "robot": ("panda", "the robot whose links /joint_states moves (panda, kinova_j2s6s200 or a "
                       "robot YAML), as control_node's; empty = no robot links on /tf"),
    "fused_points_topic": ("/fused_points", "the fused cloud (PointCloud2, world)"),
    "views_topic": ("/ortho_views", "the orthographic views (OrthoViews)"),
    "heatmaps_topic": ("/policy/heatmaps",
                       "policy_node's predicted position heatmaps (OrthoViews)"),
    "tf_rate": (10.0, "Hz: the robot's links are logged on /tf at most this often"),
    "state_period": (1.0, "s: keyposes, mode, last episode event and heatmaps are logged again "
                          "this often for clients that connected after they changed"),
    "poll_period": (0.5, "s: how often the large topics are subscribed or dropped as clients "
                         "subscribe to or leave their channels"),
}


class VizNode(Node):
    def __init__(self) -> None:
        super().__init__("viz_node")
        p = declare_parameters(self, PARAMETERS)
        for name in ("tf_rate", "state_period", "poll_period"):
            if not float(p[name]) > 0.0:
                raise ValueError(f"{name} {p[name]} is not > 0")
        port = int(p["port"])
        if not 0 <= port <= 65535:
            raise ValueError(f"port {port} is not a TCP port")
        self._links = _link_tree(str(p["robot"]))
        self._lock = threading.Lock()
        self._static: dict[str, Any] = {}  # child frame -> FrameTransform, from /tf_static
        self._joints: JointState | None = None
        self._keyposes: dict[str, Keypose] = {}  # "predicted", then "<i> <PHASE>" per executed one
        self._executed = 0
        self._mode: dict[str, Any] | None = None
        self._episode: dict[str, Any] | None = None
        self._pictures: list[np.ndarray] | None = None  # the latest views' colours
        self._heatmaps: tuple[int, list[str], list[np.ndarray]] | None = None
        self._state_stamp = 0

        self._cloud_ch = PointCloudChannel("/fused_points")
        self._view_chs = {v: RawImageChannel(f"/views/{v}") for v in VIEWS}
        self._heat_chs = {v: RawImageChannel(f"/heatmaps/{v}") for v in VIEWS}
        self._scene_ch = SceneUpdateChannel("/keyposes")
        self._frames_ch = FrameTransformsChannel("/keyposes/frames")
        self._tf_ch = FrameTransformsChannel("/tf")
        self._mode_ch = foxglove.Channel("/mode", schema=live.MODE_SCHEMA)
        self._episode_ch = foxglove.Channel("/episode", schema=live.EPISODE_SCHEMA)

        # (topic, type, QoS, callback, the channels whose subscribers need it)
        self._lazy: list[tuple[str, type, QoSProfile, Callable, list[Any]]] = [
            (p["fused_points_topic"], PointCloud2, qos_profile_sensor_data, self._on_cloud,
             [self._cloud_ch]),
            (p["views_topic"], OrthoViews, VIEWS_QOS, self._on_views,
             [*self._view_chs.values(), *self._heat_chs.values()]),
            (p["heatmaps_topic"], OrthoViews, HEATMAPS_QOS, self._on_heatmaps,
             list(self._heat_chs.values())),
        ]
        if self._links is not None:
            self._lazy.append(("/joint_states", JointState, JOINTS_QOS, self._on_joints,
                               [self._tf_ch]))
        self._held: dict[str, Any] = {}
        self.create_subscription(TFMessage, "/tf_static", self._on_tf_static, LATCHED_QOS)
        self.create_subscription(KeyposeMsg, "/keypose", self._on_keypose, KEYPOSE_QOS)
        self.create_subscription(EpisodeEvent, "/episode", self._on_episode, LATCHED_QOS)
        self.create_subscription(SampleMode.Event, "/sample_mode/_service_event",
                                 self._on_sample_mode_event, EVENTS_QOS)
        self.create_subscription(PredictKeypose.Event, "/predict_keypose/_service_event",
                                 self._on_predict_event, EVENTS_QOS)
        self.create_timer(float(p["poll_period"]), self._reconcile)
        self.create_timer(1.0 / float(p["tf_rate"]), self._log_tf)
        self.create_timer(float(p["state_period"]), self._log_state)
        self._port = port
        self._server: foxglove.WebSocketServer | None = None
        self._retry = self.create_timer(RETRY_PERIOD, self._start_server)
        self._start_server()

    def _start_server(self) -> None:
        """Serve on 127.0.0.1:port; while the port is taken (another graph's viz_node), say so and
        try again every RETRY_PERIOD: the graph it belongs to keeps running without a live view."""
        try:
            self._server = foxglove.start_server(name="actaim2", host=HOST, port=self._port)
        except Exception as exc:  # noqa: BLE001 - the SDK's own error type
            self.get_logger().error(f"cannot serve Foxglove on {HOST}:{self._port} ({exc}); "
                                    f"trying again every {RETRY_PERIOD:.0f} s",
                                    throttle_duration_sec=60.0)
            return
        self._retry.cancel()
        url = f"ws://{HOST}:{self._server.port}"
        self.get_logger().info(f"viz_node ready: Foxglove WebSocket {url} "
                               "(open docs/foxglove/actaim2_layout.json in Foxglove)")

    def destroy_node(self) -> None:
        if self._server is not None:
            self._server.stop()
        super().destroy_node()

    # -- subscriptions that follow the clients ----------------------------------------------
    def _reconcile(self) -> None:
        for topic, msg_type, qos, callback, channels in self._lazy:
            wanted = any(channel.has_sinks() for channel in channels)
            held = topic in self._held
            if wanted and not held:
                self._held[topic] = self.create_subscription(msg_type, topic, callback, qos)
                self.get_logger().info(f"a client watches: subscribed to {topic}")
            elif held and not wanted:
                self.destroy_subscription(self._held.pop(topic))
                self.get_logger().info(f"no client watches: dropped {topic}")

    # -- the large topics -------------------------------------------------------------------
    def _on_cloud(self, msg: PointCloud2) -> None:
        if not self._cloud_ch.has_sinks():
            return
        fields = [Field(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
        try:
            cloud = decode(fields, msg.data, msg.height, msg.width, msg.point_step, msg.row_step,
                           msg.is_bigendian)
        except CloudFormatError as exc:
            self.get_logger().warning(f"/fused_points: {exc}", throttle_duration_sec=10.0)
            return
        stamp = stamp_ns(msg.header.stamp)
        self._cloud_ch.log(live.point_cloud(cloud.xyz, cloud.rgb, stamp, msg.header.frame_id),
                           log_time=stamp)

    def _on_views(self, msg: OrthoViews) -> None:
        views = _views_array(msg)
        try:
            pictures = live.view_pictures(views, tuple(msg.channels))
        except ValueError as exc:
            self.get_logger().warning(f"/ortho_views: {exc}", throttle_duration_sec=10.0)
            return
        with self._lock:
            self._pictures = pictures
        stamp = stamp_ns(msg.header.stamp)
        for name, picture in zip(msg.views, pictures):
            channel = self._view_chs.get(name)
            if channel is not None and channel.has_sinks():
                channel.log(live.rgb_image(picture, stamp), log_time=stamp)

    def _on_heatmaps(self, msg: OrthoViews) -> None:
        probabilities = _views_array(msg)[:, 0]
        with self._lock:
            pictures = self._pictures
        if pictures is not None and len(msg.views) != len(pictures):
            pictures = [pictures[VIEWS.index(v)] for v in msg.views]
        images = live.heatmap_pictures(probabilities, pictures)
        with self._lock:
            self._heatmaps = (stamp_ns(msg.header.stamp), list(msg.views), images)
        self._log_heatmaps()

    def _on_joints(self, msg: JointState) -> None:
        with self._lock:
            self._joints = msg

    # -- the state ------------------------------------------------------------------------------
    def _on_tf_static(self, msg: TFMessage) -> None:
        with self._lock:
            for t in msg.transforms:
                r, q = t.transform.translation, t.transform.rotation
                matrix = np.eye(4)
                matrix[:3, :3] = live.quaternion_matrix(np.array([q.x, q.y, q.z, q.w]))
                matrix[:3, 3] = (r.x, r.y, r.z)
                self._static[t.child_frame_id] = live.transform(
                    t.header.frame_id, t.child_frame_id, matrix, stamp_ns(t.header.stamp))

    def _on_keypose(self, msg: KeyposeMsg) -> None:
        keypose = keypose_data(msg)
        with self._lock:
            self._executed += 1
            self._keyposes[f"{self._executed} {PHASE_NAMES[keypose.phase]}"] = keypose
            self._state_stamp = stamp_ns(msg.header.stamp)
        self._log_keyposes()

    def _on_episode(self, msg: EpisodeEvent) -> None:
        event = "START" if msg.event == EpisodeEvent.START else "END"
        with self._lock:
            self._episode = {"episode": int(msg.episode), "event": event,
                             "object_id": msg.object_id, "success": bool(msg.success),
                             "note": msg.note}
            if event == "START":  # a new episode: its keyposes only
                self._keyposes.clear()
                self._executed = 0
                self._heatmaps = None
            self._state_stamp = stamp_ns(msg.header.stamp)
        self._log_episode()
        self._log_keyposes()

    def _on_sample_mode_event(self, msg: Any) -> None:
        response = _answer(msg)
        if response is None:
            return
        requested = msg.request[0].cluster if msg.request else -1
        with self._lock:
            self._mode = {"cluster": int(response.cluster), "requested": int(requested),
                          "probabilities": [float(v) for v in response.cluster_probabilities]}
        self._log_mode()

    def _on_predict_event(self, msg: Any) -> None:
        response = _answer(msg)
        if response is None:
            return
        with self._lock:
            self._keyposes[live.PREDICTED] = keypose_data(response.keypose)
            self._state_stamp = stamp_ns(response.keypose.header.stamp)
        self._log_keyposes()

    # -- logging --------------------------------------------------------------------------------
    def _log_tf(self) -> None:
        if not self._tf_ch.has_sinks():
            return
        with self._lock:
            transforms = list(self._static.values())
            joints = self._joints
        if joints is not None and self._links is not None:
            angles = _arm_angles(joints, self._links.model.joint_names)
            if angles is not None:
                transforms += self._links.transforms(angles, stamp_ns(joints.header.stamp))
        if transforms:
            self._tf_ch.log(live.frame_transforms(transforms))

    def _log_state(self) -> None:
        self._log_keyposes()
        self._log_mode()
        self._log_episode()
        self._log_heatmaps()

    def _log_keyposes(self) -> None:
        if not (self._scene_ch.has_sinks() or self._frames_ch.has_sinks()):
            return
        with self._lock:
            keyposes, stamp = dict(self._keyposes), self._state_stamp
        if not keyposes:
            return
        self._scene_ch.log(live.keypose_scene(keyposes, stamp))
        frames = [live.keypose_frame(k, f"keypose/{key.replace(' ', '_')}", stamp)
                  for key, k in keyposes.items()]
        self._frames_ch.log(live.frame_transforms(frames))

    def _log_mode(self) -> None:
        with self._lock:
            mode = self._mode
        if mode is not None and self._mode_ch.has_sinks():
            self._mode_ch.log(mode)

    def _log_episode(self) -> None:
        with self._lock:
            episode = self._episode
        if episode is not None and self._episode_ch.has_sinks():
            self._episode_ch.log(episode)

    def _log_heatmaps(self) -> None:
        with self._lock:
            heatmaps = self._heatmaps
        if heatmaps is None:
            return
        stamp, names, images = heatmaps
        for name, image in zip(names, images):
            channel = self._heat_chs.get(name)
            if channel is not None and channel.has_sinks():
                channel.log(live.rgb_image(image, stamp), log_time=stamp)


def _answer(event: Any) -> Any:
    """The successful response a service event carries (the server's RESPONSE_SENT), else None."""
    if event.info.event_type != ServiceEventInfo.RESPONSE_SENT or not event.response:
        return None
    return event.response[0] if event.response[0].success else None


def _views_array(msg: OrthoViews) -> np.ndarray:
    data = np.frombuffer(msg.data, np.float32)
    return data.reshape(len(msg.views), len(msg.channels), msg.height, msg.width)


def _arm_angles(msg: JointState, names: tuple[str, ...]) -> np.ndarray | None:
    """The arm's joint angles in ``names`` order, or None when /joint_states lacks one."""
    index = {name: i for i, name in enumerate(msg.name)}
    if any(name not in index for name in names):
        return None
    return np.array([msg.position[index[name]] for name in names])


def _link_tree(robot: str) -> live.LinkTree | None:
    if not robot:
        return None
    from actaim2.control.model import RobotModel
    from actaim2.robots import load_robot_spec

    return live.LinkTree(RobotModel(load_robot_spec(robot)))


def main(args: list[str] | None = None) -> int:
    return spin(VizNode, "viz_node", args)


if __name__ == "__main__":
    raise SystemExit(main())
