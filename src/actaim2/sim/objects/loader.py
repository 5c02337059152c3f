"""Load a PartNet-Mobility style object folder into a SAPIEN scene and place it before the robot.

One path for every object: SAPIEN's URDF loader on ``<folder>/mobility.urdf`` (generated
objects are written in that layout by :mod:`actaim2.sim.objects.catalog`). The object's root
is fixed to the world; gravity acts on every link, and each movable joint gets the friction,
damping and behaviour (bistable toggle, counterbalanced sash) of :mod:`.dynamics`: the
URDF's ``<dynamics>`` where given, else the category table (:mod:`.physics_table`). A part
stays where the robot leaves it if its joint's friction beats its weight, as real ones do.

Real PartNet-Mobility folders go through the same path after :mod:`.partnet` has checked
them (every failure is an :class:`ObjectLoadError` naming the file and the reason). They are
keyed by folder name, their ``model_cat`` mapped to the catalogue's names, scaled and set back
by :mod:`.sizing` (category size, workspace cube), and their collision meshes replaced by the
convex decompositions of :mod:`.hulls` (one hull per mesh, with a warning, where the cache has
none). Their links do not collide with each other: PartNet parts interpenetrate at their seams
(an oven's five buttons share one origin), and PhysX would push them apart. Continuous joints
stay unlimited in physics; their reported range is :data:`.partnet.CONTINUOUS_RANGE`.

Placement: the object, at rest (every joint at 0, clipped into its limits: the pose it was
modelled in, closed), is turned by ``yaw`` and moved so that its bounding box's front face is
``front_distance`` in front of the robot base (+x of ``world``), centred at ``lateral`` (y)
and standing on the floor (or ``base_height`` above it: :mod:`.sizing`).
"""
from __future__ import annotations

import dataclasses
import itertools
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import sapien

from ..urdf import parse_urdf
from .dynamics import ObjectDynamics, joint_dynamics
from .errors import ObjectLoadError
from .hulls import HullCache, count_hulls, needs_hulls
from .mesh import read_mesh
from .model import Handle, read_handles, read_meta
from .partnet import CONTINUOUS_RANGE, ObjectFolder, read_object_folder
from .physics_table import effective_density
from .sizing import DEFAULT_FRONT_DISTANCE, fit_object

LOG = logging.getLogger("actaim2.sim.objects")
# A PhysX shape's collision groups are four 32-bit words; SAPIEN's filter shader reads them so:
#   word 0: the shape's own group bits; word 1: the groups it collides with (pairs collide when
#     a.w0 & b.w1 or b.w0 & a.w1 is non-zero; everything here keeps SAPIEN's default 1, 1);
#   word 2: ignore bits: two shapes sharing a bit here are ignored when their word-3 low 16 bits match
#     (SAPIEN's SRDF loader gives each of a robot's ignored link pairs one of bits 0-30);
#   word 3: top 16 bits a "scene" number (different numbers never collide: keep them 0), low 16
#     bits an id that word 2's ignore bits must match.
# A real object's links get word-2 bit 31 (no robot uses it) and a word-3 id of their own, so
# they skip each other and collide with the robot, the ground and every other body.
OBJECT_IGNORE_BIT = 1 << 31
_object_ids = itertools.cycle(range(1, 1 << 16))  # word-3 ids: one per loaded real object
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
    front_distance: float = DEFAULT_FRONT_DISTANCE  # the recommended one (meta.json or sizing), before jitter
    base_height: float = 0.0  # m its bottom stands above the floor (sizing: parts that swing below it)
    hulls: int = 0  # convex collision shapes
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
        if self.dynamics is not None:
            self.dynamics.at_rest()

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


def load_object(
    scene: sapien.Scene,
    folder: Path,
    front_distance: float | None = None,
    lateral: float = 0.0,
    yaw: float = 0.0,
    scale: float | None = None,
    keep_visuals: bool = False,
    hulls: HullCache | None = None,
) -> LoadedObject:
    """Load ``folder`` (mobility.urdf + meshes) and place it; ``keep_visuals`` needs a render system.

    ``scale`` None: generated folders 1, real ones by :func:`.sizing.fit_object`. ``hulls``:
    the decomposition cache of real folders' collision meshes (default folder if None)."""
    info = read_object_folder(folder)
    folder, urdf = info.folder, info.urdf
    if info.generated:
        scale, recommended = (1.0 if scale is None else float(scale)), recommended_front_distance(folder)
        base_height = 0.0
    else:
        fit = fit_object(info, scale)
        scale, recommended, base_height = fit.scale, fit.front_distance, fit.lift
    loader = scene.create_urdf_loader()
    loader.fix_root_link = True
    loader.scale = scale
    loader.set_density(OBJECT_DENSITY)
    loader.set_material(OBJECT_FRICTION, OBJECT_FRICTION, 0.0)
    builders, actor_builders, _ = parse_urdf(loader, urdf, keep_visuals=keep_visuals)
    if len(builders) != 1 or actor_builders:
        raise ObjectLoadError(f"{urdf}: expected one articulation, got {len(builders)} articulations and {len(actor_builders)} free bodies")
    n_hulls = None if info.generated else _collisions_from_hulls(builders[0], info, hulls or HullCache(), scale)
    articulation = builders[0].build()
    articulation.name = info.object_id
    joints = articulation.get_active_joints()
    # SAPIEN's limits (prismatic ones scaled to metres); continuous joints: their reported range
    limits = np.asarray([j.limit[0] for j in joints], dtype=float) + 0.0  # + 0.0: a "-0.0" limit reads 0
    limits[~np.isfinite(limits).all(axis=1)] = CONTINUOUS_RANGE
    n_hulls = sum(len(link.collision_shapes) for link in articulation.links) if n_hulls is None else n_hulls
    obj = LoadedObject(folder, info.object_id, info.category, articulation, joints, limits[:, 0].copy(),
                       limits[:, 1].copy(), read_handles(folder), scale, recommended, base_height, n_hulls)
    obj.dynamics = ObjectDynamics(articulation, joints, joint_dynamics(urdf, joints, obj.category, info.semantics))
    place(obj, recommended if front_distance is None else front_distance, lateral, yaw)
    return obj


def _collisions_from_hulls(builder, info: ObjectFolder, hulls: HullCache, scale: float) -> int:
    """Swap each collision mesh of a real folder's links for its cached convex decomposition
    (module docstring), give each link its material's density and keep the links from
    colliding with each other; returns the number of convex shapes."""
    total, missing, checked = 0, [], {}
    object_id = next(_object_ids)
    for lb in builder.link_builders:
        density = effective_density(info.category, info.semantics.get(lb.name, ""))
        w0, w1, w2, _ = lb.collision_groups
        lb.collision_groups = [w0, w1, w2 | OBJECT_IGNORE_BIT, object_id]
        swapped = []
        for record in lb.collision_records:
            record.density = density
            if record.type != "convex_mesh":
                swapped.append(record)
                total += 1
                continue
            path = Path(record.filename).resolve()
            if path not in checked:
                entry = None
                if needs_hulls(read_mesh(path), np.asarray(record.scale, dtype=float)):
                    entry = hulls.lookup(path)
                    if entry is None:
                        missing.append(path)
                checked[path] = entry
            entry = checked[path]
            if entry is None:
                swapped.append(record)
                total += 1
            else:
                swapped.append(dataclasses.replace(record, type="multiple_convex_meshes", filename=str(entry)))
                total += count_hulls(entry)
        lb.collision_records = swapped
    if missing:
        LOG.warning("%s: %d of %d collision meshes have no convex decomposition in %s and are one convex hull each "
                    "(concave parts such as bar handles become solid): run `actaim2 prepare-objects %s --cache %s`",
                    info.folder, len(missing), len(checked), hulls.root, info.folder, hulls.root)
    return total


def recommended_front_distance(folder: Path) -> float:
    """The front distance the object's recipe recommends (meta.json), else the default."""
    return float(read_meta(folder).get("params", {}).get("front_distance", DEFAULT_FRONT_DISTANCE))


def place(obj: LoadedObject, front_distance: float, lateral: float = 0.0, yaw: float = 0.0) -> None:
    """Pose the object's root as the module docstring says (measured at rest)."""
    art = obj.articulation
    art.set_root_pose(sapien.Pose())
    obj.set_qpos(np.clip(0.0, obj.lower, obj.upper))
    lo, hi = aabb(art)
    anchor_obj = np.array([lo[0], (lo[1] + hi[1]) / 2, lo[2]])
    anchor_world = np.array([front_distance, lateral, obj.base_height])
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

