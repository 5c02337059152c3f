"""RVT-2's point pooling in the training loop: a training batch's rotation head reads the
demonstrated point, a validation batch (no RNG) the predicted one, as served."""
from __future__ import annotations

import dataclasses

import numpy as np
import torch

from actaim2.artifact.checkpoint import perception_record
from actaim2.models.predictor import proprio_features
from actaim2.train.action_loss import action_loss, action_targets
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import Trainer
from synthetic import PLACEMENT, make_dataset
from test_stop_gradient import TINY


def _rotation_ce(trainer: Trainer, batch: dict, point: torch.Tensor | None) -> float:
    eps = trainer.selector.standardise(batch["z"])
    out = trainer.predictor(batch["views"], eps, proprio_features(batch["gripper"], batch["phase"]), point)
    _, parts = action_loss(out, action_targets(batch["keypose"], PLACEMENT, batch["views"].shape[-1]))
    return float(parts["rotation"])


def test_only_training_batches_read_the_demonstrated_point(tmp_path):
    data, _ = make_dataset(4, resolution=32, seed=3)
    config = dataclasses.replace(TINY, predictor={**TINY.predictor, "rotation_pooling": "point"})  # no noise, no augmentation
    trainer = Trainer(config, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", tmp_path,
                      init_distributed("cpu"), show_progress=False)
    assert trainer.predictor.config.rotation_pooling == "point"
    items = data.keyframes()[:6]
    batch = data.keyframe_batch(items)
    with torch.no_grad():
        _, _, trained = trainer.losses("predictor", data, items, rng=np.random.default_rng(0))
        _, _, validated = trainer.losses("predictor", data, items)
        forced = _rotation_ce(trainer, batch, PLACEMENT.to_cube(batch["keypose"][:, :3]))
        served = _rotation_ce(trainer, batch, None)
    assert forced != served  # the two readings differ on this batch, so the check below can fail
    assert abs(trained["rotation"] - forced) < 1e-5 and abs(validated["rotation"] - served) < 1e-5
