"""The encoder E of the task embeddings is checked before demonstrations are converted: a checkpoint
records the E its selector learned from, and `actaim2 bag2dataset --checkpoint` refuses another E,
naming both digests, before reading any bag (finetune's own check: test_finetune.py). Without
--encoder it takes the E shipped beside the checkpoint (<stem>.encoder.pt)."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from actaim2 import cli
from actaim2.artifact import checkpoint
from actaim2.data.encoder import ImageEncoder
from actaim2.data.labelling import (
    EMBEDDINGS_FILE,
    ENCODER_FILE,
    REPORT_FILE,
    dataset_encoder,
    encoder_digest,
)
from actaim2.finetune.bag2dataset import EncoderMismatchError, check_checkpoint_encoder

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


def test_bag2dataset_takes_the_encoder_beside_the_checkpoint(encoder, tmp_path, capsys):
    stem = _checkpoint(tmp_path / "policy", {"encoder_digest": OTHER})
    argv = ["bag2dataset", str(tmp_path / "no_bag_needed"), "--out", str(tmp_path / "demos"), "--checkpoint", str(stem)]
    assert cli.main(argv) == 2
    assert "has no encoder E beside it" in capsys.readouterr().out
    beside = checkpoint.ship_encoder(stem, encoder)
    assert beside == tmp_path / "policy.encoder.pt" and beside.read_bytes() == encoder.read_bytes()
    assert cli.main(argv) == 2  # the beside file is taken (and here refused: the checkpoint names another E)
    assert f"encoder {beside} has digest {encoder_digest(encoder)}" in capsys.readouterr().out
    assert cli.main(argv[:4]) == 2  # neither --encoder nor --checkpoint
    assert "give --encoder" in capsys.readouterr().out


def test_dataset_encoder_is_the_file_whose_digest_the_embeddings_name(encoder, tmp_path):
    root = tmp_path / "ds"
    root.mkdir()
    assert dataset_encoder(root) is None  # no embeddings yet
    np.savez(root / EMBEDDINGS_FILE, ids=np.array(["a"]), z=np.zeros((1, 2), np.float32), encoder_digest=np.array(OTHER))
    (root / ENCODER_FILE).write_bytes(encoder.read_bytes())
    assert dataset_encoder(root) is None  # a file of another digest is not it
    np.savez(root / EMBEDDINGS_FILE, ids=np.array(["a"]), z=np.zeros((1, 2), np.float32),
             encoder_digest=np.array(encoder_digest(encoder)))
    assert dataset_encoder(root) == root / ENCODER_FILE
    (root / REPORT_FILE).write_text(f'{{"encoder": "{encoder}"}}')  # the file labelling used comes first
    assert dataset_encoder(root) == encoder
