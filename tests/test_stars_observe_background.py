"""observe(..., background=Dataset): visibility from the sky where each star is."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from skytorch.stars import bright_stars, limiting_magnitude, observe

TIME = "2025-09-07T21:00"
SITE = (52.5, 13.4)
#: Falchi et al. 2016 (Sci. Adv. 2, e1600377): natural sky 174 µcd m⁻² ≙ 22.0 mag arcsec⁻²
FALCHI_NATURAL_CD_M2 = 174e-6


@pytest.fixture(scope="module")
def catalog():
    return bright_stars(5.0)


def _grid(values, name="sky_brightness", units="mag arcsec-2", times=None):
    altitude = np.linspace(-2.0, 90.0, 47)
    azimuth = np.arange(0.0, 360.0, 5.0)
    data = np.broadcast_to(values(altitude[:, None], azimuth[None, :]),
                           (altitude.size, azimuth.size))
    dims = ("altitude", "azimuth")
    if times is not None:
        data = np.broadcast_to(data, (times, *data.shape))
        dims = ("time", *dims)
    return xr.Dataset({name: (dims, np.array(data), {"units": units})},
                      coords={"altitude": altitude, "azimuth": azimuth})


def test_uniform_background_equals_scalar_form(catalog):
    scalar = observe(catalog, TIME, *SITE, sky_brightness_mag_arcsec2=20.0)
    field = observe(catalog, TIME, *SITE, background=_grid(lambda a, z: 20.0 + 0 * a))
    assert field.limiting_magnitude.dims == ("time", "star")
    np.testing.assert_allclose(field.sky_brightness.values, 20.0, atol=1e-12)
    np.testing.assert_array_equal(field.visible.values, scalar.visible.values)
    assert int(field.n_visible[0]) == int(scalar.n_visible[0])


def test_bright_half_of_the_sky_hides_its_stars(catalog):
    """City glow in the east (azimuth 0–180°), dark sky in the west."""
    background = _grid(lambda a, z: np.where(z < 180.0, 16.0, 22.0))
    ds = observe(catalog, TIME, *SITE, background=background)
    az, limit = ds.azimuth.values[0], ds.limiting_magnitude.values[0]
    east = (az > 10.0) & (az < 170.0)
    west = (az > 190.0) & (az < 355.0)
    np.testing.assert_allclose(limit[east], float(limiting_magnitude(16.0)), atol=1e-9)
    np.testing.assert_allclose(limit[west], float(limiting_magnitude(22.0)), atol=1e-9)
    above = ds.above_horizon.values[0]
    magnitude = ds.magnitude.values[0]
    assert not ds.visible.values[0][east & above & (magnitude > limit)].any()
    # a 4.5 mag star is seen in the dark west, not in the bright east
    faint = (magnitude > 4.4) & (magnitude < 5.0) & above
    assert ds.visible.values[0][west & faint].all() and (west & faint).any()
    assert not ds.visible.values[0][east & faint].any() and (east & faint).any()


def test_luminance_in_candela_matches_a_published_dark_sky(catalog):
    """174 µcd m⁻² (Falchi 2016) gives the limit of 22.0 mag arcsec⁻² within 0.02 mag."""
    ds = observe(catalog, TIME, *SITE,
                 background=_grid(lambda a, z: FALCHI_NATURAL_CD_M2 + 0 * a, "luminance",
                                  "cd m-2"))
    np.testing.assert_allclose(ds.sky_brightness.values, 22.0, atol=0.02)
    assert abs(float(ds.limiting_magnitude.values.mean()) - float(limiting_magnitude(22.0))
               ) < 0.02


def test_background_over_time_and_a_gradient_with_altitude(catalog):
    times = np.array(["2025-09-07T21:00", "2025-09-07T23:00"], dtype="datetime64[ns]")
    background = _grid(lambda a, z: 18.0 + a / 30.0 + 0 * z, times=2)
    background["sky_brightness"][1] += 1.0
    ds = observe(catalog, times, *SITE, background=background)
    above = ds.above_horizon.values
    alt = ds.altitude.values
    np.testing.assert_allclose(ds.sky_brightness.values[0][above[0]],
                               18.0 + alt[0][above[0]] / 30.0, atol=1e-9)
    np.testing.assert_allclose(ds.sky_brightness.values[1][above[1]],
                               19.0 + alt[1][above[1]] / 30.0, atol=1e-9)


def test_background_times_taken_by_their_labels(catalog):
    """A background with a time coordinate gives each instant its own row, in any order."""
    times = np.array(["2025-09-07T21:00", "2025-09-07T23:00"], dtype="datetime64[ns]")
    background = _grid(lambda a, z: 18.0 + 0 * a, times=2).assign_coords(time=times)
    background["sky_brightness"][1] += 2.0
    reversed_ = observe(catalog, times[::-1], *SITE, background=background)
    np.testing.assert_allclose(reversed_.sky_brightness.values[0], 20.0, atol=1e-12)
    np.testing.assert_allclose(reversed_.sky_brightness.values[1], 18.0, atol=1e-12)
    stale = background.assign_coords(time=times - np.timedelta64(365, "D"))
    with pytest.raises(ValueError, match="background has no row for the times"):
        observe(catalog, times, *SITE, background=stale)


def test_bad_backgrounds_raise(catalog):
    good = _grid(lambda a, z: 21.0 + 0 * a)
    with pytest.raises(ValueError, match="not both"):
        observe(catalog, TIME, *SITE, sky_brightness_mag_arcsec2=21.0, background=good)
    with pytest.raises(ValueError, match="units"):
        observe(catalog, TIME, *SITE, background=_grid(lambda a, z: 21.0 + 0 * a,
                                                       units="W m-2"))
    with pytest.raises(TypeError, match="background"):
        observe(catalog, TIME, *SITE, background={"sky_brightness": 21.0})
    high = good.sel(altitude=slice(30.0, 90.0))
    with pytest.raises(ValueError, match="do not cover"):
        observe(catalog, TIME, *SITE, background=high)
    with pytest.raises(ValueError, match="times"):
        observe(catalog, TIME, *SITE, background=_grid(lambda a, z: 21.0 + 0 * a, times=3))
    with pytest.raises(ValueError, match=r"background\['sky_brightness'\] as a surface"):
        observe(catalog, TIME, *SITE, background=_grid(lambda a, z: 100.0 + 0 * a))
    with pytest.raises(ValueError, match=r"background\['luminance'\] as a surface"):
        observe(catalog, TIME, *SITE, background=_grid(lambda a, z: 1e30 + 0 * a,
                                                       "luminance", "cd m-2"))
    with pytest.raises(TypeError, match="must hold numbers"):
        observe(catalog, TIME, *SITE, background=good.astype(str))


def test_elevated_observer_needs_a_background_below_zero(catalog):
    """From 3 km stars are up down to -1.6 deg: a background from 0 deg does not cover them."""
    times = np.datetime64("2025-09-07T18:00") + np.arange(0, 720, 30) * np.timedelta64(1, "m")
    lat, lon = SITE[0], SITE[1]
    above_zero = _grid(lambda a, z: 21.0 + 0 * a).sel(altitude=slice(0.0, None))
    with pytest.raises(ValueError, match="dip of the horizon"):
        observe(catalog, times, lat, lon, 3000.0, background=above_zero)
    ds = observe(catalog, times, lat, lon, 3000.0, background=_grid(lambda a, z: 21.0 + 0 * a))
    assert float(ds.altitude.where(ds.above_horizon).min()) < 0.0
