"""The planner's per-(time, site) geometry.

Cached without changing a decision, and the cheap ephemeris path against skyfield's full
apparent-place pipeline.
"""

import dataclasses
import math

import numpy as np
import pytest
import torch

import skytorch as st
from skytorch.constants import ARCSECOND
from skytorch.scene import planner
from skytorch.scene.geometry import apparent_geocentric, site_geometries

#: agreement of the single-evaluation geometry with skyfield's observe().apparent():
#: omitted deflection (mas) and diurnal aberration (<= 0.32 arcsec)
GEOMETRY_TOLERANCE = 0.5 * ARCSECOND


def _eclipse_night():
    return st.Scene(time="2015-09-28T02:47", lat_deg=52.52, lon_deg=13.40, size=32,
                    outputs=("xyz",))


def test_cold_and_warm_plans_are_identical():
    scene = _eclipse_night()
    scene.resources().clear()
    cold = scene.plan()
    warm = scene.plan()
    assert cold.computed == warm.computed
    assert cold.skipped == warm.skipped
    assert cold.shares == warm.shares
    assert dataclasses.asdict(cold.geometry) == dataclasses.asdict(warm.geometry)
    assert "eclipse" in cold.computed


def test_cached_values_are_copies():
    scene = _eclipse_night()
    first = scene.plan()
    first.geometry.moon_altitude_deg = -90.0
    second = scene.plan()
    assert second.geometry.moon_altitude_deg > 0.0


def test_cache_keys_on_site_and_time():
    scene = _eclipse_night()
    here = scene.plan().geometry
    elsewhere = scene.replace(lon_deg=-100.0).plan().geometry
    later = scene.replace(time="2015-09-28T14:47").plan().geometry
    assert abs(here.sun_azimuth_deg - elsewhere.sun_azimuth_deg) > 1.0
    assert abs(here.moon_altitude_deg - later.moon_altitude_deg) > 1.0


@pytest.mark.parametrize("time", ["2015-09-28T02:47", "2024-04-08T18:00", "1950-01-01T00:00"])
def test_geocentric_vectors_match_skyfield(time):
    reference = st.ephemeris.sun_moon_vectors([time])
    sun, moon, _ = apparent_geocentric(np.datetime64(time, "ns"))
    for ours, theirs in ((sun, reference["sun_gcrs_m"][0]), (moon, reference["moon_gcrs_m"][0])):
        cosine = float(ours @ theirs / (ours.norm() * theirs.norm()))
        assert math.acos(min(cosine, 1.0)) < GEOMETRY_TOLERANCE
        assert abs(float(ours.norm() - theirs.norm())) < 1.0  # [m]


def test_topocentric_altaz_match_skyfield():
    lat, lon, height = [52.52, -33.9, 0.0], [13.40, 18.4, -150.0], [0.0, 1500.0, 3000.0]
    time = "2015-09-28T02:47"
    reference = st.ephemeris.sun_moon([time], lat, lon, height)
    for i, g in enumerate(site_geometries(np.datetime64(time, "ns"), lat, lon, height)):
        for body in ("sun", "moon"):
            alt = math.radians(getattr(g, f"{body}_altitude_deg"))
            az = math.radians(getattr(g, f"{body}_azimuth_deg"))
            ref_alt = math.radians(float(reference[f"{body}_altitude"][0, i]))
            ref_az = math.radians(float(reference[f"{body}_azimuth"][0, i]))
            # great-circle separation of the two directions
            cosine = (math.sin(alt) * math.sin(ref_alt)
                      + math.cos(alt) * math.cos(ref_alt) * math.cos(az - ref_az))
            assert math.acos(min(cosine, 1.0)) < GEOMETRY_TOLERANCE, (i, body)


def test_moon_flux_table_matches_the_magnitude():
    from skytorch.moon import magnitude
    from skytorch.scene.geometry import Geometry

    for alpha, distance in ((0.05, 3.6e8), (1.3, 3.9e8), (2.9, 4.05e8)):
        g = Geometry(0.0, 0.0, 0.0, 0.0, distance, 1.0e11 * 1.5, alpha, 0.0, 0.0, 0.0, 0.0)
        total, earthshine = _eclipse_night().resources().moon_fluxes(g)
        options = {"distance_m": distance, "sun_distance_m": g.sun_distance_m,
                   "n_quadrature": planner.PLANNER_MOON_QUADRATURE}
        a = torch.tensor(alpha, dtype=torch.float64)
        with_es = 10.0 ** (-0.4 * float(magnitude(a, earthshine=True, **options)))
        without = 10.0 ** (-0.4 * float(magnitude(a, earthshine=False, **options)))
        # the table interpolates between 2-degree and 10 000 km nodes: within 1 %
        assert total == pytest.approx(with_es, rel=0.01)
        assert earthshine == pytest.approx(with_es - without, rel=0.03, abs=0.01 * with_es)


def _direct_sky_flux(scene, sun_altitude_deg):
    """Return the planner's 9-direction sky-flux estimate evaluated directly (no table)."""
    from skytorch.moon.sky import radiance_to_mag_arcsec2

    atm = scene.atmosphere()
    wl = scene.wavelength_nm()
    zenith = torch.tensor([0.0] + [math.radians(60.0)] * 4 + [math.radians(85.0)] * 4,
                          dtype=torch.float64)
    azimuth = torch.tensor([0.0] + [k * math.pi / 2 for k in range(4)] * 2,
                           dtype=torch.float64) + 1.0  # any Sun azimuth
    sun_zenith = torch.full_like(zenith, math.radians(90.0 - sun_altitude_deg))
    radiance = atm.sky_radiance(wl, zenith, azimuth, sun_zenith, torch.full_like(zenith, 1.0),
                                0.0, solar_irradiance=True, n_samples=24, scattering_orders=1)
    mags = radiance_to_mag_arcsec2(radiance.clamp(min=1e-300), wl)
    return float(torch.mean(10.0 ** (-0.4 * mags))) * planner.HEMISPHERE_ARCSEC2


@pytest.mark.parametrize("altitude", [47.3, 3.1, -0.7, -4.2, -11.9, -15.3, -17.8])
def test_sky_flux_table_matches_direct_estimate(altitude):
    from skytorch.scene.geometry import Geometry

    scene = _eclipse_night()
    g = Geometry(altitude, 0.0, 0.0, 0.0, 3.8e8, 1.5e11, 0.0, 0.0, 0.0, 0.0, 0.0)
    # log-linear interpolation between 0.25-degree nodes: within 1 %
    assert planner._sky_flux(scene.resources(), 0.0, g) == pytest.approx(
        _direct_sky_flux(scene, altitude), rel=0.01)


@pytest.mark.parametrize("offset_km", [0.0, 2_000.0, 4_400.0, 5_000.0, 6_000.0, 8_000.0])
def test_eclipse_bound_shortcut_agrees_with_the_visible_fraction(offset_km):
    """Inside the umbra of the opaque sphere the shortcut returns 0.

    As the limb-darkened visible fraction (Sun fully hidden) does; outside, the fraction itself.
    """
    from skytorch.constants import EARTH_MEAN_RADIUS_M, EARTH_TOP_OF_ATMOSPHERE_M, SUN_RADIUS_M
    from skytorch.eclipse import sun_visible_fraction
    from skytorch.eclipse.shadow import shadow_angles
    from skytorch.scene.geometry import Geometry

    distance, sun = 3.8e8, 1.496e11
    offset = offset_km * 1e3 + planner.MOON_RADIUS_M  # the disc's nearest point at offset_km
    g = Geometry(0.0, 0.0, 0.0, 0.0, distance, sun, 3.1, distance, offset, 0.0, 0.0)
    angles = shadow_angles(torch.tensor(distance, dtype=torch.float64),
                           torch.tensor(offset_km * 1e3, dtype=torch.float64), sun,
                           SUN_RADIUS_M, EARTH_MEAN_RADIUS_M + EARTH_TOP_OF_ATMOSPHERE_M)
    expected = float(sun_visible_fraction(angles["sun_radius_rad"],
                                          angles["occluder_radius_rad"],
                                          angles["separation_rad"]))
    assert planner._eclipse_bounds(g) == pytest.approx(expected, abs=1e-12)
