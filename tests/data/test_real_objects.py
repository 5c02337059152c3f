"""Collection on real PartNet-Mobility folders: categories, splits (YAML or by category), and one
trajectory collected on a shared object (ray casting: no decomposition, no Vulkan needed)."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from actaim2.data.collect import CollectConfig, TrajectoryCollector, stage_tasks
from actaim2.data.real_objects import folder_objects, read_object_splits, split_by_category
from actaim2.data.splits import TRAIN, UNSEEN_CATEGORY, UNSEEN_INSTANCE
from actaim2.data.storage import EncodedTrajectory

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "sim"))
from partnet_shared import shared_partnet  # noqa: E402


def test_folders_get_their_category_and_a_split_by_category_or_from_yaml(tmp_path):
    root = shared_partnet()
    names = ["101773", "102456", "1053", "22241", "45780"]
    found = {o.object_id: o for name in names for o in folder_objects(root / name)}
    assert sorted(found) == sorted(names)
    assert found["101773"].category == "oven" and found["101773"].split == UNSEEN_CATEGORY  # not a catalogue category
    assert found["102456"].category == "box" and found["102456"].split == UNSEEN_CATEGORY  # a held-out category
    for name in ("1053", "22241", "45780"):  # training categories: seen or unseen instance, fixed per folder name
        assert found[name].split in (TRAIN, UNSEEN_INSTANCE) and found[name].split == split_by_category(found[name].category, name)
    assert {split_by_category("table", f"t{k}") for k in range(20)} == {TRAIN, UNSEEN_INSTANCE}

    yaml_file = tmp_path / "splits.yaml"
    yaml_file.write_text("45780: heldout_category\n22241: train_seen\n")
    splits = read_object_splits(yaml_file)
    chosen = {o.object_id: o.split for name in names for o in folder_objects(root / name, splits)}
    assert chosen["45780"] == UNSEEN_CATEGORY and chosen["22241"] == TRAIN and chosen["101773"] == UNSEEN_CATEGORY
    yaml_file.write_text("45780: somewhere\n")
    with pytest.raises(ValueError, match="somewhere"):
        read_object_splits(yaml_file)


CABINET = "46236"  # a train-split cabinet with a door and a drawer, all of its meshes convex: no decomposition
SAMPLER_TRAJECTORIES = 16  # per sampler


@pytest.mark.parametrize("sampler", ["random", "grasp"])
def test_the_samplers_move_a_real_cabinet(tmp_path, sampler):
    """``collect``'s own trajectory path on a real folder (seeded; ray casting, so no Vulkan):
    the samplers' ground truth is above zero, and executed trajectories touch the cabinet."""
    (cabinet,) = folder_objects(shared_partnet() / CABINET)
    config = CollectConfig(out=tmp_path / "ds", objects=(), folders=(cabinet,), per_object={sampler: SAMPLER_TRAJECTORIES},
                           workers=0, render_path="raycast", hull_cache=tmp_path / "hulls", show_progress=False)
    collector = TrajectoryCollector(config)
    entries, skipped = [], []
    for task in stage_tasks(config, sampler, range(SAMPLER_TRAJECTORIES)):
        assert (task.folder, task.category, task.instance) == (cabinet.folder, "storage_furniture", -1)
        result = collector.run(task)  # the object reset, observed, sampled on and acted upon
        if isinstance(result, EncodedTrajectory):
            entries.append(result.entry)
        else:  # every attempt refused by the planner or the IK screen: a skip record, no error
            assert result["reasons"] and not any(r.startswith("error") for r in result["reasons"]), result
            skipped.append(result)
    assert all((e["object_id"], e["category"], e["instance"]) == (CABINET, "storage_furniture", -1) for e in entries)
    assert len(entries) >= SAMPLER_TRAJECTORIES // 2, f"{len(skipped)} of {SAMPLER_TRAJECTORIES} skipped: {skipped[:2]}"
    successes = sum(e["gt_success"] for e in entries)
    moved = sum(max(abs(c) for c in e["dof_change"]) > 0.05 for e in entries)
    assert successes > 0, f"{sampler}: 0 of {len(entries)} succeeded ({moved} moved a part by more than 5 %)"
    assert sum(e["touched"] for e in entries) >= moved > 0
