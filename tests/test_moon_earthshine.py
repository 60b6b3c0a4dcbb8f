"""Earthshine: Müller et al. (2012) eq. 4 and the physical Lambert-Earth model."""

from __future__ import annotations

import math

import numpy as np
import torch

from skytorch.moon import earthshine as es


def test_lambert_phase_integral_is_three_halves():
    """Russell (1916): a Lambert sphere has phase integral q = 2∫Φ sin a da = 3/2 (A = p q)."""
    x, w = np.polynomial.legendre.leggauss(64)
    a = torch.tensor(0.5 * math.pi * (x + 1.0))
    q = 2 * float((0.5 * math.pi * torch.tensor(w) * es.lambert_phase_function(a)
                   * torch.sin(a)).sum())
    assert abs(q - 1.5) < 1e-10


def test_physical_earthshine_new_moon():
    """New Moon: E_earth/E_sun = (2A/3)(R_E/d)² = 5.4e-5 for A = 0.297."""
    ratio = float(es.earthshine_irradiance_ratio(torch.tensor(math.pi, dtype=torch.float64)))
    assert abs(ratio - 2 / 3 * 0.297 * (6371.0 / 384400.0) ** 2) < 1e-12
    assert abs(float(es.earthshine_irradiance_ratio(torch.tensor(0.0)))) < 1e-15


def test_muller_polynomial_shape_vs_physical():
    """Both peak at new Moon; normalised shapes differ by < 0.08 (measured 0.069 at 90°)."""
    phi = torch.linspace(0.5, math.pi, 50, dtype=torch.float64)
    muller = es.earthshine_muller2012(phi)
    physical = es.earthshine_irradiance_ratio(phi)
    assert int(torch.argmax(muller)) == 49 and int(torch.argmax(physical)) == 49
    shape_difference = muller / muller[-1] - physical / physical[-1]
    assert float(shape_difference.abs().max()) < 0.08
    # published value at new Moon: −0.0061 π³ + 0.0289 π²
    assert abs(float(muller[-1]) - (-0.0061 * math.pi**3 + 0.0289 * math.pi**2)) < 1e-12
