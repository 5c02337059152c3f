"""PyTorch Datasets over a stored collection, shaped for the two models of the paper.

* :class:`KeyframeDataset` - atomic training instances (O_i, a_i, z) of the action predictor:
  one item per keyframe of every selected trajectory (paper appendix, end of "Dataset Generation").
* :class:`ModeDataset` - (O_init, z) pairs of the mode selector.

Items carry the cameras' pictures as tensors; given a :class:`actaim2.perception.pipeline.Perception`,
they also carry the orthographic views recomputed from them (robot removed with the stored joint
positions when the perception has a self-filter), exactly as the running perception node makes them.
The perception's configuration must match the one the dataset was collected under in its capture
fields (rig, cube, robot filter, render path: ``dataset.json``); otherwise the dataset is refused
with the differing fields named. Its view fields (resolution, channels, splatting) are free.

Selection is by split, sampler and success label ("visual": the self-supervised label, the one
training uses; "gt": the privileged ground truth, for analysis only). Datasets hold the training
split ``train_seen`` unless told otherwise: the other splits are held out for evaluation, and
loading one needs ``allow_held_out=True`` so that it cannot slip into training by accident.
"""
from __future__ import annotations

import logging
from pathlib import Path
from typing import Sequence

import numpy as np
import torch
from torch.utils.data import Dataset

from actaim2.data.labelling import EMBEDDINGS_FILE
from actaim2.data.object_cloud import back_project
from actaim2.data.splits import TRAIN, TRAINING_SPLITS
from actaim2.data.storage import DatasetReader
from actaim2.data.trajectory import PHASES, Observation
from actaim2.keypose import Keypose
from actaim2.perception.config import CAPTURE_FIELDS, check_compatible
from actaim2.perception.fusion import CameraCloud

DEFAULT_SPLITS = (TRAIN,)
log = logging.getLogger(__name__)


def keypose_tensor(k: Keypose) -> torch.Tensor:
    """(8,) position, quaternion (x, y, z, w), gripper closed (0/1)."""
    return torch.tensor([*k.position, *k.quat_xyzw, float(k.gripper_closed)], dtype=torch.float32)


def observation_tensors(obs: Observation) -> dict[str, torch.Tensor]:
    """Cameras in name order: rgb (V, 3, H, W) uint8, depth (V, H, W) metres, K, T_world_optical."""
    cams = sorted(obs)
    return {
        "rgb": torch.from_numpy(np.stack([obs[c].rgb for c in cams])).permute(0, 3, 1, 2).contiguous(),
        "depth": torch.from_numpy(np.stack([obs[c].depth for c in cams])),
        "K": torch.from_numpy(np.stack([obs[c].K for c in cams])).float(),
        "T_world_optical": torch.from_numpy(np.stack([obs[c].T_world_optical for c in cams])).float(),
    }


class _StoredDataset(Dataset):
    """``splits`` defaults to the training split alone; a split outside :data:`TRAINING_SPLITS` needs
    ``allow_held_out=True``."""

    def __init__(self, root: str | Path, splits: Sequence[str] = DEFAULT_SPLITS, samplers: list[str] | None = None,
                 success: str | None = "visual", perception=None, allow_held_out: bool = False):
        held_out = sorted(set(splits) - set(TRAINING_SPLITS))
        if held_out and not allow_held_out:
            raise ValueError(f"split(s) {held_out} are held out from training (the training splits are {list(TRAINING_SPLITS)}): "
                             f"pass allow_held_out=True to load them (evaluation, analysis)")
        self.reader = DatasetReader(root)
        if perception is not None:  # views recomputed: the pictures must be what this perception expects
            check_compatible(self.reader.perception_capture(), perception.config, CAPTURE_FIELDS, ("dataset", "training run"))
        self.splits = tuple(splits)
        log.info("%s of %s: splits %s%s", type(self).__name__, root, list(self.splits),
                 " (the default: the training split only)" if self.splits == DEFAULT_SPLITS else "")
        entries = [e for e in self.reader.entries if e["split"] in self.splits]
        if samplers is not None:
            entries = [e for e in entries if e["sampler"] in samplers]
        if success == "visual":
            if any("label" not in e for e in entries):
                raise ValueError(f"{root} has trajectories without visual labels: run the labelling step (actaim2 collect) first")
            entries = [e for e in entries if e["label"]]
        elif success == "gt":
            entries = [e for e in entries if e["gt_success"]]
        elif success is not None:
            raise ValueError(f"success must be 'visual', 'gt' or None, got {success!r}")
        self.entries = entries
        self.perception = perception
        self.embeddings: dict[str, np.ndarray] = {}
        path = self.reader.root / EMBEDDINGS_FILE
        if path.exists():
            with np.load(path) as f:
                self.embeddings = dict(zip(f["ids"].tolist(), f["z"]))

    def __repr__(self) -> str:
        default = ", the default" if self.splits == DEFAULT_SPLITS else ""
        return f"{type(self).__name__}({self.reader.root}, splits={list(self.splits)}{default}, {len(self.entries)} trajectories)"

    def _observation_item(self, obs: Observation, joints: dict[str, float]) -> dict[str, torch.Tensor]:
        item = observation_tensors(obs)
        if self.perception is not None:
            clouds = [CameraCloud(back_project(obs[c]), obs[c].rgb.reshape(-1, 3), obs[c].T_world_optical) for c in sorted(obs)]
            if self.perception.self_filter is not None:
                self.perception.self_filter.set_joint_positions(list(joints), list(joints.values()))
            item["views"] = torch.from_numpy(self.perception.process(clouds).views)
        return item

    def _z(self, tid: str) -> dict[str, torch.Tensor]:
        return {"z": torch.from_numpy(self.embeddings[tid])} if tid in self.embeddings else {}


class KeyframeDataset(_StoredDataset):
    """(O_i, a_i, z): item k is keyframe k % 4 of trajectory k // 4."""

    def __len__(self) -> int:
        return len(self.entries) * len(PHASES)

    def __getitem__(self, k: int) -> dict:
        entry, phase = self.entries[k // len(PHASES)], k % len(PHASES)
        obs_name = f"o{phase}"
        meta, obs = self.reader.observations(entry, [obs_name])
        keyposes = [Keypose.from_json(d) for d in meta["keyposes"]]
        item = self._observation_item(obs[obs_name], meta["robot_joints"][obs_name])
        item.update(
            id=entry["id"],
            phase=phase,
            keypose=keypose_tensor(keyposes[phase]),
            gripper_closed=bool(phase > 0 and keyposes[phase - 1].gripper_closed),  # state when O_i was taken
            **self._z(entry["id"]),
        )
        return item


class ModeDataset(_StoredDataset):
    """(O_init, z) per trajectory, the mode selector's conditional input and target."""

    def __len__(self) -> int:
        return len(self.entries)

    def __getitem__(self, k: int) -> dict:
        entry = self.entries[k]
        meta, obs = self.reader.observations(entry, ["init"])
        item = self._observation_item(obs["init"], meta["robot_joints"]["init"])
        item.update(id=entry["id"], **self._z(entry["id"]))
        return item
