"""Load a PartNet-Mobility style object folder into a SAPIEN scene and place it before the robot.

One path for every object: SAPIEN's URDF loader on ``<folder>/mobility.urdf`` (generated
objects are written in that layout by :mod:`actaim2.sim.objects.catalog`). The object's root
is fixed to the world; gravity acts on every link, and each movable joint gets the friction,
damping and behaviour (bistable toggle, counterbalanced sash) of :mod:`.dynamics`: the
URDF's ``<dynamics>`` where given, else the category table (:mod:`.physics_table`). A part
stays where the robot leaves it if its joint's friction beats its weight, as real ones do.

Placement: the object, at its closed configuration (lower limits), is turned by ``yaw`` and
moved so that its bounding box's front face is ``front_distance`` in front of the robot base
(+x of ``world``), centred at ``lateral`` (y) and standing on the floor.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import sapien

from ..urdf import parse_urdf
from .dynamics import ObjectDynamics, joint_dynamics
from .model import Handle, read_handles, read_meta, read_semantics

DEFAULT_FRONT_DISTANCE = 0.55  # m, for folders whose meta.json does not recommend one
OBJECT_DENSITY = 500.0  # kg/m^3, wood-like
OBJECT_FRICTION = 1.0  # static and dynamic, on every object surface


@dataclass
class LoadedObject:
    """An articulated object in the scene, with its degrees of freedom and grasp annotations."""

    folder: Path
    object_id: str
    category: str
    articulation: sapien.physx.PhysxArticulation
    joints: list  # movable PhysxArticulationJoint, in DoF order
    lower: np.ndarray
    upper: np.ndarray
    handles: list[Handle]
    scale: float = 1.0
    dynamics: ObjectDynamics | None = None  # joint friction and springs: step() before every physics step

    @property
    def dof_names(self) -> list[str]:
        return [j.name for j in self.joints]

    @property
    def links(self) -> list:
        return list(self.articulation.links)

    def qpos(self) -> np.ndarray:
        return np.asarray(self.articulation.get_qpos(), dtype=float)

    def set_qpos(self, q: np.ndarray) -> None:
        """Teleport the DoFs to ``q`` (clipped to the limits) at rest."""
        q = np.clip(np.asarray(q, dtype=float), self.lower, self.upper)
        self.articulation.set_qpos(q)
        self.articulation.set_qvel(np.zeros_like(q))

    def pose(self) -> np.ndarray:
        """4x4 pose of the object's root link in ``world``."""
        return self.articulation.get_root_pose().to_transformation_matrix()

    def link(self, name: str):
        for link in self.articulation.links:
            if link.name == name:
                return link
        raise KeyError(f"object {self.object_id} has no link {name!r}")

    def dof_index(self, joint_name: str) -> int:
        names = self.dof_names
        if joint_name not in names:
            raise KeyError(f"object {self.object_id} has no movable joint {joint_name!r}; it has {names}")
        return names.index(joint_name)


class ObjectLoadError(ValueError):
    """An object folder that cannot be loaded (missing, no URDF, bad URDF, missing mesh...): the
    message says which file and why, so a service can answer it instead of crashing."""


def load_object(
    scene: sapien.Scene,
    folder: Path,
    front_distance: float | None = None,
    lateral: float = 0.0,
    yaw: float = 0.0,
    scale: float = 1.0,
    keep_visuals: bool = False,
) -> LoadedObject:
    """Load ``folder`` (mobility.urdf + meshes) and place it; ``keep_visuals`` needs a render system."""
    folder = Path(folder)
    urdf = folder / "mobility.urdf"
    if not urdf.is_file():
        raise ObjectLoadError(f"{folder} is not a PartNet-Mobility style object folder: no mobility.urdf")
    meta = read_meta(folder)
    loader = scene.create_urdf_loader()
    loader.fix_root_link = True
    loader.scale = scale
    loader.set_density(OBJECT_DENSITY)
    loader.set_material(OBJECT_FRICTION, OBJECT_FRICTION, 0.0)
    builders, actor_builders, _ = parse_urdf(loader, urdf, keep_visuals=keep_visuals)
    if len(builders) != 1 or actor_builders:
        raise ObjectLoadError(f"{urdf}: expected one articulation, got {len(builders)} articulations and {len(actor_builders)} free bodies")
    articulation = builders[0].build()
    try:
        articulation.name = meta.get("anno_id", folder.name)
        joints = articulation.get_active_joints()
        if not joints:
            raise ObjectLoadError(f"{urdf}: the object has no movable joint")
        limits = np.asarray([j.limit[0] for j in joints], dtype=float)
        if not np.all(np.isfinite(limits)):
            raise ObjectLoadError(f"{urdf}: every movable joint needs finite limits (continuous joints are not supported)")
    except ObjectLoadError:
        scene.remove_articulation(articulation)  # a refused object leaves nothing behind in the scene
        raise
    obj = LoadedObject(folder, articulation.name, meta.get("model_cat", "unknown"), articulation, joints,
                       limits[:, 0].copy(), limits[:, 1].copy(), read_handles(folder), scale)
    obj.dynamics = ObjectDynamics(articulation, joints, joint_dynamics(urdf, joints, obj.category, read_semantics(folder)))
    place(obj, recommended_front_distance(folder) if front_distance is None else front_distance, lateral, yaw)
    return obj


def recommended_front_distance(folder: Path) -> float:
    """The front distance the object's recipe recommends (meta.json), else the default."""
    return float(read_meta(folder).get("params", {}).get("front_distance", DEFAULT_FRONT_DISTANCE))


def place(obj: LoadedObject, front_distance: float, lateral: float = 0.0, yaw: float = 0.0) -> None:
    """Pose the object's root as the module docstring says (measured at the closed state)."""
    art = obj.articulation
    art.set_root_pose(sapien.Pose())
    obj.set_qpos(obj.lower)
    lo, hi = aabb(art)
    anchor_obj = np.array([lo[0], (lo[1] + hi[1]) / 2, lo[2]])
    anchor_world = np.array([front_distance, lateral, 0.0])
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = anchor_world - R @ anchor_obj
    art.set_root_pose(sapien.Pose(T))


def aabb(articulation: sapien.physx.PhysxArticulation) -> tuple[np.ndarray, np.ndarray]:
    """World axis-aligned bounding box of all collision shapes of an articulation."""
    boxes = [link.compute_global_aabb_tight() for link in articulation.links if link.collision_shapes]
    boxes = np.asarray(boxes, dtype=float)
    return boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)

