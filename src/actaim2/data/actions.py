"""The four-keypose action primitive every sampler produces (paper appendix, DESIGN.md phases).

{(p0, R0, open), (p1, R0, open), (p1, R0, closed), (p2, R0, closed)}: start pose p0, interaction
point p1 (reached by a straight line along the approach axis), manipulation position p2.
p0 lies on the approach axis, ``start_distance`` behind p1, so that the last REACH segment is
the straight approach DESIGN.md requires.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy.spatial.transform import Rotation

from actaim2.data.object_cloud import ObjectCloud
from actaim2.keypose import Keypose


@dataclass
class ActionSequence:
    p1: np.ndarray  # interaction point (tcp position when grasping), world
    p2: np.ndarray  # manipulation position, world
    R0: np.ndarray  # 3x3 tcp orientation, kept through all four phases
    start_distance: float  # |p1 - p0|, along the approach axis

    @property
    def p0(self) -> np.ndarray:
        return np.asarray(self.p1) - self.start_distance * np.asarray(self.R0)[:, 2]

    def keyposes(self) -> list[Keypose]:
        q = Rotation.from_matrix(self.R0).as_quat()
        q = -q if q[3] < 0 else q
        return [
            Keypose(0, self.p0, q, False),
            Keypose(1, np.asarray(self.p1, float), q, False),
            Keypose(2, np.asarray(self.p1, float), q, True),
            Keypose(3, np.asarray(self.p2, float), q, True),
        ]

    def vector(self) -> np.ndarray:
        """13-D encoding for density models (GMM): p1, p2 - p1, first two columns of R0, start distance."""
        R = np.asarray(self.R0)
        return np.concatenate([self.p1, np.asarray(self.p2) - self.p1, R[:, 0], R[:, 1], [self.start_distance]])

    @classmethod
    def from_vector(cls, v: np.ndarray) -> "ActionSequence":
        """Inverse of :meth:`vector`; the 6-D rotation is re-orthonormalised (Gram-Schmidt)."""
        v = np.asarray(v, dtype=float)
        x = v[6:9] / np.linalg.norm(v[6:9])
        y = v[9:12] - x * (x @ v[9:12])
        y /= np.linalg.norm(y)
        R = np.stack([x, y, np.cross(x, y)], axis=1)
        return cls(p1=v[0:3].copy(), p2=v[0:3] + v[3:6], R0=R, start_distance=float(max(v[12], 0.0)))

    @classmethod
    def from_keyposes(cls, keyposes: list[Keypose]) -> "ActionSequence":
        p0, p1, p2 = (np.asarray(keyposes[i].position, float) for i in (0, 1, 3))
        R0 = Rotation.from_quat(keyposes[0].quat_xyzw).as_matrix()
        return cls(p1=p1, p2=p2, R0=R0, start_distance=float(np.linalg.norm(p1 - p0)))


class Sampler(Protocol):
    """An action-sequence sampler working from the object cloud alone (no privileged state)."""

    name: str

    def sample(self, cloud: ObjectCloud, rng: np.random.Generator, index: int) -> ActionSequence | None:
        """A collision-filtered action sequence, or None when none was found.

        ``index`` numbers this sampler's trajectories on the object; the GMM-adaptive sampler
        uses it to visit its clusters in turn.
        """
