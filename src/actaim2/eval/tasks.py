"""Evaluation tasks: one executed sample each, keyed so that a rerun skips what is done.

A task is (method, object, slot[, cluster]). Slots number an object's samples; slot s has the
same reset and draw seeds for every method (``evalset.py``). A clustered method with K clusters
and n samples per cluster uses slots 0..nK-1, slot = repetition * K + cluster; the others use
slots 0..m-1 (``SampleCounts`` says how many). Tasks are ordered slot-major, so an interrupted run has covered every object and
method about equally.
"""
from __future__ import annotations

from dataclasses import dataclass

from actaim2.eval.evalset import EvalObject, reset_seed, sample_seed
from actaim2.eval.methods import ABLATIONS, METHODS, PSEUDO_CLUSTERS


@dataclass(frozen=True)
class EvalTask:
    method: str
    obj: EvalObject
    slot: int
    cluster: int = -1  # the cluster asked of a clustered method (-1: none)
    clusters: int = 0  # K of a clustered method

    @property
    def key(self) -> str:
        return f"{self.method}|{self.obj.key}|{self.slot}"

    @property
    def reset_seed(self) -> int:
        return reset_seed(self.obj, self.slot)

    @property
    def sample_seed(self) -> int:
        return sample_seed(self.obj, self.slot)


@dataclass(frozen=True)
class SampleCounts:
    """Samples per object of each method.

    ActAIM2 (and its input ablations) gets ``per_cluster`` samples from each of its K clusters. The baselines with groups
    get ``baseline_per_group`` per group: VQVAE-RVT per code, Data Collection per pseudo-cluster
    (its Mode SSR is the yardstick ActAIM2's 2nd mode is compared with, which needs samples in
    both halves of every group: 2 or more). The others get ``per_object`` samples per object.
    """

    per_cluster: int  # ActAIM2 and its ablations: samples from each cluster of each object
    baseline_per_group: int  # VQVAE-RVT per code, Data Collection per pseudo-cluster
    per_object: int  # Random, Goal-RVT (goals visited in turn), ActAIM (CVAE)

    def of(self, method: str, clusters: int) -> int:
        """Samples per object of ``method`` (``clusters``: its K, 0 when not clustered)."""
        if method == "actaim2" or method in ABLATIONS:
            return self.per_cluster * clusters
        if METHODS[method].grouping == "cluster":
            return self.baseline_per_group * clusters
        if method == "data_collection":
            return self.baseline_per_group * PSEUDO_CLUSTERS
        return self.per_object


def plan_tasks(methods: dict[str, int], objects: list[EvalObject], counts: SampleCounts,
               skip: dict[str, set[str]] | None = None) -> list[EvalTask]:
    """Tasks of ``methods`` (name -> K, 0 when not clustered) on ``objects``.

    ``skip`` maps a method to object keys it cannot run on (e.g. Data Collection on an object
    without collected trajectories).
    """
    skip = skip or {}
    tasks = []
    for name, k in methods.items():
        clustered = METHODS[name].grouping == "cluster"
        if clustered and k <= 0:
            raise ValueError(f"{name} samples per cluster but has {k} clusters")
        for obj in objects:
            if obj.key in skip.get(name, set()):
                continue
            if clustered:
                tasks += [EvalTask(name, obj, s, s % k, k) for s in range(counts.of(name, k))]
            else:
                tasks += [EvalTask(name, obj, s) for s in range(counts.of(name, 0))]
    order = {o.key: i for i, o in enumerate(objects)}
    names = list(methods)
    return sorted(tasks, key=lambda t: (t.slot, order[t.obj.key], names.index(t.method)))
