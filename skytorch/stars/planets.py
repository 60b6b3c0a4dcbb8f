r"""The naked-eye planets: apparent places, phases and V magnitudes.

Two layers:

* :func:`planet_magnitude` — the V magnitude of a planet from its distances to the Sun
  and the observer and its phase angle (Mallama & Hilton 2018, the formulae of the
  Astronomical Almanac since 2018), with the ring and latitude terms of Saturn and
  Uranus from :func:`sub_latitudes`; tensors in, tensors out, differentiable;
* :func:`planets` — a Dataset over ``(time, planet)`` of apparent places (DE421 through
  skyfield), distances, phase angle, illuminated fraction, elongation, angular diameter,
  V magnitude and B−V, with the topocentric altitude and azimuth of an observer.

Notes
-----
With :math:`r` and :math:`\Delta` the planet's distances from the Sun and the observer
[au] and :math:`\alpha` the phase angle [degree],

.. math:: V = 5 \log_{10}(r \Delta) + V(1, \alpha),

where :math:`V(1, \alpha)` is each planet's fitted phase curve (ref. 1, eqs. 2–17; the
polynomials are listed in the source). The fits hold over the phase angles observed
from Earth and, for Mercury, Venus, Mars, Jupiter and the globe of Saturn, far beyond;
Saturn with its rings is fitted only for :math:`\alpha \le 6.5°` and a ring opening
:math:`\le 27°`, Neptune's phase curve only after 2000 — outside those ranges
:func:`planet_magnitude` raises. Mars' corrections for the longitude of its central
meridian and its orbital longitude (ref. 1, its Tables 3–4, up to ±0.1 mag) are not
applied. The Sun–planet vector is taken from the Sun's centre (not the barycentre) at
the time the light left the planet.

The phase angle is the angle Sun–planet–observer; the illuminated fraction of the disc
is :math:`(1 + \cos\alpha)/2`. B−V colours (ref. 3) are the planets' mean colours at
small phase; Mars reddens with phase and the others change by under 0.1 mag.

References
----------
1. Mallama, A., Hilton, J. L. 2018, "Computing apparent planetary magnitudes for The
   Astronomical Almanac", Astronomy and Computing 25, 10–24,
   doi:10.1016/j.ascom.2018.08.002 (arXiv:1808.01973); reference program
   ``Ap_Mag_V3.f90`` and its test output ``Ap_Mag_Output_V3.txt``
   (sourceforge.net/projects/planetary-magnitudes).
2. Archinal, B. A. et al. 2018, "Report of the IAU Working Group on Cartographic
   Coordinates and Rotational Elements: 2015", Celestial Mechanics and Dynamical
   Astronomy 130, 22, doi:10.1007/s10569-017-9805-5 (pole directions and equatorial
   radii).
3. Cox, A. N. (ed.) 2000, "Allen's Astrophysical Quantities", 4th ed., Springer, §12.3
   (B−V of the planets).

Examples
--------
>>> import torch
>>> from skytorch.stars.planets import planet_magnitude
>>> v = planet_magnitude("jupiter", torch.tensor(4.957681473205),
...                      torch.tensor(3.95393078136013), torch.tensor(0.3431).deg2rad())
>>> round(float(v), 3)
-2.934
"""

from __future__ import annotations

import json
import math

import numpy as np
import torch
import xarray as xr

from skytorch._validate import (
    as_tensor,
    check_broadcastable,
    check_choice,
    check_flag,
    check_range,
)
from skytorch.constants import ASTRONOMICAL_UNIT_M
from skytorch.dataset import VariableSpec, build_dataset, coordinate, time_coordinate, variable
from skytorch.ephemeris import (
    EPHEMERIS_FILE,
    load_ephemeris,
    one_observer,
    parse_times,
    skyfield_time,
)
from skytorch.stars.observation import refract, refraction_table
from skytorch.stars.photometry import apparent_horizon, extinction, extinction_table

__all__ = ["PLANETS", "PLANET_BV", "PLANET_RADIUS_M", "PLANET_TIME_MIN", "planet_magnitude",
           "planets", "sub_latitudes"]

#: the planets :func:`planets` and :func:`planet_magnitude` know, from the Sun outwards
PLANETS = ("mercury", "venus", "mars", "jupiter", "saturn", "uranus", "neptune")
#: DE421 targets (barycentres of the systems with moons; the Mars–barycentre offset is
#: 20 cm, Jupiter's 600 km, 0.0002″ at opposition)
_TARGETS = {"mercury": "mercury", "venus": "venus", "mars": "mars barycenter",
            "jupiter": "jupiter barycenter", "saturn": "saturn barycenter",
            "uranus": "uranus barycenter", "neptune": "neptune barycenter"}
#: mean B−V colour [mag] (ref. 3)
PLANET_BV = {"mercury": 0.93, "venus": 0.82, "mars": 1.36, "jupiter": 0.83, "saturn": 1.04,
             "uranus": 0.56, "neptune": 0.41}
#: equatorial radius [m] (ref. 2; 1-bar level for the giants)
PLANET_RADIUS_M = {"mercury": 2_440_530.0, "venus": 6_051_800.0, "mars": 3_396_190.0,
                   "jupiter": 71_492_000.0, "saturn": 60_268_000.0, "uranus": 25_559_000.0,
                   "neptune": 24_764_000.0}
#: north pole (right ascension, declination) at J2000 [degree] and their rates per Julian
#: century (ref. 2), for the latitude terms of Saturn and Uranus
_POLES = {"saturn": ((40.589, -0.036), (83.537, -0.004)),
          "uranus": ((257.311, 0.0), (-15.175, 0.0))}
#: Saturn's ring model holds up to this phase angle and ring opening [degree] (ref. 1)
SATURN_RING_LIMITS_DEG = (6.5, 27.0)
#: earliest UTC instant for the planets: DE421 starts at 1899-07-29 00:00 and Neptune's light
#: takes up to 4.5 h to reach Earth
PLANET_TIME_MIN = np.datetime64("1899-07-29T05:00", "ns")
#: Neptune's phase term is fitted to observations after this year (ref. 1)
NEPTUNE_PHASE_SINCE_YEAR = 2000.0


def _polynomial(x: torch.Tensor, coefficients) -> torch.Tensor:
    """Horner sum ``c0 + c1 x + c2 x^2 + ...``."""
    total = torch.full_like(x, coefficients[-1])
    for c in reversed(coefficients[:-1]):
        total = total * x + c
    return total


def _mercury(alpha, **_):
    return _polynomial(alpha, (-0.613, 6.3280e-02, -1.6336e-03, 3.3644e-05, -3.4265e-07,
                               1.6893e-09, -3.0334e-12))


def _venus(alpha, **_):
    near = _polynomial(alpha, (-4.384, -1.044e-03, 3.687e-04, -2.814e-06, 8.938e-09))
    crescent = _polynomial(alpha, (236.05828, -2.81914, 8.39034e-03))
    return torch.where(alpha < 163.7, near, crescent)


def _mars(alpha, **_):
    return torch.where(alpha <= 50.0, _polynomial(alpha, (-1.601, 2.267e-02, -1.302e-04)),
                       _polynomial(alpha, (-0.367, -0.02573, 3.445e-04)))


def _jupiter(alpha, **_):
    x = alpha / 180.0
    far = -9.428 - 2.5 * torch.log10(_polynomial(x, (1.0, -1.507, -0.363, -0.062, 2.809,
                                                     -1.876)))
    return torch.where(alpha <= 12.0, _polynomial(alpha, (-9.395, -3.7e-04, 6.16e-04)), far)


def _saturn(alpha, sun_latitude, observer_latitude, rings, **_):
    if rings:
        # geometric mean of the ring openings seen from the Sun and the observer, 0 when
        # they light and see opposite faces
        product = sun_latitude * observer_latitude
        opening = torch.sqrt(torch.where(product > 0.0, product, torch.ones_like(product)))
        opening = torch.where(product > 0.0, opening, torch.zeros_like(opening))
        limit_alpha, limit_opening = SATURN_RING_LIMITS_DEG
        outside = (alpha > limit_alpha) | (opening.rad2deg() > limit_opening)
        if bool(outside.any()):
            raise ValueError(
                "Saturn's magnitude with rings is fitted for phase angles <= "
                f"{limit_alpha} deg and ring openings <= {limit_opening} deg (Mallama & "
                f"Hilton 2018); got phase angle up to {float(alpha.max()):.2f} deg, opening "
                f"up to {float(opening.rad2deg().max()):.2f} deg (rings=False gives the "
                "globe alone)")
        s = torch.sin(opening)
        return -8.914 - 1.825 * s + 0.026 * alpha - 0.378 * s * torch.exp(-2.25 * alpha)
    # the globe alone; 1.506e-6 reproduces the reference program's output (ref. 1)
    return torch.where(alpha <= 6.0, _polynomial(alpha, (-8.95, -3.7e-04, 6.16e-04)),
                       _polynomial(alpha, (-8.94, 2.446e-04, 2.672e-04, -1.506e-06,
                                           4.767e-09)))


def _uranus(alpha, sun_latitude, observer_latitude, **_):
    latitude = 0.5 * (sun_latitude.abs() + observer_latitude.abs()).rad2deg()
    phase = torch.where(alpha > 3.1, _polynomial(alpha, (0.0, 6.587e-03, 1.045e-04)),
                        torch.zeros_like(alpha))
    return -7.110 - 8.4e-04 * latitude + phase


def _neptune(alpha, year, **_):
    level = torch.clamp(-6.89 - 0.0054 * (year - 1980.0), -7.00, -6.89)
    far = alpha > 1.9
    if bool((far & (year < NEPTUNE_PHASE_SINCE_YEAR)).any()):
        raise ValueError("Neptune's phase curve beyond 1.9 deg is fitted to observations "
                         f"after {NEPTUNE_PHASE_SINCE_YEAR:.0f} only (Mallama & Hilton 2018); "
                         "got a phase angle above 1.9 deg before it")
    phase = torch.where(far, _polynomial(alpha, (0.0, 7.944e-03, 9.617e-05)),
                        torch.zeros_like(alpha))
    return level + phase


_CURVES = {"mercury": _mercury, "venus": _venus, "mars": _mars, "jupiter": _jupiter,
           "saturn": _saturn, "uranus": _uranus, "neptune": _neptune}


def planet_magnitude(planet: str, sun_distance_au, observer_distance_au, phase_angle_rad, *,
                     sun_latitude_rad=None, observer_latitude_rad=None, year=None,
                     rings: bool = True) -> torch.Tensor:
    """V magnitude of a planet (Mallama & Hilton 2018) (...) [mag].

    Parameters
    ----------
    planet : {"mercury", "venus", "mars", "jupiter", "saturn", "uranus", "neptune"}
        The planet (:data:`PLANETS`).
    sun_distance_au, observer_distance_au : Tensor (...)
        Distances of the planet from the Sun and the observer [au], > 0.
    phase_angle_rad : Tensor (...)
        Angle Sun–planet–observer [rad], in [0, π].
    sun_latitude_rad, observer_latitude_rad : Tensor (...), optional
        Planetocentric latitudes of the sub-solar and sub-observer points [rad]
        (:func:`sub_latitudes`); needed for Saturn (ring opening) and Uranus.
    year : Tensor (...), optional
        Julian year (TT) of the observation; needed for Neptune.
    rings : bool
        Saturn with its rings (default) or the globe alone.

    Returns
    -------
    Tensor (...)
        V magnitude [mag]; dtype of the inputs.

    Raises
    ------
    ValueError
        Unknown planet, distances ≤ 0, a phase angle outside [0, π], a missing latitude or
        year, Saturn with rings beyond its fitted range, Neptune's phase curve before 2000.
    """
    check_choice("planet", planet, PLANETS)
    r = check_range("sun_distance_au", sun_distance_au, 0.0, low_inclusive=False, unit=" au")
    delta = check_range("observer_distance_au", observer_distance_au, 0.0,
                        low_inclusive=False, unit=" au", dtype=r.dtype)
    alpha = check_range("phase_angle_rad", phase_angle_rad, 0.0, math.pi,
                        dtype=r.dtype).rad2deg()
    check_broadcastable(sun_distance_au=r, observer_distance_au=delta, phase_angle_rad=alpha)
    extra = {"rings": check_flag("rings", rings)}
    # a setting of another planet's phase curve is refused, not ignored
    unused = [name for name, value, owners in (
        ("sun_latitude_rad", sun_latitude_rad, ("saturn", "uranus")),
        ("observer_latitude_rad", observer_latitude_rad, ("saturn", "uranus")),
        ("year", year, ("neptune",)), ("rings", None if extra["rings"] else False, ("saturn",)))
        if value is not None and planet not in owners]
    if unused:
        raise ValueError(f"{', '.join(unused)}: not used by the phase curve of {planet} "
                         "(sub-latitudes: saturn and uranus; year: neptune; rings: saturn)")
    if planet in ("saturn", "uranus"):
        for name, value in (("sun_latitude_rad", sun_latitude_rad),
                            ("observer_latitude_rad", observer_latitude_rad)):
            if value is None:
                raise ValueError(f"{name} is needed for {planet} (sub_latitudes)")
            extra[name.removesuffix("_rad")] = check_range(name, value, -0.5 * math.pi,
                                                           0.5 * math.pi, dtype=r.dtype)
    if planet == "neptune":
        if year is None:
            raise ValueError("year is needed for neptune (its brightening 1980-2000)")
        extra["year"] = check_range("year", year, dtype=r.dtype)
    return 5.0 * torch.log10(r * delta) + _CURVES[planet](alpha, **extra)


def _pole(planet: str, julian_centuries: np.ndarray) -> np.ndarray:
    """ICRS unit vector of the planet's north pole (n, 3)."""
    (ra0, ra_rate), (dec0, dec_rate) = _POLES[planet]
    ra = np.radians(ra0 + ra_rate * julian_centuries)
    dec = np.radians(dec0 + dec_rate * julian_centuries)
    return np.stack([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)], -1)


def sub_latitudes(pole, sun_to_planet, observer_to_planet) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Planetocentric latitudes of the sub-solar and sub-observer points [rad].

    Parameters
    ----------
    pole : Tensor (..., 3)
        Unit vector of the planet's north pole.
    sun_to_planet, observer_to_planet : Tensor (..., 3)
        Vectors from the Sun and the observer to the planet (any common length unit).

    Returns
    -------
    sun_latitude_rad, observer_latitude_rad : Tensor (...)
        :math:`\arcsin(-\hat p \cdot \hat v)` for each vector :math:`v`: the latitude of
        the point on the planet below the Sun or the observer.
    """
    pole = as_tensor("pole", pole)
    out = []
    for name, vector in (("sun_to_planet", sun_to_planet),
                         ("observer_to_planet", observer_to_planet)):
        v = as_tensor(name, vector, dtype=pole.dtype)
        check_broadcastable(pole=pole, **{name: v})
        cosine = -(pole * v).sum(-1) / torch.linalg.vector_norm(v, dim=-1)
        out.append(torch.asin(cosine.clamp(-1.0, 1.0)))
    return out[0], out[1]


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between rows of two (n, 3) arrays [rad] (atan2: accurate near 0 and π)."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), (a * b).sum(-1))


def _planet_columns(t, earth, earth_to_sun: np.ndarray, planet: str) -> dict[str, np.ndarray]:
    """Geocentric apparent place, distances, phase and magnitude of one planet.

    ``earth`` is the Earth's barycentric position at ``t`` (skyfield), ``earth_to_sun`` the
    astrometric geocentric Sun (n, 3) [au].
    """
    ephemeris = load_ephemeris()
    astrometric = earth.observe(ephemeris[_TARGETS[planet]])
    ra, dec, _ = astrometric.apparent().radec(epoch="date")
    astrometric_ra, astrometric_dec, _ = astrometric.radec()
    emitted = t.ts.tdb_jd(t.tdb - astrometric.light_time)
    observer_to_planet = np.asarray(astrometric.position.au, np.float64).T.reshape(-1, 3)
    planet_at_emission = np.asarray(earth.position.au, np.float64).T.reshape(-1, 3) \
        + observer_to_planet
    sun = np.asarray(ephemeris["sun"].at(emitted).position.au, np.float64).T.reshape(-1, 3)
    sun_to_planet = planet_at_emission - sun
    phase = _angle(sun_to_planet, observer_to_planet)
    extra = {}
    if planet in ("saturn", "uranus"):  # their phase curves take the sub-latitudes
        centuries = (np.asarray(t.tdb, np.float64).reshape(-1) - 2451545.0) / 36525.0
        sun_latitude, observer_latitude = sub_latitudes(
            torch.from_numpy(_pole(planet, centuries)), torch.from_numpy(sun_to_planet),
            torch.from_numpy(observer_to_planet))
        extra = {"sun_latitude_rad": sun_latitude, "observer_latitude_rad": observer_latitude}
    year = torch.from_numpy(np.asarray(t.J, np.float64).reshape(-1))
    delta = np.linalg.norm(observer_to_planet, axis=-1)
    magnitude = planet_magnitude(
        planet, torch.from_numpy(np.linalg.norm(sun_to_planet, axis=-1)),
        torch.from_numpy(delta), torch.from_numpy(phase),
        year=year if planet == "neptune" else None, **extra)
    radius_au = PLANET_RADIUS_M[planet] / ASTRONOMICAL_UNIT_M
    return {
        "ra": 15.0 * np.asarray(ra.hours, np.float64).reshape(-1),
        "dec": np.asarray(dec.degrees, np.float64).reshape(-1),
        "astrometric_ra": 15.0 * np.asarray(astrometric_ra.hours, np.float64).reshape(-1),
        "astrometric_dec": np.asarray(astrometric_dec.degrees, np.float64).reshape(-1),
        "distance": delta,
        "sun_distance": np.linalg.norm(sun_to_planet, axis=-1),
        "phase_angle": np.degrees(phase),
        "illuminated_fraction": 0.5 * (1.0 + np.cos(phase)),
        "elongation": np.degrees(_angle(earth_to_sun, observer_to_planet)),
        "angular_diameter": np.degrees(2.0 * np.arcsin(radius_au / delta)) * 3600.0,
        "magnitude": magnitude.numpy(),
    }


_PLANET_SPECS = {
    "ra": ("degree", "apparent geocentric right ascension",
           "Apparent geocentric right ascension of the planet (true equator and equinox of "
           "date; light time, aberration and light deflection applied; DE421)."),
    "dec": ("degree", "apparent geocentric declination",
            "Apparent geocentric declination of the planet (true equator and equinox of "
            "date; light time, aberration and light deflection applied; DE421)."),
    "astrometric_ra": ("degree", "astrometric geocentric right ascension",
                       "Astrometric geocentric right ascension (ICRS; light time applied, "
                       "no aberration or deflection): the catalogue-like place that "
                       "skytorch.stars.observe turns into an apparent one."),
    "astrometric_dec": ("degree", "astrometric geocentric declination",
                        "Astrometric geocentric declination (ICRS; light time applied, no "
                        "aberration or deflection)."),
    "distance": ("au", "geocentric distance", "Light-time distance from Earth's centre."),
    "sun_distance": ("au", "heliocentric distance",
                     "Distance from the Sun's centre when the light left the planet."),
    "phase_angle": ("degree", "phase angle", "Angle Sun–planet–Earth."),
    "illuminated_fraction": ("1", "illuminated fraction of the disc",
                             "(1 + cos phase angle) / 2."),
    "elongation": ("degree", "elongation", "Angle Sun–Earth–planet (geocentric)."),
    "angular_diameter": ("arcsec", "apparent equatorial diameter",
                         "Twice the angular equatorial radius (IAU 2015) seen from Earth."),
    "magnitude": ("mag", "V magnitude",
                  "Apparent V magnitude above the atmosphere, Mallama & Hilton (2018); Mars "
                  "without its rotational and orbital-longitude corrections (up to 0.1 mag); "
                  "Saturn with its rings."),
    "altitude": ("degree", "topocentric altitude",
                 "Apparent topocentric altitude of the planet's centre above the observer's "
                 "horizontal plane, geometric (no atmospheric refraction)."),
    "apparent_altitude": ("degree", "apparent topocentric altitude",
                          "Topocentric altitude of the planet's centre refracted by the "
                          "atmosphere (ray-traced)."),
    "extinction": ("mag", "V-band extinction",
                   "Extinction of the planet's light (its B-V) along the refracted path."),
    "airmass": ("1", "relative air mass", "Air mass of the refracted path."),
    "apparent_magnitude": ("mag", "V magnitude after extinction",
                           "magnitude + extinction."),
    "above_horizon": ("1", "above the apparent horizon",
                      "Apparent altitude at or above the apparent horizon (the ground)."),
    "azimuth": ("degree", "topocentric azimuth",
                "Apparent topocentric azimuth of the planet, from north through east in "
                "[0, 360)."),
}


def _through_the_atmosphere(columns, bodies, atmosphere, elevation_m: float) -> None:
    """Add refracted altitudes and V extinction to the planets' columns (in place)."""
    refraction = refraction_table(atmosphere, elevation_m)
    table = extinction_table(atmosphere, elevation_m, refraction=True)
    horizon = apparent_horizon(atmosphere, elevation_m)
    for column, body in zip(columns, bodies, strict=True):
        apparent = refract(torch.from_numpy(np.radians(column["altitude"])), refraction)
        delta_m, airmass = extinction(torch.tensor([PLANET_BV[body]], dtype=torch.float64),
                                      apparent[:, None], table)
        column["apparent_altitude"] = np.degrees(apparent.numpy())
        column["extinction"] = delta_m[:, 0].numpy()
        column["airmass"] = airmass[:, 0].numpy()
        column["apparent_magnitude"] = column["magnitude"] + column["extinction"]
        column["above_horizon"] = (apparent >= horizon).numpy()


def _check_request(bodies, lat_deg, lon_deg, elevation_m, atmosphere):
    """Check the planets and the observer of :func:`planets`; return the observer or None."""
    if isinstance(bodies, str) or not bodies:
        raise ValueError(f"bodies must be a non-empty sequence of {PLANETS}; got {bodies!r}")
    for body in bodies:
        check_choice("bodies", body, PLANETS)
    if len(set(bodies)) != len(bodies):
        raise ValueError(f"bodies must name each planet once; got {tuple(bodies)!r}")
    observer = one_observer("planets", lat_deg, lon_deg, elevation_m)
    if atmosphere is not None and observer is None:
        raise ValueError("atmosphere needs an observer: give lat_deg and lon_deg")
    return observer


def _topocentric(columns, bodies, t, observer) -> None:
    """Add the observer's geometric altitude and azimuth [degree] to the columns (in place)."""
    from skyfield.api import wgs84

    ephemeris = load_ephemeris()
    site = (ephemeris["earth"] + wgs84.latlon(observer[0], observer[1],
                                              elevation_m=observer[2])).at(t)
    for column, body in zip(columns, bodies, strict=True):
        altitude, azimuth, _ = site.observe(ephemeris[_TARGETS[body]]).apparent().altaz()
        column["altitude"] = np.asarray(altitude.degrees, np.float64).reshape(-1)
        column["azimuth"] = np.asarray(azimuth.degrees, np.float64).reshape(-1)


def planets(times, lat_deg=None, lon_deg=None, elevation_m=0.0, *,
            bodies=PLANETS, atmosphere=None) -> xr.Dataset:
    """Apparent places, phases and V magnitudes of the planets over time.

    Parameters
    ----------
    times : str, datetime, datetime64 or a list/array of them
        UTC instants (dimension ``time``), from :data:`PLANET_TIME_MIN` to
        :data:`skytorch.ephemeris.TIME_MAX`.
    lat_deg, lon_deg : float, optional
        One observer's WGS84 geodetic latitude and east longitude [degree]; both or
        neither.
    elevation_m : float
        The observer's height above the ellipsoid [m].
    bodies : sequence of str
        Planets (dimension ``planet``), from :data:`PLANETS`.
    atmosphere : skytorch.atmosphere.Atmosphere, optional
        With an observer: refract and extinguish the planets through it (scalar
        parameters), as :func:`skytorch.stars.observe` does for the stars.

    Returns
    -------
    xarray.Dataset
        Over ``(time, planet)``: ``ra``, ``dec`` [degree] (apparent, of date),
        ``astrometric_ra``, ``astrometric_dec`` [degree] (ICRS), ``distance``, ``sun_distance``
        [au], ``phase_angle``, ``elongation`` [degree], ``illuminated_fraction`` [1],
        ``angular_diameter`` [arcsec], ``magnitude`` [mag]; ``bv`` [mag] over ``planet``;
        with an observer also ``altitude`` and ``azimuth`` [degree] (no refraction);
        with an atmosphere also ``apparent_altitude`` [degree] (ray-traced refraction,
        :func:`skytorch.stars.refraction_table`), ``extinction`` [mag] and ``airmass``
        [1] of the V band along the refracted path for the planet's B−V
        (:func:`skytorch.stars.extinction_table`), ``apparent_magnitude`` [mag] and
        ``above_horizon`` (apparent altitude at or above the apparent horizon; below it
        the horizon's extinction is reported, finite). The magnitude is geocentric (the
        observer's offset changes it by < 0.001 mag).

    Raises
    ------
    ValueError
        An unknown planet, times out of range, a bad observer.

    Examples
    --------
    >>> ds = planets("2021-10-04T00:00Z", bodies=("venus", "jupiter"))
    >>> [round(float(v), 2) for v in ds.magnitude[0]]
    [-4.25, -2.69]
    """
    observer = _check_request(bodies, lat_deg, lon_deg, elevation_m, atmosphere)
    values = parse_times(times)
    if (values < PLANET_TIME_MIN).any():
        raise ValueError(f"times: the planets need times from {PLANET_TIME_MIN} UTC (DE421 "
                         "starts at 1899-07-29 and Neptune's light takes 4.5 h); got "
                         f"{values.min()}")
    t = skyfield_time(values)
    earth = load_ephemeris()["earth"].at(t)
    earth_to_sun = np.asarray(earth.observe(load_ephemeris()["sun"]).position.au,
                              np.float64).T.reshape(-1, 3)
    columns = [_planet_columns(t, earth, earth_to_sun, body) for body in bodies]
    if observer is not None:
        _topocentric(columns, bodies, t, observer)
    if atmosphere is not None:
        _through_the_atmosphere(columns, bodies, atmosphere, observer[2])
    data = {name: variable(("time", "planet"),
                           np.stack([column[name] for column in columns], axis=1),
                           VariableSpec(*_PLANET_SPECS[name]))
            for name in columns[0]}
    data["bv"] = variable("planet", np.array([PLANET_BV[b] for b in bodies]),
                          VariableSpec("mag", "B-V colour index",
                                       "Mean B-V of the planet at small phase (Allen's "
                                       "Astrophysical Quantities, 4th ed., 12.3)."))
    coords = {"time": time_coordinate(values),
              "planet": coordinate("planet", np.array(list(bodies)),
                                   VariableSpec("1", "planet", "Name of the planet."))}
    parameters: dict[str, object] = {"ephemeris": EPHEMERIS_FILE,
                                     "refraction": atmosphere is not None}
    if observer is not None:
        parameters.update(lat_deg=observer[0], lon_deg=observer[1], elevation_m=observer[2])
    if atmosphere is not None:
        parameters["atmosphere"] = json.dumps(atmosphere.parameters_dict(), default=str)
    return build_dataset(
        data, coords, title="Apparent places and V magnitudes of the planets",
        references=[
            "Mallama, A., Hilton, J. L. 2018, Astronomy and Computing 25, 10, "
            "doi:10.1016/j.ascom.2018.08.002",
            "Folkner, W. M. et al. 2009, The Planetary and Lunar Ephemeris DE 421, "
            "IPN Progress Report 42-178",
            "Archinal, B. A. et al. 2018, Celest. Mech. Dyn. Astr. 130, 22",
        ],
        parameters=parameters)
