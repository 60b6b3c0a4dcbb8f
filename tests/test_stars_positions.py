"""Apparent star positions against skyfield (independent code), and hard cases."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from skytorch.constants import ARCSECOND, DEGREE
from skytorch.ephemeris import icrs_to_horizontal_matrices, load_ephemeris, skyfield_time
from skytorch.stars import (
    bright_stars,
    horizontal_vectors,
    observe,
    star_vectors,
    time_operators,
)
from skytorch.stars.positions import aberration_operators, horizontal_planes

#: instants 1900–2050 including both sides of the 2016-12-31 leap second
TIMES = np.array(["1900-03-01T03:00", "1931-11-17T14:25", "1977-05-04T21:10",
                  "2016-12-31T23:59:59", "2017-01-01T00:00:00", "2049-11-30T05:00"],
                 dtype="datetime64[ns]")
SITES = [(52.5, 13.4, 34.0), (-24.63, -70.40, 2635.0), (19.82, -155.47, 4205.0),
         (-89.99, 0.0, 2835.0)]
#: gravitational light deflection by the Sun is not modelled: 0.155″ at 3° from the Sun
SUN_EXCLUSION_DEG = 3.0


@pytest.fixture(scope="module")
def sample():
    ds = bright_stars(6.5)
    rng = np.random.default_rng(2024)
    rows = np.concatenate([rng.choice(ds.sizes["star"], 60, replace=False),
                           np.nonzero(np.isin(ds.hip.values, [71683, 11767, 32349]))[0]])
    return ds.isel(star=rows)


def _skyfield_altaz(sub, times, lat, lon, elevation):
    from skyfield.api import Star, wgs84

    ephemeris = load_ephemeris()
    observer = ephemeris["earth"] + wgs84.latlon(lat, lon, elevation)
    star = Star(ra_hours=sub.ra.values / 15.0, dec_degrees=sub.dec.values,
                ra_mas_per_year=sub.pm_ra.values, dec_mas_per_year=sub.pm_dec.values,
                parallax_mas=np.clip(sub.parallax.values, 0.0, None))
    t = skyfield_time(times)
    altitude, azimuth, elongation = [], [], []
    for i in range(len(times)):
        apparent = observer.at(t[i]).observe(star).apparent()
        alt, az, _ = apparent.altaz()
        sun = observer.at(t[i]).observe(ephemeris["sun"]).apparent()
        altitude.append(alt.radians)
        azimuth.append(az.radians)
        elongation.append(apparent.separation_from(sun).degrees)
    return np.array(altitude), np.array(azimuth), np.array(elongation)


def _separation(alt1, az1, alt2, az2):
    """Great-circle angle between two horizontal directions [rad]."""
    cos = (np.sin(alt1) * np.sin(alt2)
           + np.cos(alt1) * np.cos(alt2) * np.cos(az1 - az2))
    sin = np.hypot(np.cos(alt2) * np.sin(az1 - az2),
                   np.cos(alt1) * np.sin(alt2) - np.sin(alt1) * np.cos(alt2)
                   * np.cos(az1 - az2))
    return np.arctan2(sin, cos)


@pytest.mark.parametrize("site", SITES, ids=["berlin", "paranal", "maunakea", "southpole"])
def test_altaz_matches_skyfield_within_one_arcsecond(sample, site, dtype):
    lat, lon, elevation = site
    ds = observe(sample, TIMES, lat, lon, elevation, atmosphere=False, dtype=dtype)
    ref_alt, ref_az, elongation = _skyfield_altaz(sample, TIMES, lat, lon, elevation)
    error = _separation(np.deg2rad(ds.altitude.values.astype(float)),
                        np.deg2rad(ds.azimuth.values.astype(float)), ref_alt, ref_az)
    far = elongation > SUN_EXCLUSION_DEG
    assert far.sum() > 0.9 * far.size
    assert error[far].max() < 1.0 * ARCSECOND
    assert np.median(error) < (0.02 if dtype == torch.float64 else 0.1) * ARCSECOND


def test_fast_planes_equal_reference_aberration(sample):
    stars = star_vectors(sample.ra.values, sample.dec.values, sample.pm_ra.values,
                         sample.pm_dec.values, sample.parallax.values)
    operators, velocity = time_operators(TIMES, 30.0, -60.0)
    reference = horizontal_vectors(stars, operators, velocity)
    folded = aberration_operators(operators, velocity)
    north, east, up = horizontal_planes(stars.T.contiguous(), folded)
    fast = torch.stack([north, east, up], dim=-1)
    fast = fast / torch.linalg.vector_norm(fast, dim=-1, keepdim=True)
    assert torch.allclose(fast, reference, atol=1e-13, rtol=0.0)


def _star_at(direction_horizontal, time, lat, lon):
    """RA/Dec [deg] of a fixed star whose geometric direction is the given horizontal one."""
    matrix = icrs_to_horizontal_matrices([time], lat, lon)[0]
    u = matrix.T @ torch.as_tensor(direction_horizontal, dtype=torch.float64)
    ra = float(torch.rad2deg(torch.atan2(u[1], u[0]))) % 360.0
    dec = float(torch.rad2deg(torch.asin(u[2].clamp(-1.0, 1.0))))
    return ra, dec


def _single_star_vectors(ra, dec, dtype):
    ra_t = torch.tensor([ra], dtype=torch.float64, requires_grad=True)
    dec_t = torch.tensor([dec], dtype=torch.float64, requires_grad=True)
    stars = star_vectors(ra_t, dec_t, torch.zeros(1), torch.zeros(1), torch.zeros(1),
                         dtype=dtype)
    return ra_t, dec_t, stars


@pytest.mark.parametrize("lat", [48.0, 90.0, -90.0], ids=["mid", "northpole", "southpole"])
def test_zenith_star_finite_values_and_gradients(dtype, lat):
    time = "2024-03-01T00:00"
    ra, dec = _star_at([0.0, 0.0, 1.0], time, lat, 11.0)
    ra_t, dec_t, stars = _single_star_vectors(ra, dec, dtype)
    operators, _ = time_operators([time], lat, 11.0, aberration=False, parallax=False,
                                  anchor_minutes=None)
    from skytorch.stars import observe_tensors

    out = observe_tensors(stars, torch.zeros(1), torch.zeros(1), operators, None, None, None)
    altitude = out["altitude"]
    assert torch.isfinite(out["azimuth"]).all()
    assert float(altitude.detach()) > torch.pi / 2 - (1e-7 if dtype == torch.float32 else 1e-12)
    altitude.sum().backward()
    assert torch.isfinite(ra_t.grad).all() and torch.isfinite(dec_t.grad).all()


def test_pole_star_seen_from_the_pole_is_at_the_zenith():
    """A star at the celestial pole of date is at the zenith of a polar observer."""
    time = "2030-06-01T12:00"
    for lat in (90.0, -90.0):
        ra, dec = _star_at([0.0, 0.0, 1.0], time, lat, 0.0)
        assert abs(abs(dec) - 90.0) < 0.5  # the pole of date is < 0.5° from the ICRS pole
        ds = bright_stars(6.5).isel(star=slice(0, 1)).copy()
        ds["ra"][:] = ra
        ds["dec"][:] = dec
        ds["pm_ra"][:] = ds["pm_dec"][:] = ds["parallax"][:] = 0.0
        obs = observe(ds, time, lat, 0.0, atmosphere=False)
        # annual aberration moves it by up to 20.5″
        assert 90.0 - float(obs.altitude[0, 0]) < 21.0 / 3600.0


def test_altitude_at_the_pole_is_declination_of_date(sample):
    """At the north pole the altitude of every star is its declination of date."""
    ds = observe(sample, TIMES[:2], 90.0, 0.0, atmosphere=False)
    ref_alt, _, _ = _skyfield_altaz(sample, TIMES[:2], 90.0, 0.0, 0.0)
    assert np.abs(np.deg2rad(ds.altitude.values) - ref_alt).max() < 1.0 * ARCSECOND


def test_leap_second_rotates_the_sky_by_two_seconds(sample):
    """23:59:59 → 00:00:00 across the 2016 leap second is 2 SI seconds: 30.1″ of rotation."""
    ds = observe(sample.isel(star=slice(0, 5)), TIMES[3:5], 0.0, 0.0, atmosphere=False)
    matrices = icrs_to_horizontal_matrices(TIMES[3:5], 0.0, 0.0)
    rotation = matrices[1] @ matrices[0].T
    angle = torch.arccos(((torch.trace(rotation) - 1.0) / 2.0).clamp(-1.0, 1.0))
    sidereal_rate = 2.0 * np.pi / 86164.0905  # [rad/s]
    assert float(angle) == pytest.approx(2.0 * sidereal_rate, rel=1e-3)
    assert np.isfinite(ds.altitude.values).all()


def test_empty_catalogue_observes_nothing():
    ds = observe(bright_stars(-5.0), ["2025-01-01T00:00", "2025-01-01T01:00"], 10.0, 20.0,
                 atmosphere=False)
    assert ds.sizes["star"] == 0 and ds.sizes["time"] == 2
    assert ds.n_visible.values.tolist() == [0, 0]


def test_bad_observer_raises():
    with pytest.raises(ValueError, match="lat_deg"):
        observe(bright_stars(1.0), "2025-01-01", 95.0, 0.0, atmosphere=False)
    with pytest.raises(ValueError):
        observe(bright_stars(1.0), "1800-01-01", 45.0, 0.0, atmosphere=False)


def test_time_operators_combine_parallax():
    """Annual parallax of alpha Cen (0.75″) is in the operators' last column."""
    operators, _ = time_operators(["2020-01-01"], 0.0, 0.0)
    earth = operators[0, :, 6]
    # -M e with |e| ≈ 1 au
    assert float(torch.linalg.vector_norm(earth)) == pytest.approx(0.983, abs=0.01)
    assert DEGREE > 0


def test_anchored_precession_nutation_matches_direct_matrices():
    """Precession-nutation every 30 min plus Earth rotation about the pole: < 3 mas."""
    from skytorch.stars.positions import _rotation_matrices

    times = np.array(["2016-12-31T23:40", "2016-12-31T23:59:59", "2017-01-01T00:00:00",
                      "2017-01-01T00:14:59", "1900-05-01T12:07", "2050-01-01T00:00"],
                     dtype="datetime64[ns]")
    for lat in (52.5, -89.9, 0.0):
        anchored = _rotation_matrices(times, lat, 13.4, 0.0, 30.0)
        direct = _rotation_matrices(times, lat, 13.4, 0.0, None)
        assert float((anchored - direct).abs().max()) < 3e-3 * ARCSECOND


def test_several_observers_stack_along_observer(sample):
    sub = sample.isel(star=slice(0, 8))
    both = observe(sub, TIMES[:2], [52.5, -24.63], [13.4, -70.40], [34.0, 2635.0],
                   atmosphere=False)
    assert both.altitude.dims == ("observer", "time", "star")
    assert both.lat.attrs["units"] == "degree_north"
    for i, (lat, lon, elevation) in enumerate(SITES[:2]):
        single = observe(sub, TIMES[:2], lat, lon, elevation, atmosphere=False)
        assert np.array_equal(both.altitude.values[i], single.altitude.values)
