"""Fuse camera clouds into one world-frame cloud: transform, crop to the workspace, voxel downsample.

Implemented in torch: measured on this machine (2 cores, shared) for ring5 (5 x 320x240 points,
~80k after cropping) transform + crop + 5 mm voxel grid took 13-17 ms in torch against 58 ms with
Open3D's legacy PointCloud and 225 ms with its tensor PointCloud (mostly conversion and the
voxel hash map). Statistical outlier removal needs k nearest neighbours, for which torch has no
spatial index, so that optional step uses Open3D's KD-tree on the (already small) voxel cloud.

Voxels average position and colour of their points, as Open3D's ``voxel_down_sample`` does.
Points from clouds without colour get :data:`NO_COLOUR` so every fused point has one.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

NO_COLOUR = np.array([128, 128, 128], dtype=np.uint8)  # mid grey for xyz-only clouds


@dataclass(frozen=True)
class CameraCloud:
    """One decoded cloud and the transform from its frame to world."""

    xyz: np.ndarray  # (N, 3) float32 in the cloud's own frame, NaN = no return
    rgb: np.ndarray | None  # (N, 3) uint8, or None for xyz-only clouds
    T_world_cloud: np.ndarray  # 4x4


@dataclass(frozen=True)
class FusedCloud:
    xyz: np.ndarray  # (M, 3) float32, world frame
    rgb: np.ndarray  # (M, 3) uint8

    def subset(self, mask: np.ndarray) -> "FusedCloud":
        return FusedCloud(self.xyz[mask], self.rgb[mask])


@dataclass(frozen=True)
class FusionConfig:
    center: tuple[float, float, float] = (0.5, 0.0, 0.4)  # workspace cube centre, world (m)
    half_extent: float = 0.6  # half side of the workspace cube (m): the table top in front of the robot
    voxel_size: float = 0.005  # m; 0 keeps every point
    outlier_neighbors: int = 0  # statistical outlier removal: k neighbours; 0 disables it
    outlier_std_ratio: float = 2.0  # ... drop points whose mean k-NN distance exceeds mean + ratio * std


def _to_world_cropped(cloud: CameraCloud, center: torch.Tensor, half_extent: float) -> tuple[torch.Tensor, torch.Tensor]:
    T = torch.as_tensor(np.asarray(cloud.T_world_cloud, dtype=np.float32))
    xyz = torch.from_numpy(np.ascontiguousarray(cloud.xyz, dtype=np.float32))
    world = torch.addmm(T[:3, 3], xyz, T[:3, :3].T)
    inside = torch.nonzero(((world - center).abs_() <= half_extent).all(dim=1)).squeeze(1)  # NaN compares False
    rgb = torch.from_numpy(cloud.rgb).index_select(0, inside) if cloud.rgb is not None else torch.from_numpy(NO_COLOUR).expand(len(inside), 3)
    return world.index_select(0, inside), rgb


def voxel_downsample(xyz: torch.Tensor, rgb: torch.Tensor, origin: torch.Tensor, voxel_size: float, cells: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Mean position and colour per occupied voxel of a grid of ``cells``^3 starting at ``origin``."""
    k = ((xyz - origin) / voxel_size).long().clamp_(0, cells - 1)  # points are inside the grid: trunc = floor
    key = (k[:, 0] * cells + k[:, 1]) * cells + k[:, 2]
    _, inverse, counts = torch.unique(key, return_inverse=True, return_counts=True)
    n = len(counts)
    # One weighted bincount over (voxel, channel) pairs instead of one per channel.
    values = torch.cat([xyz, rgb.float()], dim=1).reshape(-1)
    slots = (inverse[:, None] * 6 + torch.arange(6)).reshape(-1)
    means = torch.bincount(slots, weights=values, minlength=6 * n).reshape(n, 6) / counts[:, None]
    return means[:, :3].float(), means[:, 3:].round().to(torch.uint8)


def remove_statistical_outliers(xyz: np.ndarray, neighbors: int, std_ratio: float) -> np.ndarray:
    """Keep mask of points whose mean distance to their k neighbours is not unusually large."""
    import open3d as o3d

    if len(xyz) <= neighbors:
        return np.ones(len(xyz), dtype=bool)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(xyz.astype(np.float64)))
    _, kept = cloud.remove_statistical_outlier(nb_neighbors=neighbors, std_ratio=std_ratio)
    mask = np.zeros(len(xyz), dtype=bool)
    mask[np.asarray(kept, dtype=np.int64)] = True
    return mask


def fuse(clouds: list[CameraCloud], config: FusionConfig) -> FusedCloud:
    """World-frame fused cloud inside the workspace cube (possibly empty)."""
    center = torch.tensor(config.center, dtype=torch.float32)
    parts = [_to_world_cropped(c, center, config.half_extent) for c in clouds]
    xyz = torch.cat([p[0] for p in parts]) if parts else torch.zeros((0, 3))
    rgb = torch.cat([p[1] for p in parts]) if parts else torch.zeros((0, 3), dtype=torch.uint8)
    if config.voxel_size > 0 and len(xyz):
        cells = int(np.ceil(2 * config.half_extent / config.voxel_size)) + 1
        xyz, rgb = voxel_downsample(xyz, rgb, center - config.half_extent, config.voxel_size, cells)
    fused = FusedCloud(xyz.numpy(), rgb.contiguous().numpy())
    if config.outlier_neighbors > 0:
        fused = fused.subset(remove_statistical_outliers(fused.xyz, config.outlier_neighbors, config.outlier_std_ratio))
    return fused
