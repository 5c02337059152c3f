"""PartNet-Mobility object folders: read and check one before SAPIEN sees it.

A user's folder (``mobility.urdf``, ``meta.json``, ``semantics.txt``, ``textured_objs/*.obj``)
is read here with the standard library only, so every problem becomes an
:class:`ObjectLoadError` that names the file and the reason (SAPIEN's loader would skip a
missing mesh silently, or abort the process on a malformed URDF):

* the folder, its ``mobility.urdf`` and every mesh a ``<visual>`` or ``<collision>`` names
  must exist; the URDF must be well-formed XML with one tree of links, joints of a supported
  type (``revolute``, ``continuous``, ``prismatic``, ``fixed``) with numeric origins, axes
  and limits (``lower <= upper``; negative and ``-0.0`` limits are ordinary numbers), and at
  least one movable joint;
* objects are keyed by their folder name (``meta.json``'s ``anno_id`` is not always it);
* ``meta.json``'s ``model_cat`` (CamelCase, ``StorageFurniture``) becomes the catalogue's
  snake_case name (``storage_furniture``), which the physics table and the size table use;
* ``continuous`` joints (revolutes without limits: knobs) stay unlimited in physics and are
  reported with the reference range :data:`CONTINUOUS_RANGE` (one full turn, -pi..pi), so
  "moved by more than 30% of its range" means a turn of more than 108 deg, and a
  ``dof_fraction`` places the knob within that turn.

Folders written by the generator (:mod:`.catalog`) have the same layout; their meta.json
carries ``format_version`` and they are built at their real size (scale 1).
"""
from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import ObjectLoadError
from .model import read_meta, read_semantics

URDF_NAME = "mobility.urdf"
MOVABLE_TYPES = ("revolute", "continuous", "prismatic")
JOINT_TYPES = MOVABLE_TYPES + ("fixed",)
CONTINUOUS_RANGE = (-np.pi, np.pi)  # reported range of a continuous joint: one full turn


@dataclass(frozen=True)
class CollisionMesh:
    """One ``<collision>`` of a link: a mesh file (``path``) or a primitive (box, cylinder,
    sphere: ``path`` None, ``points`` on its surface), its pose in the link frame and scale."""

    path: Path | None
    origin: np.ndarray  # 4x4
    scale: np.ndarray  # 3 (the URDF's <mesh scale>)
    points: np.ndarray | None = None  # primitives: corner / rim points in the collision frame


@dataclass(frozen=True)
class JointSpec:
    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray  # 4x4, child joint frame in the parent link frame
    axis: np.ndarray  # unit vector in the joint frame
    lower: float  # reported limits (CONTINUOUS_RANGE for continuous joints)
    upper: float

    @property
    def movable(self) -> bool:
        return self.type in MOVABLE_TYPES

    def motion(self, q: float) -> np.ndarray:
        """4x4 motion of the child at joint position ``q`` (rotation about or slide along the axis)."""
        T = np.eye(4)
        if self.type in ("revolute", "continuous"):
            from scipy.spatial.transform import Rotation

            T[:3, :3] = Rotation.from_rotvec(self.axis * q).as_matrix()
        elif self.type == "prismatic":
            T[:3, 3] = self.axis * q
        return T


@dataclass(frozen=True)
class ObjectFolder:
    """What a checked folder holds: its joints (URDF order), links' collision meshes, labels."""

    folder: Path
    object_id: str
    category: str
    generated: bool
    root_link: str
    joints: list[JointSpec]
    collisions: dict[str, list[CollisionMesh]]
    semantics: dict[str, str] = field(default_factory=dict)

    @property
    def urdf(self) -> Path:
        return self.folder / URDF_NAME

    @property
    def movable_joints(self) -> list[JointSpec]:
        return [j for j in self.joints if j.movable]

    def collision_mesh_files(self) -> list[Path]:
        """Every distinct collision mesh file, in URDF order."""
        return list(dict.fromkeys(m.path for meshes in self.collisions.values() for m in meshes if m.path is not None))


def category_name(model_cat: str) -> str:
    """The catalogue's name of a meta.json ``model_cat``: ``StorageFurniture`` -> ``storage_furniture``,
    ``TrashCan`` -> ``trash_can``, ``USB`` -> ``usb``; snake_case names are kept."""
    words = re.sub(r"([a-z0-9])([A-Z])", r"\1_\2", model_cat.strip())
    words = re.sub(r"([A-Z]+)([A-Z][a-z])", r"\1_\2", words)
    return re.sub(r"[^a-z0-9]+", "_", words.lower()).strip("_") or "unknown"


def read_object_folder(folder: Path) -> ObjectFolder:
    """Read and check ``folder`` (module docstring); raises ObjectLoadError naming file and reason."""
    folder = Path(folder).expanduser()
    if not folder.exists():
        raise ObjectLoadError(f"{folder}: no such object folder (expected a PartNet-Mobility folder with {URDF_NAME})")
    if not folder.is_dir():
        raise ObjectLoadError(f"{folder}: not a folder (expected a PartNet-Mobility object folder)")
    urdf = folder / URDF_NAME
    if not urdf.is_file():
        raise ObjectLoadError(f"{folder} is not a PartNet-Mobility style object folder: no {URDF_NAME}")
    try:
        root = ET.parse(urdf).getroot()
    except ET.ParseError as error:
        raise ObjectLoadError(f"{urdf}: malformed URDF (not well-formed XML: {error})") from None
    if root.tag != "robot":
        raise ObjectLoadError(f"{urdf}: malformed URDF: the root element is <{root.tag}>, not <robot>")
    try:
        meta = read_meta(folder)
    except ValueError as error:  # json.JSONDecodeError
        raise ObjectLoadError(f"{folder / 'meta.json'}: not valid JSON ({error})") from None
    links = [link.get("name") for link in root.findall("link")]
    if not links or None in links or len(set(links)) != len(links):
        raise ObjectLoadError(f"{urdf}: malformed URDF: every <link> needs a unique name (got {links})")
    joints = [_joint(urdf, j, set(links)) for j in root.findall("joint")]
    children = [j.child for j in joints]
    if len(set(children)) != len(children):
        raise ObjectLoadError(f"{urdf}: malformed URDF: a link is the child of two joints")
    roots = [name for name in links if name not in children]
    if len(roots) != 1:
        raise ObjectLoadError(f"{urdf}: malformed URDF: expected one root link (a link no joint moves), got {roots}")
    if not any(j.movable for j in joints):
        raise ObjectLoadError(f"{urdf}: the object has no movable joint (revolute, continuous or prismatic)")
    collisions = {}
    for link in root.findall("link"):
        for visual in link.findall("visual"):
            _mesh_path(urdf, link.get("name"), visual)  # checked: SAPIEN renders them
        collisions[link.get("name")] = [m for m in (_collision(urdf, link.get("name"), c) for c in link.findall("collision")) if m]
    return ObjectFolder(folder, folder.name, category_name(str(meta.get("model_cat", "unknown"))),
                        "format_version" in meta, roots[0], joints, collisions, read_semantics(folder))


def _floats(urdf: Path, element: ET.Element, attribute: str, default: str, count: int) -> np.ndarray:
    text = element.get(attribute, default)
    try:
        values = np.array([float(v) for v in text.split()], dtype=float)
    except ValueError:
        values = np.array([])
    if len(values) != count or not np.all(np.isfinite(values)):
        raise ObjectLoadError(f"{urdf}: malformed URDF: <{element.tag} {attribute}=\"{text}\"> needs {count} finite numbers")
    return values


def _origin(urdf: Path, element: ET.Element | None) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    origin = element.find("origin") if element is not None else None
    T = np.eye(4)
    if origin is not None:
        T[:3, :3] = Rotation.from_euler("xyz", _floats(urdf, origin, "rpy", "0 0 0", 3)).as_matrix()
        T[:3, 3] = _floats(urdf, origin, "xyz", "0 0 0", 3)
    return T


def _joint(urdf: Path, j: ET.Element, links: set[str]) -> JointSpec:
    name, kind = j.get("name"), j.get("type")
    if kind not in JOINT_TYPES:
        raise ObjectLoadError(f"{urdf}: joint {name!r} has type {kind!r}; supported: {', '.join(JOINT_TYPES)}")
    ends = []
    for tag in ("parent", "child"):
        element = j.find(tag)
        link = element.get("link") if element is not None else None
        if link not in links:
            raise ObjectLoadError(f"{urdf}: joint {name!r}: <{tag} link=\"{link}\"> is not a link of this URDF")
        ends.append(link)
    axis_element = j.find("axis")
    axis = _floats(urdf, axis_element, "xyz", "1 0 0", 3) if axis_element is not None else np.array([1.0, 0.0, 0.0])
    lower = upper = 0.0
    if kind in MOVABLE_TYPES:
        if np.linalg.norm(axis) < 1e-9:
            raise ObjectLoadError(f"{urdf}: joint {name!r} has a zero axis")
        axis = axis / np.linalg.norm(axis)
    if kind == "continuous":
        lower, upper = CONTINUOUS_RANGE
    elif kind in ("revolute", "prismatic"):
        limit = j.find("limit")
        if limit is None:
            raise ObjectLoadError(f"{urdf}: joint {name!r} ({kind}) has no <limit> (a {kind} joint needs lower and upper)")
        lower, upper = (float(_floats(urdf, limit, key, "0", 1)[0]) for key in ("lower", "upper"))
        if lower > upper:
            raise ObjectLoadError(f"{urdf}: joint {name!r} has lower limit {lower} above its upper limit {upper}")
    return JointSpec(name, kind, ends[0], ends[1], _origin(urdf, j), axis, lower + 0.0, upper + 0.0)  # + 0.0: -0.0 -> 0.0


def _mesh_path(urdf: Path, link: str, element: ET.Element) -> tuple[Path, np.ndarray] | None:
    mesh = element.find("geometry/mesh")
    if mesh is None:
        return None
    filename = mesh.get("filename", "")
    path = Path(filename[len("package://"):] if filename.startswith("package://") else filename)
    path = path if path.is_absolute() else urdf.parent / path
    if not filename or not path.is_file():
        raise ObjectLoadError(f"{urdf}: link {link!r} names mesh {filename!r}, which does not exist ({path})")
    return path, _floats(urdf, mesh, "scale", "1 1 1", 3)


def _collision(urdf: Path, link: str, element: ET.Element) -> CollisionMesh | None:
    found = _mesh_path(urdf, link, element)
    if found is not None:
        return CollisionMesh(found[0], _origin(urdf, element), found[1])
    points = _primitive_points(urdf, element.find("geometry"))
    return None if points is None else CollisionMesh(None, _origin(urdf, element), np.ones(3), points)


def _primitive_points(urdf: Path, geometry: ET.Element | None) -> np.ndarray | None:
    """Points spanning a box, cylinder (axis z) or sphere: enough for bounding boxes."""
    if geometry is None:
        return None
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    if (box := geometry.find("box")) is not None:
        return corners * _floats(urdf, box, "size", "", 3) / 2
    if (cylinder := geometry.find("cylinder")) is not None:
        radius, length = (float(_floats(urdf, cylinder, key, "", 1)[0]) for key in ("radius", "length"))
        return corners * np.array([radius, radius, length / 2])
    if (sphere := geometry.find("sphere")) is not None:
        return corners * float(_floats(urdf, sphere, "radius", "", 1)[0])
    return None
