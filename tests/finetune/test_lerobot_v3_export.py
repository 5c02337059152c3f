"""`actaim2 export-lerobot --format v3`: the converted demonstrations (or the bags themselves, with
--from-bags) as a LeRobot v3.0 dataset, read back: the same frames as the v2.1 export, laid out as
LeRobot v3.0 defines it (meta/info.json, meta/tasks.parquet, meta/stats.json,
meta/episodes/chunk-*/file-*.parquet, data/chunk-*/file-*.parquet); damaged files are refused.

The ``lerobot`` package cannot be installed beside this project's torch (``lerobot_v21`` says why),
so the files are checked against the format's published layout rather than loaded by it."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from actaim2 import cli
from actaim2.data.storage import DatasetReader
from actaim2.export.lerobot_v3 import EPISODE_COLUMNS, STATS, export_lerobot_v3, read_lerobot_v3
from actaim2.export.lerobot_v21 import LeRobotFormatError, read_lerobot

# meta/info.json of LeRobot v3.0 (lerobot/datasets/utils.py, create_empty_dataset_info)
V3_INFO_KEYS = {"codebase_version", "robot_type", "total_episodes", "total_frames", "total_tasks",
                "chunks_size", "data_files_size_in_mb", "video_files_size_in_mb", "fps", "splits",
                "data_path", "video_path", "features"}


@pytest.fixture(scope="module")
def exports(converted, tmp_path_factory):
    root = tmp_path_factory.mktemp("lerobot_v3")
    for fmt in ("v2.1", "v3"):
        assert cli.main(["export-lerobot", str(converted.dataset), "--out", str(root / fmt),
                         "--format", fmt]) == 0
    return root


def test_v3_round_trip_gives_the_frames_of_the_v21_export(converted, exports):
    info, episodes = read_lerobot_v3(exports / "v3")
    info21, episodes21 = read_lerobot(exports / "v2.1")
    reader = DatasetReader(converted.dataset)
    assert info["codebase_version"] == "v3.0"
    assert info["total_episodes"] == len(reader.entries) == 4
    assert info["total_frames"] == 16 and info["features"] == info21["features"]
    for v3, v21, entry in zip(episodes, episodes21, reader.entries):
        assert v3.task == v21.task == entry["mode_label"] and v3.meta["actaim2_id"] == entry["id"]
        assert set(v3.columns) == set(v21.columns)
        for name, values in v21.columns.items():
            np.testing.assert_array_equal(v3.columns[name], values, err_msg=name)
        for row, keypose in zip(v3.columns["action"], reader.read(entry).keyposes):
            np.testing.assert_allclose(row[:3], keypose.position, atol=1e-6)


def test_the_files_are_laid_out_as_lerobot_v3(exports):
    root = exports / "v3"
    info = json.loads((root / "meta" / "info.json").read_text())
    assert set(info) == V3_INFO_KEYS and info["video_path"] is None
    assert info["data_path"] == "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
    assert info["splits"] == {"train": "0:4"} and info["chunks_size"] == 1000
    assert sorted(p.relative_to(root).as_posix() for p in root.rglob("*.parquet")) == [
        "data/chunk-000/file-000.parquet", "meta/episodes/chunk-000/file-000.parquet",
        "meta/tasks.parquet"]
    data = pq.read_table(root / "data" / "chunk-000" / "file-000.parquet")
    assert len(data) == 16 and data.column("index").to_pylist() == list(range(16))
    hf = json.loads(data.schema.metadata[b"huggingface"])["info"]["features"]
    assert hf["observation.images.azure_kinect"]["_type"] == "Image"
    episodes = pq.read_table(root / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    assert set(EPISODE_COLUMNS) <= set(episodes.schema.names)
    assert episodes.schema.field("tasks").type == pa.list_(pa.string())
    rows = episodes.to_pylist()
    assert [(r["dataset_from_index"], r["dataset_to_index"]) for r in rows] == \
        [(0, 4), (4, 8), (8, 12), (12, 16)]
    for feature in info["features"]:
        for stat in STATS:
            assert f"stats/{feature}/{stat}" in episodes.schema.names
    tasks = pq.read_table(root / "meta" / "tasks.parquet")
    pandas_meta = json.loads(tasks.schema.metadata[b"pandas"])
    assert pandas_meta["index_columns"] == ["task"]  # pd.read_parquet: task texts are the index
    assert dict(zip(tasks.column("task").to_pylist(), tasks.column("task_index").to_pylist())) == \
        {"pull": 0, "push": 1}
    stats = json.loads((root / "meta" / "stats.json").read_text())
    assert set(stats) == set(info["features"]) and stats["action"]["count"] == [16]
    actions = np.concatenate([np.asarray(r["stats/action/mean"])[None] for r in rows])
    np.testing.assert_allclose(stats["action"]["mean"], actions.mean(axis=0), atol=1e-6)
    all_actions = np.asarray(data.column("action").to_pylist())
    np.testing.assert_allclose(stats["action"]["std"], all_actions.std(axis=0), atol=1e-5)


def test_episodes_share_files_and_a_full_file_starts_the_next(converted, tmp_path):
    out = tmp_path / "small_files"
    info = export_lerobot_v3(converted.dataset, out, file_size_mb=1e-6)  # one episode per file
    assert info["data_files_size_in_mb"] == 1e-6
    files = sorted(p.name for p in (out / "data" / "chunk-000").iterdir())
    assert files == [f"file-{i:03d}.parquet" for i in range(4)]
    _, episodes = read_lerobot_v3(out)
    assert [e.meta["data/file_index"] for e in episodes] == [0, 1, 2, 3]
    assert [int(e.columns["index"][0]) for e in episodes] == [0, 4, 8, 12]


def test_from_bags_exports_the_bags_as_the_converted_dataset(converted, exports, tmp_path, capsys):
    out = tmp_path / "from_bags"
    assert cli.main(["export-lerobot", str(converted.recording.bag), "--from-bags", "--encoder",
                     str(converted.recording.encoder), "--out", str(out), "--format", "v3"]) == 0
    assert "bag2dataset: 1/1 bag (" in capsys.readouterr().err  # the conversion's progress line
    _, from_bags = read_lerobot_v3(out)
    _, from_dataset = read_lerobot_v3(exports / "v3")
    assert [e.task for e in from_bags] == [e.task for e in from_dataset]
    for a, b in zip(from_bags, from_dataset):
        np.testing.assert_allclose(a.columns["action"], b.columns["action"], atol=1e-6)
    assert (tmp_path / "from_bags.dataset" / "dataset.json").is_file()
    assert cli.main(["export-lerobot", str(tmp_path / "no_bag"), "--from-bags", "--encoder",
                     str(converted.recording.encoder), "--out", str(tmp_path / "x")]) == 2


def test_other_versions_and_damaged_v3_exports_are_refused(exports, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(exports / "v3", copy)
    info_path = copy / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    info_path.write_text(json.dumps({**info, "codebase_version": "v2.1"}))
    with pytest.raises(LeRobotFormatError, match="format v2.1"):
        read_lerobot_v3(copy)
    info_path.write_text(json.dumps({**info, "total_frames": 15}))
    with pytest.raises(LeRobotFormatError, match="info.json says"):
        read_lerobot_v3(copy)
    info_path.write_text(json.dumps(info))
    episodes_path = copy / "meta" / "episodes" / "chunk-000" / "file-000.parquet"
    table = pq.read_table(episodes_path)
    shifted = pa.array([r + 1 for r in table.column("dataset_from_index").to_pylist()], pa.int64())
    column = table.schema.get_field_index("dataset_from_index")
    pq.write_table(table.set_column(column, "dataset_from_index", shifted), episodes_path)
    with pytest.raises(LeRobotFormatError, match="disagree with meta/episodes"):
        read_lerobot_v3(copy)
    with pytest.raises(LeRobotFormatError, match="format v3.0"):
        read_lerobot(exports / "v3")
