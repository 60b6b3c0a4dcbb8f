"""Gradients w.r.t. every continuous atmosphere parameter.

By float64 gradcheck on small cases, through optical_depth and sky_radiance, and both float32 and
float64 inputs.
"""

from __future__ import annotations

import pytest
import torch

from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.model import _PARAMETERS
from skytorch.constants import EARTH_MEAN_RADIUS_M, EARTH_TOP_OF_ATMOSPHERE_M

WAVELENGTH = torch.tensor([450.0, 600.0, 762.0], dtype=torch.float64)
#: a point inside every parameter's range, away from its bounds and from exact zeros
VALUES = {
    "surface_pressure_pa": 95_000.0, "surface_temperature_k": 280.0, "gravity_m_s2": 9.8,
    "molar_mass_kg_mol": 0.029, "rayleigh_scale_height_m": 8200.0, "angstrom_beta": 0.08,
    "angstrom_alpha": 1.2, "aerosol_scale_height_m": 1300.0,
    "aerosol_single_scattering_albedo": 0.92, "aerosol_asymmetry": 0.7, "ozone_du": 320.0,
    "ozone_peak_altitude_m": 24_000.0, "ozone_half_width_m": 14_000.0,
    "ozone_temperature_k": 226.0, "reference_refractivity": 2.8e-4,
    "reference_pressure_pa": 101_000.0, "reference_temperature_k": 287.0,
    "stratospheric_aerosol_optical_depth": 0.05, "stratospheric_aerosol_altitude_m": 21_000.0,
    "stratospheric_aerosol_width_m": 3500.0, "precipitable_water_cm": 1.2,
}


def _atmosphere(values, profile):
    return Atmosphere(planet_radius_m=EARTH_MEAN_RADIUS_M,
                      top_altitude_m=EARTH_TOP_OF_ATMOSPHERE_M, molecule_profile=profile,
                      **dict(zip(NAMES, values, strict=True)))


NAMES = tuple(name for name in _PARAMETERS if name in VALUES)


def test_every_parameter_is_covered():
    assert set(_PARAMETERS) <= set(VALUES), set(_PARAMETERS) - set(VALUES)


def _inputs():
    return tuple(torch.tensor(VALUES[name], dtype=torch.float64, requires_grad=True)
                 for name in NAMES)


@pytest.mark.parametrize("profile", ["us1976", "exponential"])
def test_gradcheck_optical_depth_and_refractivity(profile):
    zenith = torch.tensor([0.2, 1.45], dtype=torch.float64)
    altitude = torch.tensor([0.0, 5000.0], dtype=torch.float64)

    def f(*values):
        atm = _atmosphere(values, profile)
        # the reference_* parameters act through the refractivity only
        return (atm.optical_depth(WAVELENGTH, zenith, 300.0).reshape(-1),
                1e4 * atm.refractivity(altitude))

    assert torch.autograd.gradcheck(f, _inputs(), eps=1e-6, atol=1e-7, rtol=1e-5)


def test_gradcheck_sky_radiance():
    names = [n for n in NAMES if not n.startswith("reference_")]  # refraction-only ones

    def f(*values):
        full = dict(VALUES)
        full.update(zip(names, values, strict=True))
        atm = _atmosphere(tuple(full[n] for n in NAMES), "us1976")
        return atm.sky_radiance(WAVELENGTH, torch.tensor([0.3, 1.2], dtype=torch.float64),
                                0.4, 0.9, 0.0, n_samples=6, sun_steps=3, scattering_orders=1)

    inputs = tuple(torch.tensor(VALUES[n], dtype=torch.float64, requires_grad=True)
                   for n in names)
    assert torch.autograd.gradcheck(f, inputs, eps=1e-6, atol=1e-9, rtol=1e-5)


def test_float32_and_float64_agree():
    atm = Atmosphere.earth(turbidity=3.0, ozone_du=300.0, stratospheric_aerosol_optical_depth=0.1)
    zenith = torch.tensor([0.0, 1.0, 1.5, 1.58], dtype=torch.float64)
    tau64 = atm.optical_depth(WAVELENGTH, zenith, 500.0)
    tau32 = atm.optical_depth(WAVELENGTH.float(), zenith.float(), 500.0)
    assert tau32.dtype == torch.float32 and tau64.dtype == torch.float64
    assert torch.allclose(tau32.double(), tau64, rtol=3e-5)
    sky64 = atm.sky_radiance(WAVELENGTH, zenith[:3], 0.5, 0.8, 0.0, n_samples=16, scattering_orders=1)
    sky32 = atm.sky_radiance(WAVELENGTH.float(), zenith[:3].float(), 0.5, 0.8, 0.0,
                             n_samples=16, scattering_orders=1)
    assert sky32.dtype == torch.float32
    assert torch.allclose(sky32.double(), sky64, rtol=1e-4)
