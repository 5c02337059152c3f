"""predictor_samplers: the predictor's phases learn from the listed samplers' trajectories only,
the selector from all of them; a list that matches nothing is refused before training starts."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from actaim2.artifact.checkpoint import perception_record
from actaim2.data.storage import sampler_of, trajectory_id
from actaim2.train.config import TrainConfig
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import Trainer
from synthetic import PLACEMENT, make_dataset
from test_stop_gradient import TINY

SAMPLERS = ("random", "grasp", "gmm", "grasp", "random", "gmm")


def _trainer(tmp_path, samplers: tuple[str, ...]) -> Trainer:
    data, _ = make_dataset(len(SAMPLERS), resolution=32, seed=3)
    data.ids = [trajectory_id("storage_furniture_004", s, i) for i, s in enumerate(SAMPLERS)]
    return Trainer(dataclasses.replace(TINY, predictor_samplers=samplers), data, None, PLACEMENT,
                   perception_record({"synthetic": 1}), "synthetic", tmp_path, init_distributed("cpu"), show_progress=False)


def test_sampler_is_read_back_from_the_trajectory_id():
    assert sampler_of(trajectory_id("storage_furniture-004", "gmm", 12)) == "gmm"


def test_predictor_phases_keep_only_the_listed_samplers(tmp_path):
    trainer = _trainer(tmp_path, ("grasp", "gmm"))
    for phase in ("predictor", "joint"):
        rows = np.unique(trainer._items(phase, trainer.train)[:, 0])
        assert [SAMPLERS[r] for r in rows] == ["grasp", "gmm", "grasp", "gmm"]
    assert len(trainer._items("selector", trainer.train)) == len(SAMPLERS)


def test_no_list_means_every_trajectory(tmp_path):
    trainer = _trainer(tmp_path, ())
    assert len(trainer._items("predictor", trainer.train)) == len(trainer.train.keyframes())


def test_a_list_matching_no_trajectory_stops_the_phase(tmp_path):
    trainer = _trainer(tmp_path, ("heuristic",))
    with pytest.raises(ValueError, match="no training items for phase predictor"):
        trainer._run_phase("predictor")


def test_yaml_list_becomes_a_tuple():
    assert TrainConfig.from_dict({"predictor_samplers": ["grasp"]}).predictor_samplers == ("grasp",)


def test_bundled_structured_demos_config_retrains_only_the_predictor():
    from actaim2.train.config import load_config

    config = load_config("structured_demos")
    assert config.predictor_samplers == ("grasp", "gmm") and config.phases == ("predictor",)
