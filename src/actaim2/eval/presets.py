"""Evaluation sizes: ``--smoke`` (CI, <= 2 min), ``--quick`` (<= 10 min), full (<= 3.5 h, resumable).

Each fixes the objects (catalogue splits, instances per category, categories) and the samples
per object (``tasks.SampleCounts``). Budgets are wall times on 2 cores with 2 workers; the
measured figures are in docs/evaluation.md.
"""
from __future__ import annotations

from dataclasses import dataclass

from actaim2.eval.tasks import SampleCounts


@dataclass(frozen=True)
class Preset:
    name: str
    instances_per_category: int  # 0 = all (8 per category and split)
    categories: tuple[str, ...]  # () = all
    counts: SampleCounts
    videos: int  # objects whose episodes are filmed (one per cluster) when --videos is not given


PRESETS = {
    # one object per split, one sample per cluster: every code path, no statistics
    "smoke": Preset("smoke", 1, ("storage_furniture", "box"), SampleCounts(per_cluster=1, baseline_per_group=1, per_object=2), 0),
    # one instance of every category per split (15 objects); ActAIM2's Mode SSR from 1 + 1 samples per cluster
    "quick": Preset("quick", 1, (), SampleCounts(per_cluster=2, baseline_per_group=1, per_object=2), 2),
    # every catalogue object (120): the 4 samples per cluster, 8 per object for the other rows; VQVAE-RVT
    # and Data Collection get 4 per code / pseudo-cluster too (32 per object): their Mode SSR is "the same
    # statistic" as ActAIM2's, so it is measured on as many half-B samples (2 per group), not on half as many
    "full": Preset("full", 0, (), SampleCounts(per_cluster=4, baseline_per_group=4, per_object=8), 2),
}
