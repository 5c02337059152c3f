"""The Data Collection row's samplers: collection's GMM-adaptive sampler, fitted per object as collection fits it.

The paper's "Data Collection" baseline is its adaptive data collection: GMMs over the task
embeddings and action sequences of an object's exploration trajectories (random + heuristic
grasp), sampled cluster by cluster. :func:`actaim2.data.collect.fit_gmm_samplers` with
``round_start=0`` fits exactly the samplers of collection's first adaptive round from the
dataset's exploration stage and its visual labels; evaluation executes fresh samples of them.
An object without collected trajectories has no sampler and no Data Collection samples.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from actaim2.data.collect import CollectConfig, fit_gmm_samplers
from actaim2.data.gmm_sampler import GMMAdaptiveSampler
from actaim2.data.storage import DatasetReader
from actaim2.eval.evalset import EvalObject


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
