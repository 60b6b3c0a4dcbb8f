"""Stars behind the Moon vanish from scene images.

Reference: the occultation of Aldebaran (HIP 21421) on 2015-10-29 seen from Berlin,
found and checked with skyfield alone (topocentric apparent places of the Moon and of
the catalogue star): at 22:29 UTC the star is 0.06° from the Moon's centre, well inside
its 0.27° radius; at 21:10 UTC it is outside the disc.
"""

import math

import pytest
import torch

import skytorch as st

SITE = {"lat_deg": 52.52, "lon_deg": 13.40}
ALDEBARAN_HIP = 21421
DURING, BEFORE = "2015-10-29T22:29", "2015-10-29T21:10"
FOV_DEG = 2.0
SIZE = 64
PIXEL_DEG = FOV_DEG / SIZE


def _skyfield_places(time):
    """Aldebaran's and the Moon's topocentric apparent places from skyfield.

    Separation and the Moon's radius [degree], the star's refracted altitude and azimuth [rad].
    """
    from skyfield.api import Star, wgs84

    from skytorch.ephemeris import load_ephemeris, skyfield_time

    cat = st.stars.bright_stars(1.5)
    i = list(cat["hip"].values).index(ALDEBARAN_HIP)
    star = Star(ra_hours=float(cat["ra"][i]) / 15.0, dec_degrees=float(cat["dec"][i]),
                ra_mas_per_year=float(cat["pm_ra"][i]),
                dec_mas_per_year=float(cat["pm_dec"][i]),
                parallax_mas=float(cat["parallax"][i]))
    kernel, t = load_ephemeris(), skyfield_time([time])
    observer = (kernel["earth"] + wgs84.latlon(**{"latitude_degrees": SITE["lat_deg"],
                                                   "longitude_degrees": SITE["lon_deg"]})).at(t)
    moon = observer.observe(kernel["moon"]).apparent()
    place = observer.observe(star).apparent()
    separation = float(moon.separation_from(place).degrees[0])
    radius = math.degrees(math.asin(1_737_400.0 / float(moon.distance().m[0])))
    altitude, azimuth, _ = place.altaz(temperature_C=10.0, pressure_mbar=1013.25)
    return separation, radius, float(altitude.radians[0]), float(azimuth.radians[0])


def _star_flux_near_aldebaran(time):
    scene = st.Scene(time=time, **SITE, view="camera",
                     camera={"target": "moon", "fov_deg": FOV_DEG}, size=SIZE,
                     outputs=("spectral",), force=["stars", "moon"], exclude=["eclipse"])
    view = scene.make_view()
    ds = scene.render()
    stars = ds["component_radiance"].sel(component="stars").isel(wavelength=1).values
    _, _, altitude, azimuth = _skyfield_places(time)
    index = int(view.pixel_index(torch.tensor([altitude]), torch.tensor([azimuth]))[0])
    assert index >= 0
    row, column = divmod(index, SIZE)
    # 5 x 5 pixels (±2 pixels = ±3.8') around the star's place: no other catalogue star
    window = stars[row - 2:row + 3, column - 2:column + 3]
    solid = view.solid_angle_sr.numpy()[row - 2:row + 3, column - 2:column + 3]
    return float((window * solid).sum())


@pytest.mark.parametrize(("time", "inside"), [(DURING, True), (BEFORE, False)])
def test_geometry_of_the_reference_event(time, inside):
    separation, radius, _, _ = _skyfield_places(time)
    margin = 3 * PIXEL_DEG
    assert (separation < radius - margin) if inside else (separation > radius + margin)


def test_occulted_star_vanishes():
    before = _star_flux_near_aldebaran(BEFORE)
    during = _star_flux_near_aldebaran(DURING)
    # Aldebaran (V = 0.87) is there before the occultation and gone behind the Moon
    assert before > 0.0
    assert during == 0.0
