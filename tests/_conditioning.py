"""Numerical references that involve a solver, checked for scaling before they are solved.

A reference solved by an iterative or simplex solver (scipy's HiGHS, a least-squares fit)
is only independent evidence when the problem is well scaled: a linear programme with
constraint coefficients of 1e-7 against costs of 1e5 was solved on one machine and
reported "numerical difficulties" (status 4) on another with the same scipy. Tests build
such references through the helpers here, which normalise nothing silently: they refuse a
badly scaled problem, so the test author scales it (in physical units that are O(1)).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linprog

#: largest allowed ratio between the largest and smallest non-zero magnitude of one array
#: of a linear programme, and the band in which those magnitudes must lie
MAX_DYNAMIC_RANGE = 1e4
MAGNITUDE_BAND = (1e-4, 1e4)

#: largest allowed 2-norm condition number of a least-squares design matrix
MAX_CONDITION_NUMBER = 1e8


def scaling_problems(**arrays) -> list[str]:
    """Descriptions of the arrays whose non-zero magnitudes are badly scaled (empty if none)."""
    problems = []
    low, high = MAGNITUDE_BAND
    for name, array in arrays.items():
        values = np.abs(np.asarray(array, dtype=float)).ravel()
        values = values[values > 0]
        if values.size == 0:
            continue
        smallest, largest = values.min(), values.max()
        if smallest < low or largest > high:
            problems.append(f"{name} has magnitudes in [{smallest:.3g}, {largest:.3g}], "
                            f"outside [{low:g}, {high:g}]")
        elif largest / smallest > MAX_DYNAMIC_RANGE:
            problems.append(f"{name} spans a dynamic range of {largest / smallest:.3g}")
    return problems


def well_scaled_linprog(c, A_ub, b_ub, bounds):
    """``scipy.optimize.linprog`` (HiGHS), after asserting that the problem is well scaled."""
    problems = scaling_problems(c=c, A_ub=A_ub, b_ub=b_ub)
    assert not problems, "reference linear programme badly scaled: " + "; ".join(problems)
    result = linprog(c=c, A_ub=A_ub, b_ub=b_ub, bounds=bounds, method="highs")
    assert result.success, f"reference linear programme not solved: {result.message}"
    return result


def condition_number(design) -> float:
    """2-norm condition number of a design matrix."""
    return float(np.linalg.cond(np.asarray(design, dtype=float)))


def well_conditioned_lstsq(design, target):
    """Least-squares solution of ``design @ x = target`` after checking the conditioning."""
    design = np.asarray(design, dtype=float)
    kappa = condition_number(design)
    assert kappa < MAX_CONDITION_NUMBER, f"least-squares design ill conditioned: {kappa:.3g}"
    solution, *_ = np.linalg.lstsq(design, np.asarray(target, dtype=float), rcond=None)
    return solution
