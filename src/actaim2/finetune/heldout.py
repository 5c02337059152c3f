"""Which demonstrations are held out for validation while fine-tuning: a fraction of each mode label.

Sixty demonstrations in two modes are few; a held-out set drawn without regard to the label can
miss a mode entirely. Each label's demonstrations are ranked by a hash of their id (stable when
more bags are converted later: a demonstration keeps its side) and the first ``fraction`` of each
label is held out, at least one of every label that has two or more, never a label's last one.
"""
from __future__ import annotations

import hashlib
from typing import Sequence

import numpy as np


def _rank(seed: int, tid: str) -> str:
    return hashlib.sha256(f"{seed}:{tid}".encode()).hexdigest()


def heldout_rows(ids: Sequence[str], labels: Sequence[str], fraction: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(training rows, validation rows) of ``ids``, validation stratified by ``labels``."""
    if not 0.0 <= fraction < 1.0:
        raise ValueError(f"the held-out fraction must be in [0, 1), got {fraction}")
    if len(ids) != len(labels):
        raise ValueError(f"{len(ids)} ids but {len(labels)} labels")
    val: list[int] = []
    for label in sorted(set(labels)):
        rows = sorted((i for i, given in enumerate(labels) if given == label), key=lambda i: _rank(seed, ids[i]))
        n = int(round(fraction * len(rows)))
        if fraction > 0 and len(rows) >= 2:
            n = min(max(n, 1), len(rows) - 1)
        val += rows[:n]
    held = np.zeros(len(ids), bool)
    held[val] = True
    return np.flatnonzero(~held), np.flatnonzero(held)
