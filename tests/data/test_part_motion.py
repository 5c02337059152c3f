"""Part motion from robot-hidden depth pictures, and the visual success label built on it.

Synthetic pairs: boxes ray-cast analytically by the ring5 cameras, a part moved by a known
rigid motion (or not at all). The simulator pair: a generated door and a generated table
drawer rendered by SimEnv's robot-hidden cameras at half-open and at 20% and 35% of their
range further, told apart by the label with its shipped calibration.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from actaim2.data.labelling import success_scores
from actaim2.data.part_motion import part_motions
from actaim2.data.success import DEFAULT_MODEL
from actaim2.data.trajectory import CameraImage
from actaim2.sim.cameras import ring5

CENTER = np.array([0.75, 0.0, 0.4])
CAMERAS = ring5(CENTER)
BODY = (np.eye(4), np.array([0.2, 0.3, 0.3]), (120, 120, 130))  # a cabinet body standing on the floor
BODY[0][:3, 3] = [0.95, 0.0, 0.3]


def _box_pose(center: np.ndarray, R: np.ndarray = np.eye(3)) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, center
    return T


def render(boxes: list[tuple[np.ndarray, np.ndarray, tuple[int, int, int]]]) -> dict[str, CameraImage]:
    """Each ring5 camera's picture of the floor (z = 0) and oriented boxes (pose, half sizes, colour)."""
    pictures = {}
    for spec in CAMERAS:
        rays = spec.pixel_rays().reshape(-1, 3)  # optical frame, z = 1
        T = spec.T_world_optical
        d, o = rays @ T[:3, :3].T, T[:3, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            t_best = np.where(d[:, 2] < -1e-9, -o[2] / d[:, 2], np.inf)
            colour = np.tile(np.array([90, 90, 100], np.uint8), (len(d), 1))
            for pose, half, rgb in boxes:
                R, c = pose[:3, :3], pose[:3, 3]
                ol, dl = (o - c) @ R, d @ R  # ray in the box frame
                t1, t2 = (-half - ol) / dl, (half - ol) / dl
                near, far = np.nanmax(np.minimum(t1, t2), axis=1), np.nanmin(np.maximum(t1, t2), axis=1)
                hit = (near <= far) & (near > 0) & (near < t_best)
                t_best = np.where(hit, near, t_best)
                colour[hit] = rgb
        depth = np.where(np.isfinite(t_best) & (t_best < 5.0), t_best, 0.0)  # t is z-depth: rays have z = 1
        # what the stored pictures hold: millimetre depth
        depth = np.round(depth * 1000.0) / 1000.0
        pictures[spec.name] = CameraImage(colour.reshape(spec.height, spec.width, 3),
                                          depth.reshape(spec.height, spec.width).astype(np.float32), spec.K, spec.T_world_optical)
    return pictures


def door(angle_deg: float) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int]]:
    """A 0.4 m wide door on the body's front (x = 0.75), hinged at y = -0.2, opened towards the robot (-x)."""
    hinge = np.array([0.74, -0.2, 0.3])
    R = Rotation.from_euler("z", angle_deg, degrees=True).as_matrix()
    return _box_pose(hinge + R @ np.array([-0.01, 0.2, 0.0]), R), np.array([0.01, 0.2, 0.12]), (200, 160, 90)


def drawer(pulled: float) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int]]:
    """A drawer front 0.3 m wide above the door, pulled ``pulled`` m out of the body towards the robot."""
    return _box_pose(np.array([0.73 - pulled, 0.0, 0.5])), np.array([0.02, 0.15, 0.04]), (160, 90, 90)


def test_an_unmoved_pair_has_no_moving_part():
    scene = render([BODY, door(40.0)])
    assert part_motions(scene, scene) == []
    assert success_scores([[]], DEFAULT_MODEL)[0] == 0.0 < DEFAULT_MODEL.threshold


@pytest.mark.parametrize("angle", [8.0, 25.0])
def test_a_door_swing_is_measured_as_its_angle(angle):
    parts = part_motions(render([BODY, door(40.0)]), render([BODY, door(40.0 + angle)]))
    assert len(parts) == 1
    p = parts[0]
    assert np.degrees(p.angle) == pytest.approx(angle, abs=1.0)
    assert abs(abs(p.axis[2]) - 1.0) < 0.02  # the hinge is vertical
    assert p.radius == pytest.approx(0.4, abs=0.03)  # the door's width: its far edge is the lever arm


@pytest.mark.parametrize("pulled", [0.03, 0.09])
def test_a_drawer_pull_is_measured_as_its_travel(pulled):
    parts = part_motions(render([BODY, drawer(0.05)]), render([BODY, drawer(0.05 + pulled)]))
    assert len(parts) == 1
    p = parts[0]
    assert np.degrees(p.angle) < 1.0 and p.radius == 0.0  # a translation
    assert p.shift == pytest.approx(pulled, abs=0.003)
    assert abs(p.axis[0]) > 0.99  # along the pull


def test_two_parts_moving_are_two_parts():
    parts = part_motions(render([BODY, door(40.0), drawer(0.05)]), render([BODY, door(60.0), drawer(0.05)]))
    assert len(parts) == 1  # only the door moved
    parts = part_motions(render([BODY, drawer(0.05), door(40.0)]), render([BODY, drawer(0.15), door(60.0)]))
    assert len(parts) == 2
    assert sorted(round(float(np.degrees(p.angle))) for p in parts) == [0, 20]


@pytest.fixture(scope="module")
def sim():
    from actaim2.sim.env import SimEnv

    return SimEnv("panda", cameras="ring5")


def _observe(env, category: str, instance: int, fraction: np.ndarray) -> dict[str, CameraImage]:
    from actaim2.data.collect import from_sim

    env.reset(category, instance, seed=0, dof_fraction=fraction, jitter=False)
    return from_sim(env.observe(with_robot=False))


@pytest.mark.parametrize("category, instance, dof, kind", [("door", 0, 0, "revolute"), ("table", 0, 0, "prismatic")])
def test_moves_of_20_and_35_percent_of_the_range_are_told_apart(sim, category, instance, dof, kind):
    """One part of a generated object, rendered half-open and then 20% and 35% of its range further."""
    info = sim.reset(category, instance, seed=0, jitter=False)
    n = len(info.dof_names)
    span = float(info.dof_upper[dof] - info.dof_lower[dof])
    start = np.full(n, 0.5)
    init = _observe(sim, category, instance, start)
    scores = {}
    for moved in (0.2, 0.35):
        fraction = start.copy()
        fraction[dof] += moved
        parts = part_motions(init, _observe(sim, category, instance, fraction))
        assert len(parts) == 1, f"{category}: {parts}"
        measured = parts[0].angle if kind == "revolute" else parts[0].shift
        assert measured == pytest.approx(moved * span, rel=0.1), f"{category} {moved:.0%}: {measured} vs {moved * span}"
        scores[moved] = float(success_scores([parts], DEFAULT_MODEL)[0])
    assert scores[0.2] < DEFAULT_MODEL.threshold < scores[0.35], scores
