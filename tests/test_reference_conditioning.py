"""Solver-based references in the tests are well scaled (a fresh machine solves them too)."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
from _conditioning import (
    condition_number,
    scaling_problems,
    well_conditioned_lstsq,
    well_scaled_linprog,
)

TESTS = Path(__file__).parent

#: solver entry points that tests may reach only through the helpers of _conditioning
SOLVERS = {"linprog", "milp", "minimize", "least_squares", "nnls", "curve_fit", "lstsq",
           "fsolve", "root"}


def _solver_calls(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
            if name in SOLVERS:
                found.append(f"{path.name}:{node.lineno} {name}")
    return found


def test_tests_call_solvers_only_through_the_conditioning_helpers():
    calls = [call for path in sorted(TESTS.glob("*.py")) if path.name != "_conditioning.py"
             for call in _solver_calls(path)]
    assert calls == [], "solver called directly (use tests/_conditioning.py): " + ", ".join(calls)


def test_the_scan_finds_a_direct_solver_call(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text("from scipy.optimize import linprog\nlinprog(c=[1.0])\n")
    assert _solver_calls(sample) == ["sample.py:2 linprog"]


def test_badly_scaled_programme_is_refused():
    # the scale of the LP that HiGHS failed on: luminances of 1e-7 cd/m2, costs of 1e5 lm
    problems = scaling_problems(c=[2e5, 8e5], A_ub=[[-3e-7, -1e-7]], b_ub=[-2e-7])
    assert [problem.split()[0] for problem in problems] == ["c", "A_ub", "b_ub"]
    with pytest.raises(AssertionError, match="badly scaled"):
        well_scaled_linprog([2e5, 8e5], [[-3e-7, -1e-7]], [-2e-7], [(0, 1)] * 2)


def test_well_scaled_programme_is_solved_exactly():
    # minimise x + 2y subject to x + y >= 1, 0 <= x, y <= 1: optimum x = 1, y = 0
    result = well_scaled_linprog([1.0, 2.0], [[-1.0, -1.0]], [-1.0], [(0, 1)] * 2)
    assert result.fun == pytest.approx(1.0, abs=1e-12)


def test_least_squares_refuses_an_ill_conditioned_design():
    x = np.linspace(1.0, 1.0 + 1e-10, 5)
    design = np.stack([x, np.ones_like(x)], axis=1)
    assert condition_number(design) > 1e8
    with pytest.raises(AssertionError, match="ill conditioned"):
        well_conditioned_lstsq(design, x)
    fit = well_conditioned_lstsq(np.stack([np.arange(5.0), np.ones(5)], axis=1),
                                 2.0 * np.arange(5.0) + 3.0)
    np.testing.assert_allclose(fit, [2.0, 3.0], atol=1e-12)
