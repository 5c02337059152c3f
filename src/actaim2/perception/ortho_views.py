"""Orthographic re-rendering of a fused world cloud into RVT's five virtual views.

This module is the single definition of what the policy sees, used unchanged by training-data
preprocessing, the perception node and ``actaim2 render``: the view list, the channel list,
the empty-pixel marker, and the pixel <-> world mapping the action predictor needs to turn a
heatmap peak back into a 3-D point.

Geometry: the rendered volume is the cube ``center +- half_extent`` (world frame). Each view is
an orthographic camera sitting on one face of the cube and looking through it; pixel (u, v)
(column, row; v grows downwards) covers a square of side ``2 * half_extent / resolution``.
``depth`` is the distance in metres from that face into the cube (0 .. 2 * half_extent); the
point with the smallest depth wins each pixel (z-buffer). World axes follow REP-103 with the
robot base at the origin: x forward (away from the robot), y left, z up.

Channels: r, g, b in 0..1; x, y, z world coordinates in metres; depth in metres; occupancy 1 for
a pixel that received a point. An empty pixel holds :data:`EMPTY_VALUE` (0) in every channel,
occupancy included, so occupancy alone tells "empty" from a real zero. RVT's pixel-coordinate
channels are constant images, so the model appends them itself (as RVT's MVT does); they are
not rendered here.
"""
from __future__ import annotations

import numpy as np
import torch

VIEWS: tuple[str, ...] = ("top", "front", "back", "left", "right")
CHANNELS: tuple[str, ...] = ("r", "g", "b", "x", "y", "z", "depth", "occupancy")
EMPTY_VALUE = 0.0
DEFAULT_RESOLUTION = 128
DEPTH_STEP = 1e-5  # m: depth is z-buffered and reported in steps of 10 um

# Per view, rows: image right (+u), image down (+v), viewing direction (into the cube), all in
# world coordinates. right x down = direction, like an optical frame (x right, y down, z forward).
VIEW_AXES = np.array(
    [
        [[0, -1, 0], [-1, 0, 0], [0, 0, -1]],  # top: from above, +x (away from the robot) up in the image
        [[0, 1, 0], [0, 0, -1], [-1, 0, 0]],  # front: from +x, facing the robot
        [[0, -1, 0], [0, 0, -1], [1, 0, 0]],  # back: from behind the robot, looking along +x
        [[-1, 0, 0], [0, 0, -1], [0, -1, 0]],  # left: from +y
        [[1, 0, 0], [0, 0, -1], [0, 1, 0]],  # right: from -y
    ],
    dtype=np.float32,
)


def project(points: np.ndarray, center, half_extent: float, resolution: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Continuous pixel coordinates (u, v) and depth of world points in every view: each (V, N).

    Integer parts are the pixel indices; points outside the cube fall outside [0, resolution).
    """
    rel = np.asarray(points, dtype=np.float64).reshape(-1, 3) - np.asarray(center, dtype=np.float64)
    local = np.einsum("vjk,nk->vnj", VIEW_AXES.astype(np.float64), rel)
    scale = resolution / (2.0 * half_extent)
    return (local[..., 0] + half_extent) * scale, (local[..., 1] + half_extent) * scale, local[..., 2] + half_extent


def unproject(view: int, u: float, v: float, depth: float, center, half_extent: float, resolution: int) -> np.ndarray:
    """World point at continuous pixel (u, v) and depth of ``view`` (the inverse of :func:`project`)."""
    scale = (2.0 * half_extent) / resolution
    local = np.array([u * scale - half_extent, v * scale - half_extent, depth - half_extent])
    return np.asarray(center, dtype=np.float64) + VIEW_AXES[view].astype(np.float64).T @ local


def render_views(
    xyz: np.ndarray,
    rgb: np.ndarray,
    center,
    half_extent: float,
    resolution: int = DEFAULT_RESOLUTION,
) -> np.ndarray:
    """Z-buffered orthographic views of world points: float32 (len(VIEWS), len(CHANNELS), R, R).

    ``xyz`` (N, 3) world metres, ``rgb`` (N, 3) uint8. Points outside the cube or non-finite are
    ignored. Ties in depth go to the point with the lowest index, so the result is deterministic.
    """
    n_views, pixels = len(VIEWS), resolution * resolution
    # Points as one row per axis (3, N): products and tests over contiguous rows run 3-6x faster
    # here than over (N, 3) points.
    points = torch.from_numpy(np.ascontiguousarray(xyz, dtype=np.float32)).reshape(-1, 3).T.contiguous()
    colours = torch.from_numpy(np.ascontiguousarray(rgb, dtype=np.uint8)).reshape(-1, 3)
    centre = torch.tensor(center, dtype=torch.float32)
    inside = (points - centre[:, None]).abs_().amax(dim=0) <= half_extent  # NaN compares False
    if not bool(inside.all()):
        kept = torch.from_numpy(np.flatnonzero(inside.numpy()))  # numpy's SIMD nonzero: 8x torch.nonzero here
        points, colours = points.index_select(1, kept), colours.index_select(0, kept)
    n = points.shape[1]
    # One affine map gives, per view, the column and row in pixels and the depth in DEPTH_STEPs,
    # all measured from the cube corner: (V, 3, N), each row contiguous. Values are >= 0, so
    # trunc = floor; pixel indices stay exact in float32 (< 2^24) until the final conversion.
    axes = torch.from_numpy(VIEW_AXES.reshape(-1, 3))
    scale = torch.tensor([resolution / (2 * half_extent), resolution / (2 * half_extent), 1.0 / DEPTH_STEP]).repeat(n_views)
    offset = (half_extent - axes @ centre) * scale
    grid = torch.addmm(offset[:, None], axes * scale[:, None], points).trunc_().reshape(n_views, 3, n)
    pixel = grid[:, :2].clamp_(max=resolution - 1)
    flat = torch.addcmul(pixel[:, 0], pixel[:, 1], torch.tensor(float(resolution)))
    flat += (torch.arange(n_views, dtype=torch.float32) * pixels)[:, None]

    # One integer z-buffer pass: key = depth << 32 | point index, so the minimum per pixel is the
    # nearest point, ties going to the lowest index (deterministic), and the depth is read back
    # from the key without another gather.
    empty = torch.iinfo(torch.int64).max
    key = grid[:, 2].long().bitwise_left_shift_(32).bitwise_or_(torch.arange(n))
    best = torch.full((n_views * pixels,), empty, dtype=torch.long).scatter_reduce_(0, flat.long().reshape(-1), key.reshape(-1), "amin")
    hit = best != empty
    winner = torch.where(hit, best & 0xFFFFFFFF, n)  # n = the empty-marker column of the table below

    features = torch.full((6, n + 1), EMPTY_VALUE)  # channels r, g, b, x, y, z per point
    features[:3, :n] = colours.T
    features[:3, :n] /= 255.0
    features[3:, :n] = points
    out = torch.empty((n_views, len(CHANNELS), pixels))
    out[:, :6] = features.index_select(1, winner).reshape(6, n_views, pixels).transpose(0, 1)
    out[:, 6] = torch.where(hit, (best >> 32).float() * DEPTH_STEP, EMPTY_VALUE).reshape(n_views, pixels)
    out[:, 7] = hit.reshape(n_views, pixels)
    return out.reshape(n_views, len(CHANNELS), resolution, resolution).numpy()


def rgb_mosaic(views: np.ndarray, background: int = 0) -> np.ndarray:
    """(R, V*R, 3) uint8 image of the views' colours side by side, empty pixels ``background``."""
    rgb = views[:, :3] * 255.0
    occupied = views[:, CHANNELS.index("occupancy")] > 0
    image = np.where(occupied[:, None], rgb, float(background)).round().clip(0, 255).astype(np.uint8)
    return np.concatenate(list(image.transpose(0, 2, 3, 1)), axis=1)


def depth_mosaic(views: np.ndarray, half_extent: float) -> np.ndarray:
    """(R, V*R) uint8 image of depth, near = bright, empty = black, for people to look at."""
    depth = views[:, CHANNELS.index("depth")]
    occupied = views[:, CHANNELS.index("occupancy")] > 0
    shade = np.where(occupied, 255.0 - depth / (2 * half_extent) * 200.0, 0.0)
    return np.concatenate(list(shade.round().clip(0, 255).astype(np.uint8)), axis=1)
