"""`actaim2 finetune` on the converted demonstrations: a tiny parent policy trained through the training
API, then fine-tuned by the joint phase; the training loss goes down, held-out demonstrations of every
label are validated, the checkpoint loads (checkpoint loader and the policy's server library) and its
JSON carries the lineage. Nothing here trains for more than a few seconds."""
from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from actaim2 import cli
from actaim2.artifact import checkpoint
from actaim2.data.labelling import EMBEDDINGS_FILE, encoder_digest
from actaim2.data.storage import dataset_digest
from actaim2.finetune.clusters import cluster_table, format_table, label_assignment, mode_accuracy
from actaim2.finetune.finetune import FinetuneConfig, FinetuneError, check_encoder, finetune
from actaim2.finetune.heldout import heldout_rows
from actaim2.models.obs_encoder import ObsEncoderConfig
from actaim2.models.selector_base import SelectorConfig
from actaim2.train.config import PhaseConfig, TrainConfig

PARENT_CONFIG = TrainConfig(
    phases=("selector", "predictor"),
    selector=SelectorConfig(z_tokens=4, clusters=4, width=32, blocks=1, decoder_layers=1, latent_dim=8, y_dim=8,
                            obs=ObsEncoderConfig(input_resolution=16, widths=(8, 16), token_dim=16)),
    predictor=dict(patch=8, width=32, layers_within=1, layers_across=1, heads=2, dropout=0.0),
    selector_phase=PhaseConfig(epochs=2, batch_size=8, lr=1e-3),
    predictor_phase=PhaseConfig(epochs=2, batch_size=8, lr=1e-3),
    augment=False, validation_fraction=0.0, checkpoint_minutes=1e9, log_every=10_000,
)
RESOLUTION = 64


@pytest.fixture(scope="module")
def parent(converted, tmp_path_factory):
    """A briefly trained policy (the azure_kinect configuration at 64 px) standing in for the sim-pretrained one."""
    from actaim2.data.splits import TRAIN
    from actaim2.models.view_geometry import CubePlacement
    from actaim2.perception.config import load_perception_config
    from actaim2.train.data import ensure_cache, open_cache
    from actaim2.train.distributed import init_distributed
    from actaim2.train.loop import POLICY, Trainer

    config = load_perception_config("azure_kinect").replace(resolution=RESOLUTION)
    record = checkpoint.perception_record(config)
    ensure_cache(converted.dataset, config, [TRAIN], show_progress=False)
    placement = CubePlacement.of(config)
    data = open_cache(converted.dataset, config, [TRAIN])
    out = tmp_path_factory.mktemp("parent")
    Trainer(PARENT_CONFIG, data, None, placement, record, dataset_digest(converted.dataset), out,
            init_distributed("cpu"), show_progress=False).run()
    return out / POLICY, config


def test_finetune_lowers_the_training_loss_and_writes_a_loadable_checkpoint_with_its_lineage(converted, parent, tmp_path, capsys):
    from actaim2.policy.inference import PolicyModel

    stem, config = parent
    out = tmp_path / "ft"
    argv = ["finetune", str(stem), str(converted.dataset), "--out", str(out), "--epochs", "12", "--lr", "1e-3",
            "--heldout", "0.25", "--device", "cpu", "--no-progress"]
    assert cli.main(argv) == 0
    printed = capsys.readouterr().out
    report = json.loads((out / "finetune.json").read_text())
    before, after = report["before"]["joint"], report["after"]["joint"]
    assert after["train"]["loss"] < before["train"]["loss"], (before["train"], after["train"])
    assert after["train"]["action"] < before["train"]["action"]
    assert before["val"] is not None and after["val"] is not None  # held-out demonstrations were validated
    # one held-out demonstration per label (two of each), stratified
    labels = {e["id"]: e["mode_label"] for e in map(json.loads, (converted.dataset / "index.jsonl").read_text().splitlines())}
    assert sorted(labels[i] for i in report["heldout"]) == ["pull", "push"]
    history = [json.loads(line) for line in (out / "history.jsonl").read_text().splitlines()]
    assert history and all(h["phase"] == "joint" and h["val"] is not None for h in history)
    # the cluster of every labelled demonstration, tabulated by label
    table = report["after"]["clusters"]
    assert {d["id"] for d in table["demonstrations"]} == set(labels)
    assert {k: sum(v) for k, v in table["by_label"].items()} == {"pull": 2, "push": 2}
    assert "| pull |" in printed and "| push |" in printed
    # the new checkpoint: loadable, and its JSON says where it comes from
    policy = checkpoint.load_policy(out / "policy", checkpoint.perception_record(config))
    lineage = policy.meta["lineage"]
    parent_weights = checkpoint.paths(stem)[0]
    assert lineage["finetune"]["parent"]["weights_sha256"] == hashlib.sha256(parent_weights.read_bytes()).hexdigest()
    assert lineage["finetune"]["dataset"]["digest"] == dataset_digest(converted.dataset) == policy.meta["dataset_digest"]
    assert lineage["finetune"]["command"][:6] == ["actaim2", "finetune", str(stem), str(converted.dataset), "--out", str(out)]
    assert lineage["finetune"]["command"][lineage["finetune"]["command"].index("--epochs") + 1] == "12.0"
    assert lineage["phases_done"] == ["joint"] and lineage["init_from"]["path"] == str(stem)
    with np.load(converted.dataset / EMBEDDINGS_FILE) as f:
        assert lineage["encoder_digest"] == str(f["encoder_digest"])
    assert encoder_digest(checkpoint.encoder_path(out / "policy")) == lineage["encoder_digest"]  # E travels with it
    model = PolicyModel.load(out / "policy", config, "cpu")  # as policy_node loads it
    assert model.clusters == PARENT_CONFIG.selector.clusters
    model.warm_up()
    # the parent is untouched
    assert checkpoint.load_policy(stem).meta["lineage"].get("finetune") is None


def test_the_demonstrations_must_be_embedded_by_the_parents_encoder(converted, tmp_path):
    with np.load(converted.dataset / EMBEDDINGS_FILE) as f:
        ours = str(f["encoder_digest"])
    assert check_encoder({"lineage": {"encoder_digest": ours}}, converted.dataset, None)["checked"]
    with pytest.raises(FinetuneError, match="convert the bags with the pretraining data's encoder"):
        check_encoder({"lineage": {"encoder_digest": "0123456789abcdef"}}, converted.dataset, None)
    # through the pretraining dataset: it must be the parent's data, and its E is compared
    meta = {"lineage": {}, "dataset_digest": dataset_digest(converted.dataset)}
    assert check_encoder(meta, converted.dataset, converted.dataset)["checked"]
    with pytest.raises(FinetuneError, match="is not the data the parent checkpoint was trained on"):
        check_encoder({"lineage": {}, "dataset_digest": "another"}, converted.dataset, converted.dataset)
    assert not check_encoder({"lineage": {}}, converted.dataset, None)["checked"]  # said, not silently passed


def test_heldout_demonstrations_cover_every_label_and_keep_their_side():
    ids = [f"d{i}" for i in range(10)]
    labels = ["push"] * 6 + ["pull"] * 3 + ["open"]
    train, val = heldout_rows(ids, labels, 0.2)
    assert sorted(labels[i] for i in val) == ["pull", "push"]  # a lone "open" is never held out
    assert sorted(np.concatenate([train, val]).tolist()) == list(range(10))
    _, val_more = heldout_rows(ids + ["d10", "d11"], labels + ["pull", "pull"], 0.2)
    assert {ids[i] for i in val if labels[i] == "push"} <= {(ids + ["d10", "d11"])[i] for i in val_more}
    with pytest.raises(ValueError):
        heldout_rows(ids, labels, 1.0)


def test_cluster_table_names_each_labels_majority_cluster():
    table = cluster_table(["a", "b", "c", "d", "e"], ["push", "push", "pull", "pull", ""], np.array([2, 2, 0, 1, 3]), 4)
    assert table["by_label"] == {"push": [0, 0, 2, 0], "pull": [1, 1, 0, 0], "<none>": [0, 0, 0, 1]}
    assert table["label_cluster"]["push"] == 2 and table["label_cluster_share"]["push"] == 1.0
    assert "| push | 0 | 0 | 2* | 0 | c2 (100%) |" in format_table(table)


def test_fine_tuning_by_mode_label_gives_each_label_a_cluster_of_its_own(converted, parent, tmp_path):
    from actaim2.policy.inference import PolicyModel

    stem, config = parent
    report = finetune(stem, converted.dataset, tmp_path / "ft", FinetuneConfig(epochs=60, lr=1e-3, heldout_fraction=0.25,
                                                                               device="cpu"), show_progress=False)
    modes = report["mode_labels"]
    label_cluster = modes["label_cluster"]
    assert sorted(label_cluster) == ["pull", "push"] and label_cluster["pull"] != label_cluster["push"]
    # after fine-tuning every training demonstration's posterior picks its label's cluster, so labels share none
    heldout = set(report["heldout"])
    for demo in report["after"]["clusters"]["demonstrations"]:
        if demo["id"] not in heldout:
            assert demo["cluster"] == label_cluster[demo["label"]], demo
    assert report["after"]["clusters"]["label_cluster"] == label_cluster
    accuracy = modes["heldout_accuracy"]["after"]
    assert accuracy["demonstrations"] == 2 and set(accuracy["by_label"]) == {"pull", "push"}
    # the map travels in the checkpoint's JSON, where policy_node serves mode labels from
    assert PolicyModel.load(tmp_path / "ft" / "policy", config, "cpu").mode_labels == label_cluster


def test_label_free_fine_tuning_infers_every_cluster(converted, parent, tmp_path):
    stem, _ = parent
    report = finetune(stem, converted.dataset, tmp_path / "ft", FinetuneConfig(epochs=2, lr=1e-3, device="cpu",
                                                                               mode_labels=False), show_progress=False)
    assert report["mode_labels"]["label_cluster"] == {} and "not asked" in report["mode_labels"]["note"]
    assert report["mode_labels"]["heldout_accuracy"] == {"before": None, "after": None}
    assert report["after"]["joint"]["train"]["loss"] is not None


def test_two_labels_favouring_one_cluster_are_given_different_clusters():
    # both labels' demonstrations sit in cluster 2; pull's second choice is cluster 0
    probabilities = np.array([[0.0, 0.1, 0.9, 0.0], [0.1, 0.0, 0.9, 0.0], [0.3, 0.0, 0.7, 0.0], [0.3, 0.1, 0.6, 0.0],
                              [0.25, 0.25, 0.25, 0.25]])
    labels = ["push", "push", "pull", "pull", ""]
    assert label_assignment(probabilities, labels) == {"push": 2, "pull": 0}
    assert label_assignment(probabilities, [""] * 5) == {}
    with pytest.raises(ValueError, match="5 mode labels .* but the selector has 4 clusters"):
        label_assignment(probabilities, ["a", "b", "c", "d", "e"])
    accuracy = mode_accuracy(labels, np.array([2, 1, 0, 2, 3]), {"push": 2, "pull": 0})
    assert (accuracy["correct"], accuracy["demonstrations"]) == (2, 4)
    assert accuracy["by_label"]["pull"] == {"cluster": 0, "demonstrations": 2, "correct": 1, "accuracy": 0.5}
