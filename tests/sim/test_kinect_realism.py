"""Azure Kinect sensor realism: each effect measured on synthetic frames of known geometry or on
rendered frames of the floor-and-box scene of test_cameras, with its switch off and on; the
documented numbers of the ``azure_kinect`` preset; and /points2 from sim_node with the rig's
defaults still in DESIGN.md's layout."""
from __future__ import annotations

import numpy as np
import pytest
import sapien
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import PointCloud2, PointField

from actaim2.sim.cameras import AZURE_KINECT_BASELINE, CameraFrame, make_rig
from actaim2.sim.observe import CameraRig
from actaim2.sim.render_raycast import entity_colour
from actaim2.sim.render_sapien import SapienRenderer
from actaim2.sim.sensor_noise import SensorNoise
from actaim2_ros.pointcloud2 import from_msg
from harness import wait_for
from test_cameras import BOX_CENTER, build_scene, needs_vulkan

AZURE = SensorNoise.preset("azure_kinect")
(KINECT,) = make_rig("azure_kinect", BOX_CENTER)
SURFACE_ID = 7  # segmentation id of the synthetic surfaces


def plane_frame(normal, distance: float, grey: int = 150, camera=KINECT) -> CameraFrame:
    """The camera's view of the plane n.p = distance (optical frame), rays through pixel centres."""
    rays = camera.pixel_rays()
    t = distance / (rays @ np.asarray(normal, dtype=float))
    xyz = np.where((t > 0)[..., None], rays * t[..., None], np.nan).astype(np.float32)
    valid = np.isfinite(xyz[..., 2])
    rgb = np.where(valid[..., None], np.full(xyz.shape, grey, np.uint8), 0).astype(np.uint8)
    return CameraFrame(camera.name, xyz, rgb, np.where(valid, SURFACE_ID, 0).astype(np.int32))


def incidence_deg(frame: CameraFrame, normal) -> np.ndarray:
    rays = frame.xyz / np.linalg.norm(frame.xyz, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.abs(rays @ (np.asarray(normal) / np.linalg.norm(normal)))))


def test_the_preset_carries_the_documented_numbers():
    assert AZURE.depth_noise_std * 3.86 == pytest.approx(0.017)  # random error std <= 17 mm
    assert (AZURE.systematic_error, AZURE.systematic_error_per_metre) == (0.011, 0.001)  # < 11 mm + 0.1% of distance
    assert AZURE.min_ir_signal == pytest.approx(0.15 / 5.46**2)  # 15% reflectivity at the NFOV binned max range
    fov = KINECT.with_nominal_fov()
    # NFOV 75 x 65 degrees edge to edge, on the 320x288 (binned) pixel grid
    assert np.degrees(2 * np.arctan(fov.cx / fov.fx)) == pytest.approx(75.0)
    assert np.degrees(2 * np.arctan(fov.cy / fov.fy)) == pytest.approx(65.0)
    colour = KINECT.colour
    assert np.degrees(2 * np.arctan(colour.cx / colour.fx)) == pytest.approx(90.0)  # 90 x 59 degrees (16:9)
    assert np.degrees(2 * np.arctan(colour.cy / colour.fy)) == pytest.approx(59.0)
    T = KINECT.T_optical_colour
    assert np.linalg.norm(T[:3, 3]) == pytest.approx(AZURE_KINECT_BASELINE) and T[0, 3] > 0
    assert np.degrees(np.arccos(T[2, 2])) == pytest.approx(6.0)  # the depth camera looks 6 degrees lower
    assert SensorNoise.preset("rig", "azure_kinect") == AZURE and SensorNoise.preset("rig", "ring5") == SensorNoise()
    with pytest.raises(ValueError, match="needs a rig"):
        SensorNoise.preset("rig")


def test_range_noise_grows_with_distance_and_the_bias_stays_within_its_bound():
    rng = np.random.default_rng(0)
    random_only = SensorNoise(depth_noise_std=AZURE.depth_noise_std)
    stds = []
    for distance in (1.0, 2.0, 3.0):
        clean = plane_frame([0.0, 0.0, 1.0], distance)
        noisy = random_only.apply(clean, rng)
        both = np.isfinite(noisy.depth)
        # points move along their rays: x/z and y/z are unchanged
        np.testing.assert_allclose(noisy.xyz[both][:, 0] / noisy.depth[both], clean.xyz[both][:, 0] / distance, atol=1e-5)
        stds.append(np.std(noisy.depth[both] - distance))
    np.testing.assert_allclose(stds, 0.017 / 3.86 * np.array([1.0, 2.0, 3.0]), rtol=0.03)
    systematic_only = SensorNoise(systematic_error=AZURE.systematic_error, systematic_error_per_metre=AZURE.systematic_error_per_metre)
    shifted = systematic_only.apply(plane_frame([0.0, 0.0, 1.0], 2.0), rng, bias=-1.0)
    np.testing.assert_allclose(shifted.depth[np.isfinite(shifted.depth)], 2.0 - (0.011 + 0.001 * 2.0), atol=1e-6)
    biases = systematic_only.draw_biases([KINECT] * 200, rng)
    assert all(-1.0 <= b <= 1.0 for b in biases.values())


def step_frame() -> CameraFrame:
    """A wall at 1.0 m on the left half of the image, at 1.5 m on the right half."""
    near, far = plane_frame([0.0, 0.0, 1.0], 1.0), plane_frame([0.0, 0.0, 1.0], 1.5)
    right = np.arange(KINECT.width) >= KINECT.width // 2
    return CameraFrame(KINECT.name, np.where(right[None, :, None], far.xyz, near.xyz), near.rgb, near.segmentation)


def test_flying_pixels_appear_at_a_depth_edge_only_when_switched_on():
    frame = step_frame()
    edge_columns = [KINECT.width // 2 - 1, KINECT.width // 2]
    rng = np.random.default_rng(1)

    def between(f: CameraFrame) -> np.ndarray:
        return (f.depth > 1.0 + 1e-4) & (f.depth < 1.5 - 1e-4)  # NaN compares False

    no_edges = SensorNoise().apply(frame, rng)
    assert np.isfinite(no_edges.depth).all() and not between(no_edges).any()
    invalidated = SensorNoise(edge_jump_ratio=AZURE.edge_jump_ratio).apply(frame, rng)
    assert not between(invalidated).any()
    assert np.array_equal(np.flatnonzero(~np.isfinite(invalidated.depth).all(axis=0)), edge_columns)
    flying = SensorNoise(edge_jump_ratio=AZURE.edge_jump_ratio, flying_pixel_rate=AZURE.flying_pixel_rate).apply(frame, rng)
    fly = between(flying)
    assert set(np.flatnonzero(fly.any(axis=0))) == set(edge_columns)  # only at the edge
    assert fly.sum() / (2 * KINECT.height) == pytest.approx(AZURE.flying_pixel_rate, abs=0.06)
    # a flying pixel stays on its own ray
    rays = KINECT.pixel_rays()[fly]
    np.testing.assert_allclose(flying.xyz[fly] / flying.depth[fly][:, None], rays, atol=1e-5)


def test_pixels_seen_at_grazing_angles_do_not_return():
    normal = [np.sin(np.radians(70.0)), 0.0, -np.cos(np.radians(70.0))]  # a wall turned 70 degrees away
    frame = plane_frame(normal, -1.0)
    angle = incidence_deg(frame, normal)
    assert angle[np.isfinite(angle)].min() < 60.0 and angle[np.isfinite(angle)].max() > 85.0
    out = SensorNoise(grazing_angle_deg=AZURE.grazing_angle_deg).apply(frame, np.random.default_rng(0))
    invalid = ~np.isfinite(out.depth)
    interior = np.zeros_like(invalid)
    interior[1:-1, 1:-1] = True  # normals need both neighbours
    interior &= frame.depth < KINECT.max_depth  # NaN compares False
    assert invalid[interior & (angle > 80.5)].mean() > 0.99
    assert invalid[interior & (angle < 79.5)].mean() < 0.01
    assert not (~np.isfinite(SensorNoise().apply(frame, np.random.default_rng(0)).depth) & interior).any()


def test_dark_surfaces_do_not_return():
    dark_switch = SensorNoise(min_ir_signal=AZURE.min_ir_signal)
    rng = np.random.default_rng(0)
    black, grey = plane_frame([0.0, 0.0, 1.0], 1.2, grey=10), plane_frame([0.0, 0.0, 1.0], 1.2, grey=150)
    assert not np.isfinite(dark_switch.apply(black, rng).depth).any()
    assert np.isfinite(dark_switch.apply(grey, rng).depth).all()
    assert np.isfinite(SensorNoise().apply(black, rng).depth).all()
    # a 15%-reflective surface seen head-on still returns near the far end of the binned range
    # (5.46 m), a 10% one does not even at 5 m
    fifteen, ten = (round(255 * r ** (1 / 2.2)) + 1 for r in (0.15, 0.10))
    far = plane_frame([0.0, 0.0, 1.0], 5.4, grey=fifteen)
    head_on = incidence_deg(far, [0.0, 0.0, 1.0]) < 10.0
    assert np.isfinite(dark_switch.apply(far, rng).depth[head_on]).all()
    assert not np.isfinite(dark_switch.apply(plane_frame([0.0, 0.0, 1.0], 5.0, grey=ten), rng).depth).any()


def test_specular_surfaces_return_only_near_normal_incidence():
    normal = [np.sin(np.radians(20.0)), 0.0, -np.cos(np.radians(20.0))]
    frame = plane_frame(normal, -1.0)
    angle = incidence_deg(frame, normal)
    model = SensorNoise(specular_lobe_deg=AZURE.specular_lobe_deg)
    out = model.apply(frame, np.random.default_rng(0), specular_ids=frozenset({SURFACE_ID}))
    valid = np.isfinite(out.depth)
    interior = np.zeros_like(valid)
    interior[1:-1, 1:-1] = True
    assert valid[interior & (angle < 19.5)].mean() > 0.99 and not valid[interior & (angle > 20.5)].any()
    matte = model.apply(frame, np.random.default_rng(0), specular_ids=frozenset({SURFACE_ID + 1}))
    assert np.isfinite(matte.depth[interior]).all()


@needs_vulkan
def test_the_renderer_tells_glossy_metal_from_matte():
    scene, floor, box = build_scene(render=True)
    builder = scene.create_actor_builder()
    chrome = sapien.render.RenderMaterial(base_color=[0.8, 0.8, 0.8, 1.0], metallic=1.0, roughness=0.1)
    builder.add_box_visual(half_size=[0.05, 0.05, 0.05], material=chrome)
    builder.add_box_collision(half_size=[0.05, 0.05, 0.05])
    handle = builder.build_static(name="chrome")
    handle.set_pose(sapien.Pose(BOX_CENTER + [-0.25, 0.0, 0.0]))
    renderer = SapienRenderer(scene, [KINECT])
    renderer.render()
    assert renderer.specular_entities() == {handle.per_scene_id}


@pytest.fixture(scope="module")
def floor_and_box():
    scene, floor, box = build_scene(render=False)
    yield floor, box, lambda noise: CameraRig(scene, [KINECT], "raycast", noise=noise, seed=0).observe(0.0).frames[KINECT.name]


def test_registration_shadow_behind_a_foreground_edge(floor_and_box):
    floor, box, observe = floor_and_box
    box_colour = entity_colour("box")
    frames = {on: observe(SensorNoise(colour_registration=on)) for on in (False, True)}
    shadows = {}
    for on, frame in frames.items():
        on_floor = frame.segmentation == floor.per_scene_id
        shadows[on] = on_floor & np.all(frame.rgb == box_colour, axis=-1)
    assert not shadows[False].any()
    rows, cols = np.nonzero(shadows[True])
    assert len(rows) > 50
    # The colour camera sits 32 mm to the right (+x): it sees past the box's right side and cannot
    # see the floor just left of the box, which takes the box's colour (the SDK has no occlusion test).
    on_box = frames[True].segmentation == box.per_scene_id
    left_edge = np.array([np.flatnonzero(on_box[r]).min() if on_box[r].any() else -1 for r in rows])
    assert np.mean((left_edge - cols >= 1) & (left_edge - cols <= 3)) > 0.9
    # Depth pixels the colour camera cannot see at all (the bottom of the depth image: the colour
    # camera looks 6 degrees higher) are dropped, as the driver drops points without colour.
    lost = np.isfinite(frames[False].depth) & ~np.isfinite(frames[True].depth)
    assert lost.any() and np.flatnonzero(lost.any(axis=1)).min() > KINECT.height * 0.8


def test_the_documented_field_of_view_is_rendered(floor_and_box):
    _, _, observe = floor_and_box
    for nominal, half_angle in ((False, np.degrees(np.arctan(KINECT.cx / KINECT.fx))), (True, 37.5)):
        frame = observe(SensorNoise(nominal_fov=nominal))
        valid = np.isfinite(frame.depth)
        widest = np.degrees(np.arctan(np.abs(frame.xyz[valid][:, 0] / frame.depth[valid]))).max()
        pixel = 75.0 / KINECT.width  # the outermost pixel centre is half a pixel inside the edge
        assert half_angle - pixel < widest < half_angle, nominal


def test_sim_node_points2_layout_with_the_rigs_default_realism(start_node, ros_node):
    params = dict(rig="azure_kinect", render_path="raycast", real_time_factor=0.0, camera_rate=2.0,
                  category="storage_furniture", instance=0, seed=0)
    process = start_node("actaim2_sim", "sim_node", params)
    messages = []
    ros_node.create_subscription(PointCloud2, "/points2", messages.append, qos_profile_sensor_data)
    assert wait_for(lambda: messages, 60.0), process.output()
    msg = messages[-1]
    assert (msg.header.frame_id, msg.height, msg.width, msg.point_step, msg.row_step) == ("depth_camera_link", 288, 320, 32, 32 * 320)
    assert not msg.is_dense and not msg.is_bigendian
    assert [(f.name, f.offset, f.datatype, f.count) for f in msg.fields] == [
        ("x", 0, PointField.FLOAT32, 1), ("y", 4, PointField.FLOAT32, 1),
        ("z", 8, PointField.FLOAT32, 1), ("rgb", 16, PointField.FLOAT32, 1)]
    cloud = from_msg(msg)
    xyz = cloud.xyz.reshape(288, 320, 3)
    valid = np.isfinite(xyz).all(axis=-1)
    assert 0.2 < valid.mean() < 0.9
    assert not valid[-30:].any()  # below the colour camera's view: no colour, no point (the driver's rule)
    assert np.all(cloud.rgb[~valid.ravel()] == 0)
    # the widest point lies beyond the 64.8-degree pinhole of fx = 252 px: the 75-degree NFOV is rendered
    assert np.degrees(np.arctan(np.abs(xyz[valid][:, 0] / xyz[valid][:, 2]))).max() > 34.0
    assert process.alive()
