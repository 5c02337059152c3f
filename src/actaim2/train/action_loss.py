"""L_action = CE(p) + CE(R) + CE(q): the action predictor's behaviour-cloning loss (paper eq. loss_action).

* CE(p): per view, cross-entropy between the heatmap's softmax over pixels and the Gaussian
  (sigma 1.5 px) soft target around the ground-truth position's projection, averaged over views
  and samples (RVT). The position is moved into the cube frame first
  (:mod:`actaim2.models.view_geometry`). Its minimum is the targets' entropy, not 0. A
  single-view predictor is scored on its one view, plus the cross-entropy of its depth cells
  against their Gaussian soft target (together: the CE of the point's fine cell, factored).
* CE(R): cross-entropy of each Euler angle's 72 bins, summed over the three angles (RVT). The
  target is the keypose's rotation or its half turn about the approach axis, whichever
  :func:`~actaim2.models.rotation_bins.canonical_grasp` picks (one class per grasp). With
  ``rotation_sigma_deg`` > 0 the target of each angle is a circular Gaussian over its bins instead
  of the one bin (the training config's ``rotation_sigma_deg``; 0, RVT's one-hot, by default).
  Why: one-hot classes make a bin 5 deg off as wrong as one 180 deg off, so 72 classes per angle
  are learnt from a few hundred demonstrations one by one; a Gaussian target tells the head that
  neighbouring angles are nearly right, as the heatmap's Gaussian does for pixels.
* CE(q): cross-entropy of the gripper state (0 open, 1 closed).

The parts are returned separately for logging.
"""
from __future__ import annotations

from typing import NamedTuple

import torch
import torch.nn.functional as F

from actaim2.models.predictor import PredictorOutput
from actaim2.models.rotation_bins import ROTATION_BINS, canonical_grasp, quat_to_bins
from actaim2.models.view_geometry import (
    HEATMAP_SIGMA,
    CubePlacement,
    depth_targets,
    heatmap_targets,
)


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


def rotation_soft_targets(bins: torch.Tensor, n_bins: int, sigma_deg: float) -> torch.Tensor:
    """(B, 3) bins -> (B, 3, n_bins) circular Gaussians of std ``sigma_deg`` around them, each summing to 1."""
    centres = torch.arange(n_bins, device=bins.device)
    offset = (centres - bins.unsqueeze(-1)).remainder(n_bins)  # (B, 3, n) bins from the target, either way round
    degrees = torch.minimum(offset, n_bins - offset).float() * (360.0 / n_bins)
    weights = torch.exp(-0.5 * (degrees / sigma_deg) ** 2)
    return weights / weights.sum(dim=-1, keepdim=True)


def heatmap_log_likelihood(heatmaps: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """(B,) per sample, the soft targets' log-likelihood under the heatmaps' softmax, averaged over views (-CE(p))."""
    b, v, h, w = heatmaps.shape
    log_p = F.log_softmax(heatmaps.reshape(b, v, h * w).float(), dim=-1)
    return (targets.reshape(b, v, h * w) * log_p).sum(dim=-1).mean(dim=1)


def action_loss(out: PredictorOutput, targets: ActionTargets,
                rotation_sigma_deg: float = 0.0) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """(L_action, {"translation", "rotation", "gripper"}) for a batch; the parts are detached.

    ``rotation_sigma_deg`` > 0 scores the rotation against Gaussian targets over the bins (training
    only: validation keeps the one-hot CE(R), comparable across runs and with chance, 3 ln 72).
    """
    translation = -heatmap_log_likelihood(out.heatmaps, targets.heatmaps).mean()
    if out.depth is not None:
        translation = translation - (targets.depth * F.log_softmax(out.depth.float(), dim=-1)).sum(dim=-1).mean()
    logits = out.rotation.float().transpose(1, 2)  # (B, n_bins, 3)
    rotation_target = targets.rotation_bins if rotation_sigma_deg <= 0.0 else \
        rotation_soft_targets(targets.rotation_bins, logits.shape[1], rotation_sigma_deg).transpose(1, 2)
    rotation = F.cross_entropy(logits, rotation_target, reduction="none").sum(dim=1).mean()
    gripper = F.cross_entropy(out.gripper.float(), targets.gripper)
    total = translation + rotation + gripper
    return total, {"translation": translation.detach(), "rotation": rotation.detach(), "gripper": gripper.detach()}
