"""Global circumstances of solar eclipses from the DE421 ephemeris (direct shadow-axis geometry).

Method
------
1. Candidates: mean new moons (Meeus 1998, eq. 49.1, integer lunation ``k`` counted from
   the new moon of 2000 Jan 6, the canon's "Luna Num") whose mean argument of latitude
   satisfies ``|sin F| < 0.40`` (Meeus ch. 54 uses 0.36 as the eclipse limit).
2. Around each candidate the apparent geocentric Sun and Moon vectors
   (:func:`skytorch.ephemeris.sun_moon_vectors`: DE421, light time, aberration, deflection;
   GCRS axes) are interpolated by Chebyshev series (the helpers of
   :mod:`skytorch.eclipse.circumstances`), so that every later step is a batched tensor
   operation on all candidates at once. Earth-fixed (ITRS) vectors follow from skyfield's
   precession-nutation matrix and Greenwich apparent sidereal time at the window centre,
   advanced at the sidereal rate :data:`EARTH_ROTATION_RATE_RAD_S` (error < 0.1 arcsec
   over the +-6 h windows used).
3. Shadow axis: the line through the Moon's centre along the Sun-to-Moon direction
   ``d``. Greatest eclipse is the instant when this axis passes closest to Earth's centre
   (grid search then golden section); ``gamma`` is that distance in Earth equatorial radii,
   signed like the north component of the closest point (the canon's convention).
4. Point of greatest eclipse: where the axis meets the WGS84 ellipsoid (central eclipse),
   else the point of the ellipsoid's outline (seen along ``d``) nearest the axis, where the
   Sun is on the geometric horizon. Magnitude there, from topocentric angular radii ``s``
   (Sun), ``m`` (Moon) and separation ``sigma``: ``m / s`` with the umbral ``k`` for central
   eclipses (ratio of apparent diameters), ``(s + m - sigma) / (2 s)`` with the penumbral
   ``k`` otherwise (fraction of the Sun's diameter covered).
5. Kind: partial, annular (``m < s`` on the axis), total (``m >= s``); a total eclipse
   whose central line ends (the axis grazing the ellipsoid, found by bisection) are
   annular is hybrid. A non-central eclipse whose umbra or antumbra touches the outline
   (``sigma < |m - s|`` at the outline point) is total or annular (``central`` False).
6. Duration of the central phase at the point of greatest eclipse: C3 - C2 there, from
   :func:`skytorch.eclipse.solar_local.solar_eclipse_local`'s solver.
7. Saros number from the lunation number: ``k - k0 = 223 n + 358 (S - S0)`` with the
   reference eclipse 2017 Aug 21 (``k0 = 218``, ``S0 = 145``), ``|S - S0| <= 111``
   (van den Bergh 1955: consecutive series are one inex, 358 lunations, apart).

Constants (those of the Five Millennium Canon): the Sun's semi-diameter 959.63 arcsec at
1 au, the Moon's radius ``k = 0.2722810`` Earth equatorial radii for umbral (central) phases
and ``k = 0.2725076`` for penumbral ones, Earth's WGS84 ellipsoid (a = 6378137 m,
f = 1/298.257223563). Times are UTC; ``time_tt`` is terrestrial (dynamical) time,
``delta_t`` is TT - UT1 from skyfield's tables (the canon's own Delta T extrapolation
differs for future dates, which shifts longitudes, never the TT instants or gamma).

References
----------
1. Espenak, F., Meeus, J. 2006, "Five Millennium Canon of Solar Eclipses: -1999 to +3000",
   NASA/TP-2006-214141 (definitions of greatest eclipse, gamma, magnitude, kinds, k).
2. Meeus, J. 1998, "Astronomical Algorithms", 2nd ed., Willmann-Bell, ch. 49, 54.
3. van den Bergh, G. 1955, "Periodicity and Variation of Solar (and Lunar) Eclipses",
   Tjeenk Willink, Haarlem (Saros numbering).
4. Urban, S. E., Seidelmann, P. K. (eds.) 2013, "Explanatory Supplement to the
   Astronomical Almanac", 3rd ed., ch. 11 (solar eclipse geometry).
"""

from __future__ import annotations

import logging
import math

import numpy as np
import torch
import xarray as xr

from skytorch.constants import EARTH_EQUATORIAL_RADIUS_M
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable
from skytorch.eclipse.circumstances import (
    SUN_SEMIDIAMETER_1AU_RAD,
    _bisect,
    _chebyshev_nodes,
    _chebyshev_values,
    _check_search_range,
    _golden_minimum,
    _sun_radius_m,
)
from skytorch.ephemeris import geodetic_to_itrs, skyfield_time, sun_moon_vectors

__all__ = [
    "EARTH_ROTATION_RATE_RAD_S",
    "MOON_RADIUS_PENUMBRAL",
    "MOON_RADIUS_UMBRAL",
    "SOLAR_ECLIPSE_KINDS",
    "solar_eclipses",
]

logger = logging.getLogger(__name__)

#: kinds of solar eclipse
SOLAR_ECLIPSE_KINDS = ("partial", "annular", "total", "hybrid")
#: the Moon's radius in Earth equatorial radii for the central (umbral) phases (canon)
MOON_RADIUS_UMBRAL = 0.2722810
#: the Moon's radius in Earth equatorial radii for the penumbral phases (IAU, canon)
MOON_RADIUS_PENUMBRAL = 0.2725076
#: Earth's rotation rate relative to the equinox (sidereal) [rad s-1] (IERS 2010)
EARTH_ROTATION_RATE_RAD_S = 7.2921158553e-5

_WGS84_F = 1.0 / 298.257223563
_E2 = _WGS84_F * (2.0 - _WGS84_F)
_SYNODIC_MONTH_DAYS = 29.530588861  # Meeus eq. 49.1
_J2000_NEW_MOON_JDE = 2451550.09766
_UNIX_EPOCH_JD = 2440587.5
_NODE_LIMIT = 0.40
_WIDE_HALF_S = 0.8 * 86400.0  # window around a mean new moon [s]
_NARROW_HALF_S = 6.0 * 3600.0  # window around greatest eclipse [s]
_N_NODES = 7  # first search only: the narrow window refines the result
_N_NARROW_NODES = 11
_N_GRID = 97
_GAMMA_LIMIT = 1.7  # beyond, the penumbra misses Earth (partial eclipses reach ~1.57)
_SPAN_S = 5.0 * 3600.0  # every contact and central-line end lies within 5 h of greatest
_SAROS_K0, _SAROS_S0 = 218, 145  # 2017 Aug 21, Saros 145
_INEX_INVERSE = pow(358 % 223, -1, 223)


def _datetimes(jd: np.ndarray) -> np.ndarray:
    return (np.datetime64("1970-01-01", "ns")
            + ((jd - _UNIX_EPOCH_JD) * 86400e9).astype("timedelta64[ns]"))


def _julian_days(times: np.ndarray) -> np.ndarray:
    return (times - np.datetime64("1970-01-01", "ns")) / np.timedelta64(1, "D") + _UNIX_EPOCH_JD


def _mean_new_moons(start: np.datetime64, end: np.datetime64):
    """Mean new moons near [start, end]: times (TT ~ UTC), lunation numbers, |sin F|."""
    k_first = math.floor((_julian_days(start) - _J2000_NEW_MOON_JDE) / _SYNODIC_MONTH_DAYS) - 1
    k_last = math.ceil((_julian_days(end) - _J2000_NEW_MOON_JDE) / _SYNODIC_MONTH_DAYS) + 1
    k = np.arange(k_first, k_last + 1, dtype=np.float64)
    t = k / 1236.85  # Meeus eq. 49.3
    jde = (_J2000_NEW_MOON_JDE + _SYNODIC_MONTH_DAYS * k + 0.00015437 * t**2
           - 0.000000150 * t**3 + 0.00000000073 * t**4)
    f = np.radians(160.7108 + 390.67050284 * k - 0.0016118 * t**2 - 0.00000227 * t**3
                   + 0.000000011 * t**4)  # Meeus eq. 49.6
    return _datetimes(jde), k.astype(np.int64), np.abs(np.sin(f))


def saros_number(lunation) -> np.ndarray:
    """Saros series number of the eclipse at lunation ``k`` (Meeus/canon numbering).

    Parameters
    ----------
    lunation : int or array_like of int
        New moons since 2000 Jan 6 (the canon's "Luna Num").

    Returns
    -------
    numpy.ndarray of int
        The series: ``k - 218 = 223 n + 358 (S - 145)`` with ``|S - 145| <= 111``.
    """
    k = np.asarray(lunation, dtype=np.int64)
    step = ((k - _SAROS_K0) * _INEX_INVERSE) % 223
    return _SAROS_S0 + np.where(step > 111, step - 223, step)


class _SunMoon:
    """Sun and Moon vectors around window centres (batched), in GCRS and ITRS axes."""

    def __init__(self, centres: np.ndarray, half_window_s: float, n_nodes: int):
        nodes, to_coefficients = _chebyshev_nodes(n_nodes)
        offsets = (nodes * half_window_s * 1e9).astype("timedelta64[ns]")
        shape = (len(centres), n_nodes, 3)
        if len(centres):
            vectors = sun_moon_vectors((centres[:, None] + offsets[None, :]).reshape(-1),
                                       frames=("gcrs",))
            t = skyfield_time(centres)
            npb = np.moveaxis(np.asarray(t.M, np.float64), -1, 0).reshape(-1, 3, 3)
            gast = np.asarray(t.gast, np.float64).reshape(-1) * (np.pi / 12.0)
        else:
            empty = torch.zeros(shape, dtype=torch.float64)
            vectors = {"sun_gcrs_m": empty, "moon_gcrs_m": empty}
            npb, gast = np.zeros((0, 3, 3)), np.zeros(0)
        matrix = torch.as_tensor(to_coefficients, dtype=torch.float64)
        self.sun = torch.einsum("kj,cjx->ckx", matrix, vectors["sun_gcrs_m"].reshape(shape))
        self.moon = torch.einsum("kj,cjx->ckx", matrix, vectors["moon_gcrs_m"].reshape(shape))
        self.npb = torch.from_numpy(npb)
        self.gast = torch.from_numpy(gast)
        self.centres = centres
        self.half_window_s = half_window_s

    def subset(self, rows: torch.Tensor) -> _SunMoon:
        """Return the same series for the windows ``rows`` only."""
        new = object.__new__(_SunMoon)
        new.sun, new.moon = self.sun[rows], self.moon[rows]
        new.npb, new.gast = self.npb[rows], self.gast[rows]
        new.centres = self.centres[rows.numpy()]
        new.half_window_s = self.half_window_s
        return new

    def itrs(self, seconds: torch.Tensor, rows: torch.Tensor | None = None):
        """Sun and Moon vectors [m] in Earth-fixed axes at ``seconds`` (n, m) -> (n, m, 3)."""
        pick = (lambda value: value) if rows is None else (lambda value: value[rows])
        tau = seconds / self.half_window_s
        both = torch.cat((pick(self.sun), pick(self.moon)), dim=-1)  # one series, (n, k, 6)
        values = _chebyshev_values(both, tau).unflatten(-1, (2, 3))
        tod = values @ pick(self.npb)[:, None].transpose(-1, -2)  # rows: N P B v
        theta = (pick(self.gast)[:, None] + EARTH_ROTATION_RATE_RAD_S * seconds)[..., None]
        cos, sin = torch.cos(theta), torch.sin(theta)
        x, y, z = tod.unbind(-1)
        itrs = torch.stack((cos * x + sin * y, -sin * x + cos * y, z), dim=-1)
        return itrs[..., 0, :], itrs[..., 1, :]


def _norm(vector: torch.Tensor) -> torch.Tensor:
    return torch.linalg.vector_norm(vector, dim=-1)


def _axis(sun: torch.Tensor, moon: torch.Tensor):
    """Return the unit shadow-axis direction (Sun to Moon) and its point nearest Earth's centre."""
    direction = moon - sun
    direction = direction / _norm(direction)[..., None]
    closest = moon - (moon * direction).sum(-1, keepdim=True) * direction
    return direction, closest


_SCALE = torch.tensor([1.0, 1.0, 1.0 / (1.0 - _WGS84_F)], dtype=torch.float64)


def _line_surface_point(origin: torch.Tensor, direction: torch.Tensor):
    """First point where the line ``origin + t direction`` (t > 0) meets the ellipsoid.

    Returns the point [m] (..., 3) and the scaled discriminant (> 0: the line meets the
    ellipsoid). Where it misses, the point of the ellipsoid's outline (seen along
    ``direction``) nearest the line: in coordinates with z stretched by ``1 / (1 - f)``
    the ellipsoid is a sphere of radius ``a`` and that point lies on the stretched
    perpendicular (the exact nearest point differs by a distance of order ``f**2 a``).
    """
    scale = _SCALE.to(origin.dtype)
    origin, step = origin * scale, direction * scale
    a = EARTH_EQUATORIAL_RADIUS_M
    qa = (step * step).sum(-1)
    qb = (origin * step).sum(-1)
    qc = (origin * origin).sum(-1) - a * a
    discriminant = (qb * qb - qa * qc) / (a * a)
    root = (-qb - torch.sqrt(torch.clamp(discriminant, min=0.0)) * a) / qa
    meet = origin + root[..., None] * step
    foot = origin - (qb / qa)[..., None] * step
    outline = a * foot / _norm(foot)[..., None]
    point = torch.where((discriminant >= 0)[..., None], meet, outline) / scale
    return point, discriminant


def _axis_surface_point(sun: torch.Tensor, moon: torch.Tensor):
    """Where the shadow axis meets the ellipsoid (near side), else the nearest outline point.

    See :func:`_line_surface_point`; the axis runs from the Moon's centre away from the Sun.
    """
    direction, _ = _axis(sun, moon)
    return _line_surface_point(moon, direction)


def _geodetic(point: torch.Tensor):
    """Geodetic latitude and east longitude [rad] of a point on the ellipsoid (..., 3)."""
    x, y, z = point.unbind(-1)
    return torch.atan2(z, (1.0 - _E2) * torch.hypot(x, y)), torch.atan2(y, x)


def _up(lat: torch.Tensor, lon: torch.Tensor) -> torch.Tensor:
    return torch.stack((torch.cos(lat) * torch.cos(lon), torch.cos(lat) * torch.sin(lon),
                        torch.sin(lat)), dim=-1)


def _topocentric(sun: torch.Tensor, moon: torch.Tensor, point: torch.Tensor, k: float):
    """Angular radii of Sun and Moon and their separation [rad] seen from ``point``."""
    to_sun, to_moon = sun - point, moon - point
    sun_radius = torch.asin(_sun_radius_m() / _norm(to_sun))
    moon_radius = torch.asin(k * EARTH_EQUATORIAL_RADIUS_M / _norm(to_moon))
    separation = torch.atan2(_norm(torch.linalg.cross(to_sun, to_moon)),
                             (to_sun * to_moon).sum(-1))
    return sun_radius, moon_radius, separation, to_sun


def _to_times(centres: np.ndarray, seconds: torch.Tensor) -> np.ndarray:
    values = seconds.detach().numpy()
    finite = np.isfinite(values)
    result = np.full(values.shape, np.datetime64("NaT"), dtype="datetime64[ns]")
    offsets = (np.where(finite, values, 0.0) * 1e9).astype("timedelta64[ns]")
    result[finite] = np.broadcast_to(centres, values.shape)[finite] + offsets[finite]
    return result


#: contact names, in time order
LOCAL_CONTACTS = ("c1", "c2", "c3", "c4")
_GRID_STEP_S = 360.0


def _observer_itrs(lat_deg, lon_deg, elevation_m):
    """Return the ITRS positions [m] of geodetic observers (degrees, metres)."""
    return geodetic_to_itrs(torch.deg2rad(lat_deg), torch.deg2rad(lon_deg), elevation_m)


def _state(geometry: _SunMoon, seconds: torch.Tensor, points: torch.Tensor):
    """Topocentric radii, separation and the Sun's direction at ``seconds`` (n, m)."""
    sun, moon = geometry.itrs(seconds)
    s, m_pen, sigma, to_sun = _topocentric(sun, moon, points, MOON_RADIUS_PENUMBRAL)
    m_umb = m_pen * (MOON_RADIUS_UMBRAL / MOON_RADIUS_PENUMBRAL)
    return s, m_pen, m_umb, sigma, to_sun


def _illinois(function, a, b, fa, fb, iterations: int = 7):
    """Batched Illinois (modified regula falsi) root of ``function`` in [a, b] (fa fb <= 0)."""
    for _ in range(iterations):
        denominator = fb - fa
        safe = denominator != 0
        c = torch.where(safe, (a * fb - b * fa) / torch.where(safe, denominator, 1.0), b)
        fc = function(c)
        opposite = fc * fb < 0
        a, fa = torch.where(opposite, b, a), torch.where(opposite, fb, 0.5 * fa)
        b, fb = c, fc
    return b


def _parabola_vertex(t, h, f_minus, f_zero, f_plus):
    """Vertex of the parabola through (t - h, t, t + h), limited to +-1.5 h."""
    curvature = f_plus - 2.0 * f_zero + f_minus
    step = torch.where(curvature > 0, 0.5 * h * (f_minus - f_plus)
                       / torch.where(curvature > 0, curvature, 1.0), 0.0)
    return t + torch.clamp(step, -1.5 * h, 1.5 * h)


def _local_maximum_and_contacts(geometry: _SunMoon, centre_s: torch.Tensor,
                                points: torch.Tensor) -> dict:
    """Maximum and contacts [s from the window centre] for observers ``points`` (n, m, 3).

    ``centre_s`` (n,) is the time around which to search (greatest eclipse) for the ``m``
    observers of each window. The Sun and Moon are evaluated once on a grid shared by the
    observers of a window; maximum eclipse is refined by parabolas through the squared
    separation (steps 6 min, 20 s, 1 s), each contact by the Illinois method in the grid
    cell where its level is crossed (or between that cell and maximum).
    """
    n, m = points.shape[:2]
    offsets = torch.arange(-_SPAN_S, _SPAN_S + 0.5, _GRID_STEP_S, dtype=torch.float64)
    grid = centre_s[:, None] + offsets  # (n, g)
    sun, moon = geometry.itrs(grid)
    s, m_pen, sigma, _ = _topocentric(sun[:, None], moon[:, None], points[:, :, None],
                                      MOON_RADIUS_PENUMBRAL)  # (n, m, g)
    m_umb = m_pen * (MOON_RADIUS_UMBRAL / MOON_RADIUS_PENUMBRAL)
    index = sigma.argmin(-1).clamp(1, len(offsets) - 2)
    times = grid[:, None, :].expand(n, m, -1)

    def pick(values, i):
        return torch.gather(values, 2, i[..., None])[..., 0]

    triple = points.repeat(1, 3, 1)

    def separation2(seconds):  # (n, 3 m)
        return _state(geometry, seconds, triple)[3] ** 2

    best = pick(times, index)
    best = _parabola_vertex(best, _GRID_STEP_S, pick(sigma, index - 1) ** 2,
                            pick(sigma, index) ** 2, pick(sigma, index + 1) ** 2)
    for h in (20.0, 1.0):
        both = separation2(torch.cat((best - h, best, best + h), dim=1))
        best = _parabola_vertex(best, h, both[:, :m], both[:, m:2 * m], both[:, 2 * m:])
    maximum = best

    levels = {"c1": s + m_pen, "c4": s + m_pen, "c2": torch.abs(m_umb - s),
              "c3": torch.abs(m_umb - s)}
    at_max = _state(geometry, maximum, points)
    at_levels = {"c1": at_max[0] + at_max[1], "c2": torch.abs(at_max[2] - at_max[0])}
    at_levels["c4"], at_levels["c3"] = at_levels["c1"], at_levels["c2"]
    result = {"maximum": maximum}
    for name in LOCAL_CONTACTS:
        umbral, after = name in ("c2", "c3"), name in ("c3", "c4")
        f_grid = sigma - levels[name]  # (n, m, g)
        f_max = at_max[3] - at_levels[name]
        outside = f_grid >= 0
        beyond = (times > maximum[..., None]) if after else (times < maximum[..., None])
        candidates = outside & beyond
        g = len(offsets)
        positions = torch.arange(g).expand_as(candidates)
        if after:
            k = torch.where(candidates, positions, g).amin(-1)  # first outside after max
            found = (k < g) & (f_max < 0)
            k = k.clamp(max=g - 1)
            inner = (k - 1).clamp(min=0)
            inner_time = torch.maximum(pick(times, inner), maximum)
        else:
            k = torch.where(candidates, positions, -1).amax(-1)  # last outside before max
            found = (k >= 0) & (f_max < 0)
            k = k.clamp(min=0)
            inner = (k + 1).clamp(max=g - 1)
            inner_time = torch.minimum(pick(times, inner), maximum)
        use_max = inner_time == maximum
        f_inner = torch.where(use_max, f_max, pick(f_grid, inner))

        def excess(seconds, umbral=umbral):
            s_, m_pen_, m_umb_, sigma_, _ = _state(geometry, seconds, points)
            level = torch.abs(m_umb_ - s_) if umbral else s_ + m_pen_
            return sigma_ - level

        root = _illinois(excess, pick(times, k), inner_time, pick(f_grid, k), f_inner)
        result[name] = torch.where(found, root, torch.nan)
    return result



_SPECS = {
    "time": VariableSpec("", "time of greatest eclipse (UTC)",
                         "Instant when the axis of the Moon's shadow passes closest to "
                         "Earth's centre (UTC)."),
    "time_tt": VariableSpec("", "time of greatest eclipse (TT)",
                            "Greatest eclipse in terrestrial (dynamical) time, TD of the "
                            "canon."),
    "delta_t": VariableSpec("s", "Delta T", "TT - UT1 at greatest eclipse (skyfield tables)."),
    "kind": VariableSpec("1", "eclipse kind", "partial, annular, total or hybrid."),
    "central": VariableSpec("1", "central eclipse",
                            "True when the shadow axis meets Earth's ellipsoid."),
    "gamma": VariableSpec("1", "gamma",
                          "Distance of the shadow axis from Earth's centre at greatest "
                          "eclipse in Earth equatorial radii, positive when the axis passes "
                          "north of the centre."),
    "magnitude": VariableSpec("1", "eclipse magnitude at greatest eclipse",
                              "Ratio of the apparent diameters of Moon and Sun on the axis "
                              "(central eclipses, umbral k), else the fraction of the Sun's "
                              "diameter covered at the point nearest the axis (penumbral "
                              "k)."),
    "latitude": VariableSpec("degree_north", "latitude of greatest eclipse",
                             "Geodetic (WGS84) latitude of the point of greatest eclipse.",
                             "latitude"),
    "longitude": VariableSpec("degree_east", "longitude of greatest eclipse",
                              "East longitude of the point of greatest eclipse.",
                              "longitude"),
    "sun_altitude": VariableSpec("degree", "Sun altitude at greatest eclipse",
                                 "Geometric altitude of the Sun's centre at the point of "
                                 "greatest eclipse (0 on the outline for non-central "
                                 "eclipses).", "solar_elevation_angle"),
    "central_duration": VariableSpec("s", "duration of the central phase",
                                     "C3 - C2 (totality or annularity) at the point of "
                                     "greatest eclipse (for non-central eclipses the "
                                     "outline point, Sun on the horizon; the canon gives "
                                     "0 there); NaN for partial eclipses."),
    "central_start": VariableSpec("", "first contact of the axis with Earth (UTC)",
                                  "Start of the central line; NaT if not central."),
    "central_end": VariableSpec("", "last contact of the axis with Earth (UTC)",
                                "End of the central line; NaT if not central."),
    "lunation": VariableSpec("1", "lunation number",
                             "New moons since 2000 Jan 6 (Meeus k, the canon's Luna Num)."),
    "saros": VariableSpec("1", "Saros series", "Saros series number (van den Bergh 1955)."),
}


def _greatest(geometry: _SunMoon, low: torch.Tensor, high: torch.Tensor) -> torch.Tensor:
    def distance(seconds):
        sun, moon = geometry.itrs(seconds)
        return _norm(_axis(sun, moon)[1])

    return _golden_minimum(distance, low, high)


def _central_ends(geometry: _SunMoon, central: torch.Tensor) -> torch.Tensor:
    """Return times [s from the centre] where the axis starts and ends meeting the ellipsoid."""
    n = len(central)
    start = torch.zeros(n, 2, dtype=torch.float64)

    def outside(seconds):
        return -_axis_surface_point(*geometry.itrs(seconds))[1]

    ends = _bisect(outside, start.clone(), start + torch.tensor([-_SPAN_S, _SPAN_S]),
                   iterations=44)
    return torch.where(central[:, None], ends, torch.nan)


def _candidates(start_time, end_time):
    centres, lunations, node = _mean_new_moons(start_time, end_time)
    window = np.timedelta64(int(_WIDE_HALF_S * 1e9), "ns")
    keep = (node < _NODE_LIMIT) & (centres >= start_time - window) & (centres < end_time + window)
    return centres[keep], lunations[keep]


def solar_eclipses(start, end) -> xr.Dataset:
    """Every solar eclipse whose greatest eclipse lies in ``[start, end)``.

    Parameters
    ----------
    start, end : str, datetime or datetime64
        UTC time range, within 1899-07-31T00:30 .. 2053-10-06T23:30 (the DE421 range of
        :mod:`skytorch.ephemeris` less two days at each end).

    Returns
    -------
    xarray.Dataset
        Dimension ``eclipse`` (eclipse number 0 .. n-1 in time order) with ``time``
        (greatest eclipse, UTC), ``time_tt`` (TT), ``delta_t`` [s], ``kind``, ``central``,
        ``gamma``, ``magnitude``, ``latitude``, ``longitude``, ``sun_altitude`` [degree],
        ``central_duration`` [s], ``central_start``, ``central_end`` (UTC), ``lunation``,
        ``saros``.

    Raises
    ------
    TypeError, ValueError
        ``start`` or ``end`` is not one time, is outside the range, or ``end <= start``.

    Notes
    -----
    See the module docstring for the method and constants. Against the Five Millennium
    Canon 2015-2030 (``tests/test_eclipse_solar.py``, ``docs/eclipse_solar.md``): times,
    gamma, magnitudes and kinds of all 36 eclipses.

    Examples
    --------
    >>> ds = solar_eclipses("2024-01-01", "2025-01-01")
    >>> ds.kind.values.tolist(), [round(float(g), 4) for g in ds.gamma]
    (['total', 'annular'], [0.3431, -0.3509])
    """
    start_time, end_time = _check_search_range(start, end)
    centres, lunations = _candidates(start_time, end_time)
    logger.info("%d new moons near a node between %s and %s", len(centres), start_time,
                end_time)
    n = len(centres)
    wide = _SunMoon(centres, _WIDE_HALF_S, _N_NODES)
    grid = torch.linspace(-_WIDE_HALF_S, _WIDE_HALF_S, _N_GRID, dtype=torch.float64)
    sun, moon = wide.itrs(grid.expand(n, -1))
    best = grid[_norm(_axis(sun, moon)[1]).argmin(dim=1)]
    step = float(grid[1] - grid[0])
    first = _greatest(wide, best - step, best + step)
    sun, moon = (v[:, 0] for v in wide.itrs(first[:, None]))
    near = (_norm(_axis(sun, moon)[1]) < _GAMMA_LIMIT * EARTH_EQUATORIAL_RADIUS_M).numpy()
    first_times = (centres + (first.numpy() * 1e9).astype("timedelta64[ns]"))[near]
    lunations = lunations[near]

    # refine in a narrow window centred on the first estimate; eclipses need the penumbra
    # to reach the outline: sigma < s + m at the nearest outline point
    geometry = _SunMoon(first_times, _NARROW_HALF_S, _N_NARROW_NODES)
    zero = torch.zeros(len(first_times), dtype=torch.float64)
    greatest = _greatest(geometry, zero - 120.0, zero + 120.0)
    sun, moon = (v[:, 0] for v in geometry.itrs(greatest[:, None]))
    point, discriminant = _axis_surface_point(sun, moon)
    s, m_pen, sigma, to_sun = _topocentric(sun, moon, point, MOON_RADIUS_PENUMBRAL)
    _, m_umb, _, _ = _topocentric(sun, moon, point, MOON_RADIUS_UMBRAL)
    times = first_times + (greatest.numpy() * 1e9).astype("timedelta64[ns]")
    keep = ((sigma < s + m_pen).numpy() & (times >= start_time) & (times < end_time))
    rows = torch.as_tensor(np.nonzero(keep)[0], dtype=torch.long)
    geometry = geometry.subset(rows)
    greatest, point, discriminant = greatest[rows], point[rows], discriminant[rows]
    s, m_pen, m_umb, sigma, to_sun = s[rows], m_pen[rows], m_umb[rows], sigma[rows], to_sun[rows]
    sun, moon = sun[rows], moon[rows]
    times = times[keep]

    central = discriminant >= 0
    ratio = m_umb / s
    umbral_touch = sigma < torch.abs(m_umb - s)
    ends = _central_ends(geometry, central)
    end_sun, end_moon = geometry.itrs(torch.nan_to_num(ends))
    end_point, _ = _axis_surface_point(end_sun, end_moon)
    end_s, end_m, _, _ = _topocentric(end_sun, end_moon, end_point, MOON_RADIUS_UMBRAL)
    annular_end = (end_m < end_s).any(dim=1)
    kind = np.where(~(central | umbral_touch).numpy(), "partial",
                    np.where((ratio < 1).numpy(), "annular",
                             np.where((central & annular_end).numpy(), "hybrid", "total")))
    magnitude = torch.where(central, ratio, (s + m_pen - sigma) / (2.0 * s))

    lat, lon = _geodetic(point)
    altitude = torch.asin(torch.clamp((_up(lat, lon) * to_sun).sum(-1) / _norm(to_sun),
                                      -1.0, 1.0))
    altitude = torch.where(central, altitude, torch.zeros_like(altitude))
    local = _local_maximum_and_contacts(geometry, greatest, point[:, None])
    duration = (local["c3"] - local["c2"])[:, 0]
    duration = torch.where(central | umbral_touch, duration, torch.nan)
    _, closest = _axis(sun, moon)
    gamma = torch.where(closest[:, 2] >= 0, 1.0, -1.0) * _norm(closest) \
        / EARTH_EQUATORIAL_RADIUS_M

    if len(times):
        t = skyfield_time(times)
        delta_t = np.asarray(t.delta_t, dtype=np.float64).reshape(-1)
        tt_minus_utc = (np.asarray(t.tt, np.float64).reshape(-1) - _julian_days(times)) * 86400.0
    else:
        delta_t = tt_minus_utc = np.zeros(0)
    time_tt = times + np.round(tt_minus_utc * 1e9).astype("timedelta64[ns]")
    lunation = lunations[keep]
    values = {
        "time": times, "time_tt": time_tt, "delta_t": delta_t, "kind": kind.astype(str),
        "central": central.numpy(), "gamma": gamma, "magnitude": magnitude,
        "latitude": torch.rad2deg(lat), "longitude": torch.rad2deg(lon),
        "sun_altitude": torch.rad2deg(altitude), "central_duration": duration,
        "central_start": _to_times(geometry.centres, ends[:, 0]),
        "central_end": _to_times(geometry.centres, ends[:, 1]),
        "lunation": lunation, "saros": saros_number(lunation),
    }
    data_vars = {name: variable(("eclipse",), value, _SPECS[name])
                 for name, value in values.items()}
    coords = {"eclipse": coordinate("eclipse", np.arange(len(times)),
                                    VariableSpec("1", "eclipse number",
                                                 "Index of the eclipse in time order."))}
    return build_dataset(
        data_vars, coords, title="Solar eclipse circumstances",
        references=[
            "Espenak, F., Meeus, J. 2006, Five Millennium Canon of Solar Eclipses, "
            "NASA/TP-2006-214141",
            "Meeus, J. 1998, Astronomical Algorithms, 2nd ed., Willmann-Bell, ch. 49, 54",
            "Folkner, W. M. et al. 2009, The Planetary and Lunar Ephemeris DE 421, "
            "IPN Progress Report 42-178",
        ],
        parameters={"start": str(start_time), "end": str(end_time), "ephemeris": "de421.bsp",
                    "sun_semidiameter_1au_arcsec": math.degrees(SUN_SEMIDIAMETER_1AU_RAD)
                    * 3600.0,
                    "earth_radius_m": EARTH_EQUATORIAL_RADIUS_M, "flattening": _WGS84_F,
                    "moon_radius_umbral": MOON_RADIUS_UMBRAL,
                    "moon_radius_penumbral": MOON_RADIUS_PENUMBRAL},
    )
