"""4x4 matrices <-> geometry_msgs/TransformStamped, and /tf_static publishing and listening.

API:
    TF_STATIC_QOS                          reliable + transient local (late joiners get extrinsics)
    matrix_to_transform(T, parent, child, stamp=None) -> TransformStamped   (T = T_parent_child)
    transform_to_matrix(msg) -> 4x4        msg: TransformStamped or Transform
    StaticTransformPublisher(node)         .send(list[TransformStamped]): like tf2_ros'
                                           StaticTransformBroadcaster, re-publishes every edge it
                                           ever sent (keyed by child frame) in one TFMessage.
    listen_tf_static(node, buffer, on_update=None) -> Subscription
                                           fills an actaim2.perception.static_tf.StaticTransformBuffer

tf2_ros is not installable here; this is the subset the project needs, with tf2's semantics.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Transform, TransformStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription
from tf2_msgs.msg import TFMessage

from actaim2.geometry import matrix_to_pose, pose_to_matrix
from actaim2.perception.static_tf import StaticTransformBuffer

# Publishers send one message holding all their edges (depth 1); listeners keep many so that
# every publisher's latched message reaches a late joiner (tf2_ros uses 1 and 100 likewise).
TF_STATIC_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
TF_STATIC_LISTENER_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)


def matrix_to_transform(T_parent_child: np.ndarray, parent: str, child: str, stamp: Time | None = None) -> TransformStamped:
    position, quat = matrix_to_pose(T_parent_child)
    msg = TransformStamped()
    msg.header.frame_id = parent
    if stamp is not None:
        msg.header.stamp = stamp
    msg.child_frame_id = child
    msg.transform.translation.x, msg.transform.translation.y, msg.transform.translation.z = map(float, position)
    r = msg.transform.rotation
    r.x, r.y, r.z, r.w = map(float, quat)
    return msg


def transform_to_matrix(msg: TransformStamped | Transform) -> np.ndarray:
    t = msg.transform if isinstance(msg, TransformStamped) else msg
    return pose_to_matrix(
        [t.translation.x, t.translation.y, t.translation.z], [t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w]
    )


class StaticTransformPublisher:
    """Latched /tf_static publisher that keeps and re-sends all of its edges."""

    def __init__(self, node: Node, topic: str = "/tf_static") -> None:
        self._publisher = node.create_publisher(TFMessage, topic, TF_STATIC_QOS)
        self._edges: dict[str, TransformStamped] = {}

    def send(self, transforms: list[TransformStamped]) -> None:
        for t in transforms:
            self._edges[t.child_frame_id] = t
        self._publisher.publish(TFMessage(transforms=list(self._edges.values())))


def listen_tf_static(
    node: Node,
    buffer: StaticTransformBuffer,
    on_update: Callable[[], None] | None = None,
    topic: str = "/tf_static",
) -> Subscription:
    """Subscribe to /tf_static and store every edge in ``buffer``.

    Edges with a zero-norm quaternion or non-finite values are skipped with a warning, so one bad
    publisher cannot poison the extrinsics of every camera.
    """

    def callback(msg: TFMessage) -> None:
        for t in msg.transforms:
            q = t.transform.rotation
            if not np.isfinite([q.x, q.y, q.z, q.w]).all() or np.linalg.norm([q.x, q.y, q.z, q.w]) < 1e-6:
                node.get_logger().warning(
                    f"ignoring /tf_static edge {t.header.frame_id} -> {t.child_frame_id}: invalid quaternion",
                    throttle_duration_sec=10.0,
                )
                continue
            try:
                buffer.set_transform(t.header.frame_id, t.child_frame_id, transform_to_matrix(t))
            except ValueError as exc:
                node.get_logger().warning(f"ignoring /tf_static edge: {exc}", throttle_duration_sec=10.0)
        if on_update is not None:
            on_update()

    return node.create_subscription(TFMessage, topic, callback, TF_STATIC_LISTENER_QOS)
