"""Do a method's groups select outcomes? A permutation test of group against outcome.

Mode SSR (``mode_ssr.py``) reports how often the group chosen for a mode produces it, on half of
the samples. It cannot tell groups that select nothing from groups that do select modes which
are each too rare to clear an interval of 48 or 96 samples. This test uses every sample: per
object, the mutual information (nats) between the group a sample was drawn from (cluster, code,
goal, pseudo-cluster) and its outcome (the (DoF, direction) of a success, or "failed"), summed
over the objects of a split. Under "the groups select nothing" every assignment of the object's
samples to its groups is equally likely, so the p-value is the fraction of permutations (groups
shuffled among one object's samples, outcomes kept, fixed seed) whose sum is at least the
observed one. The shuffled mean is printed beside it: the empirical MI of a few dozen samples is
well above zero even without any dependence.
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import Iterable

import numpy as np

PERMUTATIONS = 500


@dataclass(frozen=True)
class Dependence:
    objects: int
    samples: int
    mutual_information: float  # nats, summed over objects
    shuffled_mean: float  # the same under permuted groups
    p_value: float  # (1 + permutations at or above the observed) / (1 + permutations)

    def cell(self) -> str:
        return f"{self.mutual_information:.2f} (shuffled {self.shuffled_mean:.2f}), p {self.p_value:.3f}"


def mutual_information(groups: np.ndarray, outcomes: np.ndarray) -> np.ndarray:
    """Empirical MI of integer labels: groups (P, N) rows of assignments against outcomes (N,) -> (P,)."""
    n_groups, n_outcomes = int(groups.max()) + 1, int(outcomes.max()) + 1
    rows = np.arange(len(groups))[:, None] * (n_groups * n_outcomes)
    joint = np.bincount((rows + groups * n_outcomes + outcomes).ravel(), minlength=len(groups) * n_groups * n_outcomes)
    joint = joint.reshape(len(groups), n_groups, n_outcomes) / groups.shape[1]
    expected = joint.sum(axis=2, keepdims=True) * joint.sum(axis=1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(joint > 0, joint * np.log(joint / expected), 0.0)
    return terms.sum(axis=(1, 2))


def dependence(per_object: Iterable[tuple[np.ndarray, np.ndarray]], permutations: int = PERMUTATIONS,
               seed: int = 0) -> Dependence:
    """The test over objects given as (groups, outcomes) integer arrays of their samples."""
    rng = np.random.default_rng(seed)
    observed, shuffled, objects, samples = 0.0, np.zeros(permutations), 0, 0
    for groups, outcomes in per_object:
        observed += float(mutual_information(groups[None], outcomes)[0])
        shuffled += mutual_information(rng.permuted(np.tile(groups, (permutations, 1)), axis=1), outcomes)
        objects, samples = objects + 1, samples + len(groups)
    p = (1 + int((shuffled >= observed - 1e-12).sum())) / (1 + permutations)
    return Dependence(objects, samples, observed, float(shuffled.mean()), p)


def dependence_cells(records: Iterable[dict]) -> dict[tuple[str, str], Dependence]:
    """(method, split) -> the test over that split's objects, for records drawn from groups (group >= 0)."""
    by_object: dict[tuple[str, str, str], list[tuple[int, str]]] = defaultdict(list)
    for r in records:
        if r.get("group", -1) >= 0:
            by_object[r["method"], r["split"], r["object"]].append((r["group"], str(r["mode"]) if r["success"] else "failed"))
    per_split: dict[tuple[str, str], list[tuple[np.ndarray, np.ndarray]]] = defaultdict(list)
    for (method, split, _), pairs in sorted(by_object.items()):
        groups = np.unique([g for g, _ in pairs], return_inverse=True)[1]
        outcomes = np.unique([o for _, o in pairs], return_inverse=True)[1]
        per_split[method, split].append((groups.astype(np.int64), outcomes.astype(np.int64)))
    return {key: dependence(objects) for key, objects in per_split.items()}
