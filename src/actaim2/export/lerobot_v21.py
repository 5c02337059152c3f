"""A stored dataset as a LeRobot dataset, format version v2.1, and a reader of that format.

Why our own writer and reader: the ``lerobot`` package does not install beside this project's
pins. Its last release for Python 3.11 (0.4.4) requires torch < 2.11 (we pin 2.13.0) and reads
only its format v3.0; the releases that read v2.1 (up to 0.3.3) require torch < 2.8 and
datasets <= 3.6. So the files are written as LeRobot v2.1 lays them out (lerobot 0.3.3,
``lerobot/datasets/utils.py`` and ``lerobot_dataset.py``; the parquet schema as Hugging Face
``datasets`` 3.x writes it), and :func:`read_lerobot` reads them back for the round-trip test::

    meta/info.json               codebase_version "v2.1", fps, features (dtype, shape, names), totals,
                                 splits, data_path, chunks_size
    meta/tasks.jsonl             {"task_index", "task"}: the mode labels
    meta/episodes.jsonl          {"episode_index", "tasks", "length"} (+ actaim2_id, success: extra keys)
    meta/episodes_stats.jsonl    {"episode_index", "stats": {feature: {min, max, mean, std, count}}}
    meta/actaim2.json            where the episodes come from (not part of the LeRobot format)
    data/chunk-000/episode_000000.parquet ...   one row per frame; images embedded as PNG
                                 ({"bytes", "path"} structs), the ``huggingface`` schema metadata
                                 naming each column's feature type

One episode per trajectory, one frame per keyframe (four): ``observation.images.<camera>`` the
RGB picture of O_i, ``observation.state`` the joint positions when O_i was taken, ``action`` the
keypose a_i = (position xyz, quaternion xyzw, gripper closed 0/1), ``task`` the mode label
(empty when the trajectory has none, e.g. simulated collection). Keyframes are not evenly
spaced in time, and LeRobot requires timestamps 1/fps apart: ``fps`` is 1 and ``timestamp`` the
keyframe number. Depth pictures are not exported (LeRobot v2.1 has no depth feature type; the
actaim2 dataset keeps them).
"""
from __future__ import annotations

import io
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np
from PIL import Image

from actaim2.data.storage import DatasetReader, png_bytes
from actaim2.data.torch_dataset import keypose_tensor
from actaim2.data.trajectory import KEYFRAME_OBSERVATIONS
from actaim2.keypose import Keypose

CODEBASE_VERSION = "v2.1"
FPS = 1
CHUNK_SIZE = 1000  # episodes per data chunk (LeRobot's DEFAULT_CHUNK_SIZE)
DATA_PATH = "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet"
ACTION_NAMES = ["x", "y", "z", "qx", "qy", "qz", "qw", "gripper_closed"]
INDEX_FEATURES = {  # LeRobot's DEFAULT_FEATURES
    "timestamp": "float32", "frame_index": "int64", "episode_index": "int64", "index": "int64", "task_index": "int64",
}


class LeRobotFormatError(ValueError):
    """Files that are not a LeRobot v2.1 dataset as this module writes it."""


def arrow_modules():
    """pyarrow and pyarrow.parquet (imported on use: the CLI's parser stays cheap)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    return pa, pq


def features_of(cameras: list[str], image_shape: tuple[int, int], joint_names: list[str]) -> dict:
    """info.json's ``features``: cameras' images, state, action, then LeRobot's index columns."""
    h, w = image_shape
    features = {f"observation.images.{c}": {"dtype": "image", "shape": [h, w, 3], "names": ["height", "width", "channels"]}
                for c in cameras}
    features["observation.state"] = {"dtype": "float32", "shape": [len(joint_names)], "names": list(joint_names)}
    features["action"] = {"dtype": "float32", "shape": [len(ACTION_NAMES)], "names": list(ACTION_NAMES)}
    features.update({name: {"dtype": dtype, "shape": [1], "names": None} for name, dtype in INDEX_FEATURES.items()})
    return features


def _hf_feature(spec: dict) -> tuple[dict, object]:
    """(Hugging Face ``datasets`` 3.x feature dict, arrow type) of one LeRobot feature, as
    ``get_hf_features_from_features`` maps them: image -> Image, (1,) -> Value, (n,) -> Sequence."""
    pa, _ = arrow_modules()
    if spec["dtype"] == "image":
        return {"mode": None, "decode": True, "id": None, "_type": "Image"}, pa.struct({"bytes": pa.binary(), "path": pa.string()})
    arrow = {"float32": pa.float32(), "int64": pa.int64()}[spec["dtype"]]
    value = {"dtype": spec["dtype"], "id": None, "_type": "Value"}
    if list(spec["shape"]) == [1]:
        return value, arrow
    return {"feature": value, "length": int(spec["shape"][0]), "id": None, "_type": "Sequence"}, pa.list_(arrow, int(spec["shape"][0]))


def arrow_schema(features: dict):
    """The parquet schema of a data file, with the ``huggingface`` metadata ``datasets`` reads features from."""
    pa, _ = arrow_modules()
    hf, fields = {}, []
    for name, spec in features.items():
        hf[name], arrow = _hf_feature(spec)
        fields.append(pa.field(name, arrow))
    return pa.schema(fields).with_metadata({"huggingface": json.dumps({"info": {"features": hf}})})


def _stats(values: np.ndarray) -> dict:
    """min, max, mean, std over frames (axis 0) and the frame count, as lists (LeRobot's episode stats)."""
    values = np.asarray(values, dtype=np.float64)
    return {"min": values.min(axis=0).tolist(), "max": values.max(axis=0).tolist(), "mean": values.mean(axis=0).tolist(),
            "std": values.std(axis=0).tolist(), "count": [int(len(values))]}


def _image_stats(images: np.ndarray) -> dict:
    """Per-channel statistics of (N, H, W, 3) uint8 pictures in [0, 1], shaped (3, 1, 1) as LeRobot keeps them."""
    x = images.astype(np.float64).reshape(-1, 3) / 255.0
    shape = lambda a: a.reshape(3, 1, 1).tolist()  # noqa: E731
    return {"min": shape(x.min(axis=0)), "max": shape(x.max(axis=0)), "mean": shape(x.mean(axis=0)),
            "std": shape(x.std(axis=0)), "count": [int(len(images))]}


def _jsonl(path: Path, rows: list[dict]) -> None:
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))


@dataclass
class EpisodeColumns:
    """One trajectory as LeRobot frames: the data columns, their statistics, the task."""

    columns: dict[str, list]
    stats: dict[str, dict]
    task: str
    length: int
    joint_names: list[str]
    cameras: list[str]
    features: dict


def episode_columns(reader: DatasetReader, entry: dict, episode_index: int, first_index: int,
                    tasks: dict[str, int]) -> EpisodeColumns:
    """The frames of trajectory ``entry`` (one per keyframe) as episode ``episode_index`` whose
    first frame has the global index ``first_index``; ``tasks`` (label -> task index) gains its
    label."""
    meta, obs = reader.observations(entry, list(KEYFRAME_OBSERVATIONS))
    cameras = meta["cameras"]
    names = list(meta["robot_joints"][KEYFRAME_OBSERVATIONS[0]])
    features = features_of(cameras, obs[KEYFRAME_OBSERVATIONS[0]][cameras[0]].rgb.shape[:2], names)
    label = entry.get("mode_label") or ""
    task_index = tasks.setdefault(label, len(tasks))
    n = len(KEYFRAME_OBSERVATIONS)
    actions = np.stack([keypose_tensor(Keypose.from_json(k)).numpy() for k in meta["keyposes"]])
    states = np.array([[meta["robot_joints"][o][j] for j in names] for o in KEYFRAME_OBSERVATIONS],
                      np.float32)
    columns, stats = {}, {}
    for c in cameras:
        images = np.stack([obs[o][c].rgb for o in KEYFRAME_OBSERVATIONS])
        columns[f"observation.images.{c}"] = [{"bytes": png_bytes(im), "path": None}
                                               for im in images]
        stats[f"observation.images.{c}"] = _image_stats(images)
    index_values = {"timestamp": np.arange(n, dtype=np.float32) / FPS, "frame_index": np.arange(n),
                    "episode_index": np.full(n, episode_index),
                    "index": first_index + np.arange(n),
                    "task_index": np.full(n, task_index)}
    columns.update({"observation.state": states.tolist(), "action": actions.tolist(),
                    **{k: v.tolist() for k, v in index_values.items()}})
    stats.update({"observation.state": _stats(states), "action": _stats(actions),
                  **{k: _stats(v[:, None]) for k, v in index_values.items()}})
    return EpisodeColumns(columns, stats, label, n, names, cameras, features)


def check_same_robot(entry: dict, episode: EpisodeColumns, joint_names: list[str],
                     features: dict) -> None:
    """A LeRobotFormatError unless ``episode`` has the first episode's joints and cameras."""
    if episode.joint_names != joint_names or set(episode.features) != set(features):
        raise LeRobotFormatError(f"trajectory {entry['id']} has joints {episode.joint_names} / "
                                 f"cameras {episode.cameras}, unlike the first one: one LeRobot "
                                 f"dataset holds one robot and one camera set")


def export_entries(dataset: str | Path, out: Path,
                   successful_only: bool) -> tuple[DatasetReader, list[dict]]:
    """The reader of ``dataset`` and the trajectories to export into the new folder ``out``."""
    reader = DatasetReader(dataset)
    if (out / "meta" / "info.json").exists():
        raise FileExistsError(f"{out} already holds a LeRobot dataset: export into a new folder")
    entries = [e for e in reader.entries if not successful_only or e.get("label")]
    if not entries:
        raise LeRobotFormatError(f"{dataset} has no trajectory to export"
                                 + (" labelled successful" if successful_only else ""))
    return reader, entries


def episode_tables(reader: DatasetReader, entries: list[dict],
                   tasks: dict[str, int]) -> Iterator[tuple[dict, EpisodeColumns, object]]:
    """(entry, its frames, its arrow table) for each trajectory, as consecutive episodes of one
    robot and camera set (a LeRobotFormatError otherwise); ``tasks`` gains their labels."""
    pa, _ = arrow_modules()
    schema = joint_names = features = None
    frames = 0
    for episode_index, entry in enumerate(entries):
        episode = episode_columns(reader, entry, episode_index, frames, tasks)
        if features is None:
            joint_names, features = episode.joint_names, episode.features
            schema = arrow_schema(features)
        check_same_robot(entry, episode, joint_names, features)
        frames += episode.length
        yield entry, episode, pa.Table.from_pydict(episode.columns, schema=schema)


def export_lerobot(dataset: str | Path, out: str | Path, successful_only: bool = False) -> dict:
    """Write the trajectories of ``dataset`` as a LeRobot v2.1 dataset at ``out``; returns
    info.json."""
    _, pq = arrow_modules()
    out = Path(out)
    reader, entries = export_entries(dataset, out, successful_only)
    (out / "meta").mkdir(parents=True, exist_ok=True)
    tasks: dict[str, int] = {}
    episodes, episode_stats = [], []
    frames_total = 0
    episodes_read = episode_tables(reader, entries, tasks)
    for episode_index, (entry, episode, table) in enumerate(episodes_read):
        features, stats, label, n = episode.features, episode.stats, episode.task, episode.length
        path = out / DATA_PATH.format(episode_chunk=episode_index // CHUNK_SIZE, episode_index=episode_index)
        path.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(table, path)
        episodes.append({"episode_index": episode_index, "tasks": [label], "length": n,
                         "actaim2_id": entry["id"], "success": entry.get("label")})
        episode_stats.append({"episode_index": episode_index, "stats": stats})
        frames_total += n
    info = {
        "codebase_version": CODEBASE_VERSION, "robot_type": reader.info.get("robot"), "total_episodes": len(episodes),
        "total_frames": frames_total, "total_tasks": len(tasks), "total_videos": 0,
        "total_chunks": (len(episodes) - 1) // CHUNK_SIZE + 1, "chunks_size": CHUNK_SIZE, "fps": FPS,
        "splits": {"train": f"0:{len(episodes)}"}, "data_path": DATA_PATH, "video_path": None, "features": features,
    }
    (out / "meta" / "info.json").write_text(json.dumps(info, indent=4))
    _jsonl(out / "meta" / "tasks.jsonl", [{"task_index": i, "task": t} for t, i in tasks.items()])
    _jsonl(out / "meta" / "episodes.jsonl", episodes)
    _jsonl(out / "meta" / "episodes_stats.jsonl", episode_stats)
    (out / "meta" / "actaim2.json").write_text(json.dumps(
        {"source": str(dataset), "rig": reader.info.get("rig"), "successful_only": successful_only,
         "frames": "one per keyframe O_0..O_3; action = keypose (x y z, qx qy qz qw, gripper closed); task = mode label"}, indent=2))
    return info


@dataclass
class LeRobotEpisode:
    index: int
    task: str
    meta: dict  # its episodes.jsonl row
    columns: dict[str, np.ndarray]  # feature -> (frames, ...) array; images decoded to (frames, H, W, 3) uint8


def _read_jsonl(path: Path) -> list[dict]:
    if not path.exists():
        raise LeRobotFormatError(f"{path} is missing")
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def decode_columns(table, features: dict) -> dict[str, np.ndarray]:
    """Feature -> (frames, ...) array of a data table; images decoded to (frames, H, W, 3)."""
    columns = {}
    for name, spec in features.items():
        values = table.column(name).to_pylist()
        if spec["dtype"] == "image":
            columns[name] = np.stack([np.asarray(Image.open(io.BytesIO(v["bytes"])).convert("RGB"))
                                      for v in values])
        else:
            columns[name] = np.asarray(values, dtype=spec["dtype"])
    return columns


def read_info(root: Path, version: str) -> dict:
    """meta/info.json of a LeRobot dataset of format ``version`` (else a LeRobotFormatError)."""
    try:
        info = json.loads((root / "meta" / "info.json").read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise LeRobotFormatError(f"{root}/meta/info.json cannot be read: {exc}") from exc
    if info.get("codebase_version") != version:
        raise LeRobotFormatError(f"{root} is LeRobot format {info.get('codebase_version')}, "
                                 f"this reader reads {version}")
    return info


def check_totals(root: Path, info: dict, episodes: list[LeRobotEpisode], frames: int) -> None:
    """A LeRobotFormatError unless info.json counts the episodes and frames that were read."""
    if frames != info["total_frames"] or len(episodes) != info["total_episodes"]:
        raise LeRobotFormatError(f"{root}: {len(episodes)} episodes / {frames} frames, info.json "
                                 f"says {info['total_episodes']} / {info['total_frames']}")


def read_lerobot(root: str | Path) -> tuple[dict, list[LeRobotEpisode]]:
    """(info, episodes) of a LeRobot v2.1 dataset, every data file checked against info.json."""
    _, pq = arrow_modules()
    root = Path(root)
    info = read_info(root, CODEBASE_VERSION)
    tasks = {t["task_index"]: t["task"] for t in _read_jsonl(root / "meta" / "tasks.jsonl")}
    rows = sorted(_read_jsonl(root / "meta" / "episodes.jsonl"), key=lambda e: e["episode_index"])
    features = info["features"]
    expected = arrow_schema(features)
    episodes, next_index = [], 0
    for row in rows:
        i = row["episode_index"]
        path = root / info["data_path"].format(episode_chunk=i // info["chunks_size"], episode_index=i)
        table = pq.read_table(path)
        if not table.schema.equals(expected) or table.schema.metadata != expected.metadata:
            raise LeRobotFormatError(f"{path}: schema {table.schema} is not the one info.json's features give")
        columns = decode_columns(table, features)
        if len(table) != row["length"] or not np.array_equal(columns["episode_index"], np.full(len(table), i)) \
                or not np.array_equal(columns["index"], next_index + np.arange(len(table))):
            raise LeRobotFormatError(f"{path}: {len(table)} frames, episode or global index columns disagree with episodes.jsonl")
        next_index += len(table)
        task_indices = set(columns["task_index"].tolist())
        if len(task_indices) != 1 or tasks.get(task_indices.pop()) not in row["tasks"]:
            raise LeRobotFormatError(f"{path}: task_index column does not name the episode's task {row['tasks']}")
        episodes.append(LeRobotEpisode(i, row["tasks"][0], row, columns))
    check_totals(root, info, episodes, next_index)
    return info, episodes
