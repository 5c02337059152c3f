"""Intrinsics fitted to organized clouds: a pinhole cloud gives its K back, a distorted one reports its
residual, clouds that cannot give intrinsics are refused with the reason."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.data.object_cloud import back_project
from actaim2.data.trajectory import CameraImage
from actaim2.finetune.intrinsics import IntrinsicsFitError, fit_intrinsics

K = np.array([[208.5, 0.0, 161.3], [0.0, 226.0, 142.7], [0.0, 0.0, 1.0]])  # non-square pixels, off-centre


def pinhole_cloud(rng: np.random.Generator, holes: float = 0.5) -> np.ndarray:
    depth = rng.uniform(0.5, 3.0, (288, 320)).astype(np.float32)
    depth[rng.random(depth.shape) < holes] = 0.0  # no return
    image = CameraImage(np.zeros((288, 320, 3), np.uint8), depth, K, np.eye(4))
    return back_project(image).reshape(288, 320, 3)  # the project's pixel-centre convention


def test_a_pinhole_cloud_gives_its_intrinsics_back():
    fit = fit_intrinsics(pinhole_cloud(np.random.default_rng(0)))
    np.testing.assert_allclose(fit.K, K, atol=1e-3)
    assert fit.rms_px < 1e-3 and fit.max_px < 1e-2 and 0.4 * 288 * 320 < fit.points < 0.6 * 288 * 320


def test_a_distorted_cloud_reports_its_residual():
    xyz = pinhole_cloud(np.random.default_rng(1), holes=0.0).astype(np.float64)
    a, b = xyz[..., 0] / xyz[..., 2], xyz[..., 1] / xyz[..., 2]
    scale = 1.0 + 0.1 * (a**2 + b**2)  # radial distortion k1 = 0.1: what a lens model does to the rays
    xyz[..., 0], xyz[..., 1] = a * scale * xyz[..., 2], b * scale * xyz[..., 2]
    fit = fit_intrinsics(xyz)
    assert 0.5 < fit.rms_px < 10 and fit.max_px > fit.rms_px  # measured, not hidden
    assert abs(fit.K[0, 2] - K[0, 2]) < 1.0  # symmetric distortion leaves the centre


@pytest.mark.parametrize("cloud, reason", [
    (np.zeros((1, 100, 3)), "organized cloud"),
    (np.full((10, 10, 3), np.nan), "only 0 valid pixels"),
    (np.dstack([np.ones((20, 20)), np.ones((20, 20)), -np.ones((20, 20))]), "only 0 valid pixels"),
])
def test_clouds_that_cannot_give_intrinsics_are_refused(cloud, reason):
    with pytest.raises(IntrinsicsFitError, match=reason):
        fit_intrinsics(cloud)


def test_a_cloud_in_a_non_optical_frame_is_refused():
    xyz = pinhole_cloud(np.random.default_rng(2))
    flipped = xyz * np.array([-1.0, 1.0, 1.0])  # x left: not an optical frame
    with pytest.raises(IntrinsicsFitError, match="not in an optical frame"):
        fit_intrinsics(flipped)
