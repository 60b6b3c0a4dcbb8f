"""Phase functions and single-scattering sky radiance."""

from __future__ import annotations

import math

import pytest
import torch
from scipy import integrate

from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.scattering import (
    cornette_shanks,
    henyey_greenstein,
    rayleigh_phase,
    single_scattering_radiance,
)
from skytorch.atmosphere.tables import TransmittanceTable
from skytorch.constants import DEGREE, PERCENT

WAVELENGTH = torch.tensor([440.0, 550.0, 680.0], dtype=torch.float64)


def _moments(phase):
    def f(c):
        return float(phase(torch.tensor(c, dtype=torch.float64))) * 2.0 * math.pi

    norm = integrate.quad(f, -1.0, 1.0, epsabs=1e-13)[0]
    mean = integrate.quad(lambda c: c * f(c), -1.0, 1.0, epsabs=1e-13)[0]
    return norm, mean


@pytest.mark.parametrize("g", [-0.3, 0.0, 0.5, 0.8])
def test_henyey_greenstein_normalised_with_mean_cosine_g(g):
    norm, mean = _moments(lambda c: henyey_greenstein(c, g))
    assert norm == pytest.approx(1.0, abs=1e-9)
    assert mean == pytest.approx(g, abs=1e-9)


@pytest.mark.parametrize("g", [0.3, 0.8])
def test_cornette_shanks_normalised_with_published_asymmetry(g):
    # Cornette & Shanks 1992: <cos> = 3 g (4 + g^2) / (5 (2 + g^2))
    norm, mean = _moments(lambda c: cornette_shanks(c, g))
    assert norm == pytest.approx(1.0, abs=1e-9)
    assert mean == pytest.approx(3 * g * (4 + g * g) / (5 * (2 + g * g)), abs=1e-9)


def test_rayleigh_phase_normalised():
    norm, mean = _moments(rayleigh_phase)
    assert norm == pytest.approx(1.0, abs=1e-12)
    assert mean == pytest.approx(0.0, abs=1e-12)


def test_aerosol_phase_of_atmosphere_normalised():
    atm = Atmosphere.earth(turbidity=2.0)
    norm, _ = _moments(atm.aerosol_phase)
    assert norm == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("sun_zenith_deg", [0.0, 30.0, 60.0])
def test_optically_thin_limit(sun_zenith_deg):
    # thin atmosphere, zenith view: L/E = tau_R P_R(theta) (single scattering, no extinction)
    thin = Atmosphere.earth(aerosol_optical_depth=0.0, ozone_du=0.0, surface_pressure_pa=10.0)
    sun_zenith = sun_zenith_deg * DEGREE
    radiance = thin.sky_radiance(WAVELENGTH, 0.0, 0.0, sun_zenith, 0.0, n_samples=512, scattering_orders=1)
    tau = thin.optical_depth(WAVELENGTH, per_species=True)["rayleigh"]
    expected = tau * float(rayleigh_phase(torch.tensor(math.cos(sun_zenith))))
    assert torch.allclose(radiance, expected, rtol=1e-4)


def test_default_resolution_against_converged_run():
    atm = Atmosphere.earth(turbidity=3.0, ozone_du=300.0)
    view = torch.tensor([0.0, 0.8, 1.3, 1.5, 1.56], dtype=torch.float64)
    default = atm.sky_radiance(WAVELENGTH, view, 0.0, 1.1, 0.5, scattering_orders=1)
    converged = atm.sky_radiance(WAVELENGTH, view, 0.0, 1.1, 0.5, n_samples=2048, scattering_orders=1)
    assert float(((default - converged).abs() / converged).max()) <= 2 * PERCENT


def test_planet_shadow_in_twilight():
    atm = Atmosphere.earth(turbidity=2.0, ozone_du=300.0)
    view = torch.tensor([0.0, 0.5, 1.0], dtype=torch.float64)
    noon = atm.sky_radiance(WAVELENGTH, 0.0, 0.0, 0.0, 0.0, scattering_orders=1)
    # Sun 20 deg below the horizon: the shadow reaches 409 km, above the 100 km top
    deep = atm.sky_radiance(WAVELENGTH, view, 0.0, 110.0 * DEGREE, 0.0, scattering_orders=1)
    assert float(deep.abs().max()) == 0.0
    civil = atm.sky_radiance(WAVELENGTH, view, 0.0, 95.0 * DEGREE, 0.0, scattering_orders=1)
    assert bool(torch.isfinite(civil).all()) and bool((civil > 0).all())
    assert bool((civil < 1e-2 * noon).all())
    deeper = atm.sky_radiance(WAVELENGTH, view, 0.0, 98.0 * DEGREE, 0.0, scattering_orders=1)
    assert bool((deeper < civil).all())


def test_azimuthal_symmetry_and_blue_sky():
    atm = Atmosphere.earth(turbidity=2.0, ozone_du=300.0)
    left = atm.sky_radiance(WAVELENGTH, 1.0, 0.3, 0.8, 0.0, scattering_orders=1)
    right = atm.sky_radiance(WAVELENGTH, 1.0, -0.3, 0.8, 0.0, scattering_orders=1)
    assert torch.allclose(left, right, rtol=1e-12)
    zenith = atm.sky_radiance(WAVELENGTH, 0.0, 0.0, 30.0 * DEGREE, 0.0, scattering_orders=1)
    assert float(zenith[0]) > float(zenith[1]) > float(zenith[2])


def test_batched_parameters_and_views():
    atm = Atmosphere.earth(turbidity=torch.tensor([[2.0], [6.0]], dtype=torch.float64))
    view = torch.linspace(0.0, 1.4, 5, dtype=torch.float64)
    radiance = atm.sky_radiance(WAVELENGTH, view, 0.0, 0.7, 0.0, scattering_orders=1)
    assert radiance.shape == (2, 5, 3)
    single = Atmosphere.earth(turbidity=6.0).sky_radiance(WAVELENGTH, view, 0.0, 0.7, 0.0, scattering_orders=1)
    assert torch.allclose(radiance[1], single, rtol=1e-12)
    # an all-sky grid: zenith (4, 1) x azimuth (6,)
    grid = Atmosphere.earth().sky_radiance(WAVELENGTH, view[:4, None],
                                           torch.linspace(0.0, 6.0, 6, dtype=torch.float64),
                                           0.7, 0.0, n_samples=16, scattering_orders=1)
    assert grid.shape == (4, 6, 3)


def test_table_for_sun_transmittance_agrees():
    atm = Atmosphere.earth(turbidity=2.0, ozone_du=300.0)
    table = TransmittanceTable.build(atm, WAVELENGTH)
    view = torch.tensor([0.0, 0.7, 1.4], dtype=torch.float64)
    direct = single_scattering_radiance(atm, WAVELENGTH, view, 0.0, 1.2, 0.4)
    looked_up = single_scattering_radiance(atm, WAVELENGTH, view, 0.0, 1.2, 0.4, table=table)
    assert torch.allclose(direct, looked_up, rtol=1 * PERCENT)


def test_sky_radiance_gradients(dtype):
    atm = Atmosphere.earth(turbidity=2.0, ozone_du=300.0)
    sun = torch.tensor(1.3, dtype=dtype, requires_grad=True)
    radiance = atm.sky_radiance(WAVELENGTH.to(dtype), torch.tensor(0.6, dtype=dtype), 0.0,
                                sun, 0.0, scattering_orders=1)
    radiance.sum().backward()
    assert bool(torch.isfinite(sun.grad))
    if dtype == torch.float64:
        assert torch.autograd.gradcheck(
            lambda z: atm.sky_radiance(WAVELENGTH, torch.tensor(0.6, dtype=torch.float64),
                                       0.0, z, 0.0, n_samples=16, scattering_orders=1),
            (torch.tensor(1.3, dtype=torch.float64, requires_grad=True),), eps=1e-5,
            atol=1e-8, rtol=1e-4)


def test_sky_radiance_in_physical_units():
    from skytorch.spectrum import solar_irradiance

    atm = Atmosphere.earth(turbidity=2.0, ozone_du=300.0)
    relative = atm.sky_radiance(WAVELENGTH, 0.0, 0.0, 0.5, 0.0, scattering_orders=1)
    physical = atm.sky_radiance(WAVELENGTH, 0.0, 0.0, 0.5, 0.0, solar_irradiance=True, scattering_orders=1)
    assert torch.allclose(physical, relative * solar_irradiance(WAVELENGTH), rtol=1e-12)
