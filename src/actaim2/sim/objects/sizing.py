"""Scale and front distance of a real object: its category's size, shrunk until its moving parts
stay inside the rig's workspace cube.

PartNet-Mobility meshes are normalised (about unit size) and their users scale each object.
The rule here, for a folder not written by the generator (those are built at real size):

1. **Category size.** The object's largest side at rest becomes :data:`CATEGORY_SIZES`'s value
   for its category: the middle of a range of real sizes that the robot can still work on
   (docs/simulation.md, "Sizes and placement", gives the real ranges and why some are smaller;
   an unknown category gets :data:`DEFAULT_SIZE`).
2. **Front distance.** Its closed front stands ``DEFAULT_FRONT_DISTANCE`` before the robot
   base, farther when its parts, all half-open (the default reset), would reach closer than
   ``HOME_CLEARANCE`` to the base: the generated objects' rule (:mod:`.parts`).
3. **Floor.** The object stands on the floor, raised (as on a plinth) where a part swept over
   its range would go below it: a door hinged at the bottom edge swings its lower edge under
   the hinge, and the floor would stop it (PhysX then pushes it through its limits).
4. **Workspace fit.** Every movable link (handles are part of their link), swept over its
   joint's whole range one joint at a time, must stay inside the workspace cube shrunk by
   :data:`WORKSPACE_MARGIN` (room for the reset's placement jitter); if it does not, the scale
   shrinks (bisection) until it does. A scale given by the caller is kept as it is.

The workspace cube is the perception rigs' (``actaim2/perception/configs/*.yaml``): centre
:data:`WORKSPACE_CENTER`, half side :data:`WORKSPACE_HALF_EXTENT` = 0.6 m, so x 0.15..1.35,
y -0.6..0.6, z -0.2..1.0 m in ``world``; its 1.2 m side over 128 view pixels is 9.4 mm per
pixel (5.4 mm at 224 px). A test checks these constants against the rig configurations.
Forward kinematics run on the collision meshes' convex-hull vertices, in numpy, so the fit is
known before SAPIEN loads anything (and ``prepare-objects`` knows the scale too).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import ObjectLoadError
from .mesh import convex_hull, read_mesh
from .partnet import ObjectFolder
from .parts import HOME_CLEARANCE

WORKSPACE_CENTER = np.array([0.75, 0.0, 0.4])  # m, world: where objects stand and the cameras look
WORKSPACE_HALF_EXTENT = 0.6  # m
WORKSPACE_MARGIN = 0.1  # m: placement jitter (+-3 cm, +-5 cm sideways, +-5 deg) moves a part by up to ~9 cm
DEFAULT_FRONT_DISTANCE = 0.55  # m, for folders whose meta.json does not recommend one
SWEEP_SAMPLES = 9  # joint positions per movable joint in the workspace fit

# Largest side (m) of an object at rest per category: (low, high) of sizes the robot can work on;
# the rule uses the middle. Real ranges and the reasons for smaller ones: docs/simulation.md.
CATEGORY_SIZES: dict[str, tuple[float, float]] = {
    "storage_furniture": (0.5, 0.92),  # real 0.5-1.2 high; the top drawer stays below ~0.9 m
    "table": (0.6, 0.95),  # real 0.6-1.8 wide; drawers at 0.35-0.5 m
    "door": (0.75, 0.95),  # real leaf 2.0-2.1 high: scaled ~0.45 as the generated doors
    "refrigerator": (0.85, 1.0),  # under-counter and mini fridges
    "faucet": (0.2, 0.35),  # spout reach 0.12-0.25, body up to 0.35
    "switch": (0.07, 0.12),  # one-gang plate 0.07 x 0.115
    "window": (0.45, 0.62),  # real 0.6-1.5: scaled ~0.5
    "box": (0.26, 0.44),  # small boxes: the lid's sweep stays reachable
    "safe": (0.3, 0.6),
    "oven": (0.5, 0.7),  # built-in ovens 0.6 wide
    "microwave": (0.45, 0.55),
    "dishwasher": (0.6, 0.85),
    "washing_machine": (0.6, 0.85),
    "trash_can": (0.3, 0.7),
    "kitchen_pot": (0.2, 0.35),
    "laptop": (0.3, 0.4),
    "suitcase": (0.4, 0.7),
}
DEFAULT_SIZE = (0.3, 0.6)
FIT_MEMORY = 64  # folders whose fit is remembered


@dataclass(frozen=True)
class Fit:
    """Scale and front distance of an object, and how the rule got there."""

    scale: float
    front_distance: float
    category_scale: float  # the scale of step 1 alone
    note: str
    lift: float = 0.0  # m the object's bottom stands above the floor (step 3)


def category_size(category: str) -> float:
    low, high = CATEGORY_SIZES.get(category, DEFAULT_SIZE)
    return 0.5 * (low + high)


def fit_object(info: ObjectFolder, scale: float | None = None) -> Fit:
    """The scale (``scale`` if given) and front distance of a real folder (module docstring);
    remembered per folder, URDF modification time and scale (resets on one object repeat it)."""
    key = (info.folder.resolve(), info.urdf.stat().st_mtime_ns, scale)
    if key not in _FITS:
        if len(_FITS) >= FIT_MEMORY:
            _FITS.clear()
        _FITS[key] = _fit(info, scale)
    return _FITS[key]


def _fit(info: ObjectFolder, scale: float | None) -> Fit:
    kin = _Kinematics(info)
    rest = kin.points(kin.rest)
    lo, hi = rest.min(axis=0), rest.max(axis=0)
    anchor = np.array([lo[0], 0.5 * (lo[1] + hi[1]), lo[2]])  # loader.place's anchor: front, centre, bottom
    half_open = kin.points({j.name: 0.5 * (j.lower + j.upper) for j in info.movable_joints}) - anchor
    swept = kin.swept_movable() - anchor
    category_scale = category_size(info.category) / max(float((hi - lo).max()), 1e-9)

    def front(s: float) -> float:
        return max(DEFAULT_FRONT_DISTANCE, HOME_CLEARANCE - s * float(half_open[:, 0].min(initial=0.0)))

    low_bound = WORKSPACE_CENTER - WORKSPACE_HALF_EXTENT + WORKSPACE_MARGIN
    high_bound = WORKSPACE_CENTER + WORKSPACE_HALF_EXTENT - WORKSPACE_MARGIN

    def lift(s: float) -> float:
        return max(0.0, -s * float(swept[:, 2].min(initial=0.0)))

    def inside(s: float) -> bool:
        world = s * swept + np.array([front(s), 0.0, lift(s)])
        return bool(np.all(world >= low_bound) and np.all(world <= high_bound))

    def fit(s: float, note: str) -> Fit:
        return Fit(float(s), front(s), category_scale, note, lift(s))

    if scale is not None:
        return fit(scale, "scale given" + ("" if inside(scale) else "; some moving part leaves the workspace cube"))
    if inside(category_scale):
        return fit(category_scale, f"{info.category} size {category_size(info.category):.2f} m")
    low, high = 0.0, category_scale
    for _ in range(30):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if inside(mid) else (low, mid)
    return fit(low, f"shrunk from {category_scale:.3f} to {low:.3f}: a moving part left the workspace cube")


_FITS: dict[tuple, Fit] = {}


class _Kinematics:
    """Forward kinematics of an object folder's links, on its collision hull vertices."""

    def __init__(self, info: ObjectFolder):
        self.info = info
        self.by_child = {j.child: j for j in info.joints}
        self.rest = {j.name: float(np.clip(0.0, j.lower, j.upper)) for j in info.movable_joints}
        self.local = {}
        for link, meshes in info.collisions.items():
            pieces = []
            for m in meshes:
                if m.path is None:
                    v = m.points
                else:
                    try:
                        mesh = read_mesh(m.path)
                    except (OSError, ValueError) as error:
                        raise ObjectLoadError(f"{info.urdf}: link {link!r}: cannot read collision mesh {m.path} ({error})") from None
                    if len(mesh.vertices) == 0:
                        continue
                    v = convex_hull(mesh).vertices if len(mesh.vertices) >= 4 else mesh.vertices
                pieces.append((v * m.scale) @ m.origin[:3, :3].T + m.origin[:3, 3])
            if pieces:
                self.local[link] = np.concatenate(pieces)
        if not self.local:
            raise ObjectLoadError(f"{info.urdf}: no link has collision geometry")

    def link_pose(self, link: str, q: dict[str, float]) -> np.ndarray:
        T = np.eye(4)
        while link in self.by_child:
            joint = self.by_child[link]
            T = joint.origin @ joint.motion(q.get(joint.name, 0.0)) @ T
            link = joint.parent
        return T

    def points(self, q: dict[str, float], links: set[str] | None = None) -> np.ndarray:
        q = {**self.rest, **q}
        chosen = [name for name in self.local if links is None or name in links]
        return np.concatenate([self.local[name] @ self.link_pose(name, q)[:3, :3].T + self.link_pose(name, q)[:3, 3]
                               for name in chosen])

    def subtree(self, link: str) -> set[str]:
        out, todo = set(), [link]
        while todo:
            name = todo.pop()
            out.add(name)
            todo += [j.child for j in self.info.joints if j.parent == name]
        return out

    def swept_movable(self) -> np.ndarray:
        """Every movable link's points over its joint's range (others at rest)."""
        clouds = []
        for joint in self.info.movable_joints:
            links = self.subtree(joint.child) & set(self.local)
            if not links:
                continue
            for q in np.linspace(joint.lower, joint.upper, SWEEP_SAMPLES):
                clouds.append(self.points({joint.name: float(q)}, links))
        return np.concatenate(clouds) if clouds else np.zeros((0, 3))
