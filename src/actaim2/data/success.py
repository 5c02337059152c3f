"""The visual success label: z = E(O_init) - E(O_final), success iff score(z) > threshold.

z is a vector, so "z > z_bar" needs a scalar. The change of a trajectory is the root-mean-square
of z, ``||z|| / sqrt(dim z)``: zero when the robot-hidden scene did not change, growing with how
much of it moved (dividing by sqrt(dim) keeps it comparable between encoders of different sizes).

The ground-truth criterion is *relative* (some DoF moved by more than 30% of its range), and so
is the score: the change divided by the 90th percentile of the changes of all trajectories on
the same object. How much a picture changes when a part moves by 30% of its range depends on
the part: a cabinet door sweeps a large area, a switch toggle a few pixels. Measured on a
316-trajectory collection (docs/data_collection.md), one threshold on the change itself labels
68.1% of the trajectories outside the calibration split correctly (it calls nearly every
held-out-category trajectory a failure); relative to the object's own changes, 85.1%.
The normaliser uses the object's pictures only, no state. The threshold is the one that labels
a calibration split best against the ground truth; the label's accuracy is then reported on
*other* splits. Ground truth is privileged: it is read here and nowhere else.
"""
from __future__ import annotations

import numpy as np

OBJECT_PERCENTILE = 90.0  # the object's "large change" reference, robust to a few outliers


def change(z: np.ndarray) -> np.ndarray:
    """RMS of each task embedding: (N, D) -> (N,)."""
    z = np.atleast_2d(np.asarray(z, dtype=np.float64))
    return np.linalg.norm(z, axis=1) / np.sqrt(z.shape[1])


def relative_score(changes: np.ndarray, objects: np.ndarray, percentile: float = OBJECT_PERCENTILE) -> np.ndarray:
    """Each change divided by the ``percentile``-th change among the trajectories of its object."""
    changes, objects = np.asarray(changes, dtype=np.float64), np.asarray(objects)
    out = np.empty_like(changes)
    for obj in np.unique(objects):
        mine = objects == obj
        out[mine] = changes[mine] / max(float(np.percentile(changes[mine], percentile)), 1e-12)
    return out


def calibrate_threshold(scores: np.ndarray, gt: np.ndarray) -> float:
    """The threshold with the best labelling accuracy on (scores, gt), midway between neighbours.

    Ties are broken towards balanced accuracy so that a split with few successes does not pick
    "everything failed".
    """
    order = np.argsort(np.asarray(scores, dtype=np.float64), kind="stable")
    s = np.asarray(scores, dtype=np.float64)[order]
    g = np.asarray(gt, dtype=bool)[order]
    n, positives = len(s), int(g.sum())
    if n == 0:
        raise ValueError("cannot calibrate a threshold on an empty split")
    # Cut k labels s[k:] successful; only cuts between distinct scores are thresholds.
    k = np.concatenate([[0], np.flatnonzero(np.diff(s) > 0) + 1, [n]])
    tp = positives - np.concatenate([[0], np.cumsum(g)])[k]  # successes at or above the cut
    tn = np.concatenate([[0], np.cumsum(~g)])[k]  # failures below it
    accuracy = (tp + tn) / n
    recall = tp / positives if positives else np.zeros_like(accuracy, dtype=float)
    specificity = tn / (n - positives) if n > positives else np.zeros_like(accuracy, dtype=float)
    best = np.lexsort((recall + specificity, accuracy))[-1]
    lo = s[k[best] - 1] if k[best] > 0 else s[0] - 1e-6
    hi = s[k[best]] if k[best] < n else s[-1] + 1e-6
    return float((lo + hi) / 2.0)


def label_metrics(scores: np.ndarray, gt: np.ndarray, threshold: float) -> dict:
    """Accuracy of ``scores > threshold`` against gt, with balanced accuracy, precision and recall."""
    pred = np.asarray(scores) > threshold
    gt = np.asarray(gt, dtype=bool)
    tp, tn = int(np.sum(pred & gt)), int(np.sum(~pred & ~gt))
    fp, fn = int(np.sum(pred & ~gt)), int(np.sum(~pred & gt))
    n = len(gt)
    recall = tp / (tp + fn) if tp + fn else float("nan")
    specificity = tn / (tn + fp) if tn + fp else float("nan")
    return {
        "n": n,
        "positives": tp + fn,
        "accuracy": (tp + tn) / n if n else float("nan"),
        "balanced_accuracy": float(np.nanmean([recall, specificity])) if n else float("nan"),
        "precision": tp / (tp + fp) if tp + fp else float("nan"),
        "recall": recall,
    }
