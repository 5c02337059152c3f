"""Fine-tuning a trained policy on demonstrations (paper: the real-world fine-tuning on 60 teleop trajectories).

The training loop of ``actaim2 train`` (:class:`~actaim2.train.loop.Trainer`) does the work,
started from the parent checkpoint (``init_from``: its selector, predictor and their z statistics,
so eps keeps the meaning the parent learned); by default only its joint phase runs:
L_action(predictor(O_i, sg[eps_hat])) + w L_ELBO, both models updated, the stop-gradient keeping
the action loss out of the selector. The parent's training configuration is kept except for
the phases' length and learning rate, which fine-tuning chooses.

* Data: a dataset of demonstrations (``actaim2 bag2dataset``), views rendered through the parent's
  perception configuration (refused, naming the fields, when the dataset was captured otherwise).
* Validation: held-out demonstrations, a share of every mode label (:mod:`.heldout`), evaluated by
  the loop after every epoch (``history.jsonl``) and here before and after.
* Clusters: the cluster each labelled demonstration falls into, before and after, by label
  (:mod:`.clusters`).
* Mode labels (on by default, a CGMVAE selector): each operator label gets a cluster of its own, the one the
  parent's posterior favours for its training demonstrations (one-to-one, :func:`.clusters.label_assignment`);
  training treats a labelled demonstration's cluster as known (the selector's ELBO with c observed, and the
  predictor trained jointly on that selector's eps). The map is ``lineage.finetune.mode_labels.label_cluster``
  (what ``/sample_mode`` serves a ``mode_label`` by), with the held-out demonstrations' mode accuracy before and
  after. Without labels (or ``mode_labels=False``) every cluster is inferred, as in pretraining.
* Encoder E: the task embeddings must come from the parent's E. Its digest is checked against the
  parent's lineage when recorded there, else against the pretraining dataset when it is given
  (whose digest must then be the parent's ``dataset_digest``); otherwise the check is reported as
  not made. The new checkpoint records it, so the next fine-tuning is checked.
* Output: ``<out>/policy`` (safetensors + JSON) whose ``lineage.finetune`` holds the parent
  checkpoint (path, SHA-256 of its weights and of its JSON), the dataset (path, digest, encoder
  digest), the command, the held-out demonstrations, losses and cluster tables; ``finetune.json``
  repeats that report.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
import torch

from actaim2.artifact import checkpoint
from actaim2.data.labelling import dataset_encoder, embeddings_encoder_digest
from actaim2.data.splits import TRAIN
from actaim2.data.storage import DatasetReader, dataset_digest
from actaim2.finetune.clusters import (
    assign_clusters,
    cluster_probabilities,
    cluster_table,
    known_clusters,
    label_assignment,
    mode_accuracy,
)
from actaim2.finetune.heldout import heldout_rows
from actaim2.models.selector import CGMVAE
from actaim2.models.view_geometry import CubePlacement
from actaim2.perception.config import PerceptionConfig
from actaim2.train.config import TrainConfig
from actaim2.train.data import TrainingData, ensure_cache, open_cache
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import Trainer

REPORT_FILE = "finetune.json"


class FinetuneError(ValueError):
    """Fine-tuning cannot start: the message says what does not fit."""


@dataclass(frozen=True)
class FinetuneConfig:
    phases: tuple[str, ...] = ("joint",)
    epochs: float = 20.0  # per phase
    batch_size: int = 8
    lr: float = 1e-4
    heldout_fraction: float = 0.2  # of each mode label's demonstrations
    seed: int = 0
    device: str = "auto"
    mode_labels: bool = True  # give each operator mode label a cluster of its own (module docstring)


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def check_encoder(meta: dict, dataset: Path, pretraining: Path | None) -> dict:
    """Whether the dataset's task embeddings come from the parent's encoder E; FinetuneError if not."""
    ours = embeddings_encoder_digest(dataset)
    recorded = (meta.get("lineage") or {}).get("encoder_digest")
    if recorded is None and pretraining is not None:
        if dataset_digest(pretraining) != meta.get("dataset_digest"):
            raise FinetuneError(f"{pretraining} is not the data the parent checkpoint was trained on (its digest "
                                f"{dataset_digest(pretraining)}, the checkpoint's {meta.get('dataset_digest')})")
        recorded = embeddings_encoder_digest(pretraining)
    if recorded is None:
        return {"encoder_digest": ours, "checked": False,
                "note": "the parent records no encoder digest and no pretraining dataset was given: E not checked"}
    if ours != recorded:
        raise FinetuneError(f"the demonstrations' task embeddings come from encoder {ours}, the parent's from {recorded}: "
                            f"convert the bags with the pretraining data's encoder (bag2dataset --encoder)")
    return {"encoder_digest": ours, "checked": True}


@torch.no_grad()
def mean_losses(trainer: Trainer, phase: str, data: TrainingData, seed: int, batch: int = 16) -> dict[str, float] | None:
    """Mean loss terms of ``phase`` over every item of ``data``: eval mode, no augmentation, the same
    noise for every call with the same seed (comparable before and after fine-tuning)."""
    if len(data) == 0:
        return None
    items = np.arange(len(data))[:, None] if phase == "selector" else data.keyframes()
    if len(items) == 0:
        return None
    modules = [trainer.selector, trainer.predictor]
    for m in modules:
        m.eval()
    sums: dict[str, float] = {}
    with torch.random.fork_rng(devices=[trainer.device] if trainer.device.type == "cuda" else []):
        torch.manual_seed(seed)
        for chunk in np.array_split(items, max(1, math.ceil(len(items) / batch))):
            _, metrics = trainer.loss(phase, data, chunk)
            for k, v in metrics.items():
                sums[k] = sums.get(k, 0.0) + v * len(chunk)
    for m in modules:
        m.train()
    return {k: v / len(items) for k, v in sums.items()}


def _train_config(meta: dict, config: FinetuneConfig) -> TrainConfig:
    """The parent's training configuration with fine-tuning's phases, length, batch, rate, seed and device."""
    parent = TrainConfig.from_dict(meta["train_config"])
    phases = {f"{p}_phase": dataclasses.replace(parent.phase(p), epochs=config.epochs, batch_size=config.batch_size, lr=config.lr)
              for p in config.phases}
    return dataclasses.replace(parent, phases=tuple(config.phases), seed=config.seed, device=config.device, **phases)


def label_clusters(selector: torch.nn.Module, data: TrainingData, labels: Sequence[str], rows: np.ndarray,
                   device: torch.device) -> tuple[dict[str, int], str]:
    """(label -> cluster, a note) from the demonstrations ``rows`` through ``selector``; an empty map and why
    when there is nothing to assign."""
    if not any(labels[i] for i in rows):
        return {}, "no training demonstration has a mode label: every cluster inferred"
    if not isinstance(selector, CGMVAE):
        return {}, f"a {type(selector).__name__} selector has no cluster posterior: mode labels not used"
    try:
        return label_assignment(cluster_probabilities(selector, data.subset(rows), device), [labels[i] for i in rows]), \
            "each label's cluster: the one its training demonstrations' posterior favours under the parent, one-to-one"
    except ValueError as exc:
        raise FinetuneError(str(exc)) from exc


def finetune(parent: str | Path, dataset: str | Path, out: str | Path, config: FinetuneConfig = FinetuneConfig(),
             command: Sequence[str] = (), pretraining: str | Path | None = None, show_progress: bool = True) -> dict:
    """Fine-tune the checkpoint ``parent`` on ``dataset`` into ``<out>/policy``; returns the report."""
    dataset, out = Path(dataset), Path(out)
    weights_path, json_path = checkpoint.paths(parent)
    try:
        _, meta = checkpoint.read(parent)
    except checkpoint.CheckpointError as exc:
        raise FinetuneError(str(exc)) from exc
    if meta.get("selector_config") is None or meta.get("predictor_config") is None:
        raise FinetuneError(f"{json_path} does not hold both a selector and a predictor: fine-tuning needs a full policy")
    perception = PerceptionConfig.from_dict(meta["perception"]["fields"])
    record = checkpoint.perception_record(perception)
    encoder = check_encoder(meta, dataset, Path(pretraining) if pretraining else None)
    reader = DatasetReader(dataset)
    robot = reader.info.get("robot", "panda")
    ensure_cache(dataset, perception, [TRAIN], show_progress)
    placement = CubePlacement.of(perception)
    data = open_cache(dataset, perception, [TRAIN])
    labels = [reader.by_id[i].get("mode_label", "") for i in data.ids]
    train_rows, val_rows = heldout_rows(data.ids, labels, config.heldout_fraction, config.seed)
    ctx = init_distributed(config.device)
    label_cluster, note = {}, "not asked (mode_labels off): every cluster inferred"
    if config.mode_labels:
        label_cluster, note = label_clusters(checkpoint.load_policy(parent, record, ctx.device).selector, data, labels,
                                             train_rows, ctx.device)
    if label_cluster:
        data = dataclasses.replace(data, clusters=known_clusters(labels, label_cluster))
    train, val = data.subset(train_rows), data.subset(val_rows)
    trainer = Trainer(_train_config(meta, config), train, val, placement, record, dataset_digest(dataset), out,
                      ctx, init_from=checkpoint.paths(parent)[1].with_suffix(""), show_progress=show_progress)
    k = trainer.selector_config.clusters if trainer.selector_config.kind != "cvae" else 0
    clusters_before = assign_clusters(trainer.selector, data, trainer.device)
    before = {"clusters": cluster_table(data.ids, labels, clusters_before, k),
              **{p: {"train": mean_losses(trainer, p, train, config.seed), "val": mean_losses(trainer, p, val, config.seed)}
                 for p in config.phases}}
    trainer.lineage.update(encoder_digest=encoder["encoder_digest"])
    beside = checkpoint.encoder_path(parent)
    trainer.encoder_file = dataset_encoder(dataset) or (beside if encoder["checked"] and beside.is_file() else None)
    results = trainer.run()
    clusters_after = assign_clusters(trainer.selector, data, trainer.device)
    after = {"clusters": cluster_table(data.ids, labels, clusters_after, k),
             **{p: {"train": mean_losses(trainer, p, train, config.seed), "val": mean_losses(trainer, p, val, config.seed)}
                for p in config.phases}}
    heldout_labels = [labels[i] for i in val_rows]
    modes = {"label_cluster": label_cluster, "note": note,
             "heldout_accuracy": {side: mode_accuracy(heldout_labels, clusters[val_rows], label_cluster) if label_cluster else None
                                  for side, clusters in (("before", clusters_before), ("after", clusters_after))}}
    report = {
        "parent": {"path": str(json_path.with_suffix("")), "weights_sha256": _sha256(weights_path), "json_sha256": _sha256(json_path)},
        "dataset": {"path": str(dataset), "digest": dataset_digest(dataset), "trajectories": len(data), "robot": robot},
        "encoder": encoder,
        "command": list(command),
        "config": dataclasses.asdict(config),
        "heldout": [data.ids[i] for i in val_rows],
        "phases": {p: {"steps": r.steps, "seconds": round(r.seconds, 2)} for p, r in results.items()},
        "before": before,
        "after": after,
        "mode_labels": modes,
    }
    trainer.lineage["finetune"] = report
    report["checkpoint"] = str(trainer.save_policy().with_suffix(""))
    (out / REPORT_FILE).write_text(json.dumps(report, indent=2))
    return report

