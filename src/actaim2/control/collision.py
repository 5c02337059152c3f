"""Is an arm configuration safe? Self-collision and collision with the known environment.

Self-collision uses the URDF collision geometry through Pinocchio + coal. Meshes are
replaced by their convex hulls: GJK on hulls is an order of magnitude faster than on the
raw triangle soups (the Kinova meshes are visual-quality, up to 45k triangles) and errs on
the safe side. Link pairs that can never or always touch are skipped, as MoveIt's setup
assistant does: pairs the SRDF disables, kinematically adjacent links, and pairs already
in contact at the home configuration.

The environment is what the controller knows without perception: the support plane (table
or ground) and a workspace safety box, both as coal half-spaces, plus optionally the fused
point cloud as an octree with the points near the grasp point removed (the gripper is meant
to touch the object there). Links rigidly fixed to the robot's root (the base, standing on
the plane) are not checked against the environment.
"""
from __future__ import annotations

from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin

from actaim2.control.model import RobotModel
from actaim2.profiling import timed


@dataclass(frozen=True)
class Workspace:
    """What the arm must never touch: the support plane and the outside of a safety box (world)."""

    table_height: float = 0.0
    box_min: tuple[float, float, float] = (-0.8, -0.9, -0.05)
    box_max: tuple[float, float, float] = (1.3, 0.9, 1.5)

    def __post_init__(self) -> None:
        if not np.all(np.asarray(self.box_min) < np.asarray(self.box_max)):
            raise ValueError(f"workspace box_min {self.box_min} must be below box_max {self.box_max}")


@dataclass(frozen=True)
class Collision:
    """The first colliding pair found: ``kind`` is "self" or "environment"."""

    kind: str
    first: str
    second: str

    def __str__(self) -> str:
        return f"{self.kind} collision between {self.first} and {self.second}"


class CollisionChecker:
    """Collision queries on joint angles of one :class:`RobotModel` in one :class:`Workspace`."""

    def __init__(self, robot: RobotModel, workspace: Workspace = Workspace()):
        self.robot = robot
        self.workspace = workspace
        geom = robot.geometry.clone()
        for obj in geom.geometryObjects:
            if isinstance(obj.geometry, coal.BVHModelBase):
                obj.geometry.buildConvexHull(False, "Qt")
                obj.geometry = obj.geometry.convex
        self._moving = [i for i, o in enumerate(geom.geometryObjects) if o.parentJoint != 0]
        geom.addAllCollisionPairs()
        self._remove_never_colliding(geom)
        self._n_self_pairs = len(geom.collisionPairs)
        for name, normal, offset in _halfspaces(workspace):
            obj = pin.GeometryObject(name, 0, 0, pin.SE3.Identity(), coal.Halfspace(normal, offset))
            env = geom.addGeometryObject(obj)
            for i in self._moving:
                geom.addCollisionPair(pin.CollisionPair(i, env))
        self.geometry = geom
        self.data = pin.GeometryData(geom)
        self._cloud: coal.OcTree | None = None
        self._request = coal.CollisionRequest()
        self._result = coal.CollisionResult()

    def _remove_never_colliding(self, geom: pin.GeometryModel) -> None:
        model = self.robot.model
        spec = self.robot.spec
        if spec.srdf_path is not None and spec.srdf_path.is_file():
            pin.removeCollisionPairs(model, geom, str(spec.srdf_path), False)
        objs = geom.geometryObjects

        def adjacent(pair: pin.CollisionPair) -> bool:
            a, b = objs[pair.first].parentJoint, objs[pair.second].parentJoint
            return a == b or model.parents[a] == b or model.parents[b] == a

        data = pin.GeometryData(geom)
        pin.computeCollisions(model, model.createData(), geom, data, self.robot.to_q(spec.home), False)
        remove = [
            (p.first, p.second)  # copied: the pairs are views into a vector that shrinks below
            for p, res in zip(geom.collisionPairs, data.collisionResults)
            if adjacent(p) or res.isCollision()
        ]
        for first, second in remove:
            geom.removeCollisionPair(pin.CollisionPair(first, second))

    def set_cloud(self, points: np.ndarray | None, resolution: float = 0.01) -> None:
        """Obstacle points in `world` (None clears). Cropping around the grasp point is the
        caller's job (:func:`points_away_from`), as only it knows where the grasp is."""
        if points is None or len(points) == 0:
            self._cloud = None
            return
        points = np.asarray(points, dtype=float)
        self._cloud = coal.makeOctree(points[np.all(np.isfinite(points), axis=1)], resolution)

    @property
    def has_cloud(self) -> bool:
        return self._cloud is not None

    @timed("collision checks")
    def check(self, angles: np.ndarray, use_cloud: bool = True) -> Collision | None:
        """The first collision at these joint angles, or None when the configuration is safe."""
        model, geom, data = self.robot.model, self.geometry, self.data
        if pin.computeCollisions(model, self.robot.data, geom, data, self.robot.to_q(angles), True):
            for k, res in enumerate(data.collisionResults):
                if res.isCollision():
                    pair = geom.collisionPairs[k]
                    kind = "self" if k < self._n_self_pairs else "environment"
                    return Collision(kind, geom.geometryObjects[pair.first].name, geom.geometryObjects[pair.second].name)
        if use_cloud and self._cloud is not None:
            identity = coal.Transform3s()
            for i in self._moving:
                self._result.clear()
                placement = data.oMg[i]
                tf = coal.Transform3s(placement.rotation, placement.translation)
                if coal.collide(geom.geometryObjects[i].geometry, tf, self._cloud, identity, self._request, self._result):
                    return Collision("environment", geom.geometryObjects[i].name, "point cloud")
        return None


def points_away_from(points: np.ndarray, center: np.ndarray, radius: float) -> np.ndarray:
    """The points farther than ``radius`` from ``center``: the cloud minus the grasp region."""
    points = np.asarray(points, dtype=float)
    return points[np.linalg.norm(points - np.asarray(center, dtype=float), axis=1) > radius]


def _halfspaces(ws: Workspace) -> list[tuple[str, np.ndarray, float]]:
    """coal half-spaces {x : n.x <= d} for the region under the table and outside the box."""
    out = [("table", np.array([0.0, 0.0, 1.0]), ws.table_height)]
    for axis, name in enumerate("xyz"):
        n = np.zeros(3)
        n[axis] = 1.0
        out.append((f"workspace_min_{name}", n, ws.box_min[axis]))  # x_axis <= min
        out.append((f"workspace_max_{name}", -n, -ws.box_max[axis]))  # x_axis >= max
    return out
