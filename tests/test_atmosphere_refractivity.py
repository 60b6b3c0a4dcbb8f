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
    mixed = Atmosphere.earth(molecule_profile="exponential", refractivity_profile="us1976")
    standard = Atmosphere.earth(molecule_profile="us1976")
    # the refractivity follows the molecules unless given
    exponential = Atmosphere.earth(molecule_profile="exponential")
    assert exponential.refractivity_profile == "exponential"
    assert standard.refractivity_profile == "us1976"
    # the Earth default: one vertical structure, US 1976 for refractivity and molecules
    default = Atmosphere.earth()
    assert (default.refractivity_profile, default.molecule_profile) == ("us1976", "us1976")
    assert torch.equal(default.refractivity(ALTITUDE), mixed.refractivity(ALTITUDE))
    # refractivity from the US 1976 density, optical depths from the 8 km exponential
    assert torch.equal(mixed.refractivity(ALTITUDE), standard.refractivity(ALTITUDE))
    assert not torch.allclose(mixed.refractivity(ALTITUDE), exponential.refractivity(ALTITUDE))
    zenith = torch.tensor([0.0, 1.2, 1.5], dtype=torch.float64)
    assert torch.equal(mixed.optical_depth(WAVELENGTH, zenith),
                       exponential.optical_depth(WAVELENGTH, zenith))
    assert mixed.refractivity_breakpoints_m == _US1976_BREAKS_M
    assert exponential.refractivity_breakpoints_m == ()
    assert exponential.refractivity_kinks_m == ()
    # dn/dh jumps at the layer bases: one-sided slopes differ there and agree elsewhere
    kinks = torch.tensor(mixed.refractivity_kinks_m, dtype=torch.float64)
    assert len(kinks) == 7 and abs(float(kinks[0]) - 11_019.07) < 0.01

    def slope(altitude):
        altitude = altitude.clone().requires_grad_(True)
        (grad,) = torch.autograd.grad(mixed.refractivity(altitude).sum(), altitude)
        return grad

    below, above = slope(kinks[:4] - 1e-3), slope(kinks[:4] + 1e-3)
    assert bool(((above - below).abs() > 0.02 * below.abs()).all())  # 3 %-23 %
    smooth = kinks[:4] - 500.0
    assert torch.allclose(slope(smooth - 1e-3), slope(smooth + 1e-3), rtol=1e-5)


def test_us1976_refractivity_gives_bennett_horizon_refraction():
    # the isothermal exponential profile overstates the density gradient near the ground:
    # 37.9' at Bennett's conditions; the US 1976 lapse rate gives 33.4' (Bennett 34.5')
    horizon = torch.tensor(0.0, dtype=torch.float64)
    default = Atmosphere.earth(turbidity=1.0, ozone_du=0.0, **BENNETT)
    exponential = Atmosphere.earth(turbidity=1.0, ozone_du=0.0,
                                   refractivity_profile="exponential", **BENNETT)
    assert 33 * ARCMINUTE <= float(default.refraction(horizon)) <= 36 * ARCMINUTE
    assert float(exponential.refraction(horizon)) > 36 * ARCMINUTE


def _saemundsson_arcmin(true_altitude_deg, pressure_hpa, temperature_c):
    """Saemundsson 1986 (Sky Tel. 72, 70; Meeus 1998 eq. 16.4).

    Refraction of an object at true altitude h, R = 1.02' cot(h + 10.3/(h + 5.11)), times
    (P/1010)(283/(273 + T)).
    """
    h = torch.as_tensor(true_altitude_deg, dtype=torch.float64)
    cot = 1.0 / torch.tan(torch.deg2rad(h + 10.3 / (h + 5.11)))
    return 1.02 * cot * (pressure_hpa / 1010.0) * (283.0 / (273.0 + temperature_c))


def test_default_inverse_refraction_vs_saemundsson():
    """Apparent altitude of objects at true altitudes 0-60 degrees against Saemundsson.

    Default Earth at 1013.25 hPa, 15 degC, against Saemundsson's formula (consistent with Bennett's
    plain formula to 0.1'; measured: -0.68' at the true horizon (28.57' vs 27.89'), -0.17' at 10
    degrees, -0.05' at 45 degrees).
    """
    atm = Atmosphere.earth(turbidity=1.0, ozone_du=0.0)
    true = torch.tensor([0.0, 1.0, 2.0, 5.0, 10.0, 20.0, 45.0, 60.0], dtype=torch.float64)
    model = (atm.apparent_altitude(torch.deg2rad(true)) - torch.deg2rad(true)) / ARCMINUTE
    reference = _saemundsson_arcmin(true, 1013.25, 15.0)
    assert torch.allclose(model, reference, rtol=0, atol=1.0)  # arcmin, near the horizon
    high = true >= 5.0
    assert torch.allclose(model[high], reference[high], rtol=0, atol=0.2)  # arcmin
