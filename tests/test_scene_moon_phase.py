"""Phase shading of the Moon's disc in scene images.

References, independent of the renderer: the topocentric apparent Sun and Moon of
skyfield (phase angle, hour angle, right ascension and declination), the bright-limb
position angle of Meeus (1998, eq. 48.5; :func:`skytorch.moon.bright_limb_position_angle`)
and the parallactic angle (Meeus eq. 14.1), the illuminated fraction
k = (1 + cos i)/2, and the disc-integrated magnitude :func:`skytorch.moon.magnitude`.

Pixel quantisation of the lit fraction: a pixel counts as lit when its centre is, so
each pixel crossed by a boundary of the lit region is off by at most half its area
(a boundary straight on the pixel's scale: the side holding the centre holds at least
half of it). A curve of length L crosses at most √2 L/δ + 2 pixels of side δ, so the
lit area is within (√2 L/δ + 2) δ²/2 and the lit fraction f = A_lit/A_disc within
(ΔA_lit + f ΔA_disc)/A_disc, with L_lit = πR + the terminator's half ellipse
(semi-axes R and R|cos i|) and L_disc = 2πR.
"""

import math

import numpy as np
import pytest
import torch

import skytorch as st
from skytorch.constants import DEGREE, MAG, MOON_RADIUS_M, PERCENT

SITE = {"lat_deg": 52.52, "lon_deg": 13.40}
#: instants with the Moon well up at Berlin: waxing quarter (evening), waning crescent
#: (morning), waxing gibbous (night)
INSTANTS = ("2015-10-20T18:00", "2015-10-09T04:30", "2015-10-23T20:00")
FOV_DEG = 0.7
SIZE = 128
#: position angle of the lit side's centroid against the bright limb's
LIMB_ANGLE_TOLERANCE = 1.0 * DEGREE
#: disc-summed V flux against st.moon.magnitude (the scene's 12-24-node disc quadrature
#: against 48 nodes; measured 1.4e-5 mag)
FLUX_TOLERANCE = 0.001 * MAG
#: a sub-pixel Moon against the resolved disc (the moonlit sky under the Moon's pixel is
#: estimated from its neighbours; measured 5.8e-4 mag)
SUBPIXEL_TOLERANCE = 0.002 * MAG
#: earthshine flux of the night-side pixels: the pixel-centre area of the night side of the
#: crescent (R = 45 pixels) is within 3.4 % by the bound of the module docstring, and the
#: earthshine's radiance varies little over it (measured: 0.16 %)
EARTHSHINE_TOLERANCE = 5 * PERCENT
#: direction of the pixel holding a sub-pixel crescent: half a pixel diagonal seen from
#: 2.6 pixels
CRESCENT_PIXEL_ANGLE = math.atan(0.5 * math.sqrt(2.0) / 2.6)
#: pixels whose lit/dark state differs from an independent ray-sphere classification:
#: the scene's and skyfield's places of the Moon differ by < 0.5 arcsec, a few pixels on
#: the terminator may switch
MISCLASSIFIED_SHARE = 0.5 * PERCENT


def _skyfield(time):
    """Topocentric apparent Sun and Moon from skyfield.

    Horizontal vectors (north, east, up) [m], hour angle, right ascension and declination of date
    [rad].
    """
    from skyfield.api import wgs84

    from skytorch.ephemeris import load_ephemeris, skyfield_time

    kernel, t = load_ephemeris(), skyfield_time([time])
    observer = kernel["earth"] + wgs84.latlon(SITE["lat_deg"], SITE["lon_deg"])
    out = {}
    for body in ("sun", "moon"):
        apparent = observer.at(t).observe(kernel[body]).apparent()
        alt, az, distance = apparent.altaz()
        a, z, d = alt.radians[0], az.radians[0], distance.m[0]
        ra, dec, _ = apparent.radec(epoch="date")
        hour_angle, _, _ = apparent.hadec()
        out[body] = {"vector": d * np.array([math.cos(a) * math.cos(z),
                                             math.cos(a) * math.sin(z), math.sin(a)]),
                     "ra": ra.radians[0], "dec": dec.radians[0],
                     "hour_angle": hour_angle.radians[0]}
    return out


def _render(time, dtype=torch.float64, size=SIZE, **kwargs):
    options = {"view": "camera", "camera": {"target": "moon", "fov_deg": FOV_DEG},
               "size": size, "outputs": ("spectral",), "exclude": ["stars", "earthshine"],
               "force": ["moon"], "dtype": dtype}
    options.update(kwargs)
    scene = st.Scene(time=time, **SITE, **options)
    return scene, scene.make_view(), scene.render()


@pytest.fixture(scope="module", params=INSTANTS)
def phase(request):
    time = request.param
    scene, view, ds = _render(time)
    return time, scene, view, ds, _skyfield(time)


def _disc_masks(view, ds, moon_vector):
    """Disc pixels, lit pixels and the moonlit-sky level of the Moon component (green)."""
    radiance = ds["component_radiance"].sel(component="moon").isel(wavelength=1).values
    unit = view.unit_vectors().numpy()
    from_centre = np.arccos(np.clip(unit @ view.frame[0].numpy(), -1.0, 1.0))
    radius = math.asin(MOON_RADIUS_M / np.linalg.norm(moon_vector))
    disc = from_centre < radius
    sky = radiance[~disc].max()  # scattered moonlight, ~1e-5 of the disc
    return radiance, disc, disc & (radiance > 10.0 * sky), radius


def test_dark_limb_faces_away_from_the_sun(phase):
    """The centroid of the lit pixels lies towards the bright limb.

    Meeus' position angle from skyfield's Sun and Moon, turned to the camera's zenith-up frame by
    the parallactic angle, and the Sun's own direction projected on the image agree with it.
    """
    time, scene, view, ds, sky = phase
    _, disc, lit, _ = _disc_masks(view, ds, sky["moon"]["vector"])
    x = np.tan(np.radians(ds["camera_x"].values))[None, :].repeat(SIZE, 0)
    y = np.tan(np.radians(ds["camera_y"].values))[:, None].repeat(SIZE, 1)
    solid = view.solid_angle_sr.numpy()
    centroid = np.array([(x * solid)[lit].sum() - (x * solid)[disc].sum() / solid[disc].sum()
                         * solid[lit].sum(),
                         (y * solid)[lit].sum() - (y * solid)[disc].sum() / solid[disc].sum()
                         * solid[lit].sum()])
    # image angle of the lit side from the vertical through the left (through the east)
    measured = math.atan2(-centroid[0], centroid[1])
    sun, moon = sky["sun"], sky["moon"]
    chi = float(st.moon.bright_limb_position_angle(sun["ra"], sun["dec"], moon["ra"],
                                                   moon["dec"]))
    q = float(st.moon.parallactic_angle(moon["hour_angle"], moon["dec"],
                                        math.radians(SITE["lat_deg"])))
    expected = chi - q
    difference = math.remainder(measured - expected, 2 * math.pi)
    assert abs(difference) < LIMB_ANGLE_TOLERANCE, (math.degrees(measured),
                                                    math.degrees(expected))
    # the great circle from the Moon to the Sun, projected on the camera's axes
    centre, right, up, _ = (v.numpy() if torch.is_tensor(v) else v for v in view.frame)
    moon_dir = moon["vector"] / np.linalg.norm(moon["vector"])
    sun_dir = sun["vector"] / np.linalg.norm(sun["vector"])
    towards = sun_dir - (sun_dir @ moon_dir) * moon_dir
    projected = math.atan2(-(towards @ right), towards @ up)
    assert abs(math.remainder(measured - projected, 2 * math.pi)) < LIMB_ANGLE_TOLERANCE


def _quantisation_bound(k, radius_pixels):
    """Worst-case lit-fraction error of pixel-centre counting (module docstring)."""
    cos_i = abs(2.0 * k - 1.0)
    a, b = 1.0, cos_i  # terminator half ellipse, Ramanujan's perimeter / 2
    terminator = 0.5 * math.pi * (3 * (a + b) - math.sqrt((3 * a + b) * (a + 3 * b)))
    area = math.pi * radius_pixels ** 2

    def error(length):
        return (math.sqrt(2.0) * length * radius_pixels + 2.0) / 2.0

    return (error(math.pi + terminator) + k * error(2 * math.pi)) / area


def _sunlit_pixels(view, moon, sun):
    """Pixels whose line of sight meets a sunlit point of skyfield's Moon (ray-sphere).

    The camera is centred on the refracted Moon, so the lines of sight are first turned
    by the rotation from that centre to skyfield's unrefracted Moon.
    """
    centre = view.frame[0].numpy()
    moon_dir = moon / np.linalg.norm(moon)
    axis = np.cross(centre, moon_dir)
    angle = math.asin(np.linalg.norm(axis))
    axis = axis / np.linalg.norm(axis)
    unit = view.unit_vectors().numpy()
    rotated = (unit * math.cos(angle) + np.cross(axis, unit) * math.sin(angle)
               + axis * (unit @ axis)[..., None] * (1 - math.cos(angle)))
    along = rotated @ moon
    discriminant = along ** 2 - moon @ moon + MOON_RADIUS_M ** 2
    hit = discriminant > 0
    point = (along - np.sqrt(np.clip(discriminant, 0, None)))[..., None] * rotated
    return hit & (((point - moon) * (sun - point)).sum(-1) > 0)


def test_lit_fraction_is_the_illuminated_fraction(phase):
    """The solid-angle share of lit disc pixels is k = (1 + cos i)/2.

    With the phase angle i of skyfield's topocentric Moon, within the pixel-quantisation bound, and
    the lit pixels are those whose line of sight meets a sunlit point of skyfield's Moon.
    """
    time, scene, view, ds, sky = phase
    _, disc, lit, radius = _disc_masks(view, ds, sky["moon"]["vector"])
    moon, sun = sky["moon"]["vector"], sky["sun"]["vector"]
    to_sun, to_observer = sun - moon, -moon
    cosine = to_sun @ to_observer / np.linalg.norm(to_sun) / np.linalg.norm(to_observer)
    k = 0.5 * (1.0 + cosine)
    solid = view.solid_angle_sr.numpy()
    fraction = solid[lit].sum() / solid[disc].sum()
    radius_pixels = radius / (math.radians(FOV_DEG) / SIZE)
    assert abs(fraction - k) < _quantisation_bound(k, radius_pixels), (fraction, k)
    sunlit = _sunlit_pixels(view, moon, sun)
    differ = (sunlit != lit) & disc
    assert differ.sum() <= MISCLASSIFIED_SHARE * disc.sum(), (differ.sum(), disc.sum())


def _v_magnitude(flux, wavelength):
    from skytorch.spectrum import spectrum_to_magnitude

    return float(spectrum_to_magnitude(torch.as_tensor(flux, dtype=torch.float64),
                                       torch.as_tensor(wavelength, dtype=torch.float64)))


def _reference_magnitude(sky, earthshine):
    moon, sun = sky["moon"]["vector"], sky["sun"]["vector"]
    to_sun = sun - moon
    i = math.acos(to_sun @ -moon / np.linalg.norm(to_sun) / np.linalg.norm(moon))
    return float(st.moon.magnitude(torch.tensor(i, dtype=torch.float64),
                                   distance_m=float(np.linalg.norm(moon)),
                                   sun_distance_m=float(np.linalg.norm(to_sun)),
                                   earthshine=earthshine))


def _extinction(scene, altitude_rad, wavelength):
    """Transmittance (wl,) of the scene's atmosphere at an apparent altitude [rad]."""
    zenith = torch.tensor(0.5 * math.pi - altitude_rad, dtype=torch.float64)
    return scene.atmosphere().transmittance(torch.as_tensor(wavelength, dtype=torch.float64),
                                            zenith, scene.elevation_m).numpy()


@pytest.mark.parametrize("earthshine", [False, True])
def test_disc_flux_is_the_moon_magnitude(dtype, earthshine):
    """The Moon's flux summed over its disc pixels is st.moon.magnitude's.

    Summed over the shaded disc pixels, the Moon's flux (moonlit sky subtracted, extinction removed)
    is st.moon.magnitude of skyfield's topocentric geometry, with and without earthshine, in float32
    and float64; so is the flux of a sub-pixel Moon in an all-sky image.
    """
    from skytorch.moon.brightness import V_BAND_WAVELENGTHS_NM

    time = INSTANTS[1]  # a crescent: earthshine adds 0.008 mag
    wavelengths = list(V_BAND_WAVELENGTHS_NM)
    exclude = ["stars"] if earthshine else ["stars", "earthshine"]
    force = ["moon", "earthshine"] if earthshine else ["moon"]
    scene, view, ds = _render(time, dtype, size=96, wavelengths=wavelengths, exclude=exclude,
                              force=force)
    assert ("earthshine" in ds.attrs["effects_computed"]) == earthshine
    sky = _skyfield(time)
    moon = ds["component_radiance"].sel(component="moon").values.astype(np.float64)
    assert np.isfinite(moon).all() and (moon >= 0).all()
    solid = view.solid_angle_sr.numpy().astype(np.float64)[..., None]
    unit = view.unit_vectors().numpy()
    from_centre = np.arccos(np.clip(unit @ view.frame[0].numpy(), -1.0, 1.0))
    radius = math.asin(MOON_RADIUS_M / np.linalg.norm(sky["moon"]["vector"]))
    near = from_centre < 1.1 * radius
    ring = (from_centre > 1.1 * radius) & (from_centre < 1.3 * radius)
    background = np.median(moon[ring], axis=0)
    flux = ((moon - background) * solid)[near].sum(0)
    altitude = math.asin(float(view.frame[0][2]))
    outside = flux / _extinction(scene, altitude, wavelengths)
    reference = _reference_magnitude(sky, earthshine)
    assert abs(_v_magnitude(outside, wavelengths) - reference) < FLUX_TOLERANCE
    # the same Moon below a pixel of a coarse fisheye keeps the disc-integrated flux
    fisheye = st.Scene(time=time, **SITE, size=64, outputs=("spectral",), dtype=dtype,
                       wavelengths=wavelengths, exclude=exclude, force=force)
    fmoon = fisheye.render()["component_radiance"].sel(component="moon").values
    fsolid = fisheye.make_view().solid_angle_sr.numpy().astype(np.float64)[..., None]
    fflux = fmoon.astype(np.float64) * fsolid
    iy, ix = np.unravel_index(np.argmax(fflux[..., 10]), fflux.shape[:2])
    neighbours = fmoon[iy - 1:iy + 2, ix - 1:ix + 2].astype(np.float64).reshape(9, -1)
    background = np.median(np.delete(neighbours, 4, axis=0), axis=0)  # the moonlit sky
    pixel = fflux[iy, ix] - background * fsolid[iy, ix]
    assert abs(_v_magnitude(pixel, wavelengths) - _v_magnitude(flux, wavelengths)) \
        < SUBPIXEL_TOLERANCE


def test_earthshine_lights_the_dark_side():
    """With earthshine the night side of the crescent carries the earthshine flux.

    Its pixels carry the earthshine flux of st.moon.magnitude (with minus without
    earthshine); without it they are dark (only the faint moonlit sky).
    """
    from skytorch.moon.brightness import V_BAND_WAVELENGTHS_NM

    time = INSTANTS[1]
    wavelengths = list(V_BAND_WAVELENGTHS_NM)
    sky = _skyfield(time)
    moon, sun = sky["moon"]["vector"], sky["sun"]["vector"]
    fluxes = {}
    for earthshine in (True, False):
        scene, view, ds = _render(time, size=96, wavelengths=wavelengths,
                                  exclude=["stars"] if earthshine else ["stars", "earthshine"],
                                  force=["moon", "earthshine"] if earthshine else ["moon"])
        radiance = ds["component_radiance"].sel(component="moon").values
        unit = view.unit_vectors().numpy()
        from_centre = np.arccos(np.clip(unit @ view.frame[0].numpy(), -1.0, 1.0))
        radius = math.asin(MOON_RADIUS_M / np.linalg.norm(moon))
        disc = from_centre < radius
        ring = (from_centre > 1.1 * radius) & (from_centre < 1.3 * radius)
        night = disc & ~_sunlit_pixels(view, moon, sun)
        solid = view.solid_angle_sr.numpy()[..., None]
        flux = ((radiance - np.median(radiance[ring], axis=0)) * solid)[night].sum(0)
        altitude = math.asin(float(view.frame[0][2]))
        fluxes[earthshine] = flux / _extinction(scene, altitude, wavelengths)
    v_flux = {e: 10.0 ** (-0.4 * _v_magnitude(f, wavelengths)) for e, f in fluxes.items()}
    reference = (10.0 ** (-0.4 * _reference_magnitude(sky, True))
                 - 10.0 ** (-0.4 * _reference_magnitude(sky, False)))
    assert v_flux[True] == pytest.approx(reference, rel=EARTHSHINE_TOLERANCE)
    assert v_flux[False] < 1e-3 * reference


def test_crescent_narrower_than_the_pixels():
    """A crescent narrower than the pixels puts its whole flux in one pixel.

    A day-old crescent (phase angle 174°, lit width 0.005 of the radius) on a disc about 6
    pixels across, no pixel centre on its lit part: its whole flux (st.moon.magnitude) lands
    in one pixel on the Sun's side of the disc centre.
    """
    from skytorch.moon.brightness import V_BAND_WAVELENGTHS_NM

    time = "2015-10-12T11:00"
    wavelengths = list(V_BAND_WAVELENGTHS_NM)
    scene, view, ds = _render(time, size=8, wavelengths=wavelengths,
                              exclude=["stars", "earthshine", "sky", "sun"])
    sky = _skyfield(time)
    moon = ds["component_radiance"].sel(component="moon").values
    solid = view.solid_angle_sr.numpy()[..., None]
    background = np.median(moon[..., 10])
    iy, ix = np.unravel_index(np.argmax(moon[..., 10]), moon.shape[:2])
    assert moon[iy, ix, 10] > 1e3 * background  # one pixel holds the crescent
    flux = (moon[iy, ix] - np.median(moon.reshape(-1, moon.shape[-1]), axis=0)) * solid[iy, ix]
    altitude = math.asin(float(view.frame[0][2]))
    outside = flux / _extinction(scene, altitude, wavelengths)
    assert abs(_v_magnitude(outside, wavelengths) - _reference_magnitude(sky, False)) \
        < FLUX_TOLERANCE
    # on the Sun's side: the pixel's offset against the Sun's direction projected on the
    # image, within the angle a pixel subtends from the lit centroid (0.85 radii, 2.6 px)
    _, right, up, _ = view.frame
    moon_dir = sky["moon"]["vector"] / np.linalg.norm(sky["moon"]["vector"])
    sun_dir = sky["sun"]["vector"] / np.linalg.norm(sky["sun"]["vector"])
    towards = sun_dir - (sun_dir @ moon_dir) * moon_dir
    expected = math.atan2(towards @ up.numpy(), towards @ right.numpy())
    centre = 0.5 * (moon.shape[0] - 1)
    measured = math.atan2(centre - iy, ix - centre)
    assert abs(math.remainder(measured - expected, 2 * math.pi)) < CRESCENT_PIXEL_ANGLE


@pytest.mark.parametrize("phase_deg", [0.0, 90.0, 180.0])
def test_moon_at_the_zenith_and_extreme_phases(phase_deg):
    """Hard cases of the disc frame.

    The Moon exactly at the zenith (no vertical to orient the disc by; north is used) at full,
    quarter and new Moon. The shading is finite and non-negative; at quarter the sunlit half (μ0 > 0
    of the normal towards the Sun, placed due north) is exactly the northern half of the disc.
    """
    from skytorch.scene.geometry import Geometry
    from skytorch.scene.render import MoonDisc

    distance, sun_distance = 3.8e8, 1.496e11
    alpha = math.radians(phase_deg)
    moon = (0.0, 0.0, distance)
    # the Sun seen from the Moon at the phase angle, towards the north
    sun = (sun_distance * math.sin(alpha), 0.0, distance - sun_distance * math.cos(alpha))
    g = Geometry(0.0, 0.0, 90.0, 0.0, distance, sun_distance, alpha, 0.0, 0.0, 0.0, 0.0,
                 sun_horizontal_m=sun, moon_horizontal_m=moon)
    scene = st.Scene(time=INSTANTS[0], **SITE)
    wavelength = torch.tensor([550.0], dtype=torch.float64)
    disc = MoonDisc(scene.resources(), g, wavelength, 0.5 * math.pi, earthshine=False,
                    eclipse=False)
    assert float(disc.phase_angle_rad) == pytest.approx(alpha, abs=1e-9)
    offsets = torch.linspace(-0.95, 0.95, 21, dtype=torch.float64) * g.moon_radius_rad
    north, east = torch.meshgrid(offsets, offsets, indexing="ij")
    directions = torch.stack([north, east, torch.ones_like(north)], -1).reshape(-1, 3)
    directions = directions / torch.linalg.vector_norm(directions, dim=-1, keepdim=True)
    inside = (north ** 2 + east ** 2).reshape(-1) < (0.95 * g.moon_radius_rad) ** 2
    brightness, shadow = disc(directions[inside])
    assert shadow is None and torch.isfinite(brightness).all() and (brightness >= 0).all()
    lit = brightness[:, 0] > 0
    if phase_deg == 180.0:
        assert not bool(lit.any())  # new Moon: dark without earthshine
        altitude, _ = disc.bright_point()
        assert math.isfinite(altitude)
    elif phase_deg == 90.0:
        northern = north.reshape(-1)[inside] > 0
        assert bool((lit == northern).all())
    else:
        assert bool(lit.all())
