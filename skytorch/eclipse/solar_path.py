"""The Moon's shadow on Earth: obscuration maps and the path of a central solar eclipse.

Method
------
*Obscuration map*: for every node of a latitude-longitude grid on the WGS84 ellipsoid
(height 0) the topocentric Sun and Moon radii and separation at one instant (the
Chebyshev-interpolated DE421 vectors of :mod:`skytorch.eclipse.solar`) give the
magnitude and the covered fraction of the solar disc (exact lens area,
:func:`skytorch.eclipse.sun_visible_fraction` with no limb darkening; penumbral ``k``).
The values are geometric: where the Sun is below the horizon (``sun_altitude < 0``) the
Moon's cone is continued through Earth, and users mask those points.

*Path*: at each instant the central line is where the shadow axis meets the ellipsoid.
A limit point at time ``t`` is the point of the ellipsoid at the edge of the umbral
(antumbral) cone that sees its maximum eclipse at ``t``: its offset from the axis is
perpendicular to its velocity relative to the shadow. It is found by a fixed-point
iteration on the surface (offset ``L n`` from the axis, ``L`` the cone radius at the
point's axial distance, ``n`` normal to the axis and to the relative velocity, the
velocity by central differences over 1 s); the "northern" limit is the one with the
larger north component of ``n``. Umbral ``k`` throughout.

References
----------
1. Espenak, F., Meeus, J. 2006, NASA/TP-2006-214141.
2. Urban, S. E., Seidelmann, P. K. (eds.) 2013, Explanatory Supplement to the Astronomical
   Almanac, 3rd ed., ch. 11 (limits of the umbral path).
"""

from __future__ import annotations

import numpy as np
import torch
import xarray as xr

from skytorch._validate import check_range, refuse_gradient
from skytorch.constants import EARTH_EQUATORIAL_RADIUS_M
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable
from skytorch.eclipse.circumstances import _parse_one
from skytorch.eclipse.occlusion import sun_visible_fraction
from skytorch.eclipse.solar import (
    _N_NARROW_NODES,
    _NARROW_HALF_S,
    MOON_RADIUS_PENUMBRAL,
    MOON_RADIUS_UMBRAL,
    _axis,
    _axis_surface_point,
    _central_ends,
    _geodetic,
    _line_surface_point,
    _norm,
    _sun_radius_m,
    _SunMoon,
    _topocentric,
    _up,
)
from skytorch.eclipse.solar_local import _find_eclipse
from skytorch.ephemeris import geodetic_to_itrs, parse_times

__all__ = ["obscuration_map", "solar_eclipse_path"]

_LIMIT_ITERATIONS = 6


def _grid(values, name: str, low: float, high: float, default: np.ndarray) -> torch.Tensor:
    if values is None:
        return torch.as_tensor(default, dtype=torch.float64)
    tensor = check_range(name, values, low, high, unit=" deg", dtype=torch.float64)
    if tensor.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional; got shape {tuple(tensor.shape)}")
    return tensor


def obscuration_map(time, lat_deg=None, lon_deg=None) -> xr.Dataset:
    """Obscuration of the Sun by the Moon over a latitude-longitude grid at one instant.

    Parameters
    ----------
    time : str, datetime or datetime64
        One UTC instant.
    lat_deg : array_like (latitude,), optional
        Geodetic latitudes [degree] in [-90, 90]; default 720 cell centres (0.25 deg).
    lon_deg : array_like (longitude,), optional
        East longitudes [degree] in [-180, 360]; default 1440 cell centres (0.25 deg).

    Returns
    -------
    xarray.Dataset
        Over ``(latitude, longitude)``: ``obscuration`` (covered fraction of the disc
        area, 0 outside the penumbra), ``magnitude`` (fraction of the diameter, negative
        outside), ``sun_altitude`` [degree] (geometric; mask ``< 0`` for the night side).

    Examples
    --------
    >>> ds = obscuration_map("2024-04-08T18:42:39", [32.7767], [-96.797])
    >>> round(float(ds.obscuration[0, 0]), 3)
    1.0
    """
    refuse_gradient("obscuration_map", lat_deg=lat_deg, lon_deg=lon_deg)
    instant = _parse_one("time", time, parse_times)
    lat = _grid(lat_deg, "lat_deg", -90.0, 90.0, np.arange(-89.875, 90.0, 0.25))
    lon = _grid(lon_deg, "lon_deg", -180.0, 360.0, np.arange(-179.875, 180.0, 0.25))
    geometry = _SunMoon(np.array([instant]), 60.0, 3)  # +-1 min series, evaluated at 0
    sun, moon = geometry.itrs(torch.zeros(1, 1, dtype=torch.float64))
    lat_r, lon_r = torch.deg2rad(lat)[:, None], torch.deg2rad(lon)[None, :]
    lat_r, lon_r = torch.broadcast_tensors(lat_r, lon_r)
    points = geodetic_to_itrs(lat_r, lon_r, torch.zeros_like(lat_r))
    s, m, sigma, to_sun = _topocentric(sun[0], moon[0], points, MOON_RADIUS_PENUMBRAL)
    magnitude = (s + m - sigma) / (2.0 * s)
    obscuration = torch.zeros_like(magnitude)
    inside = magnitude > 0
    if inside.any():
        obscuration[inside] = 1.0 - sun_visible_fraction(s[inside], m[inside], sigma[inside],
                                                         limb_darkening=0.0)
    altitude = torch.rad2deg(torch.asin((_up(lat_r, lon_r) * to_sun).sum(-1) / _norm(to_sun)))
    dims = ("latitude", "longitude")
    specs = {
        "obscuration": VariableSpec("1", "obscuration",
                                    "Fraction of the Sun's disc area covered by the Moon "
                                    "(uniform disc, penumbral k; geometric)."),
        "magnitude": VariableSpec("1", "eclipse magnitude",
                                  "(s + m - sigma) / (2 s), negative outside the penumbra."),
        "sun_altitude": VariableSpec("degree", "Sun altitude",
                                     "Geometric altitude of the Sun's centre.",
                                     "solar_elevation_angle"),
    }
    values = {"obscuration": obscuration, "magnitude": magnitude, "sun_altitude": altitude}
    coords = {
        "latitude": coordinate("latitude", lat, VariableSpec("degree_north", "latitude",
                                                             "Geodetic (WGS84) latitude.",
                                                             "latitude")),
        "longitude": coordinate("longitude", lon, VariableSpec("degree_east", "longitude",
                                                               "East longitude.",
                                                               "longitude")),
    }
    return build_dataset(
        {name: variable(dims, value, specs[name]) for name, value in values.items()}, coords,
        title="Solar eclipse obscuration map",
        references=["Espenak, F., Meeus, J. 2006, NASA/TP-2006-214141"],
        parameters={"time": str(instant), "moon_radius_penumbral": MOON_RADIUS_PENUMBRAL},
        time=str(instant))


def _relative_offset(geometry, seconds, point):
    """Offset of ``point`` from the shadow axis, perpendicular to the axis [m]."""
    sun, moon = geometry.itrs(seconds)
    direction, _ = _axis(sun, moon)
    offset = point - moon
    return offset - (offset * direction).sum(-1, keepdim=True) * direction


def _limit_points(geometry, seconds: torch.Tensor, start: torch.Tensor, side: float):
    """Northern (``side = +1``) or southern (-1) limit points at ``seconds`` (1, T)."""
    sun, moon = geometry.itrs(seconds)
    direction, _ = _axis(sun, moon)
    separation = _norm(sun - moon)
    sin_f2 = (_sun_radius_m() - MOON_RADIUS_UMBRAL * EARTH_EQUATORIAL_RADIUS_M) / separation
    tan_f2 = sin_f2 / torch.sqrt(1.0 - sin_f2**2)
    vertex = moon + (MOON_RADIUS_UMBRAL * EARTH_EQUATORIAL_RADIUS_M / sin_f2)[..., None] \
        * direction
    point = start
    for _ in range(_LIMIT_ITERATIONS):
        radius = torch.abs(((point - vertex) * direction).sum(-1)) * tan_f2
        velocity = (_relative_offset(geometry, seconds + 1.0, point)
                    - _relative_offset(geometry, seconds - 1.0, point)) / 2.0
        normal = torch.linalg.cross(direction, velocity)
        normal = normal / _norm(normal)[..., None]
        normal = torch.where((normal[..., 2:3] * side) >= 0, normal, -normal)
        origin = moon - (moon * direction).sum(-1, keepdim=True) * direction \
            + radius[..., None] * normal
        origin = origin - 2.0 * EARTH_EQUATORIAL_RADIUS_M * direction  # sunward of Earth
        point, discriminant = _line_surface_point(origin, direction)
        point = torch.where((discriminant >= 0)[..., None], point, torch.nan)
    return point


def _distance_to_polyline(points: torch.Tensor, line: torch.Tensor) -> torch.Tensor:
    """Straight-line distance [m] from each of ``points`` (T, 3) to the polyline (S, 3).

    Segments with a NaN end are skipped; NaN where no segment is left.
    """
    a, b = line[:-1][None], line[1:][None]
    edge = b - a
    t = ((points[:, None] - a) * edge).sum(-1) / (edge * edge).sum(-1)
    nearest = a + torch.clamp(t, 0.0, 1.0)[..., None] * edge
    distance = _norm(points[:, None] - nearest)
    distance = torch.where(torch.isnan(distance), torch.inf, distance).amin(dim=1)
    return torch.where(torch.isinf(distance), torch.nan, distance)


#: time step of the limit lines that the path width is measured to [s]: the widths do not
#: depend on the output's ``step_s`` (chords of 300-600 s widened the path by 5-15 % near
#: its ends)
_WIDTH_STEP_S = 5.0


def _path_width(geometry, first: float, last: float, central: torch.Tensor,
                missing: torch.Tensor) -> torch.Tensor:
    """Path width [m] (1, T) at the central points (T, 3): to limit lines every few seconds.

    NaN where a limit line has left Earth at the central point's instant (``missing``):
    the nearest piece of the other end of that line is no width of the path.
    """
    fine = torch.linspace(first + 1e-3, last - 1e-3,
                          max(2, int(np.ceil((last - first) / _WIDTH_STEP_S)) + 1),
                          dtype=torch.float64)[None, :]
    axis_points, _ = _axis_surface_point(*geometry.itrs(fine))
    width = (_distance_to_polyline(central, _limit_points(geometry, fine, axis_points, 1.0)[0])
             + _distance_to_polyline(central,
                                     _limit_points(geometry, fine, axis_points, -1.0)[0]))
    return torch.where(missing, torch.nan, width)[None]


def solar_eclipse_path(time_or_date, step_s: float = 60.0) -> xr.Dataset:
    """Central line and the northern and southern limits of a central solar eclipse.

    Parameters
    ----------
    time_or_date : str, datetime or datetime64
        A UTC time or date within 2 days of the eclipse's greatest eclipse.
    step_s : float
        Time step along the path [s], in [1, 3600].

    Returns
    -------
    xarray.Dataset
        Over ``time`` (UTC, from the first to the last contact of the axis with Earth):
        ``central_latitude``, ``central_longitude``, ``north_latitude``,
        ``north_longitude``, ``south_latitude``, ``south_longitude`` [degree] (NaN where
        the limit leaves Earth), ``moon_sun_ratio`` on the central line, ``sun_altitude``
        [degree] there, ``path_width`` [m] (distances from the central point to the two
        limit lines, straight-line, summed; across the path).

    Raises
    ------
    ValueError
        No eclipse within 2 days, or the eclipse is not central (no central line).

    Examples
    --------
    >>> ds = solar_eclipse_path("2024-04-08", step_s=600.0)
    >>> bool((ds.moon_sun_ratio > 1).all())
    True
    """
    step = float(check_range("step_s", step_s, 1.0, 3600.0, unit=" s"))
    greatest = _find_eclipse(time_or_date)
    geometry = _SunMoon(np.array([greatest]), _NARROW_HALF_S, _N_NARROW_NODES)
    _, discriminant = _axis_surface_point(*geometry.itrs(torch.zeros(1, 1,
                                                                     dtype=torch.float64)))
    if not bool(discriminant[0, 0] >= 0):
        raise ValueError(f"time_or_date: the solar eclipse of {greatest} is not central "
                         "(its shadow axis misses Earth): no central line")
    ends = _central_ends(geometry, torch.tensor([True]))[0]
    first, last = float(ends[0]), float(ends[1])
    # instants on multiples of ``step`` of UTC from midnight
    of_day = float((greatest - greatest.astype("datetime64[D]")) / np.timedelta64(1, "ns")) * 1e-9
    seconds = torch.arange(np.ceil((of_day + first) / step) * step, of_day + last, step,
                           dtype=torch.float64) - of_day
    seconds = torch.cat((torch.tensor([first + 1e-3]), seconds, torch.tensor([last - 1e-3])))
    seconds = seconds[None, :]
    sun, moon = geometry.itrs(seconds)
    central, _ = _axis_surface_point(sun, moon)
    s, _, _, to_sun = _topocentric(sun, moon, central, MOON_RADIUS_UMBRAL)
    _, m_umb, _, _ = _topocentric(sun, moon, central, MOON_RADIUS_UMBRAL)
    lat, lon = _geodetic(central)
    altitude = torch.rad2deg(torch.asin(torch.clamp(
        (_up(lat, lon) * to_sun).sum(-1) / _norm(to_sun), -1.0, 1.0)))
    north = _limit_points(geometry, seconds, central, 1.0)
    south = _limit_points(geometry, seconds, central, -1.0)
    values = {"central_latitude": torch.rad2deg(lat), "central_longitude": torch.rad2deg(lon)}
    for name, point in (("north", north), ("south", south)):
        plat, plon = _geodetic(point)
        values[f"{name}_latitude"], values[f"{name}_longitude"] = (torch.rad2deg(plat),
                                                                   torch.rad2deg(plon))
    values["moon_sun_ratio"] = m_umb / s
    values["sun_altitude"] = altitude
    values["path_width"] = _path_width(geometry, first, last, central[0],
                                       torch.isnan(north[0, :, 0]) | torch.isnan(south[0, :, 0]))
    text = {"central": "central line (shadow axis on the ellipsoid)",
            "north": "northern limit of the umbral (antumbral) path",
            "south": "southern limit of the umbral (antumbral) path"}
    specs = {}
    for key, description in text.items():
        specs[f"{key}_latitude"] = VariableSpec("degree_north", f"latitude of the {key} line",
                                                f"Geodetic latitude of the {description}.")
        specs[f"{key}_longitude"] = VariableSpec("degree_east", f"longitude of the {key} line",
                                                 f"East longitude of the {description}.")
    specs["moon_sun_ratio"] = VariableSpec("1", "Moon/Sun apparent diameter ratio",
                                           "On the central line, umbral k.")
    specs["sun_altitude"] = VariableSpec("degree", "Sun altitude on the central line",
                                         "Geometric altitude of the Sun's centre.",
                                         "solar_elevation_angle")
    specs["path_width"] = VariableSpec("m", "path width",
                                       "Distance from the central-line point to the northern "
                                       "limit line plus that to the southern limit line "
                                       "(straight-line chords to the limit lines computed "
                                       "every 5 s, whatever the step; NaN where a limit has "
                                       "left Earth at that instant).")
    times = greatest + np.round(seconds[0].numpy() * 1e9).astype("timedelta64[ns]")
    coords = {"time": coordinate("time", times, VariableSpec("", "time (UTC)",
                                                             "Instant along the path."))}
    return build_dataset(
        {name: variable(("time",), value[0], specs[name]) for name, value in values.items()},
        coords, title="Solar eclipse path",
        references=["Espenak, F., Meeus, J. 2006, NASA/TP-2006-214141",
                    "Urban, S. E., Seidelmann, P. K. 2013, Explanatory Supplement, 3rd ed., "
                    "ch. 11"],
        parameters={"greatest_eclipse": str(greatest), "step_s": step,
                    "moon_radius_umbral": MOON_RADIUS_UMBRAL},
        greatest_eclipse=str(greatest))
