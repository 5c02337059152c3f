"""Binomial rates with 95 % Wilson score intervals: every SSR cell of the tables; and the
protocol's intervals by bootstrap over objects within category.

Wilson's interval (Wilson 1927; Newcombe 1998, method 3) keeps its coverage near 95 % for the
small counts and rates near 0 or 1 that evaluation cells have (8 objects x a few samples), where
the normal approximation gives intervals outside [0, 1] or of zero width at 0 successes.

Samples of one object are not independent (one geometry, one handle), so the protocol's
intervals resample objects, not samples: each bootstrap round draws, within every category, as
many of its objects as it has, with replacement (:func:`bootstrap_weights`), and recomputes the
statistic on them (percentile interval, 95 %). Seeds are pooled: an object's counts add up its
samples over every seed's run. :func:`paired_bootstrap` is the SSR difference of two methods on
the same scenes (ActAIM2 minus Data Collection): each object contributes the scenes both ran.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

Z95 = 1.959963984540054  # two-sided 95 % standard-normal quantile


def wilson_interval(successes: int, trials: int, z: float = Z95) -> tuple[float, float]:
    """(lower, upper) of the Wilson score interval; (0, 1) when there is no trial."""
    if trials < 0 or not 0 <= successes <= trials:
        raise ValueError(f"need 0 <= successes <= trials, got {successes} of {trials}")
    if trials == 0:
        return 0.0, 1.0
    p = successes / trials
    z2 = z * z
    centre = (p + z2 / (2 * trials)) / (1 + z2 / trials)
    half = z * math.sqrt(p * (1 - p) / trials + z2 / (4 * trials * trials)) / (1 + z2 / trials)
    return max(0.0, centre - half), min(1.0, centre + half)


@dataclass(frozen=True)
class Rate:
    """successes out of trials, with its Wilson interval."""

    successes: int
    trials: int

    @property
    def value(self) -> float:
        return self.successes / self.trials if self.trials else float("nan")

    @property
    def interval(self) -> tuple[float, float]:
        return wilson_interval(self.successes, self.trials)

    @property
    def half_width(self) -> float:
        """Half the interval's width: the "+-" figure a reader compares."""
        lo, hi = self.interval
        return (hi - lo) / 2

    def __add__(self, other: "Rate") -> "Rate":
        return Rate(self.successes + other.successes, self.trials + other.trials)

    def cell(self) -> str:
        """Markdown cell: percent and interval, e.g. ``48.6 [43.1-54.2]``; ``-`` without trials."""
        if not self.trials:
            return "-"
        lo, hi = self.interval
        return f"{100 * self.value:.1f} [{100 * lo:.1f}-{100 * hi:.1f}]"

    def to_json(self) -> dict:
        lo, hi = self.interval
        return {"successes": self.successes, "trials": self.trials, "rate": self.value if self.trials else None,
                "lower": lo, "upper": hi}


@dataclass(frozen=True)
class Estimate:
    """A difference of rates and its 95 % bootstrap percentile interval."""

    value: float
    lower: float
    upper: float

    @classmethod
    def of(cls, value: float, draws: np.ndarray) -> Estimate:
        lo, hi = np.nanpercentile(np.asarray(draws, float), [2.5, 97.5])
        return cls(float(value), float(lo), float(hi))

    def cell(self) -> str:
        """Markdown cell in percentage points, e.g. ``+8.1 [+2.3, +13.9]``."""
        return f"{100 * self.value:+.1f} [{100 * self.lower:+.1f}, {100 * self.upper:+.1f}]"


def bootstrap_weights(categories: Sequence[str], rounds: int,
                      rng: np.random.Generator) -> np.ndarray:
    """[rounds, objects]: how often each object is drawn when every category's objects are
    resampled with replacement, within the category (module docstring)."""
    if rounds < 1:
        raise ValueError(f"bootstrap rounds must be >= 1, got {rounds}")
    cats = np.asarray(categories)
    weights = np.zeros((rounds, len(cats)))
    for category in sorted(set(cats.tolist())):
        members = np.flatnonzero(cats == category)
        draws = rng.integers(len(members), size=(rounds, len(members)))
        weights[:, members] = (draws[:, :, None] == np.arange(len(members))).sum(axis=1)
    return weights


def pooled_and_macro(weights: np.ndarray, counts: np.ndarray,
                     categories: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """Rate of method A minus rate of method B, pooled over objects and as the mean over categories
    of each category's pooled difference; [rounds, tables] each.

    ``weights``: [rounds, objects] (ones for the point estimate); ``counts``: [4, tables, objects]:
    successes and trials of A, successes and trials of B, per object, in each of several tables
    (e.g. halvings). A round whose drawn objects have no trial gives NaN."""
    cats = np.asarray(categories)

    def difference(mask: np.ndarray) -> np.ndarray:
        sa, na, sb, nb = (weights[:, mask] @ counts[k][:, mask].T for k in range(4))
        with np.errstate(divide="ignore", invalid="ignore"):
            return sa / na - sb / nb

    pooled = difference(np.ones(len(cats), bool))
    with np.errstate(invalid="ignore"):
        macro = np.mean([difference(cats == c) for c in sorted(set(cats.tolist()))], axis=0)
    return pooled, macro


@dataclass(frozen=True)
class PairedCounts:
    """One object's scenes run by both methods, its seeds pooled."""

    category: str
    scenes: int
    successes_a: int
    successes_b: int

    def __post_init__(self) -> None:
        if not (0 <= self.successes_a <= self.scenes and 0 <= self.successes_b <= self.scenes):
            raise ValueError(f"successes must be within 0..{self.scenes} scenes, got "
                             f"{self.successes_a}, {self.successes_b}")


@dataclass(frozen=True)
class RateDifference:
    """A rate of method A minus method B, pooled over samples and as the category macro-average."""

    pooled: Estimate
    macro: Estimate

    @property
    def above_zero(self) -> bool:
        """Both lower bounds above 0: A beats B."""
        return self.pooled.lower > 0 and self.macro.lower > 0


def paired_bootstrap(objects: Sequence[PairedCounts], rounds: int = 2000,
                     seed: int = 0) -> RateDifference:
    """The paired SSR difference and its intervals by bootstrap over objects within category."""
    if not objects or not any(o.scenes for o in objects):
        raise ValueError("no paired scene to compare")
    counts = np.array([[[o.successes_a for o in objects]], [[o.scenes for o in objects]],
                       [[o.successes_b for o in objects]], [[o.scenes for o in objects]]], float)
    cats = [o.category for o in objects]
    point_pooled, point_macro = pooled_and_macro(np.ones((1, len(objects))), counts, cats)
    weights = bootstrap_weights(cats, rounds, np.random.default_rng(seed))
    draws_pooled, draws_macro = pooled_and_macro(weights, counts, cats)
    return RateDifference(Estimate.of(point_pooled[0, 0], draws_pooled[:, 0]),
                            Estimate.of(point_macro[0, 0], draws_macro[:, 0]))
