"""A synthetic policy dataset with two interaction modes per observation, for training tests.

Each trajectory shows one of three coloured boxes somewhere in the cube (rendered by the real
orthographic renderer, robot-free). Its task embedding z is the box type's signature, a term in
the box position, and +-d for the mode (d shared by all boxes plus a type-specific part, as
"open" changes a cabinet's appearance alike across cabinets). The keyposes touch the box on
the side the mode says (-x side for mode 0, +x side for mode 1), so the action depends on eps.
"""
from __future__ import annotations

import numpy as np
import torch

from actaim2.models.view_geometry import CubePlacement
from actaim2.perception.ortho_views import render_views
from actaim2.train.data import TrainingData

PLACEMENT = CubePlacement((0.5, 0.0, 0.3), 0.3)
COLOURS = np.array([[220, 40, 40], [40, 200, 40], [40, 40, 220]], dtype=np.uint8)


def box_points(center: np.ndarray, size: float, rng: np.random.Generator, n: int = 1500) -> np.ndarray:
    return center + rng.uniform(-size / 2, size / 2, (n, 3))


def make_dataset(n: int, resolution: int = 32, z_dim: int = 20, seed: int = 0) -> tuple[TrainingData, np.ndarray]:
    """(data, mode label per trajectory)."""
    rng = np.random.default_rng(seed)
    # Fixed across calls: rows 0-2 box types, 3 the shared mode direction, 4-5 type-specific mode parts, 6-8 position.
    signatures = np.random.default_rng(1234).normal(size=(9, z_dim))
    types = rng.integers(0, 3, n)
    modes = rng.integers(0, 2, n)
    centers = np.asarray(PLACEMENT.center) + rng.uniform(-0.12, 0.12, (n, 3)) * [1, 1, 0.5]
    views = np.zeros((n, 5, 8, resolution, resolution), np.float16)
    keyposes = np.zeros((n, 4, 8), np.float32)
    for i in range(n):
        pts = box_points(centers[i], 0.1, rng)
        views[i] = render_views(pts, np.repeat(COLOURS[types[i]][None], len(pts), 0), PLACEMENT.center,
                                PLACEMENT.half_extent, resolution)
        side = np.array([-0.09 if modes[i] == 0 else 0.09, 0.0, 0.0])
        for j in range(4):
            keyposes[i, j, :3] = centers[i] + side * (1.6 if j == 0 else 1.0)
            keyposes[i, j, 3:7] = [0.0, 0.0, 0.0, 1.0] if modes[i] == 0 else [0.0, 0.0, 1.0, 0.0]
            keyposes[i, j, 7] = float(j >= 2)
    sign = (2 * modes - 1)[:, None]
    z = (signatures[types] + (centers - PLACEMENT.center) @ signatures[6:9] * 2.0
         + sign * (signatures[3] + 0.5 * signatures[4 + types % 2]) + 0.05 * rng.normal(size=(n, z_dim)))
    key_views = np.repeat(views[:, None], 4, axis=1)
    gripper = np.zeros((n, 4), bool)
    gripper[:, 3] = True
    valid = PLACEMENT.contains(torch.from_numpy(keyposes[..., :3])).numpy()
    data = TrainingData(views, key_views, keyposes, gripper, valid, z.astype(np.float32), [f"t{i:05d}" for i in range(n)])
    return data, modes
