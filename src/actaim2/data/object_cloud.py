"""The object as the samplers see it: points from the robot-hidden cameras, nothing privileged.

Depth images are back-projected, fused in `world` and cropped to the workspace cube
(``actaim2.perception.fusion``), then the support surface is found with RANSAC and removed.
The result is the object cloud (random interaction points are drawn from it). Removing the
object's own large planar faces as well (cabinet fronts, table tops) and clustering the rest
with DBSCAN leaves the parts that stick out: handles, knobs, buttons (heuristic grasping).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from actaim2.data.trajectory import CameraImage, Observation
from actaim2.geometry import depth_to_points
from actaim2.perception.fusion import CameraCloud, FusionConfig, fuse
from actaim2.profiling import timed


@dataclass(frozen=True)
class CloudConfig:
    center: tuple[float, float, float]  # workspace cube around the object, world (m)
    half_extent: float = 0.6
    voxel_size: float = 0.005
    plane_distance: float = 0.006  # RANSAC inlier distance (m)
    support_max_tilt_deg: float = 15.0  # a support plane is within this of horizontal
    support_band: float = 0.05  # ... and within this of the cloud's lowest point (m)
    face_min_width: float = 0.06  # m: a plane is an object face (removed) if its inliers span this both ways
    max_part_planes: int = 10
    dbscan_eps: float = 0.015
    dbscan_min_points: int = 8
    segment_min_points: int = 15
    segment_max_extent: float = 0.35  # m; larger clusters are bodies, not handles or knobs ...
    segment_max_bar_width: float = 0.08  # m: ... unless they are bars no wider than a hand's opening
    #   across both their narrow axes (a refrigerator's full-height handle)
    max_segments: int = 8  # the largest ones; the rest are mostly strips left along face edges


@dataclass
class ObjectCloud:
    points: np.ndarray  # (N, 3) world, support removed
    colors: np.ndarray  # (N, 3) uint8


@timed("back-projection")
def back_project(image: CameraImage) -> np.ndarray:
    """(H*W, 3) points in the camera's optical frame (NaN where depth is 0): :func:`actaim2.geometry.depth_to_points`."""
    return depth_to_points(image.depth, image.K).reshape(-1, 3)


def fused_cloud(observation: Observation, config: CloudConfig):
    clouds = [CameraCloud(back_project(im), im.rgb.reshape(-1, 3), im.T_world_optical) for _, im in sorted(observation.items())]
    return fuse(clouds, FusionConfig(center=config.center, half_extent=config.half_extent, voxel_size=config.voxel_size))


def _o3d(points: np.ndarray):
    import open3d as o3d

    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, dtype=np.float64)))


def fit_plane(points: np.ndarray, distance: float, rng: np.random.Generator, sample: int = 5000) -> tuple[np.ndarray, np.ndarray]:
    """RANSAC plane (a, b, c, d), unit normal, and the inlier mask over all points.

    The model is fitted on a random subsample (Open3D's RANSAC, seeded from ``rng`` so that
    collection is reproducible) and its inliers counted on every point: a plane holding a
    useful share of the cloud is found as well from 5000 points as from 100000, ~20x faster.
    """
    import open3d as o3d

    idx = rng.choice(len(points), size=min(sample, len(points)), replace=False)
    o3d.utility.random.seed(int(rng.integers(2**31)))
    model, _ = _o3d(points[idx]).segment_plane(distance, 3, 200)
    model = np.asarray(model, dtype=float) / np.linalg.norm(model[:3])
    return model, np.abs(points @ model[:3] + model[3]) <= distance


def remove_support(points: np.ndarray, config: CloudConfig, rng: np.random.Generator) -> np.ndarray:
    """Keep mask without the support surface (floor or table) and anything below it.

    The support is a near-horizontal plane among the first three RANSAC planes lying at the
    bottom of the cloud: the object's own horizontal faces (a table top, a lid) lie higher.
    """
    if len(points) < 3:
        return np.ones(len(points), dtype=bool)
    bottom = float(np.min(points[:, 2]))
    remaining = np.ones(len(points), dtype=bool)
    cos_tilt = np.cos(np.deg2rad(config.support_max_tilt_deg))
    heights = []
    for _ in range(3):
        idx = np.flatnonzero(remaining)
        if len(idx) < 3:
            break
        model, inliers = fit_plane(points[idx], config.plane_distance, rng)
        if abs(model[2]) >= cos_tilt and -model[3] / model[2] <= bottom + config.support_band:
            heights.append(-model[3] / model[2])
        remaining[idx[inliers]] = False
    if not heights:
        return np.ones(len(points), dtype=bool)
    return points[:, 2] > min(heights) + config.plane_distance


def estimate_normals(points: np.ndarray, radius: float) -> np.ndarray:
    """Unit normals (unoriented) from each point's neighbours within ``radius``."""
    import open3d as o3d

    if len(points) < 3:
        return np.zeros_like(points, dtype=float)
    pcd = _o3d(points)
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=20))
    return np.asarray(pcd.normals)


@timed("object cloud")
def object_cloud(observation: Observation, config: CloudConfig, rng: np.random.Generator) -> ObjectCloud:
    """Robot-hidden observation -> the object's points (normals are left to whoever needs them)."""
    fused = fused_cloud(observation, config)
    keep = remove_support(fused.xyz, config, rng)
    return ObjectCloud(fused.xyz[keep].astype(np.float64), fused.rgb[keep])


def _narrower_side(points: np.ndarray) -> float:
    """Extent of a planar point set along its second principal axis (its width)."""
    if len(points) < 3:
        return 0.0
    centred = points - points.mean(0)
    _, _, vt = np.linalg.svd(centred[:: max(1, len(centred) // 2000)], full_matrices=False)
    return float(np.ptp(centred @ vt[1]))


def _principal_extents(points: np.ndarray) -> np.ndarray:
    """The extents of ``points`` along their principal axes, largest first."""
    centred = points - points.mean(axis=0)
    _, _, axes = np.linalg.svd(centred, full_matrices=False)
    return np.ptp(centred @ axes.T, axis=0)


def part_segments(cloud: ObjectCloud, config: CloudConfig, rng: np.random.Generator) -> list[np.ndarray]:
    """Index arrays of compact clusters left after removing the object's large planar faces.

    These are the parts a hand can close on: handles, knobs, buttons, levers, and bars of any
    length (a cluster longer than ``segment_max_extent`` is kept when it is no wider than
    ``segment_max_bar_width`` across: a long handle, not a body).
    """
    remaining = np.arange(len(cloud.points))
    for _ in range(config.max_part_planes):
        if len(remaining) < max(3, config.segment_min_points):
            break
        _, inliers = fit_plane(cloud.points[remaining], config.plane_distance, rng)
        if _narrower_side(cloud.points[remaining[inliers]]) < config.face_min_width:
            break  # the best plane left is a strip through a part (a handle's side): parts start here
        remaining = remaining[~inliers]
    if len(remaining) < config.segment_min_points:
        return []
    labels = np.asarray(_o3d(cloud.points[remaining]).cluster_dbscan(config.dbscan_eps, config.dbscan_min_points))
    segments = []
    for label in range(labels.max(initial=-1) + 1):
        idx = remaining[labels == label]
        if len(idx) < config.segment_min_points:
            continue
        length, width, _ = _principal_extents(cloud.points[idx])
        if length <= config.segment_max_extent or width <= config.segment_max_bar_width:
            segments.append(idx)
    return sorted(segments, key=len, reverse=True)[: config.max_segments]
