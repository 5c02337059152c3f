"""Checkpoints: round trip without unpickling, refusals with clear messages, resume after an interruption."""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from actaim2.artifact import checkpoint
from actaim2.artifact.checkpoint import (
    CorruptCheckpointError,
    PerceptionMismatchError,
    WeightsMismatchError,
    load_policy,
    perception_record,
)
from actaim2.train.config import PhaseConfig
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import POLICY, STATE, Trainer
from synthetic import PLACEMENT, make_dataset
from test_stop_gradient import TINY

PERCEPTION = perception_record({"rig": "ring5", "center": [0.5, 0.0, 0.3], "half_extent": 0.3, "resolution": 32})


@pytest.fixture(scope="module")
def data():
    return make_dataset(8, resolution=32, seed=3)[0]


def _trainer(config, data, out, perception=PERCEPTION) -> Trainer:
    return Trainer(config, data, None, PLACEMENT, perception, "digest-a", out, init_distributed("cpu"), show_progress=False)


@pytest.fixture(scope="module")
def saved(data, tmp_path_factory):
    out = tmp_path_factory.mktemp("ckpt")
    trainer = _trainer(TINY, data, out)
    trainer.save_policy()
    return out / POLICY, trainer


def test_round_trip_gives_the_same_models(saved, data):
    stem, trainer = saved
    policy = load_policy(stem, PERCEPTION)
    assert policy.meta["perception"]["digest"] == PERCEPTION["digest"] and policy.meta["dataset_digest"] == "digest-a"
    assert policy.meta["packages"]["torch"] == torch.__version__.split("+")[0] or policy.meta["packages"]["torch"] == torch.__version__
    views, z = data.selector_batch(np.arange(2))
    g = lambda: torch.Generator().manual_seed(0)  # noqa: E731
    trainer.selector.eval()
    torch.testing.assert_close(policy.selector.sample(views, 3, g()).eps, trainer.selector.sample(views, 3, g()).eps, rtol=0, atol=0)
    for name, tensor in trainer.predictor.state_dict().items():
        assert torch.equal(policy.predictor.state_dict()[name], tensor)


def test_other_perception_configuration_is_refused(saved):
    stem, _ = saved
    other = perception_record({"rig": "ring5", "center": [0.5, 0.0, 0.3], "half_extent": 0.4, "resolution": 32})
    with pytest.raises(PerceptionMismatchError, match=r"half_extent: 0\.3 != 0\.4"):
        load_policy(stem, other)


def test_weights_that_do_not_match_the_config_are_refused(saved, tmp_path):
    stem, trainer = saved
    for path in checkpoint.paths(stem):
        (tmp_path / path.name).write_bytes(path.read_bytes())
    meta_path = tmp_path / f"{POLICY}.json"
    meta = json.loads(meta_path.read_text())
    meta["selector_config"]["width"] = 48  # the JSON now describes a wider selector than the weights hold
    meta_path.write_text(json.dumps(meta))
    with pytest.raises(WeightsMismatchError, match="selector weights do not match its configuration"):
        load_policy(tmp_path / POLICY, PERCEPTION)


@pytest.mark.parametrize("damage", ["flip_weights", "truncate_weights", "garbage_json", "missing_json", "rehashed_garbage"])
def test_corrupted_files_raise_a_checkpoint_error(saved, tmp_path, damage):
    stem, _ = saved
    weights, meta = checkpoint.paths(stem)
    w, j = tmp_path / weights.name, tmp_path / meta.name
    w.write_bytes(weights.read_bytes())
    j.write_bytes(meta.read_bytes())
    if damage == "flip_weights":
        raw = bytearray(w.read_bytes())
        raw[len(raw) // 2] ^= 0xFF
        w.write_bytes(bytes(raw))
    elif damage == "truncate_weights":
        w.write_bytes(w.read_bytes()[:1000])
    elif damage == "garbage_json":
        j.write_text("{not json")
    elif damage == "missing_json":
        j.unlink()
    else:  # a weights file that is not safetensors at all, with a JSON hash that matches it
        w.write_bytes(b"\x10\x00\x00\x00\x00\x00\x00\x00{broken header!!" + b"\x00" * 64)
        body = json.loads(j.read_text())
        body["weights_sha256"] = checkpoint._sha256(w)
        j.write_text(json.dumps(body))
    with pytest.raises(CorruptCheckpointError):
        load_policy(tmp_path / POLICY, PERCEPTION)


def test_resume_after_interruption_continues_exactly(data, tmp_path, monkeypatch):
    config = TINY.__class__(**{**TINY.__dict__, "phases": ("selector",), "checkpoint_minutes": 0.0,
                               "selector_phase": PhaseConfig(epochs=3, batch_size=4, lr=1e-3)})  # 6 steps, a save after each
    reference = _trainer(config, data, tmp_path / "reference")
    reference.run()

    class Interrupted(Exception):
        pass

    saves = {"n": 0}
    original = Trainer.save_state

    def save_then_stop(self, optimizer, phase):
        original(self, optimizer, phase)
        saves["n"] += 1
        if saves["n"] == 3:
            raise Interrupted

    monkeypatch.setattr(Trainer, "save_state", save_then_stop)
    with pytest.raises(Interrupted):
        _trainer(config, data, tmp_path / "run").run()
    monkeypatch.setattr(Trainer, "save_state", original)
    resumed = _trainer(config, data, tmp_path / "run")
    assert resumed.resume() and resumed.step == 3
    resumed.run()
    for name, tensor in reference.selector.state_dict().items():
        torch.testing.assert_close(resumed.selector.state_dict()[name], tensor, rtol=0, atol=0, msg=name)
    with pytest.raises(PerceptionMismatchError):  # a resumed run must keep its perception configuration
        _trainer(config, data, tmp_path / "run", perception_record({"rig": "azure_kinect"})).resume()
    assert (tmp_path / "run" / f"{STATE}.json").exists()
