"""Colour for depth pixels from a separate colour camera, the way an Azure Kinect's /points2 gets it.

The Azure Kinect ROS driver builds its coloured cloud in ``depth_camera_link`` with the Sensor
SDK's ``k4a_transformation_color_image_to_depth_camera``: every depth pixel's 3D point is moved
into the colour camera (factory extrinsics, ~32 mm away), projected, and the colour image is
sampled there bilinearly. The SDK does no occlusion test, so a background point that the colour
camera cannot see - it hides behind a foreground edge, in the registration shadow - takes the
colour of the foreground that hides it. A point that projects outside the colour image gets an
invalid colour (alpha 0), and the driver then drops the whole point (x, y, z NaN, colour 0).

Here the same, with one difference of convention: the SDK's integer pixel coordinates are pixel
centres, :class:`CameraSpec`'s principal point puts pixel centres at u + 0.5.
"""
from __future__ import annotations

import numpy as np

from actaim2.sim.cameras import CameraFrame, CameraSpec


def register_colour(frame: CameraFrame, depth: CameraSpec, colour_frame: CameraFrame) -> CameraFrame:
    """``frame`` (the depth camera's) with the colour of ``colour_frame`` (its colour camera,
    ``depth.colour``) at each point; points outside the colour image are dropped."""
    colour = depth.colour
    if colour is None:
        raise ValueError(f"camera '{depth.name}' has no separate colour camera to register")
    T = np.linalg.inv(depth.T_optical_colour)  # depth optical -> colour optical
    xyz = frame.xyz.reshape(-1, 3).astype(np.float64)
    p = xyz @ T[:3, :3].T + T[:3, 3]
    with np.errstate(invalid="ignore", divide="ignore"):
        u = colour.fx * p[:, 0] / p[:, 2] + colour.cx - 0.5
        v = colour.fy * p[:, 1] / p[:, 2] + colour.cy - 0.5
        u0, v0 = np.floor(u), np.floor(v)
        # the SDK's test: the 2x2 neighbourhood of the bilinear sample lies inside the image
        inside = (p[:, 2] > 0) & (u0 >= 0) & (v0 >= 0) & (u0 + 1 < colour.width) & (v0 + 1 < colour.height)
    rgb = np.zeros((len(xyz), 3), dtype=np.uint8)
    index = np.flatnonzero(inside)
    if index.size:
        iu, iv = u0[index].astype(np.int64), v0[index].astype(np.int64)
        fu, fv = (u - u0)[index, None], (v - v0)[index, None]
        image = colour_frame.rgb.astype(np.float32)
        top = (1 - fu) * image[iv, iu] + fu * image[iv, iu + 1]
        bottom = (1 - fu) * image[iv + 1, iu] + fu * image[iv + 1, iu + 1]
        rgb[index] = ((1 - fv) * top + fv * bottom + 0.5).astype(np.uint8)
    shape = frame.xyz.shape[:2]
    keep = inside.reshape(shape)
    return CameraFrame(
        frame.name,
        np.where(keep[..., None], frame.xyz, np.nan).astype(np.float32),
        rgb.reshape(*shape, 3),
        np.where(keep, frame.segmentation, 0).astype(np.int32),
    )
