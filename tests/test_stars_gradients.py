"""Gradients of star photometry at hard cases, against finite differences and closed forms.

Extinction is differentiated through the altitude table lookup at the horizon (where the
table starts, so the reference is a one-sided difference), just above it and at the
zenith; the scintillation index and the relative brightness have closed-form derivatives.
"""

from __future__ import annotations

import math

import pytest
import torch
from torch.autograd import gradcheck

from skytorch.stars.photometry import extinction, extinction_table, relative_brightness
from skytorch.stars.scintillation import scintillation_index


@pytest.fixture(scope="module")
def table():
    from skytorch.atmosphere import Atmosphere

    return extinction_table(Atmosphere.earth(), 0.0, refraction=True)


def _delta_m(table, altitude: float, bv: float = 0.65) -> float:
    dm, _ = extinction(torch.tensor([bv], dtype=torch.float64),
                       torch.tensor([[altitude]], dtype=torch.float64), table)
    return float(dm)


def test_extinction_gradient_at_the_horizon_is_the_one_sided_derivative(table):
    """Differentiate at h = 0, the first table node (below it the horizon value is held).

    The gradient is the slope from above: a second-order forward difference, h = 1e-9 rad.
    """
    altitude = torch.zeros(1, 1, dtype=torch.float64, requires_grad=True)
    dm, _ = extinction(torch.tensor([0.65], dtype=torch.float64), altitude, table)
    (gradient,) = torch.autograd.grad(dm.sum(), altitude)
    h = 1e-9
    reference = (-3 * _delta_m(table, 0.0) + 4 * _delta_m(table, h)
                 - _delta_m(table, 2 * h)) / (2 * h)
    assert reference < -100.0  # [mag/rad]: extinction falls steeply above the horizon
    assert abs(float(gradient) - reference) < 1e-4 * abs(reference)


def test_extinction_gradient_matches_central_differences(table):
    """Just above the horizon, at 30° and next to the zenith (inside table cells)."""
    altitude = torch.tensor([[1e-6, 0.5236, math.pi / 2 - 1e-3]], dtype=torch.float64,
                            requires_grad=True)
    bv = torch.tensor([0.65, -0.2, 1.8], dtype=torch.float64, requires_grad=True)
    assert gradcheck(lambda h, c: extinction(c, h, table)[0], (altitude, bv), eps=1e-10,
                     atol=1e-6, rtol=1e-5)


def test_extinction_colour_gradient_is_the_colour_term(table):
    """Δm = A(h) + B(h) (B−V): ∂Δm/∂(B−V) is the table's colour term B at the node."""
    bv = torch.tensor([0.65], dtype=torch.float64, requires_grad=True)
    dm, _ = extinction(bv, torch.zeros(1, 1, dtype=torch.float64), table)
    (gradient,) = torch.autograd.grad(dm.sum(), bv)
    assert float(gradient) == pytest.approx(float(table["colour"][0]), rel=1e-12)


@pytest.mark.parametrize(("model", "exponent"), [("young1967", 3.5), ("osborn2015", 3.0)])
def test_scintillation_gradient_at_zenith_and_horizon(model, exponent):
    """σ_I² ∝ X^p: ∂σ_I²/∂X = p σ_I² / X at X = 1 (zenith) and X = 40 (horizon)."""
    airmass = torch.tensor([1.0, 40.0], dtype=torch.float64, requires_grad=True)
    value = scintillation_index(airmass, model=model)
    (gradient,) = torch.autograd.grad(value.sum(), airmass)
    torch.testing.assert_close(gradient, exponent * value.detach() / airmass.detach(),
                               rtol=1e-12, atol=0.0)


def test_relative_brightness_gradient():
    """∂/∂m 10^(0.4 (m_a − m)) = −0.4 ln 10 · 10^(0.4 (m_a − m)), for bright and faint."""
    magnitude = torch.tensor([-1.5, 6.0, 30.0], dtype=torch.float64, requires_grad=True)
    value = relative_brightness(magnitude, 6.0)
    (gradient,) = torch.autograd.grad(value.sum(), magnitude)
    torch.testing.assert_close(gradient, -0.4 * math.log(10.0) * value.detach(), rtol=1e-12,
                               atol=0.0)
