"""`actaim2 collect --domain-randomisation`: the single-view pretraining data of the fine-tuning issue
(Kinova, the azure_kinect rig, randomised lighting, colours, placement, depth noise and extrinsics).

One object, two trajectories, one process: the collection completes, dataset.json records the
randomisation, every trajectory its own draw, and the labelling the digest of the encoder E that
made the task embeddings (what checkpoints record and bag2dataset / finetune compare).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from actaim2 import cli
from actaim2.data.collect import CollectConfig, check_resumable, collect
from actaim2.data.labelling import EMBEDDINGS_FILE, embeddings_encoder_digest, encoder_digest
from actaim2.data.storage import DatasetReader
from actaim2.sim.randomisation import load_randomisation

OBJECT = ("storage_furniture", 0)


def test_a_randomised_azure_kinect_collection_with_the_kinova_records_its_draws_and_its_encoder(tmp_path):
    out = tmp_path / "azure"
    randomisation = load_randomisation("default")
    config = CollectConfig(out=out, objects=(OBJECT,), per_object={"random": 2, "grasp": 0, "gmm": 0}, workers=0,
                           robot="kinova_j2s6s200", perception="azure_kinect", randomisation=randomisation,
                           encoder_steps=5, show_progress=False)
    report = collect(config)
    reader = DatasetReader(out)
    assert len(reader.entries) + report["stages"][0]["skipped"] == 2 and reader.entries, report
    assert reader.info["domain_randomisation"] == randomisation.to_dict() and reader.info["robot"] == "kinova_j2s6s200"
    draws = []
    for entry in reader.entries:
        trajectory = reader.read(entry)
        assert all(set(observation) == {"azure_kinect"} for observation in trajectory.observations.values())  # single view
        draw = trajectory.info["randomisation"]
        assert draw["rendered"] and draw["colours"]["object"] and draw["lighting"]["ambient"] > 0
        draws.append(draw)
    if len(draws) == 2:  # each trajectory drew its own scene
        assert draws[0]["lighting"] != draws[1]["lighting"]
    with np.load(out / EMBEDDINGS_FILE) as f:
        assert str(f["encoder_digest"]) == encoder_digest(out / "encoder.pt") == embeddings_encoder_digest(out)
    assert '"encoder_digest": "' + encoder_digest(out / "encoder.pt") + '"' in (out / "labelling.json").read_text()
    # resumed only with the same randomisation
    with pytest.raises(ValueError, match="collected with domain randomisation"):
        check_resumable(reader.info, replace(config, randomisation=None))
    check_resumable(reader.info, config)


def test_the_collect_command_refuses_an_unknown_randomisation_file(tmp_path, capsys):
    assert cli.main(["collect", "--out", str(tmp_path / "ds"), "--domain-randomisation", str(tmp_path / "none.yaml")]) == 2
    assert "no domain randomisation file" in capsys.readouterr().err


def test_the_single_view_training_configuration_reads_one_cameras_task_embedding():
    from actaim2.data.encoder import ImageEncoder
    from actaim2.train.config import load_config

    config = load_config("azure_kinect")
    assert ImageEncoder.autoencoder().dim_per_camera % config.selector.z_tokens == 0
    assert config.phases == load_config("cpu_default").phases
