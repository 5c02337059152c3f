"""The paper's success criterion: some degree of freedom moved by more than 30% of its range.

Privileged (it reads the object's joint state): used to evaluate policies and to check the
visual success labels, never as a policy input.
"""
from __future__ import annotations

import numpy as np

SUCCESS_FRACTION = 0.3


def moved_fraction(initial: np.ndarray, current: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Signed change of each DoF as a fraction of its range (a DoF without range never moves)."""
    span = np.asarray(upper, float) - np.asarray(lower, float)
    delta = np.asarray(current, float) - np.asarray(initial, float)
    return np.where(span > 1e-9, delta / np.where(span > 1e-9, span, 1.0), 0.0)


def dof_success(initial: np.ndarray, current: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                fraction: float = SUCCESS_FRACTION) -> bool:
    """True iff some DoF moved (either way) by more than ``fraction`` of its range."""
    return bool(np.any(np.abs(moved_fraction(initial, current, lower, upper)) > fraction))
