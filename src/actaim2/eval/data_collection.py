"""The Data Collection row's samplers: collection's GMM-adaptive sampler, fitted per object as collection fits it.

The paper's "Data Collection" baseline is its adaptive data collection: GMMs over the task
embeddings and action sequences of an object's exploration trajectories (random + heuristic
grasp), sampled cluster by cluster. :func:`actaim2.data.collect.fit_gmm_samplers` with
``round_start=0`` fits exactly the samplers of collection's first adaptive round from the
dataset's exploration stage and its visual labels; evaluation executes fresh samples of them.
An object the training dataset has no trajectories of (``val`` and test objects, any
``--objects`` folder) gets its own exploration first (:func:`explored_samplers`): random and
heuristic-grasp trajectories collected into the evaluation's folder, labelled by the success
model calibrated on the training dataset, as collection would label them.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from actaim2.data.collect import CollectConfig, collect, fit_gmm_samplers
from actaim2.data.gmm_sampler import GMMAdaptiveSampler
from actaim2.data.labelling import dataset_encoder, label_dataset, stored_model
from actaim2.data.real_objects import FolderObject
from actaim2.data.storage import DatasetReader
from actaim2.eval.evalset import EvalObject
from actaim2.eval.presets import DATA_COLLECTION_EXPLORATION

EXPLORATION_DIR = "data_collection"  # the exploration's dataset inside an evaluation's folder


def data_collection_samplers(data: Path,
                             objects: Sequence[EvalObject]) -> dict[str, GMMAdaptiveSampler]:
    """Evaluation key of each of ``objects`` that the dataset has trajectories of -> the
    GMM-adaptive sampler collection would draw its first adaptive round from (the dataset names
    objects by id: a catalogue object id, or a real folder's name)."""
    info = DatasetReader(data).info
    config = CollectConfig(out=Path(data), objects=(), per_object={}, seed=int(info.get("seed", 0)),
                           robot=info.get("robot", "panda"))
    fitted = fit_gmm_samplers(config, 0)
    return {o.key: fitted[o.object_id] for o in objects if o.object_id in fitted}


def exploration_config(data: Path, objects: Sequence[EvalObject], out: Path, per_object: int,
                       render_path: str, workers: int, show_progress: bool) -> CollectConfig:
    """Collection of ``per_object`` exploration trajectories on each of ``objects`` (half random,
    half heuristic grasp) into ``out``, with the training dataset's seed, robot and rig, its
    pictures taken on ``render_path`` (the evaluation's)."""
    info = DatasetReader(data).info
    return CollectConfig(
        out=Path(out), objects=tuple((o.category, o.instance) for o in objects if not o.folder),
        folders=tuple(FolderObject(o.folder, o.category, o.split) for o in objects if o.folder),
        per_object={"random": per_object - per_object // 2, "grasp": per_object // 2},
        seed=int(info.get("seed", 0)), robot=info.get("robot", "panda"), perception=info.get("rig", "ring5"),
        render_path=render_path, workers=workers, encoder=dataset_encoder(data), show_progress=show_progress)


def explored_samplers(data: Path, objects: Sequence[EvalObject], out: Path, per_object: int = DATA_COLLECTION_EXPLORATION,
                      render_path: str = "sapien", workers: int = 2,
                      show_progress: bool = True) -> tuple[dict[str, GMMAdaptiveSampler], dict]:
    """(evaluation key -> GMM-adaptive sampler, the labelling report) of ``objects`` after an
    exploration of their own in ``out`` (resumable), labelled by the success model calibrated on
    the training dataset ``data``. The report gives the label's accuracy against the ground
    truth on these objects, per split and per category."""
    config = exploration_config(data, objects, out, per_object, render_path, workers, show_progress)
    if config.encoder is None:
        raise FileNotFoundError(f"{data} has no encoder E beside its embeddings: Data Collection's "
                                f"GMMs cluster the task embeddings it makes")
    model = stored_model(data)
    collect(config)
    report = label_dataset(config.out, config.encoder, workers=workers, show_progress=show_progress, model=model)
    fitted = fit_gmm_samplers(config, 0, model)
    return {o.key: fitted[o.object_id] for o in objects if o.object_id in fitted}, report
