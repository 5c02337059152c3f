"""Geometric checks of the open hand against a cloud, in the canonical `tcp` frame.

Samplers see the object only as points, so "would this pose collide" and "is something between
the fingers" are questions about which points fall into which box. The boxes are the robot
preset's :class:`actaim2.robots.HandGeometry`; the frame is DESIGN.md's `tcp`: origin between
the fingertips, z = approach, y = finger closing direction.
"""
from __future__ import annotations

import numpy as np

from actaim2.robots import HandGeometry


def points_in_tcp(points: np.ndarray, T_world_tcp: np.ndarray) -> np.ndarray:
    """(N, 3) world points expressed in the tcp frame."""
    R, t = T_world_tcp[:3, :3], T_world_tcp[:3, 3]
    return (np.asarray(points, dtype=float) - t) @ R


def count_inside(local: np.ndarray, box: tuple[np.ndarray, np.ndarray]) -> int:
    lo, hi = box
    return int(np.sum(np.all((local >= lo) & (local <= hi), axis=1)))


def collides(gripper: HandGeometry, points: np.ndarray, T_world_tcp: np.ndarray, tolerance: int = 3) -> bool:
    """True when more than ``tolerance`` cloud points fall inside the open hand's fingers or palm.

    The tolerance absorbs single stray points (depth noise, voxel averaging at edges).
    """
    local = points_in_tcp(points, T_world_tcp)
    half = gripper.hand_extent()
    near = local[(np.abs(local[:, 0]) <= half[0]) & (np.abs(local[:, 1]) <= half[1]) & (local[:, 2] >= -half[2]) & (local[:, 2] <= 0.0)]
    if len(near) <= tolerance:
        return False
    return sum(count_inside(near, box) for box in gripper.boxes().values()) > tolerance


def points_near(points: np.ndarray, segment_start: np.ndarray, segment_end: np.ndarray, radius: float) -> np.ndarray:
    """The points within ``radius`` of a line segment (the volume a moving hand can touch)."""
    a, b = np.asarray(segment_start, float), np.asarray(segment_end, float)
    ab = b - a
    t = np.clip((points - a) @ ab / max(ab @ ab, 1e-12), 0.0, 1.0)
    return points[np.linalg.norm(points - (a + t[:, None] * ab), axis=1) <= radius]


def tcp_pose(position: np.ndarray, approach: np.ndarray, closing: np.ndarray) -> np.ndarray:
    """4x4 tcp pose from a position, an approach (z) and a closing (y) direction (y made orthogonal)."""
    z = np.asarray(approach, dtype=float)
    z = z / np.linalg.norm(z)
    y = np.asarray(closing, dtype=float)
    y = y - z * (y @ z)
    y = y / np.linalg.norm(y)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = np.cross(y, z), y, z, position
    return T
