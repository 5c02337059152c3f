"""Noise on the predictor's eps: drawn while training (from the step's RNG, so a resumed run draws
the same), absent in validation and when the configuration sets none."""
from __future__ import annotations

import dataclasses

import numpy as np
import torch

from actaim2.artifact.checkpoint import perception_record
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import Trainer
from synthetic import PLACEMENT, make_dataset
from test_stop_gradient import TINY


def _trainer(tmp_path, noise: float) -> Trainer:
    data, _ = make_dataset(4, resolution=32, seed=2)
    return Trainer(dataclasses.replace(TINY, eps_noise=noise), data, None, PLACEMENT, perception_record({"synthetic": 1}),
                   "synthetic", tmp_path, init_distributed("cpu"), show_progress=False)


def test_training_draws_noise_of_the_configured_spread_reproducibly(tmp_path):
    trainer = _trainer(tmp_path, 0.5)
    eps = torch.zeros(64, 300)
    a = trainer.perturb_eps(eps, np.random.default_rng(7))
    b = trainer.perturb_eps(eps, np.random.default_rng(7))
    assert torch.equal(a, b)
    assert abs(float(a.std()) - 0.5) < 0.02 and abs(float(a.mean())) < 0.02


def test_no_noise_without_an_rng_or_when_configured_off(tmp_path):
    eps = torch.randn(8, 20)
    assert torch.equal(_trainer(tmp_path / "a", 0.5).perturb_eps(eps, None), eps)  # validation, serving
    assert torch.equal(_trainer(tmp_path / "b", 0.0).perturb_eps(eps, np.random.default_rng(0)), eps)
