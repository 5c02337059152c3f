"""A recording that dies: chunks written by age, `actaim2 bag-reindex` finishing the files a
recorder left open and rebuilding metadata.yaml, and the readers' advice when it is missing.
(The SIGKILL of a real bag_recorder process: tests/bags/test_bag_recorder_node.py.)"""
from __future__ import annotations

import hashlib
import shutil
import time

import pytest
import yaml

import bagtools
from actaim2.bags import salvage
from actaim2.bags.recorder import Recorder
from actaim2.bags.reindex import reindex
from actaim2.bags.source import BagSource
from actaim2.bags.writer import BagWriter
from actaim2.finetune.bag_episodes import BagProblem, read_episodes
from bagtools import T0, joint_state, read_anyreader, read_mcap_package, spec
from harness import wait_for


def write_files(path, storage="mcap", **kwargs):
    """120 joint states, 4 small clouds, a /tf_static; the storage files, in split order."""
    bagtools.write_bag(path, storage, "lz4" if storage == "mcap" else "none", frames=120,
                       cloud_every=30, cloud_size=(16, 12), **kwargs)
    files = [p for p in path.iterdir() if p.suffix in (".mcap", ".db3")]
    return sorted(files, key=lambda p: int(p.stem.rsplit("_", 1)[1]))


def digests(bag):
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
            for p in bag.iterdir() if p.name != "metadata.yaml"}


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_closed_split_bag_gets_the_writers_metadata_yaml_back_byte_for_byte(tmp_path, storage):
    bag = tmp_path / "bag"
    files = write_files(bag, storage, max_file_size=6_000, chunk_size=2048)
    assert len(files) >= 3
    written, before = (bag / "metadata.yaml").read_text(), digests(bag)
    (bag / "metadata.yaml").unlink()
    lines = []
    body = reindex(bag, lines.append)
    assert (bag / "metadata.yaml").read_text() == written
    assert digests(bag) == before  # files their writer finished are only read
    assert body["message_count"] == 1 + 120 + 4 and len(lines) == len(files)
    assert all("finished by its writer (only read)" in line for line in lines)


def cut_points(mcap):
    """Byte offsets where a dying writer can leave the file: inside, at the end of and after each
    chunk record, inside its message indexes, and inside the summary."""
    chunks = salvage.scan(mcap).chunks
    points = []
    for c in chunks:
        done = c.start + c.chunk_length
        points += [(done - 1, c.start), (done, done), (done + 12, done), (c.end, done)]
    points.append((chunks[-1].end + 40, chunks[-1].end))
    return chunks, points


def test_an_mcap_file_cut_anywhere_keeps_every_complete_chunk_for_both_readers(tmp_path):
    (mcap,) = write_files(tmp_path / "closed", chunk_size=2048)
    data = mcap.read_bytes()
    chunks, points = cut_points(mcap)
    assert len(chunks) >= 6
    for cut, kept_through in points:
        bag = tmp_path / f"cut_{cut}"
        bag.mkdir()
        (bag / mcap.name).write_bytes(data[:cut])
        lines = []
        body = reindex(bag, lines.append)
        expected = sum(sum(c.channel_counts.values())
                       for c in chunks if c.start + c.chunk_length <= kept_through)
        assert body["message_count"] == expected, (cut, lines)
        assert "not finished by its writer" in lines[0]
        for read in (read_anyreader, read_mcap_package):
            messages = read(bag)
            assert sum(len(m) for m in messages.values()) == expected, (cut, read.__name__)
            positions = [m.position[0] for _, m in messages.get("/joint_states", [])]
            assert positions == list(range(len(positions)))
        again = []
        reindex(bag, again.append)  # a finished file is not touched again
        assert "finished by its writer (only read)" in again[0]


def test_the_writer_thread_puts_old_messages_on_disk_without_waiting_for_more(tmp_path):
    def record(max_chunk_age):
        path = tmp_path / f"age_{max_chunk_age}"
        recorder = Recorder(lambda name: BagWriter(path / name, max_chunk_age=max_chunk_age))
        recorder.add_topic(spec("/joint_states", "sensor_msgs/msg/JointState"), reliable=True,
                           latched=False)
        recorder.start_bag("bag", T0)
        for i in range(10):
            recorder.put("/joint_states", T0 + i, joint_state(i))
        return recorder, path / "bag" / "bag_0.mcap"

    recorder, mcap = record(0.2)  # then nothing more arrives
    assert wait_for(lambda: mcap.exists() and salvage.scan(mcap).counts == {1: 10}, 5.0)
    recorder.stop()
    recorder, mcap = record(0.0)  # by size only: everything waits in the open chunk
    time.sleep(1.0)
    assert salvage.scan(mcap).counts == {}
    recorder.stop()


def test_a_bag_without_metadata_yaml_is_refused_with_the_command_that_rebuilds_it(tmp_path):
    bag = tmp_path / "bag"
    write_files(bag)
    (bag / "metadata.yaml").unlink()
    advice = f"`actaim2 bag-reindex {bag}`"
    with pytest.raises(FileNotFoundError, match=f"metadata.yaml is missing .*{advice}"):
        BagSource(bag, print)
    with pytest.raises(BagProblem, match=advice):  # bag2dataset reports it so
        next(read_episodes(bag, {"/points2": "azure"}, print))
    reindex(bag, print)
    played = [m.topic for m in BagSource(bag, print).messages({"/joint_states", "/tf_static"})]
    assert played.count("/joint_states") == 120 and played.count("/tf_static") == 1


def test_a_killed_recording_plays_before_reindexing_and_says_how_to_finish_it(tmp_path):
    bag = tmp_path / "bag"
    (mcap,) = write_files(tmp_path / "closed", chunk_size=2048)
    shutil.copytree(tmp_path / "closed", bag)
    chunks = salvage.scan(mcap).chunks
    (bag / mcap.name).write_bytes(mcap.read_bytes()[: chunks[3].end])
    reports = []
    source = BagSource(bag, reports.append)
    kept = sum(sum(c.channel_counts.values()) for c in chunks[:4])
    assert len(list(source.messages({"/joint_states", "/points2", "/tf_static"}))) == kept
    assert any(f"`actaim2 bag-reindex {bag}` finishes the file" in r for r in reports), reports


def test_a_split_recording_killed_in_its_last_file_plays_the_rest_and_names_the_fix(tmp_path):
    bag = tmp_path / "bag"
    files = write_files(bag, max_file_size=6_000, chunk_size=2048)
    info = yaml.safe_load((bag / "metadata.yaml").read_text())
    info["rosbag2_bagfile_information"]["relative_file_paths"].pop()  # what the writer had written
    (bag / "metadata.yaml").write_text(yaml.safe_dump(info))
    reports = []
    BagSource(bag, reports.append)
    assert reports == [f"{files[-1]}: not listed in metadata.yaml; skipped "
                       f"(`actaim2 bag-reindex {bag}` adds it)"]
    reindex(bag, print)
    reports.clear()
    played = BagSource(bag, reports.append).messages({"/joint_states", "/points2", "/tf_static"})
    assert len(list(played)) == 1 + 120 + 4 and reports == []
