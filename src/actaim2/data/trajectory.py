"""In-memory records of one collected trajectory T = {(a_i, O_i), i = 0..3} + O_init, O_final.

``O_i`` is the observation the keypose ``a_i`` is chosen from (so it is taken *before* a_i is
executed): O_0 at the start, O_1 after INIT, O_2 after REACH, O_3 after GRASP. ``O_init`` and
``O_final`` are rendered with the robot hidden (before a_0 and after a_3) so that the task
embedding z = E(O_init) - E(O_final) sees only what happened to the object.

Observations keep what the cameras measure (RGB and depth) plus each camera's intrinsics and
extrinsics; orthographic views and clouds are recomputed from them, which keeps files small
and lets the view renderer change without re-collecting.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from actaim2.keypose import Keypose
from actaim2.sim.success import dof_success, moved_fraction

PHASES = ("init", "reach", "grasp", "manipulate")  # keypose phase ids 0..3 (DESIGN.md Keypose.msg)
KEYFRAME_OBSERVATIONS = ("o0", "o1", "o2", "o3")  # O_i, taken before a_i
HIDDEN_ROBOT_OBSERVATIONS = ("init", "final")  # O_init, O_final
OBSERVATION_NAMES = KEYFRAME_OBSERVATIONS + HIDDEN_ROBOT_OBSERVATIONS


@dataclass
class CameraImage:
    """One camera's picture: RGB, z-depth along the optical axis, and where the camera is.

    ``depth`` is in metres, 0 where the camera saw nothing; ``T_world_optical`` is the pose of the
    ROS optical frame (x right, y down, z forward) in ``world``.
    """

    rgb: np.ndarray  # (H, W, 3) uint8
    depth: np.ndarray  # (H, W) float32 metres, 0 = no return
    K: np.ndarray  # (3, 3) pinhole intrinsics
    T_world_optical: np.ndarray  # (4, 4)

    def __post_init__(self) -> None:
        if self.rgb.ndim != 3 or self.rgb.shape[2] != 3 or self.rgb.dtype != np.uint8:
            raise ValueError(f"rgb must be (H, W, 3) uint8, got {self.rgb.shape} {self.rgb.dtype}")
        if self.depth.shape != self.rgb.shape[:2]:
            raise ValueError(f"depth {self.depth.shape} and rgb {self.rgb.shape[:2]} sizes differ")
        self.depth = np.nan_to_num(np.asarray(self.depth, dtype=np.float32), nan=0.0, posinf=0.0, neginf=0.0)
        self.K = np.asarray(self.K, dtype=float).reshape(3, 3)
        self.T_world_optical = np.asarray(self.T_world_optical, dtype=float).reshape(4, 4)


Observation = dict[str, CameraImage]  # camera name -> image, one entry per camera of the rig


@dataclass
class ObjectState:
    """The articulated object's DoF values: privileged, used only to validate the visual label."""

    names: list[str]
    lower: np.ndarray
    upper: np.ndarray
    initial: np.ndarray
    final: np.ndarray

    def signed_change(self) -> np.ndarray:
        """(final - initial) / range per DoF (a DoF without range counts as not moved)."""
        return moved_fraction(self.initial, self.final, self.lower, self.upper)

    def to_json(self) -> dict:
        return {k: (list(v) if k == "names" else [float(x) for x in v]) for k, v in vars(self).items()}

    @classmethod
    def from_json(cls, d: dict) -> "ObjectState":
        return cls(list(d["names"]), *(np.asarray(d[k], float) for k in ("lower", "upper", "initial", "final")))


def ground_truth_success(state: ObjectState) -> bool:
    """The paper's criterion (``actaim2.sim.success``): some DoF moved by more than 30% of its range."""
    return dof_success(state.initial, state.final, state.lower, state.upper)


@dataclass
class Trajectory:
    """One sampled interaction: four keyposes, their observations, and the object it touched."""

    id: str
    object_id: str
    category: str
    instance: int
    split: str
    sampler: str
    seed: int
    keyposes: list[Keypose]
    observations: dict[str, Observation]  # OBSERVATION_NAMES -> Observation
    robot_joints: dict[str, dict[str, float]]  # OBSERVATION_NAMES -> joint name -> position (robot self-filter)
    object_state: ObjectState
    info: dict = field(default_factory=dict)  # sampler details, execution results (JSON-able)

    def __post_init__(self) -> None:
        if len(self.keyposes) != len(PHASES):
            raise ValueError(f"a trajectory has {len(PHASES)} keyposes, got {len(self.keyposes)}")
        missing = set(OBSERVATION_NAMES) - set(self.observations)
        if missing:
            raise ValueError(f"trajectory {self.id} lacks observations {sorted(missing)}")

    @property
    def gt_success(self) -> bool:
        return ground_truth_success(self.object_state)
