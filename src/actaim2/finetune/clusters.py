"""Which cluster of the mode selector each labelled demonstration falls into.

A demonstration's cluster is argmax_c q(c | x, y, O) at the posterior means of x and y given its
task embedding and its robot-hidden initial views (``ModeSelector.assign_clusters``). Tabulated by
the operator's mode label, it answers the paper's question "are the modes classified correctly?"
and names, per label, the cluster holding most of its demonstrations: the cluster a push (pull)
is then asked for in evaluation.

Fine-tuning by mode label (:func:`label_assignment`) gives each label a cluster of its own before training:
the cluster its demonstrations' posterior favours, one-to-one, so that push and pull are never one cluster;
training then treats a demonstration's cluster as known (``TrainingData.clusters``) and
:func:`mode_accuracy` scores the held-out demonstrations against that map.
"""
from __future__ import annotations

from typing import Callable, Sequence

import numpy as np
import torch
from scipy.optimize import linear_sum_assignment

from actaim2.models.selector import CGMVAE
from actaim2.models.selector_base import ModeSelector
from actaim2.train.data import TrainingData

NO_LABEL = "<none>"


@torch.no_grad()
def _per_trajectory(selector: ModeSelector, data: TrainingData, device: torch.device | str, batch: int,
                    read: Callable[[torch.Tensor, torch.Tensor], torch.Tensor]) -> list[np.ndarray]:
    """``read(views, standardised z)`` of every trajectory of ``data``, in batches."""
    selector.eval()
    out = []
    for start in range(0, len(data), batch):
        views, z = data.selector_batch(np.arange(start, min(start + batch, len(data))), device)
        out.append(read(views, selector.standardise(z)).cpu().numpy())
    return out


def assign_clusters(selector: ModeSelector, data: TrainingData, device: torch.device | str = "cpu",
                    batch: int = 64) -> np.ndarray:
    """(N,) cluster of every trajectory of ``data`` (-1 for a selector without discrete modes)."""
    out = _per_trajectory(selector, data, device, batch, selector.assign_clusters)
    return np.concatenate(out) if out else np.zeros(0, np.int64)


def cluster_probabilities(selector: CGMVAE, data: TrainingData, device: torch.device | str = "cpu",
                          batch: int = 64) -> np.ndarray:
    """(N, K) q(c | x, y, O) of every trajectory of ``data`` at its posterior means."""
    out = _per_trajectory(selector, data, device, batch, selector.cluster_probabilities)
    return np.concatenate(out) if out else np.zeros((0, selector.config.clusters), np.float32)


def label_assignment(probabilities: np.ndarray, labels: Sequence[str]) -> dict[str, int]:
    """label -> cluster, one cluster per label: the assignment maximising the summed mean posterior of each label's
    demonstrations (``probabilities`` (N, K), one row per demonstration; unlabelled ones are left out), solved as
    a linear assignment so that a tie or two labels favouring one cluster never give them the same cluster."""
    names = sorted({label for label in labels if label})
    k = probabilities.shape[1]
    if len(names) > k:
        raise ValueError(f"{len(names)} mode labels ({', '.join(names)}) but the selector has {k} clusters: "
                         "each label needs a cluster of its own")
    if not names:
        return {}
    rows = np.asarray(labels)
    score = np.stack([probabilities[rows == name].mean(axis=0) for name in names])
    chosen_labels, chosen_clusters = linear_sum_assignment(score, maximize=True)
    return {names[i]: int(c) for i, c in zip(chosen_labels, chosen_clusters)}


def known_clusters(labels: Sequence[str], label_cluster: dict[str, int]) -> np.ndarray:
    """(N,) each demonstration's cluster under ``label_cluster``, -1 for an unlabelled one."""
    return np.array([label_cluster.get(label, -1) for label in labels], np.int64)


def mode_accuracy(labels: Sequence[str], clusters: np.ndarray, label_cluster: dict[str, int]) -> dict:
    """Share of the labelled demonstrations whose cluster is their label's, overall and per label."""
    by_label = {}
    for name, target in sorted(label_cluster.items()):
        picked = np.asarray([c for label, c in zip(labels, clusters) if label == name])
        by_label[name] = {"cluster": target, "demonstrations": len(picked), "correct": int(np.sum(picked == target)),
                          "accuracy": float(np.mean(picked == target)) if len(picked) else None}
    n = sum(v["demonstrations"] for v in by_label.values())
    correct = sum(v["correct"] for v in by_label.values())
    return {"demonstrations": n, "correct": correct, "accuracy": correct / n if n else None, "by_label": by_label}


def cluster_table(ids: Sequence[str], labels: Sequence[str], clusters: np.ndarray, k: int) -> dict:
    """Per label: demonstrations in each of the ``k`` clusters, the cluster holding most of them and
    the share it holds; per demonstration: its cluster."""
    by_label: dict[str, list[int]] = {}
    for label, c in zip(labels, clusters):
        counts = by_label.setdefault(label or NO_LABEL, [0] * k)
        if 0 <= c < k:
            counts[int(c)] += 1
    majority = {label: int(np.argmax(counts)) for label, counts in by_label.items() if sum(counts)}
    return {
        "clusters": k,
        "by_label": by_label,
        "label_cluster": majority,
        "label_cluster_share": {label: by_label[label][c] / sum(by_label[label]) for label, c in majority.items()},
        "demonstrations": [{"id": i, "label": label or NO_LABEL, "cluster": int(c)}
                           for i, label, c in zip(ids, labels, clusters)],
    }


def format_table(table: dict) -> str:
    """The table as Markdown: one row per label, one column per cluster, the majority marked *."""
    k = table["clusters"]
    lines = ["| label | " + " | ".join(f"c{c}" for c in range(k)) + " | majority |",
             "|---|" + "---|" * (k + 1)]
    for label, counts in sorted(table["by_label"].items()):
        best = table["label_cluster"].get(label)
        cells = [f"{n}*" if c == best and n else str(n) for c, n in enumerate(counts)]
        share = table["label_cluster_share"].get(label)
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {'-' if best is None else f'c{best} ({share:.0%})'} |")
    return "\n".join(lines)
