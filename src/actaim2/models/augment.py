"""RVT scene augmentation: one random SE(3) perturbation applied to the scene and to the keypose.

RVT perturbs the point cloud and the action together (translation of a few cm, a yaw about the
vertical axis) and re-renders the views, so the predictor cannot memorise absolute pixel
positions. Here the scene is rotated about the vertical axis through the cube centre by
yaw ~ U(-max_yaw, max_yaw) and shifted by t ~ U(-max_translation, max_translation)^3; the keypose
gets the same transform (position and orientation). A draw that moves the keypose out of the
cube is redrawn (up to ``tries`` times, then the sample stays unperturbed), as RVT does.

The scene cloud is read back from the views themselves - every occupied pixel stores a
cube-frame position and a colour - and re-rendered by the perception renderer
(:func:`actaim2.perception.ortho_views.render_views`), so training only needs the cached views,
not the fused clouds. Points hidden in all five views are lost, which the views never showed
anyway; a yaw can open small holes where a surface was seen edge-on, and a pixel that blended
splats of two points reads back as one point between them (at silhouettes only).

Cost: ``actaim2 bench models`` reports the time per sample (``augment`` row).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from actaim2.models.view_geometry import CubePlacement
from actaim2.perception.ortho_views import CHANNELS, render_views

_RGB = [CHANNELS.index(c) for c in "rgb"]
_XYZ = [CHANNELS.index(c) for c in "xyz"]
_OCCUPANCY = CHANNELS.index("occupancy")


@dataclass(frozen=True)
class AugmentConfig:
    max_translation: float = 0.05  # m, per axis
    max_yaw_deg: float = 45.0  # RVT's yaw range
    tries: int = 10  # draws before giving up on keeping the keypose inside the cube


def sample_perturbation(rng: np.random.Generator, config: AugmentConfig, placement: CubePlacement) -> np.ndarray:
    """4x4 world transform: yaw about the vertical axis through the cube centre, then a shift."""
    yaw = np.radians(rng.uniform(-config.max_yaw_deg, config.max_yaw_deg))
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("z", yaw).as_matrix()
    center = np.asarray(placement.center, dtype=np.float64)
    T[:3, 3] = center - T[:3, :3] @ center + rng.uniform(-config.max_translation, config.max_translation, 3)
    return T


def transform_keypose(T: np.ndarray, keypose: np.ndarray) -> np.ndarray:
    """(8,) [position, quaternion (x, y, z, w), gripper] moved by the 4x4 transform T."""
    out = np.array(keypose, dtype=np.float64)
    out[:3] = T[:3, :3] @ out[:3] + T[:3, 3]
    out[3:7] = (Rotation.from_matrix(T[:3, :3]) * Rotation.from_quat(out[3:7])).as_quat()
    return out


def views_cloud(views: np.ndarray, placement: CubePlacement) -> tuple[np.ndarray, np.ndarray]:
    """The points the views show: (N, 3) float64 world xyz and (N, 3) uint8 colour, one per occupied pixel."""
    occupied = views[:, _OCCUPANCY] > 0  # (V, R, R)
    cube = torch.from_numpy(views[:, _XYZ].transpose(0, 2, 3, 1)[occupied].astype(np.float64))
    rgb = np.rint(views[:, _RGB].transpose(0, 2, 3, 1)[occupied] * 255.0).astype(np.uint8)
    return placement.to_world(cube).numpy(), rgb


def augment(
    views: np.ndarray,
    keypose: np.ndarray,
    placement: CubePlacement,
    rng: np.random.Generator,
    config: AugmentConfig = AugmentConfig(),
) -> tuple[np.ndarray, np.ndarray]:
    """One sample perturbed: (views (V, C, R, R) as rendered, keypose (8,) in world coordinates).

    The transform is the first draw of :func:`sample_perturbation` from ``rng`` that keeps the
    keypose inside the cube.
    """
    position = np.asarray(keypose[:3], dtype=np.float64)
    center = np.asarray(placement.center, dtype=np.float64)
    for _ in range(config.tries):
        T = sample_perturbation(rng, config, placement)
        if np.abs(T[:3, :3] @ position + T[:3, 3] - center).max() <= placement.half_extent:
            break
    else:
        return views, np.asarray(keypose, dtype=np.float64)
    xyz, rgb = views_cloud(views, placement)
    moved = (xyz @ T[:3, :3].T + T[:3, 3]).astype(np.float32)
    rendered = render_views(moved, rgb, placement.center, placement.half_extent, views.shape[-1])
    return rendered, transform_keypose(T, keypose)
