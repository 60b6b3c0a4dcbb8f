"""Danjon L from Vital's correlation, the linear proxy, and the verbal-class cross-check.

References (published numbers, not the formula in the code):
- Vital, 2019-01-21 report: L = 2.4 -> m = -1.56 (worked example).
- Vital, 2010-12-21 report: L = 2.4 +- 0.4 -> m ~ -1.6.
- Vital, 2008-02-21 report: predicted L = 3.0 +- 0.4 and m = -2.6 +- 0.4.
- issue 15 (from Vital's predictions): L = 2.6 -> m = -2.0.
The printed magnitudes are rounded to 0.1 mag (two decimals for -1.56); the L tolerance
below is what a 0.1 mag rounding costs in L (dL/dm is at most 0.63 per mag between m = -2.6
and -1.5) plus the 0.05 the L themselves are rounded to.
"""

from __future__ import annotations

import pytest
import torch

from skytorch.eclipse import danjon_class_l, danjon_l, danjon_l_linear
from skytorch.eclipse.danjon import DANJON_V_RANGE, vital_magnitude

# (L, m) published by Vital, and the half-width of the last printed digit of m [mag]
WORKED = [(2.4, -1.56, 0.005), (2.4, -1.6, 0.05), (3.0, -2.6, 0.05), (2.6, -2.0, 0.05)]


@pytest.mark.parametrize("level, magnitude, rounding", WORKED)
def test_vital_worked_examples(level, magnitude, rounding):
    # L from the published magnitude: within the L the rounding of m allows (+0.1 L for
    # the prediction L = 2.6 -> -2.0, which is 0.09 mag off the relation; see below)
    got = float(danjon_l(magnitude))
    slope = 1.0 / (4.8 + magnitude) ** 0.5
    assert abs(got - level) <= slope * rounding + 0.1
    # and the forward relation gives the published magnitude to within 0.1 mag
    assert abs(float(vital_magnitude(level)) - magnitude) <= 0.1


def test_worked_example_fixes_the_sign():
    # with the sign lost in the 2019 text (+3 L) L = 2.4 would be m = +12.8, not -1.56
    assert float(vital_magnitude(2.4)) == pytest.approx(-1.56, abs=0.005)
    assert float(danjon_l(-1.56)) == pytest.approx(2.4, abs=0.005)


def test_range_ends_and_monotonic():
    assert DANJON_V_RANGE == pytest.approx((-3.8, 4.2))
    ends = danjon_l(torch.tensor(DANJON_V_RANGE, dtype=torch.float64))
    assert ends.tolist() == pytest.approx([4.0, 0.0], abs=1e-12)
    grid = torch.linspace(-3.8, 4.2, 81, dtype=torch.float64)
    level = danjon_l(grid)
    assert bool((level.diff() < 0).all())
    # round trip through the forward relation
    assert torch.allclose(vital_magnitude(level), grid, atol=1e-12)


def test_outside_range_raises_or_nan():
    with pytest.raises(ValueError, match=r"v_magnitude must be in \[-3\.8, 4\.2\]"):
        danjon_l(-4.5)
    with pytest.raises(ValueError, match="v_magnitude"):
        danjon_l(torch.tensor([0.0, 5.0]))
    with pytest.raises(ValueError, match="finite"):
        danjon_l(float("nan"))
    with pytest.raises(ValueError, match="outside"):
        danjon_l(0.0, outside="clip")
    values = danjon_l(torch.tensor([-4.5, -1.56, 5.0]), outside="nan")
    assert torch.isnan(values[[0, 2]]).all() and float(values[1]) == pytest.approx(2.4, abs=1e-3)
    with pytest.raises(ValueError, match="danjon_l"):
        vital_magnitude(4.5)


def test_uncertainty_returned():
    level, sigma = danjon_l(torch.tensor([-2.8, -1.5]), return_uncertainty=True)
    assert sigma.tolist() == pytest.approx([0.4, 0.4]) and level.shape == sigma.shape
    assert sigma.dtype == level.dtype == torch.float32


def test_gradcheck():
    v = torch.tensor([-3.7, -2.2, 0.0, 4.1], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(danjon_l, (v,))
    # dL/dm = -1 at m = -3.8 (L = 4), -1/3 at m = 4.2 (L = 0): finite at the ends
    ends = torch.tensor([-3.8, 4.2], dtype=torch.float64, requires_grad=True)
    danjon_l(ends).sum().backward()
    assert ends.grad.tolist() == pytest.approx([-1.0, -1.0 / 3.0])


def test_nan_members_keep_finite_gradient():
    v = torch.tensor([-5.0, -1.0], dtype=torch.float64, requires_grad=True)
    danjon_l(v, outside="nan")[1].backward()
    assert torch.isfinite(v.grad).all() and v.grad[0] == 0.0


def test_linear_proxy_anchors():
    values = danjon_l_linear(torch.tensor([3.0, 2.0, -0.65, -3.3, -5.0]))
    assert torch.allclose(values, torch.tensor([0.0, 0.0, 2.0, 4.0, 4.0], dtype=values.dtype))


def test_old_import_paths():
    from skytorch.eclipse.lunar import DANJON_ANCHORS, DANJON_RELATION
    from skytorch.eclipse.lunar import danjon_l as from_lunar
    assert from_lunar is danjon_l and DANJON_ANCHORS == ((0.0, 2.0), (4.0, -3.3))
    assert "Vital" in DANJON_RELATION


@pytest.mark.parametrize("centre, rim, colour, expected, words", [
    (5.0, 2.0, 1.6, 0, "very dark, almost invisible (fainter than m(L=0))"),
    (2.5, 3.0, 1.6, 1, "dark, little rim contrast"),
    (3.0, 30.0, 1.8, 2, "very dark centre, relatively bright outer edge"),
    (-1.6, 3.0, 1.2, 2, "centre at Vital's L = 2.4"),
    (-2.6, 3.0, 1.0, 3, "brick red, bright rim"),
    (-3.9, 3.0, 0.5, 4, "very bright, bluish rim"),
    (-3.9, 3.0, 1.5, 3, "very bright centre but a yellow/red rim: 3"),
])
def test_verbal_classes_on_clear_cases(centre, rim, colour, expected, words):
    assert float(danjon_class_l(centre, rim, colour)) == expected, words


def test_verbal_classes_batched_and_checked():
    classes = danjon_class_l(torch.tensor([5.0, -3.9]), torch.tensor([2.0, 3.0]), 0.5)
    assert classes.tolist() == [0.0, 4.0]
    with pytest.raises(ValueError, match="rim_to_centre"):
        danjon_class_l(0.0, 0.0, 1.0)


def test_class_l_refuses_mismatched_shapes_and_a_gradient():
    """A class carries no gradient (it was dropped); shapes are checked by name."""
    with pytest.raises(ValueError, match=r"centre_v_magnitude \(3,\), rim_to_centre \(2,\)"):
        danjon_class_l(torch.zeros(3), torch.ones(2), 1.0)
    with pytest.raises(ValueError, match="centre_v_magnitude requires a gradient"):
        danjon_class_l(torch.tensor(-3.9, requires_grad=True), 3.0, 0.5)
