"""Robot self-filter: drop points that lie on the robot at its current joint positions.

The mode selector is trained on observations in which the robot is hidden; a real arm cannot be
hidden, so its points are removed here instead, making deployment views look like training
views. Geometry is the URDF's collision model as loaded by Pinocchio (coal shapes), posed with
forward kinematics at the joint positions of the cloud's stamp (``joint_history``). Clouds fused
together may carry different stamps; the robot is then removed as it stood at each of them
(:meth:`RobotSelfFilter.set_configurations`). Each collision shape is replaced by a tight
bounding polytope (support planes in 90 fixed directions; the Panda's collision meshes are
convex, so this is within millimetres of the mesh) and a point is removed when it lies inside
that polytope grown by ``margin``: growing the faces outward removes the sensor noise around the
surface while a nearby object (a handle 2 cm from the fingers) is kept.
"""
from __future__ import annotations

from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin
import torch

from actaim2.profiling import timed
from actaim2.robots import RobotSpec

DEFAULT_MARGIN = 0.01  # m: above depth noise at 1 m, below the 2 cm gap to a handle being grasped

# Round primitives are replaced by polygons with this many sides; the hull then lies inside the
# true surface by at most r * (1 - cos(pi / n)) = 0.5% of the radius.
_ROUND_SEGMENTS = 32


@dataclass(frozen=True)
class _Shape:
    joint: int  # Pinocchio joint the shape is attached to (its placement is relative to it)
    placement: np.ndarray  # 4x4 shape frame in the joint frame
    vertices: np.ndarray  # (V, 3) in the shape frame
    planes: np.ndarray  # (F, 4) outward unit normal n and offset d: inside <=> n.x + d <= 0 (shape frame)


def _circle(radius: float, z: float) -> np.ndarray:
    a = np.linspace(0.0, 2 * np.pi, _ROUND_SEGMENTS, endpoint=False)
    return np.stack([radius * np.cos(a), radius * np.sin(a), np.full_like(a, z)], axis=1)


def _sphere(radius: float, z: float = 0.0) -> np.ndarray:
    return np.concatenate([_circle(radius * np.cos(e), z + radius * np.sin(e)) for e in np.linspace(-np.pi / 2, np.pi / 2, 9)])


def shape_vertices(shape: coal.CollisionGeometry) -> np.ndarray:
    """Points whose convex hull is the shape (round shapes: a close polygonal approximation)."""
    if isinstance(shape, coal.BVHModelBase):
        return np.asarray(shape.vertices(), dtype=float)
    if isinstance(shape, coal.Box):
        h = np.asarray(shape.halfSide, dtype=float)
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float) * h
    if isinstance(shape, coal.Sphere):
        return _sphere(shape.radius)
    if isinstance(shape, coal.Cylinder):
        return np.concatenate([_circle(shape.radius, -shape.halfLength), _circle(shape.radius, shape.halfLength)])
    if isinstance(shape, coal.Capsule):
        return np.concatenate([_sphere(shape.radius, -shape.halfLength), _sphere(shape.radius, shape.halfLength)])
    raise ValueError(f"self-filter: unsupported collision shape {type(shape).__name__}")


def _fibonacci_directions(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (1.0 + 5**0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


# Bounding-polytope directions: the 26 of a box with bevelled edges and corners, plus 64 spread
# evenly. Fewer planes than a finely tessellated hull (200-300 for the Panda's links) makes the
# test 3-4x faster, while the polytope stays within a few millimetres of the hull.
_DIRECTIONS = np.concatenate([
    np.array([d for d in np.ndindex(3, 3, 3) if d != (1, 1, 1)], dtype=float) - 1.0,
    _fibonacci_directions(64),
])
_DIRECTIONS /= np.linalg.norm(_DIRECTIONS, axis=1, keepdims=True)


def _bounding_planes(vertices: np.ndarray) -> np.ndarray:
    """Planes (n, -h(n)) of the support function h over ``_DIRECTIONS``: a polytope containing the shape."""
    return np.concatenate([_DIRECTIONS, -(vertices @ _DIRECTIONS.T).max(axis=0)[:, None]], axis=1)


def set_configuration(model: pin.Model, q: np.ndarray, joint_positions: dict[str, float]) -> None:
    """Write named joint positions into Pinocchio's q in place (continuous joints take (cos, sin))."""
    for name, value in joint_positions.items():
        if not model.existJointName(name):
            continue
        joint = model.joints[model.getJointId(name)]
        if joint.nq == 1:
            q[joint.idx_q] = value
        elif joint.nq == 2:
            q[joint.idx_q : joint.idx_q + 2] = np.cos(value), np.sin(value)


class RobotSelfFilter:
    """Removes points inside the robot's collision geometry grown by ``margin`` (metres)."""

    def __init__(self, spec: RobotSpec, margin: float = DEFAULT_MARGIN) -> None:
        self.margin = float(margin)
        self.model, geometry = pin.buildModelsFromUrdf(
            str(spec.urdf_path), package_dirs=[str(p) for p in spec.package_dirs], geometry_types=pin.GeometryType.COLLISION
        )
        self._data = self.model.createData()
        self._shapes = []
        for obj in geometry.geometryObjects:
            vertices = shape_vertices(obj.geometry)
            self._shapes.append(_Shape(obj.parentJoint, obj.placement.homogeneous, vertices, _bounding_planes(vertices)))
        self._q = pin.neutral(self.model)
        self._configurations = [self._q.copy()]  # the robot is removed as it stands in each of these
        self._posed: list[tuple[torch.Tensor, torch.Tensor, np.ndarray, np.ndarray]] | None = None

    def set_joint_positions(self, names: list[str], positions: list[float] | np.ndarray) -> None:
        """Update from a JointState; joints the URDF does not have are ignored, missing ones keep their value."""
        self.set_configurations([dict(zip(names, positions))])

    def set_configurations(self, joint_positions: list[dict[str, float]]) -> None:
        """Remove the robot as it stood at each of these joint positions (one per distinct cloud
        stamp of a fused set). Each starts from the previous update's values for joints it lacks."""
        if not joint_positions:
            raise ValueError("set_configurations needs at least one set of joint positions")
        configurations = []
        for positions in joint_positions:
            q = self._q.copy()
            set_configuration(self.model, q, positions)
            configurations.append(q)
        self._q = configurations[-1]
        self._configurations = configurations
        self._posed = None

    def _pose(self) -> list[tuple[torch.Tensor, torch.Tensor, np.ndarray, np.ndarray]]:
        """Per shape and configuration: world-frame plane normals (F, 3) and offsets (F, 1) grown
        by the margin, and the grown world AABB."""
        if self._posed is None:
            posed = []
            for q in self._configurations:
                pin.forwardKinematics(self.model, self._data, q)
                for shape in self._shapes:
                    T = self._data.oMi[shape.joint].homogeneous @ shape.placement
                    R, t = T[:3, :3], T[:3, 3]
                    normals = shape.planes[:, :3] @ R.T
                    offsets = shape.planes[:, 3] - normals @ t - self.margin
                    world_vertices = shape.vertices @ R.T + t
                    posed.append((
                        torch.from_numpy(np.ascontiguousarray(normals, dtype=np.float32)),
                        torch.from_numpy(offsets.astype(np.float32)[:, None]),
                        world_vertices.min(axis=0) - self.margin,
                        world_vertices.max(axis=0) + self.margin,
                    ))
            self._posed = posed
        return self._posed

    @timed("self-filter")
    def keep_mask(self, points: np.ndarray) -> np.ndarray:
        """True for world points (N, 3) that are not on the robot."""
        points = np.ascontiguousarray(points, dtype=np.float32)
        keep = np.ones(len(points), dtype=bool)
        posed = self._pose()
        # Most points (table, object) are far from the arm: one test against the box around the
        # whole robot leaves only a few candidates for the per-shape tests.
        lo = np.array([p[2] for p in posed])
        hi = np.array([p[3] for p in posed])
        candidates = np.flatnonzero(_in_box(points.T, lo.min(axis=0), hi.max(axis=0)))
        # Candidates as one row per axis (3, M): the box tests of all shapes at once, the
        # (F, 3) x (3, M) products and the max over planes then run along contiguous rows.
        near_robot = np.ascontiguousarray(np.take(points, candidates, axis=0).T)
        in_boxes = _in_box(near_robot[:, None], lo.T[..., None], hi.T[..., None])  # (shapes, M)
        for (normals, offsets, _, _), in_box in zip(posed, in_boxes):
            near = np.flatnonzero(in_box)
            if near.size == 0:
                continue
            # torch (one thread) for the product: numpy's BLAS threads stalled 10x on a busy machine.
            distances = torch.addmm(offsets, normals, torch.from_numpy(np.take(near_robot, near, axis=1)))
            inside = (distances.amax(dim=0) <= 0.0).numpy()
            keep[candidates[near[inside]]] = False
        return keep


def _in_box(rows: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Which points of ``rows`` (3, ...: x, y and z of each point) lie in the box [lo, hi] (broadcast)."""
    x, y, z = rows
    return (x >= lo[0]) & (x <= hi[0]) & (y >= lo[1]) & (y <= hi[1]) & (z >= lo[2]) & (z <= hi[2])
