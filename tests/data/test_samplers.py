"""Samplers on synthetic clouds: random (filters), heuristic grasp (antipodal on a handle), GMM (equal per cluster)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from actaim2.data.actions import ActionSequence
from actaim2.data.gmm_sampler import GMMAdaptiveSampler, GMMConfig
from actaim2.data.grasp import AntipodalConfig, AntipodalGraspProposer
from actaim2.data.grasp_sampler import HeuristicGraspSampler
from actaim2.data.gripper import collides
from actaim2.data.object_cloud import CloudConfig, ObjectCloud, part_segments
from actaim2.data.random_sampler import RandomSampler, SamplingConfig
from actaim2.robots import load_robot_spec

PANDA = SamplingConfig.for_robot(load_robot_spec("panda"))
KINOVA = SamplingConfig.for_robot(load_robot_spec("kinova_j2s6s200"))

HANDLE_CENTER = np.array([0.56, 0.0, 0.6])  # a horizontal bar 4 cm in front of a door at x = 0.6
HANDLE_RADIUS = 0.01


@pytest.fixture(scope="module")
def door_with_handle() -> ObjectCloud:
    ys, zs = np.meshgrid(np.arange(-0.3, 0.3, 0.005), np.arange(0.2, 0.8, 0.005))
    face = np.c_[np.full(ys.size, 0.6), ys.ravel(), zs.ravel()]
    t, a = np.meshgrid(np.arange(-0.08, 0.08, 0.004), np.linspace(0, 2 * np.pi, 24, endpoint=False))
    bar = HANDLE_CENTER + np.c_[HANDLE_RADIUS * np.cos(a.ravel()), t.ravel(), HANDLE_RADIUS * np.sin(a.ravel())]
    points = np.r_[face, bar]
    return ObjectCloud(points, np.zeros((len(points), 3), np.uint8))


def test_handle_is_segmented_and_grasped_antipodally(door_with_handle):
    rng = np.random.default_rng(0)
    segments = part_segments(door_with_handle, CloudConfig(center=(0.6, 0.0, 0.5)), rng)
    assert len(segments) == 1  # the door face is a plane, removed; the bar is left
    assert np.abs(door_with_handle.points[segments[0]] - HANDLE_CENTER).max() < 0.09
    grasps = AntipodalGraspProposer(AntipodalConfig(PANDA.gripper, PANDA.reach.center)).propose(door_with_handle, segments[0], 0, rng)
    assert grasps
    best = max(grasps, key=lambda g: g.score)
    T = best.T_world_tcp
    assert best.score > 0.9
    assert abs(best.width - 2 * HANDLE_RADIUS) < 0.006  # fingers close across the bar's diameter
    assert abs(T[:3, 1] @ [0.0, 1.0, 0.0]) < 0.1  # closing axis across the bar, not along it
    assert T[:3, 2] @ [1.0, 0.0, 0.0] > 0.5  # approaching from the robot's side (robot at the origin)
    offset = T[:3, 3] - HANDLE_CENTER
    assert np.hypot(offset[0], offset[2]) < 0.012  # the bar sits between the fingertips
    assert not collides(PANDA.gripper, door_with_handle.points, T)


def test_a_full_height_bar_handle_is_a_part_and_a_body_is_not():
    """A refrigerator's 45 cm vertical bar is longer than any knob, but thin: a part to grasp; a
    45 x 20 cm block standing off the door is a body."""
    ys, zs = np.meshgrid(np.arange(-0.3, 0.3, 0.005), np.arange(0.1, 0.9, 0.005))
    face = np.c_[np.full(ys.size, 0.6), ys.ravel(), zs.ravel()]
    t, a = np.meshgrid(np.arange(0.25, 0.70, 0.004), np.linspace(0, 2 * np.pi, 24, endpoint=False))
    bar = np.c_[0.56 + HANDLE_RADIUS * np.cos(a.ravel()), 0.2 + HANDLE_RADIUS * np.sin(a.ravel()), t.ravel()]
    by, bz = np.meshgrid(np.arange(-0.25, -0.05, 0.005), np.arange(0.25, 0.70, 0.005))
    block = np.r_[np.c_[np.full(by.size, 0.57), by.ravel(), bz.ravel()], np.c_[np.full(by.size, 0.59), by.ravel(), bz.ravel()]]
    points = np.r_[face, bar, block]
    cloud = ObjectCloud(points, np.zeros((len(points), 3), np.uint8))
    config = CloudConfig(center=(0.6, 0.0, 0.5))
    segments = part_segments(cloud, config, np.random.default_rng(0))
    on_bar = [seg for seg in segments if np.abs(points[seg, 1] - 0.2).max() < 0.02]
    assert len(on_bar) == 1 and np.ptp(points[on_bar[0], 2]) > config.segment_max_extent
    assert not any(np.any(points[seg, 1] < -0.04) for seg in segments)  # the block is no part


@pytest.mark.parametrize("config", [PANDA, KINOVA], ids=["panda", "kinova_j2s6s200"])
def test_grasp_sampler_builds_a_full_action_on_the_handle(door_with_handle, config):
    sampler = HeuristicGraspSampler(CloudConfig(center=(0.6, 0.0, 0.5)), config)
    action = sampler.sample(door_with_handle, np.random.default_rng(1), 0)
    assert action is not None
    assert np.linalg.norm(action.p1 - HANDLE_CENTER) < 0.09
    kp = action.keyposes()
    assert [k.gripper_closed for k in kp] == [False, False, True, True]
    # p0 on the approach axis, the robot's approach distance back (Kinova's longer fingers: further)
    np.testing.assert_allclose(kp[0].position, action.p1 - config.gripper.approach_distance * action.R0[:, 2])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = action.R0, action.p1
    assert not collides(config.gripper, door_with_handle.points, T, config.collision_tolerance)


def test_samplers_use_the_robot_preset():
    """Reach, hand and approach differ between the presets, and sampling reads them from the preset."""
    assert KINOVA.reach != PANDA.reach and KINOVA.gripper != PANDA.gripper
    assert KINOVA.start_distance == 0.15 and PANDA.start_distance == 0.12
    shoulder_k, shoulder_p = np.asarray(KINOVA.reach.center), np.asarray(PANDA.reach.center)
    beyond_panda = shoulder_p + np.array([PANDA.reach.max + 0.02, 0.0, 0.0])  # in the Jaco2's longer reach only
    assert KINOVA.reachable(beyond_panda) and not PANDA.reachable(beyond_panda)
    assert np.linalg.norm(beyond_panda - shoulder_k) < KINOVA.reach.max
    grasp = HeuristicGraspSampler(CloudConfig(center=(0.6, 0.0, 0.5)), KINOVA)
    assert grasp.proposer.config.gripper == KINOVA.gripper and grasp.proposer.config.reach_center == KINOVA.reach.center
    with pytest.raises(ValueError, match="no hand geometry"):
        SamplingConfig.for_robot(replace(load_robot_spec("panda"), hand=None))


@pytest.mark.parametrize("config", [PANDA, KINOVA], ids=["panda", "kinova_j2s6s200"])
def test_random_sampler_respects_reach_and_collisions(door_with_handle, config):
    sampler = RandomSampler(config)
    rng = np.random.default_rng(2)
    for _ in range(10):
        a = sampler.sample(door_with_handle, rng, 0)
        assert a is not None
        assert all(config.reachable(p) for p in (a.p0, a.p1, a.p2))
        assert config.manipulation_min - 1e-9 <= np.linalg.norm(a.p2 - a.p1) <= config.manipulation_max + 1e-9
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = a.R0, a.p1
        assert not collides(config.gripper, door_with_handle.points, T, config.collision_tolerance)
        np.testing.assert_allclose(a.R0 @ a.R0.T, np.eye(3), atol=1e-9)


def test_action_vector_round_trip():
    rng = np.random.default_rng(3)
    from scipy.spatial.transform import Rotation

    a = ActionSequence(rng.normal(size=3), rng.normal(size=3), Rotation.random(rng=rng).as_matrix(), 0.12)
    b = ActionSequence.from_vector(a.vector())
    np.testing.assert_allclose(b.R0, a.R0, atol=1e-12)
    np.testing.assert_allclose(b.p2, a.p2)
    np.testing.assert_allclose(b.p0, a.p0)


def test_gmm_samples_equally_from_every_cluster():
    rng = np.random.default_rng(4)
    sizes = [60, 15, 9]  # unbalanced modes: equal sampling must not follow these proportions
    z_centres = rng.normal(0, 10, size=(3, 32))
    p1_centres = np.array([[0.5, -0.2, 0.3], [0.5, 0.0, 0.5], [0.5, 0.2, 0.3]])
    z, actions = [], []
    for k, n in enumerate(sizes):
        z.append(z_centres[k] + rng.normal(0, 0.5, size=(n, 32)))
        for _ in range(n):
            a = ActionSequence(p1_centres[k] + rng.normal(0, 0.01, 3), p1_centres[k] + [-0.15, 0, 0], np.diag([1.0, -1.0, -1.0]), 0.12)
            actions.append(a.vector())
    z, actions = np.concatenate(z), np.array(actions)
    sampler = GMMAdaptiveSampler(actions, z, np.ones(len(z), bool), GMMConfig(max_clusters=5), PANDA, seed=0)
    assert sampler.n_clusters == 3 and sorted(sampler.cluster_sizes.tolist()) == sorted(sizes)
    empty = ObjectCloud(np.zeros((0, 3)), np.zeros((0, 3), np.uint8))
    drawn = [sampler.sample(empty, rng, i) for i in range(30)]
    assert all(a is not None for a in drawn)
    mode_of = [int(np.argmin(np.linalg.norm(p1_centres - a.p1, axis=1))) for a in drawn]
    assert sorted(np.bincount(mode_of, minlength=3).tolist()) == [10, 10, 10]
    for i, a in enumerate(drawn):  # round robin: consecutive indices visit different clusters
        assert sampler.cluster_of(i) == i % 3


def test_gmm_falls_back_to_all_trajectories_without_enough_successes():
    rng = np.random.default_rng(5)
    actions = np.array([ActionSequence(np.array([0.5, 0.0, 0.4]) + rng.normal(0, 0.02, 3), np.array([0.4, 0, 0.4]), np.eye(3), 0.12).vector()
                        for _ in range(20)])
    sampler = GMMAdaptiveSampler(actions, rng.normal(size=(20, 8)), np.zeros(20, bool), GMMConfig(), PANDA, seed=0)
    assert not sampler.used_successes_only and sampler.n_clusters >= 1
