"""The samples ``actaim2 view`` shows, read from a dataset, an evaluation run or rosbag2 bags.

* a dataset (``dataset.json``): one sample per trajectory, its O_init and O_final pictures,
  their fused cloud and views (recomputed with the dataset's perception configuration), the
  keyposes, the ground-truth outcome, the visual label and the GMM sampler's cluster;
* an evaluation run (``results.jsonl``), or a record of one under ``results/`` (its
  ``results.jsonl.gz``): one sample per executed sample, its outcome, cluster, confidences and
  moved fractions, with the run's figures of its object (``figures/``: the heatmaps of a
  re-executed sample per phase and view, the eps embedding); no pictures are kept per sample,
  so there is no cloud;
* bags (a ``.mcap`` / ``.db3`` file, a bag folder, or a folder of bag folders): one sample per
  teleop episode (``actaim2.finetune.bag_episodes``): the rig's clouds at START and at END as
  pictures, their fused cloud and views (robot included unless a robot is named to remove),
  the marked keyposes, the operator's verdict and the mode label.
"""
from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from actaim2.keypose import Keypose
from actaim2.perception.config import CAPTURE_FIELDS, PerceptionConfig
from actaim2.perception.fusion import CameraCloud
from actaim2.perception.pipeline import Perception
from actaim2.viz.recording import Sample

BAG_SUFFIXES = (".mcap", ".db3")
WORLD = "world"
OBSERVATION_NAMES = {"init": "O_init", "final": "O_final"}  # stored name -> shown name


def kind_of(path: Path) -> str:
    """``dataset``, ``evaluation`` or ``bags``; ValueError for anything else."""
    if (path / "dataset.json").exists():
        return "dataset"
    if _results_file(path) is not None:
        return "evaluation"
    if bag_paths(path):
        return "bags"
    raise ValueError(f"{path} is neither a dataset (dataset.json), an evaluation run (results.jsonl) nor rosbag2 bags")


def _results_file(path: Path) -> Path | None:
    """An evaluation run's results, or a record's (``actaim2.report.records``)."""
    from actaim2.eval.results import RECORD_SAMPLES_FILE, RESULTS_FILE

    return next((path / name for name in (RESULTS_FILE, RECORD_SAMPLES_FILE) if (path / name).is_file()), None)


def bag_paths(path: Path) -> list[Path]:
    """The bags at ``path``: the file or bag folder itself, or every bag folder directly under it."""
    if path.is_file():
        return [path] if path.suffix in BAG_SUFFIXES else []
    if (path / "metadata.yaml").exists():
        return [path]
    return sorted(p for p in path.iterdir() if p.is_dir() and (p / "metadata.yaml").exists()) if path.is_dir() else []


def _observe(perception: Perception, clouds: list[CameraCloud]) -> tuple[tuple[np.ndarray, np.ndarray | None], list[np.ndarray]]:
    """The fused cloud (xyz, rgb) and each view's colours."""
    from actaim2.viz.foxglove_live import view_pictures

    fused = perception.fuse(clouds)
    views = perception.render(perception.without_robot(fused) if perception.self_filter is not None else fused)
    return (fused.xyz, fused.rgb), view_pictures(views, perception.config.channels)


def dataset_samples(root: Path, limit: int) -> Iterator[Sample]:
    from actaim2.data.object_cloud import back_project
    from actaim2.data.storage import DatasetReader
    from actaim2.perception.config import load_perception_config

    reader = DatasetReader(root)
    capture = reader.perception_capture()
    config = load_perception_config(capture["rig"]).replace(
        **{name: capture[name] for name in CAPTURE_FIELDS if name not in ("rig", "remove_robot_views")},
        remove_robot_views=False)
    perception = Perception(config)  # O_init and O_final are rendered without the robot: nothing to filter
    for entry in reader.entries[:limit]:
        meta, observations = reader.observations(entry, list(OBSERVATION_NAMES))
        sample = Sample(entry["id"], {
            "object": meta["object_id"], "split": meta["split"], "sampler": meta["sampler"],
            "success": bool(entry.get("gt_success", False)), "visual label": entry.get("label", "not labelled"),
            "label score": entry.get("score", ""), "cluster": meta["info"].get("sampler_cluster"), "seed": meta["seed"],
        }, keyposes=[Keypose.from_json(k) for k in meta["keyposes"]])
        for name, shown in OBSERVATION_NAMES.items():
            cameras = observations[name]
            sample.pictures[shown] = {c: cameras[c].rgb for c in sorted(cameras)}
            clouds = [CameraCloud(back_project(cameras[c]), cameras[c].rgb.reshape(-1, 3), cameras[c].T_world_optical)
                      for c in sorted(cameras)]
            cloud, sample.views[shown] = _observe(perception, clouds)
            if name == "init":
                sample.cloud = cloud
        yield sample


def evaluation_samples(run: Path, limit: int) -> Iterator[Sample]:
    import gzip

    from PIL import Image

    figures: dict[str, dict[str, np.ndarray]] = {}  # object -> its figures, one dict shared by its samples
    path = _results_file(run)
    if path is None:
        raise ValueError(f"{run} holds no evaluation results")
    text = gzip.decompress(path.read_bytes()).decode() if path.suffix == ".gz" else path.read_text()
    lines = [line for line in text.splitlines() if line.strip()]
    for line in lines[:limit]:
        try:
            result = json.loads(line)
        except json.JSONDecodeError:  # a line cut short by a kill (results.py drops it as well)
            continue
        name = result["object"]
        if name not in figures:
            figures[name] = {kind: np.asarray(Image.open(path).convert("RGB"))
                             for kind in ("heatmaps", "embeddings")
                             if (path := run / "figures" / f"{kind}_{name}.png").exists()}
        summary = {key: result[key] for key in ("method", "object", "split", "cluster", "requested_cluster", "success",
                                                "largest_change", "phases_executed", "confidence", "fractions", "note")
                   if key in result}
        yield Sample(result["key"], summary, figures=figures[name])


def bag_samples(path: Path, limit: int, config: PerceptionConfig, robot: str | None,
                report: Callable[[str], None]) -> Iterator[Sample]:
    from actaim2.finetune.bag2dataset import rig_topics
    from actaim2.finetune.bag_episodes import read_episodes

    self_filter = None
    if robot is not None:
        from actaim2.perception.self_filter import RobotSelfFilter
        from actaim2.robots import load_robot_spec

        self_filter = RobotSelfFilter(load_robot_spec(robot), config.self_filter_margin)
    perception = Perception(config.replace(remove_robot_views=robot is not None), self_filter)
    shown = 0
    for bag in bag_paths(path):
        for episode in read_episodes(bag, rig_topics(config), report):
            if shown == limit:
                return
            sample = Sample(f"{bag.name} episode {episode.episode}", {
                "bag": bag.name, "object": episode.object_id, "success": episode.success,
                "mode label": episode.label or "none", "note": episode.note}, keyposes=episode.keyposes)
            for name, shown_name in OBSERVATION_NAMES.items():
                clouds = episode.observations[name]
                sample.pictures[shown_name] = {c: cloud.rgb for c, cloud in sorted(clouds.items()) if cloud.rgb is not None}
                if self_filter is not None:
                    joints = episode.joints_at(min(c.stamp_ns for c in clouds.values()))
                    self_filter.set_joint_positions(list(joints), list(joints.values()))
                cloud, sample.views[shown_name] = _observe(perception, [
                    CameraCloud(c.xyz.reshape(-1, 3), None if c.rgb is None else c.rgb.reshape(-1, 3),
                                episode.transforms.lookup(WORLD, c.frame_id)) for _, c in sorted(clouds.items())])
                if name == "init":
                    sample.cloud = cloud
            shown += 1
            yield sample
