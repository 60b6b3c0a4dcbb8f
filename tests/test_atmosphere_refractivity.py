"""Refractivity profile chosen independently of the molecular profile.

References: Bennett 1982 (J. Navigation 35, 255) horizon refraction 34.5' at 1010 hPa,
10 degC (the issue's band 33'-36'); the U.S. Standard Atmosphere 1976 densities; Bodhaine
et al. 1999 for the unchanged Rayleigh optical depth.
"""

from __future__ import annotations

import torch

from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.model import _US1976_BREAKS_M
from skytorch.constants import ARCMINUTE

ALTITUDE = torch.tensor([0.0, 500.0, 2000.0, 11_000.0, 30_000.0, 80_000.0],
                        dtype=torch.float64)
WAVELENGTH = torch.tensor([400.0, 550.0, 700.0], dtype=torch.float64)
BENNETT = {"surface_pressure_pa": 101_000.0, "surface_temperature_k": 283.15}


def test_refractivity_follows_its_own_profile():
    mixed = Atmosphere.earth(refractivity_profile="us1976")
    standard = Atmosphere.earth(molecule_profile="us1976")
    exponential = Atmosphere.earth()
    assert exponential.refractivity_profile == "exponential"
    assert standard.refractivity_profile == "us1976"
    # refractivity from the US 1976 density, optical depths from the 8 km exponential
    assert torch.equal(mixed.refractivity(ALTITUDE), standard.refractivity(ALTITUDE))
    assert not torch.allclose(mixed.refractivity(ALTITUDE), exponential.refractivity(ALTITUDE))
    zenith = torch.tensor([0.0, 1.2, 1.5], dtype=torch.float64)
    assert torch.equal(mixed.optical_depth(WAVELENGTH, zenith),
                       exponential.optical_depth(WAVELENGTH, zenith))
    assert mixed.refractivity_breakpoints_m == _US1976_BREAKS_M
    assert exponential.refractivity_breakpoints_m == ()


def test_us1976_refractivity_gives_bennett_horizon_refraction():
    # the isothermal exponential profile overstates the density gradient near the ground:
    # 37.9' at Bennett's conditions; the US 1976 lapse rate gives 33.4' (Bennett 34.5')
    horizon = torch.tensor(0.0, dtype=torch.float64)
    mixed = Atmosphere.earth(turbidity=1.0, ozone_du=0.0, refractivity_profile="us1976",
                             **BENNETT)
    exponential = Atmosphere.earth(turbidity=1.0, ozone_du=0.0, **BENNETT)
    assert 33 * ARCMINUTE <= float(mixed.refraction(horizon)) <= 36 * ARCMINUTE
    assert float(exponential.refraction(horizon)) > 36 * ARCMINUTE
