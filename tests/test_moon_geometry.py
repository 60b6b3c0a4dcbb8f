"""Lunar geometry against Meeus (1998) worked examples and USNO almanac phases."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from skytorch.constants import ARCSECOND, DEGREE, PERCENT
from skytorch.moon import geometry as g

# Meeus 1998, examples 47.a / 48.a / 53.a: 1992 April 12, 0h TD
MEEUS_SUN_RA, MEEUS_SUN_DEC, MEEUS_SUN_DIST_KM = 20.6579, 8.6964, 149971520.0
MEEUS_MOON_RA, MEEUS_MOON_DEC, MEEUS_MOON_DIST_KM = 134.688470, 13.768368, 368409.7
MEEUS_MOON_LON, MEEUS_MOON_LAT, MEEUS_DPSI = 133.167265, -3.229126, 0.004610
MEEUS_T = (2448724.5 - 2451545.0) / 36525.0


def test_phase_and_bright_limb_meeus_48a(dtype):
    """Meeus ex. 48.a: i = 69.0756°, k = 0.6786, χ = 285.0°."""
    t = lambda v: torch.tensor(v * DEGREE, dtype=dtype)  # noqa: E731
    phase = g.phase_angle_from_radec(t(MEEUS_SUN_RA), t(MEEUS_SUN_DEC),
                                     torch.tensor(MEEUS_SUN_DIST_KM * 1e3, dtype=dtype),
                                     t(MEEUS_MOON_RA), t(MEEUS_MOON_DEC),
                                     torch.tensor(MEEUS_MOON_DIST_KM * 1e3, dtype=dtype))
    assert phase.dtype == dtype
    tolerance = 1e-4 * DEGREE if dtype == torch.float64 else 2e-3 * DEGREE
    assert abs(float(phase) - 69.0756 * DEGREE) < tolerance
    assert abs(float(g.illuminated_fraction(phase)) - 0.6786) < 6e-5
    chi = g.bright_limb_position_angle(t(MEEUS_SUN_RA), t(MEEUS_SUN_DEC), t(MEEUS_MOON_RA),
                                       t(MEEUS_MOON_DEC))
    assert abs(float(chi) - 285.0 * DEGREE) < 0.05 * DEGREE


def test_optical_libration_meeus_53a(dtype):
    """Meeus ex. 53.a: l' = −1.206°, b' = +4.194°."""
    lon, lat = g.optical_libration(torch.tensor(MEEUS_MOON_LON * DEGREE, dtype=dtype),
                                   torch.tensor(MEEUS_MOON_LAT * DEGREE, dtype=dtype),
                                   torch.tensor(MEEUS_T, dtype=dtype),
                                   torch.tensor(MEEUS_DPSI * DEGREE, dtype=dtype))
    assert abs(float(lon) - (-1.206) * DEGREE) < 0.0006 * DEGREE
    assert abs(float(lat) - 4.194 * DEGREE) < 0.0006 * DEGREE


def test_axis_position_angle_meeus_53a():
    """Meeus ex. 53.a: P = 15.08° with physical libration (b = 4.20°); 15.066° without."""
    args = (torch.tensor(MEEUS_T, dtype=torch.float64),
            torch.tensor(23.440636 * DEGREE, dtype=torch.float64),
            torch.tensor(MEEUS_DPSI * DEGREE, dtype=torch.float64))
    ra = torch.tensor(MEEUS_MOON_RA * DEGREE, dtype=torch.float64)
    p = g.axis_position_angle(ra, torch.tensor(4.1998 * DEGREE, dtype=torch.float64), *args)
    assert abs(float(p) - 15.08 * DEGREE) < MEEUS_TOTAL_TOLERANCE_DEG * DEGREE
    optical = g.axis_position_angle(ra, torch.tensor(4.194 * DEGREE, dtype=torch.float64),
                                    *args, physical=False)
    assert abs(float(p - optical)) > 0.01 * DEGREE  # the physical terms matter at this level


#: Meeus ex. 53.a: ρ = −0.01042°, σ = −0.01574°, τ = +0.02673°; l″ = −0.025°, b″ = +0.006°
MEEUS_53A_RHO_SIGMA_TAU_DEG = (-0.01042, -0.01574, 0.02673)
MEEUS_53A_PHYSICAL_DEG = (-0.025, 0.006)
#: Meeus prints the totals l = −1.23°, b = +4.20° and P = 15.08° to 0.01°
MEEUS_TOTAL_TOLERANCE_DEG = 0.006


def test_physical_libration_meeus_53a(dtype):
    """Meeus ex. 53.a: the ρ, σ, τ series, l″, b″ and the totals l = −1.23°, b = +4.20°."""
    t = torch.tensor(MEEUS_T, dtype=dtype)
    angles = g.physical_libration_angles(t)
    for value, expected in zip(angles, MEEUS_53A_RHO_SIGMA_TAU_DEG, strict=True):
        assert value.dtype == dtype
        assert abs(float(value) - expected * DEGREE) < 0.000006 * DEGREE
    moon = (torch.tensor(MEEUS_MOON_LON * DEGREE, dtype=dtype),
            torch.tensor(MEEUS_MOON_LAT * DEGREE, dtype=dtype), t,
            torch.tensor(MEEUS_DPSI * DEGREE, dtype=dtype))
    extra = g.physical_libration(*moon)
    for value, expected in zip(extra, MEEUS_53A_PHYSICAL_DEG, strict=True):
        assert abs(float(value) - expected * DEGREE) < 0.0006 * DEGREE
    lon, lat = g.libration(*moon)
    assert abs(float(lon) - (-1.23) * DEGREE) < MEEUS_TOTAL_TOLERANCE_DEG * DEGREE
    assert abs(float(lat) - 4.20 * DEGREE) < MEEUS_TOTAL_TOLERANCE_DEG * DEGREE
    optical = g.libration(*moon, physical=False)
    assert torch.equal(optical[0], g.optical_libration(*moon)[0])


def test_physical_libration_bounded_and_differentiable():
    """Over 1900–2050 |l″|, |b″| stay below the series bound; finite gradients.

    Bound: the τ amplitudes of Meeus ch. 53 sum to 0.0505°, the ρ and σ ones to 0.058°
    each, times tan b′ ≤ tan 7° for l″: |l″| < 0.058°, |b″| ≤ √2 · 0.058° < 0.083°.
    """
    t = torch.linspace(-1.0, 0.5, 2001, dtype=torch.float64, requires_grad=True)
    # mean longitude (Meeus eq. 47.1, linear part) and β ≈ 5.128° sin F of the Moon
    lam = (218.3164477 + 481267.88123421 * t) * DEGREE
    beta = 5.128 * DEGREE * torch.sin(g.mean_lunar_elements(t)[0])
    lon, lat = g.physical_libration(lam, beta, t)
    assert float(lon.detach().abs().max()) < 0.058 * DEGREE
    assert float(lat.detach().abs().max()) < 0.083 * DEGREE
    assert float(lon.detach().abs().max()) > 0.02 * DEGREE  # τ's 0.025° annual term
    (lon.sum() + lat.sum()).backward()
    assert torch.isfinite(t.grad).all()


def test_orientation_matrix_is_rotation():
    m = g.orientation_matrix(torch.tensor([0.0, -0.02]), torch.tensor([0.0, 0.07]),
                             torch.tensor([0.0, 0.6]), torch.tensor([0.0, 0.26]))
    assert torch.allclose(m[0], torch.eye(3))
    assert torch.allclose(m[1] @ m[1].T, torch.eye(3), atol=1e-6)
    assert abs(float(torch.linalg.det(m[1])) - 1.0) < 1e-6
    # R_x(b) R_y(l) R_z(p − a) applied to the x axis, written out by hand
    b, l, z = 0.07, -0.02, 0.6 - 0.26
    x = torch.tensor([math.cos(l) * math.cos(z),
                      math.sin(b) * math.sin(l) * math.cos(z) + math.cos(b) * math.sin(z),
                      -math.cos(b) * math.sin(l) * math.cos(z) + math.sin(b) * math.sin(z)])
    assert torch.allclose(m[1, :, 0], x, atol=1e-6)


def test_moon_geometry_dataset_reproduces_meeus():
    """Ephemeris-driven Dataset at 1992-04-12 0h (TD − UT = 58 s, negligible)."""
    from skytorch.moon import moon_geometry

    ds = moon_geometry("1992-04-12T00:00:00")
    assert abs(float(ds.optical_libration_longitude[0]) - (-1.206)) < 0.003
    assert abs(float(ds.optical_libration_latitude[0]) - 4.194) < 0.003
    # totals with physical libration, printed to 0.01° by Meeus: l = −1.23°, b = +4.20°
    assert abs(float(ds.libration_longitude[0]) - (-1.23)) < MEEUS_TOTAL_TOLERANCE_DEG
    assert abs(float(ds.libration_latitude[0]) - 4.20) < MEEUS_TOTAL_TOLERANCE_DEG
    assert abs(float(ds.bright_limb_angle[0]) - 285.0) < 0.1
    # DE421 at 0h UT instead of Meeus's ELP at 0h TD moves P by 0.003° (tensor test: 0.004°)
    assert abs(float(ds.axis_position_angle[0]) - 15.08) < 0.01
    assert abs(float(ds.illuminated_fraction[0]) - 0.6786) < 2e-4
    assert ds.magnitude.attrs["long_name"]


# USNO "Phases of the Moon" (aa.usno.navy.mil), April 2024, UT
USNO_PHASES_2024 = [
    ("2024-04-08T18:21", "new"),
    ("2024-04-15T19:13", "first quarter"),
    ("2024-04-23T23:49", "full"),
    ("2024-05-01T11:27", "last quarter"),
]


def test_phases_at_usno_times():
    from skytorch.ephemeris import sun_moon_vectors

    times = [t for t, _ in USNO_PHASES_2024]
    v = sun_moon_vectors(times)
    phase = g.phase_angle(v["sun_gcrs_m"], v["moon_gcrs_m"])
    k = g.illuminated_fraction(phase).numpy()
    assert k[0] < 1e-4  # new Moon during the total solar eclipse
    assert k[2] > 0.99
    # quarters: elongation 90° in longitude; k = 0.5 within the Moon's latitude effect
    assert abs(k[1] - 0.5) < 1 * PERCENT and abs(k[3] - 0.5) < 1 * PERCENT


def test_parallactic_angle_against_spherical_vectors():
    """Meeus eq. 14.1 vs the angle between the pole and zenith directions on the sky."""
    rng = np.random.default_rng(1)
    h, dec, lat = (rng.uniform(-math.pi, math.pi, 200), rng.uniform(-1.4, 1.4, 200),
                   rng.uniform(-1.5, 1.5, 200))
    q = g.parallactic_angle(torch.tensor(h), torch.tensor(dec), torch.tensor(lat)).numpy()
    # equatorial frame of the observer: x towards the meridian on the equator, z to the pole
    star = np.stack([np.cos(dec) * np.cos(h), -np.cos(dec) * np.sin(h), np.sin(dec)], -1)
    zenith = np.stack([np.cos(lat), np.zeros_like(lat), np.sin(lat)], -1)
    pole = np.array([0.0, 0.0, 1.0])
    north = pole - (star @ pole)[:, None] * star
    north /= np.linalg.norm(north, axis=-1, keepdims=True)
    up = zenith - np.sum(zenith * star, -1, keepdims=True) * star
    up /= np.linalg.norm(up, axis=-1, keepdims=True)
    # positive towards the west: the sense of rotation from north about the line of sight
    sine = np.sum(np.cross(north, up) * star, -1)
    reference = np.arctan2(-sine, np.sum(north * up, -1))
    difference = np.angle(np.exp(1j * (q - reference)))
    assert np.max(np.abs(difference)) < 1e-9


def test_apparent_diameter_meeus():
    """Meeus ch. 55: geocentric semidiameter s = 358473400'' / Δ[km] (k = 0.272481)."""
    d = torch.tensor(MEEUS_MOON_DIST_KM * 1e3)
    semidiameter = 0.5 * g.apparent_diameter(d)
    assert abs(float(semidiameter) / (358473400.0 / MEEUS_MOON_DIST_KM * ARCSECOND) - 1) < 0.1 * PERCENT
    with pytest.raises(ValueError, match="distance_m"):
        g.apparent_diameter(torch.tensor(1000.0))


@pytest.mark.parametrize("phase_deg", [0.0, 180.0])
def test_phase_angle_hard_cases(dtype, phase_deg):
    """Exactly full and new Moon: finite value and gradient, no NaN."""
    moon = torch.tensor([3.844e8, 0.0, 0.0], dtype=dtype, requires_grad=True)
    sign = -1.0 if phase_deg == 0.0 else 1.0
    sun = torch.tensor([sign * 1.496e11, 0.0, 0.0], dtype=dtype)
    phase = g.phase_angle(sun, moon)
    assert abs(float(phase.detach()) - phase_deg * DEGREE) < 1e-6
    k = g.illuminated_fraction(phase)
    k.backward()
    assert torch.isfinite(moon.grad).all()
    assert 0.0 <= float(k.detach()) <= 1.0


def test_phase_angle_gradcheck():
    sun = torch.tensor([1.2e11, 8.0e10, 3.0e10], dtype=torch.float64)
    moon = torch.tensor([2.0e8, 3.0e8, 1.0e7], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda m: g.phase_angle(sun, m), (moon,))


def test_bad_inputs():
    with pytest.raises(ValueError, match="sun_vec"):
        g.phase_angle(torch.tensor([1.0, 2.0]), torch.tensor([1.0, 2.0, 3.0]))
    with pytest.raises(ValueError, match="finite"):
        g.illuminated_fraction(torch.tensor(float("nan")))
    # Moon at the Sun or at the observer: undefined angle, an error rather than NaN
    moon = torch.tensor([3.844e8, 0.0, 0.0], dtype=torch.float64)
    with pytest.raises(ValueError, match="moon_vec coincides with the Sun"):
        g.phase_angle(moon, moon)
    with pytest.raises(ValueError, match="moon_vec coincides with the observer"):
        g.phase_angle(torch.tensor([1.5e11, 0.0, 0.0]), torch.zeros(3))


def test_moon_geometry_topocentric():
    """With an observer: topocentric distance as skyfield's, phase within the parallax."""
    from skyfield.api import wgs84

    from skytorch.ephemeris import load_ephemeris, skyfield_time
    from skytorch.moon import moon_geometry

    times = ["2024-04-15T19:13", "2024-04-16T02:00"]
    geo = moon_geometry(times)
    topo = moon_geometry(times, lat_deg=52.5, lon_deg=13.4)
    ephemeris = load_ephemeris()
    site = ephemeris["earth"] + wgs84.latlon(52.5, 13.4)
    distance = site.at(skyfield_time(times)).observe(ephemeris["moon"]).apparent().distance().m
    expected = 2 * np.degrees(np.arcsin(1737400.0 / distance))
    assert np.allclose(topo.apparent_diameter.values, expected, rtol=1e-5)  # 4 km
    shift = np.abs(topo.phase_angle.values - geo.phase_angle.values)
    assert (shift < 1.0).all() and (shift > 0.0).all()  # lunar parallax ≤ 0.95°
    assert "parallactic_angle" in topo and "parallactic_angle" not in geo
