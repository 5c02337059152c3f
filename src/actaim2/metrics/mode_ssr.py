"""Mode SSR with a split-half cluster choice (paper Table 2 and its appendix table of 3rd/4th modes).

For one object, a method executed samples from each of its groups: the clusters of ActAIM2, the
codes of VQVAE-RVT, the goals of Goal-RVT, or random pseudo-clusters of a sampler's samples.
The outcome of a successful sample is (DoF, direction) (``outcome.py``).

  1. Every sample is in half A or half B: by default A holds the even repetition indices of each
     group and B the odd ones; a random halving (:func:`random_half_a`) puts a random half of
     each group's repetitions (rounded up) in A.
  2. Modes are the outcomes ranked by their frequency over the successful samples of half A only
     (ties: by name, so the order is fixed): half B decides nothing, it only measures.
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

Comparing two methods on one mode (:func:`halving_rule`): one halving is one draw of luck, so
the difference of the mode's SSR (method A minus method B, each halved independently) is
averaged over many random halvings; its interval comes from resampling objects within their
category (``stats.bootstrap_weights``) with every halving recomputed on the same draws. The
rule holds when the interval's lower bound is above 0 and the difference is positive in at least
``POSITIVE_SHARE`` of the halvings.
"""
from __future__ import annotations

import zlib
from collections import Counter
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from actaim2.metrics.stats import (
    Estimate,
    Rate,
    RateDifference,
    bootstrap_weights,
    pooled_and_macro,
)

Mode = tuple[str, int]  # (DoF, direction)
HALVINGS = 100  # random halvings the comparison is averaged over, at least
POSITIVE_SHARE = 0.9  # share of halvings in which the difference must be positive


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


def random_half_a(samples: Sequence[GroupSample],
                  rng: np.random.Generator) -> set[tuple[int, int]]:
    """(group, repetition) of the samples a random halving puts in half A: a random half of each
    group's repetitions, rounded up (as the even indices are)."""
    out: set[tuple[int, int]] = set()
    for g in sorted({s.group for s in samples}):
        reps = sorted(s.repetition for s in samples if s.group == g)
        chosen = rng.permutation(len(reps))[: (len(reps) + 1) // 2]
        out |= {(g, reps[k]) for k in chosen}
    return out


def object_mode_ssr(samples: Sequence[GroupSample], modes: int, tie_key: str,
                    half_a: set[tuple[int, int]] | None = None) -> list[ModeResult]:
    """Mode SSR of modes 1..``modes`` on one object; ``tie_key`` (e.g. method/object) seeds the tie
    breaks; ``half_a``: the (group, repetition) in half A (None: the even repetitions)."""
    in_a = [(s.group, s.repetition) in half_a if half_a is not None else s.repetition % 2 == 0
            for s in samples]
    groups = sorted({s.group for s in samples})
    half_b = {g: [s for s, a in zip(samples, in_a) if s.group == g and not a] for g in groups}
    half_a_samples = {g: [s for s, a in zip(samples, in_a) if s.group == g and a] for g in groups}
    per_group_b = int(round(np.mean([len(v) for v in half_b.values()]))) if groups else 0
    rng = np.random.default_rng(zlib.crc32(tie_key.encode()))
    ranked = rank_modes([s for s, a in zip(samples, in_a) if a])
    taken: set[int] = set()
    results = []
    for rank in range(1, modes + 1):
        free = [g for g in groups if g not in taken]
        if rank > len(ranked) or not free:
            results.append(ModeResult(rank, None, -1, Rate(0, per_group_b)))
            continue
        mode = ranked[rank - 1]
        score = np.array([sum(s.mode == mode for s in half_a_samples[g]) for g in free])
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


@dataclass(frozen=True)
class HalvingComparison:
    """Mode ``rank``'s SSR of method A minus method B, averaged over random halvings."""

    rank: int
    halvings: int
    difference: RateDifference  # averaged over the halvings; intervals over objects in category
    positive_share: float  # halvings whose pooled difference is above 0

    @property
    def holds(self) -> bool:
        """The rule: lower bounds above 0 and positive in at least ``POSITIVE_SHARE`` of the
        halvings."""
        return self.difference.above_zero and self.positive_share >= POSITIVE_SHARE


Runs = Sequence[Sequence[GroupSample]]  # an object's samples in each seed's run


def halving_rule(a: Mapping[str, Runs], b: Mapping[str, Runs], categories: Mapping[str, str],
                 rank: int = 2, halvings: int = HALVINGS, rounds: int = 2000,
                 seed: int = 0) -> HalvingComparison:
    """Compare method A's and method B's mode ``rank`` on the objects both ran, as the module
    docstring says. ``a``, ``b``: object -> its samples in each seed's run (each run is chosen
    and scored on its own, its half-B counts added up: seeds pooled); ``categories``: object ->
    category."""
    if halvings < HALVINGS:
        raise ValueError(f"{halvings} halvings: the rule averages over at least {HALVINGS}")
    objects = sorted(set(a) & set(b))
    if not objects:
        raise ValueError("the two methods share no object")
    rng = np.random.default_rng(seed)
    counts = np.zeros((4, halvings, len(objects)))  # successes A, trials A, successes B, trials B
    for h in range(halvings):
        for k, obj in enumerate(objects):
            for row, (name, runs) in enumerate((("a", a[obj]), ("b", b[obj]))):
                for r, samples in enumerate(runs):
                    half_a = random_half_a(samples, rng)
                    key = f"{name}|{obj}|{r}|{h}"
                    rate = object_mode_ssr(samples, rank, key, half_a)[rank - 1].rate
                    counts[2 * row:2 * row + 2, h, k] += rate.successes, rate.trials
    cats = [categories[o] for o in objects]
    # [1, halvings] each, then [rounds, halvings] each
    diff_pooled, diff_macro = pooled_and_macro(np.ones((1, len(objects))), counts, cats)
    weights = bootstrap_weights(cats, rounds, rng)
    boot_pooled, boot_macro = pooled_and_macro(weights, counts, cats)
    pooled = Estimate.of(float(np.mean(diff_pooled)), np.nanmean(boot_pooled, axis=1))
    macro = Estimate.of(float(np.mean(diff_macro)), np.nanmean(boot_macro, axis=1))
    return HalvingComparison(rank, halvings, RateDifference(pooled, macro),
                             float(np.mean(diff_pooled[0] > 0)))
