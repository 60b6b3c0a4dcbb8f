"""Input contract of the stars' public entry points, as hypothesis property tests.

Every call either returns an all-finite result within its physical bounds, or raises
``ValueError``/``TypeError`` naming one of its parameters (:mod:`tests._contract`). Each
argument is drawn from valid values (the ends of the documented ranges included: the
ephemeris range ``TIME_MIN`` … ``TIME_MAX``, the poles, a 0.1 mm aperture), hard values
and bad ones (wrong types, None, strings, NaN/inf, out-of-range numbers, shapes that do
not match). A call with a bad input must be refused; a call with only valid inputs must
be accepted.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from _contract import arg, bad_values, call_and_check, expect_rejected
from hypothesis import given, settings
from hypothesis import strategies as st

from skytorch.ephemeris import TIME_MAX, TIME_MIN
from skytorch.stars import bright_stars, observe
from skytorch.stars.photometry import (
    bv_to_srgb,
    extinction,
    extinction_coefficient,
    relative_brightness,
)
from skytorch.stars.positions import star_vectors
from skytorch.stars.scintillation import scintillation_index, twinkle
from skytorch.stars.visibility import limiting_magnitude, muller_day_night_factor

SETTINGS = settings(max_examples=60, derandomize=True, deadline=None)
BAD = bad_values()


@pytest.fixture(scope="module")
def atmosphere():
    from skytorch.atmosphere import Atmosphere

    return Atmosphere.earth()


CATALOG = bright_stars(1.0)
TIMES_VALID = ["2025-09-07T20:00", TIME_MAX, TIME_MIN, ["2025-01-01T00:00", "2025-06-01T03:00"],
               np.array(["2030-03-20T12:00"], dtype="datetime64[ns]")]
TIMES_BAD = [None, 3, "garbage", "2100-01-01", np.datetime64("NaT"), [],
             TIME_MAX + np.timedelta64(1, "s")]
LAT_VALID = [52.5, 90.0, -90.0, 0.0, np.array([10.0, -33.0])]
LAT_BAD = [*BAD, 91.0, -90.5, np.array([[1.0]])]
LON_VALID = [13.4, -180.0, 359.999, 0, np.array([1.0, 2.0, 3.0])]
LON_BAD = [*BAD, -181.0, 360.0]
ELEVATION_VALID = [0.0, 1e4, 2000]
ELEVATION_BAD = [*BAD, -1.0, 2e4]


@SETTINGS
@given(catalog=arg([CATALOG], [None, "bsc5", 3, CATALOG.drop_vars("bv")]),
       times=arg(TIMES_VALID, TIMES_BAD), lat=arg(LAT_VALID, LAT_BAD),
       lon=arg(LON_VALID, LON_BAD), elevation=arg(ELEVATION_VALID, ELEVATION_BAD),
       use_atmosphere=arg([False, True, None], ["earth", 3, True]),
       refraction=arg([True, False], ["yes", 1, None]),
       sky=arg([22.0, 17, np.array([21.0])], [*BAD, 50.0, np.array([20.0, 21.0, 22.0])]),
       aperture=arg([0.007, 1e-4, 1.0], [*BAD, 0.0, 1e-5]),
       twinkle_samples=arg([0, 1, 3], [-1, 2.5, "3", None]),
       visibility=arg(["schaefer1990", "muller2012"], ["x", 3]),
       dtype=arg([torch.float64, torch.float32], ["float64", torch.int64, None]),
       misspelled=st.sampled_from([None, None, None, "twinkle_sample"]))
def test_observe_contract(atmosphere, catalog, times, lat, lon, elevation, use_atmosphere,
                          refraction, sky, aperture, twinkle_samples, visibility, dtype,
                          misspelled):
    # "use_atmosphere" True stands for the shared Atmosphere object (tables cached)
    value, flag = use_atmosphere
    if value is True and not flag:
        use_atmosphere = (atmosphere, False)
    elif value is None:
        use_atmosphere = (False, False)  # the default atmosphere is the shared one's twin
    # a (3,) sky brightness matches 3 times only; 3 longitudes do not match 2 latitudes
    arguments = {"catalog": catalog, "times": times, "lat_deg": lat, "lon_deg": lon,
                 "elevation_m": elevation, "atmosphere": use_atmosphere,
                 "refraction": refraction, "sky_brightness_mag_arcsec2": sky,
                 "aperture_m": aperture, "twinkle_samples": twinkle_samples,
                 "visibility": visibility, "dtype": dtype}
    sizes = {np.size(v) for v, _ in (lat, lon, elevation) if np.ndim(v) > 0}
    result = call_and_check(observe, arguments, misspelled=misspelled, bad=len(sizes) > 1)
    if not isinstance(result, Exception):
        assert bool((np.abs(result["altitude"].values) <= 90.0).all())
        assert bool((result["relative_brightness"].values >= 0).all())
        if twinkle_samples[0]:
            assert result.sizes["sample"] == twinkle_samples[0]


@settings(max_examples=20, derandomize=True, deadline=None)
@given(times=arg(TIMES_VALID), lat=arg(LAT_VALID), lon=arg(LON_VALID[:-1]),
       elevation=arg(ELEVATION_VALID), use_atmosphere=st.booleans(),
       refraction=arg([True, False]), sky=arg([22.0, 17, np.array([21.0])]),
       aperture=arg([0.007, 1e-4, 1.0]), twinkle_samples=arg([0, 1, 3]),
       visibility=arg(["schaefer1990", "muller2012"]),
       dtype=arg([torch.float64, torch.float32]))
def test_observe_accepts_valid_inputs(atmosphere, times, lat, lon, elevation, use_atmosphere,
                                      refraction, sky, aperture, twinkle_samples, visibility,
                                      dtype):
    """Only valid (and hard) inputs: every call returns a finite, in-bounds Dataset."""
    arguments = {"catalog": (CATALOG, False), "times": times, "lat_deg": lat, "lon_deg": lon,
                 "elevation_m": elevation,
                 "atmosphere": (atmosphere if use_atmosphere else False, False),
                 "refraction": refraction, "sky_brightness_mag_arcsec2": sky,
                 "aperture_m": aperture, "twinkle_samples": twinkle_samples,
                 "visibility": visibility, "dtype": dtype}
    result = call_and_check(observe, arguments)
    assert bool((np.abs(result["altitude"].values) <= 90.0).all())
    assert bool((result["airmass"].values >= 1.0 - 1e-9).all())
    assert bool(((result["relative_brightness"].values >= 0)).all())


def test_observe_accepts_the_documented_time_range():
    """TIME_MIN and TIME_MAX themselves are valid instants of observe (as of parse_times)."""
    for instant in (TIME_MIN, TIME_MAX):
        ds = observe(CATALOG, instant, 52.5, 13.4, atmosphere=False)
        assert ds["time"].values[0] == instant
        assert np.isfinite(ds["altitude"].values).all()


def test_twinkle_with_tiny_aperture_at_the_horizon():
    """observe(twinkle_samples=1, aperture_m=1e-4): σ_I² ~ 1e7 at the horizon, finite."""
    ds = observe(CATALOG, "2025-09-07T20:00", 52.5, 13.4, twinkle_samples=1,
                 aperture_m=1e-4)
    assert float(ds["scintillation_index"].max()) > 1e6
    assert np.isfinite(ds["twinkle"].values).all() and (ds["twinkle"].values > 0).all()


AIRMASS_VALID = [1.0, 40.0, torch.tensor([1, 2, 3]), torch.tensor([[1.0], [9.0]])]
AIRMASS_BAD = [*BAD, 0.5, -1.0, 1e5]


@SETTINGS
@given(airmass=arg(AIRMASS_VALID, AIRMASS_BAD),
       aperture=arg([0.007, 1e-4, 100.0], [*BAD, 0.0, 1000.0]),
       exposure=arg([0.1, 1e-6, 10], [*BAD, 0.0, -1.0]),
       altitude=arg([0.0, 4000.0, -500.0], [*BAD, 2e4]),
       model=arg(["young1967", "osborn2015"], ["young", 3]))
def test_scintillation_index_contract(airmass, aperture, exposure, altitude, model):
    arguments = {"airmass": airmass, "aperture_m": aperture, "exposure_s": exposure,
                 "altitude_m": altitude, "model": model}
    call_and_check(scintillation_index, arguments, bounds=(0.0, math.inf))


@SETTINGS
@given(variance=arg([0.0, 0.01, 1e7, torch.tensor([[0.1, 1e3]]), torch.tensor([0, 1])],
                    [*BAD, -0.1, torch.tensor([0.1, math.inf])]),
       n=arg([1, 5, 300], [0, -1, 2.5, "4", None]),
       interval=arg([0.01, 1e-9], [*BAD, 0.0]),
       seed=arg([0, 12345], [-1, 1.5, "7", None]))
def test_twinkle_contract(variance, n, interval, seed):
    arguments = {"scintillation_index_value": variance, "n_samples": n,
                 "sample_interval_s": interval, "seed": seed}
    call_and_check(twinkle, arguments, bounds=(0.0, math.inf))


@SETTINGS
@given(sky=arg([22.0, 4.0, torch.tensor([17, 21]), -20.0, 40.0], [*BAD, 41.0, -21.0]),
       pupil=arg([7.0, 1.0, 10.0], [*BAD, 0.5, 11.0]))
def test_limiting_magnitude_contract(sky, pupil):
    call_and_check(limiting_magnitude, {"sky_mag_arcsec2": sky, "pupil_diameter_mm": pupil},
                   bounds=(-40.0, 12.0))


@SETTINGS
@given(altitude=arg([0.0, -math.pi / 2, math.pi / 2, torch.tensor([0, 1])], [*BAD, 2.0]))
def test_day_night_factor_contract(altitude):
    call_and_check(muller_day_night_factor, {"sun_altitude_rad": altitude}, bounds=(0.0, 1.0))


@SETTINGS
@given(magnitude=arg([1.0, torch.tensor([-1, 6, 30])], [*BAD]),
       control=arg([6.0, -30.0, 40.0], [*BAD, 41.0]))
def test_relative_brightness_contract(magnitude, control):
    call_and_check(relative_brightness, {"magnitude": magnitude, "control_magnitude": control},
                   bounds=(0.0, math.inf))


@SETTINGS
@given(bv=arg([0.65, torch.tensor([-0.3, 2.0, 5.0]), torch.tensor([0, 1])],
              [*BAD, 11.0, -6.0]))
def test_bv_to_srgb_contract(bv):
    call_and_check(bv_to_srgb, {"bv": bv}, bounds=(0.0, 1.0))


@SETTINGS
@given(ra=arg([torch.tensor([10.0, 200.0]), torch.tensor([0, 359])], [*BAD, 800.0]),
       dec=arg([torch.tensor([-90.0, 90.0]), torch.tensor([0, 45])],
               [*BAD, torch.tensor([91.0, 0.0]), torch.ones(3), torch.ones(2, 2)]),
       pm=arg([torch.tensor([0.0, 1e3]), 5.0], [*BAD]),
       parallax=arg([torch.tensor([1.0, -0.5]), torch.tensor([0, 7])], [*BAD]),
       dtype=arg([torch.float64, torch.float32], ["float32", torch.int32]))
def test_star_vectors_contract(ra, dec, pm, parallax, dtype):
    arguments = {"ra_deg": ra, "dec_deg": dec, "pm_ra_mas_yr": pm, "pm_dec_mas_yr": pm,
                 "parallax_mas": parallax, "dtype": dtype}
    result = call_and_check(star_vectors, arguments)
    if not isinstance(result, Exception):
        assert result.shape == (2, 8)
        np.testing.assert_allclose(result[:, :3].norm(dim=-1).numpy(), 1.0, rtol=1e-6)


def test_extinction_refuses_bad_tables_and_shapes():
    table = {"offset": torch.zeros(16), "colour": torch.zeros(16), "airmass": torch.ones(16)}
    expect_rejected(lambda: extinction(torch.zeros(3), torch.zeros(2, 4), table),
                    ("bv", "apparent_altitude_rad"))
    expect_rejected(lambda: extinction(torch.zeros(3), torch.zeros(2, 3), None), ("table",
                                                                                  "extinction_table"))
    expect_rejected(lambda: extinction(torch.zeros(3), torch.full((2, 3), math.nan), table),
                    ("apparent_altitude_rad",))


@pytest.mark.parametrize("atmosphere_value", ["earth", None, 3, object()])
def test_extinction_coefficient_refuses_non_atmospheres(atmosphere_value):
    expect_rejected(lambda: extinction_coefficient(atmosphere_value), ("atmosphere",))


# ------------------------------------------- spectrum functions behind star colours ---

WAVELENGTHS = torch.tensor([450.0, 550.0, 650.0])


@SETTINGS
@given(flux=arg([torch.ones(3), torch.ones(2, 3), torch.tensor([1, 2, 3])],
                [*BAD, torch.ones(4), -torch.ones(3), torch.tensor([1.0, math.nan, 1.0])]),
       wavelength=arg([WAVELENGTHS, [450, 550, 650]],
                      [*BAD, WAVELENGTHS[None], torch.tensor([550.0, 550.0, 600.0])]),
       band=arg(["V", "B"], ["Q", 3, None]))
def test_spectrum_to_magnitude_contract(flux, wavelength, band):
    from skytorch.spectrum import spectrum_to_magnitude

    call_and_check(spectrum_to_magnitude, {"spectral_flux": flux, "wavelength_nm": wavelength,
                                           "band": band}, bounds=(-30.0, 40.0))


@SETTINGS
@given(wavelength=arg([WAVELENGTHS, 550.0, torch.tensor([[500.0], [600.0]])],
                      [*BAD, 0.0, -5.0]),
       temperature=arg([5772.0, torch.tensor([3000, 6000, 10000]), 1.0,
                        torch.ones(2) * 5000.0], [*BAD, 0.0, -5.0]))
def test_blackbody_radiance_contract(wavelength, temperature):
    from skytorch.spectrum import blackbody_radiance

    bad = False
    if not wavelength[1] and not temperature[1]:
        try:
            np.broadcast_shapes(np.shape(np.asarray(wavelength[0])),
                                np.shape(np.asarray(temperature[0])))
        except ValueError:
            bad = True
    call_and_check(blackbody_radiance, {"wavelength_nm": wavelength,
                                        "temperature_k": temperature}, bad=bad,
                   bounds=(0.0, math.inf))


@SETTINGS
@given(preset=arg(["rgb", "cie5", "bands15"], ["x", 3, None]),
       dtype=arg([torch.float64, torch.float32], ["float64", torch.int64, None]))
def test_wavelength_grid_contract(preset, dtype):
    from skytorch.spectrum import wavelength_grid

    call_and_check(wavelength_grid, {"preset": preset, "dtype": dtype}, bounds=(300.0, 900.0))


def test_observe_an_empty_catalogue():
    """A limit brighter than every star: no stars, no visible star, no error."""
    empty = bright_stars(-2.0)
    assert empty.sizes["star"] == 0
    ds = observe(empty, ["2025-09-07T20:00", "2025-09-07T21:00"], 52.5, 13.4)
    assert ds.sizes["star"] == 0 and ds.color.shape == (2, 0, 3)
    assert (ds.n_visible.values == 0).all()


@pytest.mark.parametrize("value", [float("nan"), float("inf"), -1e6])
def test_observe_refuses_bad_catalogue_magnitudes(value):
    catalog = bright_stars(2.0)
    catalog["vmag"] = catalog["vmag"].copy()
    catalog["vmag"][0] = value
    with pytest.raises(ValueError, match=r"catalog\['vmag'\]"):
        observe(catalog, "2025-09-07T20:00", 52.5, 13.4)


def test_observe_refuses_inputs_that_require_a_gradient():
    """A Dataset holds no gradient: one asked for is refused, not detached."""
    from skytorch.atmosphere import Atmosphere

    catalog = bright_stars(2.0)
    wanted = torch.tensor(2.0, dtype=torch.float64, requires_grad=True)
    cases = ({"sky_brightness_mag_arcsec2": wanted * 10.0},
             {"lat_deg": wanted * 26.0},
             {"atmosphere": Atmosphere.earth(turbidity=wanted)})
    for keywords in cases:
        arguments = {"lat_deg": 52.5, "lon_deg": 13.4, **keywords}
        with pytest.raises(ValueError, match=f"{next(iter(keywords))}.* a gradient"):
            observe(catalog, "2025-09-07T20:00", **arguments)


def test_several_observers_twinkle_independently_and_none_is_refused():
    """Observer k draws its twinkle from SeedSequence([seed, k]); the seed given is kept."""
    catalog = bright_stars(2.0)
    ds = observe(catalog, ["2025-09-07T21:00"], [52.5, 52.5], [13.4, 13.41],
                 twinkle_samples=200, seed=7)
    first, second = (ds.twinkle.isel(observer=k).values.ravel() for k in (0, 1))
    assert abs(np.corrcoef(first, second)[0, 1]) < 0.05       # was 1.0: one seed for all
    assert int(ds.attrs["parameter_seed"]) == 7
    again = observe(catalog, ["2025-09-07T21:00"], [52.5, 52.5], [13.4, 13.41],
                    twinkle_samples=200, seed=7)
    np.testing.assert_array_equal(again.twinkle.values, ds.twinkle.values)
    with pytest.raises(ValueError, match="lat_deg must hold at least one observer"):
        observe(catalog, "2025-09-07T21:00", [], [])


def test_elevated_observer_without_air_sees_down_to_the_geometric_dip():
    """atmosphere=False from 3 km: the horizon is acos(R / (R + h)) = 1.758 deg below 0."""
    from skytorch.constants import EARTH_MEAN_RADIUS_M

    times = np.datetime64("2025-09-07T18:00") + np.arange(0, 720, 10) * np.timedelta64(1, "m")
    ds = observe(bright_stars(3.0), times, 46.5, 7.0, 3000.0, atmosphere=False)
    dip = math.degrees(math.acos(EARTH_MEAN_RADIUS_M / (EARTH_MEAN_RADIUS_M + 3000.0)))
    assert abs(dip - 1.758) < 1e-3
    altitude, above = ds.altitude.values, ds.above_horizon.values
    assert altitude[above].min() >= -dip and (above & (altitude < 0.0)).any()
    assert not above[altitude < -dip].any()


@pytest.mark.parametrize(("epoch", "error"), [(float("nan"), ValueError), (5000.0, ValueError),
                                              ("J2000", TypeError)])
def test_observe_refuses_a_bad_catalogue_epoch(epoch, error):
    catalog = bright_stars(2.0)
    catalog.attrs["epoch_jyear"] = epoch
    with pytest.raises(error, match="epoch_jyear"):
        observe(catalog, "2025-09-07T21:00", 52.5, 13.4)


def test_observer_set_up_gradients_are_refused_not_dropped():
    """Scalars of the observing set-up became Python floats: a gradient was dropped silently.

    The scintillation law's aperture, exposure, altitude and site factor and the eye's pupil
    and acuity are refused with a gradient; the Earth's albedo of the earthshine keeps it.
    """
    from skytorch.moon.earthshine import earthshine_irradiance_ratio
    from skytorch.stars.scintillation import scintillation_index
    from skytorch.stars.visibility import limiting_magnitude

    wanted = torch.tensor(0.5, dtype=torch.float64, requires_grad=True)
    for name in ("aperture_m", "exposure_s", "altitude_m"):
        with pytest.raises(ValueError, match=f"{name} requires a gradient"):
            scintillation_index(2.0, **{name: wanted})
    with pytest.raises(ValueError, match="site_factor requires a gradient"):
        scintillation_index(2.0, model="osborn2015", site_factor=wanted * 3.0)
    with pytest.raises(ValueError, match="model='young1967' has none"):
        scintillation_index(2.0, site_factor=2.0)
    for name, value in (("pupil_diameter_mm", wanted * 14.0), ("acuity_factor", wanted)):
        with pytest.raises(ValueError, match=f"{name} requires a gradient"):
            limiting_magnitude(21.0, **{name: value})
    albedo = torch.tensor(0.3, dtype=torch.float64, requires_grad=True)
    earthshine_irradiance_ratio(torch.tensor(1.0, dtype=torch.float64),
                                bond_albedo=albedo).backward()
    assert albedo.grad is not None and float(albedo.grad) > 0.0
