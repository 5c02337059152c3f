"""The checkpoints shipped in actaim2_policy/checkpoints load under the perception configuration
their node configuration serves them with, and answer both services' library calls."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from actaim2.artifact.checkpoint import encoder_path
from actaim2.data.labelling import encoder_digest
from actaim2.perception.config import load_perception_config
from actaim2.policy.inference import PolicyModel
from actaim2.policy.views import Views

CHECKPOINTS = Path(__file__).resolve().parents[2] / "actaim2_policy" / "checkpoints"
SERVED = {"actaim2_ring5": "ring5", "actaim2_azure_kinect": "azure_kinect"}  # policy_node.yaml, policy_node_azure.yaml
SHIPS_ENCODER = {"actaim2_ring5"}  # actaim2_azure_kinect was trained before E travelled with checkpoints (docs/finetuning.md)


def test_every_committed_checkpoint_is_served_by_a_node_configuration():
    assert sorted(p.stem for p in CHECKPOINTS.glob("*.json")) == sorted(SERVED)


@pytest.mark.parametrize("name", sorted(SERVED))
def test_a_committed_checkpoint_loads_and_answers(name):
    serving = load_perception_config(SERVED[name])
    model = PolicyModel.load(CHECKPOINTS / name, serving, device="cpu")
    meta = json.loads((CHECKPOINTS / f"{name}.json").read_text())
    assert meta["perception"]["fields"]["rig"] == SERVED[name]
    assert meta["lineage"]["encoder_digest"]  # the E its selector learned z of (bag2dataset / finetune check it)
    config = model.views_config("selector")
    channels, resolution = len(config.channels), config.resolution
    # five orthographic views of the fused cloud, whatever the rig
    views = Views(0, np.random.default_rng(0).uniform(-1, 1, (5, channels, resolution, resolution)).astype(np.float32))
    sample = model.sample_mode(views, 0, 7)
    assert sample.cluster == 0 and np.isfinite(sample.eps).all()
    prediction = model.predict_keypose(views, sample.eps, 0, False)
    assert np.isfinite(prediction.keypose.position).all()


@pytest.mark.parametrize("name", sorted(SERVED))
def test_a_shipped_encoder_is_the_one_the_selector_learned_from(name):
    """bag2dataset and Goal-RVT embed new observations with the E beside the checkpoint: it must be
    the E whose z the selector was trained on, or fine-tuning would mix two embeddings."""
    encoder = encoder_path(CHECKPOINTS / name)
    if name not in SHIPS_ENCODER:
        assert not encoder.exists()  # docs/finetuning.md: this checkpoint is shipped without E
        return
    meta = json.loads((CHECKPOINTS / f"{name}.json").read_text())
    assert encoder_digest(encoder) == meta["lineage"]["encoder_digest"]
