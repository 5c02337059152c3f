"""A keypose a = (p, R, q) of the four-phase primitive (paper: keyframe actions; DESIGN.md phases).

The one in-library representation of what actaim2_msgs/Keypose carries: planning (control),
sampling and storage (data) and the nodes all use it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

INIT, REACH, GRASP, MANIPULATE = 0, 1, 2, 3  # Keypose.phase values, as Keypose.msg's PHASE_* constants
PHASE_NAMES = ("INIT", "REACH", "GRASP", "MANIPULATE")
UNIT_TOLERANCE = 1e-3  # how far from unit length a quaternion may be before it is refused, not normalised
# Closer to unit length than this a quaternion is kept as given (a float32 or float64 rounding of a unit
# one): the keyposes read from messages and bags stay the very numbers sent.
UNIT_ROUNDING = 1e-6


def check_phase(phase: int) -> int:
    """``phase`` as an int if it names a phase; a ValueError that lists the phases otherwise."""
    if not 0 <= int(phase) < len(PHASE_NAMES):
        known = ", ".join(f"{i} ({name})" for i, name in enumerate(PHASE_NAMES))
        raise ValueError(f"unknown phase {phase}: expected one of {known}")
    return int(phase)


@dataclass
class Keypose:
    """a = (p, R, q): the pose of `tcp` in `world` and whether the gripper is closed."""

    phase: int
    position: np.ndarray  # (3,)
    quat_xyzw: np.ndarray  # (4,), unit length
    gripper_closed: bool

    def __post_init__(self) -> None:
        """Checked once, where a keypose is made: a known phase, three finite coordinates and a
        finite quaternion within :data:`UNIT_TOLERANCE` of unit length, normalised when it is further
        than :data:`UNIT_ROUNDING` from it. A ValueError says what is wrong."""
        self.phase = check_phase(self.phase)
        position, quat = np.asarray(self.position), np.asarray(self.quat_xyzw)
        if position.shape != (3,) or not np.all(np.isfinite(position)):
            raise ValueError(f"position {position.tolist()} is not finite (x, y, z)")
        norm = float(np.linalg.norm(quat)) if quat.shape == (4,) else float("nan")
        if not abs(norm - 1.0) <= UNIT_TOLERANCE:
            raise ValueError(f"orientation {quat.tolist()} is not a unit quaternion (x, y, z, w)")
        self.position, self.quat_xyzw = position, quat if abs(norm - 1.0) <= UNIT_ROUNDING else quat / norm

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
