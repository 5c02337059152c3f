"""What fusion_node publishes for a recorded bag, computed in-process: the reference a replay must match.

Every synchronised set of clouds in the bag goes through the node's own steps, in its order:
:meth:`Perception.fuse` (the unfiltered /fused_points), the robot posed at each distinct cloud
stamp of the set by a :class:`JointStateHistory` of the bag's /joint_states (interpolated
between the messages that bracket the stamp, as the node does once the next JointState has
arrived), :meth:`Perception.without_robot`, :meth:`Perception.render` (the /ortho_views, robot
hidden when the configuration says so). Extrinsics come from the bag's /tf_static. A set the
node would drop (no point in the cube, joints unknown at its stamp, an unknown frame) is
skipped here too. Bags are read with ``rosbags``: no ROS install is needed.

Uses: the golden outputs of the committed sim bags (tests/bags/golden.py), and any tool that
needs a bag's observations exactly as served (bag-to-dataset conversion).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from actaim2.geometry import pose_to_matrix
from actaim2.perception.cloud_codec import CloudFormatError, Field, decode
from actaim2.perception.config import PerceptionConfig
from actaim2.perception.fusion import CameraCloud, FusedCloud
from actaim2.perception.joint_history import JointStateHistory, JointStateUnavailable
from actaim2.perception.pipeline import EmptyObservationError, Perception
from actaim2.perception.self_filter import RobotSelfFilter
from actaim2.perception.static_tf import StaticTransformBuffer, UnknownFrameError
from actaim2.perception.time_sync import ApproximateTimeSync
from actaim2.robots import RobotSpec
from actaim2.stamps import header_stamp_ns


@dataclass(frozen=True)
class BagFrame:
    stamp_ns: int  # the newest cloud stamp of the set: the header stamp of both outputs
    fused: FusedCloud  # /fused_points as published unfiltered (world, cube, voxel grid)
    views: np.ndarray  # /ortho_views data: (views, channels, R, R) float32


def bag_frames(bag: Path, config: PerceptionConfig, robot: RobotSpec | None, topics: tuple[str, ...] = ("/points2",),
               slop: float = 0.05, world: str = "world", max_extrapolation: float = 0.025) -> Iterator[BagFrame]:
    """The frames fusion_node (``cloud_topics`` = ``topics``, ``sync_slop`` = ``slop``,
    ``perception_config`` = ``config``, ``robot``) publishes when ``bag`` is played into it."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    needs_robot = config.remove_robot_views
    if needs_robot and robot is None:
        raise ValueError("robot-hidden views need the robot whose joint states the bag holds")
    perception = Perception(config, RobotSelfFilter(robot, config.self_filter_margin) if needs_robot else None)
    tf = StaticTransformBuffer()
    joints = JointStateHistory(history=1e9, max_extrapolation=max_extrapolation)  # the whole bag is known at once
    with AnyReader([Path(bag)], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        found = {c.topic for c in reader.connections}
        if missing := [t for t in topics if t not in found]:
            raise ValueError(f"{bag}: no {missing} (topics: {sorted(found)})")
        context = [c for c in reader.connections if c.topic in ("/tf_static", "/joint_states")]
        for connection, _, raw in reader.messages(connections=context):
            msg = reader.deserialize(raw, connection.msgtype)
            if connection.topic == "/tf_static":
                for t in msg.transforms:
                    r, p = t.transform.rotation, t.transform.translation
                    tf.set_transform(t.header.frame_id, t.child_frame_id, pose_to_matrix([p.x, p.y, p.z], [r.x, r.y, r.z, r.w]))
            else:
                joints.add(header_stamp_ns(msg.header), list(msg.name), list(msg.position))
        sync = ApproximateTimeSync(len(topics), int(slop * 1e9))
        clouds = [c for c in reader.connections if c.topic in topics]
        for connection, _, raw in reader.messages(connections=clouds):
            msg = reader.deserialize(raw, connection.msgtype)
            group = sync.add(topics.index(connection.topic), header_stamp_ns(msg.header), msg)
            if group is None:
                continue
            try:
                frame = _frame(perception, tf, joints, group, world)
            except (CloudFormatError, UnknownFrameError, EmptyObservationError, JointStateUnavailable):
                continue  # the node reports these and publishes nothing for the set
            yield frame


def _frame(perception: Perception, tf: StaticTransformBuffer, joints: JointStateHistory, group: list, world: str) -> BagFrame:
    clouds = []
    for msg in group:
        fields = [Field(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
        decoded = decode(fields, msg.data, msg.height, msg.width, msg.point_step, msg.row_step, msg.is_bigendian)
        clouds.append(CameraCloud(decoded.xyz, decoded.rgb, tf.lookup(world, msg.header.frame_id)))
    fused = perception.fuse(clouds)
    stamps = sorted({header_stamp_ns(m.header) for m in group})
    shown = fused
    if perception.self_filter is not None:
        perception.self_filter.set_configurations([joints.at(s) for s in stamps])
        shown = perception.without_robot(fused) if perception.config.remove_robot_views else fused
    return BagFrame(stamps[-1], fused, perception.render(shown))
