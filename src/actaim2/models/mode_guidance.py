"""Mode guidance: at serving, amplify what the interaction mode eps changes in the predictor's "where".

Why: the committed predictor's heatmaps are nearly the same whatever eps it reads. Fed the true
eps of a trajectory's own outcome, its REACH lands near that outcome's demonstrations hardly more
often than the object's most frequent outcome would (README, "Where the mode chain breaks"), so
the argmax picks the same part for every cluster and the clusters do not become modes. What eps
does change is small beside the mode-independent mass, and the argmax discards it.

Classifier-free guidance (Ho & Salimans 2022) sharpens the conditional part of a model's
log-density: ``log p_w(x | c) = log p(x | c) + w (log p(x | c) - log p(x))``. The predictor was
never trained with a null condition, so the reference is the predictor fed the *mean* mode,
eps = 0: eps is whitened (zero mean over the training trajectories,
``selector_base.ModeSelector.standardise``). Applied to the translation only (per-view heatmaps
and a single-view predictor's depth cells): a mode is *which part moves which way*, decided by
where the hand grasps and where it pulls to; rotation and gripper are read from the eps rows as
they are. ``w = 0`` is the plain predictor (one forward pass, no reference).
"""
from __future__ import annotations

import torch
import torch.nn.functional as F

from actaim2.models.predictor import PredictorOutput


def with_reference(eps: torch.Tensor) -> torch.Tensor:
    """(B, D) eps -> (2B, D): the eps rows, then as many rows of the reference mode (zeros)."""
    return torch.cat([eps, torch.zeros_like(eps)], dim=0)


def _guided(log_probs: torch.Tensor, weight: float) -> torch.Tensor:
    """(2B, ...) log-probabilities of [eps rows; reference rows] -> (B, ...) guided log-scores."""
    conditional, reference = log_probs.chunk(2, dim=0)
    return conditional + weight * (conditional - reference)


def guide(out: PredictorOutput, weight: float) -> PredictorOutput:
    """The guided output of the eps rows of ``out``, a forward pass of :func:`with_reference`'s batch.

    Heatmaps (and depth cells) become guided log-scores, normalised per view (per ray) again so
    they stay log-probabilities for the decoder and the confidence; rotation and gripper are the
    eps rows' own logits.
    """
    if weight < 0.0:
        raise ValueError(f"mode guidance weight {weight} is negative (0 = off)")
    b, v, h, w = out.heatmaps.shape
    pixels = F.log_softmax(out.heatmaps.reshape(b, v, h * w).float(), dim=-1)
    heatmaps = F.log_softmax(_guided(pixels, weight), dim=-1).reshape(b // 2, v, h, w)
    depth = None
    if out.depth is not None:
        depth = F.log_softmax(_guided(F.log_softmax(out.depth.float(), dim=-1), weight), dim=-1)
    rows = b // 2
    return PredictorOutput(heatmaps, out.rotation[:rows], out.gripper[:rows], depth)
