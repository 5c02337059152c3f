"""The partnet catalogue: real PartNet-Mobility folders split by their splits.yaml, never by hash;
a collection on them keeps val and test objects out of what training reads."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pytest
import yaml

from actaim2.cli import main as cli
from actaim2.data.real_objects import (
    PARTNET_ROOT_ENV,
    catalogue_folders,
    check_training_objects,
    folder_objects,
    partnet_root,
    partnet_splits,
    read_object_splits,
)
from actaim2.data.splits import CALIBRATION_SPLITS, GENERATED, PARTNET, TRAINING_SPLITS, catalogue
from actaim2.data.storage import DatasetReader

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "sim"))
from partnet_shared import SHARED_PARTNET, make_object, shared_partnet  # noqa: E402

COMMITTED = (
    Path(__file__).resolve().parents[2] / "actaim2_policy" / "checkpoints" / "actaim2_ring5"
)


def test_catalogues_name_their_splits_and_roles() -> None:
    assert PARTNET.splits == (
        "train",
        "val",
        "test_unseen_instance",
        "test_unseen_category",
        "extra",
    )
    assert set(PARTNET.training) == {"train", "extra"} and PARTNET.test == (
        "test_unseen_instance",
        "test_unseen_category",
    )
    assert not set(TRAINING_SPLITS) & set(PARTNET.validation + PARTNET.test) and set(
        CALIBRATION_SPLITS
    ) == {"train_seen", "train"}
    assert not set(GENERATED.splits) & set(
        PARTNET.splits
    )  # a trajectory's split names its catalogue
    with pytest.raises(ValueError, match="not splits of the partnet catalogue"):
        PARTNET.check_splits(("train_seen",), "--splits")
    with pytest.raises(ValueError, match="unknown catalogue"):
        catalogue("shapenet")


def test_partnet_root_comes_from_the_option_or_the_environment(monkeypatch, tmp_path) -> None:
    monkeypatch.delenv(PARTNET_ROOT_ENV, raising=False)
    with pytest.raises(ValueError, match="--partnet-root"):
        partnet_root()
    with pytest.raises(ValueError, match="no splits.yaml"):
        partnet_root(tmp_path)
    monkeypatch.setenv(PARTNET_ROOT_ENV, str(shared_partnet()))
    assert partnet_root() == SHARED_PARTNET


def test_catalogue_folders_follow_the_splits_file() -> None:
    root = shared_partnet()
    listed = yaml.safe_load((root / "splits.yaml").read_text())
    for split in PARTNET.splits:
        found = catalogue_folders(root, (split,))
        assert sorted(f.object_id for f in found) == sorted(
            k for k, v in listed.items() if v == split
        )
        assert {f.split for f in found} == {split}
    faucets = catalogue_folders(root, ("train", "val"), categories=("faucet",), per_category=1)
    assert [(f.split, f.category) for f in faucets] == [("train", "faucet"), ("val", "faucet")]
    with pytest.raises(ValueError, match="train_seen"):
        catalogue_folders(root, ("train_seen",))


def test_an_unlisted_folder_is_refused_never_split_by_hash(tmp_path, capsys) -> None:
    root = tmp_path / "objects"
    make_object(root / "77777")
    (root / "splits.yaml").write_text("'12': val\n")
    with pytest.raises(ValueError, match=r"\['77777'\] are in no split"):
        folder_objects(root, partnet_splits(root), listed_only=True)
    assert folder_objects(root)[0].split in (
        "train_seen",
        "train_unseen_instance",
    )  # without a catalogue: by hash
    code = cli(
        [
            "collect",
            "--out",
            str(tmp_path / "ds"),
            "--catalogue",
            "partnet",
            "--partnet-root",
            str(root),
            "--objects",
            str(root),
            "--no-progress",
        ]
    )
    assert code == 2 and "77777" in capsys.readouterr().err
    (root / "splits.yaml").write_text("'77777': somewhere\n")
    with pytest.raises(ValueError, match="somewhere"):
        partnet_splits(root)


@pytest.fixture(scope="module")
def collected(tmp_path_factory) -> Path:
    """Two random trajectories on the first faucet of train, val and test_unseen_instance each,
    collected through `actaim2 collect --catalogue partnet` (ray casting; the convex decomposition
    is left to its own tests: each object's meshes are then one hull)."""
    root = shared_partnet()
    out = tmp_path_factory.mktemp("partnet") / "ds"
    prepared: list[list[Path]] = []
    args = ("--splits train,val,test_unseen_instance --categories faucet "
            "--instances-per-category 1 --random 2 --grasp 0 --gmm 0 --workers 0 "
            "--render-path raycast --encoder-steps 2 --no-progress").split()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("actaim2.data.collect.prepare_objects",
                      lambda folders, cache, workers: prepared.append(folders))
        code = cli(["collect", "--out", str(out), "--catalogue", "partnet",
                    "--partnet-root", str(root), "--hull-cache", str(out.parent / "hulls"), *args])
    assert code == 0
    assert len(prepared) == 1 and len(prepared[0]) == 3
    return out


def test_val_and_test_objects_never_reach_training(collected: Path, tmp_path, capsys) -> None:
    listed = partnet_splits(shared_partnet())
    entries = DatasetReader(collected).entries
    assert entries and {e["split"] for e in entries} <= {"train", "val", "test_unseen_instance"}
    for e in entries:  # every trajectory carries its object's split from splits.yaml
        assert e["instance"] == -1 and e["split"] == listed[e["object_id"]]
    training = {e["object_id"] for e in entries if e["split"] in TRAINING_SPLITS}
    assert training and all(listed[o] == "train" for o in training)
    info = json.loads((collected / "dataset.json").read_text())
    assert sorted(split for _, split in info["folders"]) == [
        "test_unseen_instance",
        "train",
        "val",
    ]
    check_training_objects(entries, listed)

    # a dataset whose index claims a val object is a training object:
    # `train --catalogue partnet` refuses it
    tampered = tmp_path / "tampered"
    shutil.copytree(collected, tampered)
    val_id = next(e["object_id"] for e in entries if e["split"] == "val")
    lines = [
        json.loads(t) for t in (tampered / "index.jsonl").read_text().splitlines() if t.strip()
    ]
    (tampered / "index.jsonl").write_text(
        "".join(
            json.dumps({**e, "split": "train"} if e["object_id"] == val_id else e) + "\n"
            for e in lines
        )
    )
    code = cli(
        [
            "train",
            "--data",
            str(tampered),
            "--out",
            str(tmp_path / "run"),
            "--catalogue",
            "partnet",
            "--partnet-root",
            str(shared_partnet()),
            "--no-progress",
        ]
    )
    assert code == 2 and f"{val_id} (stored as train, catalogue val)" in capsys.readouterr().out
    assert not (tmp_path / "run").exists()


@pytest.mark.skipif(not COMMITTED.with_suffix(".json").is_file(), reason="no committed checkpoint")
def test_validate_refuses_a_test_split_without_final(collected: Path, tmp_path, capsys,
                                                     monkeypatch) -> None:
    monkeypatch.delenv(PARTNET_ROOT_ENV, raising=False)
    base = ["validate", str(tmp_path / "v"), "--checkpoint", str(COMMITTED),
            "--lock", str(tmp_path / "protocol.lock")]
    args = base + ["--data", str(collected), "--catalogue", "partnet",
                   "--partnet-root", str(shared_partnet())]
    assert cli(args + ["--split", "test_unseen_instance"]) == 2
    out = capsys.readouterr().out
    assert "refuses test-split objects" in out and "--final" in out
    assert cli(args + ["--split", "test_unseen_instance", "--final"]) == 2
    assert "no protocol lock" in capsys.readouterr().out
    # a test object stored under a generated split name is known by the splits file beside it
    relabelled = tmp_path / "relabelled"
    shutil.copytree(collected, relabelled)
    lines = [json.loads(t) for t in (relabelled / "index.jsonl").read_text().splitlines() if t]
    test_id = next(e["object_id"] for e in lines if e["split"] == "test_unseen_instance")
    moved = [{**e, "split": "train_unseen_instance"} if e["object_id"] == test_id else e
             for e in lines]
    (relabelled / "index.jsonl").write_text("".join(json.dumps(e) + "\n" for e in moved))
    assert cli(base + ["--data", str(relabelled), "--split", "train_unseen_instance"]) == 2
    assert f"test_unseen_instance: {test_id}" in capsys.readouterr().out
    assert not (tmp_path / "v" / "validation.json").exists()


def test_the_sim_loop_runs_a_partnet_split_but_never_a_test_split(monkeypatch) -> None:
    from actaim2.policy.episodes import catalogue_paths

    root = shared_partnet()
    listed = yaml.safe_load((root / "splits.yaml").read_text())
    val = catalogue_paths("partnet", str(root), [""])  # the default: val
    assert sorted(Path(p).name for p in val) == sorted(k for k, v in listed.items() if v == "val")
    monkeypatch.setenv(PARTNET_ROOT_ENV, str(root))
    assert len(catalogue_paths("partnet", "", ["train", "extra"])) == 42 + 51
    with pytest.raises(ValueError, match="test splits"):
        catalogue_paths("partnet", str(root), ["val", "test_unseen_category"])
    assert catalogue_paths("generated", "", [""]) == []
    with pytest.raises(ValueError, match="for the partnet catalogue"):
        catalogue_paths("generated", "", ["val"])


def test_data_collection_finds_real_objects_by_folder_name(collected: Path) -> None:
    from actaim2.eval.data_collection import data_collection_samplers
    from actaim2.eval.evalset import partnet_objects

    objects = partnet_objects(shared_partnet(), ("val", "test_unseen_instance"), 1, ("faucet",))
    samplers = data_collection_samplers(collected, objects)
    assert sorted(samplers) == sorted(o.key for o in objects)
    assert all(o.key == f"folder:{o.object_id}" for o in objects)


def test_data_collection_explores_an_object_the_dataset_does_not_hold(collected: Path, tmp_path,
                                                                      monkeypatch) -> None:
    """A val faucet the dataset has no trajectory of: Data Collection collects its own exploration
    (half random, half grasp, skipped ones replaced), labels it with the dataset's calibrated success model, never
    recalibrating on it, and fits its GMM sampler from it."""
    from actaim2.data.labelling import stored_model
    from actaim2.eval.data_collection import data_collection_samplers, explored_samplers
    from actaim2.eval.evalset import partnet_objects

    held = {e["object_id"] for e in DatasetReader(collected).entries}
    unheld = [o for o in partnet_objects(shared_partnet(), ("val",), 2, ("faucet",))
              if o.object_id not in held]
    assert unheld and not data_collection_samplers(collected, unheld)
    monkeypatch.setattr("actaim2.data.collect.prepare_objects", lambda folders, cache, workers: None)
    out = tmp_path / "data_collection"
    samplers, labelling = explored_samplers(collected, unheld[:1], out, per_object=3,
                                            render_path="raycast", workers=0, show_progress=False)
    entries = DatasetReader(out).entries
    assert len(entries) == 3 and {e["sampler"] for e in entries} <= {"random", "grasp"}  # a skipped grasp: a random top-up
    assert {e["object_id"] for e in entries} == {unheld[0].object_id}
    assert {e["split"] for e in entries} == {"val"}
    assert list(samplers) == [unheld[0].key]
    model = stored_model(collected)
    assert labelling["model"]["weights"] == list(model.weights)
    assert labelling["model"]["threshold"] == model.threshold
    assert not labelling["model"]["calibrated_here"]
    assert labelling["per_split"]["val"]["n"] == 3 and "faucet" in labelling["per_category"]


def test_object_splits_take_the_partnet_split_names(tmp_path) -> None:
    root = tmp_path / "objects"
    make_object(root / "77777")
    make_object(root / "88888")
    named = tmp_path / "mine.yaml"
    named.write_text("'77777': val\n'88888': test_unseen_category\n")
    found = {o.object_id: o.split for o in folder_objects(root, read_object_splits(named))}
    assert found == {"77777": "val", "88888": "test_unseen_category"}
