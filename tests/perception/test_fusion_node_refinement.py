"""fusion_node with ``refine_extrinsic``: a hand-eye calibration off by 1 cm / 1 deg is corrected by registering
the robot itself to the cloud, so /fused_points lands where the scene is.

The scene is test_fusion_node's Azure Kinect cloud (a floor, a box and the Panda at home, ray cast from its
collision meshes) with the /tf_static chain's calibration edge ``world -> camera_base`` moved by the error.
"""
from __future__ import annotations

import numpy as np
from rclpy.qos import qos_profile_sensor_data
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import JointState, PointCloud2

from actaim2_ros.pointcloud2 import from_msg, to_msg
from actaim2_ros.transforms import StaticTransformPublisher, matrix_to_transform
from harness import wait_for
from test_fusion_node import (  # noqa: F401 - azure_cloud and panda_joints are fixtures
    T_BASE_DEPTH,
    T_WORLD_BASE,
    Inbox,
    azure_cloud,
    node_params,
    panda_joints,
    publish_until,
)


def miscalibrated() -> np.ndarray:
    """The calibration edge moved by 1 cm and turned by 1 deg in camera_base's frame."""
    delta = np.eye(4)
    delta[:3, :3] = Rotation.from_rotvec(np.deg2rad(1.0) * np.array([0.6, -0.8, 0.0])).as_matrix()
    delta[:3, 3] = 0.01 * np.array([0.0, 0.6, 0.8])
    return T_WORLD_BASE @ delta


def median_gap(fused: np.ndarray, truth: np.ndarray) -> float:
    return float(np.median(cKDTree(truth).query(fused)[0]))


def test_a_miscalibrated_extrinsic_is_refined_from_the_robot(ros_node, start_node, azure_cloud, panda_joints, tmp_path):  # noqa: F811
    _, joints = panda_joints
    process = start_node("actaim2_perception", "fusion_node",
                         node_params(tmp_path, robot="panda", refine_extrinsic=True, refine_extrinsic_period=1.0,
                                     report_period=1.0))
    StaticTransformPublisher(ros_node).send([matrix_to_transform(miscalibrated(), "world", "camera_base")])
    StaticTransformPublisher(ros_node).send([matrix_to_transform(T_BASE_DEPTH, "camera_base", "depth_camera_link")])
    cloud_pub = ros_node.create_publisher(PointCloud2, "/points2", qos_profile_sensor_data)
    joint_pub = ros_node.create_publisher(JointState, "/joint_states", 10)
    fused = Inbox(ros_node, PointCloud2, "/fused_points", qos_profile_sensor_data)
    assert wait_for(lambda: cloud_pub.get_subscription_count() > 0 and joint_pub.get_subscription_count() > 0, 30.0), process.output()

    def joint_state_and_cloud():
        stamp = ros_node.get_clock().now().to_msg()
        state = JointState(name=list(joints), position=list(joints.values()))
        state.header.stamp = stamp
        joint_pub.publish(state)
        return to_msg(azure_cloud, None, "depth_camera_link", stamp)

    points = azure_cloud.reshape(-1, 3)
    points = points[np.isfinite(points).all(axis=1)]
    world = {name: points @ T[:3, :3].T + T[:3, 3] for name, T in
             (("truth", T_WORLD_BASE @ T_BASE_DEPTH), ("miscalibrated", miscalibrated() @ T_BASE_DEPTH))}
    assert median_gap(world["miscalibrated"], world["truth"]) > 0.01  # what /tf_static alone would give

    def on_the_scene() -> bool:
        return fused.latest() is not None and median_gap(from_msg(fused.latest()).xyz, world["truth"]) < 0.004

    assert publish_until(cloud_pub, joint_state_and_cloud, on_the_scene), \
        (fused.latest() and median_gap(from_msg(fused.latest()).xyz, world["truth"]), process.output())
    assert "extrinsic refined from the robot by" in process.output()
