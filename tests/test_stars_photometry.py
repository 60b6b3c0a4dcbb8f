"""Star photometry: extinction from the atmosphere model, air mass, colours, brightness."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from skytorch.constants import DEGREE, MAG, PERCENT
from skytorch.spectrum import bv_to_temperature, temperature_to_srgb
from skytorch.stars import (
    bright_stars,
    bv_to_srgb,
    extinction,
    extinction_coefficient,
    extinction_table,
    observe,
    relative_brightness,
)

atmosphere_module = pytest.importorskip("skytorch.atmosphere")
Atmosphere = atmosphere_module.Atmosphere


@pytest.fixture(scope="module")
def atm():
    return Atmosphere.earth(turbidity=2.0, ozone_du=300.0)


@pytest.fixture(scope="module")
def table(atm):
    return extinction_table(atm, 0.0, refraction=True)


def test_extinction_coefficient_sea_level_in_observed_range(atm):
    """Sea-level sites: k_V ≈ 0.2–0.35 mag/airmass (e.g. Schaefer 1998; Krisciunas 1987)."""
    k = float(extinction_coefficient(atm, 0.0))
    assert 0.20 <= k <= 0.35


def test_extinction_coefficient_mountain_site_clear():
    """A clear night at ~2.3 km: k_V ≈ 0.13–0.15 (King 1985, La Palma median 0.13)."""
    k = float(extinction_coefficient(Atmosphere.earth(turbidity=2.0), 2300.0))
    assert k == pytest.approx(0.14, abs=0.03)


def test_table_matches_direct_path_integral_off_nodes(atm, table):
    """Interpolated table + colour line vs V-band integral at altitudes between nodes."""
    from skytorch.spectrum import blackbody_radiance, v_band_response

    altitude = torch.tensor([0.3, 2.77, 11.1, 37.4, 71.9], dtype=torch.float64) * DEGREE
    bv = torch.tensor([-0.2, 0.4, 0.65, 1.2, 1.8], dtype=torch.float64)
    wavelength = torch.linspace(470.0, 700.0, 231, dtype=torch.float64)
    tau = atm.optical_depth(wavelength, math.pi / 2 - altitude, 0.0, refraction=True)
    weights = (blackbody_radiance(wavelength, bv_to_temperature(bv)[:, None])
               * v_band_response(wavelength))
    direct = -2.5 * torch.log10((weights * torch.exp(-tau)).sum(-1) / weights.sum(-1))
    delta_m, _ = extinction(bv, altitude[None, :], table)
    error = (delta_m[0] - direct).abs()
    # tolerance grows with the optical depth: 0.4 % of the extinction, at least 3 mmag
    assert torch.all(error <= torch.clamp(0.004 * direct, min=0.003 * MAG))


def test_airmass_against_kasten_young(table):
    """Slant/vertical optical depth vs Kasten & Young (1989) at 30° and 10° altitude."""
    from skytorch.atmosphere.optical_depth import kasten_young_air_mass

    for altitude_deg, tolerance in ((90.0, 0.1 * PERCENT), (30.0, 1.0 * PERCENT), (10.0, 3.0 * PERCENT)):
        altitude = torch.tensor([[altitude_deg * DEGREE]], dtype=torch.float64)
        _, airmass = extinction(torch.tensor([0.65], dtype=torch.float64), altitude, table)
        reference = kasten_young_air_mass(torch.tensor((90.0 - altitude_deg) * DEGREE))
        assert float(airmass) == pytest.approx(float(reference), rel=tolerance)


def test_horizon_and_below_stay_finite_with_gradients(table, dtype):
    altitude = torch.tensor([[-0.5, -1e-9, 0.0, 1e-6, 0.02, math.pi / 2]], dtype=dtype,
                            requires_grad=True)
    bv = torch.tensor([0.65] * 6, dtype=dtype)
    delta_m, airmass = extinction(bv, altitude, table)
    assert torch.isfinite(delta_m).all() and torch.isfinite(airmass).all()
    assert delta_m.dtype == dtype
    # below the horizon: the horizon values (flagged not visible by observe)
    assert float(delta_m[0, 0].detach()) == pytest.approx(float(delta_m[0, 2].detach()))
    delta_m.sum().backward()
    assert torch.isfinite(altitude.grad).all()
    assert float(altitude.grad[0, 4]) < 0.0  # brighter as the star rises


def test_extinction_gradcheck_float64(table):
    altitude = torch.tensor([[0.05, 0.4, 1.2]], dtype=torch.float64, requires_grad=True)
    bv = torch.tensor([0.0, 0.65, 1.5], dtype=torch.float64)
    assert torch.autograd.gradcheck(lambda a: extinction(bv, a, table)[0], (altitude,))


def test_sun_like_colour_from_ballesteros():
    """B−V 0.65 → T ≈ 5800 K (Ballesteros 2012) → the colour of a 5800 K black body."""
    assert float(bv_to_temperature(0.65)) == pytest.approx(5800.0, abs=50.0)
    rgb = bv_to_srgb(torch.tensor([0.65, -0.3, 1.6], dtype=torch.float64))
    assert torch.allclose(rgb[0], temperature_to_srgb(torch.tensor(5800.0,
                                                                   dtype=torch.float64)),
                          atol=0.01)
    assert float(rgb[1, 2]) >= float(rgb[1, 0])  # hot star: blue ≥ red
    assert float(rgb[2, 0]) > float(rgb[2, 2])  # cool star: red > blue


def test_relative_brightness_is_pogson():
    """Five magnitudes are a factor 100 by definition (Pogson 1856)."""
    ratio = relative_brightness(torch.tensor([1.0, 6.0, 11.0]), control_magnitude=6.0)
    assert torch.allclose(ratio, torch.tensor([100.0, 1.0, 0.01]), rtol=1e-6)


def test_observed_magnitudes_at_zenith_and_horizon(atm):
    stars = bright_stars(1.5)
    ds = observe(stars, ["2025-09-07T20:00", "2025-09-08T02:00"], 52.5, 13.4, 34.0,
                 atmosphere=atm)
    magnitude, vmag = ds.magnitude.values, ds.vmag.values
    assert np.isfinite(magnitude).all() and np.isfinite(ds.airmass.values).all()
    above = ds.above_horizon.values
    # extinction is positive and grows with air mass
    assert (magnitude - vmag >= 0.0).all()
    k = float(extinction_coefficient(atm, 34.0))
    high = above & (ds.altitude.values > 60.0)
    assert high.any()
    assert np.all(np.abs((magnitude - vmag)[high] / ds.airmass.values[high] - k) < 0.03 * MAG)
    assert not ds.visible.values[~above].any()
    assert (ds.relative_brightness.values[~above] == 0.0).all()


def test_float32_observation_matches_float64(atm):
    stars = bright_stars(2.0)
    times = ["2025-09-07T20:00", "2025-09-08T03:30"]
    single = observe(stars, times, 28.76, -17.88, 2396.0, atmosphere=atm, dtype=torch.float32)
    double = observe(stars, times, 28.76, -17.88, 2396.0, atmosphere=atm)
    assert single.magnitude.dtype == np.float32
    assert np.abs(single.altitude.values - double.altitude.values).max() < 0.5 / 3600.0
    above = double.above_horizon.values
    assert np.abs(single.magnitude.values - double.magnitude.values)[above].max() < 1e-3 * MAG
    assert np.isfinite(single.magnitude.values).all()


def test_hazy_atmosphere_huge_horizon_extinction_stays_finite():
    """Turbidity 12: ~100 mag of extinction at the horizon, finite and not visible."""
    hazy = Atmosphere.earth(turbidity=12.0)
    ds = observe(bright_stars(2.0), "2025-09-07T20:00", 52.5, 13.4, atmosphere=hazy)
    low = ds.above_horizon.values & (ds.altitude.values < 0.5)
    assert np.isfinite(ds.magnitude.values).all()
    assert np.isfinite(ds.relative_brightness.values).all()
    table = extinction_table(hazy, 0.0)
    assert float(table["offset"][0]) > 50.0
    assert not ds.visible.values[low].any()
