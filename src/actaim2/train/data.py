"""Training data of the policy: per trajectory, normalised views of O_init and of O_0..O_3, keyposes, z.

Rendering views from stored camera pictures (fuse, remove the robot, z-buffer: ~30 ms a set
on this machine) is done once per (dataset, perception configuration) and cached as float16
``.npy`` files under ``<dataset>/cache/``, memory-mapped at training time, so epochs cost only
the networks. Only visually-labelled successes enter (the paper trains on the trajectories
the self-supervised label calls successful; the privileged ground truth is never used).

Views are stored as rendered (the renderer's units are the networks' input units: cube-frame
xyz, depth as a fraction of the cube side); scene augmentation re-renders them per batch.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from actaim2.data.storage import dataset_digest
from actaim2.data.trajectory import PHASES
from actaim2.progress import progress

CACHE_DIR = "cache"
@dataclass
class TrainingData:
    """N trajectories; arrays may be memory-mapped (views) - index them, do not copy them whole."""

    init_views: np.ndarray  # (N, V, C, R, R) float16 as rendered, O_init (robot hidden)
    key_views: np.ndarray  # (N, 4, V, C, R, R) float16, O_i taken before keypose a_i
    keyposes: np.ndarray  # (N, 4, 8) float32 [position (world m), quaternion (x, y, z, w), gripper closed]
    gripper: np.ndarray  # (N, 4) bool, gripper state when O_i was taken
    valid: np.ndarray  # (N, 4) bool, keypose position inside the cube (the others have no heatmap target)
    z: np.ndarray  # (N, D) float32 task embeddings
    ids: list[str]
    # (N,) str: each trajectory's outcome, "DoF index, direction" (data.storage.trajectory_outcome);
    # None where a trajectory has no DoF measurement (demonstrations from bags) or the data no index
    # (synthetic data); the mode contrast and validate's outcome figures need them
    outcomes: np.ndarray | None = None
    # (N,) int: each trajectory's known cluster, -1 where unknown; a demonstration's mode label mapped to the cluster
    # fine-tuning assigns it (finetune/clusters.py); None: no cluster known (the ELBO infers every one)
    clusters: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.ids)

    def subset(self, rows: np.ndarray) -> "TrainingData":
        """The given trajectories; views stay where they are (a lazy row selection, no copy)."""
        rows = np.asarray(rows)
        return TrainingData(_Rows(self.init_views, rows), _Rows(self.key_views, rows), self.keyposes[rows],
                            self.gripper[rows], self.valid[rows], self.z[rows], [self.ids[i] for i in rows],
                            None if self.outcomes is None else self.outcomes[rows],
                            None if self.clusters is None else self.clusters[rows])

    def known_clusters(self, rows: np.ndarray, device: torch.device | str = "cpu") -> torch.Tensor | None:
        """(B,) the known clusters of trajectory ``rows`` (-1: unknown), None when the data know none."""
        return None if self.clusters is None else torch.from_numpy(self.clusters[rows].astype(np.int64)).to(device)

    def keyframes(self) -> np.ndarray:
        """(M, 2) [trajectory, phase] of every keyframe with a valid target."""
        return np.argwhere(self.valid)

    def selector_batch(self, rows: np.ndarray, device: torch.device | str = "cpu") -> tuple[torch.Tensor, torch.Tensor]:
        """(O_init views (B, V, C, R, R) float32, z (B, D))."""
        return (torch.from_numpy(np.asarray(self.init_views[rows], dtype=np.float32)).to(device),
                torch.from_numpy(self.z[rows]).to(device))

    def keyframe_batch(self, frames: np.ndarray, device: torch.device | str = "cpu") -> dict[str, torch.Tensor]:
        """Views of O_i, keypose a_i, gripper state, phase, z and O_init of keyframes given as (B, 2) [trajectory, phase]."""
        t, p = frames[:, 0], frames[:, 1]
        views = np.stack([np.asarray(self.key_views[i][j], dtype=np.float32) for i, j in zip(t, p)])
        as_t = lambda a: torch.from_numpy(np.ascontiguousarray(a)).to(device)  # noqa: E731
        return {
            "views": as_t(views),
            "keypose": as_t(self.keyposes[t, p].astype(np.float32)),
            "gripper": as_t(self.gripper[t, p]),
            "phase": as_t(p.astype(np.int64)),
            "z": as_t(self.z[t]),
            "init_views": as_t(np.stack([np.asarray(self.init_views[i], dtype=np.float32) for i in t])),
        }


class _Rows:
    """A lazy row selection of a memory-mapped array (indexing copies only what is asked for)."""

    def __init__(self, array: np.ndarray, rows: np.ndarray):
        self.array, self.rows = array, np.asarray(rows)
        self.shape = (len(rows),) + array.shape[1:]

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, index):
        return self.array[self.rows[index]]


def holdout_split(ids: list[str], fraction: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(train rows, validation rows): a fixed fraction of trajectories held out, chosen by a hash of the id.

    Hashing the id (not the position) keeps a trajectory on its side when the collection grows.
    """
    score = np.array([int(hashlib.sha256(f"{seed}:{i}".encode()).hexdigest()[:8], 16) / 0xFFFFFFFF for i in ids])
    val = score < fraction
    return np.flatnonzero(~val), np.flatnonzero(val)


def cache_folder(root: str | Path, splits: list[str], perception_digest: str) -> Path:
    """Where the views of (this dataset's content, these splits, this perception configuration) are cached."""
    return Path(root) / CACHE_DIR / f"views-{dataset_digest(root)}-{perception_digest}-{'+'.join(sorted(splits))}"


def build_cache(root: str | Path, perception, splits: list[str], perception_digest: str,
                show_progress: bool = True, allow_held_out: bool = False) -> Path:
    """Render and store the views of the visually successful trajectories of ``splits``; returns the cache folder.

    ``perception``: an :class:`actaim2.perception.pipeline.Perception` (with the robot
    self-filter: views are robot-hidden).
    An existing complete cache of the same dataset digest and perception digest is reused.
    """
    from actaim2.data.torch_dataset import KeyframeDataset, ModeDataset

    root = Path(root)
    folder = cache_folder(root, splits, perception_digest)
    if (folder / "done.json").exists():
        return folder
    folder.mkdir(parents=True, exist_ok=True)
    modes = ModeDataset(root, splits=splits, success="visual", perception=perception, allow_held_out=allow_held_out)
    keys = KeyframeDataset(root, splits=splits, success="visual", perception=perception, allow_held_out=allow_held_out)
    missing = [e["id"] for e in modes.entries if e["id"] not in modes.embeddings]
    if missing:
        raise ValueError(f"{root} has no task embedding for {len(missing)} trajectories (e.g. {missing[:3]}): run the labelling step")
    n, phases = len(modes), len(PHASES)
    if n == 0:
        raise ValueError(f"{root} has no visually successful trajectory in splits {splits}")
    first = modes[0]["views"]
    init = np.lib.format.open_memmap(folder / "init_views.npy", "w+", np.float16, (n,) + tuple(first.shape))
    key = np.lib.format.open_memmap(folder / "key_views.npy", "w+", np.float16, (n, phases) + tuple(first.shape))
    keyposes = np.zeros((n, phases, 8), np.float32)
    gripper = np.zeros((n, phases), bool)
    z = np.zeros((n, len(modes.embeddings[modes.entries[0]["id"]])), np.float32)
    for i in progress(range(n), desc="rendering views", unit="sample", disable=not show_progress):
        item = modes[i]
        init[i] = item["views"].numpy()
        z[i] = item["z"].numpy()
        for j in range(phases):
            kf = keys[i * phases + j]
            key[i, j] = kf["views"].numpy()
            keyposes[i, j] = kf["keypose"].numpy()
            gripper[i, j] = kf["gripper_closed"]
    init.flush()
    key.flush()
    np.save(folder / "keyposes.npy", keyposes)
    np.save(folder / "gripper.npy", gripper)
    np.save(folder / "z.npy", z)
    (folder / "done.json").write_text(json.dumps({"ids": [e["id"] for e in modes.entries], "splits": splits}))
    return folder


def ensure_cache(root: str | Path, perception_config, splits: list[str], show_progress: bool = True,
                 allow_held_out: bool = False) -> Path:
    """Render (or reuse) the cached views of ``splits`` under a perception configuration; the cache folder.

    The robot self-filter, when the configuration asks for robot-hidden views, is the dataset's
    own robot's (``dataset.json``), so views match what collection and serving see.
    """
    from actaim2.artifact.checkpoint import perception_record
    from actaim2.data.storage import DatasetReader
    from actaim2.perception.pipeline import Perception
    from actaim2.perception.self_filter import RobotSelfFilter
    from actaim2.robots import load_robot_spec

    robot = DatasetReader(root).info.get("robot", "panda")
    self_filter = RobotSelfFilter(load_robot_spec(robot), perception_config.self_filter_margin) \
        if perception_config.remove_robot_views else None
    return build_cache(root, Perception(perception_config, self_filter), splits,
                       perception_record(perception_config)["digest"], show_progress, allow_held_out)


def open_cache(root: str | Path, perception_config, splits: list[str]) -> TrainingData:
    """The cached views of ``splits`` (built by :func:`ensure_cache`), memory-mapped, with each trajectory's
    outcome when every one has a DoF measurement."""
    from actaim2.artifact.checkpoint import perception_record
    from actaim2.data.storage import DatasetReader, trajectory_outcome
    from actaim2.models.view_geometry import CubePlacement

    folder = cache_folder(root, splits, perception_record(perception_config)["digest"])
    data = load_cache(folder, CubePlacement.of(perception_config))
    entries = DatasetReader(root).by_id
    changes = [entries[i].get("dof_change") for i in data.ids]
    if all(changes):  # demonstrations from bags measured no DoF: they have no outcome
        data.outcomes = np.array([trajectory_outcome(c) for c in changes])
    return data


def load_cache(folder: str | Path, placement) -> TrainingData:
    folder = Path(folder)
    meta = json.loads((folder / "done.json").read_text())
    keyposes = np.load(folder / "keyposes.npy")
    valid = placement.contains(torch.from_numpy(keyposes[..., :3])).numpy()
    return TrainingData(np.load(folder / "init_views.npy", mmap_mode="r"), np.load(folder / "key_views.npy", mmap_mode="r"),
                        keyposes, np.load(folder / "gripper.npy"), valid, np.load(folder / "z.npy"), meta["ids"])
