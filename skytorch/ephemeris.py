"""Times, Sun and Moon positions, and ICRS-to-horizontal rotations (skyfield + DE421).

Everything here runs offline: the JPL planetary ephemeris DE421 and the IERS
``finals2000A.all`` Earth-orientation table come from the ``skyfield-data`` package and
are opened with a skyfield ``Loader`` pointed at that package's data folder, so nothing is
ever downloaded. Loaded objects are cached for the life of the process.

Three kinds of output:

* :func:`sun_moon` — an ``xarray.Dataset`` over ``time`` (and ``observer`` when several
  observers are given) with apparent geocentric right ascension, declination and
  distance of the Sun and Moon, and, with an observer, topocentric altitude and azimuth
  without refraction (refraction belongs to :mod:`skytorch.atmosphere`).
* :func:`sun_moon_vectors` — apparent geocentric position vectors as float64 tensors,
  for eclipse geometry.
* :func:`icrs_to_horizontal_matrices` with :func:`earth_barycentric_velocity`,
  :func:`observer_gcrs_velocity` and :func:`aberrate` — per-time rotation matrices so that
  thousands of catalogue stars are transformed with one batched matmul per time.

Apparent star directions are obtained as (Notes of :func:`icrs_to_horizontal_matrices`)::

    v = earth_barycentric_velocity(t)[:, None] + observer_gcrs_velocity(t, lat, lon)[:, None]
    u_apparent = aberrate(u_icrs, v)                       # (n_time, n_star, 3), ICRS axes
    horizontal = u_apparent @ M.transpose(-1, -2)          # M from icrs_to_horizontal_matrices
    altitude_rad, azimuth_rad = altaz_from_horizontal(horizontal)

Time scales: inputs are UTC. UTC is converted to TT/TDB/UT1 by skyfield with the leap
seconds and UT1-UTC of ``finals2000A.all``; beyond the end of that table skyfield's
long-term Delta T model is used (its uncertainty, ~0.1 s a few years ahead, rotates the
sky by ~1.5 arcsec).

References
----------
1. Rhodes, B. 2019, "Skyfield: High precision research-grade positions for planets and
   Earth satellites generator", Astrophysics Source Code Library, ascl:1907.024.
2. Folkner, W. M., Williams, J. G., Boggs, D. H. 2009, "The Planetary and Lunar Ephemeris
   DE 421", IPN Progress Report 42-178.
3. Kaplan, G. H. 2005, "The IAU Resolutions on Astronomical Reference Systems, Time
   Scales, and Earth Rotation Models", USNO Circular 179, arXiv:astro-ph/0602086.
4. Urban, S. E., Seidelmann, P. K. (eds.) 2013, "Explanatory Supplement to the
   Astronomical Almanac", 3rd ed., University Science Books, ch. 7 (aberration, light
   deflection).
5. Petit, G., Luzum, B. (eds.) 2010, "IERS Conventions (2010)", IERS Technical Note 36
   (Earth's angular velocity, WGS84 ellipsoid).

Examples
--------
>>> from skytorch.ephemeris import sun_moon
>>> ds = sun_moon(["2024-06-20T20:51Z"])
>>> round(float(ds.sun_dec[0]), 2)
23.44
"""

from __future__ import annotations

import atexit
import datetime as _dt
import logging
import re
import warnings
from collections.abc import Iterable
from functools import lru_cache
from pathlib import Path

import numpy as np
import torch
import xarray as xr

from skytorch._validate import (
    as_tensor,
    check_broadcastable,
    check_finite,
    check_range,
    check_shape_last,
    refuse_gradient,
)
from skytorch.constants import SPEED_OF_LIGHT_M_S
from skytorch.dataset import VariableSpec, build_dataset, coordinate, time_coordinate, variable

__all__ = [
    "EPHEMERIS_FILE",
    "TIME_MAX",
    "TIME_MIN",
    "aberrate",
    "aberration_matrix",
    "altaz_from_horizontal",
    "check_observer",
    "one_observer",
    "earth_barycentric_velocity",
    "earth_rotation",
    "geodetic_to_itrs",
    "horizontal_rows",
    "icrs_to_horizontal_matrices",
    "load_ephemeris",
    "observer_gcrs_velocity",
    "parse_times",
    "skyfield_time",
    "sun_moon",
    "sun_moon_vectors",
    "VECTOR_FRAMES",
    "timescale",
]

logger = logging.getLogger(__name__)

EPHEMERIS_FILE = "de421.bsp"
EOP_FILE = "finals2000A.all"
#: DE421 covers 1899-07-29 00:00 to 2053-10-09 00:00 TDB; the usable UTC range keeps
#: half an hour of margin for the Sun's light time (8.3 min) and Delta T (-3 s .. 70 s).
TIME_MIN = np.datetime64("1899-07-29T00:30", "ns")
TIME_MAX = np.datetime64("2053-10-08T23:30", "ns")
DE421_RANGE_TEXT = "1899-07-29 .. 2053-10-09"

#: Earth's nominal mean angular velocity [rad/s] (IERS Conventions 2010, ref. 5)
EARTH_ANGULAR_VELOCITY_RAD_S = 7.292115e-5
#: WGS84 ellipsoid (ref. 5)
WGS84_SEMI_MAJOR_AXIS_M = 6_378_137.0
WGS84_FLATTENING = 1.0 / 298.257223563

#: geodetic latitude [degree] (both ends valid)
LATITUDE_RANGE_DEG = (-90.0, 90.0)
#: east longitude [degree] (the upper end excluded: 360 is 0)
LONGITUDE_RANGE_DEG = (-180.0, 360.0)
#: observer height above the WGS84 ellipsoid [m] (the Dead Sea shore, -430 m, to the top
#: of the model atmospheres, 100 km)
ELEVATION_MIN_M = -500.0
ELEVATION_MAX_M = 1.0e5

_LEAP_SECOND = re.compile(r"T?\s*\d{1,2}:\d{2}:60")
_OFFSET = re.compile(r"[+-]\d{2}:?\d{2}$")


# --- data loading ------------------------------------------------------------------------


@lru_cache(maxsize=1)
def _data_directory() -> Path:
    """skyfield-data's folder, without its file-expiry warning (the files stay usable)."""
    import skyfield_data

    with warnings.catch_warnings():
        # skyfield-data warns once the IERS predictions it ships are past their date;
        # DE421 never expires and UT1-UTC falls back on skyfield's Delta T model.
        warnings.simplefilter("ignore", RuntimeWarning)
        directory = Path(skyfield_data.get_skyfield_data_path())
    for name in (EPHEMERIS_FILE, EOP_FILE):
        if not (directory / name).is_file():
            raise FileNotFoundError(
                f"{name} is missing from skyfield-data ({directory}); reinstall skyfield-data"
            )
    return directory


@lru_cache(maxsize=1)
def _loader():
    from skyfield.api import Loader

    return Loader(str(_data_directory()), verbose=False)


@lru_cache(maxsize=1)
def timescale():
    """Return the offline skyfield ``Timescale`` (leap seconds and UT1-UTC from finals2000A.all).

    Returns
    -------
    skyfield.timelib.Timescale
    """
    # The file exists locally (checked in _data_directory), so the loader opens it and
    # never downloads.
    return _loader().timescale(builtin=False)


@lru_cache(maxsize=1)
def load_ephemeris():
    """Return the JPL DE421 ephemeris shipped with skyfield-data (cached).

    Returns
    -------
    skyfield.jpllib.SpiceKernel
    """
    kernel = _loader()(EPHEMERIS_FILE)
    atexit.register(kernel.close)  # the kernel keeps its file open while cached
    return kernel


# --- times -----------------------------------------------------------------------------------


def _parse_string(text: str) -> np.datetime64:
    original = text
    text = text.strip()
    if _LEAP_SECOND.search(text):
        raise ValueError(
            f"times: time {original!r} is a leap second (23:59:60), which numpy datetime64 "
            "cannot represent; give the instants before and after it instead"
        )
    try:
        if text[-1:] in "Zz":
            return np.datetime64(text[:-1].strip())
        if "T" in text[10:11] or " " in text[10:11]:
            if _OFFSET.search(text[11:]):
                moment = _dt.datetime.fromisoformat(text)
                return _from_datetime(moment)
        return np.datetime64(text)
    except (ValueError, IndexError) as error:
        raise ValueError(
            f"times: cannot parse time {original!r}; expected ISO 8601 UTC such as "
            "'2015-09-28T02:47:17Z' or '2015-09-28 02:47'"
        ) from error


def _from_datetime(moment: _dt.datetime) -> np.datetime64:
    if moment.tzinfo is not None and moment.utcoffset() is not None:
        moment = moment.astimezone(_dt.timezone.utc).replace(tzinfo=None)
    return np.datetime64(moment)


def _parse_one(value) -> np.datetime64:
    if isinstance(value, str):
        return _parse_string(value)
    if isinstance(value, _dt.datetime):
        return _from_datetime(value)
    if isinstance(value, _dt.date):
        return np.datetime64(value)
    if isinstance(value, np.datetime64):
        return value
    raise TypeError(
        "times must be ISO 8601 strings, datetime, date or numpy datetime64 values; got "
        f"{type(value).__name__}: {value!r:.60}"
    )


def parse_times(times) -> np.ndarray:
    """Parse UTC times into a 1-D ``datetime64[ns]`` array.

    Parameters
    ----------
    times : str, datetime.datetime, datetime.date, numpy.datetime64, or a list/array of them
        ISO 8601 strings with or without a trailing ``Z`` (UTC) or a numeric offset such
        as ``+02:00`` (converted to UTC); naive datetimes are UTC, aware ones are
        converted.

    Returns
    -------
    numpy.ndarray of datetime64[ns], shape (n_time,)

    Raises
    ------
    TypeError
        For values that are not times (numbers, None, tensors ...).
    ValueError
        For unparseable strings, NaT, leap-second labels ``23:59:60``, empty input, arrays
        of more than one dimension, and times outside DE421's range
        (1899-07-29 .. 2053-10-09; the usable UTC range is ``TIME_MIN`` .. ``TIME_MAX``).

    Examples
    --------
    >>> parse_times(["2015-09-28T02:46Z", "2016-12-31 23:59:59"])
    array(['2015-09-28T02:46:00.000000000', '2016-12-31T23:59:59.000000000'],
          dtype='datetime64[ns]')
    """
    if isinstance(times, (str, _dt.date, np.datetime64)):
        times = [times]
    if isinstance(times, torch.Tensor):
        raise TypeError("times must be strings, datetimes or datetime64 values, not a tensor")
    if not isinstance(times, np.ndarray) and hasattr(times, "__array__"):
        times = np.asarray(times)  # xarray / pandas datetime containers
    if isinstance(times, np.ndarray) and np.issubdtype(times.dtype, np.datetime64):
        values = times
    else:
        if not isinstance(times, (Iterable, np.ndarray)):
            raise TypeError(
                "times must be a time or a list/array of times; got "
                f"{type(times).__name__}: {times!r:.60}"
            )
        array = np.asarray(times, dtype=object)
        if array.ndim > 1:
            raise ValueError(f"times must be one-dimensional; got shape {array.shape}")
        parsed = [_parse_one(v) for v in array.reshape(-1)]
        # each in its own unit until the range is checked: datetime64[ns] holds the years
        # 1678-2261 only, and converting a time outside wraps it round silently
        values = np.empty(len(parsed), dtype=object)
        values[:] = parsed
    if values.ndim > 1:
        raise ValueError(f"times must be one-dimensional; got shape {values.shape}")
    values = values.reshape(-1)
    if values.size == 0:
        raise ValueError("times is empty; give at least one time")
    coarse = np.array([np.datetime64(v, "us") for v in values], dtype="datetime64[us]")
    if np.isnat(coarse).any():
        raise ValueError(f"times contains NaT at index {int(np.flatnonzero(np.isnat(coarse))[0])}")
    _check_time_range(coarse)
    return np.array([np.datetime64(v, "ns") for v in values], dtype="datetime64[ns]")


def _check_time_range(values: np.ndarray) -> None:
    # compared in microseconds: a comparison with the datetime64[ns] bounds would convert
    # the values to ns, which wraps the years outside 1678-2261 round
    low, high = (bound.astype("datetime64[us]") for bound in (TIME_MIN, TIME_MAX))
    values = values.astype("datetime64[us]")
    bad = (values < low) | (values > high)
    if bad.any():
        index = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"times: time {values[index]} (index {index}) is outside the range of the DE421 "
            f"ephemeris ({DE421_RANGE_TEXT}); valid UTC times are "
            f"{np.datetime_as_string(TIME_MIN, 'm')} .. {np.datetime_as_string(TIME_MAX, 'm')}"
        )


def skyfield_time(times):
    """Return a skyfield ``Time`` array for UTC ``times`` (anything :func:`parse_times` accepts).

    Leap seconds are honoured: the UTC calendar day and the seconds within it are handed
    to skyfield separately, so ``2016-12-31T23:59:59`` and ``2017-01-01T00:00:01`` are
    3 SI seconds apart.
    """
    values = parse_times(times)
    days = values.astype("datetime64[D]")
    seconds = (values - days).astype("timedelta64[ns]").astype(np.int64) / 1e9
    months = days.astype("datetime64[M]")
    year = months.astype("datetime64[Y]").astype(np.int64) + 1970
    month = months.astype(np.int64) % 12 + 1
    day = (days - months).astype(np.int64) + 1
    return timescale().utc(year, month, day, 0, 0, seconds)


# --- observers -------------------------------------------------------------------------------


def check_observer(lat_deg, lon_deg, elevation_m=0.0, dtype=torch.float64):
    """Validate observer coordinates and broadcast them to one shape.

    The one definition of the valid observer ranges, shared by every entry point that
    takes an observer.

    Parameters
    ----------
    lat_deg : float or array_like (*obs)
        Geodetic (WGS84) latitude [degree], in :data:`LATITUDE_RANGE_DEG` ([-90, 90]).
    lon_deg : float or array_like (*obs)
        East longitude [degree], in :data:`LONGITUDE_RANGE_DEG` ([-180, 360)).
    elevation_m : float or array_like (*obs)
        Height above the ellipsoid [m], in [:data:`ELEVATION_MIN_M`,
        :data:`ELEVATION_MAX_M`] ([-500, 1e5]).
    dtype : torch.dtype
        Floating type of non-tensor inputs (integer tensors are promoted to it).

    Returns
    -------
    lat, lon, elevation : Tensor (*obs)
        Broadcast to one shape; tensors keep their autograd graph.

    Raises
    ------
    TypeError
        Non-numeric coordinates (naming the parameter).
    ValueError
        NaN, inf or out-of-range values (naming the parameter, the value and the range),
        or shapes that do not broadcast (naming the three parameters and their shapes).

    Examples
    --------
    >>> lat, lon, height = check_observer([10, 20], 5, 0)
    >>> tuple(lat.shape), lon.dtype
    ((2,), torch.float64)
    >>> check_observer(91.0, 0.0)
    Traceback (most recent call last):
    ...
    ValueError: lat_deg must be in [-90.0 deg, 90.0 deg]; got 91.0 deg
    """
    lat = check_range("lat_deg", lat_deg, *LATITUDE_RANGE_DEG, unit=" deg", dtype=dtype)
    lon = check_range("lon_deg", lon_deg, *LONGITUDE_RANGE_DEG, high_inclusive=False,
                      unit=" deg", dtype=dtype)
    elevation = check_range("elevation_m", elevation_m, ELEVATION_MIN_M, ELEVATION_MAX_M,
                            unit=" m", dtype=dtype)
    shape = check_broadcastable(lat_deg=lat, lon_deg=lon, elevation_m=elevation)
    return lat.expand(shape), lon.expand(shape), elevation.expand(shape)


def _no_height_without_observer(where: str, elevation_m) -> None:
    """ValueError for a height other than 0 m given without an observer (it would be unused)."""
    if elevation_m is None:
        return
    height = check_range("elevation_m", elevation_m, ELEVATION_MIN_M, ELEVATION_MAX_M,
                         unit=" m")
    if bool((height != 0.0).any()):
        raise ValueError(f"{where}: elevation_m={elevation_m!r} needs an observer (give "
                         "lat_deg and lon_deg)")


def one_observer(where: str, lat_deg=None, lon_deg=None, elevation_m=None):
    """Validate an optional single observer: ``(lat, lon, elevation)`` floats or None.

    Latitude and longitude come together or not at all; a height without them, or more
    than one observer, is refused (ValueError naming ``where``); ranges as
    :func:`check_observer` (height default 0 m).
    """
    refuse_gradient(where, why="skyfield computes its positions",
                    lat_deg=lat_deg, lon_deg=lon_deg, elevation_m=elevation_m)
    if (lat_deg is None) != (lon_deg is None):
        raise ValueError(f"{where}: give both lat_deg and lon_deg for an observer, or "
                         f"neither; got lat_deg={lat_deg!r}, lon_deg={lon_deg!r}")
    if lat_deg is None:
        _no_height_without_observer(where, elevation_m)
        return None
    lat, lon, elevation = check_observer(lat_deg, lon_deg,
                                         0.0 if elevation_m is None else elevation_m)
    if lat.ndim:
        raise ValueError(f"{where} takes one observer: lat_deg, lon_deg and elevation_m "
                         f"must be scalars; got shape {tuple(lat.shape)}")
    return float(lat), float(lon), float(elevation)


def horizontal_rows(lat_rad: torch.Tensor, lon_rad: torch.Tensor) -> torch.Tensor:
    """Rotation from Earth-fixed (ITRS) axes to the local (north, east, up) axes.

    Parameters
    ----------
    lat_rad, lon_rad : Tensor (...)
        Geodetic latitude and east longitude [rad].

    Returns
    -------
    Tensor (..., 3, 3)
        Matrices whose rows are the north, east and up unit vectors in ITRS axes [1].
    """
    sin_lat, cos_lat = torch.sin(lat_rad), torch.cos(lat_rad)
    sin_lon, cos_lon = torch.sin(lon_rad), torch.cos(lon_rad)
    zero = torch.zeros_like(lat_rad)
    north = torch.stack([-sin_lat * cos_lon, -sin_lat * sin_lon, cos_lat], dim=-1)
    east = torch.stack([-sin_lon, cos_lon, zero], dim=-1)
    up = torch.stack([cos_lat * cos_lon, cos_lat * sin_lon, sin_lat], dim=-1)
    return torch.stack([north, east, up], dim=-2)


def geodetic_to_itrs(lat_rad, lon_rad, elevation_m) -> torch.Tensor:
    """Earth-fixed (ITRS) Cartesian position of a point given in WGS84 geodetic coordinates.

    Parameters
    ----------
    lat_rad, lon_rad : Tensor (...)
        Geodetic latitude and east longitude [rad].
    elevation_m : Tensor (...)
        Height above the WGS84 ellipsoid [m].

    Returns
    -------
    Tensor (..., 3)
        Position [m] in ITRS axes.
    """
    e2 = WGS84_FLATTENING * (2.0 - WGS84_FLATTENING)
    sin_lat = torch.sin(lat_rad)
    n = WGS84_SEMI_MAJOR_AXIS_M / torch.sqrt(1.0 - e2 * sin_lat**2)
    xy = (n + elevation_m) * torch.cos(lat_rad)
    z = (n * (1.0 - e2) + elevation_m) * sin_lat
    return torch.stack([xy * torch.cos(lon_rad), xy * torch.sin(lon_rad), z], dim=-1)


def earth_rotation(t) -> torch.Tensor:
    """Rotation from ICRS to Earth-fixed axes (pseudo-ITRS, no polar motion).

    ``R3(GAST) @ N @ P @ B`` with skyfield's IAU 2006/2000A precession-nutation matrix
    ``t.M`` and Greenwich apparent sidereal time ``t.gast`` (ref. 3, eq. 6.5).

    Parameters
    ----------
    t : skyfield.timelib.Time
        The instants (scalar or array).

    Returns
    -------
    Tensor (n_time, 3, 3)
        Rotation matrices [1], float64.
    """
    m = np.moveaxis(np.asarray(t.M, dtype=np.float64), -1, 0).reshape(-1, 3, 3)
    theta = np.asarray(t.gast, dtype=np.float64).reshape(-1) * (np.pi / 12.0)
    c, s = np.cos(theta), np.sin(theta)
    rotation = np.zeros((theta.size, 3, 3))
    rotation[:, 0, 0] = c
    rotation[:, 0, 1] = s
    rotation[:, 1, 0] = -s
    rotation[:, 1, 1] = c
    rotation[:, 2, 2] = 1.0
    return torch.from_numpy(rotation @ m)


def icrs_to_horizontal_matrices(times, lat_deg, lon_deg, elevation_m=0.0) -> torch.Tensor:
    """Rotation matrices from ICRS (GCRS) axes to the observer's horizontal frame.

    ``horizontal = M @ u`` for an apparent direction ``u`` in ICRS/GCRS axes, with the
    horizontal axes (north, east, up): altitude ``asin(h_up)``, azimuth
    ``atan2(h_east, h_north)`` measured from north through east. Note that (north, east,
    up) is a left-handed triad (north x east = down): ``det M = -1``; cross products in
    this frame need the sign flipped.

    Parameters
    ----------
    times : str, datetime, datetime64 or a list/array of them
        UTC, ``n_time`` instants (dimension ``time``).
    lat_deg : float or tensor, shape (*obs)
        Geodetic (WGS84) latitude [deg], in [-90, 90].
    lon_deg : float or tensor, shape (*obs)
        East longitude [deg], in [-180, 360).
    elevation_m : float or tensor, shape (*obs)
        Height above the ellipsoid [m], in [-500, 1e5]; validated only (the direction of
        the vertical does not depend on it).

    Returns
    -------
    torch.Tensor, float64, shape (n_time, *obs, 3, 3)
        ``(n_time, 3, 3)`` for a single observer. Differentiable with respect to
        ``lat_deg`` and ``lon_deg``.

    Notes
    -----
    ``M = H(phi, lambda) R3(GAST) N P B`` where ``N P B`` is skyfield's precession-nutation
    matrix (IAU 2006 precession, IAU 2000A nutation) to the true equator and equinox of
    date, ``R3(GAST)`` Earth's rotation by the Greenwich apparent sidereal time, and ``H``
    the rows north ``(-sin phi cos lambda, -sin phi sin lambda, cos phi)``, east
    ``(-sin lambda, cos lambda, 0)`` and up ``(cos phi cos lambda, cos phi sin lambda,
    sin phi)``. Polar motion (< 0.5 arcsec) is ignored, as skyfield does by default.

    To get apparent topocentric directions of stars, apply annual plus diurnal aberration
    in ICRS axes *before* the rotation, with the observer's barycentric velocity
    ``earth_barycentric_velocity(t) + observer_gcrs_velocity(t, lat, lon, h)``
    (:func:`aberrate`, up to 20.5 arcsec + 0.3 arcsec). Gravitational light deflection
    by the Sun is neglected: 4 mas at 90 deg from the Sun, ``0.004" cot(psi/2)`` in
    general, 1.75 arcsec at the solar limb. Stellar parallax and proper motion belong to the
    catalogue. The result matches skyfield's ``observe().apparent().altaz()`` to a few
    milliarcseconds (tests assert < 1 arcsec).

    Examples
    --------
    >>> m = icrs_to_horizontal_matrices(["2024-01-01T00:00Z"], 48.0, 11.0)
    >>> tuple(m.shape)
    (1, 3, 3)
    """
    t = skyfield_time(times)
    lat, lon, _ = check_observer(lat_deg, lon_deg, elevation_m)
    earth = earth_rotation(t)  # (n, 3, 3)
    local = horizontal_rows(torch.deg2rad(lat), torch.deg2rad(lon))  # (*obs, 3, 3)
    earth = earth.reshape(earth.shape[0], *([1] * lat.ndim), 3, 3)
    return local.to(torch.float64) @ earth


def altaz_from_horizontal(vectors: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Altitude and azimuth [rad] of (north, east, up) vectors of shape (..., 3).

    Azimuth is measured from north through east in [0, 2 pi). Integer tensors are
    promoted to float; the zero vector gives altitude and azimuth 0.

    Raises
    ------
    TypeError
        ``vectors`` is not numeric.
    ValueError
        ``vectors`` does not have shape (..., 3).
    """
    vectors = check_shape_last("vectors", as_tensor("vectors", vectors), 3)
    north, east, up = vectors.unbind(-1)
    altitude = torch.atan2(up, torch.hypot(north, east))
    azimuth = torch.remainder(torch.atan2(east, north), 2.0 * torch.pi)
    return altitude, azimuth


def earth_barycentric_velocity(times) -> torch.Tensor:
    """Velocity of Earth's centre relative to the solar-system barycentre [m/s].

    Parameters
    ----------
    times : see :func:`parse_times`

    Returns
    -------
    torch.Tensor, float64, shape (n_time, 3)
        ICRS axes, from DE421 (ref. 2); about 30 km/s.
    """
    t = skyfield_time(times)
    velocity = load_ephemeris()["earth"].at(t).velocity.m_per_s
    return torch.from_numpy(np.ascontiguousarray(np.asarray(velocity, np.float64).T))


def observer_gcrs_velocity(times, lat_deg, lon_deg, elevation_m=0.0) -> torch.Tensor:
    """Velocity of an observer on the rotating Earth relative to Earth's centre [m/s].

    Parameters
    ----------
    times : see :func:`parse_times`
    lat_deg, lon_deg, elevation_m : float or tensor, shape (*obs)
        WGS84 geodetic latitude and east longitude [deg], height above the ellipsoid [m].

    Returns
    -------
    torch.Tensor, float64, shape (n_time, *obs, 3)
        GCRS (ICRS) axes; at most 465 m/s at the equator (diurnal aberration 0.32 arcsec).

    Notes
    -----
    ``v = (R3(GAST) N P B)^T (omega z x r_ITRS)`` with ``omega`` Earth's nominal angular
    velocity and ``r_ITRS`` the WGS84 position of the observer (ref. 5).
    """
    t = skyfield_time(times)
    lat, lon, elevation = check_observer(lat_deg, lon_deg, elevation_m)
    position = geodetic_to_itrs(torch.deg2rad(lat), torch.deg2rad(lon), elevation)
    x, y, _ = position.unbind(-1)
    velocity = EARTH_ANGULAR_VELOCITY_RAD_S * torch.stack([-y, x, torch.zeros_like(x)], dim=-1)
    earth = earth_rotation(t)
    earth = earth.reshape(earth.shape[0], *([1] * lat.ndim), 3, 3)
    return (earth.transpose(-1, -2) @ velocity.to(torch.float64).unsqueeze(-1)).squeeze(-1)


def _aberrated(direction: torch.Tensor, beta: torch.Tensor) -> torch.Tensor:
    """``γ⁻¹ u + (1 + (u·β)/(1 + γ⁻¹)) β``: the aberrated direction before normalisation."""
    inverse_gamma = torch.sqrt(1.0 - (beta * beta).sum(-1, keepdim=True))
    dot = (direction * beta).sum(-1, keepdim=True)
    return inverse_gamma * direction + (1.0 + dot / (1.0 + inverse_gamma)) * beta


def _beta(velocity_m_s, dtype: torch.dtype | None = None) -> torch.Tensor:
    """``β = v/c``, checked: a speed of light or more would give NaN (γ⁻¹ = √(1 − β²))."""
    velocity = check_shape_last("velocity_m_s",
                                check_finite("velocity_m_s", velocity_m_s, dtype=dtype), 3)
    with torch.no_grad():
        speed = torch.linalg.vector_norm(velocity, dim=-1)
        if speed.numel() and float(speed.max()) >= SPEED_OF_LIGHT_M_S:
            raise ValueError(f"velocity_m_s must have a speed below c = {SPEED_OF_LIGHT_M_S} "
                             f"m/s; got {float(speed.max())} m/s")
    return velocity / SPEED_OF_LIGHT_M_S


def aberrate(direction: torch.Tensor, velocity_m_s: torch.Tensor) -> torch.Tensor:
    """Apply relativistic stellar aberration to unit directions.

    Parameters
    ----------
    direction : torch.Tensor, shape (..., 3)
        Unit vectors towards the sources (ICRS axes), as seen from the barycentre.
    velocity_m_s : torch.Tensor, shape (..., 3)
        Observer's barycentric velocity [m/s], broadcastable against ``direction``.

    Returns
    -------
    torch.Tensor, shape (..., 3)
        Unit vectors of the aberrated (apparent) directions, dtype of ``direction``.

    Notes
    -----
    With ``beta = v / c`` and ``gamma^-1 = sqrt(1 - beta^2)`` (ref. 4, eq. 7.40)::

        u' ∝ gamma^-1 u + (1 + (u . beta) / (1 + gamma^-1)) beta

    The map before normalisation is affine in ``u``: :func:`aberration_matrix`.

    Examples
    --------
    >>> import torch
    >>> u = torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64)
    >>> moved = aberrate(u, torch.tensor([0.0, 29.8e3, 0.0], dtype=torch.float64))
    >>> round(float(torch.rad2deg(torch.atan2(moved[1], moved[0]))) * 3600.0, 2)  # [arcsec]
    20.5
    """
    direction = check_shape_last("direction", as_tensor("direction", direction), 3)
    beta = _beta(velocity_m_s, dtype=direction.dtype)
    check_broadcastable(direction=direction, velocity_m_s=beta)
    moved = _aberrated(direction, beta)
    return moved / torch.linalg.vector_norm(moved, dim=-1, keepdim=True)


def aberration_matrix(velocity_m_s: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Affine form of :func:`aberrate`: ``u' ∝ A u + β``.

    Parameters
    ----------
    velocity_m_s : torch.Tensor, shape (..., 3)
        Observer's barycentric velocity [m/s].

    Returns
    -------
    matrix : torch.Tensor, shape (..., 3, 3)
        ``A = γ⁻¹ I + β βᵀ / (1 + γ⁻¹)``, dtype of ``velocity_m_s``.
    beta : torch.Tensor, shape (..., 3)
        ``β = v/c``.

    Notes
    -----
    The columns of ``A`` are the unnormalised images of the basis vectors less ``β``, so
    ``A u + β`` is exactly the vector that :func:`aberrate` normalises; folded into linear
    operators it applies aberration with one matrix product
    (:func:`skytorch.stars.positions.aberration_operators`).

    Examples
    --------
    >>> import torch
    >>> matrix, beta = aberration_matrix(torch.tensor([0.0, 29.8e3, 0.0], dtype=torch.float64))
    >>> tuple(matrix.shape), round(float(beta[1]) * 1e4, 3)
    ((3, 3), 0.994)
    """
    beta = _beta(velocity_m_s)
    eye = torch.eye(3, dtype=beta.dtype)
    images = _aberrated(eye, beta.unsqueeze(-2))  # row i: A e_i + β
    return (images - beta.unsqueeze(-2)).transpose(-1, -2), beta


# --- Sun and Moon ----------------------------------------------------------------------------


def _apparent_geocentric(t):
    ephemeris = load_ephemeris()
    earth = ephemeris["earth"].at(t)
    return earth.observe(ephemeris["sun"]).apparent(), earth.observe(ephemeris["moon"]).apparent()


#: frames of :func:`sun_moon_vectors`: GCRS (ICRS axes) and true equator and equinox of date
VECTOR_FRAMES = ("gcrs", "tod")


def sun_moon_vectors(times, frames=VECTOR_FRAMES) -> dict[str, torch.Tensor]:
    """Apparent geocentric position vectors of the Sun and Moon [m].

    Parameters
    ----------
    times : see :func:`parse_times`
    frames : sequence of {"gcrs", "tod"}
        Frames to return (:data:`VECTOR_FRAMES`); ``"tod"`` needs the IAU 2000A nutation
        at every time, most of the cost for a few thousand times.

    Returns
    -------
    dict of str to torch.Tensor, float64, each (n_time, 3)
        ``"sun_gcrs_m"``, ``"moon_gcrs_m"``: GCRS (ICRS) axes; ``"sun_tod_m"``,
        ``"moon_tod_m"``: true equator and equinox of date. Light time, aberration by
        Earth's barycentric velocity and gravitational deflection included (skyfield
        ``observe().apparent()``); lengths are the light-time distances.
    """
    if isinstance(frames, str) or not all(isinstance(f, str) for f in frames) \
            or not set(frames) <= set(VECTOR_FRAMES) or not frames:
        raise ValueError(f"frames must be a non-empty sequence of {VECTOR_FRAMES}; got "
                         f"{frames!r:.60}")
    t = skyfield_time(times)
    sun, moon = _apparent_geocentric(t)
    matrix = (np.moveaxis(np.asarray(t.M, np.float64), -1, 0).reshape(-1, 3, 3)
              if "tod" in frames else None)
    result = {}
    for name, position in (("sun", sun), ("moon", moon)):
        gcrs = np.ascontiguousarray(np.asarray(position.position.m, np.float64).T)
        if "gcrs" in frames:
            result[f"{name}_gcrs_m"] = torch.from_numpy(gcrs)
        if matrix is not None:
            result[f"{name}_tod_m"] = torch.from_numpy(np.einsum("nij,nj->ni", matrix, gcrs))
    return result


_FRAME = "true equator and equinox of date"
_SPECS = {
    "ra": ("degree", "apparent geocentric right ascension of the {body}",
           "Apparent geocentric right ascension of the {body}'s centre ({frame}; light time, "
           "aberration and light deflection applied; DE421)."),
    "dec": ("degree", "apparent geocentric declination of the {body}",
            "Apparent geocentric declination of the {body}'s centre ({frame}; light time, "
            "aberration and light deflection applied; DE421)."),
    "distance": ("m", "geocentric distance of the {body}",
                 "Distance from Earth's centre to the {body}'s centre (light-time corrected)."),
    "altitude": ("degree", "topocentric altitude of the {body}",
                 "Apparent topocentric altitude of the {body}'s centre above the observer's "
                 "horizontal plane, geometric (no atmospheric refraction)."),
    "azimuth": ("degree", "topocentric azimuth of the {body}",
                "Apparent topocentric azimuth of the {body}'s centre, from north through east "
                "in [0, 360)."),
}
_STANDARD_NAMES = {("sun", "altitude"): "solar_elevation_angle",
                   ("sun", "azimuth"): "solar_azimuth_angle"}


def _spec(body: str, quantity: str) -> VariableSpec:
    units, long_name, description = _SPECS[quantity]
    name = "Sun" if body == "sun" else "Moon"
    return VariableSpec(units, long_name.format(body=name),
                        description.format(body=name, frame=_FRAME),
                        _STANDARD_NAMES.get((body, quantity)))


def _topocentric_altaz(t, lat: float, lon: float, elevation: float):
    from skyfield.api import wgs84

    ephemeris = load_ephemeris()
    observer = (ephemeris["earth"] + wgs84.latlon(lat, lon, elevation_m=elevation)).at(t)
    out = {}
    for body in ("sun", "moon"):
        altitude, azimuth, _ = observer.observe(ephemeris[body]).apparent().altaz()
        out[f"{body}_altitude"] = np.asarray(altitude.degrees, np.float64).reshape(-1)
        out[f"{body}_azimuth"] = np.asarray(azimuth.degrees, np.float64).reshape(-1)
    return out


def sun_moon(times, lat_deg=None, lon_deg=None, elevation_m=0.0) -> xr.Dataset:
    """Sun and Moon positions over time as a CF-annotated Dataset.

    Parameters
    ----------
    times : str, datetime, datetime64 or a list/array of them
        UTC instants (dimension ``time``).
    lat_deg, lon_deg : float or 1-D sequence, optional
        Observer's WGS84 geodetic latitude in [-90, 90] and east longitude in [-180, 360)
        [deg]. Both or neither. A 1-D sequence gives one observer per element (dimension
        ``observer``).
    elevation_m : float or 1-D sequence
        Height above the ellipsoid [m], in [-500, 1e5].

    Returns
    -------
    xarray.Dataset
        ``sun_ra``, ``sun_dec`` [degree], ``sun_distance`` [m], ``moon_ra``, ``moon_dec``,
        ``moon_distance`` over ``time``; with an observer also ``sun_altitude``,
        ``sun_azimuth``, ``moon_altitude``, ``moon_azimuth`` [degree] over ``time`` (and
        ``observer`` for several observers), geometric (no refraction).

    Raises
    ------
    ValueError
        Times outside 1899-07-29 .. 2053-10-09, latitude/longitude/elevation out of range
        or NaN, only one of ``lat_deg``/``lon_deg``.
    TypeError
        Non-numeric observer coordinates or non-time ``times``.

    Examples
    --------
    >>> ds = sun_moon("2024-03-20T03:06Z", lat_deg=0.0, lon_deg=0.0)
    >>> abs(float(ds.sun_dec[0])) < 0.01
    True
    """
    refuse_gradient("sun_moon", why="skyfield computes its positions",
                    lat_deg=lat_deg, lon_deg=lon_deg, elevation_m=elevation_m)
    if (lat_deg is None) != (lon_deg is None):
        raise ValueError("give both lat_deg and lon_deg for an observer, or neither; got "
                         f"lat_deg={lat_deg!r}, lon_deg={lon_deg!r}")
    if lat_deg is None:  # a height other than 0 would go unused
        _no_height_without_observer("sun_moon", elevation_m)
    else:
        lat, lon, elevation = check_observer(lat_deg, lon_deg, elevation_m)
        if lat.ndim > 1:
            raise ValueError(
                "observer coordinates lat_deg, lon_deg, elevation_m must be scalars or 1-D; "
                f"they broadcast to shape {tuple(lat.shape)}"
            )
    values = parse_times(times)
    t = skyfield_time(values)
    sun, moon = _apparent_geocentric(t)
    data = {}
    for body, position in (("sun", sun), ("moon", moon)):
        ra, dec, distance = position.radec(epoch="date")
        data[f"{body}_ra"] = variable("time", 15.0 * np.asarray(ra.hours, np.float64).reshape(-1),
                                      _spec(body, "ra"))
        data[f"{body}_dec"] = variable("time", np.asarray(dec.degrees, np.float64).reshape(-1),
                                       _spec(body, "dec"))
        data[f"{body}_distance"] = variable("time", np.asarray(distance.m, np.float64).reshape(-1),
                                            _spec(body, "distance"))
    coords = {"time": time_coordinate(values)}
    parameters: dict[str, object] = {"ephemeris": EPHEMERIS_FILE, "refraction": False}
    if lat_deg is not None:
        parameters.update(lat_deg=lat, lon_deg=lon, elevation_m=elevation)
        observers = [(float(a), float(b), float(c)) for a, b, c in
                     zip(lat.reshape(-1), lon.reshape(-1), elevation.reshape(-1), strict=True)]
        columns = [_topocentric_altaz(t, *observer) for observer in observers]
        for name in columns[0]:
            body, quantity = name.split("_")
            if lat.ndim == 0:
                data[name] = variable("time", columns[0][name], _spec(body, quantity))
            else:
                stacked = np.stack([column[name] for column in columns], axis=1)
                data[name] = variable(("time", "observer"), stacked, _spec(body, quantity))
        if lat.ndim == 1:
            coords["observer"] = coordinate(
                "observer", np.arange(lat.shape[0]),
                VariableSpec("1", "observer index", "Index of the observer."))
            for name, value, spec in (
                ("latitude", lat, VariableSpec("degree_north", "latitude",
                                               "WGS84 geodetic latitude of the observer.",
                                               "latitude")),
                ("longitude", lon, VariableSpec("degree_east", "longitude",
                                                "East longitude of the observer.", "longitude")),
                ("elevation", elevation, VariableSpec("m", "observer height",
                                                      "Height above the WGS84 ellipsoid.",
                                                      "height_above_reference_ellipsoid")),
            ):
                coords[name] = variable("observer", value, spec)
    return build_dataset(
        data, coords,
        title="Apparent Sun and Moon positions",
        references=[
            "Rhodes, B. 2019, Skyfield, Astrophysics Source Code Library, ascl:1907.024",
            "Folkner, W. M. et al. 2009, The Planetary and Lunar Ephemeris DE 421, "
            "IPN Progress Report 42-178",
        ],
        parameters=parameters,
        frame=_FRAME,
    )
