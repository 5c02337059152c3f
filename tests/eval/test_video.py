"""Episode videos (eval/video.py): a filmed ActAIM2 episode becomes a readable animated GIF, and filming
changes nothing of the episode (the same sample run without the film gives the same record)."""
from __future__ import annotations

import pytest
from PIL import Image

from actaim2.eval.checkpoints import perception_of
from actaim2.eval.episode import run_sample
from actaim2.eval.evalset import EvalObject
from actaim2.eval.tasks import EvalTask
from actaim2.eval.video import FILM_SIZE, LABEL_HEIGHT, video_table, write_videos
from actaim2.eval.worker import EvalWorker, WorkerSetup
from actaim2.sim.render_path import vulkan_device_error
from tiny_checkpoint import CLUSTERS, make_checkpoint


@pytest.mark.timeout(900)
def test_filmed_episodes_are_animated_gifs_of_the_unchanged_episode(tmp_path) -> None:
    stem = make_checkpoint(tmp_path / "policy")
    perception = perception_of(stem)
    setup = WorkerSetup("panda", perception.rig, "sapien" if vulkan_device_error() is None else "raycast",
                        tuple(perception.center), float(perception.half_extent), {"actaim2": str(stem)})
    worker = EvalWorker(setup)
    obj = EvalObject("train_seen", "faucet", 0)  # the tiny checkpoint's keyposes are reachable here: all 4 phases run
    tasks = [EvalTask("actaim2", obj, slot, slot % CLUSTERS, CLUSTERS) for slot in range(CLUSTERS)]
    filmed = tasks[:2]  # results for two clusters only: only those are filmed

    videos = write_videos(worker, tasks, {t.key: {} for t in filmed}, tmp_path / "out" / "videos", objects=1)

    assert [(v.object, v.cluster) for v in videos] == [(obj.key, 0), (obj.key, 1)]
    for video in videos:
        assert video.record["phases_executed"] == 4, video.record
        with Image.open(video.path) as gif:  # four motions of a second or more each, a frame every 0.1 s
            assert gif.format == "GIF" and gif.is_animated and gif.n_frames >= 10
            assert gif.size == (FILM_SIZE[0], FILM_SIZE[1] + LABEL_HEIGHT)
    plain = run_sample(worker.env, worker.planner, worker.executor, worker.cloud_config, worker.source("actaim2"), filmed[1],
                       setup.dof_fraction, setup.velocity_scaling)
    same = ("success", "largest_change", "fractions", "phases_executed", "note", "cluster", "confidence")
    assert {k: videos[1].record[k] for k in same} == {k: plain[k] for k in same}
    table = video_table(videos, tmp_path / "out")
    assert f"| {obj.key} | 1 | " in table
    assert f"(videos/{videos[0].path.name})" in table
