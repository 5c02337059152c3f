"""fusion_node poses the robot at the cloud's stamp from the /joint_states around it, and refuses
(logging why) a cloud newer than its joint states by more than the extrapolation window.

The cloud is test_fusion_node's Azure Kinect scene with the Panda at home. The JointStates that
bracket the cloud's stamp swing joint 1 by +-0.4 rad (the hand 12 cm either side): only the
state interpolated at the stamp puts the robot where the cloud shows it.
"""
from __future__ import annotations

import time

import numpy as np
import pinocchio as pin
from actaim2_msgs.msg import OrthoViews
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState, PointCloud2

from actaim2.perception.ortho_views import CHANNELS, cube_to_world
from actaim2.perception.self_filter import RobotSelfFilter, set_configuration
from actaim2_ros.pointcloud2 import to_msg
from harness import wait_for
from test_fusion_node import (
    CENTER,
    HALF,
    T_BASE_DEPTH,
    T_WORLD_BASE,
    Inbox,
    azure_cloud,
    node_params,
    panda_joints,
    publish_until,
    send_tf_chain,
)

__all__ = ["azure_cloud", "panda_joints"]  # fixtures used by the tests below

MS = 1_000_000


def stamped(joints: dict[str, float], stamp_ns: int) -> JointState:
    msg = JointState(name=list(joints), position=list(joints.values()))
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    return msg


def near_hand(spec, joints: dict[str, float], points: np.ndarray) -> np.ndarray:
    """Points within 8 cm of the hand (its origin to the fingertips) at ``joints``."""
    model = RobotSelfFilter(spec).model
    data, q = model.createData(), pin.neutral(model)
    set_configuration(model, q, joints)
    pin.framesForwardKinematics(model, data, q)
    T = data.oMf[model.getFrameId(spec.flange_frame)].homogeneous
    a, b = T[:3, 3], (T @ spec.T_flange_tcp)[:3, 3]
    s = np.clip((points - a) @ (b - a) / np.dot(b - a, b - a), 0.0, 1.0)
    return np.linalg.norm(points - (a + s[:, None] * (b - a)), axis=1) < 0.08


def azure_cloud_world(xyz: np.ndarray) -> np.ndarray:
    """The test cloud's valid points in world, through the same extrinsics the node gets."""
    T = T_WORLD_BASE @ T_BASE_DEPTH
    points = xyz.reshape(-1, 3)
    points = points[np.isfinite(points).all(axis=1)]
    return points @ T[:3, :3].T + T[:3, 3]


def test_the_robot_is_removed_where_it_stood_at_the_cloud_stamp(ros_node, start_node, azure_cloud, panda_joints, tmp_path):
    spec, home = panda_joints
    process = start_node("actaim2_perception", "fusion_node", node_params(tmp_path, report_period=1.0))
    send_tf_chain(ros_node)
    cloud_pub = ros_node.create_publisher(PointCloud2, "/points2", qos_profile_sensor_data)
    joint_pub = ros_node.create_publisher(JointState, "/joint_states", 10)
    views = Inbox(ros_node, OrthoViews, "/ortho_views", QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
    assert wait_for(lambda: cloud_pub.get_subscription_count() > 0 and joint_pub.get_subscription_count() > 0, 30.0), process.output()

    swung = {sign: dict(home, panda_joint1=home["panda_joint1"] + sign * 0.4) for sign in (1, -1)}
    stamp = ros_node.get_clock().now().nanoseconds
    cloud = to_msg(azure_cloud, None, "depth_camera_link")
    cloud.header.stamp.sec, cloud.header.stamp.nanosec = divmod(stamp, 1_000_000_000)

    def states_then_cloud():
        joint_pub.publish(stamped(swung[1], stamp - 10 * MS))  # 10 ms before the cloud
        joint_pub.publish(stamped(swung[-1], stamp + 10 * MS))  # 10 ms after: the newest
        return cloud

    assert publish_until(cloud_pub, states_then_cloud, lambda: views.latest() is not None), process.output()
    out = views.latest()
    assert (out.header.stamp.sec, out.header.stamp.nanosec) == divmod(stamp, 1_000_000_000)
    data = np.asarray(out.data, dtype=np.float32).reshape(len(out.views), len(out.channels), out.height, out.width)
    occupied = data[:, CHANNELS.index("occupancy")] > 0
    view_points = cube_to_world(data.transpose(0, 2, 3, 1)[occupied][:, [CHANNELS.index(c) for c in "xyz"]], CENTER, HALF)
    assert near_hand(spec, home, azure_cloud_world(azure_cloud)).sum() > 50  # the cloud does show the hand
    assert near_hand(spec, home, view_points).sum() == 0  # ... the views do not

    # A cloud 1 s after the newest JointState: refused, with the reason, and nothing published for it.
    late = stamp + 1010 * MS
    cloud.header.stamp.sec, cloud.header.stamp.nanosec = divmod(late, 1_000_000_000)
    reason = "stamp 1000.0 ms after its newest JointState (extrapolation limited to 25.0 ms)"
    assert wait_for(lambda: cloud_pub.publish(cloud) or reason in process.output(), 20.0, interval=0.3), process.output()
    time.sleep(0.5)
    latest = views.latest().header.stamp
    assert latest.sec * 10**9 + latest.nanosec == stamp
    assert process.alive()

