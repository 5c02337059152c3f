"""Input-ablation checkpoints (depth-only, single-view predictor) trained as the ablation configs train
them - predictor phase only, the selector taken from a full policy - then loaded and served by
PolicyModel, which must feed each predictor the inputs its JSON names."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from actaim2.artifact import checkpoint
from actaim2.artifact.checkpoint import perception_record
from actaim2.models.view_geometry import CubePlacement
from actaim2.perception.ortho_views import CHANNELS, VIEWS
from actaim2.policy.inference import PolicyModel
from actaim2.policy.views import Views
from actaim2.train.config import load_config
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import POLICY, Trainer
from tiny_policy import CONFIG, TARGETS, training_data
from torch_threads import single_torch_thread

ABLATIONS = {"depth": "ablation_depth", "single_view": "ablation_single_view"}
pytestmark = pytest.mark.timeout(1200)  # ~20 s of CPU; the rest is room for a loaded shared machine


@pytest.fixture(scope="module")
def ablated(tiny_checkpoint, tmp_path_factory) -> dict[str, PolicyModel]:
    """The tiny policy's ablations: its config with the bundled ablation config's phases and predictor inputs."""
    placement = CubePlacement.of(tiny_checkpoint.config)
    data = training_data(tiny_checkpoint.views, placement)
    models = {}
    with single_torch_thread():
        for name, bundled in ABLATIONS.items():
            ablation = load_config(bundled)
            inputs = {k: ablation.predictor[k] for k in ("inputs", "view")}
            config = dataclasses.replace(CONFIG, phases=ablation.phases, predictor={**CONFIG.predictor, **inputs})
            out = tmp_path_factory.mktemp(name)
            torch.manual_seed(0)
            Trainer(config, data, None, placement, perception_record(tiny_checkpoint.config), "tiny-synthetic", out,
                    init_distributed("cpu"), init_from=tiny_checkpoint.stem, show_progress=False).run()
            models[name] = PolicyModel.load(out / POLICY, tiny_checkpoint.config, "cpu")
    return models


def test_the_checkpoints_record_their_inputs_and_keep_the_full_policys_selector(ablated, tiny_checkpoint):
    full = checkpoint.load_policy(tiny_checkpoint.stem)
    for name, model in ablated.items():
        meta = json.loads(checkpoint.paths(model.stem)[1].read_text())
        expected = {"depth": (["depth", "uv"], "all"), "single_view": (["rgb", "xyz", "depth", "uv"], "back")}[name]
        assert (meta["predictor_config"]["inputs"], meta["predictor_config"]["view"]) == expected
        assert meta["lineage"]["init_from"]["predictor_loaded"] is False and meta["lineage"]["phases_done"] == ["predictor"]
        own = model.selector.state_dict()
        assert all(torch.equal(own[k], v) for k, v in full.selector.state_dict().items())


@pytest.mark.parametrize("name", ABLATIONS)
def test_served_ablations_predict_the_trained_keyposes(ablated, tiny_checkpoint, name):
    model = ablated[name]
    model.warm_up()
    views = Views(5, tiny_checkpoint.views[1])
    eps = model.sample_mode(views, -1, 3).eps
    for phase, target in enumerate(TARGETS):
        prediction = model.predict_keypose(views, eps, phase, phase == 3)
        # 64 px over a 1.2 m cube: 19 mm cells. The single "back" view sees y and z; x, the only
        # coordinate in which the targets differ, comes from its depth output alone.
        assert np.linalg.norm(prediction.keypose.position - target[:3]) < 0.04, (name, phase, prediction.keypose.position)
        assert prediction.keypose.gripper_closed == bool(target[7]) and 0.0 < prediction.confidence <= 1.0


def _prediction(model: PolicyModel, data: np.ndarray) -> tuple[np.ndarray, float]:
    p = model.predict_keypose(Views(5, data), np.zeros(model.embedding_dim, np.float32), 1, False)
    return p.keypose.position, p.confidence


def test_served_ablations_read_only_their_inputs(ablated, tiny_checkpoint):
    views = tiny_checkpoint.views[0]
    rng = np.random.default_rng(0)
    rgb_xyz, back = [CHANNELS.index(c) for c in "rgbxyz"], VIEWS.index("back")
    cases = {"depth": [(np.s_[:, rgb_xyz], True), (np.s_[:, CHANNELS.index("depth")], False)],
             "single_view": [(np.s_[[i for i in range(len(VIEWS)) if i != back]], True), (np.s_[back], False)]}
    for name, changes in cases.items():
        position, confidence = _prediction(ablated[name], views)
        for where, ignored in changes:
            other = views.copy()
            other[where] = rng.uniform(0.0, 1.0, other[where].shape)
            moved_position, moved_confidence = _prediction(ablated[name], other)
            same = np.array_equal(position, moved_position) and confidence == moved_confidence
            assert same == ignored, (name, where)
