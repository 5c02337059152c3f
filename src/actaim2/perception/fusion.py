"""Fuse camera clouds into one world-frame cloud: transform, crop to the workspace, voxel downsample.

Measured on this machine (2 cores shared with other jobs; ring5 = 5 x 320x240 random-ish points,
~80k after cropping): transform + crop + 5 mm voxel grid took 13-17 ms in torch against 58 ms with
Open3D's legacy PointCloud and 225 ms with its tensor PointCloud (conversions and its voxel hash
map). So transform and crop run in torch (one thread, see the node's ``torch_threads``); the voxel
grouping then uses numpy's SIMD sort, which beat torch.unique 2-4x on the real ring5 scene
(180k points in the cube). Statistical outlier removal needs k nearest neighbours, for which
torch has no spatial index, so that optional step uses Open3D's KD-tree on the voxel cloud.

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


def voxel_downsample(xyz: np.ndarray, rgb: np.ndarray, origin: np.ndarray, voxel_size: float, cells: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean position and colour per occupied voxel of a grid of ``cells``^3 starting at ``origin``.

    Grouping sorts ``voxel key << 32 | point index`` with numpy's SIMD sort (1-3 ms for 180k
    points here, against 6-10 ms for torch.unique); the sums then go through torch's index_add_
    over the sorted voxel ids, 5x faster here than numpy's reduceat or bincount.
    """
    k = ((xyz - origin) / voxel_size).astype(np.int64)  # points are inside the grid: trunc = floor
    np.clip(k, 0, cells - 1, out=k)
    key = (k[:, 0] * cells + k[:, 1]) * cells + k[:, 2]
    ordered = np.sort((key << 32) | np.arange(len(key)))
    voxel = ordered >> 32
    first = np.empty(len(ordered), dtype=bool)
    first[0] = True
    np.not_equal(voxel[1:], voxel[:-1], out=first[1:])
    group = torch.from_numpy(np.cumsum(first) - 1)
    n = int(group[-1]) + 1
    values = torch.cat([torch.from_numpy(xyz), torch.from_numpy(rgb).float()], dim=1)
    sums = torch.zeros((n, 6)).index_add_(0, group, values.index_select(0, torch.from_numpy(ordered & 0xFFFFFFFF)))
    means = sums / torch.bincount(group, minlength=n)[:, None]
    return means[:, :3].numpy(), means[:, 3:].round().to(torch.uint8).numpy()


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
    xyz = torch.cat([p[0] for p in parts]).numpy() if parts else np.zeros((0, 3), np.float32)
    rgb = torch.cat([p[1] for p in parts]).numpy() if parts else np.zeros((0, 3), np.uint8)
    if config.voxel_size > 0 and len(xyz):
        cells = int(np.ceil(2 * config.half_extent / config.voxel_size)) + 1
        origin = np.asarray(config.center, dtype=np.float32) - np.float32(config.half_extent)
        xyz, rgb = voxel_downsample(xyz, rgb, origin, config.voxel_size, cells)
    fused = FusedCloud(np.ascontiguousarray(xyz, dtype=np.float32), np.ascontiguousarray(rgb))
    if config.outlier_neighbors > 0:
        fused = fused.subset(remove_statistical_outliers(fused.xyz, config.outlier_neighbors, config.outlier_std_ratio))
    return fused
