"""Fusion: two offset cameras, each seeing one side of a box, reconstruct the whole box."""
from __future__ import annotations

import numpy as np

from actaim2.perception.cloud_codec import decode, encode
from actaim2.perception.fusion import NO_COLOUR, CameraCloud, FusionConfig, fuse
from actaim2.perception.synthetic import RaycastScene, box_mesh
from actaim2.sim.cameras import look_at_optical

BOX_CENTER = np.array([0.5, 0.0, 0.3])
BOX_SIZE = np.array([0.2, 0.3, 0.25])


def distance_to_box_surface(points):
    d = np.abs(points - BOX_CENTER) - BOX_SIZE / 2
    outside = np.linalg.norm(np.maximum(d, 0), axis=1)
    inside = np.minimum(d.max(axis=1), 0)
    return np.abs(outside + inside)


def two_camera_clouds():
    scene = RaycastScene([(box_mesh(BOX_CENTER, BOX_SIZE), (200, 40, 40))])
    cameras = [look_at_optical(BOX_CENTER + [0.3, 0.8, 0.4], BOX_CENTER), look_at_optical(BOX_CENTER + [-0.3, -0.8, 0.4], BOX_CENTER)]
    clouds = []
    for T in cameras:
        xyz, rgb = scene.capture(T, 160, 120)
        wire = encode(xyz, rgb)  # through the message layout, as the node receives them
        decoded = decode(wire.fields, wire.data, wire.height, wire.width, wire.point_step, wire.row_step)
        clouds.append(CameraCloud(decoded.xyz, decoded.rgb, T))
    return clouds


def test_two_offset_cameras_reconstruct_a_known_box():
    clouds = two_camera_clouds()
    config = FusionConfig(center=(0.5, 0.0, 0.4), half_extent=0.5, voxel_size=0.0)
    fused = fuse(clouds, config)
    assert np.all(distance_to_box_surface(fused.xyz) < 1e-4)
    np.testing.assert_array_equal(np.unique(fused.rgb, axis=0), [[200, 40, 40]])
    # Each camera alone sees one y face; together both faces and the full box extent appear.
    for cloud, face_y in zip(clouds, (BOX_SIZE[1] / 2, -BOX_SIZE[1] / 2)):
        alone = fuse([cloud], config).xyz
        assert np.any(np.abs(alone[:, 1] - face_y) < 1e-4) and not np.any(np.abs(alone[:, 1] + face_y) < 1e-4)
    np.testing.assert_allclose(fused.xyz.min(axis=0), BOX_CENTER - BOX_SIZE / 2, atol=0.01)
    np.testing.assert_allclose(fused.xyz.max(axis=0), BOX_CENTER + BOX_SIZE / 2, atol=0.01)


def test_voxel_grid_averages_and_crop_removes_outside_points():
    clouds = two_camera_clouds()
    full = fuse(clouds, FusionConfig(center=(0.5, 0.0, 0.4), half_extent=0.5, voxel_size=0.0))
    # (0.0085 m keeps the box faces off voxel boundaries, where float32 and float64 could disagree)
    voxels = fuse(clouds, FusionConfig(center=(0.5, 0.0, 0.4), half_extent=0.5, voxel_size=0.0085))
    origin = np.array([0.5, 0.0, 0.4]) - 0.5
    full_keys = np.floor((full.xyz - origin) / 0.0085).astype(int)
    unique_keys, inverse = np.unique(full_keys, axis=0, return_inverse=True)
    assert len(voxels.xyz) == len(unique_keys) < len(full.xyz)
    means = np.stack([np.bincount(inverse.ravel(), weights=full.xyz[:, i]) for i in range(3)], 1) / np.bincount(inverse.ravel())[:, None]
    order = np.lexsort(np.floor((voxels.xyz - origin) / 0.0085).astype(int).T[::-1])
    np.testing.assert_allclose(voxels.xyz[order], means, atol=1e-5)  # each voxel holds its points' mean
    cropped = fuse(clouds, FusionConfig(center=(0.5, 0.0, 0.5), half_extent=0.1, voxel_size=0.0))
    assert len(cropped.xyz) and np.all(cropped.xyz[:, 2] >= 0.4 - 1e-6)


def test_xyz_only_clouds_get_the_neutral_colour_and_outliers_can_be_removed():
    cloud = two_camera_clouds()[0]
    stray = np.array([[0.9, 0.4, 0.85]], np.float32)  # one isolated return in camera frame terms
    T = cloud.T_world_cloud
    stray_cam = (stray - T[:3, 3]) @ T[:3, :3]
    with_stray = CameraCloud(np.concatenate([cloud.xyz, stray_cam.astype(np.float32)]), None, T)
    config = FusionConfig(center=(0.5, 0.0, 0.5), half_extent=0.45, voxel_size=0.005)
    plain = fuse([with_stray], config)
    assert np.all(plain.rgb == NO_COLOUR)
    assert np.any(np.linalg.norm(plain.xyz - stray, axis=1) < 1e-3)
    filtered = fuse([with_stray], FusionConfig(config.center, config.half_extent, 0.005, outlier_neighbors=10))
    assert not np.any(np.linalg.norm(filtered.xyz - stray, axis=1) < 1e-3)
    assert len(filtered.xyz) > 0.95 * len(plain.xyz)


def test_payload_views_fuse_like_copies():
    """A payload as rclpy delivers it (a writable array.array) decodes to a view that fusion reads
    in place; the fused cloud is the one of contiguous copies, bit for bit."""
    import array

    config = FusionConfig(center=tuple(BOX_CENTER), half_extent=0.4)
    views, copies = [], []
    for cloud in two_camera_clouds():
        wire = encode(cloud.xyz.reshape(120, 160, 3), cloud.rgb.reshape(120, 160, 3))
        payload = array.array("B", wire.data)
        decoded = decode(wire.fields, payload, wire.height, wire.width, wire.point_step,
                         wire.row_step)
        assert np.shares_memory(decoded.xyz, np.frombuffer(payload, np.uint8))
        views.append(CameraCloud(decoded.xyz, decoded.rgb, cloud.T_world_cloud))
        copy = np.ascontiguousarray(decoded.xyz)
        copies.append(CameraCloud(copy, decoded.rgb.copy(), cloud.T_world_cloud))
    fused, reference = fuse(views, config), fuse(copies, config)
    assert len(fused.xyz) > 1000
    np.testing.assert_array_equal(fused.xyz, reference.xyz)
    np.testing.assert_array_equal(fused.rgb, reference.rgb)
