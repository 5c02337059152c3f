"""A parallel gripper as boxes in the canonical `tcp` frame, for geometric checks against a cloud.

Samplers see the object only as points, so "would this pose collide" and "is something between
the fingers" are questions about which points fall into which box. The frame is DESIGN.md's
`tcp`: origin between the fingertips, z = approach, y = finger closing direction. Defaults are
the Franka Hand's dimensions (80 mm opening, ~54 mm fingers, a 0.2 m wide palm body).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class GripperGeometry:
    max_opening: float = 0.08  # m between the finger pads when open
    finger_length: float = 0.054  # along z, back from the fingertips
    finger_thickness: float = 0.02  # along y, each finger
    finger_width: float = 0.02  # along x
    palm_depth: float = 0.06  # along z, behind the fingers
    palm_width: float = 0.21  # along y
    palm_thickness: float = 0.07  # along x

    def boxes(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """name -> (min corner, max corner) in the tcp frame, fingers open."""
        half = self.max_opening / 2.0
        fx, px = self.finger_width / 2.0, self.palm_thickness / 2.0
        z_base = -self.finger_length
        return {
            "finger_left": (np.array([-fx, half, z_base]), np.array([fx, half + self.finger_thickness, 0.0])),
            "finger_right": (np.array([-fx, -half - self.finger_thickness, z_base]), np.array([fx, -half, 0.0])),
            "palm": (np.array([-px, -self.palm_width / 2, z_base - self.palm_depth]), np.array([px, self.palm_width / 2, z_base])),
        }

    def hand_extent(self) -> np.ndarray:
        """Half-widths (x, y) and depth behind the tcp (z) of the box holding the whole open hand."""
        return np.array([self.palm_thickness / 2, self.palm_width / 2, self.finger_length + self.palm_depth])

    def closing_region(self) -> tuple[np.ndarray, np.ndarray]:
        """The space swept by the closing fingers: what lies here gets grasped."""
        half, fx = self.max_opening / 2.0, self.finger_width / 2.0
        return np.array([-fx, -half, -self.finger_length]), np.array([fx, half, 0.0])


def points_in_tcp(points: np.ndarray, T_world_tcp: np.ndarray) -> np.ndarray:
    """(N, 3) world points expressed in the tcp frame."""
    R, t = T_world_tcp[:3, :3], T_world_tcp[:3, 3]
    return (np.asarray(points, dtype=float) - t) @ R


def count_inside(local: np.ndarray, box: tuple[np.ndarray, np.ndarray]) -> int:
    lo, hi = box
    return int(np.sum(np.all((local >= lo) & (local <= hi), axis=1)))


def collides(gripper: GripperGeometry, points: np.ndarray, T_world_tcp: np.ndarray, tolerance: int = 3) -> bool:
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
