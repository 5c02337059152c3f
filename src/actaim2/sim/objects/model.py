"""An articulated object as plain data, written out in PartNet-Mobility layout.

Generated objects are described by :class:`ObjectModel` (links made of boxes, cylinders and
convex mesh pieces, each of a material; joints with limits, friction and damping; handle
annotations) and written to a folder with the same layout as a PartNet-Mobility object
(``mobility.urdf``, ``semantics.txt``, ``meta.json``, ``textured_objs/*.obj`` meshes). Every
movable link gets an ``<inertial>`` from its shapes' volumes and materials' densities
(:mod:`.mass`, :mod:`.physics_table`). Mesh pieces (handle bends, knob caps) are convex, one
OBJ each, so a collision hull per file is exact: a bar on standoffs stays a bar with an
empty gap behind it, never a filled block. The simulator then loads every object, generated
or user-supplied, through one path: SAPIEN's URDF loader on that folder.

``handles.json`` is this project's addition to the layout: where each movable part can be
grasped (privileged information for the scripted expert, never a policy input). Objects
without it can still be simulated, only not driven by the expert.

Object frame convention: z up, the object's front faces -x, origin at the centre of its
footprint on the floor. Folders from elsewhere are assumed to face -x too (as PartNet-Mobility
objects are commonly loaded with SAPIEN); one facing another way is turned with the loader's
``yaw``.
"""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from .mass import link_mass_properties
from .physics_table import MATERIALS
from .shapes import Shape, Vec3, shape_mesh

# Version of the generator's output: bump it to invalidate cached object folders.
FORMAT_VERSION = 16


@dataclass
class Link:
    """A rigid part; ``material`` is its shapes' default material ("" = no inertial written:
    the fixed base, whose mass never moves)."""

    name: str
    shapes: list[Shape] = field(default_factory=list)
    material: str = ""


@dataclass(frozen=True)
class Joint:
    """A URDF joint. Movable joints open towards ``upper`` (``lower`` is the closed state)."""

    name: str
    type: str  # "fixed" | "revolute" | "prismatic"
    parent: str
    child: str
    xyz: Vec3
    axis: Vec3 = (1.0, 0.0, 0.0)
    lower: float = 0.0
    upper: float = 0.0
    damping: float = 0.0
    friction: float = 0.0
    semantic: str = ""  # PartNet-Mobility part label: drawer, door, lid, lever, toggle, ...


@dataclass(frozen=True)
class Handle:
    """A grasp on a movable part, in the part's link frame.

    ``position`` is where the canonical TCP (between the fingertips) goes, ``approach`` the
    TCP z axis (the direction the gripper moves in), ``closing`` the TCP y axis (the finger
    closing direction); the gripper is symmetric, so -closing is as good. ``depth`` is how far
    the surface the handle is mounted on lies beyond ``position`` along ``approach``, ``span``
    the handle's extent along the TCP x axis (where a hand pushing the part must stay clear).
    """

    link: str
    joint: str
    kind: str
    position: Vec3
    approach: Vec3
    closing: Vec3
    depth: float = 0.0
    span: float = 0.0

    def tcp_in_link(self) -> np.ndarray:
        """4x4 pose of the TCP in the link frame when grasping this handle."""
        z = np.asarray(self.approach, dtype=float)
        y = np.asarray(self.closing, dtype=float)
        z /= np.linalg.norm(z)
        y = y - z * (y @ z)
        y /= np.linalg.norm(y)
        T = np.eye(4)
        T[:3, 0] = np.cross(y, z)
        T[:3, 1] = y
        T[:3, 2] = z
        T[:3, 3] = self.position
        return T


@dataclass
class ObjectModel:
    """One generated articulated object: ``base`` is its root link, fixed to the world."""

    object_id: str
    category: str
    links: list[Link]
    joints: list[Joint]
    handles: list[Handle]
    params: dict = field(default_factory=dict)

    def movable_joints(self) -> list[Joint]:
        return [j for j in self.joints if j.type != "fixed"]

    def to_urdf(self, mesh_files: dict[tuple[str, int], str] | None = None) -> str:
        """URDF text; shapes listed in ``mesh_files`` reference that OBJ file instead of a primitive
        (``mesh`` shapes, having no primitive, always reference theirs: :func:`mesh_path`)."""
        lines = ['<?xml version="1.0"?>', f"<robot name={quoteattr(self.object_id)}>"]
        for link in self.links:
            lines.append(f'  <link name="{link.name}">')
            if link.material:
                lines.append(_inertial_xml(link))
            for i, s in enumerate(link.shapes):
                mesh = mesh_files.get((link.name, i)) if mesh_files else None
                if mesh is None and s.kind == "mesh":
                    mesh = mesh_path(link.name, i)
                geometry = _geometry_xml(s, mesh)
                origin = f'<origin xyz="{_fmt(s.xyz if mesh is None else (0, 0, 0))}" rpy="{_fmt(s.rpy if mesh is None else (0, 0, 0))}"/>'
                lines.append(
                    f'    <visual name="{link.name}-{i}">{origin}{geometry}'
                    f'<material name="{link.name}-{i}"><color rgba="{_fmt(s.rgba)}"/></material></visual>'
                )
                lines.append(f"    <collision>{origin}{geometry}</collision>")
            lines.append("  </link>")
        for j in self.joints:
            lines.append(f'  <joint name="{j.name}" type="{j.type}">')
            lines.append(f'    <parent link="{j.parent}"/><child link="{j.child}"/>')
            lines.append(f'    <origin xyz="{_fmt(j.xyz)}" rpy="0 0 0"/>')
            if j.type != "fixed":
                lines.append(f'    <axis xyz="{_fmt(j.axis)}"/>')
                lines.append(f'    <limit lower="{j.lower:.6g}" upper="{j.upper:.6g}" effort="1000" velocity="10"/>')
                lines.append(f'    <dynamics damping="{j.damping:.6g}" friction="{j.friction:.6g}"/>')
            lines.append("  </joint>")
        lines.append("</robot>")
        return "\n".join(lines) + "\n"

    def write_folder(self, folder: Path, meshes: bool = False) -> Path:
        """Write the PartNet-Mobility layout into ``folder``; ``meshes`` writes every shape as an
        OBJ (mesh pieces always are)."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        mesh_files = {}
        for link in self.links:
            for i, s in enumerate(link.shapes):
                if meshes or s.kind == "mesh":
                    rel = mesh_path(link.name, i)
                    (folder / "textured_objs").mkdir(exist_ok=True)
                    _write_obj(folder / rel, *shape_mesh(s))
                    mesh_files[(link.name, i)] = rel
        (folder / "mobility.urdf").write_text(self.to_urdf(mesh_files))
        semantics = []
        for j in self.joints:
            kind = {"revolute": "hinge", "prismatic": "slider"}.get(j.type, "static")
            semantics.append(f"{j.child} {kind} {j.semantic or 'body'}")
        (folder / "semantics.txt").write_text("\n".join(semantics) + "\n")
        meta = {"model_cat": self.category, "anno_id": self.object_id, "format_version": FORMAT_VERSION, "params": self.params}
        (folder / "meta.json").write_text(json.dumps(meta, indent=1, default=float) + "\n")
        (folder / "handles.json").write_text(json.dumps({"handles": [asdict(h) for h in self.handles]}, indent=1) + "\n")
        return folder


def mesh_path(link: str, index: int) -> str:
    """Where a folder keeps the OBJ of a link's ``index``-th shape (relative to the folder)."""
    return f"textured_objs/{link}-{index}.obj"


def read_handles(folder: Path) -> list[Handle]:
    """Handle annotations of an object folder ([] when it has none, e.g. a real PartNet object)."""
    path = Path(folder) / "handles.json"
    if not path.is_file():
        return []
    return [Handle(**{k: tuple(v) if isinstance(v, list) else v for k, v in h.items()}) for h in json.loads(path.read_text())["handles"]]


def read_semantics(folder: Path) -> dict[str, str]:
    """Part label of each link from ``semantics.txt`` (``link joint_kind label`` per line); {} without one."""
    path = Path(folder) / "semantics.txt"
    if not path.is_file():
        return {}
    out = {}
    for line in path.read_text().splitlines():
        words = line.split()
        if len(words) >= 3:
            out[words[0]] = words[2]
    return out


def read_meta(folder: Path) -> dict:
    path = Path(folder) / "meta.json"
    return json.loads(path.read_text()) if path.is_file() else {}


def _fmt(values) -> str:
    return " ".join(f"{float(v):.6g}" for v in values)


def _inertial_xml(link: Link) -> str:
    """``<inertial>`` of a link from its shapes' volumes and materials."""
    densities = [MATERIALS[s.material or link.material].density for s in link.shapes]
    mass, com, inertia = link_mass_properties(link.shapes, densities)
    return (f'    <inertial><origin xyz="{_fmt(com)}" rpy="0 0 0"/><mass value="{mass:.6g}"/>'
            f'<inertia ixx="{inertia[0, 0]:.6g}" ixy="{inertia[0, 1]:.6g}" ixz="{inertia[0, 2]:.6g}" iyy="{inertia[1, 1]:.6g}" '
            f'iyz="{inertia[1, 2]:.6g}" izz="{inertia[2, 2]:.6g}"/></inertial>')


def _geometry_xml(s: Shape, mesh: str | None) -> str:
    if mesh is not None:
        return f'<geometry><mesh filename="{mesh}"/></geometry>'
    if s.kind == "box":
        return f'<geometry><box size="{_fmt(s.size)}"/></geometry>'
    if s.kind == "cylinder":
        return f'<geometry><cylinder radius="{s.size[0]:.6g}" length="{s.size[1]:.6g}"/></geometry>'
    raise ValueError(f"unknown shape kind {s.kind!r}")


def _write_obj(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    text = "".join(f"v {x:.6g} {y:.6g} {z:.6g}\n" for x, y, z in vertices)
    text += "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces)
    path.write_text(text)
