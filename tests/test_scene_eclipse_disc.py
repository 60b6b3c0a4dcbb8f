"""The Earth's shadow across the Moon's disc in scene images.

Reference: the partial umbral phase of the 2015-09-28 eclipse seen from Berlin at
01:40 UTC (U1 01:07:11, U2 02:10:27 UTC, Five Millennium Canon of Lunar Eclipses,
Espenak & Meeus). The shadow axis comes from skyfield's apparent Sun and Moon (not the
scene's geometry) and the umbra's radius from the Danjon-enlarged cone
(:func:`skytorch.eclipse.shadow_radii`), independent of the ray-traced shadow model that
shades the image.
"""

import math

import numpy as np
import pytest
import torch

import skytorch as st
from skytorch.constants import EARTH_MEAN_RADIUS_M, MOON_RADIUS_M, PERCENT, SUN_RADIUS_M

TIME = "2015-09-28T01:40"
SITE = {"lat_deg": 52.52, "lon_deg": 13.40}
FOV_DEG = 1.2
SIZE = 48
PIXEL_DEG = FOV_DEG / SIZE
#: pixels either side of the Danjon umbra's edge left out of the comparison
EDGE_MARGIN_PIXELS = 1.0
#: contrast across the edge: the penumbral side at least this many times brighter
EDGE_CONTRAST = 10.0


def _camera_scene(**kwargs):
    options = {"view": "camera", "camera": {"target": "moon", "fov_deg": FOV_DEG},
               "size": SIZE, "outputs": ("spectral",), "exclude": ["stars"]}
    options.update(kwargs)
    return st.Scene(time=TIME, **SITE, **options)


def _shadow_axis():
    """Topocentric GCRS vectors to the shadow axis at the Moon's distance and to the Moon.

    And the Danjon umbra radius [m], from skyfield.
    """
    from skyfield.api import wgs84

    from skytorch.eclipse import shadow_radii
    from skytorch.ephemeris import load_ephemeris, skyfield_time

    kernel, t = load_ephemeris(), skyfield_time([TIME])
    earth = kernel["earth"].at(t)
    sun = earth.observe(kernel["sun"]).apparent().position.m[:, 0]
    moon = earth.observe(kernel["moon"]).apparent().position.m[:, 0]
    observer = wgs84.latlon(SITE["lat_deg"], SITE["lon_deg"]).at(t).position.m[:, 0]
    axis = sun / np.linalg.norm(sun)
    along = -float(moon @ axis)
    umbra, _ = shadow_radii(torch.tensor(along), float(np.linalg.norm(sun)), SUN_RADIUS_M,
                            EARTH_MEAN_RADIUS_M, enlargement="danjon")
    return -axis * along - observer, moon - observer, float(umbra)


@pytest.fixture(scope="module")
def partial():
    scene = _camera_scene(force=["moon", "eclipse"])
    return scene, scene.make_view(), scene.render()


def _altaz(vector):
    vector = vector / np.linalg.norm(vector)
    return math.asin(vector[2]), math.atan2(vector[1], vector[0])


def test_disc_shows_the_umbra_edge(partial):
    scene, view, ds = partial
    axis, moon, umbra_m = _shadow_axis()
    rotation = st.ephemeris.icrs_to_horizontal_matrices([TIME], **SITE)[0].numpy()
    # the camera is centred on the refracted Moon: shift the axis point by the same amount
    centre = view.frame[0].numpy()
    shift = math.asin(centre[2]) - _altaz(rotation @ moon)[0]
    altitude, azimuth = _altaz(rotation @ axis)
    altitude += shift
    axis_dir = np.array([math.cos(altitude) * math.cos(azimuth),
                         math.cos(altitude) * math.sin(azimuth), math.sin(altitude)])
    unit = view.unit_vectors().numpy()
    from_centre = np.degrees(np.arccos(np.clip(unit @ centre, -1.0, 1.0)))
    from_axis = np.degrees(np.arccos(np.clip(unit @ axis_dir, -1.0, 1.0)))
    moon_radius = math.degrees(MOON_RADIUS_M / np.linalg.norm(moon))
    umbra = math.degrees(umbra_m / np.linalg.norm(axis))
    radiance = ds["component_radiance"].sel(component="moon").isel(wavelength=1).values
    disc = from_centre < moon_radius - 0.5 * PIXEL_DEG
    umbral = disc & (from_axis < umbra - EDGE_MARGIN_PIXELS * PIXEL_DEG)
    penumbral = disc & (from_axis > umbra + EDGE_MARGIN_PIXELS * PIXEL_DEG)
    # a partial phase: both parts of the disc are large
    assert umbral.sum() > 0.3 * disc.sum() and penumbral.sum() > 0.3 * disc.sum()
    # dark on the side toward the shadow axis, bright on the other, across the edge
    assert radiance[penumbral].min() > EDGE_CONTRAST * radiance[umbral].max()
    # brightness grows away from the axis over the disc
    assert np.corrcoef(from_axis[disc], np.log(radiance[disc]))[0, 1] > 0.9
    # the umbral part is below 1 % of the uneclipsed disc
    full = _camera_scene(force=["moon"], exclude=["stars", "eclipse"]).render()
    full_radiance = full["component_radiance"].sel(component="moon").isel(wavelength=1).values
    assert radiance[umbral].max() < 1 * PERCENT * full_radiance[disc].min()


def test_subpixel_moon_carries_the_disc_averaged_shadow(partial):
    """The Moon in a coarse fisheye has the flux of the resolved disc of the camera image.

    The Moon is smaller than a pixel there; two integrations over the disc (pixel centres vs polar
    quadrature) agree.
    """
    scene, view, ds = partial
    moon = ds["component_radiance"].sel(component="moon").values  # (y, x, wl)
    solid = view.solid_angle_sr.numpy()[..., None]
    unit = view.unit_vectors().numpy()
    near = np.degrees(np.arccos(np.clip(unit @ view.frame[0].numpy(), -1.0, 1.0))) < 0.4
    resolved = (moon * solid)[near].sum(0)
    fisheye = st.Scene(time=TIME, **SITE, size=64, outputs=("spectral",),
                       force=["moon", "eclipse"], exclude=["stars"])
    fds = fisheye.render()
    fmoon = fds["component_radiance"].sel(component="moon").values
    fsolid = fisheye.make_view().solid_angle_sr.numpy()[..., None]
    flux = fmoon * fsolid
    index = np.unravel_index(np.argmax(flux[..., 1]), flux.shape[:2])
    sky = np.median(fmoon[..., 1][fmoon[..., 1] > 0])  # the moonlit sky, nearly uniform
    subpixel = flux[index] - sky * fsolid[index]
    # the pixel-centre sum over a 48-pixel image of the disc: within 3 %
    np.testing.assert_allclose(subpixel, resolved, rtol=3 * PERCENT)


def test_float32_disc_shading_matches_float64():
    """The per-pixel shadow in a float32 scene.

    Finite, non-negative and within 1e-4 of the float64 image (the geometry and shadow model run in
    float64, the image is cast).
    """
    import torch

    images = {}
    for dtype in (torch.float32, torch.float64):
        ds = _camera_scene(force=["moon", "eclipse"], size=16, dtype=dtype).render()
        images[dtype] = ds["component_radiance"].sel(component="moon").values
    single, double = images[torch.float32], images[torch.float64]
    assert single.dtype == np.float32 and np.isfinite(single).all() and (single >= 0).all()
    np.testing.assert_allclose(single, double, rtol=1e-4, atol=1e-6 * double.max())
