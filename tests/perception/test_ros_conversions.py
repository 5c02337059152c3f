"""actaim2_perception's message conversions (used by the sim node too): PointCloud2 and TransformStamped."""
from __future__ import annotations

import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import PointCloud2

from actaim2.geometry import pose_to_matrix
from actaim2_ros.pointcloud2 import from_msg, to_msg
from actaim2_ros.transforms import TF_STATIC_QOS, matrix_to_transform, transform_to_matrix


def test_pointcloud2_round_trip_through_cdr():
    rng = np.random.default_rng(0)
    xyz = rng.normal(size=(6, 4, 3)).astype(np.float32)
    xyz[2, 3] = np.nan
    rgb = rng.integers(0, 256, size=(6, 4, 3), dtype=np.uint8)
    msg = to_msg(xyz, rgb, "cam0_optical_frame")
    assert (msg.height, msg.width, msg.point_step, msg.row_step, msg.is_dense, msg.is_bigendian) == (6, 4, 32, 128, False, False)
    assert [(f.name, f.offset, f.datatype, f.count) for f in msg.fields] == [
        ("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("rgb", 16, 7, 1)]
    back = from_msg(deserialize_message(serialize_message(msg), PointCloud2))
    np.testing.assert_array_equal(back.xyz, xyz.reshape(-1, 3))
    np.testing.assert_array_equal(back.rgb, rgb.reshape(-1, 3))
    unorganized = to_msg(xyz.reshape(-1, 3)[:5], None, "world")
    assert (unorganized.height, unorganized.width, unorganized.point_step) == (1, 5, 16)


def test_transform_round_trip_and_tf_static_qos():
    T = pose_to_matrix([0.4, -1.2, 2.0], [0.2, -0.3, 0.1, 0.927])
    msg = matrix_to_transform(T, "world", "camera_base")
    assert (msg.header.frame_id, msg.child_frame_id) == ("world", "camera_base")
    q = msg.transform.rotation
    assert abs(np.linalg.norm([q.x, q.y, q.z, q.w]) - 1.0) < 1e-9 and q.w >= 0
    np.testing.assert_allclose(transform_to_matrix(msg), T, atol=1e-12)
    np.testing.assert_allclose(transform_to_matrix(msg.transform), T, atol=1e-12)
    assert TF_STATIC_QOS.durability.name == "TRANSIENT_LOCAL" and TF_STATIC_QOS.reliability.name == "RELIABLE"
