"""CPU fallback render path: ray casting SAPIEN's collision geometry with Open3D.

Used when no Vulkan device exists (SAPIEN cannot create a camera at all then). Every rigid
body's collision shapes are turned into one triangle mesh per entity (cached), posed at the
entity's current pose, and intersected with one ray per pixel by
``open3d.t.geometry.RaycastingScene``. Depth agrees with SAPIEN's rasteriser to about a
millimetre on the same geometry; colour is a flat colour per entity (no shading, no texture),
which is what the fallback promises.
"""
from __future__ import annotations

import zlib

import numpy as np
import open3d as o3d
import sapien

from actaim2.sim.cameras import CameraFrame, CameraSpec

GROUND_HALF_EXTENT = 20.0  # metres: an infinite PhysX plane becomes a square this large
_CYLINDER_SEGMENTS = 24
_Z_TO_X = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # rotates +z onto +x


def collision_shape_mesh(shape: sapien.physx.PhysxCollisionShape) -> tuple[np.ndarray, np.ndarray] | None:
    """(vertices, triangles) of one collision shape in its own frame, or None if unsupported.

    PhysX conventions: capsules and cylinders run along local x; a plane is x = 0 with normal +x.
    """
    physx = sapien.physx
    if isinstance(shape, physx.PhysxCollisionShapeBox):
        mesh = o3d.geometry.TriangleMesh.create_box(*(2.0 * np.asarray(shape.half_size)))
        mesh.translate(-np.asarray(shape.half_size))
    elif isinstance(shape, physx.PhysxCollisionShapeSphere):
        mesh = o3d.geometry.TriangleMesh.create_sphere(shape.radius, resolution=12)
    elif isinstance(shape, physx.PhysxCollisionShapeCapsule):
        mesh = o3d.geometry.TriangleMesh.create_cylinder(shape.radius, 2.0 * shape.half_length, _CYLINDER_SEGMENTS)
        for sign in (-1.0, 1.0):
            cap = o3d.geometry.TriangleMesh.create_sphere(shape.radius, resolution=12)
            mesh += cap.translate([0.0, 0.0, sign * shape.half_length])
        mesh.rotate(_Z_TO_X, center=np.zeros(3))
    elif isinstance(shape, physx.PhysxCollisionShapeCylinder):
        mesh = o3d.geometry.TriangleMesh.create_cylinder(shape.radius, 2.0 * shape.half_length, _CYLINDER_SEGMENTS)
        mesh.rotate(_Z_TO_X, center=np.zeros(3))
    elif isinstance(shape, (physx.PhysxCollisionShapeConvexMesh, physx.PhysxCollisionShapeTriangleMesh)):
        return np.asarray(shape.vertices, dtype=np.float64) * np.asarray(shape.scale), np.asarray(shape.triangles, dtype=np.int64)
    elif isinstance(shape, physx.PhysxCollisionShapePlane):
        e = GROUND_HALF_EXTENT
        vertices = np.array([[0.0, -e, -e], [0.0, e, -e], [0.0, e, e], [0.0, -e, e]])
        return vertices, np.array([[0, 1, 2], [0, 2, 3]])
    else:
        return None
    return np.asarray(mesh.vertices), np.asarray(mesh.triangles, dtype=np.int64)


def entity_colour(name: str) -> np.ndarray:
    """A stable, saturated RGB colour for an entity name (same name -> same colour in every run)."""
    h = zlib.crc32(name.encode()) & 0xFFFFFF
    hue = (h % 360) / 60.0
    x = 1.0 - abs(hue % 2.0 - 1.0)
    rgb = [(1, x, 0), (x, 1, 0), (0, 1, x), (0, x, 1), (x, 0, 1), (1, 0, x)][int(hue) % 6]
    return (60 + 160 * np.asarray(rgb)).astype(np.uint8)


class RaycastRenderer:
    """Renders :class:`CameraSpec` views of a SAPIEN scene by ray casting collision meshes."""

    path = "raycast"

    def __init__(self, scene: sapien.Scene, cameras: list[CameraSpec]) -> None:
        self._scene = scene
        self._rays_optical = {c.name: c.pixel_rays().reshape(-1, 3) for c in cameras}
        self._cameras: list[CameraSpec] = []
        self._rays_world: dict[str, np.ndarray] = {}
        self._place(cameras)
        # entity per_scene_id -> (name, vertices in entity frame, triangles), filled lazily:
        # entities added by a reset are meshed on first sight, removed ones are never posed.
        self._meshes: dict[int, tuple[str, np.ndarray, np.ndarray] | None] = {}

    def _place(self, cameras: list[CameraSpec]) -> None:
        """Set the camera poses and precompute each camera's rays (origin, direction) in world."""
        self._cameras = list(cameras)
        for cam in self._cameras:
            rays_opt = self._rays_optical[cam.name]
            R, p = cam.T_world_optical[:3, :3], cam.T_world_optical[:3, 3]
            rays = np.empty((len(rays_opt), 6), dtype=np.float32)
            rays[:, :3] = p
            # per-column products instead of a BLAS matmul: cheap and single-threaded
            rays[:, 3:] = rays_opt[:, :1] * R[:, 0] + rays_opt[:, 1:2] * R[:, 1] + rays_opt[:, 2:] * R[:, 2]
            self._rays_world[cam.name] = rays

    def set_camera_poses(self, T_world_optical: dict[str, np.ndarray]) -> None:
        self._place([c.with_pose(T_world_optical.get(c.name, c.T_world_optical)) for c in self._cameras])

    def _entity_mesh(self, entity: sapien.Entity) -> tuple[str, np.ndarray, np.ndarray] | None:
        key = entity.per_scene_id
        if key not in self._meshes:
            body = entity.find_component_by_type(sapien.physx.PhysxRigidBaseComponent)
            parts_v, parts_t, offset = [], [], 0
            for shape in body.collision_shapes if body is not None else []:
                local = collision_shape_mesh(shape)
                if local is None:
                    continue
                v, t = local
                T = shape.local_pose.to_transformation_matrix()
                parts_v.append(v @ T[:3, :3].T + T[:3, 3])
                parts_t.append(t + offset)
                offset += len(v)
            self._meshes[key] = (entity.name, np.concatenate(parts_v), np.concatenate(parts_t)) if parts_v else None
        return self._meshes[key]

    def _build_scene(self, hidden: set[int]) -> tuple[o3d.t.geometry.RaycastingScene, np.ndarray, np.ndarray]:
        """A raycasting scene of every visible entity at its current pose, plus per-geometry
        entity ids and colours (indexed by the geometry id Open3D returns)."""
        rc = o3d.t.geometry.RaycastingScene()
        ids, colours = [], []
        for entity in self._scene.entities:
            if entity.per_scene_id in hidden:
                continue
            mesh = self._entity_mesh(entity)
            if mesh is None:
                continue
            name, v, t = mesh
            T = entity.pose.to_transformation_matrix()
            rc.add_triangles(
                o3d.core.Tensor((v @ T[:3, :3].T + T[:3, 3]).astype(np.float32)), o3d.core.Tensor(t.astype(np.uint32))
            )
            ids.append(entity.per_scene_id)
            colours.append(entity_colour(name))
        ids.append(0)  # INVALID_ID lookups are clamped onto this "nothing" entry
        colours.append(np.zeros(3, np.uint8))
        return rc, np.asarray(ids, dtype=np.int32), np.asarray(colours, dtype=np.uint8)

    def specular_entities(self) -> frozenset[int]:
        """None: collision geometry carries no render material."""
        return frozenset()

    def render(self, hidden: set[int] = frozenset()) -> dict[str, CameraFrame]:
        """One frame per camera; entities whose per_scene_id is in ``hidden`` are left out."""
        rc, ids, colours = self._build_scene(set(hidden))
        frames = {}
        for cam in self._cameras:
            rays_opt = self._rays_optical[cam.name]
            hit = rc.cast_rays(o3d.core.Tensor(self._rays_world[cam.name]))
            t = hit["t_hit"].numpy()  # the direction has optical z = 1, so t is the depth
            geometry = hit["geometry_ids"].numpy().astype(np.int64)
            geometry[geometry >= len(ids) - 1] = len(ids) - 1  # INVALID_ID (uint32 max) -> "nothing"
            valid = np.isfinite(t) & (t >= cam.min_depth) & (t <= cam.max_depth)
            xyz = np.where(valid[:, None], rays_opt * t[:, None], np.nan).astype(np.float32)
            seg = np.where(valid, ids[geometry], 0)
            rgb = np.where(valid[:, None], colours[geometry], 0).astype(np.uint8)
            shape = (cam.height, cam.width)
            frames[cam.name] = CameraFrame(
                cam.name, xyz.reshape(*shape, 3), rgb.reshape(*shape, 3), seg.reshape(shape).astype(np.int32)
            )
        return frames
