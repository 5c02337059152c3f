"""`actaim2 export-lerobot`: the converted demonstrations as a LeRobot v2.1 dataset, read back by our reader:
every keypose, mode label, picture and joint state comes back; the files are laid out and typed as
LeRobot v2.1 (and Hugging Face ``datasets``) expect; damaged or other-version datasets are refused."""
from __future__ import annotations

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from actaim2 import cli
from actaim2.data.storage import DatasetReader
from actaim2.data.trajectory import KEYFRAME_OBSERVATIONS
from actaim2.export.lerobot_v21 import ACTION_NAMES, LeRobotFormatError, read_lerobot


@pytest.fixture(scope="module")
def exported(converted, tmp_path_factory):
    out = tmp_path_factory.mktemp("lerobot") / "demos"
    assert cli.main(["export-lerobot", str(converted.dataset), "--out", str(out)]) == 0
    return out


def test_round_trip_reproduces_every_keypose_label_picture_and_state(converted, exported):
    info, episodes = read_lerobot(exported)
    reader = DatasetReader(converted.dataset)
    assert len(episodes) == len(reader.entries) == info["total_episodes"] == 4
    assert info["total_frames"] == 16 and info["codebase_version"] == "v2.1" and info["robot_type"] == "kinova_j2s6s200"
    for episode, entry in zip(episodes, reader.entries):
        trajectory = reader.read(entry)
        assert episode.task == entry["mode_label"] and episode.meta["actaim2_id"] == entry["id"]
        actions = episode.columns["action"]
        assert actions.shape == (4, len(ACTION_NAMES))
        for row, keypose in zip(actions, trajectory.keyposes):
            np.testing.assert_allclose(row[:3], keypose.position, atol=1e-6)  # float32, metres
            np.testing.assert_allclose(row[3:7], keypose.quat_xyzw, atol=1e-6)
            assert row[7] == float(keypose.gripper_closed)
        names = info["features"]["observation.state"]["names"]
        for k, name in enumerate(KEYFRAME_OBSERVATIONS):
            np.testing.assert_array_equal(episode.columns["observation.images.azure_kinect"][k], trajectory.observations[name]["azure_kinect"].rgb)
            np.testing.assert_allclose(episode.columns["observation.state"][k], [trajectory.robot_joints[name][j] for j in names], atol=1e-6)
        np.testing.assert_array_equal(episode.columns["frame_index"], np.arange(4))
        np.testing.assert_allclose(np.diff(episode.columns["timestamp"]), 1.0 / info["fps"])  # LeRobot's timestamp check


def test_the_files_are_laid_out_and_typed_as_lerobot_v21(exported):
    meta = exported / "meta"
    tasks = [json.loads(line) for line in (meta / "tasks.jsonl").read_text().splitlines()]
    assert tasks == [{"task_index": 0, "task": "pull"}, {"task_index": 1, "task": "push"}]
    episodes = [json.loads(line) for line in (meta / "episodes.jsonl").read_text().splitlines()]
    assert [(e["episode_index"], e["tasks"], e["length"]) for e in episodes] == [(0, ["pull"], 4), (1, ["push"], 4), (2, ["pull"], 4), (3, ["push"], 4)]
    stats = [json.loads(line) for line in (meta / "episodes_stats.jsonl").read_text().splitlines()]
    info = json.loads((meta / "info.json").read_text())
    for s in stats:
        assert set(s["stats"]) == set(info["features"])
        assert np.shape(s["stats"]["observation.images.azure_kinect"]["mean"]) == (3, 1, 1)
        assert np.shape(s["stats"]["action"]["std"]) == (8,) and s["stats"]["action"]["count"] == [4]
    schema = pq.read_schema(exported / "data" / "chunk-000" / "episode_000000.parquet")
    hf = json.loads(schema.metadata[b"huggingface"])["info"]["features"]
    assert hf["observation.images.azure_kinect"]["_type"] == "Image"
    assert hf["action"] == {"feature": {"dtype": "float32", "id": None, "_type": "Value"}, "length": 8, "id": None, "_type": "Sequence"}
    assert hf["index"] == {"dtype": "int64", "id": None, "_type": "Value"}
    assert list(schema.names) == list(info["features"])  # LeRobot's column order: features, then its index columns


def test_other_versions_and_damaged_exports_are_refused(exported, tmp_path):
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(exported, copy)
    info = json.loads((copy / "meta" / "info.json").read_text())
    (copy / "meta" / "info.json").write_text(json.dumps({**info, "codebase_version": "v3.0"}))
    with pytest.raises(LeRobotFormatError, match="format v3.0"):
        read_lerobot(copy)
    (copy / "meta" / "info.json").write_text(json.dumps({**info, "total_frames": 15}))
    with pytest.raises(LeRobotFormatError, match="info.json says"):
        read_lerobot(copy)
    (copy / "meta" / "info.json").write_text(json.dumps(info))
    episodes = (copy / "meta" / "episodes.jsonl").read_text().replace('"length": 4', '"length": 5', 1)
    (copy / "meta" / "episodes.jsonl").write_text(episodes)
    with pytest.raises(LeRobotFormatError, match="disagree with episodes.jsonl"):
        read_lerobot(copy)
    assert cli.main(["export-lerobot", str(tmp_path / "no_dataset"), "--out", str(tmp_path / "x")]) == 2
