"""Robot presets: where the URDF is, which joints are arm and gripper, and where `tcp` is.

The canonical TCP frame (DESIGN.md) has its origin between the fingertips, z along the
approach direction and y along the finger closing direction. Every preset maps it onto its
own flange link with a fixed transform ``T_flange_tcp``, so keyposes mean the same thing on
every robot. Simulation (SAPIEN), control (Pinocchio) and perception (self-filter) all read
the robot from here.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml


def example_robot_data_dir() -> Path:
    """`share/example-robot-data/robots` inside the installed example-robot-data wheel."""
    import cmeel  # type: ignore[import-not-found]  (the prefix the robot-data wheels install into)

    return Path(cmeel.__file__).resolve().parent.parent / "cmeel.prefix" / "share" / "example-robot-data" / "robots"


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
    extra: dict = field(default_factory=dict)


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
    )


PRESETS = {"panda": _panda}


def load_robot_spec(name_or_yaml: str) -> RobotSpec:
    """A preset by name, or a custom robot from a YAML file with the RobotSpec fields."""
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
    return RobotSpec(
        name=cfg.get("name", path.stem),
        urdf_path=(base / cfg["urdf"]).resolve(),
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
        max_velocity=np.asarray(cfg.get("max_velocity", [1.0] * n), dtype=float),
        max_acceleration=np.asarray(cfg.get("max_acceleration", [5.0] * n), dtype=float),
        max_jerk=np.asarray(cfg.get("max_jerk", [100.0] * n), dtype=float),
    )
