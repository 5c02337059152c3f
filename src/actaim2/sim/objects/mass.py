"""Mass, centre of mass and inertia of a link from its shapes and their materials' densities.

Written into each generated link's URDF ``<inertial>`` (SAPIEN uses it as given), so a part
weighs what its volume of wood, steel or glass weighs (:mod:`.physics_table`) instead of one
density for everything. Boxes and cylinders use their closed forms; convex mesh pieces
(handles) are split into tetrahedra from their centroid.
"""
from __future__ import annotations

import numpy as np

from .shapes import Shape, convex_faces, rpy_matrix


def shape_mass_properties(shape: Shape, density: float) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, centre of mass, 3x3 inertia about the centre of mass), in the link frame."""
    R = rpy_matrix(shape.rpy)
    centre = np.asarray(shape.xyz, dtype=float)
    if shape.kind == "box":
        a, b, c = shape.size
        m = density * a * b * c
        local = m / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    elif shape.kind == "cylinder":
        r, h = shape.size[0], shape.size[1]
        m = density * np.pi * r * r * h
        side = m * (3 * r * r + h * h) / 12.0
        local = np.diag([side, side, m * r * r / 2.0])
    elif shape.kind == "mesh":
        m, com, inertia = _convex_mass_properties(np.asarray(shape.points, dtype=float), density)
        local = inertia
        centre = centre + R @ com
    else:
        raise ValueError(f"unknown shape kind {shape.kind!r}")
    return float(m), centre, R @ local @ R.T


def link_mass_properties(shapes: list[Shape], densities: list[float]) -> tuple[float, np.ndarray, np.ndarray]:
    """Total mass, centre of mass and inertia (about it) of shapes with their densities."""
    parts = [shape_mass_properties(s, d) for s, d in zip(shapes, densities)]
    mass = sum(p[0] for p in parts)
    if mass <= 0.0:
        raise ValueError("a link without volume has no mass")
    com = sum(p[0] * p[1] for p in parts) / mass
    inertia = np.zeros((3, 3))
    for m, c, part_inertia in parts:
        d = c - com
        inertia += part_inertia + m * (d @ d * np.eye(3) - np.outer(d, d))  # parallel axis theorem
    return mass, com, inertia


def _convex_mass_properties(points: np.ndarray, density: float) -> tuple[float, np.ndarray, np.ndarray]:
    """Solid convex hull of ``points``: tetrahedra from the centroid to each hull triangle."""
    faces = convex_faces(points)
    o = points.mean(axis=0)
    mass = 0.0
    first = np.zeros(3)
    second = np.zeros((3, 3))
    # canonical second moment of the unit tetrahedron (0, e1, e2, e3): integral of x x^T
    canonical = (np.ones((3, 3)) + np.eye(3)) / 120.0
    for f in faces:
        A = np.stack([points[f[0]] - o, points[f[1]] - o, points[f[2]] - o], axis=1)
        det = np.linalg.det(A)
        vol = abs(det) / 6.0
        mass += density * vol
        first += density * vol * A.sum(axis=1) / 4.0
        second += density * abs(det) * A @ canonical @ A.T
    com_rel = first / mass
    # inertia about o from the second moment, then moved to the centre of mass
    inertia_o = np.trace(second) * np.eye(3) - second
    inertia = inertia_o - mass * (com_rel @ com_rel * np.eye(3) - np.outer(com_rel, com_rel))
    return mass, o + com_rel, inertia
