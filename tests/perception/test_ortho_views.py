"""Orthographic views: known points land on hand-computed pixels with the expected depth."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.perception.ortho_views import CHANNELS, DEPTH_STEP, EMPTY_VALUE, VIEWS, project, render_views, unproject

CENTER = (0.5, 0.0, 0.4)
HALF = 0.6
R = 128  # pixel side 1.2 m / 128 = 9.375 mm
POINT = np.array([0.6, 0.1, 0.3])
# Worked out by hand from the view definitions (camera on a cube face, image right/down axes):
# view: (column u, row v, depth from that face)
EXPECTED = {
    "top": (53, 53, 0.7),  # from z = 1.0 down; right = -y, down = -x
    "front": (74, 74, 0.5),  # from x = 1.1 towards the robot; right = +y, down = -z
    "back": (53, 74, 0.7),  # from x = -0.1; right = -y
    "left": (53, 74, 0.5),  # from y = 0.6; right = -x
    "right": (74, 74, 0.7),  # from y = -0.6; right = +x
}


def channel(views, name):
    return views[:, CHANNELS.index(name)]


def test_a_point_lands_on_the_expected_pixel_of_each_view():
    views = render_views(POINT[None].astype(np.float32), np.array([[255, 0, 51]], np.uint8), CENTER, HALF, R)
    assert views.shape == (len(VIEWS), len(CHANNELS), R, R) and views.dtype == np.float32
    for i, view in enumerate(VIEWS):
        u, v, depth = EXPECTED[view]
        occupied = np.argwhere(channel(views, "occupancy")[i] > 0)
        assert occupied.tolist() == [[v, u]], view
        pixel = views[i, :, v, u]
        np.testing.assert_allclose(pixel[CHANNELS.index("depth")], depth, atol=DEPTH_STEP)
        np.testing.assert_allclose(pixel[[CHANNELS.index(c) for c in "xyz"]], POINT, atol=1e-6)
        np.testing.assert_allclose(pixel[[CHANNELS.index(c) for c in "rgb"]], [1.0, 0.0, 0.2], atol=1e-6)
    empty = channel(views, "occupancy") == 0
    assert np.all(views.transpose(1, 0, 2, 3)[:, empty] == EMPTY_VALUE)


def test_project_and_unproject_agree_with_the_renderer():
    u, v, depth = project(POINT, CENTER, HALF, R)
    for i, view in enumerate(VIEWS):
        assert (int(u[i, 0]), int(v[i, 0])) == EXPECTED[view][:2]
        np.testing.assert_allclose(depth[i, 0], EXPECTED[view][2])
        np.testing.assert_allclose(unproject(i, u[i, 0], v[i, 0], depth[i, 0], CENTER, HALF, R), POINT, atol=1e-9)


def test_z_buffer_keeps_the_nearest_point_and_ignores_outside_and_nan():
    above = POINT + [0.0, 0.0, 0.2]
    outside = np.array([2.0, 0.0, 0.4])
    xyz = np.array([POINT, above, outside, [np.nan] * 3], dtype=np.float32)
    rgb = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [9, 9, 9]], np.uint8)
    views = render_views(xyz, rgb, CENTER, HALF, R)
    top = VIEWS.index("top")
    u, v, _ = EXPECTED["top"]
    assert channel(views, "occupancy")[top].sum() == 1  # both points share the top pixel
    np.testing.assert_allclose(channel(views, "g")[top, v, u], 1.0)  # the upper one wins
    np.testing.assert_allclose(channel(views, "depth")[top, v, u], 0.5, atol=DEPTH_STEP)
    assert channel(views, "occupancy")[VIEWS.index("front")].sum() == 2


@pytest.mark.parametrize("resolution", [128, 224])
def test_resolution_and_empty_input(resolution):
    views = render_views(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint8), CENTER, HALF, resolution)
    assert views.shape == (5, len(CHANNELS), resolution, resolution)
    assert not views.any()
