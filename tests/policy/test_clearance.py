"""The hand's clearance: ranked heatmap peaks and rotation bins, and the choice that keeps the open hand off a wall."""
from __future__ import annotations

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from actaim2.data.gripper import collides
from actaim2.models.predictor import PredictorOutput, decode_action
from actaim2.models.rotation_bins import ROTATION_BINS, bins_to_quat, ranked_bins
from actaim2.models.view_geometry import CubePlacement, decode_cells, heatmap_targets, ranked_cells, score_cells
from actaim2.perception.ortho_views import CHANNELS
from actaim2.policy.clearance import ClearanceConfig, choose_clear, observed_points
from actaim2.robots import load_robot_spec

PLACEMENT = CubePlacement((0.75, 0.0, 0.4), 0.6)
R = 128
HAND = load_robot_spec("panda").hand
WALL_X = 0.75  # a wall of points in the plane x = 0.75 (a cabinet's front seen from the robot)
TARGET = np.array([0.72, 0.0, 0.4])  # 3 cm in front of it


def angle_bin(degrees: float) -> int:
    return int((degrees + 180.0) // (360.0 / ROTATION_BINS))


def wall() -> np.ndarray:
    y, z = np.meshgrid(np.linspace(-0.1, 0.1, 41), np.linspace(0.3, 0.5, 41))
    return np.stack([np.full(y.size, WALL_X), y.ravel(), z.ravel()], axis=1)


def output(beta_logits: dict[int, float], point: np.ndarray = TARGET) -> PredictorOutput:
    """Heatmaps peaked at ``point``; alpha and gamma sure of 2.5 deg, beta's bins given as {bin: logit}."""
    cube = PLACEMENT.to_cube(torch.tensor(point, dtype=torch.float32))[None]
    heatmaps = heatmap_targets(cube, R).clamp_min(1e-30).log()
    rotation = torch.full((1, 3, ROTATION_BINS), -10.0)
    rotation[0, 0, angle_bin(2.5)] = rotation[0, 2, angle_bin(2.5)] = 10.0
    for b, logit in beta_logits.items():
        rotation[0, 1, b] = logit
    return PredictorOutput(heatmaps, rotation, torch.tensor([[5.0, -5.0]]))


def test_ranked_bins_start_at_the_argmax_keep_apart_and_are_ordered():
    rng = np.random.default_rng(3)
    log_probs = torch.log_softmax(torch.from_numpy(rng.normal(size=(3, ROTATION_BINS)) * 3), dim=-1).numpy()
    triples, scores = ranked_bins(log_probs, per_axis=3, separation=2)
    assert triples.shape == (27, 3)
    assert triples[0].tolist() == log_probs.argmax(axis=1).tolist()
    assert np.all(np.diff(scores) <= 0)
    np.testing.assert_allclose(scores, log_probs[0, triples[:, 0]] + log_probs[1, triples[:, 1]] + log_probs[2, triples[:, 2]])
    for axis in range(3):
        kept = np.unique(triples[:, axis])
        gaps = np.abs(kept[:, None] - kept[None, :])
        circular = np.minimum(gaps, ROTATION_BINS - gaps)[~np.eye(len(kept), dtype=bool)]
        assert len(kept) == 3 and circular.min() > 2


def test_ranked_cells_are_apart_and_best_first():
    cube = PLACEMENT.to_cube(torch.tensor([[0.72, 0.0, 0.4], [0.9, 0.2, 0.6]]))
    heatmaps = (0.7 * heatmap_targets(cube[:1], R) + 0.3 * heatmap_targets(cube[1:], R)).clamp_min(1e-30).log()
    cells, scores = ranked_cells(heatmaps, count=4, separation=2)
    assert len(cells) == 4 and torch.all(scores[:-1] >= scores[1:])
    assert scores[0] >= score_cells(heatmaps, decode_cells(heatmaps)[:, None])[0, 0] - 1e-5
    for i in range(4):
        for j in range(i):
            assert int((cells[i] - cells[j]).abs().max()) > 2


def test_observed_points_are_the_occupied_pixels_xyz_in_world():
    views = np.zeros((5, len(CHANNELS), R, R), np.float32)
    cube = np.array([[0.1, -0.2, 0.3], [-0.5, 0.5, 0.0]], np.float32)
    for k, (v, row, col) in enumerate([(0, 3, 4), (2, 60, 61)]):
        views[v, CHANNELS.index("occupancy"), row, col] = 1.0
        for c, name in enumerate("xyz"):
            views[v, CHANNELS.index(name), row, col] = cube[k, c]
    points = observed_points(views, list(CHANNELS), PLACEMENT)
    np.testing.assert_allclose(np.sort(points, axis=0), np.sort(cube * 0.6 + np.array(PLACEMENT.center), axis=0), atol=1e-6)


def pose(position: np.ndarray, quat: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.from_quat(quat).as_matrix(), position
    return T


def test_the_most_likely_clear_rotation_is_chosen_when_the_argmax_puts_the_hand_through_the_wall():
    """beta -87.5 deg points the approach axis away from the wall, so the fingers reach through it;
    beta +87.5 deg (less likely) approaches the wall from the front and clears it."""
    points = wall()
    out = output({angle_bin(-87.5): 8.0, angle_bin(87.5): 6.0})
    argmax = decode_action(out, PLACEMENT)
    argmax_position, argmax_quat = argmax.position[0].double().numpy(), argmax.quat_xyzw[0].double().numpy()
    assert collides(HAND, points, pose(argmax_position, argmax_quat))  # the plain decode would be refused
    choice = choose_clear(out, points, argmax_position, argmax_quat, PLACEMENT, HAND, ClearanceConfig())
    assert choice.rank > 0
    assert not collides(HAND, points, pose(choice.position, choice.quat_xyzw))
    approach = Rotation.from_quat(choice.quat_xyzw).as_matrix()[:, 2]
    assert approach[0] > 0.99  # towards the wall
    assert np.linalg.norm(choice.position - TARGET) < 0.01
    np.testing.assert_allclose(choice.quat_xyzw, bins_to_quat(np.array([[angle_bin(2.5), angle_bin(87.5), angle_bin(2.5)]]))[0])


def test_a_clear_argmax_is_kept_and_no_clear_candidate_returns_the_argmax():
    points = wall()
    clear = output({angle_bin(87.5): 8.0, angle_bin(-87.5): 6.0})
    a = decode_action(clear, PLACEMENT)
    choice = choose_clear(clear, points, a.position[0].double().numpy(), a.quat_xyzw[0].double().numpy(), PLACEMENT, HAND,
                          ClearanceConfig())
    assert choice.rank == 0
    # Inside the wall every pose collides: the argmax comes back, marked -1, for the planner to refuse with its reason.
    inside = output({angle_bin(-87.5): 8.0}, point=np.array([WALL_X, 0.0, 0.4]))
    a = decode_action(inside, PLACEMENT)
    dense = np.concatenate([wall() + [dx, 0.0, 0.0] for dx in np.linspace(-0.12, 0.12, 49)])
    choice = choose_clear(inside, dense, a.position[0].double().numpy(), a.quat_xyzw[0].double().numpy(), PLACEMENT, HAND,
                          ClearanceConfig())
    assert choice.rank == -1
    np.testing.assert_allclose(choice.position, a.position[0].double().numpy())
    np.testing.assert_allclose(choice.quat_xyzw, a.quat_xyzw[0].double().numpy())
