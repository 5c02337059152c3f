"""The conditioning layers' own learning rate (TrainConfig.conditioning_lr_scale): one AdamW step from the same
start moves the mode query's layers ``scale`` times as far as at scale 1, and every other weight as far;
scale 1 keeps one parameter group (train states saved before the field resume as they were)."""
from __future__ import annotations

import dataclasses

import pytest
import torch

from actaim2.artifact.checkpoint import perception_record
from actaim2.models.predictor import CONDITIONING_LAYERS
from actaim2.train.config import PhaseConfig
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import Trainer
from synthetic import PLACEMENT, make_dataset
from test_stop_gradient import TINY
from torch_threads import single_torch_thread

pytestmark = pytest.mark.timeout(600)

# The predictor phase alone, one step (AdamW's first step moves each weight by about the rate, whatever its gradient).
ONE_STEP = dataclasses.replace(TINY, phases=("predictor",), predictor={**TINY.predictor, "conditioning": "query"},
                               predictor_phase=PhaseConfig(epochs=1e-3, warmup_fraction=0.0, weight_decay=0.0))


def _moved_by_one_step(scale: float, tmp_path) -> tuple[Trainer, dict[str, float]]:
    data, _ = make_dataset(6, resolution=32, seed=1)
    torch.manual_seed(0)
    trainer = Trainer(dataclasses.replace(ONE_STEP, conditioning_lr_scale=scale), data, None, PLACEMENT,
                      perception_record({"synthetic": 1}), "synthetic", tmp_path, init_distributed("cpu"),
                      show_progress=False)
    before = {n: p.detach().clone() for n, p in trainer.predictor.named_parameters()}
    with single_torch_thread():
        trainer.run()
    return trainer, {n: float((p.detach() - before[n]).abs().max()) for n, p in trainer.predictor.named_parameters()}


def test_the_conditioning_layers_move_scale_times_as_far_and_the_rest_alike(tmp_path):
    plain_trainer, plain = _moved_by_one_step(1.0, tmp_path / "plain")
    scaled_trainer, scaled = _moved_by_one_step(10.0, tmp_path / "scaled")
    conditioning = [n for n in plain if n.startswith(CONDITIONING_LAYERS)]
    assert sorted(conditioning) == ["key.weight", "query.bias", "query.weight"]
    for name in ("query.weight", "query.bias"):
        assert plain[name] > 0 and scaled[name] / plain[name] == pytest.approx(10.0, rel=1e-3), name
    assert plain["key.weight"] == scaled["key.weight"] == 0  # no gradient while the query is still at zero
    for name in plain.keys() - set(conditioning):
        assert scaled[name] == pytest.approx(plain[name], rel=1e-3, abs=1e-9), name
    assert len(plain_trainer._param_groups(list(plain_trainer.predictor.parameters()))) == 1
    groups = scaled_trainer._param_groups(list(scaled_trainer.predictor.parameters()))
    assert [g["lr_scale"] for g in groups] == [1.0, 10.0] and len(groups[1]["params"]) == len(conditioning)
    assert len(scaled_trainer._param_groups(list(scaled_trainer.selector.parameters()))) == 1  # no conditioning layers
