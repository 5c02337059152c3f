"""Synthetic depth-camera clouds by ray casting triangle meshes (Open3D), with exact ground truth.

Perception's tests and benchmark need clouds whose true geometry is known (a box seen by two
cameras, a robot in a known pose) without starting a simulator: a pinhole camera casts one ray
per pixel and returns an organized cloud in its ROS optical frame (x right, y down, z forward),
NaN where nothing is hit, exactly like a driver's PointCloud2. Camera poses come from
``actaim2.sim.cameras`` (``look_at_optical``, the ring5 and Azure Kinect rigs), which is pure
geometry and imports no simulator.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import open3d as o3d
import pinocchio as pin

from actaim2.perception.self_filter import set_configuration
from actaim2.robots import RobotSpec


def box_mesh(center, size) -> o3d.geometry.TriangleMesh:
    mesh = o3d.geometry.TriangleMesh.create_box(*map(float, size))
    return mesh.translate(np.asarray(center, dtype=float) - np.asarray(size, dtype=float) / 2)


def robot_collision_meshes(spec: RobotSpec, joint_positions: dict[str, float]) -> list[o3d.geometry.TriangleMesh]:
    """The robot's collision meshes and boxes posed in world (= URDF root) at the given joints."""
    model, geometry = pin.buildModelsFromUrdf(
        str(spec.urdf_path), package_dirs=[str(p) for p in spec.package_dirs], geometry_types=pin.GeometryType.COLLISION
    )
    q = pin.neutral(model)
    set_configuration(model, q, joint_positions)
    data = model.createData()
    geometry_data = geometry.createData()
    pin.updateGeometryPlacements(model, data, geometry, geometry_data, q)
    meshes = []
    for obj, placement in zip(geometry.geometryObjects, geometry_data.oMg):
        shape = obj.geometry
        if hasattr(shape, "halfSide"):
            mesh = box_mesh(np.zeros(3), 2 * np.asarray(shape.halfSide))
        else:
            mesh = o3d.io.read_triangle_mesh(obj.meshPath)
            mesh.vertices = o3d.utility.Vector3dVector(np.asarray(mesh.vertices) * np.asarray(obj.meshScale))
        meshes.append(mesh.transform(placement.homogeneous))
    return meshes


@dataclass
class RaycastScene:
    """Meshes with one flat colour each; ``capture`` returns what a depth camera would see."""

    meshes: list[tuple[o3d.geometry.TriangleMesh, tuple[int, int, int]]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._scene = o3d.t.geometry.RaycastingScene()
        self._colours = [np.asarray(rgb, dtype=np.uint8) for _, rgb in self.meshes]
        for mesh, _ in self.meshes:
            self._scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))

    def capture(self, T_world_optical: np.ndarray, width: int, height: int, hfov_deg: float = 70.0) -> tuple[np.ndarray, np.ndarray]:
        """Organized (H, W, 3) float32 xyz in the optical frame (NaN = no hit) and (H, W, 3) uint8 rgb."""
        f = width / (2.0 * np.tan(np.deg2rad(hfov_deg) / 2.0))
        u, v = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
        directions = np.stack([(u - width / 2) / f, (v - height / 2) / f, np.ones_like(u)], axis=-1)  # z = 1
        world_dirs = directions @ T_world_optical[:3, :3].T
        origins = np.broadcast_to(T_world_optical[:3, 3], world_dirs.shape)
        rays = np.concatenate([origins, world_dirs], axis=-1).astype(np.float32)
        hit = self._scene.cast_rays(o3d.core.Tensor(rays))
        t = hit["t_hit"].numpy()
        ids = hit["geometry_ids"].numpy()
        t = np.where(np.isfinite(t), t, np.nan)
        xyz = (directions * t[..., None]).astype(np.float32)  # directions have z = 1: t is the depth
        palette = np.concatenate([np.stack(self._colours), np.zeros((1, 3), np.uint8)]) if self._colours else np.zeros((1, 3), np.uint8)
        rgb = palette[np.where(np.isfinite(t), ids, len(self._colours)).astype(np.int64)]
        return xyz, rgb
