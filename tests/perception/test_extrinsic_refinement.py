"""The camera extrinsic refined from the robot itself: the Kinova seen by the azure_kinect rig, rendered
by SAPIEN (its visual meshes, as the stand-in's demonstrations are; the ray-cast path draws the collision
hulls instead), with the rig's range noise, flying pixels and missing returns on.

A known error of 1 cm and 1 deg (each in a random direction) is put into the extrinsic the refinement
is given; it must bring the camera back to within 3 mm and 0.3 deg of the pose it rendered from. A fit
that cannot be trusted is refused, the given extrinsic kept and the reason said: no arm in the cloud,
a robot model posed elsewhere than the arm in the cloud, a poor fit, a correction beyond the bound.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from actaim2.perception.extrinsic_refinement import (
    ExtrinsicRefiner,
    RefinementLimits,
    RobotSurface,
    front_pixels,
)
from actaim2.sim.env import SimEnv
from actaim2.sim.sensor_noise import SensorNoise

CAMERA = "azure_kinect"


@pytest.fixture(scope="module")
def scene():
    """(robot-visible cloud, robot-hidden cloud, the pose it was rendered from, joint positions, refiner)."""
    noise = dataclasses.replace(SensorNoise.preset("rig", CAMERA), extrinsic_translation_std=0.0,
                                extrinsic_rotation_std_deg=0.0, systematic_error=0.0, systematic_error_per_metre=0.0)
    env = SimEnv("kinova_j2s6s200", cameras=CAMERA, render_path="sapien", noise=noise)  # raises without Vulkan
    env.reset("three_drawer_shelf", 0, seed=1)
    names, q, _ = env.joint_state()
    with_robot, without = env.observe(with_robot=True), env.observe(with_robot=False)
    return (with_robot.frames[CAMERA].xyz, without.frames[CAMERA].xyz, with_robot.cameras[CAMERA].T_world_optical,
            dict(zip(names, q.astype(float))), ExtrinsicRefiner(RobotSurface(env.spec)))


def camera_error(T: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    delta = np.linalg.inv(T_true) @ T
    return float(np.linalg.norm(delta[:3, 3])), float(np.rad2deg(Rotation.from_matrix(delta[:3, :3]).magnitude()))


def miscalibrated(T: np.ndarray, metres: float, degrees: float, rng: np.random.Generator) -> np.ndarray:
    """``T`` moved by ``metres`` and turned by ``degrees`` in random directions of its own frame."""
    shift, axis = (v / np.linalg.norm(v) for v in rng.normal(size=(2, 3)))
    delta = np.eye(4)
    delta[:3, :3] = Rotation.from_rotvec(np.deg2rad(degrees) * axis).as_matrix()
    delta[:3, 3] = metres * shift
    return T @ delta


def test_a_1_cm_1_deg_extrinsic_error_is_recovered_to_3_mm_and_0_3_deg(scene):
    xyz, _, T_true, joints, refiner = scene
    rng = np.random.default_rng(0)
    for _ in range(3):
        wrong = miscalibrated(T_true, 0.01, 1.0, rng)
        assert camera_error(wrong, T_true) == pytest.approx((0.01, 1.0))
        fit = refiner.refine(xyz, wrong, joints)
        assert fit.accepted, fit.reason
        translation, rotation = camera_error(fit.T_world_optical, T_true)
        assert translation <= 0.003 and rotation <= 0.3, (translation, rotation, fit.to_json())
        assert np.allclose(fit.correction @ wrong, fit.T_world_optical)


def test_a_fit_that_cannot_be_trusted_is_refused_with_its_reason(scene):
    xyz, hidden, T_true, joints, refiner = scene
    wrong = miscalibrated(T_true, 0.01, 1.0, np.random.default_rng(1))
    stale = {**joints, "j2s6s200_joint_1": joints["j2s6s200_joint_1"] + 0.08}  # joint states of another moment
    strict = ExtrinsicRefiner(refiner.surface, RefinementLimits(min_fitness=0.99, max_rmse=0.001))
    bounded = ExtrinsicRefiner(refiner.surface, RefinementLimits(max_translation=0.005, max_rotation_deg=0.5))
    refusals = {
        "too little of the arm in view": refiner.refine(np.full_like(xyz, np.nan), wrong, joints),
        # the robot hidden: what lies where it stands (the floor by its base) is no arm to fit
        "": refiner.refine(hidden, wrong, joints),
        # the model posed where the arm was not: fitting it moves the camera far beyond a calibration's error
        "beyond the bound 30 mm / 3.0 deg": refiner.refine(xyz, wrong, stale),
        "poor fit: ": strict.refine(xyz, wrong, joints),
        "beyond the bound 5 mm / 0.5 deg": bounded.refine(xyz, wrong, joints),
    }
    for reason, fit in refusals.items():
        assert not fit.accepted and reason in fit.reason, (reason, fit.reason)
        assert np.array_equal(fit.T_world_optical, wrong) and np.array_equal(fit.correction, np.eye(4))


def test_front_pixels_leave_out_what_lies_just_behind_a_foreground_edge():
    xyz = np.ones((3, 4, 3))
    xyz[..., 2] = [[1.0, 1.0, 2.0, 2.0], [1.0, 1.0, 1.5, 2.0], [1.0, 1.0, 2.0, np.nan]]
    keep = front_pixels(xyz)
    # the foreground (1 m) and its silhouette stay; a flying pixel (1.5 m) and the background beside the
    # foreground go; the background away from the edge stays; no return is no pixel
    assert keep.tolist() == [[True, True, False, True], [True, True, False, False], [True, True, False, False]]
