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
    assert single.color.dtype == np.float32 and np.isfinite(single.color.values).all()
    assert np.abs(single.color.values - double.color.values).max() < 1e-4


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


# --- apparent colour (reddening along the path) ----------------------------------------------

#: sRGB difference of the tabulated colour from the direct 1-nm integral (measured: 1.6e-3
#: at 0–10° altitude, ≤ 4e-4 above, from the 10-nm spectra and the altitude interpolation)
APPARENT_COLOR_TOLERANCE = 0.003


def _direct_apparent_srgb(atm, bv: float, apparent_altitude_deg: float, altitude_m: float):
    """Black body through the atmosphere by direct integration on the 1-nm CIE grid.

    Independent of the colour table: the star's own path (no altitude or B−V
    interpolation), 471 wavelengths instead of 41, the CIE 1931 sum done here.
    """
    from skytorch.spectrum import (
        blackbody_radiance,
        cie_xyz_cmf,
        wavelength_grid,
        xyz_to_linear_srgb,
    )

    wl = wavelength_grid("cie1")
    zenith = torch.tensor(math.radians(90.0 - apparent_altitude_deg), dtype=torch.float64)
    tau = atm.optical_depth(wl, zenith, altitude_m, refraction=True).reshape(-1)
    spectrum = blackbody_radiance(wl, bv_to_temperature(torch.tensor(bv))) * torch.exp(
        -(tau - tau.min()))
    xyz = (spectrum[:, None] * cie_xyz_cmf(wl)).sum(0)
    linear = xyz_to_linear_srgb(xyz).clamp_min(0.0)
    linear = linear / linear.max()
    encoded = torch.where(linear <= 0.0031308, 12.92 * linear,
                          1.055 * linear.clamp_min(0.0031308) ** (1 / 2.4) - 0.055)
    return encoded.numpy(), xyz.numpy()


@pytest.fixture(scope="module")
def colour_observation(atm):
    stars = bright_stars(3.0)
    return observe(stars, ["2025-09-07T20:00", "2025-09-08T02:00"], 52.5, 13.4, 34.0,
                   atmosphere=atm)


def test_apparent_colour_against_direct_integration(atm, colour_observation):
    """The colour of observe (time, star, channel) equals a direct spectral integral per star."""
    ds = colour_observation
    assert ds.color.dims == ("time", "star", "channel")
    assert ds.color_exoatmospheric.dims == ("star", "channel")
    altitude = ds.altitude.values
    picks = []
    for low, high in ((80.0, 90.0), (40.0, 60.0), (10.0, 20.0), (3.0, 6.0), (0.2, 1.5)):
        t, s = np.argwhere((altitude > low) & (altitude < high))[0]
        picks.append((int(t), int(s)))
    for t, s in picks:
        expected, _ = _direct_apparent_srgb(atm, float(ds.bv[s]), float(altitude[t, s]), 34.0)
        got = ds.color.values[t, s]
        assert np.abs(got - expected).max() < APPARENT_COLOR_TOLERANCE, (altitude[t, s], got,
                                                                         expected)


def test_apparent_colour_zenith_near_catalogue_horizon_redder(atm, colour_observation):
    """Near the zenith the colour is close to the exo-atmospheric one; low stars redden.

    Measured with CIE chromaticity of the direct integral (B−V = 0): the zenith shift is
    the one-air-mass reddening at 34 m (Δx = +0.013, Δy = +0.017); at 30° +0.026, at 10°
    +0.074 and at 1° (~38 air masses) +0.31, an orange-red star.
    """
    ds = colour_observation
    star = int(np.argmin(np.abs(ds.bv.values - 0.0)))  # an A0-like star, white-blue
    _, xyz_space = _direct_apparent_srgb(atm, float(ds.bv[star]), 90.0, 34.0)
    chroma = {}
    for altitude in (90.0, 30.0, 10.0, 1.0):
        _, xyz = _direct_apparent_srgb(atm, float(ds.bv[star]), altitude, 34.0)
        chroma[altitude] = xyz[0] / xyz.sum()
    from skytorch.spectrum import blackbody_radiance, cie_xyz_cmf, wavelength_grid

    wl = wavelength_grid("cie1")
    source = blackbody_radiance(wl, bv_to_temperature(torch.tensor(float(ds.bv[star]))))
    xyz0 = (source[:, None] * cie_xyz_cmf(wl)).sum(0).numpy()
    x_catalogue = xyz0[0] / xyz0.sum()
    assert abs(chroma[90.0] - x_catalogue) < 0.02
    assert chroma[90.0] < chroma[30.0] < chroma[10.0] < chroma[1.0]
    assert chroma[1.0] - x_catalogue > 0.15
    # in the Dataset: red over blue grows as stars sink; above the atmosphere it does not
    rgb = ds.color.values[..., 0] / np.maximum(ds.color.values[..., 2], 1e-6)
    high = ds.above_horizon.values & (ds.altitude.values > 60.0)
    low = ds.above_horizon.values & (ds.altitude.values < 5.0)
    assert np.median(rgb[low]) > 3.0 * np.median(rgb[high])
    assert np.allclose(ds.color_exoatmospheric.values, bv_to_srgb(
        torch.as_tensor(ds.bv.values)).numpy())
    assert np.isfinite(ds.color.values).all()
    assert ((ds.color.values >= 0.0) & (ds.color.values <= 1.0 + 1e-12)).all()


def test_no_atmosphere_colour_is_exoatmospheric(atm):
    times = ["2025-09-07T20:00", "2025-09-08T02:00"]
    for options in ({"atmosphere": False}, {"atmosphere": atm, "reddening": False}):
        ds = observe(bright_stars(1.5), times, 52.5, 13.4, **options)
        assert ds.color.dims == ("time", "star", "channel")
        assert np.array_equal(ds.color.values[1], ds.color_exoatmospheric.values)


def test_apparent_colour_hard_cases_finite_with_gradients(atm, dtype):
    """Zenith, horizon, below the horizon, B − V at and beyond the grid ends."""
    from skytorch.stars.photometry import apparent_color, apparent_color_table

    table = apparent_color_table(atm, 0.0)
    altitude = torch.tensor([[math.pi / 2, 0.0, -0.05, 0.3]], dtype=dtype, requires_grad=True)
    bv = torch.tensor([-0.5, 0.65, 3.0, 4.0], dtype=dtype, requires_grad=True)
    colour = apparent_color(bv, altitude, table)
    assert colour.shape == (1, 4, 3) and colour.dtype == dtype
    assert torch.isfinite(colour).all()
    assert torch.allclose(colour.detach().amax(dim=-1), torch.ones(1, 4, dtype=dtype))
    colour.sum().backward()
    assert torch.isfinite(altitude.grad).all() and torch.isfinite(bv.grad).all()
    # the horizon is redder than the zenith for the same star
    pair = apparent_color(bv[1:2].detach(), torch.tensor([[math.pi / 2], [0.0]], dtype=dtype),
                          table)
    assert float(pair[1, 0, 2]) < float(pair[0, 0, 2])


def test_observe_colour_per_chunk_matches_apparent_colour(atm):
    """Check the per-chunk colour of observe against apparent_color.

    observe looks the colour up per chunk of times inside observe_tensors (per-star
    table); apparent_color on the whole (time, star) altitudes, and its two-node path on
    single instants, give the same colours.
    """
    from skytorch.stars.photometry import apparent_color, apparent_color_table

    catalog = bright_stars(3.0)
    times = np.datetime64("2025-09-07T18:00") + np.arange(200) * np.timedelta64(7, "m")
    ds = observe(catalog, times, 52.5, 13.4, atmosphere=atm)
    altitude = torch.deg2rad(torch.as_tensor(ds.altitude.values))
    bv = torch.as_tensor(catalog.bv.values)
    table = apparent_color_table(atm, 0.0)
    whole = apparent_color(bv, altitude, table).numpy()
    assert np.abs(ds.color.values - whole).max() < 1e-12
    instant = np.concatenate([apparent_color(bv, altitude[i:i + 1], table).numpy()
                              for i in (0, 57, 199)])
    assert np.abs(ds.color.values[[0, 57, 199]] - instant).max() < 1e-12


def test_observe_tensors_refuses_a_colour_table_of_other_stars(atm):
    from skytorch.stars import observe_tensors
    from skytorch.stars.photometry import apparent_color_table, star_color_table
    from skytorch.stars.positions import star_vectors, time_operators

    catalog = bright_stars(1.5)
    stars = star_vectors(catalog.ra.values, catalog.dec.values, catalog.pm_ra.values,
                         catalog.pm_dec.values, catalog.parallax.values)
    operators, velocity = time_operators(np.array(["2025-09-07T20:00"], dtype="M8[ns]"),
                                         52.5, 13.4, 0.0)
    vmag = torch.as_tensor(catalog.vmag.values)
    bv = torch.as_tensor(catalog.bv.values)
    other = star_color_table(bv[:3], apparent_color_table(atm, 0.0))
    with pytest.raises(ValueError, match="color_table"):
        observe_tensors(stars, vmag, bv, operators, velocity, None, None, color_table=other)


def test_bv_to_srgb_distinct_values_match_the_differentiable_path():
    """Without gradients each distinct B−V is converted once; with them, every star."""
    bv = torch.tensor([0.65, -0.2, 0.65, 1.5, -0.2, 0.65], dtype=torch.float64)
    once = bv_to_srgb(bv)
    every = bv_to_srgb(bv.clone().requires_grad_(True)).detach()
    assert once.shape == (6, 3)
    assert torch.allclose(once, every, rtol=0.0, atol=1e-12)
    assert torch.equal(once[0], once[2]) and torch.equal(once[1], once[4])


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_observe_tensors_in_place_path_matches_the_gradient_path(atm, dtype):
    """Check the in-place path of observe_tensors against its gradient path.

    Without gradients observe_tensors writes every chunk in place through scratch buffers;
    with them it builds new tensors (√(n² + e² + 1e-30) instead of hypot). Both give the same
    altitudes, azimuths, magnitudes, air masses and colours (several chunks, a partial
    last one), and the gradient of the magnitudes with respect to V is 1.
    """
    from skytorch.stars import observe_tensors
    from skytorch.stars.observation import refraction_table
    from skytorch.stars.photometry import apparent_color_table, extinction_table, star_color_table
    from skytorch.stars.positions import star_vectors, time_operators

    catalog = bright_stars(2.5)
    stars = star_vectors(catalog.ra.values, catalog.dec.values, catalog.pm_ra.values,
                         catalog.pm_dec.values, catalog.parallax.values, dtype=dtype)
    times = np.datetime64("2025-09-07T18:00", "ns") + np.arange(75) * np.timedelta64(9, "m")
    operators, velocity = time_operators(times, 52.5, 13.4, 0.0)
    vmag = torch.as_tensor(catalog.vmag.values, dtype=dtype)
    bv = torch.as_tensor(catalog.bv.values, dtype=dtype)
    tables = refraction_table(atm, 0.0), extinction_table(atm, 0.0, refraction=True)
    colours = star_color_table(bv, apparent_color_table(atm, 0.0))
    in_place = observe_tensors(stars, vmag, bv, operators, velocity, *tables,
                               time_chunk=16, color_table=colours)
    vmag_grad = vmag.clone().requires_grad_(True)
    recorded = observe_tensors(stars, vmag_grad, bv, operators, velocity, *tables,
                               time_chunk=16, color_table=colours)
    # float32: the two altitude formulas (hypot, √(n² + e² + 1e-30)) differ by rounding
    tolerance = 1e-12 if dtype == torch.float64 else 1e-5
    for name in ("altitude", "azimuth", "magnitude", "airmass", "color"):
        assert in_place[name].dtype == dtype
        assert torch.allclose(in_place[name], recorded[name].detach(), rtol=0,
                              atol=tolerance), name
    assert torch.equal(in_place["above_horizon"], recorded["above_horizon"])
    assert bool(in_place["above_horizon"].any()) and not bool(in_place["above_horizon"].all())
    (gradient,) = torch.autograd.grad(recorded["magnitude"].sum(), vmag_grad)
    assert torch.allclose(gradient, torch.full_like(gradient, float(len(times))))


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_star_color_table_shared_rows_match_the_per_star_table(atm, dtype):
    """Check the no-gradient colour table (one block per distinct B−V) against the per-star one.

    Without gradients stars of equal B−V share a block of rows, and values and slopes sit
    side by side (one gather in star_color); with gradients every star has its own block.
    Both give the same colours, and the site tables' complex pairs hold the same values
    and slopes as the real tables.
    """
    from skytorch.stars.observation import refraction_table, site_tables
    from skytorch.stars.photometry import apparent_color_table, star_color, star_color_table

    table = apparent_color_table(atm, 0.0)
    bv = torch.tensor([0.65, -0.2, 0.65, 1.5, 3.5, -0.2, 0.65, 0.0], dtype=dtype)
    shared = star_color_table(bv, table)
    per_star = star_color_table(bv.clone().requires_grad_(True), table)
    assert "rows" in shared and "rows" not in per_star
    assert shared["rows"].shape == (5 * table["linear_srgb"].shape[0], 6)
    assert shared["offsets"][0] == shared["offsets"][2] == shared["offsets"][6]
    altitude = torch.deg2rad(torch.linspace(-3.0, 90.0, 7 * 8, dtype=dtype)).reshape(7, 8)
    colour = star_color(altitude, shared)
    expected = star_color(altitude, {**per_star, "values": per_star["values"].detach(),
                                     "slopes": per_star["slopes"].detach()})
    assert colour.shape == (7, 8, 3)
    assert torch.allclose(colour, expected, rtol=0.0, atol=1e-12 if dtype == torch.float64
                          else 1e-6)
    tables = site_tables(refraction_table(atm, 0.0), extinction_table(atm, 0.0), dtype)
    assert torch.equal(tables["pairs"].real, tables["values"])
    assert torch.equal(tables["pairs"].imag, tables["slopes"])
