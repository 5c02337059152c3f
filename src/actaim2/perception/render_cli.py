"""`actaim2 render`: a rosbag2 (sqlite3 or MCAP) or a saved cloud -> orthographic views as PNG.

For people: what does the policy see in this recording? Every synchronised set of clouds in the
bag goes through the same :class:`~actaim2.perception.pipeline.Perception` as the node, with
extrinsics from the bag's /tf_static (or --calibration) and, with --remove-robot, the robot
removed at the bag's /joint_states. Bags are read with `rosbags`, so no ROS install is needed.

Output per frame: ``<stem>_rgb.png`` (the five views' colours side by side, in VIEWS order)
and ``<stem>_depth.png`` (near = bright, empty = black).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from actaim2.perception.ortho_views import VIEWS
from actaim2.stamps import header_stamp_ns

CLOUD_SUFFIXES = (".npz", ".ply", ".pcd")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", type=Path, help="rosbag2 folder, .mcap/.db3 file, or a cloud (.npz with xyz[, rgb, T_world_cloud]; .ply/.pcd in world)")
    parser.add_argument("--out", type=Path, default=Path("views"), help="output folder (created)")
    parser.add_argument("--topics", nargs="+", help="PointCloud2 topics to fuse (default: every cloud topic but /fused_points)")
    parser.add_argument("--perception", default="azure_kinect",
                        help="perception configuration: a rig name (ring5, azure_kinect) or a YAML (actaim2.perception.config)")
    parser.add_argument("--resolution", type=int, help="pixels per view side (default: the configuration's)")
    parser.add_argument("--slop", type=float, default=0.05, help="s: clouds this close in time are fused together")
    parser.add_argument("--calibration", type=Path, help="extrinsics YAML instead of the bag's /tf_static")
    parser.add_argument("--remove-robot", metavar="ROBOT", help="remove this robot (preset or YAML) at the bag's /joint_states")
    parser.add_argument("--every", type=int, default=1, help="render every N-th synchronised set")
    parser.add_argument("--max-frames", type=int, default=0, help="stop after this many frames (0 = all)")


def _save(views: np.ndarray, channels: tuple[str, ...], out: Path, stem: str) -> None:
    from PIL import Image

    from actaim2.perception.ortho_views import depth_mosaic, rgb_mosaic

    Image.fromarray(rgb_mosaic(views, channels)).save(out / f"{stem}_rgb.png")
    Image.fromarray(depth_mosaic(views, channels)).save(out / f"{stem}_depth.png")


def _load_cloud_file(path: Path):
    from actaim2.perception.fusion import CameraCloud

    if path.suffix == ".npz":
        data = np.load(path)
        xyz = np.asarray(data["xyz"], dtype=np.float32).reshape(-1, 3)
        rgb = np.asarray(data["rgb"], dtype=np.uint8).reshape(-1, 3) if "rgb" in data else None
        T = np.asarray(data["T_world_cloud"], dtype=float) if "T_world_cloud" in data else np.eye(4)
        return CameraCloud(xyz, rgb, T)
    import open3d as o3d

    cloud = o3d.io.read_point_cloud(str(path))
    if cloud.is_empty():
        raise ValueError(f"{path}: no points could be read")
    rgb = (np.asarray(cloud.colors) * 255).round().astype(np.uint8) if cloud.has_colors() else None
    return CameraCloud(np.asarray(cloud.points, dtype=np.float32), rgb, np.eye(4))


def _bag_frames(args: argparse.Namespace, perception):
    """Yield the views of every synchronised, renderable set of clouds in the bag (every N-th)."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    from actaim2.geometry import pose_to_matrix
    from actaim2.perception.calibration import load_calibration
    from actaim2.perception.cloud_codec import CloudFormatError, Field, decode
    from actaim2.perception.fusion import CameraCloud
    from actaim2.perception.pipeline import EmptyObservationError
    from actaim2.perception.static_tf import StaticTransformBuffer, UnknownFrameError
    from actaim2.perception.time_sync import ApproximateTimeSync

    tf = StaticTransformBuffer()
    if args.calibration:
        parent, transforms = load_calibration(args.calibration)
        for child, T in transforms.items():
            tf.set_transform(parent, child, T)
    with AnyReader([args.input], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        cloud_topics = sorted({c.topic for c in reader.connections if c.msgtype == "sensor_msgs/msg/PointCloud2"} - {"/fused_points"})
        topics = args.topics or cloud_topics
        missing = sorted(set(topics) - set(cloud_topics))
        if missing or not topics:
            raise ValueError(f"no PointCloud2 topic {missing or ''} in {args.input} (cloud topics: {cloud_topics})")
        wanted = set(topics) | {"/joint_states"} | (set() if args.calibration else {"/tf_static"})
        sync = ApproximateTimeSync(len(topics), int(args.slop * 1e9))
        sets = 0
        for connection, _, raw in reader.messages(connections=[c for c in reader.connections if c.topic in wanted]):
            msg = reader.deserialize(raw, connection.msgtype)
            if connection.topic == "/tf_static":
                for t in msg.transforms:
                    r, p = t.transform.rotation, t.transform.translation
                    tf.set_transform(t.header.frame_id, t.child_frame_id, pose_to_matrix([p.x, p.y, p.z], [r.x, r.y, r.z, r.w]))
                continue
            if connection.topic == "/joint_states":
                if perception.self_filter is not None:
                    perception.self_filter.set_joint_positions(list(msg.name), list(msg.position))
                continue
            stamp = header_stamp_ns(msg.header)
            group = sync.add(topics.index(connection.topic), stamp, msg)
            if group is None:
                continue
            sets += 1
            if (sets - 1) % args.every:
                continue
            try:
                clouds = []
                for cloud_msg in group:
                    fields = [Field(f.name, f.offset, f.datatype, f.count) for f in cloud_msg.fields]
                    decoded = decode(fields, cloud_msg.data, cloud_msg.height, cloud_msg.width, cloud_msg.point_step,
                                     cloud_msg.row_step, cloud_msg.is_bigendian)
                    clouds.append(CameraCloud(decoded.xyz, decoded.rgb, tf.lookup("world", cloud_msg.header.frame_id)))
                views = perception.process(clouds).views
            except (CloudFormatError, UnknownFrameError, EmptyObservationError) as exc:
                print(f"skipping the set at {stamp / 1e9:.3f} s: {exc}")
                continue
            yield views


def main(args: argparse.Namespace) -> int:
    from actaim2.perception.config import load_perception_config
    from actaim2.perception.pipeline import EmptyObservationError, Perception
    from actaim2.perception.self_filter import RobotSelfFilter
    from actaim2.robots import load_robot_spec

    try:
        config = load_perception_config(args.perception)
        config = config.replace(remove_robot_views=bool(args.remove_robot), resolution=args.resolution or config.resolution)
    except (FileNotFoundError, ValueError) as exc:
        print(f"actaim2 render: {exc}")
        return 2
    self_filter = RobotSelfFilter(load_robot_spec(args.remove_robot), config.self_filter_margin) if args.remove_robot else None
    perception = Perception(config, self_filter)
    args.out.mkdir(parents=True, exist_ok=True)
    if not args.input.exists():
        print(f"actaim2 render: {args.input} does not exist")
        return 2
    try:
        if args.input.suffix in CLOUD_SUFFIXES:
            if self_filter is not None:
                print("actaim2 render: --remove-robot needs joint states, which only a bag has")
                return 2
            _save(perception.process([_load_cloud_file(args.input)]).views, config.channels, args.out, args.input.stem)
            print(f"wrote {args.out / args.input.stem}_rgb.png and _depth.png ({', '.join(VIEWS)})")
            return 0
        frames = 0
        for frames, views in enumerate(_bag_frames(args, perception), start=1):
            _save(views, config.channels, args.out, f"frame_{frames - 1:04d}")
            if frames == args.max_frames:
                break
    except (ValueError, KeyError, EmptyObservationError) as exc:
        print(f"actaim2 render: {exc}")
        return 1
    print(f"wrote {frames} frame(s) to {args.out} (views left to right: {', '.join(VIEWS)})")
    return 0 if frames else 1
