"""Orders >= 3 of the eclipse sky (skytorch.scene.eclipse_higher_orders): checks of the method.

The accuracy against a Monte-Carlo of every order is in test_eclipse_sky_montecarlo.py. Here:
far from the Moon's shadow the dimming is 1 and the result is the clear sky's final gather of
orders 2..N of the field (skytorch.atmosphere.final_gather, a separate code path); the table of
the dimming against its direct evaluation; gradients; bad input.
"""
from __future__ import annotations

import math

import pytest
import torch

from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.final_gather import higher_orders_gathered
from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
from skytorch.scene.eclipse_higher_orders import eclipsed_higher_orders
from skytorch.scene.geometry import Geometry

WL = torch.tensor([450.0, 600.0], dtype=torch.float64)
QUICK = {"n_view": 6, "n_mu": 3, "n_phi": 8, "n_neighbourhood_mu": 3,
         "n_neighbourhood_phi": 8, "n_path": 8}


def _geometry(moon_offset_deg: float, sun_altitude_deg: float = 40.0) -> Geometry:
    """Sun due east at ``sun_altitude_deg``; the Moon ``moon_offset_deg`` higher, same azimuth."""
    def vector(altitude_deg, distance):
        h = math.radians(altitude_deg)
        return (0.0, distance * math.cos(h), distance * math.sin(h))

    moon_altitude = sun_altitude_deg + moon_offset_deg
    return Geometry(sun_altitude_deg, 90.0, moon_altitude, 90.0, 3.74e8, 1.496e11,
                    math.pi, 0.0, 0.0, 0.0, 0.0,
                    sun_horizontal_m=vector(sun_altitude_deg, 1.496e11),
                    moon_horizontal_m=vector(moon_altitude, 3.74e8))


@pytest.fixture(scope="module")
def setup():
    atmosphere = Atmosphere.earth(turbidity=2.0)
    tables = precompute_scattering(atmosphere, WL, scattering_orders=4,
                                   resolution=TableResolution.tiny())
    return atmosphere, tables


def test_far_from_the_shadow_it_is_the_clear_sky_gather(setup):
    atmosphere, tables = setup
    geometry = _geometry(moon_offset_deg=40.0)   # new Moon 40 deg from the Sun: no shadow
    zenith = torch.tensor([0.0, 1.0, 1.4], dtype=torch.float64)
    azimuth = torch.tensor([0.0, 1.2, 3.0], dtype=torch.float64)
    eclipsed = eclipsed_higher_orders(atmosphere, WL, zenith, azimuth, geometry,
                                      tables=tables, **QUICK)
    sun_zenith = torch.tensor(math.radians(50.0), dtype=torch.float64)
    sun_azimuth = torch.tensor(math.radians(90.0), dtype=torch.float64)
    gather = {key: QUICK[key] for key in ("n_view", "n_mu", "n_phi")}
    altitude = torch.tensor(0.0, dtype=torch.float64)
    clear = (higher_orders_gathered(tables, atmosphere, altitude, zenith, azimuth, sun_zenith,
                                    sun_azimuth, **gather)
             - higher_orders_gathered(tables, atmosphere, altitude, zenith, azimuth,
                                      sun_zenith, sun_azimuth, scattering_orders=2, **gather))
    assert torch.allclose(eclipsed, clear, rtol=1e-9, atol=0.0)
    # scattering_orders=3: order 3 alone, the gather of the field's order 2
    third = eclipsed_higher_orders(atmosphere, WL, zenith, azimuth, geometry, tables=tables,
                                   scattering_orders=3, **QUICK)
    clear_third = (higher_orders_gathered(tables, atmosphere, altitude, zenith, azimuth,
                                          sun_zenith, sun_azimuth, scattering_orders=3, **gather)
                   - higher_orders_gathered(tables, atmosphere, altitude, zenith, azimuth,
                                            sun_zenith, sun_azimuth, scattering_orders=2,
                                            **gather))
    assert torch.allclose(third, clear_third, rtol=1e-9, atol=0.0)
    assert bool((third < eclipsed).all())


def test_tabulated_dimming_against_its_direct_evaluation(setup):
    # the table (31 x 31 offsets within 250 km, 20 heights) against G at every point:
    # 1.6-3 % at the Monte-Carlo's zenith views (docs/solar_eclipse_sky.md); 5 % here
    atmosphere, tables = setup
    geometry = _geometry(moon_offset_deg=0.0)   # the Moon centred on the Sun: totality
    zenith = torch.tensor([0.0, 1.2], dtype=torch.float64)
    azimuth = torch.tensor([0.0, 2.0], dtype=torch.float64)
    tabulated = eclipsed_higher_orders(atmosphere, WL, zenith, azimuth, geometry,
                                       tables=tables, **QUICK)
    direct = eclipsed_higher_orders(atmosphere, WL, zenith, azimuth, geometry, tables=tables,
                                    neighbourhood_grid=None, **QUICK)
    clear = eclipsed_higher_orders(atmosphere, WL, zenith, azimuth, _geometry(40.0),
                                   tables=tables, **QUICK)
    assert bool((direct < 0.5 * clear).all())   # inside the umbra: dimmed
    assert torch.allclose(tabulated, direct, rtol=0.05, atol=0.0), (tabulated / direct)


def test_float32_tables_against_float64(setup):
    """Tables stored in float32 give the float64 result to their own rounding (1e-4)."""
    atmosphere, tables = setup
    single = precompute_scattering(atmosphere, WL, scattering_orders=4,
                                   resolution=TableResolution.tiny(), dtype=torch.float32)
    geometry = _geometry(moon_offset_deg=0.0)
    zenith = torch.tensor([0.0, 1.2], dtype=torch.float64)
    azimuth = torch.tensor([0.0, 2.0], dtype=torch.float64)
    quick = dict(QUICK, n_view=4)
    double = eclipsed_higher_orders(atmosphere, WL, zenith, azimuth, geometry, tables=tables,
                                    **quick)
    low = eclipsed_higher_orders(atmosphere, WL, zenith, azimuth, geometry, tables=single,
                                 **quick)
    assert torch.isfinite(low).all()
    assert torch.allclose(low.to(torch.float64), double, rtol=1e-4, atol=0.0)


def test_gradient_with_respect_to_the_view(setup):
    atmosphere, tables = setup
    geometry = _geometry(moon_offset_deg=0.0)
    zenith = torch.tensor([0.9], dtype=torch.float64, requires_grad=True)
    azimuth = torch.tensor([0.5], dtype=torch.float64)
    quick = dict(QUICK, n_view=4, n_neighbourhood_phi=6)
    value = eclipsed_higher_orders(atmosphere, WL, zenith, azimuth, geometry, tables=tables,
                                   **quick)
    (grad,) = torch.autograd.grad(value.sum(), zenith)
    step = 1e-5
    plus = eclipsed_higher_orders(atmosphere, WL, zenith.detach() + step, azimuth, geometry,
                                  tables=tables, **quick)
    minus = eclipsed_higher_orders(atmosphere, WL, zenith.detach() - step, azimuth, geometry,
                                   tables=tables, **quick)
    numeric = (plus - minus).sum() / (2 * step)
    assert torch.isfinite(grad).all()
    assert float(grad) == pytest.approx(float(numeric), rel=1e-4)


def test_bad_input(setup):
    atmosphere, tables = setup
    geometry = _geometry(0.0)
    zero = torch.zeros(1, dtype=torch.float64)
    with pytest.raises(TypeError, match="tables"):
        eclipsed_higher_orders(atmosphere, WL, zero, zero, geometry, tables=None)
    one = precompute_scattering(atmosphere, WL, scattering_orders=1,
                                resolution=TableResolution.tiny())
    with pytest.raises(ValueError, match="at least 2 orders"):
        eclipsed_higher_orders(atmosphere, WL, zero, zero, geometry, tables=one)
    with pytest.raises(ValueError, match="wavelength_nm"):
        eclipsed_higher_orders(atmosphere, WL[:1], zero, zero, geometry, tables=tables)
    with pytest.raises(ValueError, match="scattering_orders"):
        eclipsed_higher_orders(atmosphere, WL, zero, zero, geometry, tables=tables,
                               scattering_orders=2)
    with pytest.raises(ValueError, match="n_path"):
        eclipsed_higher_orders(atmosphere, WL, zero, zero, geometry, tables=tables, n_path=1)
    with pytest.raises(TypeError, match="neighbourhood_grid"):
        eclipsed_higher_orders(atmosphere, WL, zero, zero, geometry, tables=tables,
                               neighbourhood_grid=(31, 20))
    with pytest.raises(ValueError, match="half_width_m"):
        eclipsed_higher_orders(atmosphere, WL, zero, zero, geometry, tables=tables,
                               neighbourhood_grid=(31, 20, -1.0))
    from skytorch.atmosphere.tables import TransmittanceTable

    other = TransmittanceTable.build(atmosphere, WL[:1], cache=False, n_mu=16, n_r=8)
    with pytest.raises(ValueError, match="table was built for wavelength_nm"):
        eclipsed_higher_orders(atmosphere, WL, zero, zero, geometry, tables=tables,
                               table=other)
    with pytest.raises(TypeError, match="TransmittanceTable"):
        eclipsed_higher_orders(atmosphere, WL, zero, zero, geometry, tables=tables,
                               table="table")
    with pytest.raises(ValueError, match="altitude_m"):
        eclipsed_higher_orders(atmosphere, WL, zero, zero, geometry, 2e6, tables=tables)
