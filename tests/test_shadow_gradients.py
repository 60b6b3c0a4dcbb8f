"""Gradients of the eclipse shadow with respect to the atmosphere and the cloud tops.

``torch.autograd.gradcheck`` (float64) compares the analytical derivatives with central
finite differences of the same function. The inputs are scaled to order one (altitudes in
units of 10 km, ozone in 100 DU) and the outputs are ``log(I / I_sun)``, so that the
default tolerances (``atol`` 1e-5, ``rtol`` 1e-3) are tight for umbral values of 1e-6 as
much as for penumbral ones. The cloud-top derivative is the boundary term of the step in
the ray weight (the ring quadrature's split moves with the tops): a step differentiated
inside the integrand alone would give zero, which the finite difference refutes.
"""

from __future__ import annotations

import pytest
import torch

from skytorch.atmosphere import Atmosphere
from skytorch.eclipse import Shadow
from skytorch.eclipse.shadow_table import ShadowTable

MOON_DISTANCE = 3.844e8  # [m]
#: umbra centre, mid-umbra and the inner penumbra at the Moon's distance [m]
OFFSETS = (0.0, 3.0e6, 5.0e6)
#: wavelengths in the ozone Chappuis band, the red and the 940 nm water band [nm]
WAVELENGTHS = (600.0, 700.0, 940.0)
N_ALTITUDE = 33


def _illuminance(strat_aod, strat_altitude_10km, strat_width_10km, water_cm, ozone_100du,
                 turbidity, cloud_top_10km, *, cloud_fraction=0.6, offsets=OFFSETS):
    atmosphere = Atmosphere.earth(
        turbidity=turbidity, ozone_du=100.0 * ozone_100du,
        stratospheric_aerosol_optical_depth=strat_aod,
        stratospheric_aerosol_altitude_m=1e4 * strat_altitude_10km,
        stratospheric_aerosol_width_m=1e4 * strat_width_10km,
        precipitable_water_cm=water_cm)
    shadow = Shadow.earth(atmosphere, n_altitude=N_ALTITUDE,
                          cloud_top_altitude_m=1e4 * cloud_top_10km,
                          cloud_fraction=cloud_fraction)
    offset = torch.tensor(offsets, dtype=torch.float64)
    return shadow.relative_illuminance(MOON_DISTANCE, offset, WAVELENGTHS)


def _inputs(**changes):
    values = {"strat_aod": 0.05, "strat_altitude_10km": 2.0, "strat_width_10km": 0.3,
              "water_cm": 1.4, "ozone_100du": 3.0, "turbidity": 2.5, "cloud_top_10km": 0.8}
    values.update(changes)
    return tuple(torch.tensor(v, dtype=torch.float64, requires_grad=True)
                 for v in values.values())


@pytest.mark.parametrize("cloud_fraction", [0.6, 1.0])
def test_gradcheck_every_parameter(cloud_fraction):
    # every extinction parameter and the cloud tops at once; a closed deck (1.0) and a
    # broken one (0.6): both a step in the ray weight. A closed deck at 8 km leaves the
    # umbra's centre dark (I = 0 exactly, no log): points from mid-umbra outwards
    offsets = OFFSETS if cloud_fraction < 1.0 else OFFSETS[1:]

    def log_illuminance(*inputs):
        return torch.log(_illuminance(*inputs, cloud_fraction=cloud_fraction,
                                      offsets=offsets))

    assert torch.autograd.gradcheck(log_illuminance, _inputs())


def test_cloud_top_gradient_is_the_boundary_term():
    # the derivative is not zero (a step's derivative inside the integrand would be) and
    # darkens the umbra as the tops rise: d I / d h_c < 0 in mid-umbra (3000 km off the
    # axis: the rays grazing 8 km reach it; the centre is lit by lower rays only)
    inputs = _inputs()
    value = _illuminance(*inputs)
    (slope,) = torch.autograd.grad(value[1].sum(), inputs[-1])
    assert float(slope) < 0.0
    with torch.no_grad():
        step = 1e-3  # 10 m
        plus = _illuminance(*_inputs(cloud_top_10km=0.8 + step))[1].sum()
        minus = _illuminance(*_inputs(cloud_top_10km=0.8 - step))[1].sum()
    expected = float((plus - minus) / (2 * step))
    assert abs(float(slope) - expected) <= 1e-4 * abs(expected)


def test_shadow_table_lookup_carries_the_gradient():
    # a small (u, v) table built from a shadow with a stratospheric AOD that requires a
    # gradient: the look-up's derivative against finite differences of rebuilt tables
    def table_value(aod, *, grad):
        tensor = torch.tensor(aod, dtype=torch.float64, requires_grad=grad)
        atmosphere = Atmosphere.earth(stratospheric_aerosol_optical_depth=tensor)
        shadow = Shadow.earth(atmosphere, n_altitude=N_ALTITUDE)
        table = ShadowTable.compute(shadow, (600.0, 800.0), n_u=3, n_v=9, progress=False,
                                    min_distance_m=3.5e8, max_distance_m=4.1e8)
        value = table.lookup(torch.tensor([MOON_DISTANCE] * 2, dtype=torch.float64),
                             torch.tensor([1.0e6, 4.0e6], dtype=torch.float64))
        return tensor, value

    tensor, value = table_value(0.1, grad=True)
    assert value.requires_grad
    (slope,) = torch.autograd.grad(torch.log(value).sum(), tensor)
    with torch.no_grad():
        step = 1e-5
        plus = torch.log(table_value(0.1 + step, grad=False)[1]).sum()
        minus = torch.log(table_value(0.1 - step, grad=False)[1]).sum()
    expected = float((plus - minus) / (2 * step))
    assert expected < 0.0
    assert abs(float(slope) - expected) <= 1e-6 * abs(expected)


def test_a_cloud_top_tensor_gives_the_same_closed_deck():
    # the closed deck as a weight on a ground-based table (tensor) against the table that
    # starts at the deck (number): the same model, interpolated differently; at the default
    # 401 rows they agree to 3e-4 relative in the umbra
    atmosphere = Atmosphere.earth()
    offset = torch.linspace(0.0, 6.0e6, 7, dtype=torch.float64)
    number = Shadow.earth(atmosphere, cloud_top_altitude_m=8e3).relative_illuminance(
        MOON_DISTANCE, offset, (500.0, 700.0))
    tensor = Shadow.earth(atmosphere, cloud_top_altitude_m=torch.tensor(
        8e3, dtype=torch.float64)).relative_illuminance(MOON_DISTANCE, offset, (500.0, 700.0))
    lit = number > 1e-12
    assert bool(lit.any())
    assert float(((tensor - number) / number)[lit].abs().max()) < 3e-4


def test_refractivity_parameters_and_scattering_raise():
    pressure = torch.tensor(101325.0, dtype=torch.float64, requires_grad=True)
    shadow = Shadow.earth(Atmosphere.earth(surface_pressure_pa=pressure), n_altitude=17)
    with pytest.raises(ValueError, match="surface_pressure_pa"):
        shadow.relative_illuminance(MOON_DISTANCE, 0.0, 600.0)
    cloud = torch.tensor(5e3, dtype=torch.float64, requires_grad=True)
    scattering = Shadow.earth(cloud_top_altitude_m=cloud, scattering=True, n_altitude=17)
    with pytest.raises(ValueError, match="cloud_top_altitude_m"):
        scattering.relative_illuminance(MOON_DISTANCE, 0.0, 600.0)
    with pytest.raises(ValueError, match="0-d"):
        Shadow.earth(cloud_top_altitude_m=torch.tensor([1e3, 2e3], dtype=torch.float64))
