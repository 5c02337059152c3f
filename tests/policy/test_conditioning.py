"""How eps reaches the predictor (``PredictorConfig.conditioning``): old checkpoints read the
additive conditioning; a FiLM or mode-query predictor continued from an additive one starts as
that one (its added layers change nothing yet), and training moves them, so eps then scales the
tokens (FiLM) or scores the patches (query)."""
from __future__ import annotations

import dataclasses

import pytest
import torch

from actaim2.artifact import checkpoint
from actaim2.artifact.checkpoint import perception_record
from actaim2.models.predictor import ActionPredictor, PredictorConfig, proprio_features
from actaim2.models.view_geometry import CubePlacement
from actaim2.train.config import load_config
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import Trainer
from tiny_policy import CONFIG, training_data
from torch_threads import single_torch_thread

pytestmark = pytest.mark.timeout(600)  # ~10 s of CPU; the rest is room for a loaded shared machine


def test_old_checkpoints_read_additive_conditioning_and_a_bad_name_is_refused():
    old = PredictorConfig(embedding_dim=16).to_json()
    del old["conditioning"]  # a checkpoint saved before the field existed
    assert PredictorConfig.from_json(old).conditioning == "add"
    with pytest.raises(ValueError, match="conditioning must be one of"):
        PredictorConfig(embedding_dim=16, conditioning="concat")


@pytest.mark.parametrize("step, conditioning", [("film_conditioning", "film"), ("mode_query", "query")])
def test_the_conditioning_steps_are_the_third_steps_control_but_for_the_conditioning(step, conditioning):
    control, config = load_config("third_step_control"), load_config(step)
    assert config.predictor == {**control.predictor, "conditioning": conditioning}
    assert dataclasses.replace(config, predictor=control.predictor) == control


def _outputs(predictor: ActionPredictor, views: torch.Tensor, eps: torch.Tensor) -> list[torch.Tensor]:
    proprio = proprio_features(torch.zeros(len(views)), torch.arange(len(views)) % 4)
    with torch.no_grad():
        return list(predictor.eval()(views, eps, proprio)[:3])


def _added_layers(predictor: ActionPredictor) -> list[torch.nn.Module]:
    """The layers a conditioning adds to an additive predictor (none for ``add``)."""
    return [m for m in (predictor.film, predictor.query, predictor.key) if m is not None]


def _reset_added_layers(predictor: ActionPredictor) -> None:
    """Back to where the added layers change nothing: FiLM the identity, the query zero."""
    for layer in [*(predictor.film or ()), *([predictor.query] if predictor.query is not None else [])]:
        torch.nn.init.zeros_(layer.weight)
        torch.nn.init.zeros_(layer.bias)


@pytest.mark.parametrize("conditioning", ["film", "query"])
def test_continued_from_an_additive_run_it_starts_as_that_run_and_training_moves_the_added_layers(
        conditioning, tiny_checkpoint, tmp_path):
    parent = checkpoint.load_policy(tiny_checkpoint.stem)
    assert parent.predictor.config.conditioning == "add" and not _added_layers(parent.predictor)
    placement = CubePlacement.of(tiny_checkpoint.config)
    data = training_data(tiny_checkpoint.views, placement)
    config = dataclasses.replace(CONFIG, phases=("predictor",), predictor={**CONFIG.predictor, "conditioning": conditioning},
                                 predictor_phase=dataclasses.replace(CONFIG.predictor_phase, epochs=2))
    with single_torch_thread():
        torch.manual_seed(0)
        trainer = Trainer(config, data, None, placement, perception_record(tiny_checkpoint.config), "tiny-synthetic",
                          tmp_path, init_distributed("cpu"), init_from=tiny_checkpoint.stem, show_progress=False)
        views = torch.from_numpy(tiny_checkpoint.views)
        eps = torch.randn(len(views), parent.predictor.config.embedding_dim, generator=torch.Generator().manual_seed(1))
        for own, theirs in zip(_outputs(trainer.predictor, views, eps), _outputs(parent.predictor, views, eps)):
            torch.testing.assert_close(own, theirs)
        assert trainer.lineage["init_from"]["predictor_loaded"] is True
        trainer.run()
    trained = checkpoint.load_policy(tmp_path / "policy")
    assert trained.predictor.config.conditioning == conditioning
    added = _added_layers(trained.predictor)
    assert added and all(any(p.abs().max() > 0 for p in layer.parameters()) for layer in added)
    # The learned layers change the heatmaps: reset to where they change nothing, the heatmaps differ.
    learned = _outputs(trained.predictor, views, eps)
    _reset_added_layers(trained.predictor)
    assert not torch.allclose(learned[0], _outputs(trained.predictor, views, eps)[0])


def test_every_film_parameter_gets_a_gradient():
    config = PredictorConfig(embedding_dim=8, image_size=32, patch=8, width=32, layers_within=1, layers_across=1,
                             heads=2, conditioning="film")
    torch.manual_seed(0)
    model = ActionPredictor(config)
    views = torch.rand(2, 5, config.in_channels, 32, 32)
    out = model(views, torch.randn(2, 8), proprio_features(torch.zeros(2), torch.tensor([0, 2])))
    (out.heatmaps.square().mean() + out.rotation.square().mean()).backward()
    grads = {name: p.grad for name, p in model.named_parameters() if name.startswith("film.")}
    assert len(grads) == 4 and all(g is not None and bool(g.abs().gt(0).any()) for g in grads.values())


def test_the_mode_query_scores_each_patch_by_mode_and_starts_as_nothing():
    config = PredictorConfig(embedding_dim=8, image_size=32, patch=8, width=32, layers_within=1, layers_across=1,
                             heads=2, conditioning="query")
    torch.manual_seed(0)
    model = ActionPredictor(config)
    views = torch.rand(1, 5, config.in_channels, 32, 32).expand(2, -1, -1, -1, -1)
    eps = torch.randn(2, 8)
    proprio = proprio_features(torch.zeros(2), torch.tensor([1, 1]))
    out = model(views, eps, proprio)
    out.heatmaps.logsumexp(dim=(2, 3)).sum().backward()
    assert bool(model.query.weight.grad.abs().gt(0).any())  # zero at the start, yet it learns
    with torch.no_grad():
        torch.nn.init.normal_(model.query.weight)
        # What the query adds: one score per patch (constant over its 8 x 8 pixels), different
        # between patches and between the two modes - it moves mass between parts of the view.
        added = (model(views, eps, proprio).heatmaps - out.heatmaps).reshape(2, 5, 4, 8, 4, 8)
    per_patch = added[:, :, :, :1, :, :1]
    torch.testing.assert_close(added, per_patch.expand_as(added))
    assert float(per_patch.std()) > 1e-3 and not torch.allclose(per_patch[0], per_patch[1])


def test_a_fresh_predictor_beside_the_parents_selector_is_not_the_parents_predictor(tiny_checkpoint, tmp_path):
    """``predictor_from_parent: false`` (configs/mode_from_scratch.yaml): the selector and its z
    statistics come from --init-from, the predictor starts from its own initialisation."""
    parent = checkpoint.load_policy(tiny_checkpoint.stem)
    placement = CubePlacement.of(tiny_checkpoint.config)
    data = training_data(tiny_checkpoint.views, placement)
    config = dataclasses.replace(CONFIG, phases=("predictor",), predictor_from_parent=False,
                                 predictor={**CONFIG.predictor, "conditioning": "query"})
    with single_torch_thread():
        torch.manual_seed(0)
        trainer = Trainer(config, data, None, placement, perception_record(tiny_checkpoint.config), "tiny-synthetic",
                          tmp_path, init_distributed("cpu"), init_from=tiny_checkpoint.stem, show_progress=False)
    assert trainer.lineage["init_from"]["predictor_loaded"] is False
    for name, value in parent.selector.state_dict().items():
        torch.testing.assert_close(trainer.selector.state_dict()[name], value)
    theirs = parent.predictor.state_dict()
    assert any(not torch.equal(value, theirs[name]) for name, value in trainer.predictor.state_dict().items() if name in theirs)
