"""Gaussian rotation targets (``rotation_sigma_deg``): their shape, the loss they give, and that
only training batches use them (validation keeps the one-hot CE(R), comparable with chance)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch

from actaim2.artifact.checkpoint import perception_record
from actaim2.models.predictor import PredictorOutput
from actaim2.train.action_loss import ActionTargets, action_loss, rotation_soft_targets
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import Trainer
from synthetic import PLACEMENT, make_dataset
from test_stop_gradient import TINY


def test_targets_are_circular_gaussians_around_the_bin():
    targets = rotation_soft_targets(torch.tensor([[0, 36, 71]]), 72, 10.0)[0]
    torch.testing.assert_close(targets.sum(dim=-1), torch.ones(3))
    assert targets.argmax(dim=-1).tolist() == [0, 36, 71]
    torch.testing.assert_close(targets[0, 1], targets[0, 71])  # wraps round -180 / 180
    torch.testing.assert_close(targets[2, 0], targets[2, 70])
    # two bins (10 deg) off: exp(-1/2) of the peak
    assert float(targets[1, 38] / targets[1, 36]) == pytest.approx(math.exp(-0.5), rel=1e-5)


def _output(rotation_logits: torch.Tensor) -> PredictorOutput:
    b = rotation_logits.shape[0]
    return PredictorOutput(heatmaps=torch.zeros(b, 5, 4, 4), rotation=rotation_logits, gripper=torch.zeros(b, 2))


def _targets(bins: list[int]) -> ActionTargets:
    b = len(bins)
    return ActionTargets(heatmaps=torch.full((b, 5, 4, 4), 1 / 16), rotation_bins=torch.tensor([[k, k, k] for k in bins]),
                         gripper=torch.zeros(b, dtype=torch.long))


def test_a_near_miss_costs_less_than_a_far_one_only_with_gaussian_targets():
    near, far = torch.full((1, 3, 72), -10.0), torch.full((1, 3, 72), -10.0)
    near[..., 11] = 10.0  # the target is bin 10
    far[..., 46] = 10.0
    targets = _targets([10])
    one_hot = [float(action_loss(_output(x), targets)[1]["rotation"]) for x in (near, far)]
    gaussian = [float(action_loss(_output(x), targets, rotation_sigma_deg=10.0)[1]["rotation"]) for x in (near, far)]
    assert one_hot[0] == pytest.approx(one_hot[1])
    assert gaussian[0] < gaussian[1] - 10.0
    narrow = float(action_loss(_output(near), targets, rotation_sigma_deg=0.5)[1]["rotation"])
    assert narrow == pytest.approx(one_hot[0], rel=1e-4)  # a narrow Gaussian is the one-hot target


def test_only_training_batches_score_the_gaussian_targets(tmp_path):
    data, _ = make_dataset(4, resolution=32, seed=3)
    trainers = [Trainer(dataclasses.replace(TINY, rotation_sigma_deg=sigma), data, None, PLACEMENT,  # no noise, no augmentation
                        perception_record({"synthetic": 1}), "synthetic", tmp_path / str(sigma), init_distributed("cpu"),
                        show_progress=False) for sigma in (0.0, 10.0)]
    trainers[1].predictor.load_state_dict(trainers[0].predictor.state_dict())
    trainers[1].selector.load_state_dict(trainers[0].selector.state_dict())
    items = data.keyframes()[:6]
    with torch.no_grad():
        (_, _, hard_train), (_, _, soft_train) = (t.losses("predictor", data, items, rng=np.random.default_rng(0)) for t in trainers)
        (_, _, hard_val), (_, _, soft_val) = (t.losses("predictor", data, items) for t in trainers)
    assert abs(soft_train["rotation"] - hard_train["rotation"]) > 1e-3  # training batches score the Gaussian targets
    assert soft_val["rotation"] == pytest.approx(hard_val["rotation"], abs=1e-6)  # validation the one-hot ones
