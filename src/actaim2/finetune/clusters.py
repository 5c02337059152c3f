"""Which cluster of the mode selector each labelled demonstration falls into.

A demonstration's cluster is argmax_c q(c | x, y, O) at the posterior means of x and y given its
task embedding and its robot-hidden initial views (``ModeSelector.assign_clusters``). Tabulated by
the operator's mode label, it answers the paper's question "are the modes classified correctly?"
and names, per label, the cluster holding most of its demonstrations: the cluster a push (pull)
is then asked for in evaluation.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import torch

from actaim2.models.selector_base import ModeSelector
from actaim2.train.data import TrainingData

NO_LABEL = "<none>"


@torch.no_grad()
def assign_clusters(selector: ModeSelector, data: TrainingData, device: torch.device | str = "cpu",
                    batch: int = 64) -> np.ndarray:
    """(N,) cluster of every trajectory of ``data`` (-1 for a selector without discrete modes)."""
    selector.eval()
    out = []
    for start in range(0, len(data), batch):
        rows = np.arange(start, min(start + batch, len(data)))
        views, z = data.selector_batch(rows, device)
        out.append(selector.assign_clusters(views, selector.standardise(z)).cpu().numpy())
    return np.concatenate(out) if out else np.zeros(0, np.int64)


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
