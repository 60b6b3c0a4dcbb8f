"""Geometry of the Moon as seen from the Earth: phase, bright limb, libration, size.

Pure tensor functions (batched over leading dimensions, differentiable, float32 or
float64 following the inputs). Vectors are Cartesian ``(..., 3)`` tensors in any common
frame; angles are radians.

Notes
-----
* Phase angle ``i`` (selenocentric elongation of the Earth from the Sun) is the angle at
  the Moon between the directions to the Sun and to the observer. It is computed from
  vectors as ``atan2(|a × b|, a · b)``, which stays accurate at 0 and π where ``acos`` of
  a dot product loses half of the significant digits. Meeus (1998) eq. 48.2–48.3 is the
  same quantity from right ascensions, declinations and distances.
* Illuminated fraction ``k = (1 + cos i) / 2`` (Meeus eq. 48.1).
* Position angle of the bright limb, measured from the north point of the disc towards
  the east (Meeus eq. 48.5)::

      χ = atan2(cos δ0 sin(α0 − α), sin δ0 cos δ − cos δ0 sin δ cos(α0 − α))

* Optical libration (Meeus ch. 53, eq. 53.1)::

      W = λ − Δψ − Ω
      A = atan2(sin W cos β cos I − sin β sin I, cos W cos β)
      l' = A − F
      b' = asin(−sin W cos β sin I − sin β cos I)

  with the inclination of the mean lunar equator to the ecliptic I = 1.54242° and the
  mean elements F (argument of latitude, Meeus eq. 47.5) and Ω (longitude of the mean
  ascending node, Meeus eq. 47.7).
* Physical libration (Meeus ch. 53): the forced librations ρ, σ (of the rotation axis)
  and τ (in longitude), series in the mean elements D, M, M′, F, Ω; then
  ``l″ = −τ + (ρ cos A + σ sin A) tan b′`` and ``b″ = σ cos A − ρ sin A``, added to the
  optical values: ``l = l′ + l″``, ``b = b′ + b″`` (:func:`libration`).
* Parallactic angle (Meeus eq. 14.1): ``q = atan2(sin H, tan φ cos δ − sin δ cos H)``,
  written as ``atan2(sin H cos φ, sin φ cos δ − cos φ sin δ cos H)`` so that it stays
  finite at the poles.
* Apparent angular diameter of a sphere of radius R at distance d: ``2 asin(R / d)``.

References
----------
1. Meeus, J. 1998, *Astronomical Algorithms*, 2nd ed., Willmann-Bell, ch. 14, 47, 48, 53.
2. Müller, T., Engel, J., Döllner, J. 2012, "Single-Pass Rendering of Day and Night Sky
   Phenomena", Proc. Vision, Modeling and Visualization (VMV), doi:10.2312/PE/VMV/VMV12/055-062
   (eq. 1–2: apparent size and libration orientation of the lunar disc).

Examples
--------
>>> import torch
>>> from skytorch.moon.geometry import illuminated_fraction
>>> round(float(illuminated_fraction(torch.tensor(torch.pi / 2))), 6)  # quarter Moon
0.5
"""

from __future__ import annotations

import math

import torch

from skytorch._angles import wrap_to_turn
from skytorch._validate import (
    as_tensor,
    check_broadcastable,
    check_finite,
    check_positive,
    check_range,
    check_shape_last,
    common_dtype,
)
from skytorch.constants import DEGREE, MOON_RADIUS_M

__all__ = [
    "MEAN_LUNAR_EQUATOR_INCLINATION_RAD",
    "angle_between",
    "apparent_diameter",
    "axis_position_angle",
    "bright_limb_position_angle",
    "illuminated_fraction",
    "libration",
    "mean_lunar_elements",
    "optical_libration",
    "orientation_matrix",
    "parallactic_angle",
    "phase_angle",
    "phase_angle_from_radec",
    "physical_libration",
    "physical_libration_angles",
    "radec_to_vector",
]

#: inclination I of the mean lunar equator to the ecliptic (Meeus 1998, ch. 53) [rad]
MEAN_LUNAR_EQUATOR_INCLINATION_RAD = 1.54242 * DEGREE


def _tensor(name, value, dtype):
    return check_finite(name, as_tensor(name, value, dtype=dtype))


def _broadcast_inputs(**tensors: torch.Tensor) -> None:
    """Raise ``ValueError`` naming the inputs and their shapes unless they broadcast."""
    check_broadcastable(**tensors)


def angle_between(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Angle between vectors ``a`` and ``b`` (…, 3) as ``atan2(|a × b|, a · b)`` [rad].

    Accurate over the whole range [0, π], including nearly parallel and nearly
    anti-parallel vectors. ``a`` and ``b`` broadcast against each other (``ValueError``
    naming both shapes if they do not). Its gradient is finite except for exactly parallel or
    anti-parallel vectors, where a tiny floor keeps it finite (and zero).
    """
    a = check_shape_last("a", as_tensor("a", a), 3)
    b = check_shape_last("b", as_tensor("b", b, dtype=a.dtype), 3)
    # torch.linalg.cross needs equal shapes: broadcast first (ValueError if impossible)
    shape = check_broadcastable(a=a, b=b)
    a, b = a.expand(shape), b.expand(shape)
    # unit vectors first: products of metre-scale lengths overflow float32 (1e11² · 1e8²)
    a = a / torch.linalg.vector_norm(a, dim=-1, keepdim=True)
    b = b / torch.linalg.vector_norm(b, dim=-1, keepdim=True)
    cross = torch.linalg.cross(a, b, dim=-1)
    # sqrt(|c|^2 + tiny) keeps the gradient finite when a and b are exactly parallel
    tiny = torch.finfo(cross.dtype).tiny
    sine = torch.sqrt((cross * cross).sum(-1) + tiny)
    cosine = (a * b).sum(-1)
    return torch.atan2(sine, cosine)


def phase_angle(sun_vec, moon_vec, observer_vec=None) -> torch.Tensor:
    """Lunar phase angle: Sun–Moon–observer angle [rad].

    Parameters
    ----------
    sun_vec : Tensor (..., 3)
        Geocentric position of the Sun [m] (any frame shared with ``moon_vec``).
    moon_vec : Tensor (..., 3)
        Geocentric position of the Moon [m].
    observer_vec : Tensor (..., 3), optional
        Geocentric position of the observer [m] for the topocentric phase angle;
        the Earth's centre when omitted. The leading dimensions of the three vectors
        broadcast (``ValueError`` naming the shapes if they do not).

    Returns
    -------
    Tensor (...)
        Phase angle i in [0, π] [rad]: 0 at full Moon, π at new Moon.

    Notes
    -----
    ``i = ∠(r_sun − r_moon, r_obs − r_moon)``, computed with :func:`angle_between`.
    Equivalent to Meeus (1998) eq. 48.2–48.3 without their small-angle steps.

    Examples
    --------
    >>> import torch
    >>> sun = torch.tensor([1.496e11, 0.0, 0.0], dtype=torch.float64)
    >>> moon = torch.tensor([0.0, 3.844e8, 0.0], dtype=torch.float64)  # at quadrature
    >>> i = phase_angle(sun, moon)
    >>> round(float(torch.rad2deg(i)), 2), round(float(illuminated_fraction(i)), 3)
    (89.85, 0.501)
    """
    dtype = common_dtype(sun_vec, moon_vec, observer_vec)
    sun = check_shape_last("sun_vec", _tensor("sun_vec", sun_vec, dtype), 3)
    moon = check_shape_last("moon_vec", _tensor("moon_vec", moon_vec, dtype), 3)
    if observer_vec is None:
        shape = check_broadcastable(sun_vec=sun, moon_vec=moon)
        to_observer = -moon.expand(shape)
    else:
        observer = check_shape_last("observer_vec", _tensor("observer_vec", observer_vec,
                                                            dtype), 3)
        shape = check_broadcastable(sun_vec=sun, moon_vec=moon, observer_vec=observer)
        to_observer = observer - moon
    to_sun = (sun - moon).expand(shape)
    to_observer = to_observer.expand(shape)
    with torch.no_grad():
        for what, vector in (("the Sun", to_sun), ("the observer", to_observer)):
            if bool((torch.linalg.vector_norm(vector, dim=-1) == 0.0).any()):
                raise ValueError(f"moon_vec coincides with {what} (distance 0 m): the phase "
                                 "angle is undefined; the Moon must be at distance > 0 m")
    return angle_between(to_sun, to_observer)


def radec_to_vector(ra_rad, dec_rad, distance=1.0) -> torch.Tensor:
    """Cartesian vector (…, 3) from right ascension, declination [rad] and distance."""
    dtype = common_dtype(ra_rad, dec_rad, distance)
    ra = _tensor("ra_rad", ra_rad, dtype)
    dec = _tensor("dec_rad", dec_rad, dtype)
    dist = _tensor("distance", distance, dtype)
    _broadcast_inputs(ra_rad=ra, dec_rad=dec, distance=dist)
    cos_dec = torch.cos(dec)
    return torch.stack(torch.broadcast_tensors(dist * cos_dec * torch.cos(ra),
                                               dist * cos_dec * torch.sin(ra),
                                               dist * torch.sin(dec)), dim=-1)


def phase_angle_from_radec(sun_ra_rad, sun_dec_rad, sun_distance_m,
                           moon_ra_rad, moon_dec_rad, moon_distance_m) -> torch.Tensor:
    """Geocentric phase angle [rad] from equatorial coordinates and distances.

    Same result as Meeus (1998) eq. 48.2–48.3, evaluated through :func:`phase_angle`.
    """
    sun = radec_to_vector(sun_ra_rad, sun_dec_rad, sun_distance_m)
    moon = radec_to_vector(moon_ra_rad, moon_dec_rad, moon_distance_m)
    return phase_angle(sun, moon)


def illuminated_fraction(phase_angle_rad) -> torch.Tensor:
    """Illuminated fraction of the lunar disc, ``k = (1 + cos i) / 2`` (Meeus eq. 48.1).

    Parameters
    ----------
    phase_angle_rad : Tensor (...)
        Phase angle i [rad], in [-pi, pi] (signed phase angles, as in the photometry).

    Returns
    -------
    Tensor (...)
        Fraction in [0, 1]; 1 at full Moon, 0 at new Moon.
    """
    i = check_range("phase_angle_rad", as_tensor("phase_angle_rad", phase_angle_rad),
                    -math.pi, math.pi, unit=" rad")
    return 0.5 * (1.0 + torch.cos(i))


def bright_limb_position_angle(sun_ra_rad, sun_dec_rad, moon_ra_rad,
                               moon_dec_rad) -> torch.Tensor:
    """Position angle χ of the Moon's bright limb (Meeus 1998, eq. 48.5) [rad].

    Parameters
    ----------
    sun_ra_rad, sun_dec_rad : Tensor (...)
        Apparent right ascension α0 and declination δ0 of the Sun [rad].
    moon_ra_rad, moon_dec_rad : Tensor (...)
        Apparent right ascension α and declination δ of the Moon [rad].

    Returns
    -------
    Tensor (...)
        χ in [0, 2π), measured from the north point of the disc towards the east [rad].
        The bright limb is the midpoint of the illuminated limb; the cusps lie at χ ± 90°.
    """
    dtype = common_dtype(sun_ra_rad, sun_dec_rad, moon_ra_rad, moon_dec_rad)
    a0 = _tensor("sun_ra_rad", sun_ra_rad, dtype)
    d0 = _tensor("sun_dec_rad", sun_dec_rad, dtype)
    a = _tensor("moon_ra_rad", moon_ra_rad, dtype)
    d = _tensor("moon_dec_rad", moon_dec_rad, dtype)
    _broadcast_inputs(sun_ra_rad=a0, sun_dec_rad=d0, moon_ra_rad=a, moon_dec_rad=d)
    numerator = torch.cos(d0) * torch.sin(a0 - a)
    denominator = torch.sin(d0) * torch.cos(d) - torch.cos(d0) * torch.sin(d) * torch.cos(a0 - a)
    return wrap_to_turn(torch.atan2(numerator, denominator), 2.0 * math.pi)


def mean_lunar_elements(julian_centuries_tt) -> tuple[torch.Tensor, torch.Tensor]:
    """Moon's mean argument of latitude F and mean ascending node Ω [rad].

    Parameters
    ----------
    julian_centuries_tt : Tensor (...)
        T = (JDE − 2451545.0) / 36525, Julian centuries of TT from J2000.0.

    Returns
    -------
    (F, Ω) : tuple of Tensor (...)
        Reduced to [0, 2π) [rad].

    Notes
    -----
    Meeus (1998) eq. 47.5 and 47.7 (after Chapront-Touzé & Chapront, ELP-2000/82)::

        F = 93.2720950 + 483202.0175233 T − 0.0036539 T² − T³/3526000 + T⁴/863310000
        Ω = 125.0445479 − 1934.1362891 T + 0.0020754 T² + T³/467441 − T⁴/60616000

    (degrees). The polynomial is evaluated in float64 before the final cast: in float32
    the 483202° T term alone would lose ~0.01°.
    """
    t_in = _tensor("julian_centuries_tt", julian_centuries_tt, None)
    return (_mean_element(t_in, _ARGUMENT_OF_LATITUDE), _mean_element(t_in, _ASCENDING_NODE))


#: Meeus (1998) eq. 47.2–47.7: coefficients [deg] of 1, T, T², and the divisors of T³, T⁴
_MEAN_ELONGATION = (297.8501921, 445267.1114034, -0.0018819, 545868.0, -113065000.0)
_SUN_MEAN_ANOMALY = (357.5291092, 35999.0502909, -0.0001536, 24490000.0, math.inf)
_MOON_MEAN_ANOMALY = (134.9633964, 477198.8675055, 0.0087414, 69699.0, -14712000.0)
_ARGUMENT_OF_LATITUDE = (93.2720950, 483202.0175233, -0.0036539, -3526000.0, 863310000.0)
_ASCENDING_NODE = (125.0445479, -1934.1362891, 0.0020754, 467441.0, -60616000.0)


def _mean_element(t_in: torch.Tensor, coefficients) -> torch.Tensor:
    """c0 + c1 T + c2 T² + T³/c3 + T⁴/c4 [deg], evaluated in float64, reduced, in [rad]."""
    t = t_in.to(torch.float64)
    c0, c1, c2, c3, c4 = coefficients
    value = c0 + c1 * t + c2 * t**2 + t**3 / c3 + t**4 / c4
    return (wrap_to_turn(value, 360.0) * DEGREE).to(t_in.dtype)


#: Meeus (1998, ch. 53) physical-libration series [deg]: (amplitude, function, multiples
#: of (D, M, M′, F)); "sinE" terms carry the eccentricity factor E, "sinK1", "sinK2" and
#: "sinNode" are sin K1, sin K2 and sin Ω
_RHO_TERMS = (
    (-0.02752, "cos", (0, 0, 1, 0)), (-0.02245, "sin", (0, 0, 0, 1)),
    (0.00684, "cos", (0, 0, 1, -2)), (-0.00293, "cos", (0, 0, 0, 2)),
    (-0.00085, "cos", (-2, 0, 0, 2)), (-0.00054, "cos", (-2, 0, 1, 0)),
    (-0.00020, "sin", (0, 0, 1, 1)), (-0.00020, "cos", (0, 0, 1, 2)),
    (-0.00020, "cos", (0, 0, 1, -1)), (0.00014, "cos", (-2, 0, 1, 2)),
)
_SIGMA_TERMS = (
    (-0.02816, "sin", (0, 0, 1, 0)), (0.02244, "cos", (0, 0, 0, 1)),
    (-0.00682, "sin", (0, 0, 1, -2)), (-0.00279, "sin", (0, 0, 0, 2)),
    (-0.00083, "sin", (-2, 0, 0, 2)), (0.00069, "sin", (-2, 0, 1, 0)),
    (0.00040, "cos", (0, 0, 1, 1)), (-0.00025, "sin", (0, 0, 2, 0)),
    (-0.00023, "sin", (0, 0, 1, 2)), (0.00020, "cos", (0, 0, 1, -1)),
    (0.00019, "sin", (0, 0, 1, -1)), (0.00013, "sin", (-2, 0, 1, 2)),
    (-0.00010, "cos", (0, 0, 1, -3)),
)
_TAU_TERMS = (
    (0.02520, "sinE", (0, 1, 0, 0)), (0.00473, "sin", (0, 0, 2, -2)),
    (-0.00467, "sin", (0, 0, 1, 0)), (0.00396, "sinK1", ()),
    (0.00276, "sin", (-2, 0, 2, 0)), (0.00196, "sinNode", ()),
    (-0.00183, "cos", (0, 0, 1, -1)), (0.00115, "sin", (-2, 0, 1, 0)),
    (-0.00096, "sin", (-1, 0, 1, 0)), (0.00046, "sin", (-2, 0, 0, 2)),
    (-0.00039, "sin", (0, 0, 1, -1)), (-0.00032, "sin", (-1, -1, 1, 0)),
    (0.00027, "sin", (-2, -1, 2, 0)), (0.00023, "sinK2", ()),
    (-0.00014, "sin", (2, 0, 0, 0)), (0.00014, "cos", (0, 0, 2, -2)),
    (-0.00012, "sin", (0, 0, 1, -2)), (-0.00012, "sin", (0, 0, 2, 0)),
    (0.00011, "sin", (-2, -2, 2, 0)),
)


def physical_libration_angles(julian_centuries_tt) -> tuple[torch.Tensor, torch.Tensor,
                                                             torch.Tensor]:
    """Compute the forced physical libration ρ, σ, τ of the Moon (Meeus 1998, ch. 53) [rad].

    Parameters
    ----------
    julian_centuries_tt : Tensor (...)
        T, Julian centuries of TT from J2000.0.

    Returns
    -------
    (ρ, σ, τ) : tuple of Tensor (...)
        ρ and σ: displacements of the rotation axis (in inclination and node), τ: the
        libration in longitude; each ≲ 0.03° [rad].

    Notes
    -----
    Meeus's 10 + 13 + 19 periodic terms (after Eckhardt's theory) in the mean elongation
    D, the mean anomalies M (Sun) and M′ (Moon), the argument of latitude F, the node
    Ω (eq. 47.2–47.7), the eccentricity factor E = 1 − 0.002516 T − 0.0000074 T² and
    K1 = 119.75° + 131.849° T, K2 = 72.56° + 20.186° T.
    """
    t_in = _tensor("julian_centuries_tt", julian_centuries_tt, None)
    t = t_in.to(torch.float64)
    args = [_mean_element(t, c).to(torch.float64) for c in
            (_MEAN_ELONGATION, _SUN_MEAN_ANOMALY, _MOON_MEAN_ANOMALY, _ARGUMENT_OF_LATITUDE)]
    node = _mean_element(t, _ASCENDING_NODE).to(torch.float64)
    eccentricity = 1.0 - 0.002516 * t - 0.0000074 * t**2
    k1 = (119.75 + 131.849 * t) * DEGREE
    k2 = (72.56 + 20.186 * t) * DEGREE
    special = {"sinK1": torch.sin(k1), "sinK2": torch.sin(k2), "sinNode": torch.sin(node)}

    def series(terms):
        total = torch.zeros_like(t)
        for amplitude, kind, multiples in terms:
            if kind in special:
                total = total + amplitude * special[kind]
                continue
            angle = sum(m * a for m, a in zip(multiples, args, strict=False) if m)
            value = torch.cos(angle) if kind == "cos" else torch.sin(angle)
            if kind == "sinE":
                value = value * eccentricity
            total = total + amplitude * value
        return (total * DEGREE).to(t_in.dtype)

    return series(_RHO_TERMS), series(_SIGMA_TERMS), series(_TAU_TERMS)


def optical_libration(moon_lon_rad, moon_lat_rad, julian_centuries_tt,
                      nutation_lon_rad=0.0) -> tuple[torch.Tensor, torch.Tensor]:
    """Optical libration in longitude l' and latitude b' (Meeus 1998, eq. 53.1) [rad].

    Parameters
    ----------
    moon_lon_rad, moon_lat_rad : Tensor (...)
        Apparent geocentric ecliptic longitude λ (referred to the true equinox of date,
        i.e. including the nutation in longitude) and latitude β of the Moon [rad].
    julian_centuries_tt : Tensor (...)
        T, Julian centuries of TT from J2000.0 (for the mean elements F and Ω).
    nutation_lon_rad : Tensor (...), optional
        Nutation in longitude Δψ [rad] (0 when λ is referred to the mean equinox).

    Returns
    -------
    (l, b) : tuple of Tensor (...)
        Optical libration in longitude, wrapped to (−π, π], and in latitude [rad].
        Positive l brings the east limb (Mare Crisium) towards the observer; positive b
        brings the north pole into view. Physical libration (≲ 0.04°) is not included.
    """
    libration_lon, libration_lat, _ = _optical_libration(moon_lon_rad, moon_lat_rad,
                                                         julian_centuries_tt, nutation_lon_rad)
    return libration_lon, libration_lat


def _optical_libration(moon_lon_rad, moon_lat_rad, julian_centuries_tt, nutation_lon_rad):
    """(l′, b′, A) of Meeus eq. 53.1 [rad]."""
    dtype = common_dtype(moon_lon_rad, moon_lat_rad, julian_centuries_tt, nutation_lon_rad)
    lam = _tensor("moon_lon_rad", moon_lon_rad, dtype)
    beta = _tensor("moon_lat_rad", moon_lat_rad, dtype)
    dpsi = _tensor("nutation_lon_rad", nutation_lon_rad, dtype)
    centuries = _tensor("julian_centuries_tt", julian_centuries_tt, dtype)
    _broadcast_inputs(moon_lon_rad=lam, moon_lat_rad=beta, julian_centuries_tt=centuries,
                      nutation_lon_rad=dpsi)
    f, node = mean_lunar_elements(centuries)
    inclination = MEAN_LUNAR_EQUATOR_INCLINATION_RAD
    w = lam - dpsi - node
    sin_i, cos_i = math.sin(inclination), math.cos(inclination)
    a = torch.atan2(torch.sin(w) * torch.cos(beta) * cos_i - torch.sin(beta) * sin_i,
                    torch.cos(w) * torch.cos(beta))
    libration_lon = _wrap(a - f)
    sin_b = -torch.sin(w) * torch.cos(beta) * sin_i - torch.sin(beta) * cos_i
    libration_lat = torch.asin(sin_b)  # |b'| <= I + |β| < 7°, far from the asin poles
    return libration_lon, libration_lat, a


def _wrap(angle: torch.Tensor) -> torch.Tensor:
    """Angle wrapped to (−π, π]."""
    return torch.remainder(angle + math.pi, 2.0 * math.pi) - math.pi


def physical_libration(moon_lon_rad, moon_lat_rad, julian_centuries_tt,
                       nutation_lon_rad=0.0) -> tuple[torch.Tensor, torch.Tensor]:
    """Physical libration in longitude l″ and latitude b″ (Meeus 1998, ch. 53) [rad].

    Parameters
    ----------
    moon_lon_rad, moon_lat_rad, julian_centuries_tt, nutation_lon_rad : Tensor (...)
        As in :func:`optical_libration`.

    Returns
    -------
    (l″, b″) : tuple of Tensor (...)
        ``l″ = −τ + (ρ cos A + σ sin A) tan b′``, ``b″ = σ cos A − ρ sin A`` [rad] with ρ,
        σ, τ from :func:`physical_libration_angles` and A, b′ of the optical libration;
        |l″|, |b″| ≲ 0.04°.
    """
    _, optical_lat, a = _optical_libration(moon_lon_rad, moon_lat_rad, julian_centuries_tt,
                                           nutation_lon_rad)
    rho, sigma, tau = physical_libration_angles(julian_centuries_tt)
    rho, sigma, tau = (x.to(a.dtype) for x in (rho, sigma, tau))
    cos_a, sin_a = torch.cos(a), torch.sin(a)
    return (-tau + (rho * cos_a + sigma * sin_a) * torch.tan(optical_lat),
            sigma * cos_a - rho * sin_a)


def libration(moon_lon_rad, moon_lat_rad, julian_centuries_tt, nutation_lon_rad=0.0,
              physical: bool = True) -> tuple[torch.Tensor, torch.Tensor]:
    """Total geocentric libration l = l′ + l″, b = b′ + b″ (Meeus 1998, ch. 53) [rad].

    Parameters
    ----------
    moon_lon_rad, moon_lat_rad, julian_centuries_tt, nutation_lon_rad : Tensor (...)
        As in :func:`optical_libration`.
    physical : bool
        Add the physical libration (:func:`physical_libration`); False gives the optical
        libration alone.

    Returns
    -------
    (l, b) : tuple of Tensor (...)
        Libration in longitude, wrapped to (−π, π], and in latitude [rad]; the
        selenographic longitude and latitude of the sub-Earth point.

    Examples
    --------
    >>> import math, torch
    >>> from skytorch.moon.geometry import libration
    >>> deg = math.pi / 180  # Meeus ex. 53.a, 1992 April 12 0h TD
    >>> t = torch.tensor((2448724.5 - 2451545.0) / 36525.0, dtype=torch.float64)
    >>> l, b = libration(torch.tensor(133.167265 * deg, dtype=torch.float64),
    ...                  torch.tensor(-3.229126 * deg, dtype=torch.float64), t,
    ...                  torch.tensor(0.004610 * deg, dtype=torch.float64))
    >>> round(float(l) / deg, 2), round(float(b) / deg, 2)
    (-1.23, 4.2)
    """
    lon, lat = optical_libration(moon_lon_rad, moon_lat_rad, julian_centuries_tt,
                                 nutation_lon_rad)
    if not physical:
        return lon, lat
    extra_lon, extra_lat = physical_libration(moon_lon_rad, moon_lat_rad,
                                              julian_centuries_tt, nutation_lon_rad)
    return _wrap(lon + extra_lon), lat + extra_lat


def axis_position_angle(moon_ra_rad, libration_lat_rad, julian_centuries_tt, obliquity_rad,
                        nutation_lon_rad=0.0, physical: bool = True) -> torch.Tensor:
    """Position angle P of the Moon's axis of rotation (Meeus 1998, ch. 53) [rad].

    Parameters
    ----------
    moon_ra_rad : Tensor (...)
        Apparent right ascension α of the Moon [rad].
    libration_lat_rad : Tensor (...)
        Libration in latitude b [rad] (total, from :func:`libration`, or optical).
    julian_centuries_tt : Tensor (...)
        T, Julian centuries of TT from J2000.0 (for Ω).
    obliquity_rad : Tensor (...)
        True obliquity of the ecliptic ε [rad].
    nutation_lon_rad : Tensor (...), optional
        Nutation in longitude Δψ [rad].
    physical : bool
        Include the physical libration of the axis (ρ, σ of
        :func:`physical_libration_angles`); without it P changes by ≲ 0.03° (Meeus ex.
        53.a: 15.08° with it, 15.066° without).

    Returns
    -------
    Tensor (...)
        P in (−π/2, π/2], the position angle of the northern end of the axis, from north
        through east [rad].

    Notes
    -----
    ``V = Ω + Δψ + σ / sin I``, ``X = sin(I + ρ) sin V``,
    ``Y = sin(I + ρ) cos V cos ε − cos(I + ρ) sin ε``, ``ω = atan2(X, Y)``,
    ``sin P = √(X² + Y²) cos(α − ω) / cos b`` (ρ = σ = 0 without physical libration).
    """
    dtype = common_dtype(moon_ra_rad, libration_lat_rad, julian_centuries_tt, obliquity_rad,
                         nutation_lon_rad)
    ra = _tensor("moon_ra_rad", moon_ra_rad, dtype)
    b = _tensor("libration_lat_rad", libration_lat_rad, dtype)
    eps = _tensor("obliquity_rad", obliquity_rad, dtype)
    dpsi = _tensor("nutation_lon_rad", nutation_lon_rad, dtype)
    centuries = _tensor("julian_centuries_tt", julian_centuries_tt, dtype)
    _broadcast_inputs(moon_ra_rad=ra, libration_lat_rad=b, julian_centuries_tt=centuries,
                      obliquity_rad=eps, nutation_lon_rad=dpsi)
    _, node = mean_lunar_elements(centuries)
    inclination = torch.full_like(node, MEAN_LUNAR_EQUATOR_INCLINATION_RAD)
    v = node + dpsi
    if physical:
        rho, sigma, _ = physical_libration_angles(centuries)
        v = v + sigma / math.sin(MEAN_LUNAR_EQUATOR_INCLINATION_RAD)
        inclination = inclination + rho
    x = torch.sin(inclination) * torch.sin(v)
    y = (torch.sin(inclination) * torch.cos(v) * torch.cos(eps)
         - torch.cos(inclination) * torch.sin(eps))
    omega = torch.atan2(x, y)
    sin_p = torch.sqrt(x * x + y * y) * torch.cos(ra - omega) / torch.cos(b)
    return torch.asin(sin_p.clamp(-1.0, 1.0))


def orientation_matrix(libration_lon_rad, libration_lat_rad, parallactic_angle_rad,
                       axis_position_angle_rad) -> torch.Tensor:
    """Selenocentric orientation ``R_m = R_x(b) R_y(l) R_z(p − a)`` (Müller et al. 2012, eq. 2).

    Parameters
    ----------
    libration_lon_rad, libration_lat_rad : Tensor (...)
        Libration in longitude l and latitude b [rad].
    parallactic_angle_rad : Tensor (...)
        Parallactic angle p [rad].
    axis_position_angle_rad : Tensor (...)
        Position angle a of the lunar axis [rad].

    Returns
    -------
    Tensor (..., 3, 3)
        Rotation matrix (counter-clockwise elementary rotations about x, y, z) taking
        disc-frame normals to selenographic directions for texture look-up.
    """
    dtype = common_dtype(libration_lon_rad, libration_lat_rad, parallactic_angle_rad,
                         axis_position_angle_rad)
    b = _tensor("libration_lat_rad", libration_lat_rad, dtype)
    lon = _tensor("libration_lon_rad", libration_lon_rad, dtype)
    p = _tensor("parallactic_angle_rad", parallactic_angle_rad, dtype)
    a = _tensor("axis_position_angle_rad", axis_position_angle_rad, dtype)
    _broadcast_inputs(libration_lon_rad=lon, libration_lat_rad=b, parallactic_angle_rad=p,
                      axis_position_angle_rad=a)
    z_angle = p - a
    b, lon, z_angle = torch.broadcast_tensors(b, lon, z_angle)
    one, zero = torch.ones_like(b), torch.zeros_like(b)

    def matrix(rows):
        return torch.stack([torch.stack(row, dim=-1) for row in rows], dim=-2)

    cb, sb, cl, sl = torch.cos(b), torch.sin(b), torch.cos(lon), torch.sin(lon)
    cz, sz = torch.cos(z_angle), torch.sin(z_angle)
    rx = matrix([[one, zero, zero], [zero, cb, -sb], [zero, sb, cb]])
    ry = matrix([[cl, zero, sl], [zero, one, zero], [-sl, zero, cl]])
    rz = matrix([[cz, -sz, zero], [sz, cz, zero], [zero, zero, one]])
    return rx @ ry @ rz


def parallactic_angle(hour_angle_rad, dec_rad, lat_rad) -> torch.Tensor:
    """Parallactic angle q (Meeus 1998, eq. 14.1) [rad].

    Parameters
    ----------
    hour_angle_rad : Tensor (...)
        Local hour angle H of the object [rad] (positive west of the meridian).
    dec_rad : Tensor (...)
        Declination δ of the object [rad].
    lat_rad : Tensor (...)
        Geographic latitude φ of the observer [rad].

    Returns
    -------
    Tensor (...)
        q in (−π, π]: the angle at the object from the direction of the north celestial
        pole to the direction of the zenith, positive towards the west (q > 0 after the
        meridian passage) [rad]. Undefined (returned as 0) when the object is at the
        zenith or at a celestial pole.
    """
    dtype = common_dtype(hour_angle_rad, dec_rad, lat_rad)
    h = _tensor("hour_angle_rad", hour_angle_rad, dtype)
    dec = _tensor("dec_rad", dec_rad, dtype)
    lat = _tensor("lat_rad", lat_rad, dtype)
    _broadcast_inputs(hour_angle_rad=h, dec_rad=dec, lat_rad=lat)
    y = torch.sin(h) * torch.cos(lat)
    x = torch.sin(lat) * torch.cos(dec) - torch.cos(lat) * torch.sin(dec) * torch.cos(h)
    return torch.atan2(y, x)


def apparent_diameter(distance_m, radius_m: float = MOON_RADIUS_M) -> torch.Tensor:
    """Apparent angular diameter ``2 asin(R / d)`` of a sphere [rad].

    Parameters
    ----------
    distance_m : Tensor (...)
        Distance from the observer to the centre of the Moon [m] (> radius).
    radius_m : float
        Radius of the sphere [m]; the IAU mean lunar radius by default.

    Returns
    -------
    Tensor (...)
        Angular diameter [rad]: about 0.49°–0.56° for the Moon (Müller et al. 2012, §2.1.1).
    """
    radius_m = float(check_positive("radius_m", radius_m, unit=" m"))
    d = _tensor("distance_m", distance_m, None)
    with torch.no_grad():
        if bool((d <= radius_m).any()):
            raise ValueError(f"distance_m must be > the radius {radius_m} m; got "
                             f"{float(d.min())} m")
    return 2.0 * torch.asin(radius_m / d)
