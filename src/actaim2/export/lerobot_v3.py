"""A stored dataset as a LeRobot dataset, format version v3.0, and a reader of that format.

LeRobot v3.0 keeps many episodes per file (the v2.1 module says why this project writes the
files itself: the ``lerobot`` package does not install beside its torch). The layout, as
``lerobot/datasets/utils.py`` of LeRobot v3.0 defines it::

    meta/info.json       codebase_version "v3.0", fps, features, totals, chunks_size,
                         data_files_size_in_mb, video_files_size_in_mb, splits, data_path,
                         video_path (null: pictures are embedded in the data files)
    meta/tasks.parquet   one row per task: task_index, with the task text as the (pandas) index
    meta/stats.json      per feature min, max, mean, std, count over the whole dataset
    meta/episodes/chunk-000/file-000.parquet   one row per episode: episode_index, tasks, length,
                         data/chunk_index, data/file_index, dataset_from_index, dataset_to_index,
                         meta/episodes/chunk_index, meta/episodes/file_index,
                         stats/<feature>/<stat>
                         (+ actaim2_id, success: extra columns)
    data/chunk-000/file-000.parquet ...   the frames of consecutive episodes, a new file once one
                         holds ``data_files_size_in_mb``, a new chunk every ``chunks_size`` files

The frames, features and parquet schema of the data files are the v2.1 module's (one frame per
keyframe, images as PNG structs, the ``huggingface`` feature metadata).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from actaim2.export.lerobot_v21 import (
    FPS,
    LeRobotEpisode,
    LeRobotFormatError,
    arrow_modules,
    arrow_schema,
    check_totals,
    decode_columns,
    episode_tables,
    export_entries,
    read_info,
)

CODEBASE_VERSION = "v3.0"
CHUNK_SIZE = 1000  # files per chunk folder (LeRobot's DEFAULT_CHUNK_SIZE)
DATA_FILE_SIZE_IN_MB = 100  # a data file is closed past this size (LeRobot's default)
VIDEO_FILE_SIZE_IN_MB = 500  # LeRobot's default (no videos are written)
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
TASKS_PATH = "meta/tasks.parquet"
STATS = ("min", "max", "mean", "std", "count")
EPISODE_COLUMNS = ("episode_index", "tasks", "length", "data/chunk_index", "data/file_index",
                   "dataset_from_index", "dataset_to_index", "meta/episodes/chunk_index",
                   "meta/episodes/file_index")


def export_lerobot_v3(dataset: str | Path, out: str | Path, successful_only: bool = False,
                      file_size_mb: float = DATA_FILE_SIZE_IN_MB) -> dict:
    """Write the trajectories of ``dataset`` as a LeRobot v3.0 dataset at ``out`` (a data file
    closed past ``file_size_mb``); returns info.json."""
    pa, pq = arrow_modules()
    out = Path(out)
    reader, entries = export_entries(dataset, out, successful_only)
    tasks: dict[str, int] = {}
    rows: list[dict] = []
    all_stats: list[dict] = []
    features: dict = {}
    pending: list = []  # tables of the data file being filled
    pending_bytes, file_number, frames_total = 0, 0, 0

    def flush() -> None:
        nonlocal pending, pending_bytes, file_number
        if pending:
            path = out / DATA_PATH.format(chunk_index=file_number // CHUNK_SIZE,
                                          file_index=file_number % CHUNK_SIZE)
            path.parent.mkdir(parents=True, exist_ok=True)
            pq.write_table(pa.concat_tables(pending), path)
            pending, pending_bytes, file_number = [], 0, file_number + 1

    episodes = episode_tables(reader, entries, tasks)
    for episode_index, (entry, episode, table) in enumerate(episodes):
        features = episode.features
        if pending and pending_bytes + table.nbytes > file_size_mb * 2**20:
            flush()
        pending.append(table)
        pending_bytes += table.nbytes
        row = {"episode_index": episode_index, "tasks": [episode.task], "length": episode.length,
               "data/chunk_index": file_number // CHUNK_SIZE,
               "data/file_index": file_number % CHUNK_SIZE,
               "dataset_from_index": frames_total,
               "dataset_to_index": frames_total + episode.length,
               "meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0}
        for feature, values in episode.stats.items():
            for stat in STATS:
                row[f"stats/{feature}/{stat}"] = np.asarray(values[stat]).ravel().tolist()
        row.update({"actaim2_id": entry["id"], "success": entry.get("label")})
        rows.append(row)
        all_stats.append(episode.stats)
        frames_total += episode.length
    flush()
    episodes_path = out / EPISODES_PATH.format(chunk_index=0, file_index=0)
    episodes_path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.Table.from_pylist(rows), episodes_path)
    pq.write_table(_tasks_table(tasks), out / TASKS_PATH)
    (out / "meta" / "stats.json").write_text(json.dumps(_aggregate(all_stats), indent=4))
    info = {
        "codebase_version": CODEBASE_VERSION, "robot_type": reader.info.get("robot"),
        "total_episodes": len(rows), "total_frames": frames_total, "total_tasks": len(tasks),
        "chunks_size": CHUNK_SIZE, "data_files_size_in_mb": file_size_mb,
        "video_files_size_in_mb": VIDEO_FILE_SIZE_IN_MB, "fps": FPS,
        "splits": {"train": f"0:{len(rows)}"}, "data_path": DATA_PATH, "video_path": None,
        "features": features,
    }
    (out / "meta" / "info.json").write_text(json.dumps(info, indent=4))
    (out / "meta" / "actaim2.json").write_text(json.dumps(
        {"source": str(dataset), "rig": reader.info.get("rig"), "successful_only": successful_only,
         "frames": "one per keyframe O_0..O_3; action = keypose (x y z, qx qy qz qw, gripper "
                   "closed); task = mode label"}, indent=2))
    return info


def _tasks_table(tasks: dict[str, int]):
    """meta/tasks.parquet as pandas writes a DataFrame with the task texts as its index: LeRobot
    reads it with ``pd.read_parquet`` and looks tasks up by that index."""
    pa, _ = arrow_modules()
    pandas_meta = {
        "index_columns": ["task"],
        "column_indexes": [{"name": None, "field_name": None, "pandas_type": "unicode",
                            "numpy_type": "object", "metadata": {"encoding": "UTF-8"}}],
        "columns": [{"name": "task_index", "field_name": "task_index", "pandas_type": "int64",
                     "numpy_type": "int64", "metadata": None},
                    {"name": "task", "field_name": "task", "pandas_type": "unicode",
                     "numpy_type": "object", "metadata": None}],
        "creator": {"library": "pyarrow", "version": pa.__version__},
        "pandas_version": "2.2.3",
    }
    ordered = sorted(tasks.items(), key=lambda item: item[1])
    table = pa.table({"task_index": pa.array([i for _, i in ordered], pa.int64()),
                      "task": pa.array([t for t, _ in ordered], pa.string())})
    return table.replace_schema_metadata({"pandas": json.dumps(pandas_meta)})


def _aggregate(episode_stats: list[dict]) -> dict:
    """Dataset statistics from per-episode ones, as LeRobot's ``aggregate_stats``: min of mins,
    max of maxes, count-weighted mean, and the std of the pooled frames."""
    out = {}
    for feature in episode_stats[0]:
        parts = [s[feature] for s in episode_stats]
        counts = np.array([p["count"][0] for p in parts], np.float64)
        means = np.array([p["mean"] for p in parts], np.float64)
        stds = np.array([p["std"] for p in parts], np.float64)
        weights = (counts / counts.sum()).reshape((-1,) + (1,) * (means.ndim - 1))
        mean = (weights * means).sum(axis=0)
        variance = (weights * (stds ** 2 + (means - mean) ** 2)).sum(axis=0)
        out[feature] = {"min": np.min([p["min"] for p in parts], axis=0).tolist(),
                        "max": np.max([p["max"] for p in parts], axis=0).tolist(),
                        "mean": mean.tolist(), "std": np.sqrt(variance).tolist(),
                        "count": [int(counts.sum())]}
    return out


def read_lerobot_v3(root: str | Path) -> tuple[dict, list[LeRobotEpisode]]:
    """(info, episodes) of a LeRobot v3.0 dataset, every file checked against the metadata."""
    _, pq = arrow_modules()
    root = Path(root)
    info = read_info(root, CODEBASE_VERSION)
    tasks_table = _read_parquet(root / TASKS_PATH, pq)
    if json.loads(tasks_table.schema.metadata[b"pandas"])["index_columns"] != ["task"]:
        raise LeRobotFormatError(f"{root / TASKS_PATH}: the task texts are not its index")
    tasks = dict(zip(tasks_table.column("task_index").to_pylist(),
                     tasks_table.column("task").to_pylist()))
    episode_files = sorted((root / "meta" / "episodes").glob("chunk-*/file-*.parquet"))
    if not episode_files:
        raise LeRobotFormatError(f"{root}/meta/episodes holds no chunk-*/file-*.parquet")
    rows = sorted((r for f in episode_files for r in _read_parquet(f, pq).to_pylist()),
                  key=lambda r: r["episode_index"])
    missing = [c for c in EPISODE_COLUMNS if c not in rows[0]]
    if missing:
        raise LeRobotFormatError(f"{root}/meta/episodes: columns {missing} are missing")
    features = info["features"]
    expected = arrow_schema(features)
    files: dict[tuple[int, int], object] = {}
    episodes, next_index = [], 0
    for row in rows:
        key = (row["data/chunk_index"], row["data/file_index"])
        if key not in files:
            path = root / info["data_path"].format(chunk_index=key[0], file_index=key[1])
            files[key] = _read_parquet(path, pq)
            if not files[key].schema.equals(expected) \
                    or files[key].schema.metadata != expected.metadata:
                raise LeRobotFormatError(f"{path}: schema is not the one info.json's "
                                         "features give")
        table = files[key]
        indices = table.column("index").to_numpy()
        start = int(np.searchsorted(indices, row["dataset_from_index"]))
        frames = table.slice(start, row["length"])
        columns = decode_columns(frames, features)
        i = row["episode_index"]
        if row["dataset_from_index"] != next_index \
                or row["dataset_to_index"] - row["dataset_from_index"] != row["length"] \
                or len(frames) != row["length"] \
                or not np.array_equal(columns["index"], next_index + np.arange(row["length"])) \
                or not np.array_equal(columns["episode_index"], np.full(row["length"], i)):
            raise LeRobotFormatError(f"episode {i}: its frames in data file {key} disagree with "
                                     f"meta/episodes (from {row['dataset_from_index']}, length "
                                     f"{row['length']})")
        next_index += row["length"]
        task_indices = set(columns["task_index"].tolist())
        if len(task_indices) != 1 or tasks.get(task_indices.pop()) not in row["tasks"]:
            raise LeRobotFormatError(f"episode {i}: task_index does not name its task "
                                     f"{row['tasks']}")
        episodes.append(LeRobotEpisode(i, row["tasks"][0], row, columns))
    check_totals(root, info, episodes, next_index)
    return info, episodes


def _read_parquet(path: Path, pq):
    try:
        return pq.read_table(path)
    except (OSError, ValueError) as exc:
        raise LeRobotFormatError(f"{path} cannot be read: {exc}") from exc
