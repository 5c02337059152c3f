"""The on-disk format: exact round trip, size budget, plain-tar readability, crash recovery."""
from __future__ import annotations

import json
import tarfile

import numpy as np
import pytest

from actaim2.data.storage import (
    MAX_TRAJECTORY_BYTES,
    DatasetReader,
    DatasetWriter,
    encode_trajectory,
    write_labels,
)
from actaim2.data.trajectory import OBSERVATION_NAMES, CameraImage


def test_round_trip_is_exact_up_to_millimetre_depth(tmp_path, make_trajectory):
    traj = make_trajectory(moved=0.5)
    with DatasetWriter(tmp_path, {"rig": "ring5"}) as w:
        entry = w.append(encode_trajectory(traj))
    assert entry["size"] <= MAX_TRAJECTORY_BYTES
    reader = DatasetReader(tmp_path)
    assert reader.info["rig"] == "ring5" and len(reader) == 1
    back = reader.read(traj.id)
    assert back.gt_success and entry["gt_success"]
    assert back.keyposes[3].gripper_closed and not back.keyposes[0].gripper_closed
    for a, b in zip(traj.keyposes, back.keyposes):
        np.testing.assert_allclose(a.position, b.position)
        np.testing.assert_allclose(a.quat_xyzw, b.quat_xyzw)
    for name in OBSERVATION_NAMES:
        for cam, img in traj.observations[name].items():
            got = back.observations[name][cam]
            np.testing.assert_array_equal(got.rgb, img.rgb)
            assert np.abs(got.depth - img.depth).max() <= 0.0005 + 1e-6
            np.testing.assert_allclose(got.T_world_optical, img.T_world_optical)
            np.testing.assert_allclose(got.K, img.K)
    assert back.robot_joints == traj.robot_joints and back.info == traj.info


def test_chunks_are_plain_tar_files(tmp_path, make_trajectory):
    with DatasetWriter(tmp_path) as w:
        for k in range(2):
            w.append(encode_trajectory(make_trajectory(tid=f"obj-random-{k:05d}")))
    with tarfile.open(tmp_path / "chunks" / "chunk-00000.tar") as tar:
        names = tar.getnames()
        meta = json.loads(tar.extractfile("obj-random-00001.meta.json").read())
    assert len(names) == 2 * (1 + len(OBSERVATION_NAMES) * 5 * 2)
    assert meta["id"] == "obj-random-00001" and len(meta["keyposes"]) == 4


def test_over_budget_trajectory_is_refused(make_trajectory):
    traj = make_trajectory()
    rng = np.random.default_rng(0)
    for name in ("o0", "o1"):  # noise does not compress
        traj.observations[name] = {
            cam: CameraImage(rng.integers(0, 256, img.rgb.shape, dtype=np.uint8),
                             rng.uniform(0.5, 3.0, img.depth.shape).astype(np.float32), img.K, img.T_world_optical)
            for cam, img in traj.observations[name].items()
        }
    with pytest.raises(ValueError, match="budget"):
        encode_trajectory(traj)


def test_writer_recovers_from_an_interrupted_append(tmp_path, make_trajectory):
    with DatasetWriter(tmp_path) as w:
        for k in range(3):
            w.append(encode_trajectory(make_trajectory(tid=f"obj-random-{k:05d}")))
    chunk = tmp_path / "chunks" / "chunk-00000.tar"
    size = chunk.stat().st_size
    with open(chunk, "ab") as f:  # a half-written fourth trajectory ...
        f.write(b"x" * 70000)
    with open(tmp_path / "index.jsonl", "a") as f:  # ... and a torn index line
        f.write('{"id": "obj-random-0000')
    w = DatasetWriter(tmp_path)
    assert w.ids == {f"obj-random-{k:05d}" for k in range(3)}
    assert chunk.stat().st_size == size
    w.append(encode_trajectory(make_trajectory(tid="obj-random-00003")))
    w.close()
    reader = DatasetReader(tmp_path)
    assert [e["id"] for e in reader.entries] == [f"obj-random-{k:05d}" for k in range(4)]
    assert all(reader.read(e).id == e["id"] for e in reader.entries)


def test_new_chunk_past_the_size_limit_and_labels_join_the_index(tmp_path, make_trajectory):
    with DatasetWriter(tmp_path, chunk_bytes=1) as w:
        for k in range(3):
            w.append(encode_trajectory(make_trajectory(tid=f"obj-random-{k:05d}")))
    reader = DatasetReader(tmp_path)
    assert sorted({e["chunk"] for e in reader.entries}) == [f"chunks/chunk-{k:05d}.tar" for k in range(3)]
    write_labels(tmp_path, [{"id": e["id"], "score": 0.1 * k, "success": k == 2} for k, e in enumerate(reader.entries)])
    labels = [e["label"] for e in DatasetReader(tmp_path).entries]
    assert labels == [False, False, True]


def test_duplicate_trajectory_is_refused(tmp_path, make_trajectory):
    with DatasetWriter(tmp_path) as w:
        w.append(encode_trajectory(make_trajectory()))
        with pytest.raises(ValueError, match="already stored"):
            w.append(encode_trajectory(make_trajectory()))
