"""The encoder E of the task embeddings is checked before demonstrations are converted: a checkpoint
records the E its selector learned from, and `actaim2 bag2dataset --checkpoint` refuses another E,
naming both digests, before reading any bag (finetune's own check: test_finetune.py)."""
from __future__ import annotations

import pytest
import torch

from actaim2 import cli
from actaim2.data.encoder import ImageEncoder
from actaim2.data.labelling import encoder_digest
from actaim2.finetune.bag2dataset import EncoderMismatchError, check_checkpoint_encoder
from actaim2.train import checkpoint

OTHER = "0123456789abcdef"


@pytest.fixture()
def encoder(tmp_path):
    torch.manual_seed(0)
    path = tmp_path / "encoder.pt"
    ImageEncoder.autoencoder().save(path)
    return path


def _checkpoint(stem, lineage: dict):
    checkpoint.save(stem, {"w": torch.zeros(1)}, {"lineage": lineage})
    return stem


def test_bag2dataset_refuses_an_encoder_other_than_the_checkpoints_naming_both_digests(encoder, tmp_path, capsys):
    ours = encoder_digest(encoder)
    stem = _checkpoint(tmp_path / "policy", {"encoder_digest": OTHER})
    out = tmp_path / "demos"
    argv = ["bag2dataset", str(tmp_path / "no_bag_needed"), "--out", str(out), "--encoder", str(encoder), "--checkpoint", str(stem)]
    assert cli.main(argv) == 2
    printed = capsys.readouterr().out
    assert f"encoder {encoder} has digest {ours}" in printed and f"trained on task embeddings of encoder {OTHER}" in printed
    assert not out.exists()  # refused before anything was written
    check_checkpoint_encoder(_checkpoint(tmp_path / "same", {"encoder_digest": ours}), encoder, ours)  # the same E passes
    with pytest.raises(EncoderMismatchError, match="records no encoder digest"):  # unknown is not silently passed
        check_checkpoint_encoder(_checkpoint(tmp_path / "old", {"phases_done": []}), encoder, ours)
