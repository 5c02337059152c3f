"""A keypose a = (p, R, q) of the four-phase primitive (paper: keyframe actions; DESIGN.md phases).

The one in-library representation of what actaim2_msgs/Keypose carries: planning (control),
sampling and storage (data) and the nodes all use it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

INIT, REACH, GRASP, MANIPULATE = 0, 1, 2, 3  # Keypose.phase values, as Keypose.msg's PHASE_* constants
PHASE_NAMES = ("INIT", "REACH", "GRASP", "MANIPULATE")


@dataclass
class Keypose:
    """a = (p, R, q): the pose of `tcp` in `world` and whether the gripper is closed."""

    phase: int
    position: np.ndarray  # (3,)
    quat_xyzw: np.ndarray  # (4,)
    gripper_closed: bool

    def to_json(self) -> dict:
        return {
            "phase": int(self.phase),
            "position": [float(v) for v in self.position],
            "quat_xyzw": [float(v) for v in self.quat_xyzw],
            "gripper_closed": bool(self.gripper_closed),
        }

    @classmethod
    def from_json(cls, d: dict) -> "Keypose":
        return cls(int(d["phase"]), np.asarray(d["position"], float), np.asarray(d["quat_xyzw"], float), bool(d["gripper_closed"]))
