"""L_action = CE(p) + CE(R) + CE(q): the action predictor's behaviour-cloning loss (paper eq. loss_action).

* CE(p): per view, cross-entropy between the heatmap's softmax over pixels and the Gaussian
  (sigma 1.5 px) soft target around the ground-truth position's projection, averaged over views
  and samples (RVT). The position is moved into the cube frame first
  (:mod:`actaim2.models.view_geometry`). Its minimum is the targets' entropy, not 0. A
  single-view predictor is scored on its one view, plus the cross-entropy of its depth cells
  against their Gaussian soft target (together: the CE of the point's fine cell, factored).
* CE(R): cross-entropy of each Euler angle's 72 bins, summed over the three angles (RVT). The
  target is the keypose's rotation or its half turn about the approach axis, whichever
  :func:`~actaim2.models.rotation_bins.canonical_grasp` picks (one class per grasp).
* CE(q): cross-entropy of the gripper state (0 open, 1 closed).

The parts are returned separately for logging.
"""
from __future__ import annotations

from typing import NamedTuple

import torch
import torch.nn.functional as F

from actaim2.models.predictor import PredictorOutput
from actaim2.models.rotation_bins import ROTATION_BINS, canonical_grasp, quat_to_bins
from actaim2.models.view_geometry import HEATMAP_SIGMA, CubePlacement, depth_targets, heatmap_targets


class ActionTargets(NamedTuple):
    heatmaps: torch.Tensor  # (B, V, R, R) soft targets, each view summing to 1 (V = 1: single view)
    rotation_bins: torch.Tensor  # (B, 3) int64
    gripper: torch.Tensor  # (B,) int64, 1 = closed
    depth: torch.Tensor | None = None  # (B, R) single view only: soft targets over the depth cells


def action_targets(
    keyposes: torch.Tensor,
    placement: CubePlacement,
    resolution: int,
    n_bins: int = ROTATION_BINS,
    sigma: float = HEATMAP_SIGMA,
    view: int | None = None,
) -> ActionTargets:
    """Targets of (B, 8) keyposes [position (world m), quaternion (x, y, z, w), gripper closed].

    That is the layout of :func:`actaim2.data.torch_dataset.keypose_tensor`. Positions outside the
    cube have no pixel to aim at and are refused (filter them with ``placement.contains``).
    ``view``: the predictor's ``config.view_index`` (None: all five views).
    """
    position = keyposes[:, :3]
    outside = ~placement.contains(position)
    if bool(outside.any()):
        rows = outside.nonzero().flatten().tolist()
        raise ValueError(f"keyposes {rows} lie outside the cube {placement}: {position[outside].tolist()}")
    bins = quat_to_bins(canonical_grasp(keyposes[:, 3:7].detach().cpu().double().numpy()), n_bins)
    cube = placement.to_cube(position)
    heatmaps = heatmap_targets(cube, resolution, sigma)
    return ActionTargets(
        heatmaps=heatmaps if view is None else heatmaps[:, view : view + 1],
        rotation_bins=torch.from_numpy(bins).to(keyposes.device),
        gripper=keyposes[:, 7].round().long(),
        depth=None if view is None else depth_targets(cube, view, resolution, sigma),
    )


def action_loss(out: PredictorOutput, targets: ActionTargets) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """(L_action, {"translation", "rotation", "gripper"}) for a batch; the parts are detached."""
    b, v, h, w = out.heatmaps.shape
    log_p = F.log_softmax(out.heatmaps.reshape(b, v, h * w).float(), dim=-1)
    translation = -(targets.heatmaps.reshape(b, v, h * w) * log_p).sum(dim=-1).mean()
    if out.depth is not None:
        translation = translation - (targets.depth * F.log_softmax(out.depth.float(), dim=-1)).sum(dim=-1).mean()
    rotation = F.cross_entropy(out.rotation.float().transpose(1, 2), targets.rotation_bins, reduction="none").sum(dim=1).mean()
    gripper = F.cross_entropy(out.gripper.float(), targets.gripper)
    total = translation + rotation + gripper
    return total, {"translation": translation.detach(), "rotation": rotation.detach(), "gripper": gripper.detach()}
