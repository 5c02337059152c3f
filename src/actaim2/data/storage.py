"""The on-disk dataset: tar chunks of PNG + JSON members, an index, and visual labels.

Layout of a dataset folder::

    dataset.json          format version, rig, perception capture fields (actaim2.perception.config:
                          rig, cube, robot filter, render path), collection settings (written once)
    index.jsonl           one JSON object per stored trajectory (appended after its bytes are on disk)
    skipped.jsonl         trajectories collection gave up on (no feasible sample), with the reasons
    labels.jsonl          visual success labels {id, score, success} (rewritten by each labelling)
    chunks/chunk-00000.tar ...

A chunk is a plain POSIX tar file (WebDataset layout: members of one trajectory share the key
``<id>``), so ``tar tf`` or any tar reader lists it, no ROS needed. Members of trajectory ``<id>``:

    <id>.meta.json                     keyposes, cameras (K, T_world_optical), robot joints per observation,
                                       object, sampler, privileged DoFs
    <id>.<obs>.<camera>.rgb.png        uint8 RGB
    <id>.<obs>.<camera>.depth.png      uint16 z-depth in millimetres (0 = no return, max 65.535 m)

with ``<obs>`` in o0..o3 (before keypose a_i), init and final (robot hidden). Chunks carry no
end-of-archive blocks, so they are appended to in place; GNU tar and Python's tarfile read
them as they are. An index entry holds the chunk, the byte offset of the trajectory's first
member header and the byte size of its members, so a reader seeks straight to it.

Crash safety: a trajectory's members are written and fsync'ed before its index line; on
reopening, the writer drops a torn last index line and truncates each chunk to the end of its
last indexed trajectory, so an interrupted collection resumes with no partial records.
"""
from __future__ import annotations

import hashlib
import io
import json
import os
import tarfile
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
from PIL import Image

from actaim2.data.trajectory import (
    OBSERVATION_NAMES,
    CameraImage,
    Keypose,
    ObjectState,
    Observation,
    Trajectory,
)
from actaim2.profiling import timed

FORMAT_VERSION = 1
DEPTH_SCALE = 1000.0  # stored depth unit: millimetres
CHUNK_BYTES = 256 * 2**20  # start a new chunk past this size
MAX_TRAJECTORY_BYTES = 3 * 2**20  # the budget per trajectory
PNG_LEVEL = 3  # zlib level; measured on collected pictures: 1.3 ms and 0.51 MB per trajectory, level 6 2.0 ms and 0.43 MB

INDEX_FILE = "index.jsonl"
SKIPPED_FILE = "skipped.jsonl"  # not retried when collection resumes
LABELS_FILE = "labels.jsonl"


def encode_depth(depth_m: np.ndarray) -> np.ndarray:
    """Metres -> uint16 millimetres; NaN, negative and out-of-range values become 0 (no return)."""
    mm = np.nan_to_num(np.asarray(depth_m, dtype=np.float64) * DEPTH_SCALE, nan=0.0, posinf=0.0, neginf=0.0)
    mm = np.rint(mm)
    mm[(mm < 0) | (mm > np.iinfo(np.uint16).max)] = 0
    return mm.astype(np.uint16)


def decode_depth(mm: np.ndarray) -> np.ndarray:
    return np.asarray(mm, dtype=np.float32) / np.float32(DEPTH_SCALE)


def png_bytes(image: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG", compress_level=PNG_LEVEL)
    return buf.getvalue()


def png_array(data: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)))


def _slug(text: str) -> str:
    """Member keys may not contain dots or path separators (WebDataset keys end at the first dot)."""
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in text)


def trajectory_id(object_id: str, sampler: str, index: int) -> str:
    return f"{_slug(object_id)}-{_slug(sampler)}-{index:05d}"


def sampler_of(trajectory: str) -> str:
    """The sampler named in a :func:`trajectory_id` (object ids may hold dashes, samplers do not)."""
    return trajectory.rsplit("-", 2)[1]


def object_of(trajectory: str) -> str:
    """The object named in a :func:`trajectory_id` (everything before its sampler and index)."""
    return trajectory.rsplit("-", 2)[0]


def trajectory_outcome(dof_change: Sequence[float]) -> str:
    """"DoF index, direction" of the DoF that moved most (fractions of range), e.g. "1-"."""
    change = np.asarray(dof_change, dtype=float)
    k = int(np.argmax(np.abs(change)))
    return f"{k}{'+' if change[k] > 0 else '-'}"


@dataclass
class EncodedTrajectory:
    """A trajectory ready to be appended: its tar members and its index fields.

    Encoding (PNG compression) is the expensive part, so workers do it and the single writer
    process only copies bytes.
    """

    id: str
    members: list[tuple[str, bytes]]
    entry: dict

    @property
    def nbytes(self) -> int:
        return sum(len(data) for _, data in self.members)


@timed("encoding")
def encode_trajectory(traj: Trajectory) -> EncodedTrajectory:
    cameras = sorted(traj.observations[OBSERVATION_NAMES[0]])
    members: list[tuple[str, bytes]] = []
    camera_meta: dict[str, dict[str, dict]] = {}
    for obs_name in OBSERVATION_NAMES:
        obs = traj.observations[obs_name]
        if sorted(obs) != cameras:
            raise ValueError(f"observation {obs_name} has cameras {sorted(obs)}, expected {cameras}")
        camera_meta[obs_name] = {}
        for cam in cameras:
            if "." in cam or "/" in cam:
                raise ValueError(f"camera name {cam!r} may not contain '.' or '/'")
            img = obs[cam]
            members.append((f"{traj.id}.{obs_name}.{cam}.rgb.png", png_bytes(img.rgb)))
            members.append((f"{traj.id}.{obs_name}.{cam}.depth.png", png_bytes(encode_depth(img.depth))))
            camera_meta[obs_name][cam] = {"K": img.K.tolist(), "T_world_optical": img.T_world_optical.tolist()}
    entry = {
        "id": traj.id,
        "object_id": traj.object_id,
        "category": traj.category,
        "instance": int(traj.instance),
        "split": traj.split,
        "sampler": traj.sampler,
        "seed": int(traj.seed),
        # Privileged, for validating the visual label and for statistics only:
        "gt_success": traj.gt_success,
        "dof_change": [float(v) for v in traj.object_state.signed_change()],  # (final - initial) / range per DoF
    }
    meta = dict(entry)
    meta.update(
        format_version=FORMAT_VERSION,
        depth_scale=DEPTH_SCALE,
        cameras=cameras,
        keyposes=[k.to_json() for k in traj.keyposes],
        camera_params=camera_meta,
        robot_joints=traj.robot_joints,
        object_state=traj.object_state.to_json(),
        info=traj.info,
    )
    members.insert(0, (f"{traj.id}.meta.json", json.dumps(meta).encode()))
    encoded = EncodedTrajectory(traj.id, members, entry)
    if encoded.nbytes > MAX_TRAJECTORY_BYTES:
        raise ValueError(f"trajectory {traj.id} takes {encoded.nbytes} bytes, over the {MAX_TRAJECTORY_BYTES} budget")
    return encoded


def _tar_member(name: str, data: bytes) -> bytes:
    info = tarfile.TarInfo(name)
    info.size = len(data)
    info.mode = 0o644
    padding = (-len(data)) % tarfile.BLOCKSIZE
    return info.tobuf(tarfile.USTAR_FORMAT) + data + b"\0" * padding


def _camera_image(members: dict[str, bytes], meta: dict, obs_name: str, cam: str) -> CameraImage:
    stem = f"{meta['id']}.{obs_name}.{cam}"
    params = meta["camera_params"][obs_name][cam]
    return CameraImage(
        rgb=png_array(members[f"{stem}.rgb.png"]),
        depth=decode_depth(png_array(members[f"{stem}.depth.png"])),
        K=np.asarray(params["K"]),
        T_world_optical=np.asarray(params["T_world_optical"]),
    )


def decode_trajectory(members: dict[str, bytes]) -> Trajectory:
    meta = json.loads(next(data for name, data in members.items() if name.endswith(".meta.json")))
    return Trajectory(
        id=meta["id"],
        object_id=meta["object_id"],
        category=meta["category"],
        instance=meta["instance"],
        split=meta["split"],
        sampler=meta["sampler"],
        seed=meta["seed"],
        keyposes=[Keypose.from_json(k) for k in meta["keyposes"]],
        observations={o: {c: _camera_image(members, meta, o, c) for c in meta["cameras"]} for o in OBSERVATION_NAMES},
        robot_joints=meta["robot_joints"],
        object_state=ObjectState.from_json(meta["object_state"]),
        info=meta["info"],
    )


def _read_jsonl(path: Path) -> list[dict]:
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


class DatasetWriter:
    """Appends encoded trajectories to chunk files and the index; one writer per dataset.

    Opening an existing dataset resumes it: ``ids`` tells the caller what is already stored.
    """

    def __init__(self, root: str | Path, info: dict | None = None, chunk_bytes: int = CHUNK_BYTES):
        self.root = Path(root)
        self.chunk_bytes = chunk_bytes
        (self.root / "chunks").mkdir(parents=True, exist_ok=True)
        info_path = self.root / "dataset.json"
        if not info_path.exists():
            body = {"format_version": FORMAT_VERSION, "depth_scale": DEPTH_SCALE, **(info or {})}
            tmp = info_path.with_suffix(".tmp")
            tmp.write_text(json.dumps(body, indent=2))
            tmp.replace(info_path)
        self.index_path = self.root / INDEX_FILE
        self.entries = self._recover()
        self.ids = {e["id"] for e in self.entries}
        self._chunk_number = max((int(e["chunk"][len("chunks/chunk-"):-len(".tar")]) for e in self.entries), default=0)
        self._chunk = open(self._chunk_path(), "ab")
        self._index = open(self.index_path, "a")

    def _chunk_path(self) -> Path:
        return self.root / "chunks" / f"chunk-{self._chunk_number:05d}.tar"

    def _recover(self) -> list[dict]:
        """Drop a torn last index line and bytes past the last indexed trajectory of each chunk."""
        if self.index_path.exists():
            raw = self.index_path.read_bytes()
            complete = raw[: raw.rfind(b"\n") + 1]
            if complete != raw:
                self.index_path.write_bytes(complete)
        entries = _read_jsonl(self.index_path)
        ends: dict[str, int] = {}
        for e in entries:
            ends[e["chunk"]] = max(ends.get(e["chunk"], 0), e["offset"] + e["size"])
        for chunk in (self.root / "chunks").glob("chunk-*.tar"):
            rel = f"chunks/{chunk.name}"
            if chunk.stat().st_size != ends.get(rel, 0):
                with open(chunk, "r+b") as f:
                    f.truncate(ends.get(rel, 0))
        return entries

    def append(self, encoded: EncodedTrajectory) -> dict:
        if encoded.id in self.ids:
            raise ValueError(f"trajectory {encoded.id} is already stored")
        if self._chunk.tell() >= self.chunk_bytes:
            self._chunk.close()
            self._chunk_number += 1
            self._chunk = open(self._chunk_path(), "ab")
        offset = self._chunk.tell()
        blob = b"".join(_tar_member(name, data) for name, data in encoded.members)
        self._chunk.write(blob)
        self._chunk.flush()
        os.fsync(self._chunk.fileno())
        entry = dict(encoded.entry, chunk=f"chunks/{self._chunk_path().name}", offset=offset, size=len(blob))
        self._index.write(json.dumps(entry) + "\n")
        self._index.flush()
        os.fsync(self._index.fileno())
        self.entries.append(entry)
        self.ids.add(encoded.id)
        return entry

    def close(self) -> None:
        self._chunk.close()
        self._index.close()

    def __enter__(self) -> "DatasetWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def write_labels(root: str | Path, labels: list[dict]) -> None:
    """Replace labels.jsonl atomically ({id, score, success} per trajectory)."""
    path = Path(root) / LABELS_FILE
    tmp = path.with_suffix(".tmp")
    tmp.write_text("".join(json.dumps(label) + "\n" for label in labels))
    tmp.replace(path)


class DatasetReader:
    """Random access to a stored dataset; safe to use from DataLoader worker processes."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        info_path = self.root / "dataset.json"
        if not info_path.exists():
            raise FileNotFoundError(f"{self.root} is not an actaim2 dataset (no dataset.json)")
        self.info = json.loads(info_path.read_text())
        if self.info.get("format_version") != FORMAT_VERSION:
            raise ValueError(f"dataset format {self.info.get('format_version')} is not the supported {FORMAT_VERSION}")
        self.entries = _read_jsonl(self.root / INDEX_FILE)
        labels = {d["id"]: d for d in _read_jsonl(self.root / LABELS_FILE)}
        for e in self.entries:
            if e["id"] in labels:
                e["score"] = labels[e["id"]]["score"]
                e["label"] = labels[e["id"]]["success"]
        self.by_id = {e["id"]: e for e in self.entries}
        self._files: dict[str, object] = {}
        self._pid = os.getpid()

    def __len__(self) -> int:
        return len(self.entries)

    def perception_capture(self) -> dict:
        """The perception fields the pictures were taken under (``dataset.json``'s ``perception``).

        Training runs and resumed collections check theirs against it
        (:func:`actaim2.perception.config.check_compatible` with ``CAPTURE_FIELDS``).
        """
        if "perception" not in self.info:
            raise ValueError(f"{self.root}/dataset.json records no perception configuration (collected before "
                             f"configurations were recorded): its rig, cube and render path are unknown, re-collect it")
        return dict(self.info["perception"])

    def members(self, entry: dict) -> dict[str, bytes]:
        """The raw members (name -> bytes) of one trajectory."""
        if self._pid != os.getpid():  # file handles do not survive a fork: reopen per process
            self._files, self._pid = {}, os.getpid()
        f = self._files.get(entry["chunk"])
        if f is None:
            f = self._files[entry["chunk"]] = open(self.root / entry["chunk"], "rb")
        f.seek(entry["offset"])
        blob = f.read(entry["size"])
        if len(blob) != entry["size"]:
            raise IOError(f"{entry['chunk']} is truncated at trajectory {entry['id']}")
        out = {}
        with tarfile.open(fileobj=io.BytesIO(blob), mode="r:") as tar:
            for member in tar:
                out[member.name] = tar.extractfile(member).read()
        return out

    def read(self, tid_or_entry: str | dict) -> Trajectory:
        entry = self.by_id[tid_or_entry] if isinstance(tid_or_entry, str) else tid_or_entry
        return decode_trajectory(self.members(entry))

    def observations(self, entry: dict, names: list[str]) -> tuple[dict, dict[str, Observation]]:
        """The meta dict and the named observations of one trajectory, decoding nothing else."""
        raw = self.members(entry)
        meta = json.loads(raw[f"{entry['id']}.meta.json"])
        return meta, {o: {c: _camera_image(raw, meta, o, c) for c in meta["cameras"]} for o in names}


# The files that decide what training sees: info, index, labels, embeddings.
_DIGESTED = ("dataset.json", INDEX_FILE, "labels.jsonl", "embeddings.npz")


def dataset_digest(root: str | Path) -> str:
    """SHA-256 (16 hex) of the dataset files that decide what training sees (absent ones count by name)."""
    h = hashlib.sha256()
    for name in _DIGESTED:
        p = Path(root) / name
        h.update(name.encode())
        if p.exists():
            h.update(p.read_bytes())
    return h.hexdigest()[:16]
