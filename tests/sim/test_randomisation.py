"""Domain randomisation (actaim2.sim.randomisation): a seed's lighting and colours reach the picture,
two seeds differ, the same seed repeats its picture exactly, and extrinsic jitter moves the cloud by
the configured amount.

Lighting and colours are checked on SAPIEN pictures (the only path that renders them) with the
placement fixed and no sensor model, so nothing but the randomised light or colour can change a
pixel. The jitter is measured on ray-cast clouds (the same geometry, cheaper, no colour needed).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from actaim2.sim.env import SimEnv
from actaim2.sim.randomisation import (
    DEFAULT_FILE,
    DomainRandomisation,
    colour_temperature_rgb,
    load_randomisation,
)

ROBOT = "kinova_j2s6s200"
OBJECT = ("storage_furniture", 0)
CAMERA = "azure_kinect"
# no sensor model, no extrinsic error: only the lighting and colours vary between seeds
CLEAN = DomainRandomisation(sensor_noise="none", extrinsic_translation_std=0.0, extrinsic_rotation_std_deg=0.0)
FIXED_COLOURS = replace(CLEAN, object_hue=(0.3, 0.3), object_saturation=(0.5, 0.5), object_value=(0.7, 0.7),
                        ground_hue=(0.1, 0.1), ground_saturation=(0.2, 0.2), ground_value=(0.6, 0.6))
FIXED_LIGHT = replace(CLEAN, ambient_intensity=(0.35, 0.35), key_light_intensity=(0.7, 0.7), key_light_elevation_deg=(56.0, 56.0),
                      key_light_azimuth_deg=(63.0, 63.0), fill_light_intensity=(0.6, 0.6), colour_temperature_k=(6500.0, 6500.0))


@pytest.fixture(scope="module")
def sapien_env() -> SimEnv:
    return SimEnv(ROBOT, cameras=CAMERA, render_path="sapien", randomisation=CLEAN)


def _picture(env: SimEnv, config: DomainRandomisation, seed: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """(rgb, depth, draw) of the robot-hidden view after a reset with ``seed`` under ``config``."""
    env.randomiser.config = config  # the scene's one randomiser: it knows the object's original colours
    env.reset(*OBJECT, seed=seed, jitter=False)
    frame = env.observe(with_robot=False).frames[CAMERA]
    return frame.rgb.astype(np.int16), np.nan_to_num(frame.depth), env.randomisation_draw


def _differ(a: np.ndarray, b: np.ndarray) -> float:
    """Mean absolute RGB difference over the pixels with a return."""
    return float(np.abs(a - b).mean())


@pytest.mark.parametrize("config, varied", [(FIXED_COLOURS, "lighting"), (FIXED_LIGHT, "colours")])
def test_two_seeds_light_or_colour_the_scene_differently_and_a_seed_repeats_its_picture(sapien_env, config, varied):
    rgb1, depth1, draw1 = _picture(sapien_env, config, seed=1)
    rgb2, depth2, draw2 = _picture(sapien_env, config, seed=2)
    rgb1_again, depth1_again, draw1_again = _picture(sapien_env, config, seed=1)  # after another episode
    assert np.array_equal(rgb1, rgb1_again) and np.array_equal(depth1, depth1_again) and draw1 == draw1_again
    assert np.mean(np.abs(depth1 - depth2) > 0.002) < 0.01  # the same geometry: only the light or the colours changed
    assert draw1[varied] != draw2[varied]
    unvaried = "colours" if varied == "lighting" else "lighting"
    assert draw1[unvaried] == draw2[unvaried]
    assert _differ(rgb1, rgb2) > 5.0, f"{varied} drawn differently left the picture unchanged"
    if varied == "colours":  # both the object and the ground took other colours
        segmentation = sapien_env.observe(with_robot=False).frames[CAMERA].segmentation
        on_object = np.isin(segmentation, list(sapien_env.sim.object_entity_ids()))
        on_ground = segmentation == sapien_env.sim.ground.per_scene_id
        assert on_object.sum() > 1000 and on_ground.sum() > 1000
        # the light is fixed and the geometry the same: any change is the drawn colour (the ground's greys are close)
        assert _differ(rgb1[on_object], rgb2[on_object]) > 5.0 and _differ(rgb1[on_ground], rgb2[on_ground]) > 2.0
        assert len(draw1["colours"]["object"]) >= 2  # grouped by original colour: carcass, fronts, handles keep apart


def test_extrinsic_jitter_moves_the_cloud_by_the_configured_amount():
    """The object's cloud, seen through the nominal extrinsics, moves by the jitter the camera was
    rendered with: a translation-only jitter of std 2 cm shifts it by ~2 cm rms per axis."""
    std = 0.02
    jittered = SimEnv(ROBOT, cameras=CAMERA, render_path="raycast",
                      randomisation=replace(CLEAN, extrinsic_translation_std=std))
    nominal = SimEnv(ROBOT, cameras=CAMERA, render_path="raycast", randomisation=CLEAN)

    def object_centre(env: SimEnv, seed: int) -> np.ndarray:
        env.reset(*OBJECT, seed=seed)  # placement randomised, the same in both simulators
        observation = env.observe(with_robot=False)
        points = observation.points_world(CAMERA)
        on_object = np.isin(observation.frames[CAMERA].segmentation, list(env.sim.object_entity_ids()))
        return points[on_object].mean(axis=0)

    shifts = np.array([object_centre(jittered, seed) - object_centre(nominal, seed) for seed in range(8)])
    rms = float(np.sqrt(np.mean(shifts**2)))
    assert 0.6 * std < rms < 1.4 * std, (rms, shifts)
    assert np.array_equal(object_centre(jittered, 3) - object_centre(nominal, 3), shifts[3])  # a seed, its jitter
    assert jittered.rig.noise.extrinsic_translation_std == std and jittered.rig.noise.extrinsic_rotation_std_deg == 0.0


def test_the_default_file_is_the_documented_configuration_and_mistakes_are_refused(tmp_path):
    assert load_randomisation("default") == DomainRandomisation() == DomainRandomisation.from_dict(DomainRandomisation().to_dict())
    assert DEFAULT_FILE.read_text().count("#") > 20  # every field described
    with pytest.raises(ValueError, match=r"unknown domain randomisation field\(s\) \['ambient_intensty'\]"):
        DomainRandomisation.from_dict({"ambient_intensty": [0.1, 0.2]})
    with pytest.raises(ValueError, match="object_value is a fraction"):
        DomainRandomisation(object_value=(0.5, 1.5))
    with pytest.raises(ValueError, match="key_light_intensity must be \\[low, high\\] with low <= high"):
        DomainRandomisation(key_light_intensity=(1.0, 0.5))
    bad = tmp_path / "dr.yaml"
    bad.write_text("placement_front: -0.1\n")
    with pytest.raises(ValueError, match=f"{bad}: invalid domain randomisation: placement_front must not be negative"):
        load_randomisation(bad)
    with pytest.raises(FileNotFoundError):
        load_randomisation(tmp_path / "missing.yaml")


def test_colour_temperature_runs_from_warm_to_cool():
    warm, daylight, cool = (colour_temperature_rgb(k) for k in (3000.0, 6600.0, 7500.0))
    assert warm[0] == 1.0 and warm[2] < 0.5 * warm[0]  # a bulb is orange
    assert np.allclose(daylight, 1.0, atol=0.02)
    assert cool[2] == 1.0 and cool[0] < 0.95
