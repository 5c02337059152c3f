"""Keyposes whose open hand clears what the views see: the predictor's most likely one that does.

Why. The predictor's argmax is a point from the heatmaps and an independent argmax per Euler
angle. On unseen instances (`train_unseen_instance`, the committed checkpoint fed the true z)
the open Panda hand at the argmax REACH keypose held observed points in 66 % of 58 keyframes,
against 2 % for the demonstrations (the samplers screened those with the same box check), and
the planner refuses such keyposes before moving ("every solution collides"): 22 % of the
committed checkpoint's evaluation samples ended there, at INIT or REACH.

What. The heatmaps and rotation bins are distributions, so the choice is made on them: the best
heatmap cells a few cells apart (:func:`ranked_cells`) times distinct angles per axis (:func:`ranked_bins`),
tried in order of summed log-probability; the first whose open hand holds at most
``tolerance`` of the views' points (:func:`actaim2.data.gripper.collides`, the samplers' check)
is the keypose. Only keyposes with the hand open are screened (a closed hand holds the handle);
when no candidate clears, the argmax is returned and the planner says why it refuses it.

The points are the views' own xyz where occupied, so the check needs nothing beyond what
``/predict_keypose`` already reads, and the library evaluation and ``policy_node`` choose alike.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from actaim2.data.gripper import collides
from actaim2.models.predictor import PredictorOutput
from actaim2.models.rotation_bins import bins_to_quat, ranked_bins
from actaim2.models.view_geometry import CubePlacement, cell_centres, ranked_cells
from actaim2.robots import HandGeometry


@dataclass(frozen=True)
class ClearanceConfig:
    positions: int = 4  # heatmap cells tried (the best ones, kept apart)
    separation_cells: int = 2  # fine cells between two position candidates (Chebyshev)
    angles_per_axis: int = 3  # distinct bins per Euler angle: angles_per_axis^3 rotations
    separation_bins: int = 2  # bins between two angle candidates of one axis (5 deg each)
    tolerance: int = 3  # observed points the open hand may hold (stray points), as the random sampler allows
    neighbourhood: float = 0.25  # m: only points this close to a candidate position can touch the hand


def describe_clearance(config: ClearanceConfig) -> str:
    """How keyposes were chosen, for an evaluation's identity: results of another choice must not mix."""
    return "clearance(" + ", ".join(f"{k}={v}" for k, v in asdict(config).items()) + ")"


def observed_points(views: np.ndarray, channels: list[str] | tuple[str, ...], placement: CubePlacement) -> np.ndarray:
    """(N, 3) world points the views saw: the xyz channels (cube frame) of occupied pixels.

    A point seen in two views comes twice; at 128 px a pixel spans ~9 mm, so they are few
    (~1 % of 23,000 on the evaluation's scenes) and thinning them would cost more than it saves.
    """
    xyz = [channels.index(c) for c in "xyz"]
    occupied = views[:, channels.index("occupancy")] > 0.5  # (V, R, R)
    cube = np.moveaxis(views[:, xyz], 1, -1)[occupied].astype(np.float64)  # (N, 3)
    world = cube * placement.half_extent + np.asarray(placement.center)
    return world


@dataclass(frozen=True)
class Choice:
    position: np.ndarray  # (3,) world
    quat_xyzw: np.ndarray  # (4,)
    rank: int  # candidates tried before this one; -1: none cleared, the argmax is returned


def choose_clear(out: PredictorOutput, points: np.ndarray, argmax_position: np.ndarray, argmax_quat: np.ndarray,
                 placement: CubePlacement, hand: HandGeometry, config: ClearanceConfig) -> Choice:
    """The most likely (position, rotation) of batch row 0 whose open hand clears ``points``; the argmax
    (``decode_action``'s) when none does.

    A single-view predictor's position is its own argmax: one view's heatmap and depth cells are
    not scored as joint 3-D cells here.
    """
    if out.depth is None:
        cells, position_scores = ranked_cells(out.heatmaps[:1], config.positions, config.separation_cells)
        positions = placement.to_world(cell_centres(cells, out.heatmaps.shape[-1])).double().cpu().numpy()
        position_scores = position_scores.double().cpu().numpy()
    else:
        positions, position_scores = np.asarray(argmax_position, np.float64)[None], np.zeros(1)
    log_probs = torch.log_softmax(out.rotation[0].float(), dim=-1).cpu().numpy()
    bins, rotation_scores = ranked_bins(log_probs, config.angles_per_axis, config.separation_bins)
    quats = bins_to_quat(bins, log_probs.shape[-1])
    matrices = Rotation.from_quat(quats).as_matrix()
    total = position_scores[:, None] + rotation_scores[None, :]
    nearby: dict[int, np.ndarray] = {}
    for rank, flat in enumerate(np.argsort(-total, axis=None, kind="stable")):
        i, j = divmod(int(flat), len(quats))
        if i not in nearby:
            nearby[i] = points[np.linalg.norm(points - positions[i], axis=1) <= config.neighbourhood]
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = matrices[j], positions[i]
        if not collides(hand, nearby[i], T, config.tolerance):
            return Choice(positions[i], quats[j], rank)
    return Choice(np.asarray(argmax_position, np.float64), np.asarray(argmax_quat, np.float64), -1)
