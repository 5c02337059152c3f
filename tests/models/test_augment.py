"""RVT scene augmentation: the scene and the keypose move together, within the configured ranges."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from actaim2.models.augment import (
    AugmentConfig,
    augment,
    sample_perturbation,
    transform_keypose,
    views_cloud,
)
from actaim2.models.rotation_bins import geodesic_deg
from actaim2.models.view_geometry import CubePlacement
from actaim2.perception.ortho_views import CHANNELS, VIEWS, project, render_views

PLACEMENT = CubePlacement((0.5, 0.0, 0.4), 0.6)
R = 128
TOP = VIEWS.index("top")


def box_scene() -> tuple[np.ndarray, np.ndarray]:
    """A floor and a 30 x 40 x 30 cm box sampled every 4 mm, coloured by face."""
    s = np.arange(-0.5, 0.5, 0.004)
    floor = np.stack(np.meshgrid(s + 0.5, s, [0.0], indexing="ij"), -1).reshape(-1, 3)
    t = np.arange(0.0, 1.0, 0.01)
    u, v = np.meshgrid(t, t, indexing="ij")
    top = np.stack([0.45 + 0.3 * u, -0.2 + 0.4 * v, np.full_like(u, 0.3)], -1).reshape(-1, 3)
    front = np.stack([np.full_like(u, 0.45), -0.2 + 0.4 * u, 0.3 * v], -1).reshape(-1, 3)
    xyz = np.concatenate([floor, top, front]).astype(np.float32)
    rgb = np.concatenate([np.full((len(floor), 3), 90), np.tile([200, 30, 30], (len(top), 1)), np.tile([30, 30, 200], (len(front), 1))]).astype(np.uint8)
    return xyz, rgb


def keypose_on_the_box() -> np.ndarray:
    quat = Rotation.from_euler("xyz", [180.0, 0.0, 30.0], degrees=True).as_quat()
    return np.concatenate([[0.55, 0.05, 0.3], quat, [0.0]])


def test_scene_and_keypose_move_together():
    xyz, rgb = box_scene()
    views = render_views(xyz, rgb, PLACEMENT.center, PLACEMENT.half_extent, R)
    config = AugmentConfig()
    for seed in range(5):
        views2, keypose2 = augment(views, keypose_on_the_box(), PLACEMENT, np.random.default_rng(seed), config)
        T = sample_perturbation(np.random.default_rng(seed), config, PLACEMENT)  # the same first draw
        np.testing.assert_allclose(keypose2, transform_keypose(T, keypose_on_the_box()))
        yaw = Rotation.from_matrix(T[:3, :3]).as_rotvec()
        assert abs(yaw[0]) < 1e-9 and abs(yaw[1]) < 1e-9 and 0 < abs(np.degrees(yaw[2])) <= config.max_yaw_deg
        shift = T[:3, 3] - (np.asarray(PLACEMENT.center) - T[:3, :3] @ np.asarray(PLACEMENT.center))
        assert np.abs(shift).max() <= config.max_translation
        # The keypose sits on the box top: after the move, the top view shows the box top there.
        u, v, _ = project(keypose2[:3], PLACEMENT.center, PLACEMENT.half_extent, R)
        column, row = int(u[TOP, 0]), int(v[TOP, 0])
        assert views2[TOP, CHANNELS.index("occupancy"), row, column] > 0
        np.testing.assert_allclose(views2[TOP, :3, row, column], [200 / 255, 30 / 255, 30 / 255], atol=1e-6)
        cube_point = views2[TOP, [CHANNELS.index(c) for c in "xyz"], row, column]
        seen = np.asarray(PLACEMENT.center) + cube_point * PLACEMENT.half_extent
        assert np.linalg.norm(seen - keypose2[:3]) <= 2 * (2 * PLACEMENT.half_extent / R)
        # Orientation turned by the same yaw, gripper untouched.
        assert abs(geodesic_deg(keypose2[None, 3:7], keypose_on_the_box()[None, 3:7])[0] - abs(np.degrees(yaw[2]))) < 1e-6
        assert keypose2[7] == 0.0


def test_views_read_back_as_the_rendered_points():
    xyz, rgb = box_scene()
    views = render_views(xyz, rgb, PLACEMENT.center, PLACEMENT.half_extent, R)
    points, colours = views_cloud(views, PLACEMENT)
    assert len(points) == int((views[:, CHANNELS.index("occupancy")] > 0).sum())
    # Every read-back point lies near the scene surface it was rendered from (within a pixel).
    box_top = colours[:, 0] == 200
    assert box_top.any() and np.abs(points[box_top, 2] - 0.3).max() < 2 * PLACEMENT.half_extent / R


def test_a_keypose_that_cannot_stay_inside_is_left_unperturbed():
    xyz, rgb = box_scene()
    views = render_views(xyz, rgb, PLACEMENT.center, PLACEMENT.half_extent, R)
    corner = keypose_on_the_box()
    corner[:3] = [1.1, 0.6, 0.4]  # on a vertical edge of the cube: any yaw takes it outside
    views2, keypose2 = augment(views, corner, PLACEMENT, np.random.default_rng(1), AugmentConfig(max_translation=0.0, tries=5))
    assert views2 is views and np.array_equal(keypose2, corner)
