"""Camera rigs and both render paths against geometry whose answer is known.

A static scene - a floor (z = 0) and a 0.4 x 0.6 x 0.5 m box standing at (0.8, 0, 0.25) - is
rendered by each path; every returned point, taken to ``world`` through the nominal
extrinsics (the /tf_static chain), must lie on the box or the floor. The SAPIEN path quantises
depth to 1 mm (x and y back-projected from it), so its tolerance is 3 mm; ray casting is exact to
float precision.
"""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
import sapien

from actaim2.sim.cameras import T_CAMERA_BASE_DEPTH, make_rig, ring5
from actaim2.sim.observe import CameraRig
from actaim2.sim.render_path import resolve_render_path, vulkan_device_error
from actaim2.sim.sensor_noise import SensorNoise

BOX_CENTER = np.array([0.8, 0.0, 0.25])
BOX_HALF = np.array([0.2, 0.3, 0.25])
TOLERANCE = {"sapien": 3e-3, "raycast": 1e-4}
PLANE_POSE = sapien.Pose(q=[0.7071068, 0.0, -0.7071068, 0.0])  # PhysX plane normal (+x) -> +z

needs_vulkan = pytest.mark.skipif(vulkan_device_error() is not None, reason=f"no Vulkan device: {vulkan_device_error()}")


def build_scene(render: bool) -> tuple[sapien.Scene, sapien.Entity, sapien.Entity]:
    """Floor and box; visual shapes only when the scene has a render system."""
    if render:
        scene = sapien.Scene()
        scene.set_ambient_light([0.6, 0.6, 0.6])
        scene.add_directional_light([0.3, 0.2, -1.0], [0.6, 0.6, 0.6])
    else:
        scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    builder = scene.create_actor_builder()
    builder.add_plane_collision(PLANE_POSE)
    if render:
        builder.add_plane_visual(PLANE_POSE, [10.0, 10.0, 10.0], material=[0.8, 0.8, 0.8])
    floor = builder.build_static(name="floor")
    builder = scene.create_actor_builder()
    builder.add_box_collision(half_size=BOX_HALF)
    if render:
        builder.add_box_visual(half_size=BOX_HALF, material=[0.9, 0.1, 0.1])
    box = builder.build_static(name="box")
    box.set_pose(sapien.Pose(BOX_CENTER))
    return scene, floor, box


def compose(chain) -> np.ndarray:
    T = np.eye(4)
    parent = "world"
    for p, child, T_pc in chain:
        assert p == parent, f"tf chain broken at {p} -> {child}"
        T = T @ T_pc
        parent = child
    return T


@pytest.fixture(scope="module", params=[pytest.param("sapien", marks=needs_vulkan), "raycast"])
def rendered(request):
    path = request.param
    scene, floor, box = build_scene(render=path == "sapien")
    rig = CameraRig(scene, make_rig("ring5", BOX_CENTER), path)
    yield path, rig.observe(0.0), rig.observe(0.0, hidden={box.per_scene_id}), floor, box
    del scene  # entities report per_scene_id 0 once their scene is gone: keep it until here


def test_rigs_tf_chains_compose_to_the_render_pose():
    for rig in ("ring5", "azure_kinect"):
        for cam in make_rig(rig, BOX_CENTER):
            np.testing.assert_allclose(compose(cam.tf_chain), cam.T_world_optical, atol=1e-12)
            assert cam.tf_chain[-1][1] == cam.frame_id
            axis = cam.T_world_optical[:3, 2]
            to_target = BOX_CENTER - cam.T_world_optical[:3, 3]
            # every camera looks straight at the target
            np.testing.assert_allclose(axis, to_target / np.linalg.norm(to_target), atol=1e-9)


def test_ring5_layout():
    cams = ring5(BOX_CENTER, robot_xy=np.zeros(2), width=160, height=120)
    assert [c.name for c in cams] == [f"cam{k}" for k in range(5)]
    assert [c.topic for c in cams] == [f"/cameras/cam{k}/points" for k in range(5)]
    assert all((c.width, c.height, c.cx, c.cy) == (160, 120, 80.0, 60.0) for c in cams)
    azimuths = sorted(np.degrees(np.arctan2(*(c.T_world_optical[1::-1, 3] - BOX_CENTER[1::-1]))) % 360 for c in cams)
    # 72 degrees apart, none on the line object -> robot (azimuth 180 here)
    np.testing.assert_allclose(np.diff(azimuths), 72.0, atol=1e-6)
    assert min(abs(a - 180.0) for a in azimuths) == pytest.approx(36.0)


def test_azure_kinect_matches_the_driver():
    (cam,) = make_rig("azure_kinect", BOX_CENTER)
    assert (cam.topic, cam.frame_id, cam.width, cam.height) == ("/points2", "depth_camera_link", 320, 288)
    assert [(p, c) for p, c, _ in cam.tf_chain] == [("world", "camera_base"), ("camera_base", "depth_camera_link")]
    (full,) = make_rig("azure_kinect", BOX_CENTER, width=640, height=576)
    assert (full.width, full.height, full.fx) == (640, 576, 2 * cam.fx)
    # depth_camera_link is optical (x right, y down, z forward) and looks 6 degrees below
    # camera_base's x axis (x forward, y left, z up), 1.8 mm above its origin
    R = T_CAMERA_BASE_DEPTH[:3, :3]
    tilt = np.radians(6.0)
    np.testing.assert_allclose(R[:, 2], [np.cos(tilt), 0.0, -np.sin(tilt)], atol=1e-9)
    np.testing.assert_allclose(R[:, 0], [0.0, -1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(T_CAMERA_BASE_DEPTH[:3, 3], [0.0, 0.0, 0.0018])
    # camera_base is pitched down towards the target but not rolled: its y axis is horizontal
    T_world_base = cam.tf_chain[0][2]
    assert abs(T_world_base[2, 1]) < 1e-9 and T_world_base[2, 2] > 0.5
    with pytest.raises(ValueError, match="640x576 or 320x288"):
        make_rig("azure_kinect", BOX_CENTER, width=1024, height=1024)
    with pytest.raises(ValueError, match="ring5"):
        make_rig("ring7", BOX_CENTER)


def test_points_land_on_known_geometry(rendered):
    path, obs, _, floor, box = rendered
    for name, frame in obs.frames.items():
        assert frame.xyz.shape == (240, 320, 3) and frame.xyz.dtype == np.float32
        assert frame.rgb.shape == (240, 320, 3) and frame.rgb.dtype == np.uint8
        world = obs.points_world(name)
        on_box = world[frame.segmentation == box.per_scene_id]
        on_floor = world[frame.segmentation == floor.per_scene_id]
        assert len(on_box) > 5000 and len(on_floor) > 5000, name
        # box points lie on the box surface: inside the box (within tolerance) and on a face
        outside = np.abs(on_box - BOX_CENTER) - BOX_HALF
        assert outside.max() < TOLERANCE[path]
        assert np.abs(outside).min(axis=1).max() < TOLERANCE[path]
        assert np.abs(on_floor[:, 2]).max() < TOLERANCE[path]
        # no-return pixels are NaN and carry no colour or id
        empty = ~np.isfinite(frame.xyz[..., 2])
        assert np.all(frame.segmentation[empty] == 0) and np.all(frame.rgb[empty] == 0)
        # optical frame: z is the depth, positive
        assert np.nanmin(frame.depth) > 0


def test_published_points_are_the_stored_pictures_back_projected(rendered):
    """What sim_node publishes (frame.xyz) and what training back-projects from the stored picture
    (depth and K only) are the same points: the ROS loop's views are the training views."""
    from actaim2.data.collect import from_sim
    from actaim2.data.object_cloud import back_project

    _, obs, _, _, _ = rendered
    for name, picture in from_sim(obs).items():
        xyz = obs.frames[name].xyz.reshape(-1, 3)
        stored = back_project(picture)
        assert np.array_equal(np.isfinite(xyz[:, 2]), np.isfinite(stored[:, 2])), name
        finite = np.isfinite(xyz[:, 2])
        assert np.abs(xyz[finite] - stored[finite]).max() < 1e-6, name  # float32 rounding of the same numbers


def test_hidden_entity_neither_appears_nor_occludes(rendered):
    _, obs, hidden_obs, floor, box = rendered
    for name, frame in hidden_obs.frames.items():
        assert not np.any(frame.segmentation == box.per_scene_id)
        was_box = obs.frames[name].segmentation == box.per_scene_id
        # the floor behind the box is seen instead
        assert np.mean(frame.segmentation[was_box] == floor.per_scene_id) > 0.9
    assert hidden_obs.hidden == frozenset({box.per_scene_id})


@needs_vulkan
def test_render_paths_agree():
    depths = {}
    for path in ("sapien", "raycast"):
        scene, _, box = build_scene(render=path == "sapien")
        obs = CameraRig(scene, make_rig("azure_kinect", BOX_CENTER), path).observe(0.0)
        depths[path] = obs.frames["azure_kinect"].depth
    both = np.isfinite(depths["sapien"]) & np.isfinite(depths["raycast"])
    assert both.mean() > 0.6
    # the same pixels hit something, at the same depth (1 mm quantisation aside)
    assert np.mean(np.isfinite(depths["sapien"]) == np.isfinite(depths["raycast"])) > 0.995
    assert np.median(np.abs(depths["sapien"][both] - depths["raycast"][both])) < 2e-3


def test_tof_noise_and_extrinsic_jitter():
    scene, _, box = build_scene(render=False)
    cams = make_rig("azure_kinect", BOX_CENTER)
    clean = CameraRig(scene, cams, "raycast").observe(0.0).frames["azure_kinect"]
    noisy_rig = CameraRig(scene, cams, "raycast", noise=SensorNoise.preset("tof"), seed=3)
    noisy = noisy_rig.observe(0.0).frames["azure_kinect"]
    clean_valid, noisy_valid = np.isfinite(clean.depth), np.isfinite(noisy.depth)
    assert not np.any(noisy_valid & ~clean_valid)  # noise never invents returns
    lost = 1.0 - noisy_valid.sum() / clean_valid.sum()
    assert 0.01 < lost < 0.2  # random dropouts plus the box silhouette
    # jitter: the same seed gives the same extrinsic error, another seed another one
    again = CameraRig(scene, cams, "raycast", noise=SensorNoise.preset("tof"), seed=3).observe(0.0).frames["azure_kinect"]
    assert np.array_equal(np.isfinite(again.depth), noisy_valid)
    noisy_rig.reset(4)
    other = noisy_rig.observe(0.0).frames["azure_kinect"]
    assert not np.array_equal(np.isfinite(other.depth), noisy_valid)
    # the published (nominal) extrinsics did not move
    np.testing.assert_allclose(noisy_rig.cameras["azure_kinect"].T_world_optical, cams[0].T_world_optical)
    # depth noise only: points move along their rays, a few mm at ~1.5 m
    depth_only = SensorNoise(depth_noise_std=0.002)
    shaken = depth_only.apply(clean, np.random.default_rng(0))
    both = np.isfinite(shaken.depth)
    ratio = shaken.xyz[both] / clean.xyz[both]
    np.testing.assert_allclose(ratio[:, 0], ratio[:, 2], rtol=1e-4)
    relative_error = (shaken.depth[both] - clean.depth[both]) / clean.depth[both]
    assert np.std(relative_error) == pytest.approx(0.002, rel=0.05)
    assert abs(np.mean(relative_error)) < 1e-4


def test_render_path_selection():
    assert resolve_render_path("raycast") == "raycast"
    with pytest.raises(ValueError, match="auto"):
        resolve_render_path("opengl")
    # without a Vulkan device, auto falls back to ray casting and says so; a forced sapien fails
    env = dict(os.environ, VK_ICD_FILENAMES="/nonexistent/icd.json")
    code = (
        "import logging, sys; logging.basicConfig(level=logging.INFO, stream=sys.stdout)\n"
        "from actaim2.sim.render_path import resolve_render_path\n"
        "print('PATH', resolve_render_path('auto'))\n"
        "try:\n    resolve_render_path('sapien')\nexcept RuntimeError as e:\n    print('FORCED', e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60).stdout
    assert "PATH raycast" in out
    assert "no Vulkan device" in out and "FORCED render path 'sapien' requested" in out
