"""Local circumstances of a solar eclipse for a batch of observers (topocentric geometry).

Method
------
For each observer (WGS84 geodetic position, Earth-fixed), the topocentric angular radii
of the Sun ``s`` and Moon ``m`` and their separation ``sigma`` follow from the Chebyshev
interpolated DE421 vectors of :mod:`skytorch.eclipse.solar` (apparent geocentric
positions minus the observer's position). Maximum eclipse is the minimum of ``sigma``
(grid every 6 min over +-5 h around greatest eclipse, then golden section); the contacts
are the roots of ``sigma = s + m`` (C1, C4, penumbral ``k``) and ``sigma = |m - s|`` (C2,
C3, umbral ``k``) on each side of maximum, by batched bisection. Contacts are geometric:
they are reported whatever the Sun's altitude (the altitudes say whether they are
visible). Obscuration is the fraction of the Sun's disc area covered at maximum, from the
exact lens area of :func:`skytorch.eclipse.sun_visible_fraction` (uniform disc).
Refraction of the contact altitudes (optional) uses Saemundsson's formula (Meeus 1998,
eq. 16.4, 1010 hPa and 10 degC).

References
----------
1. Espenak, F., Meeus, J. 2006, NASA/TP-2006-214141 (definitions, k values).
2. Meeus, J. 1998, "Astronomical Algorithms", 2nd ed., ch. 16 (refraction), ch. 54.
"""

from __future__ import annotations

import numpy as np
import torch
import xarray as xr

from skytorch._validate import refuse_gradient
from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.refraction import apparent_altitude, horizon_dip
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable
from skytorch.eclipse.circumstances import _parse_one
from skytorch.eclipse.occlusion import sun_visible_fraction
from skytorch.eclipse.solar import (
    _GRID_STEP_S,
    _N_NARROW_NODES,
    _NARROW_HALF_S,
    _SPAN_S,
    LOCAL_CONTACTS,
    MOON_RADIUS_PENUMBRAL,
    MOON_RADIUS_UMBRAL,
    _local_maximum_and_contacts,
    _observer_itrs,
    _state,
    _SunMoon,
    _to_times,
    _up,
    solar_eclipses,
)
from skytorch.ephemeris import check_observer, parse_times

__all__ = ["LOCAL_CONTACTS", "solar_eclipse_local"]


def _refracted(altitude_deg: torch.Tensor, height_m: torch.Tensor, atmosphere) -> torch.Tensor:
    """Apparent altitude [deg] of the Sun's centre at true ``altitude_deg``, seen from ``height_m``.

    Ray-traced through ``atmosphere`` (the standard one,
    :meth:`skytorch.atmosphere.Atmosphere.earth`,
    :func:`skytorch.atmosphere.refraction.apparent_altitude`) down to the apparent horizon
    of an elevated observer; a Sun below the lowest visible true altitude
    (:func:`skytorch.atmosphere.refraction.horizon_dip`) is hidden by the ground and keeps
    its geometric altitude. NaN stays NaN.
    """
    true = torch.deg2rad(altitude_deg)
    height = torch.broadcast_to(torch.clamp(height_m, min=0.0), true.shape)
    lowest = horizon_dip(atmosphere, height)["true_altitude_rad"]
    seen = torch.isfinite(true) & (true >= lowest)
    apparent = torch.full_like(true, torch.nan)
    if bool(seen.any()):
        apparent[seen] = apparent_altitude(atmosphere, true[seen], height[seen],
                                           ground="raise")
    return torch.where(seen, torch.rad2deg(apparent), altitude_deg)


_SPECS = {
    "maximum_time": VariableSpec("", "time of maximum eclipse (UTC)",
                                 "Instant of minimum topocentric Sun-Moon separation."),
    "magnitude": VariableSpec("1", "eclipse magnitude at maximum",
                              "(s + m - sigma) / (2 s): fraction of the Sun's diameter "
                              "covered (penumbral k; negative when the discs do not "
                              "touch)."),
    "obscuration": VariableSpec("1", "obscuration at maximum",
                                "Fraction of the Sun's disc area covered by the Moon "
                                "(uniform disc, penumbral k)."),
    "kind": VariableSpec("1", "local kind", "none, partial, annular or total: the geometric "
                         "circumstances, whether or not the Sun is up (see visible)."),
    "visible": VariableSpec("1", "eclipse above the horizon",
                            "True where the Sun's centre is above the apparent horizon "
                            "(refraction through the standard atmosphere and the dip of an "
                            "elevated observer's horizon, horizon_dip) at C1, maximum or C4; "
                            "the geometric circumstances of the other observers happen "
                            "below their horizon."),
    "central_duration": VariableSpec("s", "duration of totality or annularity",
                                     "C3 - C2; NaN where the phase does not occur."),
    "moon_sun_ratio": VariableSpec("1", "Moon/Sun apparent diameter ratio at maximum",
                                   "m / s with the umbral k."),
}
_CONTACT_TEXT = {"c1": "first contact (partial phase begins)",
                 "c2": "second contact (totality or annularity begins)",
                 "c3": "third contact (totality or annularity ends)",
                 "c4": "fourth contact (partial phase ends)"}
for _name, _text in _CONTACT_TEXT.items():
    _SPECS[_name] = VariableSpec("", f"contact {_name.upper()} (UTC)",
                                 f"Time of {_text}, UTC; NaT when it does not occur.")
for _name in (*LOCAL_CONTACTS, "maximum"):
    _SPECS[f"sun_altitude_{_name}"] = VariableSpec(
        "degree", f"Sun altitude at {_name}",
        f"Topocentric altitude of the Sun's centre at {_name} (refracted when refraction "
        "is requested); NaN when the contact does not occur.", "solar_elevation_angle")


def _find_eclipse(time_or_date) -> np.datetime64:
    """Greatest eclipse (UTC) of the solar eclipse nearest ``time_or_date`` within 2 days."""
    when = _parse_one("time_or_date", time_or_date, parse_times)
    window = np.timedelta64(2, "D")
    try:
        found = solar_eclipses(when - window, when + window)
    except ValueError as error:
        raise ValueError(f"time_or_date: {error}") from None
    if found.sizes["eclipse"] == 0:
        raise ValueError(f"time_or_date: no solar eclipse within 2 days of {when}")
    times = found.time.values
    return times[np.argmin(np.abs(times - when))]


def solar_eclipse_local(time_or_date, lat_deg, lon_deg, elevation_m=0.0,
                        refraction: bool = False) -> xr.Dataset:
    """Local circumstances of the solar eclipse nearest ``time_or_date``, batched.

    Parameters
    ----------
    time_or_date : str, datetime or datetime64
        A UTC time or date within 2 days of the eclipse's greatest eclipse.
    lat_deg, lon_deg : float or array_like (*obs)
        Geodetic (WGS84) latitude in [-90, 90] and east longitude in [-180, 360) [degree].
    elevation_m : float or array_like (*obs)
        Height above the ellipsoid [m], in [-500, 1e5].
    refraction : bool
        Refract the Sun altitudes (ray-traced through the standard atmosphere from the
        observer's height, to an elevated observer's apparent horizon; a Sun hidden by the
        ground keeps its geometric altitude; the contacts stay geometric).

    Returns
    -------
    xarray.Dataset
        Over dimensions ``obs_0 ...`` of the observers' broadcast shape: ``c1`` .. ``c4``
        (UTC, NaT when absent), ``maximum_time`` (UTC: the minimum separation, for every
        observer), ``magnitude``, ``obscuration``, ``moon_sun_ratio``, ``kind`` (geometric),
        ``central_duration`` [s], ``visible`` (the Sun up at C1, maximum or C4),
        ``sun_altitude_<contact>`` [degree]; attribute ``greatest_eclipse``. The
        circumstances are geometric: an observer on the night side gets its contacts and
        kind with ``visible`` false.

    Raises
    ------
    TypeError, ValueError
        Bad time, no eclipse within 2 days, or observer coordinates out of range.

    Examples
    --------
    >>> ds = solar_eclipse_local("2024-04-08", 32.7767, -96.797)  # Dallas
    >>> str(ds.kind.values), int(ds.central_duration)
    ('total', 231)
    """
    refuse_gradient("solar_eclipse_local", lat_deg=lat_deg, lon_deg=lon_deg,
                    elevation_m=elevation_m)
    if not isinstance(refraction, bool):
        raise TypeError(f"refraction must be a bool; got {type(refraction).__name__}")
    lat, lon, height = check_observer(lat_deg, lon_deg, elevation_m)
    shape = lat.shape
    greatest = _find_eclipse(time_or_date)
    geometry = _SunMoon(np.array([greatest]), _NARROW_HALF_S, _N_NARROW_NODES)
    points = _observer_itrs(lat, lon, height).reshape(1, -1, 3).to(torch.float64)
    centre = torch.zeros(1, dtype=torch.float64)
    found = _local_maximum_and_contacts(geometry, centre, points)
    s, m_pen, m_umb, sigma, to_sun = _state(geometry, found["maximum"], points)
    magnitude = (s + m_pen - sigma) / (2.0 * s)
    obscuration = 1.0 - sun_visible_fraction(s, m_pen, sigma, limb_darkening=0.0)
    up = _up(torch.deg2rad(lat), torch.deg2rad(lon)).reshape(1, -1, 3).to(torch.float64)
    altitudes = {}
    for name in (*LOCAL_CONTACTS, "maximum"):
        seconds = found[name]
        sun_dir = _state(geometry, torch.nan_to_num(seconds), points)[4]
        alt = torch.rad2deg(torch.asin((up * sun_dir).sum(-1) / torch.linalg.vector_norm(
            sun_dir, dim=-1)))
        altitudes[f"sun_altitude_{name}"] = torch.where(torch.isnan(seconds), torch.nan, alt)
    # some of the eclipse seen: the Sun above the (refracted, dipped) horizon at C1,
    # maximum or C4
    # the standard atmosphere (U.S. 1976 molecules, turbidity 2) refracts
    atmosphere = Atmosphere.earth()
    lowest = torch.rad2deg(horizon_dip(atmosphere, torch.clamp(
        height.reshape(1, -1).to(torch.float64), min=0.0))["true_altitude_rad"])
    visible = torch.zeros_like(found["c1"], dtype=torch.bool)
    for name in ("c1", "maximum", "c4"):
        visible |= altitudes[f"sun_altitude_{name}"] >= lowest
    if refraction:
        altitudes = {name: _refracted(alt, height.reshape(1, -1).to(torch.float64), atmosphere)
                     for name, alt in altitudes.items()}
    visible &= ~torch.isnan(found["c1"])
    central = ~torch.isnan(found["c2"])
    kind = np.where(central.numpy(), np.where((m_umb > s).numpy(), "total", "annular"),
                    np.where(~torch.isnan(found["c1"]).numpy(), "partial", "none"))
    dims = tuple(f"obs_{i}" for i in range(len(shape)))

    def out(value):
        if isinstance(value, torch.Tensor):
            value = value.detach()
            return value.reshape(shape)
        return np.asarray(value).reshape(shape)

    values = {name: _to_times(geometry.centres, found[name]) for name in LOCAL_CONTACTS}
    values["maximum_time"] = _to_times(geometry.centres, found["maximum"])
    values.update(magnitude=magnitude, obscuration=torch.where(
        torch.isnan(found["c1"]), 0.0, obscuration), moon_sun_ratio=m_umb / s,
        kind=kind.astype(str), central_duration=found["c3"] - found["c2"], visible=visible,
        **altitudes)
    data_vars = {name: variable(dims, out(value), _SPECS[name]) for name, value in values.items()}
    coords = {dim: coordinate(dim, np.arange(size), VariableSpec(
        "1", f"observer index {i}", "Index of the observer along this dimension."))
        for i, (dim, size) in enumerate(zip(dims, shape, strict=False))}
    return build_dataset(
        data_vars, coords, title="Solar eclipse local circumstances",
        references=["Espenak, F., Meeus, J. 2006, Five Millennium Canon of Solar Eclipses, "
                    "NASA/TP-2006-214141",
                    "Meeus, J. 1998, Astronomical Algorithms, 2nd ed., ch. 16, 54"],
        parameters={"greatest_eclipse": str(greatest), "refraction": refraction,
                    "moon_radius_umbral": MOON_RADIUS_UMBRAL,
                    "moon_radius_penumbral": MOON_RADIUS_PENUMBRAL,
                    "grid_step_s": _GRID_STEP_S, "search_half_width_s": _SPAN_S},
        greatest_eclipse=str(greatest),
    )
