"""Primary render path: SAPIEN's rasteriser (Vulkan; on this CPU-only machine, Mesa lavapipe).

Cameras use SAPIEN's ``minimal`` shader, the cheapest one that gives what a depth camera needs:
``PositionSegmentation`` (int32 millimetres in the OpenGL camera frame - x right, y up,
z backward - plus the entity id) and ``Color``. Converting to the ROS optical frame (x right,
y down, z forward) is a sign flip of y and z (``T_OPENGL_OPTICAL``). Depth is therefore
quantised to 1 mm, like a real ToF camera's uint16 millimetre depth image; x and y are
back-projected from it through the pixel centres (``geometry.depth_to_points``), as the
stored pictures are.

All cameras are triggered before any picture is read, so lavapipe renders them back to back.
Heavy visual meshes are decimated the first time an entity is seen (``render_meshes``).
"""
from __future__ import annotations

import numpy as np
import sapien

from actaim2.geometry import T_ENTITY_OPTICAL, T_OPENGL_OPTICAL, depth_to_points
from actaim2.sim.cameras import CameraFrame, CameraSpec
from actaim2.sim.render_meshes import simplify_render_body

SHADER = "minimal"
# A render material counts as specular (a ToF camera's illumination is mirrored away) when it is
# a metal with a glossy finish; an entity is specular when most of its visual triangles are.
SPECULAR_METALLIC = 0.5
SPECULAR_ROUGHNESS = 0.3
_MM_TO_DEPTH = np.float32(T_OPENGL_OPTICAL[2, 2] / 1000.0)  # OpenGL z (backward, mm) -> optical z (forward, m)


class SapienRenderer:
    """Renders :class:`CameraSpec` views of a SAPIEN scene that has a render system."""

    path = "sapien"

    def __init__(self, scene: sapien.Scene, cameras: list[CameraSpec]) -> None:
        sapien.render.set_camera_shader_dir(SHADER)  # read when a camera component is created
        self._scene = scene
        self._cameras = list(cameras)
        self._components: dict[str, sapien.render.RenderCameraComponent] = {}
        self._seen: set[int] = set()  # entities whose visual meshes were already simplified
        self._specular: set[int] = set()  # entities whose visual material is mostly specular
        for spec in self._cameras:
            near = min(0.01, 0.5 * spec.min_depth)
            fovy = 2.0 * np.arctan(0.5 * spec.height / spec.fy)
            camera = scene.add_camera(f"render_{spec.name}", spec.width, spec.height, fovy, near, spec.max_depth + 1.0)
            camera.set_focal_lengths(spec.fx, spec.fy)
            camera.set_principal_point(spec.cx, spec.cy)
            self._components[spec.name] = camera
        self._pose_cameras()

    def _pose_cameras(self) -> None:
        for spec in self._cameras:
            T_world_entity = spec.T_world_optical @ np.linalg.inv(T_ENTITY_OPTICAL)
            self._components[spec.name].entity.set_pose(sapien.Pose(T_world_entity))

    def set_camera_poses(self, T_world_optical: dict[str, np.ndarray]) -> None:
        self._cameras = [c.with_pose(T_world_optical.get(c.name, c.T_world_optical)) for c in self._cameras]
        self._pose_cameras()

    def _render_bodies(self, hidden: set[int]) -> list[sapien.render.RenderBodyComponent]:
        bodies = []
        for entity in self._scene.entities:
            if entity.per_scene_id in hidden:
                body = entity.find_component_by_type(sapien.render.RenderBodyComponent)
                if body is not None and body.visibility > 0.0:
                    bodies.append(body)
        return bodies

    def render(self, hidden: set[int] = frozenset()) -> dict[str, CameraFrame]:
        """One frame per camera; entities whose per_scene_id is in ``hidden`` are invisible for
        this frame only: they neither appear nor occlude, as if they had been taken away."""
        for entity in self._scene.entities:
            if entity.per_scene_id not in self._seen:
                self._seen.add(entity.per_scene_id)
                simplify_render_body(entity)
                if _is_specular(entity):
                    self._specular.add(entity.per_scene_id)
        hidden_bodies = self._render_bodies(set(hidden))
        for body in hidden_bodies:
            body.visibility = 0.0
        try:
            self._scene.update_render()
            for spec in self._cameras:
                self._components[spec.name].take_picture()
            frames = {spec.name: self._read(spec) for spec in self._cameras}
        finally:
            for body in hidden_bodies:
                body.visibility = 1.0
        return frames

    def specular_entities(self) -> frozenset[int]:
        """per_scene_ids of the entities rendered so far whose material is specular."""
        return frozenset(self._specular)

    def _read(self, spec: CameraSpec) -> CameraFrame:
        camera = self._components[spec.name]
        position = camera.get_picture("PositionSegmentation")
        colour = camera.get_picture("Color")
        z = position[..., 2].astype(np.float32) * _MM_TO_DEPTH
        valid = (position[..., 2] < 0) & (z >= spec.min_depth) & (z <= spec.max_depth)
        # x and y back-projected from the millimetre depth, as from a depth image, not SAPIEN's
        # millimetre x and y: the pictures training stores keep only the depth, and their
        # back-projection must give the same points as the clouds published from this frame
        xyz = depth_to_points(np.where(valid, z, np.nan), spec.K).astype(np.float32)
        rgb = (np.clip(colour[..., :3], 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
        rgb[~valid] = 0
        segmentation = np.where(valid, position[..., 3], 0).astype(np.int32)
        return CameraFrame(spec.name, xyz, rgb, segmentation)


def _is_specular(entity: sapien.Entity) -> bool:
    """Most of the entity's visual triangles (a primitive counts as 12) carry a glossy metal material."""
    body = entity.find_component_by_type(sapien.render.RenderBodyComponent)
    if body is None:
        return False
    specular = total = 0
    for shape in body.render_shapes:
        parts = shape.parts if isinstance(shape, sapien.render.RenderShapeTriangleMesh) else [shape]
        for part in parts:
            weight = len(part.triangles) if hasattr(part, "triangles") else 12
            material = part.material
            total += weight
            if material.metallic >= SPECULAR_METALLIC and material.roughness <= SPECULAR_ROUGHNESS:
                specular += weight
    return total > 0 and specular > total / 2
