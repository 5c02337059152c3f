"""Robot presets: where the URDF is, which joints are arm and gripper, and where `tcp` is.

The canonical TCP frame (DESIGN.md) has its origin between the fingertips, z along the
approach direction and y along the finger closing direction. Every preset maps it onto its
own flange link with a fixed transform ``T_flange_tcp``, so keyposes mean the same thing on
every robot. Simulation (SAPIEN), control (Pinocchio) and perception (self-filter) all read
the robot from here; data collection also reads where the arm reaches and the open hand's
shape (:class:`Reach`, :class:`HandGeometry`) to sample actions this robot can carry out.
"""
from __future__ import annotations

import hashlib
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml


def example_robot_data_dir() -> Path:
    """`share/example-robot-data/robots` inside the installed example-robot-data wheel."""
    import cmeel  # type: ignore[import-not-found]  (the prefix the robot-data wheels install into)

    return Path(cmeel.__file__).resolve().parent.parent / "cmeel.prefix" / "share" / "example-robot-data" / "robots"


@dataclass(frozen=True)
class Reach:
    """Where the tcp can go: a spherical shell around the shoulder (the second joint's origin).

    ``max`` is 0.866 x the largest tcp distance from the shoulder over 20000 random joint
    configurations (Panda: 0.947 m -> 0.82 m, a margin that leaves room for orientation);
    ``min`` keeps targets off the arm folded onto itself.
    """

    center: tuple[float, float, float]  # shoulder, in `world` (the root link frame)
    min: float  # m
    max: float  # m


@dataclass(frozen=True)
class HandGeometry:
    """The open hand as boxes in the canonical `tcp` frame (z approach, y finger closing).

    Samplers see objects only as points, so "would the hand collide here" and "what lies
    between the fingers" are questions about which points fall into which box. Each preset's
    numbers are fitted to its URDF collision meshes with the gripper open (measured in
    tests/data/test_robot_hands.py): two finger boxes at +-y from ``max_opening / 2`` outwards,
    reaching from the tcp back ``finger_length``, and a palm box behind them.
    """

    max_opening: float  # m between the finger boxes' inner faces
    finger_length: float  # along z, back from the tcp
    finger_thickness: float  # along y, each finger
    finger_width: float  # along x
    palm_depth: float  # along z, behind the fingers
    palm_width: float  # along y
    palm_thickness: float  # along x
    approach_distance: float  # m the straight approach runs along z before the tcp reaches p1 (clears the fingers)

    def boxes(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """name -> (min corner, max corner) in the tcp frame, fingers open."""
        half = self.max_opening / 2.0
        fx, px = self.finger_width / 2.0, self.palm_thickness / 2.0
        z_base = -self.finger_length
        return {
            "finger_left": (np.array([-fx, half, z_base]), np.array([fx, half + self.finger_thickness, 0.0])),
            "finger_right": (np.array([-fx, -half - self.finger_thickness, z_base]), np.array([fx, -half, 0.0])),
            "palm": (np.array([-px, -self.palm_width / 2, z_base - self.palm_depth]), np.array([px, self.palm_width / 2, z_base])),
        }

    def hand_extent(self) -> np.ndarray:
        """Half-widths (x, y) and depth behind the tcp (z) of the box holding the whole open hand."""
        half_y = max(self.palm_width / 2, self.max_opening / 2 + self.finger_thickness)
        return np.array([max(self.palm_thickness, self.finger_width) / 2, half_y, self.finger_length + self.palm_depth])

    def closing_region(self) -> tuple[np.ndarray, np.ndarray]:
        """The space swept by the closing fingers: what lies here gets grasped."""
        half, fx = self.max_opening / 2.0, self.finger_width / 2.0
        return np.array([-fx, -half, -self.finger_length]), np.array([fx, half, 0.0])


@dataclass(frozen=True)
class RobotSpec:
    """Everything the project needs to know about one arm + parallel gripper."""

    name: str
    urdf_path: Path
    package_dirs: tuple[Path, ...]
    srdf_path: Path | None
    root_link: str
    arm_joints: tuple[str, ...]
    gripper_joints: tuple[str, ...]
    flange_frame: str
    T_flange_tcp: np.ndarray
    home: np.ndarray
    gripper_open: float  # finger joint position when open (per finger joint)
    gripper_closed: float  # finger joint position when fully closed
    max_velocity: np.ndarray  # rad/s per arm joint
    max_acceleration: np.ndarray  # rad/s^2
    max_jerk: np.ndarray  # rad/s^3
    reach: Reach | None = None  # for sampling actions (data collection); None: not given for this robot
    hand: HandGeometry | None = None
    extra: dict = field(default_factory=dict)
    # N: grip force when a GripperCommand gives none (max_effort 0); None = the URDF's finger
    # effort limit at the pads. Gap widths and forces <-> finger joints: actaim2.gripper.
    gripper_force: float | None = None


def _panda() -> RobotSpec:
    robots = example_robot_data_dir()
    T = np.eye(4)
    T[2, 3] = 0.1034  # panda_hand -> panda_hand_tcp (fingertip centre), same axes as the canonical tcp
    return RobotSpec(
        name="panda",
        urdf_path=robots / "panda_description" / "urdf" / "panda.urdf",
        package_dirs=(robots.parent.parent,),
        srdf_path=robots / "panda_description" / "srdf" / "panda.srdf",
        root_link="panda_link0",
        arm_joints=tuple(f"panda_joint{i}" for i in range(1, 8)),
        gripper_joints=("panda_finger_joint1", "panda_finger_joint2"),
        flange_frame="panda_hand",
        T_flange_tcp=T,
        home=np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4]),
        gripper_open=0.04,
        gripper_closed=0.0,
        # Franka Emika's published joint limits (Panda datasheet / libfranka).
        max_velocity=np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61]),
        max_acceleration=np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]),
        max_jerk=np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0]),
        reach=Reach(center=(0.0, 0.0, 0.333), min=0.3, max=0.82),  # datasheet reach 0.855 m
        # Franka Hand: 80 mm stroke, fingers (collision boxes) from z = -0.045 to the tcp, |y|
        # 0.04..0.066, x +-0.011; a 0.2 m wide hand body behind them (y +-0.104, z -0.129 ..
        # -0.097 between the fingers, its sides forward to -0.037; x +-0.032).
        hand=HandGeometry(max_opening=0.08, finger_length=0.054, finger_thickness=0.026, finger_width=0.022,
                          palm_depth=0.075, palm_width=0.21, palm_thickness=0.07, approach_distance=0.12),
        gripper_force=70.0,  # Franka Hand datasheet: 70 N continuous grasping force (140 N maximum)
    )


def _kinova_j2s6s200() -> RobotSpec:
    """Kinova Jaco2 j2s6s200 (6-DoF spherical wrist, 2 fingers) of example-robot-data.

    Flange and TCP. ``j2s6s200_end_effector`` sits 0.16 m along link_6's -z (the hand's
    approach direction), but its own x axis is the approach axis. The fingers sit at +-y of
    link_6 and close towards y = 0 (positive finger angles close). The canonical tcp is put
    where Panda's ``panda_hand_tcp`` is on its hand: at the centre of the grasping pads, here
    the middle of the distal phalanges when the fingers close on a ~2 cm handle (~1.15 rad),
    which the URDF puts at (-0.0025, 0, -0.18) in link_6, on the fingers' plane. Axes in
    link_6: z_tcp = -z (approach), y_tcp = +y (closing direction, towards finger 1 as Panda's
    y points to its left finger), x_tcp = y x z = -x. Expressed in the end-effector frame
    that is the rotation below (x_tcp = z_ee, y_tcp = -y_ee, z_tcp = x_ee) and the offset
    (0.02, 0, 0.0025).

    Limits. Velocities are the URDF's (0.628 rad/s for joints 1-3, 0.838 for 4-6); the URDF
    has no acceleration or jerk limits, so conservative values are chosen: acceleration
    4 x the velocity limit (full speed in 0.25 s) and jerk 10 x the acceleration (the
    acceleration ramps in 0.1 s), small against Panda's published 7.5-20 rad/s^2.

    Gripper. The finger joints are `fixed` in this URDF (limits 0..1.51 still written);
    :func:`movable_gripper_urdf` makes them revolute for simulation and control. 0 is wide
    open; the fingertips meet at ~1.3 rad, the "closed" command (like Panda's 0 m).

    Home: the tcp 0.35 m in front of the base (+x of `base`) at 0.45 m height, pointing down
    with Panda's home orientation, elbow up (an IK solution, wrist away from its limits).
    Joints 1, 4 and 6 are continuous (Pinocchio: nq = 9 != nv = 6); positions here are angles.
    """
    robots = example_robot_data_dir()
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])
    T[:3, 3] = [0.02, 0.0, 0.0025]
    max_velocity = np.array([0.628318530718] * 3 + [0.837758040957] * 3)
    return RobotSpec(
        name="kinova_j2s6s200",
        urdf_path=robots / "kinova_description" / "robots" / "kinova.urdf",
        package_dirs=(robots.parent.parent,),
        srdf_path=robots / "kinova_description" / "srdf" / "kinova.srdf",
        root_link="base",
        arm_joints=tuple(f"j2s6s200_joint_{i}" for i in range(1, 7)),
        gripper_joints=("j2s6s200_joint_finger_1", "j2s6s200_joint_finger_2"),
        flange_frame="j2s6s200_end_effector",
        T_flange_tcp=T,
        home=np.array([-1.5426, 3.2403, 1.8317, 0.0, 4.8746, 0.0282]),
        gripper_open=0.0,
        gripper_closed=1.3,
        max_velocity=max_velocity,
        max_acceleration=4.0 * max_velocity,
        max_jerk=40.0 * max_velocity,
        reach=Reach(center=(0.0, 0.0, 0.2755), min=0.3, max=0.87),  # tcp at most 1.006 m from the shoulder
        # Open (0 rad) the fingers splay: the distal phalanges' inner faces at |y| >= 0.061 m, the
        # proximal ones' at 0.024 m where they leave the hand (z = -0.06, where the hand body
        # starts: the palm box) and 0.04 m halfway; out to |y| = 0.106, x +-0.0115, forward to
        # z = -0.018 (closing swings them to the tcp). Hand body (link_6): z -0.18..-0.06,
        # y +-0.054, x -0.034..0.029; the palm box also holds the proximal phalanges' roots.
        # Longer fingers than Panda's: the straight approach starts 0.03 m further back.
        hand=HandGeometry(max_opening=0.08, finger_length=0.06, finger_thickness=0.066, finger_width=0.023,
                          palm_depth=0.12, palm_width=0.15, palm_thickness=0.068, approach_distance=0.15),
    )


PRESETS = {"panda": _panda, "kinova_j2s6s200": _kinova_j2s6s200}


def resolve_package_uri(uri: str, package_dirs: tuple[Path, ...], urdf_dir: Path) -> str:
    """Absolute path of a URDF mesh reference (``package://pkg/rel`` or a relative path)."""
    if uri.startswith("package://"):
        rel = uri[len("package://"):]
        for base in package_dirs:
            if (base / rel).exists():
                return str((base / rel).resolve())
        raise FileNotFoundError(f"{uri} not found under {[str(p) for p in package_dirs]}")
    if uri.startswith("file://"):
        return uri[len("file://"):]
    return str((urdf_dir / uri).resolve())


def movable_gripper_urdf(spec: RobotSpec, cache_dir: Path | None = None) -> Path:
    """The robot's URDF with movable gripper joints and absolute mesh paths, written once.

    Some published URDFs (example-robot-data's Kinova) declare the finger joints `fixed`
    although they move: simulation must actuate them and control must know where the
    fingers are. Each gripper joint declared `fixed` becomes `revolute` with the `<limit>`
    the URDF already writes for it. Mesh references (``package://``, relative) become
    absolute file paths, so SAPIEN, Pinocchio and Open3D load the file without package
    resolution. Written once per content (:func:`write_cached_urdf`).
    """
    root = ET.parse(spec.urdf_path).getroot()
    for joint in root.findall("joint"):
        if joint.get("name") in spec.gripper_joints and joint.get("type") == "fixed":
            limit = joint.find("limit")
            if limit is None or float(limit.get("upper", 0.0)) <= float(limit.get("lower", 0.0)):
                raise ValueError(f"{spec.urdf_path}: fixed gripper joint {joint.get('name')} has no usable <limit>")
            joint.set("type", "revolute")
    for mesh in root.iter("mesh"):
        mesh.set("filename", resolve_package_uri(mesh.get("filename", ""), spec.package_dirs, spec.urdf_path.parent))
    return write_cached_urdf(root, spec.name, cache_dir)


def write_cached_urdf(root: ET.Element, stem: str, cache_dir: Path | None = None) -> Path:
    """Write a rewritten URDF once, named by its content: ``<cache_dir>/<stem>-<hash>.urdf``
    (default cache ``$XDG_CACHE_HOME/actaim2/urdf``), atomically, so concurrent processes
    writing the same content share one file and never read a half-written one."""
    text = '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode")
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    if cache_dir is None:
        cache_dir = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "actaim2" / "urdf"
    path = Path(cache_dir) / f"{stem}-{digest}.urdf"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text)
        os.replace(tmp, path)
    return path


def load_robot_spec(name_or_yaml: str) -> RobotSpec:
    """A preset by name, or any URDF described by a YAML file.

    YAML keys (paths relative to the YAML file): ``urdf``, optional ``srdf`` and
    ``package_dirs``, ``root_link``, ``arm_joints``, ``gripper_joints``, ``flange_frame``,
    ``tcp_offset_xyz`` and ``tcp_offset_quat_xyzw`` (T_flange_tcp), ``gripper_open``,
    ``gripper_closed``, optional ``home``, ``name`` and limits. Missing velocity limits are
    the URDF's; missing acceleration and jerk limits follow the conservative rule of the
    Kinova preset (4 x and 40 x the velocity limit). Data collection also needs ``reach``
    ({center, min, max}) and ``hand`` (the :class:`HandGeometry` fields); a robot without
    them can be simulated and controlled but not sampled for."""
    if name_or_yaml in PRESETS:
        return PRESETS[name_or_yaml]()
    path = Path(name_or_yaml)
    if not path.is_file():
        raise ValueError(f"unknown robot '{name_or_yaml}': presets are {sorted(PRESETS)}, or give a YAML file path")
    cfg = yaml.safe_load(path.read_text())
    base = path.parent
    T = np.eye(4)
    T[:3, 3] = cfg.get("tcp_offset_xyz", [0.0, 0.0, 0.0])
    if "tcp_offset_quat_xyzw" in cfg:
        from scipy.spatial.transform import Rotation

        T[:3, :3] = Rotation.from_quat(cfg["tcp_offset_quat_xyzw"]).as_matrix()
    n = len(cfg["arm_joints"])
    urdf_path = (base / cfg["urdf"]).resolve()
    velocity = np.asarray(cfg["max_velocity"] if "max_velocity" in cfg else _urdf_velocity_limits(urdf_path, cfg["arm_joints"]), dtype=float)
    return RobotSpec(
        name=cfg.get("name", path.stem),
        urdf_path=urdf_path,
        package_dirs=tuple((base / p).resolve() for p in cfg.get("package_dirs", ["."])),
        srdf_path=(base / cfg["srdf"]).resolve() if cfg.get("srdf") else None,
        root_link=cfg["root_link"],
        arm_joints=tuple(cfg["arm_joints"]),
        gripper_joints=tuple(cfg["gripper_joints"]),
        flange_frame=cfg["flange_frame"],
        T_flange_tcp=T,
        home=np.asarray(cfg.get("home", [0.0] * n), dtype=float),
        gripper_open=float(cfg["gripper_open"]),
        gripper_closed=float(cfg["gripper_closed"]),
        max_velocity=velocity,
        max_acceleration=np.asarray(cfg.get("max_acceleration", 4.0 * velocity), dtype=float),
        max_jerk=np.asarray(cfg.get("max_jerk", 40.0 * velocity), dtype=float),
        reach=Reach(tuple(float(v) for v in cfg["reach"]["center"]), float(cfg["reach"]["min"]), float(cfg["reach"]["max"]))
        if "reach" in cfg else None,
        hand=HandGeometry(**{k: float(v) for k, v in cfg["hand"].items()}) if "hand" in cfg else None,
        gripper_force=float(cfg["gripper_force"]) if "gripper_force" in cfg else None,
    )


def urdf_joint_limits(urdf_path: Path) -> dict[str, tuple[float, float]]:
    """(effort, velocity) of every joint with a ``<limit>``; an attribute it lacks is inf."""
    out = {}
    for joint in ET.parse(urdf_path).getroot().iter("joint"):
        limit = joint.find("limit")
        if limit is not None:
            out[joint.get("name")] = (float(limit.get("effort", np.inf)), float(limit.get("velocity", np.inf)))
    return out


def _urdf_velocity_limits(urdf_path: Path, joints: list[str]) -> list[float]:
    velocity = {name: v for name, (_, v) in urdf_joint_limits(urdf_path).items() if 0.0 < v < np.inf}
    missing = [j for j in joints if j not in velocity]
    if missing:
        raise ValueError(f"{urdf_path}: no velocity limit for {missing}: give max_velocity in the robot YAML")
    return [velocity[j] for j in joints]
