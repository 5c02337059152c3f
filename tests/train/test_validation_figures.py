"""`actaim2 validate`'s action figures decode each predictor as it serves: a single-view one
through its view's heatmap and depth cells, a five-view one through all five views."""
from __future__ import annotations

import dataclasses

import pytest
import torch

from actaim2.train.checkpoint import perception_record
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import Trainer
from actaim2.train.validation import EMBEDDINGS, action_figures
from synthetic import PLACEMENT, make_dataset
from test_stop_gradient import TINY


@pytest.mark.parametrize("view", ["all", "back"])
def test_action_figures_of_five_view_and_single_view_predictors(tmp_path, view):
    data, _ = make_dataset(4, resolution=32, seed=5)
    config = dataclasses.replace(TINY, predictor={**TINY.predictor, "view": view})
    trainer = Trainer(config, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", tmp_path,
                      init_distributed("cpu"), show_progress=False)
    assert (trainer.predictor.config.view_index is None) == (view == "all")
    figures = action_figures(trainer.selector, trainer.predictor, data, PLACEMENT, torch.device("cpu"))
    assert set(figures) == set(EMBEDDINGS)
    for by_phase in figures.values():
        f = by_phase["all"]
        assert f.keyframes == len(data.keyframes()) == sum(by_phase[p].keyframes for p in by_phase if p != "all")
        assert 0.0 <= f.translation_median_mm <= f.translation_p90_mm < 2000.0 * PLACEMENT.half_extent
        assert 0.0 <= f.rotation_median_deg <= f.rotation_p90_deg <= 180.0
