"""numpy <-> sensor_msgs/PointCloud2 in the layout of DESIGN.md (used by perception and sim).

API:
    to_msg(xyz, rgb=None, frame_id="", stamp=None) -> PointCloud2
        xyz (H, W, 3) float -> organized HxW cloud; (N, 3) -> unorganized (height 1).
        rgb uint8 with the same leading shape, or None for xyz-only (point_step 16).
        NaN xyz marks "no return"; is_dense is always False. stamp: builtin_interfaces/Time.
    from_msg(msg) -> actaim2.perception.cloud_codec.DecodedCloud
        xyz (H*W, 3) float32 in msg.header.frame_id, rgb (H*W, 3) uint8 or None.
        Accepts any point_step/padding/colour layout; raises CloudFormatError when unreadable.

The byte layout itself lives in the ROS-free ``actaim2.perception.cloud_codec``.
"""
from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Time
from sensor_msgs.msg import PointCloud2, PointField

from actaim2.perception.cloud_codec import DecodedCloud, Field, decode, encode


def to_msg(xyz: np.ndarray, rgb: np.ndarray | None = None, frame_id: str = "", stamp: Time | None = None) -> PointCloud2:
    encoded = encode(xyz, rgb)
    msg = PointCloud2()
    msg.header.frame_id = frame_id
    if stamp is not None:
        msg.header.stamp = stamp
    msg.height = encoded.height
    msg.width = encoded.width
    msg.fields = [PointField(name=f.name, offset=f.offset, datatype=f.datatype, count=f.count) for f in encoded.fields]
    msg.is_bigendian = False
    msg.point_step = encoded.point_step
    msg.row_step = encoded.row_step
    msg.data = encoded.data
    msg.is_dense = False
    return msg


def from_msg(msg: PointCloud2) -> DecodedCloud:
    fields = [Field(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
    return decode(fields, msg.data, msg.height, msg.width, msg.point_step, msg.row_step, msg.is_bigendian)
