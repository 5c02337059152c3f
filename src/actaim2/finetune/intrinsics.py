"""Pinhole intrinsics recovered from an organized cloud, for clouds that come without a CameraInfo.

A bag records ``/points2`` (the Azure Kinect driver's organized cloud), not the depth image and
its intrinsics; the training-dataset format stores depth images with K (``data/storage.py``).
Every valid pixel (u, v) of an organized cloud carries its point (x, y, z) in the optical frame,
so the projection that made it can be read back: with the pixel-centre convention of the whole
project (``data.object_cloud.back_project``: pixel u covers [u, u+1), its centre is u + 0.5),

    u + 0.5 = fx * x / z + cx        v + 0.5 = fy * y / z + cy

two independent straight-line fits by linear least squares. The residual (pixels) says how
pinhole the cloud is: ~0 for the simulator (also with sensor realism: range noise and flying
pixels move points along their rays), larger for a real device whose driver undistorts with its
lens model, where the stored depth + K back-project off by residual * z / f at the edges.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MIN_POINTS = 100  # fewer valid pixels than this cannot pin four parameters down reliably


class IntrinsicsFitError(ValueError):
    """The cloud cannot give intrinsics (not organized, too few valid points, degenerate)."""


@dataclass(frozen=True)
class IntrinsicsFit:
    K: np.ndarray  # (3, 3)
    rms_px: float  # root-mean-square reprojection residual over the valid pixels (u and v together)
    max_px: float  # largest absolute residual
    points: int  # valid pixels used

    def to_json(self) -> dict:
        return {"fx": float(self.K[0, 0]), "fy": float(self.K[1, 1]), "cx": float(self.K[0, 2]), "cy": float(self.K[1, 2]),
                "rms_px": self.rms_px, "max_px": self.max_px, "points": self.points}


def _line(a: np.ndarray, b: np.ndarray) -> tuple[float, float, np.ndarray]:
    """Least-squares (slope, intercept) of b = slope * a + intercept, and the residuals."""
    A = np.stack([a, np.ones_like(a)], axis=1)
    (slope, intercept), *_ = np.linalg.lstsq(A, b, rcond=None)
    return float(slope), float(intercept), b - (slope * a + intercept)


def fit_intrinsics(xyz: np.ndarray) -> IntrinsicsFit:
    """K of an organized cloud ``xyz`` (H, W, 3) in its optical frame; NaN (or z <= 0) = no return."""
    xyz = np.asarray(xyz, dtype=np.float64)
    if xyz.ndim != 3 or xyz.shape[2] != 3 or min(xyz.shape[:2]) < 2:
        raise IntrinsicsFitError(f"intrinsics need an organized cloud (H, W, 3) with H, W >= 2, got shape {xyz.shape}")
    h, w = xyz.shape[:2]
    v, u = np.mgrid[0:h, 0:w]
    valid = np.isfinite(xyz).all(axis=2) & (xyz[..., 2] > 0)
    n = int(valid.sum())
    if n < MIN_POINTS:
        raise IntrinsicsFitError(f"only {n} valid pixels in the {w}x{h} cloud (at least {MIN_POINTS} needed)")
    x, y, z = (xyz[..., i][valid] for i in range(3))
    a_u, a_v = x / z, y / z
    if np.ptp(a_u) < 1e-6 or np.ptp(a_v) < 1e-6 or np.ptp(u[valid]) == 0 or np.ptp(v[valid]) == 0:
        raise IntrinsicsFitError("the valid pixels span a single row or column: the projection is undetermined")
    fx, cx, res_u = _line(a_u, u[valid] + 0.5)
    fy, cy, res_v = _line(a_v, v[valid] + 0.5)
    if fx <= 0 or fy <= 0:
        raise IntrinsicsFitError(f"fitted focal lengths fx={fx:.1f}, fy={fy:.1f} are not positive: "
                                 f"the cloud is not in an optical frame (x right, y down, z forward)")
    residuals = np.concatenate([res_u, res_v])
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return IntrinsicsFit(K, float(np.sqrt(np.mean(residuals**2))), float(np.abs(residuals).max()), n)
