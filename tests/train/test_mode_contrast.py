"""The mode contrast (train/mode_contrast.py): partners are the same object's trajectories of
another outcome, the loss is ln 2 when the heatmaps ignore eps and falls as they separate the
modes, the trainer adds it in the predictor phase only, and data without outcomes is refused."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch

from actaim2.artifact.checkpoint import perception_record
from actaim2.train.data import TrainingData
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import Trainer
from actaim2.train.mode_contrast import contrast_partners, draw_partners, mode_contrast_loss
from synthetic import PLACEMENT, make_dataset
from test_stop_gradient import TINY
from torch_threads import single_torch_thread

pytestmark = pytest.mark.timeout(600)


def test_partners_are_the_same_objects_other_outcomes():
    partners = contrast_partners(["a", "a", "a", "b", "b"], ["0+", "0-", "0+", "1+", "1+"])
    assert [p.tolist() for p in partners] == [[1], [0, 2], [1], [], []]
    positions, drawn = draw_partners(partners, np.array([3, 1, 0]), np.random.default_rng(0))
    assert positions.tolist() == [1, 2] and drawn[0] in (0, 2) and drawn[1] == 1


def test_the_loss_is_ln2_when_eps_is_ignored_and_falls_as_the_modes_separate():
    own = torch.tensor([-3.0, -5.0])
    assert mode_contrast_loss(own, own).item() == pytest.approx(math.log(2.0))
    assert mode_contrast_loss(own, own - 10.0).item() < 1e-3
    assert mode_contrast_loss(own, own + 10.0).item() > 9.9


def _objects_and_modes(n: int) -> tuple[TrainingData, np.ndarray]:
    """The synthetic dataset with trajectory ids naming 3 objects and the mode as each one's outcome."""
    data, modes = make_dataset(n, resolution=32, seed=3)
    ids = [f"box{i % 3}-grasp-{i:05d}" for i in range(n)]
    return dataclasses.replace(data, ids=ids, outcomes=np.array([f"0{'+' if m else '-'}" for m in modes])), modes


def _trainer(config, data, tmp_path) -> Trainer:
    torch.manual_seed(0)
    return Trainer(config, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", tmp_path,
                   init_distributed("cpu"), show_progress=False)


def test_the_trainer_adds_the_weighted_contrast_to_the_predictor_phase_only(tmp_path):
    data, _ = _objects_and_modes(12)
    items = data.keyframes()[:8]
    with single_torch_thread():
        plain = _trainer(TINY, data, tmp_path / "plain")
        weighted = _trainer(dataclasses.replace(TINY, mode_contrast=2.0), data, tmp_path / "weighted")
        base, _, base_metrics = plain.losses("predictor", data, items, rng=np.random.default_rng(5))
        total, _, metrics = weighted.losses("predictor", data, items, rng=np.random.default_rng(5))
        assert "mode_contrast" not in base_metrics and metrics["action"] == pytest.approx(base_metrics["action"])
        assert total.item() == pytest.approx(base.item() + 2.0 * metrics["mode_contrast"], rel=1e-5)
        # Validation (no rng) and the joint phase leave it out.
        assert "mode_contrast" not in weighted.losses("predictor", data, items)[2]
        assert "mode_contrast" not in weighted.losses("joint", data, items, rng=np.random.default_rng(5))[2]


def test_data_without_outcomes_is_refused(tmp_path):
    data, _ = make_dataset(6, resolution=32, seed=1)
    with pytest.raises(ValueError, match="mode_contrast needs each trajectory's outcome"):
        _trainer(dataclasses.replace(TINY, mode_contrast=1.0), data, tmp_path)
    one_outcome = dataclasses.replace(data, outcomes=np.array(["0+"] * len(data)))
    with pytest.raises(ValueError, match="no object's training trajectories reached two outcomes"):
        _trainer(dataclasses.replace(TINY, mode_contrast=1.0), one_outcome, tmp_path)
