"""`actaim2 render` on a saved cloud and on a rosbag2 with /tf_static and two cloud topics."""
from __future__ import annotations

import numpy as np
import pytest
from PIL import Image
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from actaim2.cli import main as actaim2
from actaim2.geometry import matrix_to_pose
from actaim2.perception.cloud_codec import encode
from actaim2.perception.synthetic import RaycastScene, box_mesh
from actaim2.sim.cameras import look_at_optical

BOX_CENTER = np.array([0.5, 0.0, 0.3])


def two_cameras():
    scene = RaycastScene([(box_mesh(BOX_CENTER, [0.2, 0.3, 0.25]), (200, 40, 40))])
    cameras = [look_at_optical(BOX_CENTER + [0.3, 0.8, 0.4], BOX_CENTER), look_at_optical(BOX_CENTER + [-0.3, -0.8, 0.4], BOX_CENTER)]
    return [(T, *scene.capture(T, 160, 120)) for T in cameras]


def test_saved_cloud_to_png(tmp_path):
    T, xyz, rgb = two_cameras()[0]
    np.savez(tmp_path / "cloud.npz", xyz=xyz, rgb=rgb, T_world_cloud=T)
    assert actaim2(["render", str(tmp_path / "cloud.npz"), "--out", str(tmp_path / "out"), "--resolution", "64"]) == 0
    image = np.asarray(Image.open(tmp_path / "out" / "cloud_rgb.png"))
    assert image.shape == (64, 5 * 64, 3)
    assert np.all(image[image.any(axis=2)] == [200, 40, 40])  # every drawn pixel is the box
    assert Image.open(tmp_path / "out" / "cloud_depth.png").size == (5 * 64, 64)


def write_bag(path, frames: int, store=StoragePlugin.MCAP):
    ts = get_typestore(Stores.ROS2_JAZZY)
    T = ts.types
    cameras = two_cameras()
    with Writer(path, version=9, storage_plugin=store) as writer:
        tf_conn = writer.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=ts)
        edges = []
        for i, (T_world_cam, _, _) in enumerate(cameras):
            p, q = matrix_to_pose(T_world_cam)
            edges.append(T["geometry_msgs/msg/TransformStamped"](
                header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="world"),
                child_frame_id=f"cam{i}_optical_frame",
                transform=T["geometry_msgs/msg/Transform"](
                    translation=T["geometry_msgs/msg/Vector3"](x=p[0], y=p[1], z=p[2]),
                    rotation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]))))
        writer.write(tf_conn, 1, ts.serialize_cdr(T["tf2_msgs/msg/TFMessage"](transforms=edges), "tf2_msgs/msg/TFMessage"))
        conns = [writer.add_connection(f"/cam{i}/points", "sensor_msgs/msg/PointCloud2", typestore=ts) for i in range(2)]
        for frame in range(frames):
            for i, (conn, (_, xyz, rgb)) in enumerate(zip(conns, cameras)):
                cloud = encode(xyz, rgb)
                stamp_ns = 1_000_000_000 + frame * 100_000_000 + i * 3_000_000  # cameras 3 ms apart
                msg = T["sensor_msgs/msg/PointCloud2"](
                    header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9),
                                                    frame_id=f"cam{i}_optical_frame"),
                    height=cloud.height, width=cloud.width,
                    fields=[T["sensor_msgs/msg/PointField"](name=f.name, offset=f.offset, datatype=f.datatype, count=f.count) for f in cloud.fields],
                    is_bigendian=False, point_step=cloud.point_step, row_step=cloud.row_step,
                    data=np.frombuffer(cloud.data, np.uint8), is_dense=False)
                writer.write(conn, stamp_ns, ts.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2"))


@pytest.mark.parametrize("store", [StoragePlugin.MCAP, StoragePlugin.SQLITE3])
def test_bag_to_png_frames(tmp_path, store):
    write_bag(tmp_path / "bag", frames=3, store=store)
    out = tmp_path / "out"
    assert actaim2(["render", str(tmp_path / "bag"), "--out", str(out), "--resolution", "64"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [f"frame_000{i}_{k}.png" for i in range(3) for k in ("depth", "rgb")]
    front = np.asarray(Image.open(out / "frame_0000_rgb.png"))[:, 64:128]
    assert front.any(axis=2).sum() > 50  # the box is seen from the front view
    assert actaim2(["render", str(tmp_path / "bag"), "--out", str(out), "--topics", "/nope"]) == 1
