"""Rigid-body conventions shared by every sub-package.

Quaternions are (x, y, z, w) everywhere in this library, as in ROS messages and SciPy.
SAPIEN poses and Pinocchio's ``Quaternion(w, x, y, z)`` constructor use (w, x, y, z):
convert only at those boundaries with :func:`xyzw_to_wxyz` (poses are read back from them as matrices).
Transforms are 4x4 homogeneous matrices ``T_a_b`` mapping points in frame b into frame a.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

ArrayLike = np.ndarray


def xyzw_to_wxyz(q: ArrayLike) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    return np.concatenate([q[..., 3:4], q[..., 0:3]], axis=-1)


def pose_to_matrix(position: ArrayLike, quat_xyzw: ArrayLike) -> np.ndarray:
    """4x4 transform from a position and an (x, y, z, w) quaternion (normalised here)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(np.asarray(quat_xyzw, dtype=float)).as_matrix()
    T[:3, 3] = np.asarray(position, dtype=float)
    return T


def matrix_to_pose(T: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(position, quat_xyzw) of a 4x4 transform; the quaternion has w >= 0."""
    T = np.asarray(T, dtype=float)
    q = Rotation.from_matrix(T[:3, :3]).as_quat()
    if q[3] < 0:
        q = -q
    return T[:3, 3].copy(), q


def depth_to_points(depth: ArrayLike, K: ArrayLike) -> np.ndarray:
    """(H, W, 3) float64 points in the optical frame of a z-depth image (metres; 0 or NaN: no return, NaN out).

    Pixel (u, v) covers [u, u+1) x [v, v+1) and is back-projected through its centre (u + 0.5,
    v + 0.5), the convention of SAPIEN's renderer (its principal point for an ideal camera is
    exactly W/2, H/2). The one definition of a depth camera's cloud and pixel rays: the
    simulator's published clouds, its ray caster and the stored pictures the training views are
    made from all go through it, so the ROS loop's views are the training views.
    """
    K = np.asarray(K, dtype=float)
    h, w = np.shape(depth)
    u = (np.arange(w, dtype=np.float64) + 0.5 - K[0, 2]) / K[0, 0]
    v = (np.arange(h, dtype=np.float64) + 0.5 - K[1, 2]) / K[1, 1]
    z = np.where(np.asarray(depth) > 0, depth, np.nan).astype(np.float32)
    return np.stack([u[None, :] * z, v[:, None] * z, z.astype(np.float64)], axis=-1)


def invert(T: ArrayLike) -> np.ndarray:
    """Inverse of a rigid transform without a general matrix inverse."""
    T = np.asarray(T, dtype=float)
    Ti = np.eye(4)
    Ti[:3, :3] = T[:3, :3].T
    Ti[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return Ti


def transform_points(T: ArrayLike, points: ArrayLike) -> np.ndarray:
    """Apply a 4x4 transform to an (N, 3) array (NaNs stay NaN)."""
    T = np.asarray(T, dtype=float)
    points = np.asarray(points)
    return points @ T[:3, :3].T.astype(points.dtype, copy=False) + T[:3, 3].astype(points.dtype, copy=False)


def rotation_angle(R_a: ArrayLike, R_b: ArrayLike) -> float:
    """Geodesic angle (rad) between two rotation matrices."""
    R = np.asarray(R_a, dtype=float).T @ np.asarray(R_b, dtype=float)
    return float(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))


# ROS optical frame (x right, y down, z forward) from SAPIEN's camera-entity frame
# (x forward, y left, z up): columns are the optical axes expressed in the entity frame.
T_ENTITY_OPTICAL = np.array(
    [[0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)
# ROS optical frame from the OpenGL camera frame SAPIEN renders in (x right, y up, z backward).
T_OPENGL_OPTICAL = np.diag([1.0, -1.0, -1.0, 1.0])
