"""Mode SSR with a split-half cluster choice (paper Table 2 and its appendix table of 3rd/4th modes).

For one object, a method executed samples from each of its groups: the clusters of ActAIM2, the
codes of VQVAE-RVT, the goals of Goal-RVT, or random pseudo-clusters of a sampler's samples.
The outcome of a successful sample is (DoF, direction) (``outcome.py``).

  1. Modes are the outcomes ranked by their frequency over all successful samples of the object
     (ties: by name, so the order is fixed).
  2. Every sample is in half A (its repetition index within its group is even) or half B (odd).
  3. For mode 1, 2, ... in turn, the group is chosen on half A alone: the group, among those not
     already chosen for an earlier mode, with the most A samples of that outcome (ties, including
     "none has any", broken at random with a fixed seed). A mode needs its own group: the paper
     asks for modes "distributed in separate sample options".
  4. The mode's SSR on this object is the fraction of the chosen group's half-B samples whose
     outcome is that mode.

Why the split: choosing the best of K groups and reporting its rate on the same samples rewards
chance. With 8 groups of 4 samples that all behave alike (no structure at all), the best group's
observed rate of a 15 % mode is about 45 %; chosen on A and measured on B it stays an unbiased
15 % (tests/eval/test_mode_ssr.py). The price is that only half of the samples are measured.

An object with fewer distinct modes than asked for (or fewer groups) contributes, for each
missing mode, its per-group B count with 0 successes: a method that finds no second mode
scores 0 there, as in the paper's VQVAE-RVT row.
"""
from __future__ import annotations

import zlib
from collections import Counter
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from actaim2.eval.stats import Rate

Mode = tuple[str, int]  # (DoF, direction)


@dataclass(frozen=True)
class GroupSample:
    group: int  # cluster, code, goal or pseudo-cluster the sample was drawn from
    repetition: int  # its index within the group: even -> half A (choice), odd -> half B (report)
    mode: Mode | None  # the outcome of a success, None for a failure


@dataclass(frozen=True)
class ModeResult:
    rank: int  # 1 = the most frequent outcome
    mode: Mode | None  # None: the object showed fewer modes, or no group was left
    group: int  # the group chosen on half A (-1 without a mode)
    rate: Rate  # that group's half-B samples with this outcome


def rank_modes(samples: Sequence[GroupSample]) -> list[Mode]:
    """Outcomes of the successful samples, most frequent first (ties by name, then direction)."""
    counts = Counter(s.mode for s in samples if s.mode is not None)
    return sorted(counts, key=lambda m: (-counts[m], m[0], m[1]))


def object_mode_ssr(samples: Sequence[GroupSample], modes: int, tie_key: str) -> list[ModeResult]:
    """Mode SSR of modes 1..``modes`` on one object; ``tie_key`` (e.g. method/object) seeds the tie breaks."""
    groups = sorted({s.group for s in samples})
    half_b = {g: [s for s in samples if s.group == g and s.repetition % 2 == 1] for g in groups}
    half_a = {g: [s for s in samples if s.group == g and s.repetition % 2 == 0] for g in groups}
    per_group_b = int(round(np.mean([len(v) for v in half_b.values()]))) if groups else 0
    rng = np.random.default_rng(zlib.crc32(tie_key.encode()))
    ranked = rank_modes(samples)
    taken: set[int] = set()
    results = []
    for rank in range(1, modes + 1):
        free = [g for g in groups if g not in taken]
        if rank > len(ranked) or not free:
            results.append(ModeResult(rank, None, -1, Rate(0, per_group_b)))
            continue
        mode = ranked[rank - 1]
        score = np.array([sum(s.mode == mode for s in half_a[g]) for g in free])
        best = [g for g, v in zip(free, score) if v == score.max()]
        group = best[int(rng.integers(len(best)))]
        taken.add(group)
        results.append(ModeResult(rank, mode, group, Rate(sum(s.mode == mode for s in half_b[group]), len(half_b[group]))))
    return results


def pooled(per_object: Sequence[list[ModeResult]], rank: int) -> Rate:
    """Mode ``rank``'s SSR over objects: half-B successes and trials added up (equal weight per sample)."""
    total = Rate(0, 0)
    for results in per_object:
        total = total + results[rank - 1].rate
    return total
