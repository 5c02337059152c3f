"""Wilson intervals against published values (Newcombe 1998, Table I, method 3) and edge cases."""
from __future__ import annotations

import pytest

from actaim2.metrics.stats import Rate, wilson_interval


@pytest.mark.parametrize("successes, trials, lower, upper", [
    (81, 263, 0.2553, 0.3662),
    (15, 148, 0.0624, 0.1605),
    (0, 20, 0.0, 0.1611),
    (1, 29, 0.0061, 0.1718),
    (29, 29, 0.8830, 1.0),
])
def test_wilson_matches_newcombe(successes: int, trials: int, lower: float, upper: float) -> None:
    lo, hi = wilson_interval(successes, trials)
    assert lo == pytest.approx(lower, abs=5e-5)
    assert hi == pytest.approx(upper, abs=5e-5)


def test_wilson_edges_and_errors() -> None:
    assert wilson_interval(0, 0) == (0.0, 1.0)
    with pytest.raises(ValueError):
        wilson_interval(3, 2)
    lo, hi = wilson_interval(5, 10)
    assert lo + hi == pytest.approx(1.0)  # symmetric at p = 0.5


def test_rate_pooling_and_cell() -> None:
    r = Rate(3, 10) + Rate(2, 10)
    assert (r.successes, r.trials, r.value) == (5, 20, 0.25)
    assert r.cell().startswith("25.0 [")
    assert Rate(0, 0).cell() == "-"
    assert r.half_width == pytest.approx((r.interval[1] - r.interval[0]) / 2)
