"""fusion_node and calibration_publisher over real rclpy, in their own processes.

The main scene is what a real Azure Kinect rig sends: an organized xyz-only cloud (point_step 16,
320x288) in ``depth_camera_link`` whose extrinsics arrive as the two-link /tf_static chain
``world -> camera_base`` (the hand-eye calibration) + ``camera_base -> depth_camera_link`` (the
driver), from two different publishers.
"""
from __future__ import annotations

import subprocess
import threading
import time

import numpy as np
import pytest
import yaml
from actaim2_msgs.msg import OrthoViews
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import Image, JointState, PointCloud2, PointField
from tf2_msgs.msg import TFMessage

from actaim2.geometry import T_ENTITY_OPTICAL, pose_to_matrix
from actaim2.perception.config import (
    PerceptionConfig,
    load_perception_config,
    save_perception_config,
)
from actaim2.perception.ortho_views import CHANNELS, VIEWS, cube_to_world, project
from actaim2.perception.synthetic import RaycastScene, box_mesh, robot_collision_meshes
from actaim2.robots import load_robot_spec
from actaim2.sim.cameras import look_at_optical
from actaim2_ros.pointcloud2 import from_msg, to_msg
from actaim2_ros.transforms import (
    TF_STATIC_LISTENER_QOS,
    StaticTransformPublisher,
    matrix_to_transform,
    transform_to_matrix,
)
from harness import wait_for

CENTER, HALF = (0.5, 0.0, 0.3), 0.5
BOX_CENTER, BOX_SIZE = np.array([0.6, 0.25, 0.15]), np.array([0.2, 0.2, 0.3])
# camera_base has x forward, z up; the driver's depth_camera_link is an optical frame 1.8 mm above it.
T_BASE_DEPTH = T_ENTITY_OPTICAL @ pose_to_matrix([0.0, 0.0018, 0.0], [0.0, 0.0, 0.0, 1.0])
T_WORLD_BASE = look_at_optical([1.4, 0.5, 0.9], [0.5, 0.1, 0.2]) @ np.linalg.inv(T_BASE_DEPTH)
NODE_PARAMS = {"cloud_topics": ["/points2"], "remove_robot_fused": False, "report_period": 60.0}
# The Azure Kinect rig's configuration around this scene's smaller cube.
PERCEPTION = load_perception_config("azure_kinect").replace(center=CENTER, half_extent=HALF)


def node_params(tmp_path, perception: PerceptionConfig = PERCEPTION, **params) -> dict:
    """NODE_PARAMS (+ overrides) with ``perception`` written to a YAML the node loads."""
    path = tmp_path / f"perception_{perception.digest()}.yaml"
    save_perception_config(perception, path)
    return dict(NODE_PARAMS, perception_config=str(path), **params)


@pytest.fixture(scope="module")
def panda_joints():
    spec = load_robot_spec("panda")
    joints = dict(zip(spec.arm_joints, spec.home))
    joints.update({name: 0.04 for name in spec.gripper_joints})
    return spec, joints


@pytest.fixture(scope="module")
def azure_cloud(panda_joints):
    """xyz-only organized 320x288 cloud of a floor, a box and the Panda at home, in depth_camera_link."""
    spec, joints = panda_joints
    meshes = [(box_mesh([0.5, 0.0, -0.01], [2.0, 2.0, 0.02]), (90, 90, 90)), (box_mesh(BOX_CENTER, BOX_SIZE), (200, 30, 30))]
    meshes += [(m, (230, 230, 230)) for m in robot_collision_meshes(spec, joints)]
    xyz, _ = RaycastScene(meshes).capture(T_WORLD_BASE @ T_BASE_DEPTH, 320, 288, hfov_deg=75.0)
    return xyz


class Inbox:
    """Collects messages of one topic; thread-safe enough for the executor thread + test thread."""

    def __init__(self, node, msg_type, topic, qos):
        self.messages = []
        self._lock = threading.Lock()
        node.create_subscription(msg_type, topic, self._store, qos)

    def _store(self, msg):
        with self._lock:
            self.messages.append(msg)

    def latest(self):
        with self._lock:
            return self.messages[-1] if self.messages else None


def publish_until(publisher, make_msg, done, timeout=30.0, period=0.2):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        publisher.publish(make_msg())
        if wait_for(done, period):
            return True
    return False


def send_tf_chain(node) -> None:
    """The calibration's edge and the driver's edge, from two latched publishers."""
    StaticTransformPublisher(node).send([matrix_to_transform(T_WORLD_BASE, "world", "camera_base")])
    StaticTransformPublisher(node).send([matrix_to_transform(T_BASE_DEPTH, "camera_base", "depth_camera_link")])


def test_azure_kinect_cloud_through_a_two_link_tf_chain(ros_node, start_node, azure_cloud, panda_joints, tmp_path):
    _, joints = panda_joints
    process = start_node("actaim2_perception", "fusion_node", node_params(tmp_path))
    send_tf_chain(ros_node)
    cloud_pub = ros_node.create_publisher(PointCloud2, "/points2", qos_profile_sensor_data)
    joint_pub = ros_node.create_publisher(JointState, "/joint_states", 10)
    views = Inbox(ros_node, OrthoViews, "/ortho_views", QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
    fused = Inbox(ros_node, PointCloud2, "/fused_points", qos_profile_sensor_data)
    preview = Inbox(ros_node, Image, "/ortho_views/preview", qos_profile_sensor_data)
    assert wait_for(lambda: cloud_pub.get_subscription_count() > 0 and joint_pub.get_subscription_count() > 0, 30.0), process.output()
    assert wait_for(lambda: ros_node.count_publishers("/fused_points") > 0, 10.0)

    stamp = ros_node.get_clock().now().to_msg()
    msg = to_msg(azure_cloud, None, "depth_camera_link", stamp)
    assert (msg.point_step, msg.height, msg.width) == (16, 288, 320)

    def joint_state_and_cloud():
        state = JointState(name=list(joints), position=list(joints.values()))
        state.header.stamp = stamp  # the robot is removed as it stood at the cloud's stamp
        joint_pub.publish(state)
        return msg

    received = lambda: views.latest() is not None and fused.latest() is not None and preview.latest() is not None  # noqa: E731
    assert publish_until(cloud_pub, joint_state_and_cloud, received), process.output()
    out = views.latest()
    assert (out.header.stamp.sec, out.header.stamp.nanosec) == (stamp.sec, stamp.nanosec)
    assert out.header.frame_id == "world" and list(out.views) == list(VIEWS) and list(out.channels) == list(CHANNELS)
    data = np.asarray(out.data, dtype=np.float32).reshape(len(VIEWS), len(CHANNELS), out.height, out.width)
    assert out.height == out.width == 128 and out.half_extent == pytest.approx(HALF)
    assert out.config_digest == PERCEPTION.digest()  # the configuration that made the views

    # The box's top face, seen from above: the expected pixel holds the face's point (cube frame) and depth.
    top = VIEWS.index("top")
    face_point = BOX_CENTER + [0.0, 0.0, BOX_SIZE[2] / 2]
    u, v, depth = (a[top, 0] for a in project(face_point, CENTER, HALF, 128))
    pixel = data[top, :, int(v), int(u)]
    assert pixel[CHANNELS.index("occupancy")] == 1.0
    np.testing.assert_allclose(cube_to_world(pixel[[CHANNELS.index(c) for c in "xyz"]], CENTER, HALF), face_point, atol=0.01)
    np.testing.assert_allclose(pixel[CHANNELS.index("depth")] * 2 * HALF, depth, atol=0.002)

    # /fused_points keeps the robot (remove_robot_fused false), the views do not show it.
    fused_xyz = from_msg(fused.latest()).xyz
    assert fused.latest().header.frame_id == "world"
    assert np.all(np.abs(fused_xyz - CENTER) <= HALF + 1e-6)
    hand_region = lambda p: (np.abs(p[:, 0] - 0.31) < 0.08) & (np.abs(p[:, 1]) < 0.12) & (p[:, 2] > 0.45)  # noqa: E731
    assert hand_region(fused_xyz).sum() > 50
    occupied = data[:, CHANNELS.index("occupancy")] > 0
    view_points = cube_to_world(data.transpose(0, 2, 3, 1)[occupied][:, [CHANNELS.index(c) for c in "xyz"]], CENTER, HALF)
    assert hand_region(view_points).sum() == 0
    assert (preview.latest().height, preview.latest().width, preview.latest().encoding) == (128, 640, "rgb8")
    assert process.alive()


def test_bad_input_is_logged_once_per_cause_and_never_published(ros_node, start_node, azure_cloud, tmp_path):
    params = node_params(tmp_path, PERCEPTION.replace(remove_robot_views=False), cloud_topics=["/points2", "/cam2/points"], sync_slop=0.02)
    process = start_node("actaim2_perception", "fusion_node", params)
    send_tf_chain(ros_node)
    pubs = [ros_node.create_publisher(PointCloud2, t, qos_profile_sensor_data) for t in params["cloud_topics"]]
    views = Inbox(ros_node, OrthoViews, "/ortho_views", QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
    assert wait_for(lambda: all(p.get_subscription_count() > 0 for p in pubs), 30.0), process.output()

    good = to_msg(azure_cloud, None, "depth_camera_link")
    missing_z = to_msg(azure_cloud, None, "depth_camera_link")
    missing_z.fields = [f for f in missing_z.fields if f.name != "z"]
    all_nan = to_msg(np.full_like(azure_cloud, np.nan), None, "depth_camera_link")
    empty = to_msg(np.zeros((0, 3), np.float32), None, "depth_camera_link")
    unknown = to_msg(azure_cloud, None, "kinect_that_nobody_calibrated")
    cases = [(missing_z, "missing field(s) z"), (all_nan, "every point is NaN"), (empty, "empty cloud"),
             (unknown, "unknown frame 'kinect_that_nobody_calibrated'")]

    def send_pair(bad, offset_ns=0):
        now = ros_node.get_clock().now().nanoseconds
        for pub, msg, t in ((pubs[0], good, now), (pubs[1], bad, now + offset_ns)):
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t, 1_000_000_000)
            pub.publish(msg)

    def send_until_logged(text, send):
        """Best-effort clouds of 1.5 MB can be lost: repeat until logged, then twice more."""
        assert wait_for(lambda: send() or text in process.output(), 20.0, interval=0.2), process.output()
        for _ in range(2):
            send()
            time.sleep(0.2)

    for bad, text in cases:
        send_until_logged(text, lambda: send_pair(bad))
    send_until_logged("exceed sync_slop", lambda: send_pair(good, offset_ns=100_000_000_000))  # 100 s apart, slop 20 ms
    assert views.latest() is None  # nothing half-made was published
    log = process.output()
    for _, text in cases:
        assert log.count(text) == 1, log
    assert log.count("exceed sync_slop") == 1, log

    deadline = time.monotonic() + 20.0
    while views.latest() is None and time.monotonic() < deadline:
        send_pair(good)
        wait_for(lambda: views.latest() is not None, 0.2)
    assert views.latest() is not None, process.output()
    assert process.alive()


def test_extrinsics_from_a_calibration_file(ros_node, start_node, azure_cloud, tmp_path):
    calibration = tmp_path / "calibration.yaml"
    calibration.write_text(yaml.safe_dump({"transforms": {"depth_camera_link": (T_WORLD_BASE @ T_BASE_DEPTH).tolist()}}))
    params = node_params(tmp_path, PERCEPTION.replace(remove_robot_views=False), calibration_file=str(calibration))
    process = start_node("actaim2_perception", "fusion_node", params)
    cloud_pub = ros_node.create_publisher(PointCloud2, "/points2", qos_profile_sensor_data)
    views = Inbox(ros_node, OrthoViews, "/ortho_views", QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
    assert wait_for(lambda: cloud_pub.get_subscription_count() > 0, 30.0), process.output()
    msg = to_msg(azure_cloud, None, "depth_camera_link")
    assert publish_until(cloud_pub, lambda: msg, lambda: views.latest() is not None), process.output()
    data = np.asarray(views.latest().data, dtype=np.float32).reshape(len(VIEWS), len(CHANNELS), 128, 128)
    top = VIEWS.index("top")
    face_point = BOX_CENTER + [0.0, 0.0, BOX_SIZE[2] / 2]
    u, v, _ = (a[top, 0] for a in project(face_point, CENTER, HALF, 128))
    np.testing.assert_allclose(cube_to_world(data[top, [CHANNELS.index(c) for c in "xyz"], int(v), int(u)], CENTER, HALF), face_point, atol=0.01)


def record_azure_bag(path, cloud_xyz: np.ndarray, frames: int) -> None:
    """What an Azure Kinect recording holds without an arm: /tf_static (calibration + driver edges) and /points2."""
    from rclpy.serialization import serialize_message
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    tf = TFMessage(transforms=[matrix_to_transform(T_WORLD_BASE, "world", "camera_base"),
                               matrix_to_transform(T_BASE_DEPTH, "camera_base", "depth_camera_link")])
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        tf_connection = writer.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=store)
        cloud_connection = writer.add_connection("/points2", "sensor_msgs/msg/PointCloud2", typestore=store)
        writer.write(tf_connection, 1_000_000_000, serialize_message(tf))
        for k in range(frames):
            stamp_ns = 1_000_000_000 + k * 66_666_667  # 15 Hz
            msg = to_msg(cloud_xyz, None, "depth_camera_link")
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
            writer.write(cloud_connection, stamp_ns, serialize_message(msg))


def test_azure_replay_without_joint_states_gives_fused_points(ros_node, start_node, azure_cloud, tmp_path):
    """A new user replays an Azure Kinect recording (/points2 + /tf_static, no /joint_states) into
    fusion_node with its shipped defaults: /fused_points comes out in `world` although no joint
    state ever arrives; only the robot-hidden views wait, and the log says why."""
    from rclpy.serialization import deserialize_message
    from rosbags.highlevel import AnyReader

    record_azure_bag(tmp_path / "azure_bag", azure_cloud, frames=3)
    with AnyReader([tmp_path / "azure_bag"]) as reader:
        recorded = [(c.topic, raw) for c, _, raw in reader.messages()]
    tf = deserialize_message(next(raw for topic, raw in recorded if topic == "/tf_static"), TFMessage)
    clouds = [deserialize_message(raw, PointCloud2) for topic, raw in recorded if topic == "/points2"]

    process = start_node("actaim2_perception", "fusion_node")  # no parameters: the shipped defaults
    StaticTransformPublisher(ros_node).send(list(tf.transforms))
    cloud_pub = ros_node.create_publisher(PointCloud2, "/points2", qos_profile_sensor_data)
    fused = Inbox(ros_node, PointCloud2, "/fused_points", qos_profile_sensor_data)
    views = Inbox(ros_node, OrthoViews, "/ortho_views", QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
    assert wait_for(lambda: cloud_pub.get_subscription_count() > 0, 30.0), process.output()
    frame = iter(range(10**6))
    assert publish_until(cloud_pub, lambda: clouds[next(frame) % len(clouds)], lambda: fused.latest() is not None), process.output()

    out = fused.latest()
    assert out.header.frame_id == "world"
    xyz = from_msg(out).xyz
    perception = load_perception_config("azure_kinect")
    assert len(xyz) > 1000 and np.all(np.abs(xyz - perception.center) <= perception.half_extent + 1e-6)
    top_face = (np.abs(xyz[:, :2] - BOX_CENTER[:2]) < 0.08).all(axis=1) & (np.abs(xyz[:, 2] - BOX_CENTER[2] - BOX_SIZE[2] / 2) < 0.01)
    assert top_face.sum() > 50  # the box's top face, where the recording's extrinsics put it
    assert wait_for(lambda: "/ortho_views wait" in process.output(), 10.0), process.output()
    assert views.latest() is None  # robot-hidden views need the robot's joint states
    assert process.alive()


def test_calibration_publisher_latches_the_yaml_on_tf_static(ros_node, start_node, tmp_path):
    T = pose_to_matrix([1.2, -0.3, 0.9], [0.1, 0.2, 0.3, 0.927])
    calibration = tmp_path / "calibration.yaml"
    calibration.write_text(yaml.safe_dump({"parent_frame": "world", "transforms": {"camera_base": T.tolist()}}))
    process = start_node("actaim2_perception", "calibration_publisher", {"calibration_file": str(calibration)})
    assert wait_for(lambda: "published 1 static transform" in process.output(), 30.0), process.output()
    # Subscribing only now: transient-local durability still delivers the transform (like a bag recorder).
    tf = Inbox(ros_node, TFMessage, "/tf_static", TF_STATIC_LISTENER_QOS)
    assert wait_for(lambda: tf.latest() is not None, 15.0), process.output()
    edge = tf.latest().transforms[0]
    assert (edge.header.frame_id, edge.child_frame_id) == ("world", "camera_base")
    np.testing.assert_allclose(transform_to_matrix(edge), T, atol=1e-6)

    broken = tmp_path / "broken.yaml"
    broken.write_text("transforms:\n  camera_base: [[1, 0, 0], [0, 1, 0]]\n")
    failing = subprocess.run(
        ["ros2", "run", "actaim2_perception", "calibration_publisher", "--ros-args", "-p", f"calibration_file:={broken}"],
        capture_output=True, text=True, timeout=60,
    )
    assert failing.returncode == 1 and "expected a 4x4 matrix" in failing.stdout + failing.stderr


def test_pointfield_datatypes_match_the_codec():
    assert PointField.FLOAT32 == 7 and PointField.UINT32 == 6 and PointField.FLOAT64 == 8 and PointField.UINT8 == 2
