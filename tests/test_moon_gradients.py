"""Gradients of the Moon's photometry and geometry at hard cases, against finite differences.

The references are finite differences of the same functions in float64 (central where the
function is defined on both sides, second-order one-sided at the end of the phase range)
and closed forms where they exist (the inverse-square laws of the magnitude).
"""

from __future__ import annotations

import math

import torch
from torch.autograd import gradcheck

import skytorch as st

N_QUADRATURE = 24
LN10 = math.log(10.0)


def _magnitude(alpha: float, **kwargs) -> float:
    return float(st.moon.magnitude(torch.tensor(alpha, dtype=torch.float64),
                                   n_quadrature=N_QUADRATURE, **kwargs))


def _gradient(alpha: float, **kwargs) -> float:
    a = torch.tensor(alpha, dtype=torch.float64, requires_grad=True)
    (g,) = torch.autograd.grad(st.moon.magnitude(a, n_quadrature=N_QUADRATURE, **kwargs), a)
    return float(g)


def test_magnitude_gradient_matches_central_differences():
    alpha = torch.tensor([0.3, math.pi / 2, 2.5, 3.0], dtype=torch.float64,
                         requires_grad=True)
    assert gradcheck(lambda a: st.moon.magnitude(a, n_quadrature=N_QUADRATURE), (alpha,),
                     eps=1e-6, atol=1e-6, rtol=1e-5)


def test_magnitude_gradient_at_new_moon_is_the_one_sided_derivative():
    """α = π (new Moon, earthshine only): |α| ≤ π, so the reference is one-sided.

    Second-order backward differences converge to 4.538e-4 mag/rad (h = 1e-3 … 3e-5).
    """
    h = 3e-5
    x = math.pi
    reference = (3 * _magnitude(x) - 4 * _magnitude(x - h) + _magnitude(x - 2 * h)) / (2 * h)
    assert abs(_gradient(x) - reference) < 1e-6  # [mag/rad], the gradient is 4.5e-4
    # and the same just inside the range, against central differences
    x = math.pi - 1e-3
    central = (_magnitude(x + 1e-6) - _magnitude(x - 1e-6)) / 2e-6
    assert abs(_gradient(x) - central) < 1e-6


def test_magnitude_gradient_at_full_moon():
    """m(α) = m(|α|) has a cusp at α = 0 (the opposition surge: slope ±5.39 mag/rad).

    Exactly at 0 the gradient is 0, the central difference (the mean of the one-sided
    slopes); just beside it, it is the one-sided slope.
    """
    assert _gradient(0.0) == 0.0
    assert abs((_magnitude(1e-7) - _magnitude(-1e-7)) / 2e-7) < 1e-9
    x = 1e-4
    central = (_magnitude(x + 1e-7) - _magnitude(x - 1e-7)) / 2e-7
    assert abs(_gradient(x) - central) < 1e-5
    assert 5.0 < _gradient(x) < 5.8


def test_magnitude_distance_gradients_follow_the_inverse_square_laws():
    """Without earthshine m = const + 5 log10 d + 5 log10 d_sun: ∂m/∂d = 5 / (d ln 10)."""
    d = torch.tensor([3.6e8, 4.05e8], dtype=torch.float64, requires_grad=True)
    d_sun = torch.tensor(1.47e11, dtype=torch.float64, requires_grad=True)
    alpha = torch.tensor([0.0, math.pi / 2], dtype=torch.float64)
    m = st.moon.magnitude(alpha, distance_m=d, sun_distance_m=d_sun, earthshine=False,
                          n_quadrature=N_QUADRATURE)
    g_d, g_sun = torch.autograd.grad(m.sum(), (d, d_sun))
    torch.testing.assert_close(g_d, 5.0 / (d.detach() * LN10), rtol=1e-12, atol=0.0)
    torch.testing.assert_close(g_sun, 2 * 5.0 / (d_sun.detach() * LN10), rtol=1e-12,
                               atol=0.0)
    module = st.moon.MoonPhotometry(n_quadrature=N_QUADRATURE, earthshine=False)
    (g_module,) = torch.autograd.grad(module(alpha, d).sum(), d)
    torch.testing.assert_close(g_module, 5.0 / (d.detach() * LN10), rtol=1e-12, atol=0.0)


def test_phase_angle_gradient_near_alignment():
    """Near full and new Moon (1e-6 rad from alignment) against central differences."""
    moon = torch.tensor([3.844e8, 0.0, 0.0], dtype=torch.float64)
    for angle in (1e-6, math.pi - 1e-6):
        # the Sun seen from the Moon at `angle` from the direction to the Earth
        direction = torch.tensor([-math.cos(angle), math.sin(angle), 0.0],
                                 dtype=torch.float64)
        sun = (moon + 1.496e11 * direction).requires_grad_(True)
        assert gradcheck(lambda s: st.moon.phase_angle(s, moon), (sun,), eps=1e3,
                         atol=1e-16, rtol=1e-6)  # [rad/m]; the gradient is 6.7e-12
