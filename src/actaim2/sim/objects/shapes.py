"""The shapes links are made of (boxes, cylinders, convex mesh pieces) and their geometry:
triangle meshes in the link frame and convex hulls, shared by the URDF writer (:mod:`.model`) and
the mass properties (:mod:`.mass`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

Vec3 = tuple[float, float, float]
RGBA = tuple[float, float, float, float]


@dataclass(frozen=True)
class Shape:
    """A box (``size`` = full extents), a cylinder (``size`` = (radius, length, 0), axis z) or a
    convex ``mesh`` (the hull of ``points``, in the shape frame; ``size`` unused).

    ``material`` names a :data:`.physics_table.MATERIALS` entry ("" = the link's material).
    """

    kind: str
    size: Vec3
    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)
    rgba: RGBA = (0.7, 0.7, 0.7, 1.0)
    material: str = ""
    points: tuple = ()


def rpy_matrix(rpy: Vec3) -> np.ndarray:
    """The rotation of a URDF ``rpy`` (roll, pitch, yaw about the fixed x, y, z axes)."""
    return Rotation.from_euler("xyz", rpy).as_matrix()


def shape_mesh(s: Shape, segments: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (in the link frame, the shape's origin applied) and triangles of a shape."""
    if s.kind == "box":
        h = np.asarray(s.size) / 2
        v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float) * h
        f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    elif s.kind == "mesh":
        v = np.asarray(s.points, dtype=float)
        f = convex_faces(v)
    elif s.kind == "cylinder":
        r, length = s.size[0], s.size[1]
        a = np.linspace(0, 2 * np.pi, segments, endpoint=False)
        ring = np.stack([r * np.cos(a), r * np.sin(a)], axis=1)
        v = np.concatenate([np.c_[ring, np.full(segments, -length / 2)], np.c_[ring, np.full(segments, length / 2)],
                            [[0, 0, -length / 2], [0, 0, length / 2]]])
        f = []
        for i in range(segments):
            k = (i + 1) % segments
            f += [[i, k, segments + k], [i, segments + k, segments + i],
                  [2 * segments, k, i], [2 * segments + 1, segments + i, segments + k]]
        f = np.array(f)
    else:
        raise ValueError(f"unknown shape kind {s.kind!r}")
    return v @ rpy_matrix(s.rpy).T + np.asarray(s.xyz), f


def convex_faces(points: np.ndarray) -> np.ndarray:
    """Outward-facing triangles of the convex hull of ``points`` (indices into ``points``)."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(points)
    faces = hull.simplices.copy()
    centre = points[hull.vertices].mean(axis=0)
    for k, f in enumerate(faces):
        normal = np.cross(points[f[1]] - points[f[0]], points[f[2]] - points[f[0]])
        if normal @ (points[f[0]] - centre) < 0:
            faces[k] = f[[0, 2, 1]]
    return faces
