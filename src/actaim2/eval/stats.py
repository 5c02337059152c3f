"""Binomial rates with 95 % Wilson score intervals: every SSR cell of the tables.

Wilson's interval (Wilson 1927; Newcombe 1998, method 3) keeps its coverage near 95 % for the
small counts and rates near 0 or 1 that evaluation cells have (8 objects x a few samples), where
the normal approximation gives intervals outside [0, 1] or of zero width at 0 successes.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

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
