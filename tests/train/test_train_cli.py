"""`actaim2 train` end to end on a small stored dataset: view cache, three phases, checkpoints, resume.

The dataset holds ray-cast pictures of a box on a floor (five ring5 cameras, robot absent),
written with the real storage format, visual labels and task embeddings; the run uses a tiny
YAML configuration (a few steps per phase), so it checks the plumbing, not learning.
"""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import torch
import yaml

from actaim2.artifact.checkpoint import encoder_path, load_policy, perception_record
from actaim2.cli import main as cli_main
from actaim2.data.actions import ActionSequence
from actaim2.data.encoder import ImageEncoder
from actaim2.data.labelling import EMBEDDINGS_FILE, ENCODER_FILE, encoder_digest
from actaim2.data.storage import DatasetWriter, encode_trajectory, write_labels
from actaim2.data.trajectory import OBSERVATION_NAMES, CameraImage, ObjectState, Trajectory
from actaim2.perception.config import capture_part, load_perception_config
from actaim2.perception.synthetic import RaycastScene, box_mesh
from actaim2.sim.cameras import ring5

TARGET = np.array([0.75, 0.0, 0.2])
Z_DIM = 10


def _pictures(shift: float) -> dict[str, CameraImage]:
    scene = RaycastScene([(box_mesh([0.75, 0.0, -0.01], [1.2, 1.2, 0.02]), (90, 90, 100)),
                          (box_mesh(TARGET + [shift, 0.0, 0.0], [0.3, 0.4, 0.4]), (160, 110, 60))])
    out = {}
    for cam in ring5(TARGET, width=80, height=60):
        xyz, rgb = scene.capture(cam.T_world_optical, cam.width, cam.height, np.rad2deg(2 * np.arctan(cam.width / (2 * cam.fx))))
        out[cam.name] = CameraImage(rgb, np.nan_to_num(xyz[..., 2]).astype(np.float32), cam.K, cam.T_world_optical)
    return out


def _trajectory(i: int, pictures: dict, instance: int = 0, split: str = "train_seen") -> Trajectory:
    side = 1.0 if i % 2 else -1.0
    action = ActionSequence(p1=TARGET + [-0.2, 0.1 * side, 0.1], p2=TARGET + [-0.3, 0.1 * side, 0.1], R0=np.eye(3), start_distance=0.1)
    return Trajectory(
        id=f"box-random-{i:05d}", object_id=f"storage_furniture_{instance:03d}", category="storage_furniture", instance=instance,
        split=split, sampler="random", seed=i, keyposes=action.keyposes(),
        observations={name: pictures[0.0] for name in OBSERVATION_NAMES} | {"final": pictures[0.1 * side]},
        robot_joints={name: {"panda_joint1": 0.0} for name in OBSERVATION_NAMES},
        object_state=ObjectState(["door"], np.array([0.0]), np.array([1.0]), np.array([0.0]), np.array([0.5])),
        info={},
    )


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("ds")
    pictures = {s: _pictures(s) for s in (0.0, 0.1, -0.1)}
    ids = []
    with DatasetWriter(root, {"perception": capture_part(load_perception_config("ring5")), "robot": "panda"}) as writer:
        for i in range(12):
            ids.append(writer.append(encode_trajectory(_trajectory(i, pictures)))["id"])
        # Training takes the extra training instances too, never an evaluation split's.
        ids.append(writer.append(encode_trajectory(_trajectory(12, pictures, 16, "train_extra")))["id"])
        ids.append(writer.append(encode_trajectory(_trajectory(13, pictures, 8, "train_unseen_instance")))["id"])
    write_labels(root, [{"id": t, "score": 1.0, "change": 1.0, "success": i != 5} for i, t in enumerate(ids)])  # one failure
    torch.manual_seed(0)
    ImageEncoder.autoencoder().save(root / ENCODER_FILE)  # the encoder E said to have made the synthetic task embeddings
    rng = np.random.default_rng(0)
    np.savez(root / EMBEDDINGS_FILE, ids=np.array(ids), z=rng.normal(size=(len(ids), Z_DIM)).astype(np.float32),
             encoder_digest=np.array(encoder_digest(root / ENCODER_FILE)))
    return root


def _config(tmp_path) -> str:
    path = tmp_path / "tiny.yaml"
    step = {"epochs": 2, "batch_size": 4, "lr": 1.0e-3}
    path.write_text(yaml.safe_dump({
        "phases": ["selector", "predictor", "joint"], "device": "cpu", "augment": True, "validation_fraction": 0.25,
        "selector": {"z_tokens": 2, "width": 32, "blocks": 1, "decoder_layers": 1, "latent_dim": 8, "y_dim": 8,
                     "obs": {"input_resolution": 16, "widths": [8, 16], "token_dim": 16}},
        "predictor": {"patch": 16, "width": 32, "layers_within": 1, "layers_across": 1, "heads": 2},
        "selector_phase": step, "predictor_phase": step, "joint_phase": step,
    }))
    return str(path)


def test_train_command_runs_all_phases_and_writes_loadable_checkpoints(dataset, tmp_path):
    out = tmp_path / "run"
    args = ["train", "--data", str(dataset), "--out", str(out), "--config", _config(tmp_path), "--no-progress"]
    assert cli_main(args) == 0
    caches = list((dataset / "cache").iterdir())
    cached = json.loads((caches[0] / "done.json").read_text())["ids"]
    assert len(caches) == 1 and len(cached) == 12  # the successes of train_seen and train_extra
    assert "box-random-00012" in cached and "box-random-00013" not in cached
    record = perception_record(load_perception_config("ring5"))
    policy = load_policy(out / "policy", record)
    assert policy.meta["lineage"]["phases_done"] == ["selector", "predictor", "joint"]
    digest = encoder_digest(dataset / ENCODER_FILE)
    assert policy.meta["lineage"]["encoder_digest"] == digest  # the E of the z it learned (finetune checks it)
    assert policy.predictor.config.image_size == 128 and policy.selector.config.z_dim == Z_DIM
    assert load_policy(out / "goal_rvt", record).predictor is not None
    for stem in ("policy", "goal_rvt"):  # E travels with each model: bag2dataset and Goal-RVT embed with it
        assert encoder_digest(encoder_path(out / stem)) == digest
    history = [json.loads(line) for line in (out / "history.jsonl").read_text().splitlines()]
    assert {h["phase"] for h in history} == {"selector", "predictor", "joint"}
    assert all(h["val"] is not None and np.isfinite(h["val"]["loss"]) for h in history)
    assert any((out / "tensorboard").iterdir())
    # A finished run resumes to nothing left to do, and the cache is reused.
    assert cli_main(args + ["--resume"]) == 0
    assert len(list((dataset / "cache").iterdir())) == 1
    # Curves and validation figures of the run (the fixture has one split: measured on train_seen here).
    assert cli_main(["validate", str(out), "--data", str(dataset), "--split", "train_seen", "--no-progress"]) == 0
    report = json.loads((out / "validation.json").read_text())
    assert report["weights_sha256"] == policy.meta["weights_sha256"] and report["selector"]["trajectories"] == 11
    assert sum(report["selector"]["posterior"]["counts"]) == 11 == sum(report["selector"]["prior_draws"]["counts"])
    for by_phase in report["actions"].values():
        assert list(by_phase) == ["all", "init", "reach", "grasp", "manipulate"]
        assert by_phase["all"]["keyframes"] == 44 == sum(by_phase[p]["keyframes"] for p in list(by_phase)[1:])
        for figures in by_phase.values():
            assert 0.0 <= figures["translation_median_mm"] <= figures["translation_p90_mm"] < 2000.0
            assert 0.0 <= figures["rotation_median_deg"] <= figures["rotation_p90_deg"] <= 180.0
    assert 0 <= report["mode_chain"]["trajectories"] <= 11 and set(report["outcome_following"]) <= {"init", "reach", "grasp", "manipulate"}
    assert set(report["drawn_following"]) <= {"reach", "manipulate"}
    assert set(report["swapped_following"]) == set(report["drawn_following"])  # the same keyframes, two questions
    text = (out / "validation.md").read_text()
    assert (out / "curves.png").stat().st_size > 10_000 and "| true z" in text and "| MANIPULATE | 11 |" in text
    assert "Mode chain" in text
    # A checkpoint outside a run folder (as shipped): the figures, no curves; on the threads asked for.
    shipped = tmp_path / "shipped"
    assert cli_main(["validate", str(shipped), "--checkpoint", str(out / "policy"), "--data", str(dataset),
                     "--split", "train_seen", "--no-progress", "--threads", "2"]) == 0
    assert torch.get_num_threads() == 2  # the folder's one_torch_thread fixture restores it
    assert (shipped / "validation.md").read_text() == text and not (shipped / "curves.png").exists()
    assert cli_main(["validate", str(shipped), "--data", str(dataset), "--threads", "-1"]) == 2
    # The selector's draws at another noise scale than policy_node's (0), recorded in both reports.
    assert report["noise_scale"] == 0.0
    trained = tmp_path / "trained_spread"
    assert cli_main(["validate", str(trained), "--checkpoint", str(out / "policy"), "--data", str(dataset),
                     "--split", "train_seen", "--no-progress", "--noise-scale", "1"]) == 0
    assert json.loads((trained / "validation.json").read_text())["noise_scale"] == 1.0
    assert cli_main(["validate", str(shipped), "--data", str(dataset), "--noise-scale", "-1"]) == 2


def test_another_training_seed_gives_another_checkpoint(dataset, tmp_path):
    """``--seed`` replaces the configuration's seed: recorded in the checkpoint, other weights."""
    record = perception_record(load_perception_config("ring5"))
    weights = {}
    for seed in (0, 1):
        out = tmp_path / f"seed{seed}"
        assert cli_main(["train", "--data", str(dataset), "--out", str(out), "--config", _config(tmp_path),
                         "--phases", "selector", "--seed", str(seed), "--no-progress"]) == 0
        policy = load_policy(out / "policy", record)
        assert policy.meta["train_config"]["seed"] == seed
        weights[seed] = policy.meta["weights_sha256"]
    assert weights[0] != weights[1]


def test_baseline_selector_reuses_the_goal_rvt_predictor(dataset, tmp_path):
    base = ["--data", str(dataset), "--config", _config(tmp_path), "--no-progress"]
    assert cli_main(["train", "--out", str(tmp_path / "goal"), "--phases", "predictor"] + base) == 0
    assert cli_main(["train", "--out", str(tmp_path / "cvae"), "--selector", "cvae", "--phases", "selector", "joint",
                     "--init-from", str(tmp_path / "goal" / "goal_rvt")] + base) == 0
    record = perception_record(load_perception_config("ring5"))
    cvae = load_policy(tmp_path / "cvae" / "policy", record)
    assert cvae.selector.config.kind == "cvae" and cvae.meta["lineage"]["init_from"]["path"].endswith("goal_rvt")
    goal = load_policy(tmp_path / "goal" / "goal_rvt", record)
    # the z statistics came with the predictor, so eps means the same thing to both
    assert (cvae.selector.z_mean == goal.selector.z_mean).all()


def test_validate_refuses_data_without_dof_measurements(dataset, tmp_path, capsys):
    """Bag demonstrations store no DoF change, so no outcome to follow: validate says so and exits 1."""
    out = tmp_path / "run"
    assert cli_main(["train", "--data", str(dataset), "--out", str(out), "--config", _config(tmp_path), "--no-progress"]) == 0
    bag_like = tmp_path / "bag_like"
    shutil.copytree(dataset, bag_like, ignore=shutil.ignore_patterns("cache"))
    entries = [json.loads(line) for line in (bag_like / "index.jsonl").read_text().splitlines()]
    entries[0]["dof_change"] = []  # what bag2dataset's empty ObjectState stores
    (bag_like / "index.jsonl").write_text("".join(json.dumps(e) + "\n" for e in entries))
    capsys.readouterr()
    assert cli_main(["validate", str(out), "--data", str(bag_like), "--split", "train_seen", "--no-progress"]) == 1
    assert "without a DoF measurement" in capsys.readouterr().out
    assert not (out / "validation.md").exists()
