"""Collection in the simulator: a tiny end-to-end run, determinism, resume after a hard kill.

These tests render with the simulator's cameras (SAPIEN on lavapipe, or ray casting when no
Vulkan device exists) and execute keyposes through the control package's planner.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from actaim2.data.collect import (
    SKIPPED_FILE,
    CollectConfig,
    TrajectoryCollector,
    check_resumable,
    collect,
    derive_seed,
    per_object,
    stage_tasks,
    top_up_tasks,
)
from actaim2.data.storage import MAX_TRAJECTORY_BYTES, DatasetReader, decode_trajectory
from actaim2.data.torch_dataset import KeyframeDataset, ModeDataset
from actaim2.data.trajectory import OBSERVATION_NAMES
from actaim2.parallel import ray_available
from actaim2.perception.config import load_perception_config
from actaim2.perception.ortho_views import CHANNELS, VIEWS
from actaim2.perception.pipeline import Perception
from actaim2.perception.self_filter import RobotSelfFilter
from actaim2.robots import load_robot_spec

OBJECT = ("storage_furniture", 0)


def test_tiny_collection_end_to_end(tmp_path, capsys):
    out = tmp_path / "ds"
    config = CollectConfig(out=out, objects=(OBJECT,), per_object={"random": 2, "grasp": 1, "gmm": 1}, workers=0,
                           encoder_steps=20, show_progress=False)
    report = collect(config)
    reader = DatasetReader(out)
    stored = {e["sampler"] for e in reader.entries}
    assert len(reader.entries) + report["stages"][0]["skipped"] + report["stages"][1]["skipped"] == 4
    assert "random" in stored and len(reader.entries) >= 3
    assert all(e["size"] <= MAX_TRAJECTORY_BYTES and "label" in e and e["split"] == "train_seen" for e in reader.entries)
    traj = reader.read(reader.entries[0])
    assert [k.phase for k in traj.keyposes] == [0, 1, 2, 3]
    assert set(traj.observations) == set(OBSERVATION_NAMES)
    assert all(len(obs) == 5 for obs in traj.observations.values())  # ring5
    assert all(set(j) >= {"panda_joint1", "panda_finger_joint1"} for j in traj.robot_joints.values())
    assert (out / "labelling.json").exists() and (out / "encoder.pt").exists()

    frames = KeyframeDataset(out, success=None)
    assert len(frames) == 4 * len(reader.entries)
    item = frames[1]
    assert item["phase"] == 1 and item["rgb"].shape == (5, 3, 240, 320) and item["keypose"].shape == (8,)
    assert item["z"].ndim == 1 and item["gripper_closed"] is False
    assert ModeDataset(out, success=None)[0]["depth"].shape == (5, 240, 320)
    perception = Perception(load_perception_config("ring5"),
                            RobotSelfFilter(load_robot_spec("panda")))
    views = KeyframeDataset(out, success=None, perception=perception)[2]["views"]  # O_2: the hand at p1
    assert views.shape == (len(VIEWS), len(CHANNELS), 128, 128) and views[:, CHANNELS.index("occupancy")].sum() > 1000

    from actaim2.cli import main

    assert main(["stats", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "Success rate per category and sampler" in printed and "storage_furniture" in printed


def test_counts_per_split_and_random_replacements_of_skipped_trajectories(tmp_path):
    config = CollectConfig(out=tmp_path, objects=(("box", 0), OBJECT), per_object={"random": 4, "grasp": 3}, other_splits_share=0.5)
    ids = [t.tid for s in ("random", "grasp") for t in stage_tasks(config, s, range(4))]
    assert ids == ["box_000-random-00000", "box_000-random-00001"] + [f"storage_furniture_000-random-{k:05d}" for k in range(4)] + \
        ["box_000-grasp-00000", "box_000-grasp-00001"] + [f"storage_furniture_000-grasp-{k:05d}" for k in range(3)]  # held out: half, rounded up
    assert top_up_tasks(config) == []
    assert per_object(config, "random", "train_extra") == 4  # more training instances: the full count, not the share
    given_up = [("box_000-grasp-00000", "grasp"), ("box_000-grasp-00001", "grasp"), ("storage_furniture_000-gmm-00000", "gmm")]
    (tmp_path / SKIPPED_FILE).write_text("".join(json.dumps({"id": i, "sampler": s, "reasons": ["sampler found no action"]}) + "\n"
                                                 for i, s in given_up))
    tasks = top_up_tasks(config)  # the box's two grasp trajectories become random ones past its random count; GMM ones are not explore
    assert [(t.tid, t.sampler, t.index, t.seed) for t in tasks] == [
        (f"box_000-random-{k:05d}", "random", k, derive_seed(0, "box_000", 1, k)) for k in (2, 3)]


def test_a_task_run_again_gives_the_same_trajectory(tmp_path):
    config = CollectConfig(out=tmp_path, objects=(OBJECT,), per_object={"random": 1}, workers=0, show_progress=False)
    collector = TrajectoryCollector(config)
    task = stage_tasks(config, "random", range(1))[0]
    first, second = collector.run(task), collector.run(task)
    a, b = decode_trajectory(dict(first.members)), decode_trajectory(dict(second.members))
    for ka, kb in zip(a.keyposes, b.keyposes):
        np.testing.assert_allclose(ka.position, kb.position)
        np.testing.assert_allclose(ka.quat_xyzw, kb.quat_xyzw)
    np.testing.assert_allclose(a.object_state.final, b.object_state.final, atol=1e-6)
    np.testing.assert_array_equal(a.observations["final"]["cam0"].rgb, b.observations["final"]["cam0"].rgb)


def test_actions_per_placement_share_one_reset_and_one_o_init(tmp_path):
    """--actions-per-placement 2: random trajectories 0 and 1 start from the same scene (one O_init,
    two actions), trajectory 2 from another; a dataset is resumed only with the count it was made with."""
    config = CollectConfig(out=tmp_path, objects=(OBJECT,), per_object={"random": 3}, workers=0, show_progress=False,
                           actions_per_placement=2)
    tasks = stage_tasks(config, "random", range(3))
    assert tasks[0].reset_seed == tasks[1].reset_seed != tasks[2].reset_seed
    assert len({t.seed for t in tasks}) == 3  # each its own action
    assert all(t.reset_seed is None for t in stage_tasks(CollectConfig(out=tmp_path, objects=(OBJECT,), per_object={"random": 3}),
                                                          "random", range(3)))
    collector = TrajectoryCollector(config)
    first, second, third = (decode_trajectory(dict(collector.run(t).members)) for t in tasks)
    assert first.info["reset_seed"] == second.info["reset_seed"] == tasks[0].reset_seed
    for cam in first.observations["init"]:
        np.testing.assert_array_equal(first.observations["init"][cam].rgb, second.observations["init"][cam].rgb)
        np.testing.assert_array_equal(first.observations["init"][cam].depth, second.observations["init"][cam].depth)
    assert not np.array_equal(first.observations["init"]["cam0"].depth, third.observations["init"]["cam0"].depth)
    assert not np.allclose(first.keyposes[1].position, second.keyposes[1].position)
    with pytest.raises(ValueError, match="actions_per_placement"):
        CollectConfig(out=tmp_path, objects=(OBJECT,), per_object={"random": 1}, actions_per_placement=0)
    with pytest.raises(ValueError, match="--actions-per-placement 2"):
        check_resumable({"seed": 0, "robot": "panda", "actions_per_placement": 2}, CollectConfig(out=tmp_path, objects=(OBJECT,), per_object={}))
    with pytest.raises(ValueError, match="--actions-per-placement 1"):  # collected before the option: one reset each
        check_resumable({"seed": 0, "robot": "panda"}, config)


def _run_until_stored(cmd: list[str], index, stored: int, sig: int) -> subprocess.Popen:
    """Start the CLI in its own process group; once ``stored`` trajectories are indexed, send ``sig``
    to the group (SIGINT: what Ctrl-C in a terminal does; SIGKILL: a power cut)."""
    proc = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 180
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            if index.exists() and index.read_text().count("\n") >= stored:
                break
            time.sleep(0.2)
        assert index.exists() and index.read_text().count("\n") >= stored, f"trajectory {stored} was never stored"
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, sig)
        proc.wait(timeout=60)
    return proc


def test_collection_resumes_after_a_hard_kill_and_after_ctrl_c(tmp_path):
    out = tmp_path / "ds"
    cmd = [sys.executable, "-m", "actaim2.cli", "collect", "--out", str(out), "--object", f"{OBJECT[0]}:{OBJECT[1]}",
           "--random", "4", "--grasp", "0", "--gmm", "0", "--workers", "1", "--no-progress"]
    index = out / "index.jsonl"
    _run_until_stored(cmd, index, 1, signal.SIGKILL)  # the collector and its worker, mid-trajectory
    killed = DatasetReader(out).entries
    assert 1 <= len(killed) < 4
    interrupted = _run_until_stored(cmd, index, len(killed) + 1, signal.SIGINT)
    assert interrupted.returncode == 130 and "run the same command to resume" in interrupted.stderr.read()
    before = DatasetReader(out).entries
    assert [e["id"] for e in before[: len(killed)]] == [e["id"] for e in killed]
    with pytest.raises(ValueError, match="seed 0"):  # another seed would be other trajectories under the same ids
        collect(CollectConfig(out=out, objects=(OBJECT,), per_object={"random": 4}, seed=1, workers=0, show_progress=False))
    config = CollectConfig(out=out, objects=(OBJECT,), per_object={"random": 4}, workers=0, encoder_steps=10, show_progress=False)
    report = collect(config)
    assert report["stages"][0]["already_done"] == len(before)
    after = DatasetReader(out)
    ids = [e["id"] for e in after.entries]
    skipped = (out / SKIPPED_FILE).read_text().count("\n") if (out / SKIPPED_FILE).exists() else 0  # over all three runs
    assert len(ids) == len(set(ids)) == 4 - skipped
    assert all(after.read(e).id == e["id"] for e in after.entries)


@pytest.mark.skipif(ray_available() is not None, reason=str(ray_available()))
@pytest.mark.timeout(900)
def test_collection_on_ray_actors_stores_what_this_process_stores(tmp_path):
    """`actaim2 collect --ray local` (a private Ray instance on loopback) runs the trajectories on
    two actors, the executor evaluation uses; the dataset is the one collected in this process,
    trajectory by trajectory, in the same order."""
    on_ray, here = tmp_path / "ray", tmp_path / "here"
    result = subprocess.run([sys.executable, "-m", "actaim2.cli", "collect", "--out", str(on_ray), "--object", f"{OBJECT[0]}:{OBJECT[1]}",
                             "--random", "3", "--grasp", "0", "--gmm", "0", "--encoder-steps", "10", "--ray", "local", "--workers", "2",
                             "--no-progress"], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "Ray: a local instance at 127.0.0.1:" in result.stdout and "(loopback only)" in result.stdout, result.stdout
    collect(CollectConfig(out=here, objects=(OBJECT,), per_object={"random": 3}, workers=0, encoder_steps=10, show_progress=False))
    ray_entries, here_entries = DatasetReader(on_ray).entries, DatasetReader(here).entries
    assert ray_entries and [e["id"] for e in ray_entries] == [e["id"] for e in here_entries]
    for a, b in zip(ray_entries, here_entries):
        np.testing.assert_allclose(a["action"], b["action"])
        assert a["gt_success"] == b["gt_success"]
    runs = [json.loads(line) for line in (on_ray / "runs.jsonl").read_text().splitlines()]
    assert runs[0]["ray"] == "local"
