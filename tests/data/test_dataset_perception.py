"""A dataset records the perception it was collected under; training runs are held to it.

Also: torch datasets hold the training split unless a held-out split is asked for explicitly,
and collection never falls back to ray-cast pictures unless told to.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from actaim2.data.collect import CollectConfig, collect
from actaim2.data.storage import DatasetReader, DatasetWriter, EncodedTrajectory
from actaim2.data.torch_dataset import KeyframeDataset, ModeDataset
from actaim2.perception.config import PerceptionMismatchError, capture_part, load_perception_config
from actaim2.perception.pipeline import Perception
from actaim2.perception.self_filter import RobotSelfFilter
from actaim2.robots import load_robot_spec

OBJECT = ("storage_furniture", 0)


def test_a_dataset_of_one_rig_is_refused_by_a_training_run_set_for_another(tmp_path):
    out = tmp_path / "ds"
    nothing = {"random": 0, "grasp": 0, "gmm": 0}  # dataset.json is all this test needs
    collect(CollectConfig(out=out, objects=(OBJECT,), per_object=nothing, workers=0, perception="ring5", show_progress=False))
    ring5 = load_perception_config("ring5")
    assert DatasetReader(out).perception_capture() == capture_part(ring5)
    robot = RobotSelfFilter(load_robot_spec("panda"))

    with pytest.raises(PerceptionMismatchError, match=r"rig \(dataset 'ring5', training run 'azure_kinect'\)"):
        KeyframeDataset(out, success=None, perception=Perception(load_perception_config("azure_kinect"), robot))
    with pytest.raises(PerceptionMismatchError, match=r"half_extent \(dataset 0.6, training run 0.5\)"):
        ModeDataset(out, success=None, perception=Perception(ring5.replace(half_extent=0.5), robot))
    # Resolution, channels and splatting are the run's (the checkpoint's) choice: views are recomputed.
    KeyframeDataset(out, success=None, perception=Perception(ring5.replace(resolution=224, splat_radius=0.8), robot))
    # Resuming the collection under another rig would mix pictures: refused as well.
    with pytest.raises(PerceptionMismatchError, match="rig"):
        collect(CollectConfig(out=out, objects=(OBJECT,), per_object=nothing, workers=0, perception="azure_kinect", show_progress=False))


def _entry(tid: str, split: str) -> EncodedTrajectory:
    return EncodedTrajectory(tid, [(f"{tid}.meta.json", b"{}")], {"id": tid, "split": split, "sampler": "random", "gt_success": True})


def test_torch_datasets_hold_train_seen_unless_a_held_out_split_is_asked_for(tmp_path):
    with DatasetWriter(tmp_path, {"perception": capture_part(load_perception_config("ring5"))}) as writer:
        for tid, split in (("a", "train_seen"), ("b", "train_unseen_instance"), ("c", "heldout_category"), ("d", "train_seen"),
                           ("e", "train_extra")):
            writer.append(_entry(tid, split))
    frames = KeyframeDataset(tmp_path, success=None)
    assert [e["id"] for e in frames.entries] == ["a", "d"] and frames.splits == ("train_seen",)
    assert "splits=['train_seen'], the default" in repr(frames)
    with pytest.raises(ValueError, match=r"\['heldout_category'\] are held out .* allow_held_out=True"):
        ModeDataset(tmp_path, splits=["train_seen", "heldout_category"], success=None)
    training = ModeDataset(tmp_path, splits=["train_seen", "train_extra"], success=None)  # both training splits, no flag
    assert sorted(e["id"] for e in training.entries) == ["a", "d", "e"]
    held_out = ModeDataset(tmp_path, splits=["heldout_category", "train_unseen_instance"], success=None, allow_held_out=True)
    assert sorted(e["id"] for e in held_out.entries) == ["b", "c"]


def _collect_cli(out, *extra: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, VK_ICD_FILENAMES=str(out.parent / "no_such_icd.json"))  # a machine without a Vulkan device
    cmd = [sys.executable, "-m", "actaim2.cli", "collect", "--out", str(out), "--object", f"{OBJECT[0]}:{OBJECT[1]}",
           "--random", "0", "--grasp", "0", "--gmm", "0", "--workers", "0", "--no-progress", *extra]
    return subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=120)


def test_collection_refuses_the_ray_cast_fallback_unless_allowed(tmp_path):
    refused = _collect_cli(tmp_path / "refused")
    assert refused.returncode == 1 and "--allow-raycast" in refused.stderr and "no Vulkan device" in refused.stderr
    assert not (tmp_path / "refused" / "dataset.json").exists()
    allowed = _collect_cli(tmp_path / "allowed", "--allow-raycast")
    assert allowed.returncode == 0, allowed.stderr
    assert "collecting ray-cast pictures" in allowed.stderr  # always logged
    info = json.loads((tmp_path / "allowed" / "dataset.json").read_text())
    assert info["perception"]["render_path"] == "raycast" and info["rig"] == "ring5"
