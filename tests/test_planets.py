"""Planets: V magnitudes, phases and apparent places.

References: the output of Mallama & Hilton's reference program (``Ap_Mag_Output_V3.txt``,
tests/data/planet_magnitudes_mallama2018.csv); skyfield 1.55 (Rhodes 2019) for the
apparent places, phase angles (``phase_angle(sun)``), altitudes and, fed with skyfield's
own geometry, its independent implementation of the same magnitude formulae; the
closed-form derivative of the distance term.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from skytorch.stars.planets import PLANETS, planet_magnitude, planets, sub_latitudes

DATA = Path(__file__).parent / "data" / "planet_magnitudes_mallama2018.csv"
#: Mars' corrections for its central meridian and orbital longitude (Mallama & Hilton
#: 2018, Tables 3–4), in the reference output but not in skytorch, reach 0.1 mag
MARS_CORRECTIONS_MAG = 0.1
#: accuracy of Sæmundsson's refraction formula (Meeus 1998, ch. 16) [arcsec]
SAEMUNDSSON_ARCSEC = 6.0
#: the reference output is printed to 0.001 mag
PRINTED_MAG = 0.0005
TIMES = np.datetime64("2000-01-01T00:00") + np.arange(0, 30 * 365, 29) * np.timedelta64(1, "D")


def _rows():
    with DATA.open() as handle:
        return list(csv.DictReader(handle))


def _optional(row, key, scale=1.0):
    return None if row[key] == "" else torch.tensor(float(row[key]) * scale,
                                                    dtype=torch.float64)


@pytest.mark.parametrize("row", _rows(), ids=lambda r: f"{r['planet']}-{r['phase_angle_deg']}")
def test_magnitude_against_the_reference_program(row):
    degree = math.pi / 180.0
    value = planet_magnitude(
        row["planet"], torch.tensor(float(row["sun_distance_au"]), dtype=torch.float64),
        torch.tensor(float(row["observer_distance_au"]), dtype=torch.float64),
        torch.tensor(float(row["phase_angle_deg"]) * degree, dtype=torch.float64),
        sun_latitude_rad=_optional(row, "sun_latitude_deg", degree),
        observer_latitude_rad=_optional(row, "observer_latitude_deg", degree),
        year=_optional(row, "year"), rings=row["rings"] != "0")
    tolerance = MARS_CORRECTIONS_MAG if row["planet"] == "mars" else PRINTED_MAG
    assert abs(float(value) - float(row["v_mag"])) < tolerance


@pytest.fixture(scope="module")
def dataset():
    return planets(TIMES, 40.0, -105.0, 1600.0)


@pytest.fixture(scope="module")
def skyfield_positions():
    from skytorch.ephemeris import load_ephemeris, skyfield_time
    from skytorch.stars.planets import _TARGETS

    ephemeris = load_ephemeris()
    t = skyfield_time(TIMES)
    earth = ephemeris["earth"].at(t)
    return t, ephemeris, {name: earth.observe(ephemeris[_TARGETS[name]]) for name in PLANETS}


def test_places_and_phases_against_skyfield(dataset, skyfield_positions):
    from skyfield.api import wgs84

    t, ephemeris, positions = skyfield_positions
    site = (ephemeris["earth"] + wgs84.latlon(40.0, -105.0, elevation_m=1600.0)).at(t)
    from skytorch.stars.planets import _TARGETS

    for name, astrometric in positions.items():
        column = dataset.sel(planet=name)
        ra, dec, _ = astrometric.apparent().radec(epoch="date")
        arc = np.hypot((column.ra.values - ra._degrees) * np.cos(np.radians(dec.degrees)),
                       column.dec.values - dec.degrees) * 3600.0
        assert arc.max() < 1e-3  # arcsec
        phase = astrometric.phase_angle(ephemeris["sun"]).degrees
        assert np.abs(column.phase_angle.values - phase).max() * 3600.0 < 0.5
        assert np.allclose(column.distance.values, astrometric.distance().au, rtol=1e-12)
        altitude, _, _ = site.observe(ephemeris[_TARGETS[name]]).apparent().altaz()
        assert np.abs(column.altitude.values - altitude.degrees).max() * 3600.0 < 1e-3


def test_magnitudes_against_skyfield_formulae(dataset, skyfield_positions):
    """Skyfield's planet functions, fed with heliocentric (not barycentric) geometry."""
    from skyfield import magnitudelib

    t, ephemeris, positions = skyfield_positions
    for name in ("mercury", "venus", "mars", "jupiter"):
        astrometric = positions[name]
        emitted = t - astrometric.light_time
        target = astrometric.target
        sun_distance = (ephemeris[target].at(emitted)
                        - ephemeris["sun"].at(emitted)).distance().au
        phase = astrometric.phase_angle(ephemeris["sun"]).degrees
        expected = getattr(magnitudelib, f"_{name}_magnitude")(
            sun_distance, astrometric.distance().au, phase)
        assert np.abs(dataset.magnitude.sel(planet=name).values - expected).max() < 1e-4


def test_outer_planets_against_skyfield(dataset, skyfield_positions):
    """Saturn (rings), Uranus and Neptune against ``planetary_magnitude``.

    Skyfield puts the Sun at the barycentre (up to 0.01 au away), which moves the
    magnitudes of these distant planets by up to 0.007 mag (Saturn at opposition, where
    the ring term changes fastest with phase angle). Neptune's phase term starts at 1.9°,
    so the two differ by its step (0.015 mag) where their phase angles straddle it.
    """
    from skyfield.magnitudelib import planetary_magnitude

    _, _, positions = skyfield_positions
    for name in ("saturn", "uranus", "neptune"):
        expected = planetary_magnitude(positions[name])
        keep = np.abs(dataset.phase_angle.sel(planet=name).values - 1.9) > 0.01
        difference = dataset.magnitude.sel(planet=name).values - expected
        assert np.abs(difference[keep]).max() < 0.01


def test_dataset_contents(dataset):
    assert dataset.magnitude.dims == ("time", "planet")
    assert list(dataset.planet.values) == list(PLANETS)
    fraction = dataset.illuminated_fraction.values
    assert ((fraction >= 0.0) & (fraction <= 1.0)).all()
    # the inner planets' elongation never exceeds their orbit's (Venus 47.8 deg, Mercury 28)
    assert dataset.elongation.sel(planet="venus").max() < 48.0
    assert dataset.elongation.sel(planet="mercury").max() < 28.5
    # Jupiter's equatorial diameter 30-50 arcsec; Venus' up to 66 arcsec at inferior
    # conjunction
    assert 29.0 < float(dataset.angular_diameter.sel(planet="jupiter").min())
    assert float(dataset.angular_diameter.sel(planet="jupiter").max()) < 51.0
    assert float(dataset.angular_diameter.sel(planet="venus").max()) < 66.5
    assert dataset.magnitude.attrs["units"] == "mag"
    assert float(dataset.bv.sel(planet="mars")) > float(dataset.bv.sel(planet="neptune"))


def test_gradient_of_the_distance_term():
    r = torch.tensor(5.2, dtype=torch.float64, requires_grad=True)
    delta = torch.tensor(4.2, dtype=torch.float64, requires_grad=True)
    alpha = torch.tensor(math.radians(10.0), dtype=torch.float64, requires_grad=True)
    planet_magnitude("jupiter", r, delta, alpha).backward()
    assert math.isclose(float(r.grad), 5.0 / (5.2 * math.log(10.0)), rel_tol=1e-12)
    assert math.isclose(float(delta.grad), 5.0 / (4.2 * math.log(10.0)), rel_tol=1e-12)
    assert torch.autograd.gradcheck(
        lambda a: planet_magnitude("venus", torch.tensor(0.72, dtype=torch.float64),
                                   torch.tensor(0.4, dtype=torch.float64), a), (alpha,))


def test_float32_follows_float64():
    alpha = torch.linspace(0.0, 3.0, 50, dtype=torch.float64)
    for name in ("mercury", "venus", "mars", "jupiter"):
        high = planet_magnitude(name, torch.tensor(1.0, dtype=torch.float64),
                                torch.tensor(1.0, dtype=torch.float64), alpha)
        low = planet_magnitude(name, torch.tensor(1.0), torch.tensor(1.0), alpha.float())
        assert low.dtype == torch.float32
        assert (low.double() - high).abs().max() < 1e-4


def test_sub_latitudes_of_a_pole_on_the_line_of_sight():
    pole = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)
    sun, observer = sub_latitudes(pole, torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64),
                                  torch.tensor([0.0, 0.0, -2.0], dtype=torch.float64))
    assert float(sun) == 0.0
    assert math.isclose(float(observer), 0.5 * math.pi)


def test_bad_input():
    one = torch.tensor(1.0, dtype=torch.float64)
    with pytest.raises(ValueError, match="planet"):
        planet_magnitude("pluto", one, one, one)
    with pytest.raises(ValueError, match="sun_distance_au"):
        planet_magnitude("venus", -one, one, one)
    with pytest.raises(ValueError, match="phase_angle_rad"):
        planet_magnitude("venus", one, one, 4.0 * one)
    with pytest.raises(ValueError, match="sun_latitude_rad"):
        planet_magnitude("saturn", 9.5 * one, 8.5 * one, 0.01 * one)
    with pytest.raises(ValueError, match="ring openings"):
        planet_magnitude("saturn", 9.5 * one, 8.5 * one, 0.2 * one,
                         sun_latitude_rad=0.3 * one, observer_latitude_rad=0.3 * one)
    with pytest.raises(ValueError, match="after 2000"):
        planet_magnitude("neptune", 30.0 * one, 29.0 * one, 0.05 * one, year=1990.0 * one)
    with pytest.raises(ValueError, match="shapes"):
        planet_magnitude("venus", torch.ones(3, dtype=torch.float64),
                         torch.ones(2, dtype=torch.float64), one)
    with pytest.raises(ValueError, match="bodies"):
        planets("2021-10-04", bodies=("venus", "vulcan"))
    with pytest.raises(ValueError, match="lat_deg"):
        planets("2021-10-04", lat_deg=10.0)


def test_venus_in_a_scene_image():
    """Venus (V −4.55, 2020-04-03 20:00 UTC from Paris, 25° up) in the stars component.

    Drawn at skyfield's refracted topocentric place (within one 1.9′ pixel), with the
    irradiance of its magnitude (skyfield's formula on heliocentric geometry) after the
    550 nm transmittance of the refracted ray (0.05 mag: V-band vs 550 nm extinction).
    """
    from skyfield import magnitudelib
    from skyfield.api import wgs84

    import skytorch as st
    from skytorch.ephemeris import load_ephemeris, skyfield_time
    from skytorch.scene.render import star_spectra
    from skytorch.stars.planets import PLANET_BV

    time, site, size, fov = "2020-04-03T20:00", {"lat_deg": 48.85, "lon_deg": 2.35}, 64, 2.0
    ephemeris, t = load_ephemeris(), skyfield_time([time])
    venus, sun = ephemeris["venus"], ephemeris["sun"]
    astrometric = ephemeris["earth"].at(t).observe(venus)
    emitted = t - astrometric.light_time
    magnitude = float(magnitudelib._venus_magnitude(
        (venus.at(emitted) - sun.at(emitted)).distance().au, astrometric.distance().au,
        astrometric.phase_angle(sun).degrees)[0])
    observer = (ephemeris["earth"] + wgs84.latlon(site["lat_deg"], site["lon_deg"])).at(t)
    altitude, azimuth, _ = observer.observe(venus).apparent().altaz(
        temperature_C=10.0, pressure_mbar=1013.25)
    scene = st.Scene(time=time, **site, view="camera", size=size, outputs=("spectral",),
                     camera={"fov_deg": fov, "altitude_deg": float(altitude.degrees[0]),
                             "azimuth_deg": float(azimuth.degrees[0])}, force=["stars"])
    ds = scene.render()
    wavelength = ds["wavelength"].values
    band = int(np.argmin(np.abs(wavelength - 550.0)))
    image = ds["component_radiance"].sel(component="stars").isel(wavelength=band).values
    flux = image * scene.make_view().solid_angle_sr.numpy()
    row, column = np.unravel_index(np.argmax(flux), flux.shape)
    assert abs(row - (size - 1) / 2) <= 1.0 and abs(column - (size - 1) / 2) <= 1.0
    drawn = float(flux[row - 2:row + 3, column - 2:column + 3].sum())
    wl = torch.tensor([float(wavelength[band])], dtype=torch.float64)
    zenith = torch.tensor(math.radians(90.0 - float(altitude.degrees[0])), dtype=torch.float64)
    transmittance = float(torch.exp(-scene.atmosphere().optical_depth(wl, zenith,
                                                                      refraction=True))[0])
    expected = float(star_spectra(torch.tensor([magnitude], dtype=torch.float64),
                                  torch.tensor([PLANET_BV["venus"]], dtype=torch.float64),
                                  wl)[0, 0]) * transmittance
    assert abs(2.5 * math.log10(expected / drawn)) < 0.05


def test_the_first_hours_of_the_ephemeris():
    """Neptune's light of 1899-07-29 01:00 left it before DE421 begins: raise, and scenes log."""
    from skytorch.scene.resources import SceneResources, SceneSpec

    with pytest.raises(ValueError, match="times"):
        planets("1899-07-29T01:00")
    assert planets("1899-07-29T05:00").magnitude.notnull().all()
    sources = SceneResources(SceneSpec(2.0, 300.0, (550.0,))).planet_sources(
        np.datetime64("1899-07-29T01:00"))
    assert sources["vmag"].numel() == 0


def test_venus_is_the_brightest_point_at_totality():
    """Burgos, 2026-08-12 18:29:18 UTC (totality 18:28:27–18:30:10): Venus, 26° up.

    At totality the corona holds 99 % of the image's V flux and the stars 0.2 %, yet the
    planner draws them: Venus stands out of the dark sky of its pixel (the point-source
    test). The brightest point source of the render is Venus at skyfield's place (one
    1.9° pixel of the 96² fisheye), Jupiter (3° up) among the next. The next day at the
    same time the sunlit sky hides them.
    """
    from skyfield.api import wgs84

    import skytorch as st
    from skytorch.ephemeris import load_ephemeris, skyfield_time

    time, lat, lon, height = "2026-08-12T18:29:18", 42.34, -3.70, 850.0
    ephemeris, t = load_ephemeris(), skyfield_time([time])
    site = (ephemeris["earth"] + wgs84.latlon(lat, lon, elevation_m=height)).at(t)
    altitude, azimuth, _ = site.observe(ephemeris["venus"]).apparent().altaz()
    scene = st.Scene(time=time, lat_deg=lat, lon_deg=lon, elevation_m=height, size=96,
                     fidelity="fast", outputs=("spectral",))
    plan = scene.plan()
    assert "stars" in plan.computed and plan.shares["stars"] < 0.01
    assert "stars" in scene.replace(time="2026-08-13T18:29:18").plan().skipped
    ds = scene.render()
    assert "solar_eclipse" in ds.attrs["effects_computed"]
    view = scene.make_view()
    flux = (ds["component_radiance"].sel(component="stars").isel(wavelength=1).values
            * view.solid_angle_sr.numpy())
    brightest = np.unravel_index(np.argmax(flux), flux.shape)
    index = int(view.pixel_index(torch.tensor([math.radians(float(altitude.degrees[0]))]),
                                 torch.tensor([math.radians(float(azimuth.degrees[0]))]))[0])
    row, column = divmod(index, 96)
    assert abs(brightest[0] - row) <= 1 and abs(brightest[1] - column) <= 1


def test_planets_through_the_atmosphere():
    """Refracted altitudes against skyfield's refraction formula; V extinction k·X.

    Above 15° skyfield's Sæmundsson refraction at the US 1976 surface conditions (15 °C,
    1013.25 hPa) and the ray trace differ by 5.1″ at most, within the formula's 0.1′;
    the extinction follows the zenith coefficient times Kasten & Young's air mass within
    0.03 mag above 10° (their air mass is for a standard atmosphere).
    """
    from skyfield.api import wgs84

    import skytorch as st
    from skytorch.ephemeris import load_ephemeris, skyfield_time
    from skytorch.stars import extinction_coefficient
    from skytorch.stars.planets import _TARGETS, PLANET_BV

    atmosphere = st.atmosphere.Atmosphere.earth()
    times = np.datetime64("2020-04-03T16:00") + np.arange(0, 600, 10) * np.timedelta64(1, "m")
    ds = planets(times, 48.85, 2.35, atmosphere=atmosphere)
    ephemeris, t = load_ephemeris(), skyfield_time(times)
    site = (ephemeris["earth"] + wgs84.latlon(48.85, 2.35)).at(t)
    checked = 0
    for name in PLANETS:
        column = ds.sel(planet=name)
        altitude, _, _ = site.observe(ephemeris[_TARGETS[name]]).apparent().altaz(
            temperature_C=15.0, pressure_mbar=1013.25)
        high = altitude.degrees > 15.0
        difference = (column.apparent_altitude.values - altitude.degrees)[high] * 3600.0
        assert np.abs(difference).max(initial=0.0) < SAEMUNDSSON_ARCSEC
        k = float(extinction_coefficient(atmosphere, bv=PLANET_BV[name]))
        zenith = 90.0 - column.apparent_altitude.values
        above = zenith < 80.0
        kasten_young = 1.0 / (np.cos(np.radians(zenith[above]))
                              + 0.50572 * (96.07995 - zenith[above]) ** -1.6364)
        error = column.extinction.values[above] - k * kasten_young
        assert np.abs(error).max(initial=0.0) < 0.03
        assert np.allclose(column.apparent_magnitude - column.magnitude, column.extinction,
                           rtol=0.0, atol=1e-12)
        assert bool(column.above_horizon[column.apparent_altitude > 0.5].all())
        assert not bool(column.above_horizon[column.apparent_altitude < -0.5].any())
        checked += int(high.sum())
    assert checked > 40
    with pytest.raises(ValueError, match="observer"):
        planets(times[:1], atmosphere=atmosphere)


def test_phase_curve_settings_of_other_planets_are_refused():
    """Mars took a sub-solar latitude of 5 rad and rings="no" was Saturn with rings."""
    geometry = {"sun_distance_au": 1.5, "observer_distance_au": 1.0, "phase_angle_rad": 0.1}
    with pytest.raises(TypeError, match="rings"):
        planet_magnitude("saturn", **geometry, rings="no", sun_latitude_rad=0.1,
                         observer_latitude_rad=0.1)
    for planet, setting in (("mars", {"sun_latitude_rad": 5.0}), ("mars", {"rings": False}),
                            ("jupiter", {"year": 2000.0})):
        with pytest.raises(ValueError, match=f"{next(iter(setting))}: not used by the phase "
                                             f"curve of {planet}"):
            planet_magnitude(planet, **geometry, **setting)
