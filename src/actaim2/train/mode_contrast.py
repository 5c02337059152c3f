"""The mode contrast: an auxiliary loss that makes the predictor's heatmaps depend on eps.

For a training keyframe of an object whose trajectories reached two or more outcomes (the DoF
that moved most and its direction), the predictor is run a second time on the same views with
the eps of one of that object's trajectories of *another* outcome; the loss is the logistic
``softplus(log p(target | other eps) - log p(target | own eps))``, weighted by the training
config's ``mode_contrast``: the demonstrated point must be likelier under its own trajectory's
mode than under another mode of the same object. It is 0 once the heatmaps separate the two
modes by a margin and ln 2 when they ignore eps.

Why: measured on the committed checkpoint (``actaim2 validate``, outcome following), fed a
trajectory's true eps its keyposes lie nearest a demonstration of that trajectory's outcome no
more often than guessing the object's most frequent outcome, even on its training data, and
neither FiLM nor a mode-query head engaged in 10 epochs: the translation cross-entropy gains at
most the outcome's information from eps (a fraction of a nat against a loss of ~7), so its
gradient towards using eps is small beside the rest. The contrast asks for that dependence alone.
Only the predictor phase uses it (the joint phase feeds the selector's reconstruction, whose
partner would be another kind of eps); validation losses leave it out, so curves stay comparable.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import torch
import torch.nn.functional as F


def contrast_partners(objects: Sequence[str], outcomes: Sequence[str]) -> list[np.ndarray]:
    """Per trajectory, the rows of the same object's trajectories with another outcome (empty: none)."""
    objects, outcomes = np.asarray(objects), np.asarray(outcomes)
    return [np.flatnonzero((objects == objects[i]) & (outcomes != outcomes[i])) for i in range(len(objects))]


def draw_partners(partners: list[np.ndarray], rows: np.ndarray,
                  rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(positions in ``rows`` that have a partner, one partner row drawn for each)."""
    have = np.array([len(partners[r]) > 0 for r in rows], dtype=bool)
    positions = np.flatnonzero(have)
    drawn = np.array([partners[rows[k]][rng.integers(len(partners[rows[k]]))] for k in positions], dtype=np.int64)
    return positions, drawn


def mode_contrast_loss(own: torch.Tensor, other: torch.Tensor) -> torch.Tensor:
    """Mean logistic loss of (K,) log-likelihoods of the targets under their own and another mode's eps."""
    return F.softplus(other - own).mean()
