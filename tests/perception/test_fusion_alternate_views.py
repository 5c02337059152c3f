"""fusion_node's second views topic: the same clouds rendered with the other robot-filter setting,
stamped with that configuration's digest, for a policy whose selector and predictor were trained
on different ones (policy_node's predictor_views_topic)."""
from __future__ import annotations

import numpy as np
from actaim2_msgs.msg import OrthoViews
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState, PointCloud2

from actaim2.perception.ortho_views import CHANNELS, VIEWS, cube_to_world
from actaim2_ros.pointcloud2 import to_msg
from harness import wait_for
from test_fusion_node import (
    CENTER,
    HALF,
    PERCEPTION,
    Inbox,
    azure_cloud,
    node_params,
    panda_joints,
    publish_until,
    send_tf_chain,
)

__all__ = ["azure_cloud", "panda_joints"]  # fixtures used by the test below


def hand_points(msg: OrthoViews) -> int:
    """Points of the views near the Panda's hand at home."""
    data = np.asarray(msg.data, dtype=np.float32).reshape(len(VIEWS), len(CHANNELS), msg.height, msg.width)
    occupied = data[:, CHANNELS.index("occupancy")] > 0
    xyz = cube_to_world(data.transpose(0, 2, 3, 1)[occupied][:, [CHANNELS.index(c) for c in "xyz"]], CENTER, HALF)
    return int(((np.abs(xyz[:, 0] - 0.31) < 0.08) & (np.abs(xyz[:, 1]) < 0.12) & (xyz[:, 2] > 0.45)).sum())


def test_views_with_the_robot_on_the_alternate_topic(ros_node, start_node, azure_cloud, panda_joints, tmp_path):
    _, joints = panda_joints
    process = start_node("actaim2_perception", "fusion_node", node_params(tmp_path, alternate_views_topic="/ortho_views_with_robot"))
    send_tf_chain(ros_node)
    cloud_pub = ros_node.create_publisher(PointCloud2, "/points2", qos_profile_sensor_data)
    joint_pub = ros_node.create_publisher(JointState, "/joint_states", 10)
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
    hidden, visible = Inbox(ros_node, OrthoViews, "/ortho_views", qos), Inbox(ros_node, OrthoViews, "/ortho_views_with_robot", qos)
    assert wait_for(lambda: cloud_pub.get_subscription_count() > 0 and joint_pub.get_subscription_count() > 0, 30.0), process.output()
    stamp = ros_node.get_clock().now().to_msg()

    def joint_state_and_cloud():
        state = JointState(name=list(joints), position=list(joints.values()))
        state.header.stamp = stamp
        joint_pub.publish(state)
        return to_msg(azure_cloud, None, "depth_camera_link", stamp)

    assert publish_until(cloud_pub, joint_state_and_cloud, lambda: hidden.latest() and visible.latest()), process.output()
    a, b = hidden.latest(), visible.latest()
    assert (a.header.stamp, b.header.stamp) == (stamp, stamp)
    assert a.config_digest == PERCEPTION.digest() and b.config_digest == PERCEPTION.replace(remove_robot_views=False).digest()
    assert hand_points(a) == 0 and hand_points(b) > 50
