"""Moonlit sky: Krisciunas & Schaefer (1991) model and single scattering of moonlight."""

from __future__ import annotations

import math

import pytest
import torch

from skytorch.constants import CANDELA_PER_M2_AT_ZERO_MAG_ARCSEC2, DEGREE, PERCENT
from skytorch.moon import sky


def test_nanolambert_conversion_matches_falchi():
    """K&S eq. 1 vs the independent relation L = 10.8e4 · 10^(−0.4 m) cd/m² (Falchi 2016)."""
    v = torch.tensor([16.0, 18.0, 20.0, 22.0], dtype=torch.float64)
    candela = sky.mag_arcsec2_to_nanolambert(v) * sky.NANOLAMBERT_CD_M2
    falchi = CANDELA_PER_M2_AT_ZERO_MAG_ARCSEC2 * 10 ** (-0.4 * v)
    assert torch.allclose(candela, falchi, rtol=1 * PERCENT)
    assert torch.allclose(sky.nanolambert_to_mag_arcsec2(sky.mag_arcsec2_to_nanolambert(v)), v)


def test_ks1991_model_by_hand():
    """Eq. 15–21 evaluated with plain floats: α = 30°, ρ = 45°, Z_m = 40°, Z = 20°, k = 0.172."""
    alpha, rho, zm, z, k = 30.0, 45.0, 40.0, 20.0, 0.172
    f = 10**5.36 * (1.06 + math.cos(math.radians(rho)) ** 2) + 10 ** (6.15 - rho / 40)
    illuminance = 10 ** (-0.4 * (3.84 + 0.026 * alpha + 4e-9 * alpha**4))
    airmass = lambda zz: (1 - 0.96 * math.sin(math.radians(zz)) ** 2) ** -0.5  # noqa: E731
    expected = f * illuminance * 10 ** (-0.4 * k * airmass(zm)) * (1 - 10 ** (-0.4 * k * airmass(z)))
    b = sky.moonlit_sky_ks1991(torch.tensor(alpha * DEGREE, dtype=torch.float64),
                               torch.tensor(rho * DEGREE, dtype=torch.float64),
                               torch.tensor(zm * DEGREE, dtype=torch.float64),
                               torch.tensor(z * DEGREE, dtype=torch.float64), k)
    assert abs(float(b) / expected - 1) < 1e-12
    assert abs(float(sky.airmass_ks1991(torch.tensor(math.pi / 2, dtype=torch.float64))) - 5) < 1e-9


def test_ks1991_hard_cases(dtype):
    """Moon at the zenith, sky point at the horizon, separation 0 and 180°: finite."""
    b = sky.moonlit_sky_ks1991(torch.tensor([0.0, math.pi], dtype=dtype),
                               torch.tensor([0.0, math.pi], dtype=dtype),
                               torch.tensor([0.0, math.pi / 2], dtype=dtype),
                               torch.tensor([math.pi / 2, 0.0], dtype=dtype))
    assert b.dtype == dtype and torch.isfinite(b).all() and (b > 0).all()
    with pytest.raises(ValueError, match="zenith_rad"):
        sky.moonlit_sky_ks1991(0.0, 1.0, 0.1, 2.0)


def test_single_scattering_pure_rayleigh_plane_parallel():
    """Molecules only (ϖ = 1), view at zenith: the plane-parallel closed form.

    L = E P(θ)/μv e^{−τ/μv} [1 − e^{−τ(1/μm − 1/μv)}] / (1/μm − 1/μv),
    which the spherical line-of-sight integral must match to within curvature (< 1 %).
    """
    from skytorch.atmosphere import Atmosphere
    from skytorch.atmosphere.scattering import rayleigh_phase
    from skytorch.moon.brightness import lunar_irradiance

    atm = Atmosphere.earth(turbidity=1.0, ozone_du=0.0)
    wl = torch.tensor([450.0, 550.0, 650.0], dtype=torch.float64)
    alpha = torch.tensor(20.0 * DEGREE, dtype=torch.float64)
    zm = torch.tensor(40.0 * DEGREE, dtype=torch.float64)
    radiance = sky.moonlit_sky_single_scattering(atm, alpha, zm, torch.tensor(0.0), torch.tensor(0.0),
                                                 wl, n_steps=400)
    tau = atm.optical_depth(wl, zenith_rad=0.0)
    mu_m, mu_v = math.cos(float(zm)), 1.0
    c = 1 / mu_m - 1 / mu_v
    closed = (lunar_irradiance(alpha, wl) * rayleigh_phase(torch.cos(zm)) / mu_v
              * torch.exp(-tau / mu_v) * -torch.expm1(-tau * c) / c)
    assert torch.allclose(radiance, closed, rtol=1 * PERCENT)


def test_single_scattering_vs_ks1991_is_lower_bound():
    """Single scattering omits multiple scattering: fainter than K&S, by less than 1.5 mag."""
    from skytorch.atmosphere import Atmosphere

    atm = Atmosphere.earth(turbidity=2.0)
    k = sky.extinction_coefficient_v(atm)
    alpha, zm, zv = (torch.tensor(v * DEGREE, dtype=torch.float64) for v in (10.0, 30.0, 30.0))
    daz = torch.tensor([60.0, 120.0, 180.0], dtype=torch.float64) * DEGREE
    radiance = sky.moonlit_sky_single_scattering(atm, alpha, zm, zv, daz, n_steps=48)
    v_ss = sky.radiance_to_mag_arcsec2(radiance, torch.arange(470.0, 701.0, 5.0,
                                                              dtype=torch.float64))
    cos_rho = math.cos(zm) * math.cos(zv) + math.sin(zm) * math.sin(zv) * torch.cos(daz)
    b = sky.moonlit_sky_ks1991(alpha, torch.acos(cos_rho), zm, zv, k)
    v_ks = sky.nanolambert_to_mag_arcsec2(b)
    assert ((v_ss - v_ks) > 0).all() and ((v_ss - v_ks) < 1.5).all()


@pytest.mark.parametrize("case", [(0.0, 0.0, 0.0), (0.0, 90.0, 180.0), (89.0, 89.0, 0.0)])
def test_single_scattering_hard_cases(dtype, case):
    """Moon overhead, line of sight on the horizon, Moon on the horizon, full and new Moon."""
    from skytorch.atmosphere import Atmosphere

    moon_zenith, view_zenith, phase = (torch.tensor(v * DEGREE, dtype=dtype, requires_grad=True)
                                       for v in case)
    radiance = sky.moonlit_sky_single_scattering(
        Atmosphere.earth(), phase, moon_zenith, view_zenith, torch.tensor(0.5, dtype=dtype),
        torch.tensor([550.0], dtype=dtype), n_steps=16, n_quadrature=8)
    assert radiance.dtype == dtype and torch.isfinite(radiance).all()
    assert float(radiance.detach()) > 0.0
    radiance.sum().backward()
    for value in (moon_zenith, view_zenith, phase):
        assert torch.isfinite(value.grad)
