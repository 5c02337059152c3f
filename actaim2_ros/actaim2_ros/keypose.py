"""actaim2_msgs/Keypose <-> :class:`actaim2.keypose.Keypose`, the one conversion every node uses
(policy_node, control_node, the episode runner, viz_node)."""
from __future__ import annotations

import numpy as np
from actaim2_msgs.msg import Keypose as KeyposeMsg
from builtin_interfaces.msg import Time

from actaim2.keypose import Keypose


def keypose_data(msg: KeyposeMsg) -> Keypose:
    """A Keypose message (frame ``world``) as the library's keypose."""
    p, q = msg.pose.position, msg.pose.orientation
    return Keypose(int(msg.phase), np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w]), bool(msg.gripper_closed))


def keypose_msg(keypose: Keypose, stamp: Time) -> KeyposeMsg:
    """The library's keypose as a Keypose message in frame ``world`` stamped ``stamp`` (builtin_interfaces/Time)."""
    msg = KeyposeMsg(gripper_closed=bool(keypose.gripper_closed), phase=int(keypose.phase))
    msg.header.frame_id = "world"
    msg.header.stamp = stamp
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in keypose.position)
    q = msg.pose.orientation
    q.x, q.y, q.z, q.w = (float(v) for v in keypose.quat_xyzw)
    return msg
