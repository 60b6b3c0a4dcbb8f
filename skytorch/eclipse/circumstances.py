"""Circumstances of lunar eclipses from the DE421 ephemeris and the shadow-cone geometry.

Method
------
1. Candidates: mean full moons (Meeus 1998, eq. 49.1) in the requested range; those far
   from a lunar node (``|sin F| > 0.40`` with the mean argument of latitude ``F``, Meeus
   ch. 54 uses 0.36 as the eclipse limit) cannot be eclipses and are dropped.
2. Around each remaining candidate the apparent geocentric Sun and Moon vectors
   (:func:`skytorch.ephemeris.sun_moon_vectors`: DE421, light time, aberration, deflection)
   are evaluated at Chebyshev nodes over +-0.8 day and interpolated by a Chebyshev series
   (9 nodes: interpolation error < 1 m for the Moon), so that all further steps are batched
   tensor operations on every candidate at once.
3. In the fundamental plane perpendicular to the shadow axis (the anti-Sun direction
   through Earth's centre), the Moon's centre lies at distance ``delta(t)`` from the
   axis and at axial distance ``x(t)``; the umbral and penumbral radii ``r_u``, ``r_p`` at
   ``x`` come from :func:`skytorch.eclipse.cone.shadow_radii` with the chosen enlargement.
4. Greatest eclipse: ``min delta(t)``, by a grid search and a vectorised golden-section
   search (bracket < 0.1 ms). Gamma is ``delta / R_earth`` there, positive when the Moon passes
   north of the axis.
5. Magnitudes: ``(r + R_moon - delta) / (2 R_moon)`` with ``r = r_u`` (umbral) or
   ``r_p`` (penumbral). Kind: total if the umbral magnitude is >= 1, partial if > 0,
   penumbral if only the penumbral magnitude is > 0.
6. Contacts P1/P4 (``delta = r_p + R_moon``), U1/U4 (``delta = r_u + R_moon``),
   U2/U3 (``delta = r_u - R_moon``) by batched bisection on each side of greatest eclipse;
   NaT where the Moon does not reach that level.

Times are UTC; ``delta_t`` (TT - UT1 from skyfield's tables) converts them to the
dynamical time (TD) used by the canon's tables. The radii are those of the Five Millennium
Canon: Earth's equatorial radius 6378.137 km (horizontal parallaxes), the Sun's
semi-diameter 959.63 arcsec at 1 au, and the Moon's radius k = 0.2725076 Earth radii.

References
----------
1. Espenak, F., Meeus, J. 2009, "Five Millennium Canon of Lunar Eclipses: -1999 to +3000",
   NASA/TP-2009-214172 (definitions of greatest eclipse, gamma, magnitudes, contacts).
2. Meeus, J. 1998, "Astronomical Algorithms", 2nd ed., Willmann-Bell, ch. 49 (mean
   phases of the Moon) and ch. 54 (eclipses).
3. Folkner, W. M. et al. 2009, "The Planetary and Lunar Ephemeris DE 421", IPN Progress
   Report 42-178.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import torch
import xarray as xr

from skytorch._validate import check_choice
from skytorch.constants import ARCSECOND, ASTRONOMICAL_UNIT_M, EARTH_EQUATORIAL_RADIUS_M
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable
from skytorch.eclipse.cone import ENLARGEMENTS, _cone
from skytorch.ephemeris import TIME_MAX, TIME_MIN, parse_times, skyfield_time, sun_moon_vectors

__all__ = [
    "CONTACTS",
    "ECLIPSE_KINDS",
    "MOON_EARTH_RADIUS_RATIO",
    "SUN_SEMIDIAMETER_1AU_RAD",
    "lunar_eclipses",
]

logger = logging.getLogger(__name__)

#: kinds of lunar eclipse, in order of depth
ECLIPSE_KINDS = ("penumbral", "partial", "total")
#: contact names, in time order
CONTACTS = ("p1", "u1", "u2", "u3", "u4", "p4")
#: the Sun's semi-diameter at 1 au used by the canon (Auwers' 959.63 arcsec) [rad]
SUN_SEMIDIAMETER_1AU_RAD = 959.63 * ARCSECOND
#: the Moon's radius in Earth equatorial radii (IAU 1982, used by the canon)
MOON_EARTH_RADIUS_RATIO = 0.2725076

_SYNODIC_MONTH_DAYS = 29.530588861  # Meeus eq. 49.1
_J2000_FULL_MOON_JDE = 2451550.09766  # k = 0 new moon of 2000 Jan 6 (Meeus eq. 49.1)
_UNIX_EPOCH_JD = 2440587.5
_NODE_LIMIT = 0.40  # |sin F| above which no eclipse is possible (0.36 in Meeus ch. 54)
_HALF_WINDOW_S = 0.8 * 86400.0  # half-width of the window around a mean full moon [s]
_N_NODES = 9  # Chebyshev nodes per window
_N_GRID = 97  # grid for the first search of greatest eclipse (every 24 min)
_CONTACT_SPAN_S = 0.25 * 86400.0  # contacts lie within 6 h of greatest eclipse
_GOLDEN_STEPS = 36  # 2 x 24 min x 0.618^36 = 0.09 ms
_BISECTION_STEPS = 32  # 6 h / 2^32 = 5 microseconds
#: margin between the searched range and the ephemeris' range: a candidate full moon
#: within one window of the range is searched over its window and its contacts 6 h beyond
_RANGE_MARGIN = np.timedelta64(2, "D")


def _search_range() -> tuple[np.datetime64, np.datetime64]:
    """Range of ``start`` and ``end`` accepted by :func:`lunar_eclipses` (UTC).

    The ephemeris range (:data:`skytorch.ephemeris.TIME_MIN` .. ``TIME_MAX``) less
    :data:`_RANGE_MARGIN` at each end: every time the search evaluates lies within
    ``1.85`` days of the range.
    """
    return TIME_MIN + _RANGE_MARGIN, TIME_MAX - _RANGE_MARGIN


def _sun_radius_m() -> float:
    return ASTRONOMICAL_UNIT_M * math.tan(SUN_SEMIDIAMETER_1AU_RAD)


def _mean_full_moons(start: np.datetime64, end: np.datetime64) -> tuple[np.ndarray, np.ndarray]:
    """Mean full moons (TT ~ UTC at this precision) in [start, end] and their |sin F|."""
    def jd(value):
        return (value - np.datetime64("1970-01-01", "ns")) / np.timedelta64(1, "D") \
            + _UNIX_EPOCH_JD

    k_first = math.floor((jd(start) - _J2000_FULL_MOON_JDE) / _SYNODIC_MONTH_DAYS) - 1
    k_last = math.ceil((jd(end) - _J2000_FULL_MOON_JDE) / _SYNODIC_MONTH_DAYS) + 1
    k = np.arange(k_first, k_last + 1, dtype=np.float64) + 0.5
    t = k / 1236.85  # Julian centuries since J2000 (Meeus eq. 49.3)
    jde = (_J2000_FULL_MOON_JDE + _SYNODIC_MONTH_DAYS * k + 0.00015437 * t**2
           - 0.000000150 * t**3 + 0.00000000073 * t**4)
    # Moon's argument of latitude at the mean phase (Meeus eq. 49.6)
    f = np.radians(160.7108 + 390.67050284 * k - 0.0016118 * t**2 - 0.00000227 * t**3
                   + 0.000000011 * t**4)
    times = (np.datetime64("1970-01-01", "ns")
             + ((jde - _UNIX_EPOCH_JD) * 86400e9).astype("timedelta64[ns]"))
    return times, np.abs(np.sin(f))


def _chebyshev_nodes(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Chebyshev nodes on [-1, 1] and the matrix turning values at them into coefficients."""
    j = np.arange(n)
    nodes = np.cos(np.pi * (j + 0.5) / n)
    basis = np.cos(np.outer(np.arange(n), np.pi * (j + 0.5) / n))  # T_k(node_j)
    to_coefficients = 2.0 / n * basis
    to_coefficients[0] *= 0.5
    return nodes, to_coefficients


def _chebyshev_values(coefficients: torch.Tensor, tau: torch.Tensor) -> torch.Tensor:
    """Evaluate series ``(n_candidate, n, 3)`` at ``tau`` ``(n_candidate, m)`` -> (.., m, 3)."""
    previous = torch.ones_like(tau)
    current = tau
    result = coefficients[:, None, 0] * previous[..., None]
    result = result + coefficients[:, None, 1] * current[..., None]
    for k in range(2, coefficients.shape[1]):
        previous, current = current, 2.0 * tau * current - previous
        result = result + coefficients[:, None, k] * current[..., None]
    return result


class _Geometry:
    """Shadow geometry of every candidate as a function of time (batched)."""

    def __init__(self, centres: np.ndarray, enlargement: str):
        nodes, to_coefficients = _chebyshev_nodes(_N_NODES)
        offsets = (nodes * _HALF_WINDOW_S * 1e9).astype("timedelta64[ns]")
        times = (centres[:, None] + offsets[None, :]).reshape(-1)
        shape = (len(centres), _N_NODES, 3)
        if len(centres):
            vectors = sun_moon_vectors(times, frames=("gcrs",))
        else:  # no candidate: nothing to look up
            empty = torch.zeros(shape, dtype=torch.float64)
            vectors = {"sun_gcrs_m": empty, "moon_gcrs_m": empty}
        matrix = torch.as_tensor(to_coefficients, dtype=torch.float64)
        self.sun = torch.einsum("kj,cjx->ckx", matrix, vectors["sun_gcrs_m"].reshape(shape))
        self.moon = torch.einsum("kj,cjx->ckx", matrix, vectors["moon_gcrs_m"].reshape(shape))
        self.centres = centres
        self.enlargement = enlargement
        self.earth_radius = EARTH_EQUATORIAL_RADIUS_M
        self.moon_radius = MOON_EARTH_RADIUS_RATIO * EARTH_EQUATORIAL_RADIUS_M
        self.sun_radius = _sun_radius_m()

    def __call__(self, seconds: torch.Tensor, rows: torch.Tensor | None = None) -> dict:
        """Geometry at ``seconds`` from each window centre, shape (n_candidate, m)."""
        sun = self.sun if rows is None else self.sun[rows]
        moon = self.moon if rows is None else self.moon[rows]
        tau = seconds / _HALF_WINDOW_S
        sun_position = _chebyshev_values(sun, tau)
        moon_position = _chebyshev_values(moon, tau)
        sun_distance = torch.linalg.vector_norm(sun_position, dim=-1)
        axis = -sun_position / sun_distance[..., None]
        axial = (moon_position * axis).sum(-1)
        offset = moon_position - axial[..., None] * axis
        delta = torch.linalg.vector_norm(offset, dim=-1)
        umbra, penumbra, *_ = _cone(axial, sun_distance, self.sun_radius, self.earth_radius,
                                    self.enlargement)
        return {"delta": delta, "umbra": umbra, "penumbra": penumbra, "offset": offset}


def _golden_minimum(function, low: torch.Tensor, high: torch.Tensor, iterations: int = 48):
    """Vectorised golden-section search of a batched ``function`` on ``[low, high]``.

    ``function`` maps times ``(n, 2)`` to values ``(n, 2)``; both interior points of every
    row are evaluated in one call.
    """
    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = low.clone(), high.clone()
    for _ in range(iterations):
        c = b - ratio * (b - a)
        d = a + ratio * (b - a)
        values = function(torch.stack((c, d), dim=-1))
        left = values[:, 0] < values[:, 1]
        b = torch.where(left, d, b)
        a = torch.where(left, a, c)
    return 0.5 * (a + b)


def _bisect(function, inside: torch.Tensor, outside: torch.Tensor, iterations: int = 50):
    """Batched bisection between points where ``function`` is < 0 (inside) and >= 0."""
    for _ in range(iterations):
        middle = 0.5 * (inside + outside)
        negative = function(middle) < 0
        inside = torch.where(negative, middle, inside)
        outside = torch.where(negative, outside, middle)
    return 0.5 * (inside + outside)


_SPECS = {
    "time": VariableSpec("", "time of greatest eclipse (UTC)",
                         "Instant when the Moon's centre passes closest to the axis of "
                         "Earth's shadow (UTC)."),
    "kind": VariableSpec("1", "eclipse kind",
                         "penumbral, partial (umbral) or total (umbral) lunar eclipse."),
    "umbral_magnitude": VariableSpec(
        "1", "umbral eclipse magnitude",
        "Fraction of the Moon's diameter inside Earth's umbra at greatest eclipse "
        "(negative: distance of the Moon's limb from the umbra in Moon diameters)."),
    "penumbral_magnitude": VariableSpec(
        "1", "penumbral eclipse magnitude",
        "Fraction of the Moon's diameter inside Earth's penumbra at greatest eclipse."),
    "gamma": VariableSpec(
        "1", "gamma",
        "Distance of the Moon's centre from the shadow axis at greatest eclipse in Earth "
        "equatorial radii, positive when the Moon passes north of the axis."),
    "delta_t": VariableSpec("s", "Delta T", "TT - UT1 at greatest eclipse (skyfield tables); "
                            "add it to a UTC time to get dynamical time (TD) within 1 s."),
    "moon_distance": VariableSpec("m", "geocentric distance of the Moon",
                                  "Distance between the centres of Earth and Moon at "
                                  "greatest eclipse."),
    "umbra_radius": VariableSpec("m", "umbral radius at the Moon",
                                 "Radius of the (enlarged) umbra in the plane through the "
                                 "Moon's centre perpendicular to the shadow axis."),
    "penumbra_radius": VariableSpec("m", "penumbral radius at the Moon",
                                    "Radius of the (enlarged) penumbra in the plane through "
                                    "the Moon's centre perpendicular to the shadow axis."),
    "penumbral_duration": VariableSpec("min", "duration of the penumbral eclipse",
                                       "P4 - P1 (NaN if absent)."),
    "partial_duration": VariableSpec("min", "duration of the umbral (partial) phases",
                                     "U4 - U1 (NaN if the Moon misses the umbra)."),
    "total_duration": VariableSpec("min", "duration of totality", "U3 - U2 (NaN if absent)."),
}
_CONTACT_TEXT = {
    "p1": "first contact with the penumbra (penumbral eclipse begins)",
    "u1": "first contact with the umbra (partial eclipse begins)",
    "u2": "second contact with the umbra (total eclipse begins)",
    "u3": "third contact with the umbra (total eclipse ends)",
    "u4": "last contact with the umbra (partial eclipse ends)",
    "p4": "last contact with the penumbra (penumbral eclipse ends)",
}
for _name, _text in _CONTACT_TEXT.items():
    _SPECS[_name] = VariableSpec("", f"contact {_name.upper()} (UTC)",
                                 f"Time of {_text}, UTC; NaT when it does not occur.")


def _parse_one(name: str, value, parse_times) -> np.datetime64:
    """One UTC time from ``value``, errors naming the parameter ``name``."""
    try:
        times = parse_times(value)
    except TypeError as error:
        raise TypeError(f"{name} must be one time (str, datetime or datetime64): {error}") \
            from None
    except ValueError as error:
        raise ValueError(f"{name}: {error}") from None
    if times.shape != (1,):
        raise TypeError(f"{name} must be one time; got {times.shape[0]} times")
    return times[0]


def _check_search_range(start, end) -> tuple[np.datetime64, np.datetime64]:
    """Return ``start`` and ``end`` parsed (UTC), ordered and inside the search range.

    Shared by the lunar and solar eclipse searches (ValueError naming ``start``/``end``).
    """
    start_time, end_time = (_parse_one(name, value, parse_times)
                            for name, value in (("start", start), ("end", end)))
    if not end_time > start_time:
        raise ValueError(f"end must be after start; got start={start_time}, end={end_time}")
    low, high = _search_range()
    for name, value in (("start", start_time), ("end", end_time)):
        if not low <= value <= high:
            raise ValueError(
                f"{name} must be within {np.datetime_as_string(low, 'm')} .. "
                f"{np.datetime_as_string(high, 'm')} UTC (the DE421 ephemeris range less "
                f"two days at each end); got {np.datetime_as_string(value, 's')}")
    return start_time, end_time


def lunar_eclipses(start, end, enlargement: str = "danjon") -> xr.Dataset:
    """Every lunar eclipse whose greatest eclipse lies in ``[start, end)``.

    Parameters
    ----------
    start, end : str, datetime or datetime64
        UTC time range, within 1899-07-31T00:30 .. 2053-10-06T23:30 (the DE421 range of
        :mod:`skytorch.ephemeris`, ``TIME_MIN`` .. ``TIME_MAX``, less two days at each end:
        the search looks up to 1.85 days beyond the range).
    enlargement : {"danjon", "chauvenet", "none"}
        Shadow enlargement convention (:mod:`skytorch.eclipse.cone`); the Five Millennium
        Canon uses ``"danjon"``.

    Returns
    -------
    xarray.Dataset
        Dimension ``eclipse`` (coordinate: eclipse number 0 .. n-1 in time order) with
        ``time`` (greatest eclipse, UTC), ``kind``, ``umbral_magnitude``,
        ``penumbral_magnitude``, ``gamma``, contacts ``p1``, ``u1``, ``u2``, ``u3``, ``u4``,
        ``p4`` (UTC, NaT when absent), ``penumbral_duration``, ``partial_duration``,
        ``total_duration`` [min], ``delta_t`` [s], ``moon_distance``, ``umbra_radius``,
        ``penumbra_radius`` [m]; attribute ``enlargement``.

    Notes
    -----
    See the module docstring for the method. Accuracy against the canon (same
    enlargement): magnitudes within a few 1e-4, times within a few seconds
    (``tests/test_eclipse_circumstances.py``, ``docs/eclipse_geometry.md``).

    Examples
    --------
    >>> ds = lunar_eclipses("2022-01-01", "2023-01-01")
    >>> ds.kind.values.tolist(), [round(float(m), 3) for m in ds.umbral_magnitude]
    (['total', 'total'], [1.414, 1.359])
    """
    check_choice("enlargement", enlargement, ENLARGEMENTS)
    start_time, end_time = _check_search_range(start, end)

    centres, node_distance = _mean_full_moons(start_time, end_time)
    # greatest eclipse lies within the window of its mean full moon: candidates farther
    # than one window from the range cannot contribute
    window = np.timedelta64(int(_HALF_WINDOW_S * 1e9), "ns")
    near = (centres >= start_time - window) & (centres < end_time + window)
    centres = centres[(node_distance < _NODE_LIMIT) & near]
    logger.info("%d full moons near a node between %s and %s", len(centres), start_time,
                end_time)
    geometry = _Geometry(centres, enlargement)
    n = len(centres)

    # greatest eclipse: grid search, then golden section around the best grid point
    grid = torch.linspace(-_HALF_WINDOW_S, _HALF_WINDOW_S, _N_GRID, dtype=torch.float64)
    delta = geometry(grid.expand(n, -1))["delta"]
    best = grid[delta.argmin(dim=1)]
    step = float(grid[1] - grid[0])
    greatest = _golden_minimum(lambda s: geometry(s)["delta"], best - step, best + step,
                               iterations=_GOLDEN_STEPS)
    at_greatest = {key: value[:, 0] for key, value in geometry(greatest[:, None]).items()}
    moon_radius = geometry.moon_radius
    umbral = (at_greatest["umbra"] + moon_radius - at_greatest["delta"]) / (2 * moon_radius)
    penumbral = (at_greatest["penumbra"] + moon_radius - at_greatest["delta"]) / (2 * moon_radius)
    greatest_times = centres + (greatest.numpy() * 1e9).astype("timedelta64[ns]")
    keep = ((penumbral > 0).numpy() & (greatest_times >= start_time)
            & (greatest_times < end_time))
    rows = torch.as_tensor(np.nonzero(keep)[0])

    # contacts: delta(t) - level(t) changes sign on each side of greatest eclipse; the six
    # contacts of every eclipse are found together by one batched bisection
    t0 = greatest[rows]
    sides = torch.tensor([-1.0, -1.0, -1.0, 1.0, 1.0, 1.0], dtype=torch.float64)  # CONTACTS
    offsets = torch.tensor([1.0, 1.0, -1.0, -1.0, 1.0, 1.0], dtype=torch.float64) * moon_radius
    use_umbra = torch.tensor([False, True, True, True, True, False])

    def excess(seconds):
        g = geometry(seconds, rows)
        level = torch.where(use_umbra, g["umbra"], g["penumbra"]) + offsets
        return g["delta"] - level

    start_points = t0[:, None].expand(-1, len(CONTACTS))
    reached = excess(start_points) < 0
    roots = _bisect(excess, start_points.clone(), start_points + sides * _CONTACT_SPAN_S,
                    iterations=_BISECTION_STEPS)
    roots = torch.where(reached, roots, torch.nan)
    contacts = {name: roots[:, i] for i, name in enumerate(CONTACTS)}

    times = greatest_times[keep]

    def to_times(seconds: torch.Tensor) -> np.ndarray:
        values = seconds.numpy()
        finite = np.isfinite(values)
        result = np.full(values.shape, np.datetime64("NaT"), dtype="datetime64[ns]")
        result[finite] = (centres[keep][finite]
                          + (values[finite] * 1e9).astype("timedelta64[ns]"))
        return result

    umbral, penumbral = umbral[rows], penumbral[rows]
    kind = np.where(umbral.numpy() >= 1.0, "total",
                    np.where(umbral.numpy() > 0.0, "partial", "penumbral"))
    # north of the true equator of date at greatest eclipse: the third row of the
    # GCRS → true-equator-of-date matrix (the nutation only at these times)
    pole = (torch.from_numpy(np.ascontiguousarray(
        np.asarray(skyfield_time(times).M, np.float64)[2].T)) if len(times)
        else torch.zeros(0, 3, dtype=torch.float64))
    north = (at_greatest["offset"][rows] * pole).sum(-1)
    sign = torch.where(north >= 0, 1.0, -1.0)
    delta_t = np.asarray(skyfield_time(times).delta_t, dtype=np.float64).reshape(-1) \
        if len(times) else np.zeros(0)
    durations = {
        "penumbral_duration": (contacts["p4"] - contacts["p1"]) / 60.0,
        "partial_duration": (contacts["u4"] - contacts["u1"]) / 60.0,
        "total_duration": (contacts["u3"] - contacts["u2"]) / 60.0,
    }
    moon_distance = torch.linalg.vector_norm(
        _chebyshev_values(geometry.moon[rows], (t0 / _HALF_WINDOW_S)[:, None])[:, 0], dim=-1)
    values = {
        "time": times,
        "kind": kind.astype(str),
        "umbral_magnitude": umbral,
        "penumbral_magnitude": penumbral,
        "gamma": sign * at_greatest["delta"][rows] / geometry.earth_radius,
        **{name: to_times(contacts[name]) for name in CONTACTS},
        **durations,
        "delta_t": delta_t,
        "moon_distance": moon_distance,
        "umbra_radius": at_greatest["umbra"][rows],
        "penumbra_radius": at_greatest["penumbra"][rows],
    }
    data_vars = {name: variable(("eclipse",), value, _SPECS[name])
                 for name, value in values.items()}
    coords = {"eclipse": coordinate("eclipse", np.arange(len(times)),
                                    VariableSpec("1", "eclipse number",
                                                 "Index of the eclipse in time order."))}
    return build_dataset(
        data_vars, coords,
        title="Lunar eclipse circumstances",
        references=[
            "Espenak, F., Meeus, J. 2009, Five Millennium Canon of Lunar Eclipses, "
            "NASA/TP-2009-214172",
            "Meeus, J. 1998, Astronomical Algorithms, 2nd ed., Willmann-Bell, ch. 49, 54",
            "Folkner, W. M. et al. 2009, The Planetary and Lunar Ephemeris DE 421, "
            "IPN Progress Report 42-178",
        ],
        parameters={"start": str(start_time), "end": str(end_time),
                    "enlargement": enlargement, "ephemeris": "de421.bsp",
                    "sun_semidiameter_1au_arcsec": 959.63,
                    "earth_radius_m": EARTH_EQUATORIAL_RADIUS_M,
                    "moon_earth_radius_ratio": MOON_EARTH_RADIUS_RATIO},
        enlargement=enlargement,
    )
