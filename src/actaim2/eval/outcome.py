"""What one executed sample did to the object: success and its interaction mode (DoF, direction).

Success is the paper's criterion (:func:`actaim2.sim.success.dof_success`): some DoF moved by
more than 30 % of its range from ``dof_initial``. The outcome of a success is the DoF that moved
most (as a fraction of its range) and the sign of its motion: +1 towards the upper limit
(opening), -1 towards the lower one (closing). Mode SSR ranks these outcomes (``mode_ssr.py``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from actaim2.sim.success import SUCCESS_FRACTION, moved_fraction

NO_SAMPLE = "no sample"  # how a sample's note begins when its sampler found no action (episode.run_sample)


@dataclass(frozen=True)
class Outcome:
    success: bool
    largest_change: float  # max |DoF change| as a fraction of its range
    dof: str  # the DoF that moved most ("" when nothing moved)
    direction: int  # +1 opening, -1 closing, 0 when nothing moved
    fractions: dict[str, float]  # signed change of every DoF, fraction of its range
    initial: dict[str, float]  # where every DoF started, as a fraction of its range from the lower limit

    @property
    def mode(self) -> tuple[str, int] | None:
        """(DoF, direction) of a success, None for a failure."""
        return (self.dof, self.direction) if self.success else None


def measure(names: list[str], initial: np.ndarray, final: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> Outcome:
    """The outcome of moving the object's DoFs from ``initial`` to ``final``."""
    fractions = moved_fraction(initial, final, lower, upper)
    if len(fractions) == 0:
        return Outcome(False, 0.0, "", 0, {}, {})
    start = moved_fraction(lower, initial, lower, upper)
    k = int(np.argmax(np.abs(fractions)))
    largest = float(abs(fractions[k]))
    return Outcome(largest > SUCCESS_FRACTION, largest, names[k] if largest > 0 else "", int(np.sign(fractions[k])),
                   {n: round(float(f), 5) for n, f in zip(names, fractions)}, {n: round(float(f), 5) for n, f in zip(names, start)})
