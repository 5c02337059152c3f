"""Objects for the loader tests: the five real PartNet-Mobility objects of ``../shared/partnet``
(beside the repository, as CI lays it out) with the facts of their README, and a small
hand-made folder in the same format (a U-handle to decompose, a continuous knob, "-0.0" and
negative limits) plus broken copies of it."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from actaim2.sim.objects.mesh import Mesh, write_obj

REPO = Path(__file__).resolve().parents[2]
SHARED_PARTNET = REPO.parent / "shared" / "partnet"

# folder -> (catalogue category, movable joints: name -> (type, lower, upper)); from ../shared/partnet/README.md
OBJECTS: dict[str, tuple[str, dict[str, tuple[str, float, float]]]] = {
    "45780": ("storage_furniture", {"joint_0": ("revolute", 0.0, 1.6399), "joint_1": ("revolute", 0.0, 1.6399)}),
    "1053": ("faucet", {"joint_0": ("revolute", -1.5708, 1.5708)}),
    "22241": ("table", {"joint_0": ("prismatic", 0.0, 0.696)}),
    "102456": ("box", {"joint_0": ("revolute", -0.7854, 2.0944)}),
    "101773": ("oven", {"joint_0": ("revolute", 0.0, 1.5708),
                        **{f"joint_{k}": ("continuous", -np.pi, np.pi) for k in (1, 2, 3)},
                        **{f"joint_{k}": ("prismatic", 0.0, 0.008) for k in (4, 5, 6, 7, 8)}}),
}


def urdf_limits(joints: dict[str, tuple[str, float, float]], scale: float) -> tuple[list[float], list[float]]:
    """The limits the simulator reports: prismatic ones scaled with the object (metres)."""
    k = [scale if kind == "prismatic" else 1.0 for kind, _, _ in joints.values()]
    return [j[1] * f for j, f in zip(joints.values(), k)], [j[2] * f for j, f in zip(joints.values(), k)]


def shared_partnet() -> Path:
    """The shared objects' folder; skips the test (saying why) only where it is missing."""
    if not all((SHARED_PARTNET / name / "mobility.urdf").is_file() for name in OBJECTS):
        pytest.skip(f"the shared PartNet-Mobility objects are not at {SHARED_PARTNET} (CI clones the repository next to shared/)")
    return SHARED_PARTNET


def box(lo, hi) -> Mesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return Mesh(v, f)


def merged(*parts: Mesh) -> Mesh:
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts[:-1]])
    return Mesh(np.concatenate([p.vertices for p in parts]), np.concatenate([p.faces + o for p, o in zip(parts, offsets)]))


# The hand-made object (object frame: front towards -x, z up): a cabinet body, a door hinged at
# its front left edge whose U-handle (a bar on two standoffs, one mesh) stands 0.06 in front of it.
BAR_GAP_POINT = np.array([-0.05, 0.15, 0.5])  # in the door link frame: between bar and panel, between the standoffs
HANDLE = merged(box((-0.08, 0.13, 0.35), (-0.06, 0.17, 0.65)),  # the bar
                box((-0.06, 0.13, 0.35), (-0.02, 0.17, 0.38)), box((-0.06, 0.13, 0.62), (-0.02, 0.17, 0.65)))
URDF = """<?xml version="1.0"?>
<robot name="handmade">
  <link name="base"/>
  <link name="link_body"><collision><geometry><mesh filename="textured_objs/body.obj"/></geometry></collision>
    <visual><geometry><mesh filename="textured_objs/body.obj"/></geometry></visual></link>
  <link name="link_door">
    <collision><geometry><mesh filename="textured_objs/door.obj"/></geometry></collision>
    <collision><geometry><mesh filename="textured_objs/handle.obj"/></geometry></collision></link>
  <link name="link_knob"><collision><geometry><mesh filename="textured_objs/knob.obj"/></geometry></collision></link>
  <link name="link_slide"><collision><geometry><mesh filename="textured_objs/slide.obj"/></geometry></collision></link>
  <joint name="joint_fixed" type="fixed"><parent link="base"/><child link="link_body"/><origin xyz="0 0 0" rpy="0 0 0"/></joint>
  <joint name="joint_door" type="revolute"><parent link="link_body"/><child link="link_door"/>
    <origin xyz="-0.3 -0.4 0"/><axis xyz="0 0 1"/><limit lower="-0.0" upper="1.2"/></joint>
  <joint name="joint_knob" type="continuous"><parent link="link_body"/><child link="link_knob"/>
    <origin xyz="-0.3 0.3 0.9"/><axis xyz="1 0 0"/></joint>
  <joint name="joint_slide" type="prismatic"><parent link="link_body"/><child link="link_slide"/>
    <origin xyz="0 0.2 0.95"/><axis xyz="0 1 0"/><limit lower="-0.3" upper="0.1"/></joint>
</robot>
"""


def make_object(folder: Path, urdf: str = URDF) -> Path:
    (folder / "textured_objs").mkdir(parents=True)
    write_obj(folder / "textured_objs/body.obj", [box((-0.3, -0.4, 0.0), (0.3, 0.4, 1.0))])
    write_obj(folder / "textured_objs/door.obj", [box((-0.02, 0.0, 0.02), (0.0, 0.4, 0.98))])
    write_obj(folder / "textured_objs/handle.obj", [HANDLE])
    write_obj(folder / "textured_objs/knob.obj", [box((-0.02, -0.02, -0.02), (0.0, 0.02, 0.02))])
    write_obj(folder / "textured_objs/slide.obj", [box((-0.1, -0.05, 0.0), (0.1, 0.05, 0.03))])
    (folder / "mobility.urdf").write_text(urdf)
    (folder / "meta.json").write_text('{"model_cat": "StorageFurniture", "anno_id": "123"}')
    (folder / "semantics.txt").write_text("link_door hinge rotation_door\nlink_knob hinge knob\nlink_slide slider drawer\nlink_body heavy body\n")
    return folder


def bad_folders(tmp: Path) -> dict[str, tuple[Path, list[str]]]:
    """name -> (folder, words its error message must contain)."""
    out = {"missing folder": (tmp / "nowhere", ["nowhere", "no such object folder"])}
    empty = tmp / "no_urdf"
    empty.mkdir()
    out["no URDF"] = (empty, ["no_urdf", "mobility.urdf"])
    gone = make_object(tmp / "missing_mesh")
    (gone / "textured_objs/handle.obj").unlink()
    out["missing mesh"] = (gone, ["handle.obj", "does not exist", "link_door"])
    broken = make_object(tmp / "malformed", URDF.replace("</robot>", ""))
    out["malformed URDF"] = (broken, ["mobility.urdf", "malformed"])
    number = make_object(tmp / "bad_number", URDF.replace('upper="1.2"', 'upper="wide"'))
    out["bad limit"] = (number, ["mobility.urdf", "upper", "wide"])
    stuck = make_object(tmp / "no_joint", URDF.replace('type="revolute"', 'type="fixed"').replace('type="continuous"', 'type="fixed"')
                        .replace('type="prismatic"', 'type="fixed"'))
    out["no movable joint"] = (stuck, ["mobility.urdf", "no movable joint"])
    bad_obj = make_object(tmp / "bad_obj")
    (bad_obj / "textured_objs/door.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    out["corrupt mesh"] = (bad_obj, ["door.obj", "does not exist"])
    return out
