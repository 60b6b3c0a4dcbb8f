"""Dataset builders for the Moon: geometry and photometry over time, disc images.

Positions come from :mod:`skytorch.ephemeris` (skyfield with DE421); every number is then
computed by the tensor functions of :mod:`skytorch.moon`.

References
----------
1. Meeus, J. 1998, *Astronomical Algorithms*, 2nd ed., Willmann-Bell, ch. 14, 48, 53.
2. Krisciunas, K., Schaefer, B. E. 1991, PASP 103, 1033, doi:10.1086/132921.
"""

from __future__ import annotations

import math

import numpy as np
import torch
import xarray as xr

from skytorch._angles import wrap_to_turn
from skytorch.constants import ASTRONOMICAL_UNIT_M, DEGREE, MEAN_EARTH_MOON_DISTANCE_M
from skytorch.dataset import VariableSpec, build_dataset, coordinate, time_coordinate, variable
from skytorch.moon import geometry as _geometry
from skytorch.moon.brightness import magnitude
from skytorch.moon.disc import disc_image

__all__ = ["moon_disc_image", "moon_disc_images", "moon_geometry"]

_REFERENCES = [
    "Meeus, J. 1998, Astronomical Algorithms, 2nd ed., Willmann-Bell, ch. 14, 48, 53",
    "Krisciunas, K., Schaefer, B. E. 1991, PASP 103, 1033, doi:10.1086/132921",
    "Hapke, B. 2012, Theory of Reflectance and Emittance Spectroscopy, 2nd ed., "
    "doi:10.1017/CBO9781139025683",
    "Muller, T., Engel, J., Dollner, J. 2012, Proc. VMV, doi:10.2312/PE/VMV/VMV12/055-062",
]

_SPECS = {
    "phase_angle": VariableSpec("degree", "lunar phase angle",
                                "Sun-Moon-observer angle (geocentric without an observer); "
                                "0 at full Moon."),
    "illuminated_fraction": VariableSpec("1", "illuminated fraction of the lunar disc",
                                         "k = (1 + cos i)/2 (Meeus eq. 48.1)."),
    "bright_limb_angle": VariableSpec("degree", "position angle of the bright limb",
                                      "Position angle of the midpoint of the illuminated limb, "
                                      "from the north point of the disc through east "
                                      "(Meeus eq. 48.5), geocentric."),
    "libration_longitude": VariableSpec("degree", "libration in longitude",
                                        "Total libration l = l' + l'' (optical, Meeus eq. "
                                        "53.1, plus physical, Meeus ch. 53), geocentric: "
                                        "selenographic longitude of the sub-Earth point."),
    "libration_latitude": VariableSpec("degree", "libration in latitude",
                                       "Total libration b = b' + b'' (optical plus physical, "
                                       "Meeus ch. 53), geocentric: selenographic latitude of "
                                       "the sub-Earth point."),
    "optical_libration_longitude": VariableSpec(
        "degree", "optical libration in longitude",
        "Optical libration l' (Meeus eq. 53.1), geocentric."),
    "optical_libration_latitude": VariableSpec(
        "degree", "optical libration in latitude",
        "Optical libration b' (Meeus eq. 53.1), geocentric."),
    "axis_position_angle": VariableSpec("degree", "position angle of the lunar axis",
                                        "Position angle of the northern end of the Moon's "
                                        "rotation axis, from north through east (Meeus ch. 53, "
                                        "with physical libration), geocentric."),
    "apparent_diameter": VariableSpec("degree", "apparent angular diameter of the Moon",
                                      "2 asin(R_moon / d) with d the observer-Moon distance."),
    "magnitude": VariableSpec("mag", "V magnitude of the Moon",
                              "Disc-integrated Johnson V magnitude above the atmosphere from "
                              "the Hapke reflectance law, solar spectrum and actual distances "
                              "(earthshine included), at the observer-Moon distance; the "
                              "uneclipsed Moon: the Earth's shadow is not applied "
                              "(skytorch.eclipse.lunar_eclipse gives the eclipsed Moon)."),
    "distance": VariableSpec("m", "observer-Moon distance",
                             "Distance from the observer (the Earth's centre without one) to "
                             "the Moon's centre."),
    "sun_distance": VariableSpec("m", "Moon-Sun distance",
                                 "Distance from the Moon's centre to the Sun's centre."),
    "parallactic_angle": VariableSpec("degree", "parallactic angle of the Moon",
                                      "Angle at the Moon from the north celestial pole to the "
                                      "zenith, positive west (Meeus eq. 14.1), topocentric."),
}


def moon_geometry(times, lat_deg=None, lon_deg=None, elevation_m=None) -> xr.Dataset:
    """Phase, illumination, bright limb, libration, size and magnitude of the Moon.

    Parameters
    ----------
    times : str, datetime, datetime64 or sequence of them
        UTC times (see :func:`skytorch.ephemeris.parse_times`).
    lat_deg, lon_deg : float, optional
        Observer's geodetic latitude and longitude [degree], both or neither (one
        observer); with them the phase angle, illuminated fraction, magnitude and apparent
        diameter are topocentric and the parallactic angle is added (bright limb and
        librations stay geocentric).
    elevation_m : float, optional
        Observer's height above the WGS84 ellipsoid [m] (default 0; not without an
        observer).

    Returns
    -------
    xarray.Dataset
        Dimension ``time``; variables ``phase_angle``, ``illuminated_fraction``,
        ``bright_limb_angle``, ``libration_longitude``, ``libration_latitude`` (optical
        plus physical), ``optical_libration_longitude``, ``optical_libration_latitude``,
        ``axis_position_angle``, ``apparent_diameter``, ``magnitude``, ``distance``,
        ``sun_distance`` (+ ``parallactic_angle`` with an observer).
    """
    from skyfield.api import wgs84
    from skyfield.nutationlib import iau2000b_radians, mean_obliquity

    from skytorch.ephemeris import (
        load_ephemeris,
        one_observer,
        parse_times,
        skyfield_time,
        sun_moon_vectors,
    )

    observer = one_observer("moon_geometry", lat_deg, lon_deg, elevation_m)
    if observer is not None:
        lat_deg, lon_deg, elevation_m = observer
    else:
        lat_deg = lon_deg = None
        elevation_m = 0.0
    values = parse_times(times)
    t = skyfield_time(values)
    vectors = sun_moon_vectors(values)
    sun, moon = vectors["sun_tod_m"], vectors["moon_tod_m"]
    phase = _geometry.phase_angle(sun, moon)
    sun_ra, sun_dec = _radec(sun)
    moon_ra, moon_dec = _radec(moon)
    chi = _geometry.bright_limb_position_angle(sun_ra, sun_dec, moon_ra, moon_dec)

    # ecliptic of date: rotate the true-equator vectors by the true obliquity
    dpsi, deps = (torch.as_tensor(np.atleast_1d(x), dtype=torch.float64)
                  for x in iau2000b_radians(t))
    epsilon = torch.as_tensor(np.atleast_1d(mean_obliquity(t.tdb)),
                              dtype=torch.float64) / 3600.0 * DEGREE + deps
    x, y, z = moon.unbind(-1)
    y_ecl = y * torch.cos(epsilon) + z * torch.sin(epsilon)
    z_ecl = -y * torch.sin(epsilon) + z * torch.cos(epsilon)
    lam = torch.atan2(y_ecl, x)
    beta = torch.atan2(z_ecl, torch.sqrt(x * x + y_ecl * y_ecl))
    centuries = (torch.as_tensor(np.atleast_1d(t.tt), dtype=torch.float64) - 2451545.0) / 36525
    optical_lon, optical_lat = _geometry.optical_libration(lam, beta, centuries, dpsi)
    lib_lon, lib_lat = _geometry.libration(lam, beta, centuries, dpsi)
    axis_pa = _geometry.axis_position_angle(moon_ra, lib_lat, centuries, epsilon, dpsi)

    moon_distance = moon.norm(dim=-1)
    observer = None
    parameters = {"elevation_m": float(elevation_m)}
    if lat_deg is not None and lon_deg is not None:
        site = wgs84.latlon(float(lat_deg), float(lon_deg), elevation_m=float(elevation_m))
        # topocentric phase angle and distance (up to 0.95° and 1.7 % from geocentric)
        observer = torch.as_tensor(np.ascontiguousarray(site.at(t).position.m.T),
                                   dtype=torch.float64)
        sun_g, moon_g = vectors["sun_gcrs_m"], vectors["moon_gcrs_m"]
        phase = _geometry.phase_angle(sun_g, moon_g, observer)
        moon_distance = (moon_g - observer).norm(dim=-1)
        ephemeris = load_ephemeris()
        apparent = (ephemeris["earth"] + site).at(t).observe(ephemeris["moon"]).apparent()
        hour_angle, dec, _ = apparent.hadec()
        q = _geometry.parallactic_angle(
            torch.as_tensor(np.atleast_1d(hour_angle.radians), dtype=torch.float64),
            torch.as_tensor(np.atleast_1d(dec.radians), dtype=torch.float64),
            torch.tensor(float(lat_deg) * DEGREE, dtype=torch.float64))
        parameters.update(lat_deg=float(lat_deg), lon_deg=float(lon_deg))
    data = {
        "phase_angle": phase / DEGREE,
        "illuminated_fraction": _geometry.illuminated_fraction(phase),
        "bright_limb_angle": chi / DEGREE,
        "libration_longitude": lib_lon / DEGREE,
        "libration_latitude": lib_lat / DEGREE,
        "optical_libration_longitude": optical_lon / DEGREE,
        "optical_libration_latitude": optical_lat / DEGREE,
        "axis_position_angle": axis_pa / DEGREE,
        "magnitude": magnitude(phase, distance_m=moon_distance,
                               sun_distance_m=(sun - moon).norm(dim=-1)),
    }
    if observer is not None:
        data["parallactic_angle"] = q / DEGREE
    data["apparent_diameter"] = _geometry.apparent_diameter(moon_distance) / DEGREE
    data["distance"] = moon_distance
    data["sun_distance"] = (sun - moon).norm(dim=-1)
    return build_dataset(
        {name: variable(("time",), value, _SPECS[name]) for name, value in data.items()},
        {"time": time_coordinate(values)},
        title="Geometry and brightness of the Moon",
        references=_REFERENCES, parameters=parameters)


def _radec(vector: torch.Tensor):
    x, y, z = vector.unbind(-1)
    ra = wrap_to_turn(torch.atan2(y, x), 2.0 * math.pi)
    dec = torch.atan2(z, torch.sqrt(x * x + y * y))
    return ra, dec


def _disc_dataset(image: torch.Tensor, leading: tuple[str, ...], wl: torch.Tensor,
                  n_pixels: int, coords: dict, parameters: dict) -> xr.Dataset:
    centres = (np.arange(n_pixels) + 0.5) * (2.0 / n_pixels) - 1.0
    position = "{} on the lunar disc in units of the lunar radius ({})"
    return build_dataset(
        {"radiance": variable(leading + ("y", "x", "wavelength"), image, VariableSpec(
            "W m-2 sr-1 nm-1", "spectral radiance of the lunar disc",
            "Sunlight (and earthshine) reflected by the Moon (Hapke law, Muller albedo "
            "colour), above the Earth's atmosphere; 0 outside the disc. North up (y), "
            "west to the right (x)."))},
        {**coords,
         "y": coordinate("y", centres, VariableSpec("1", "y", position.format("y", "north"))),
         "x": coordinate("x", centres, VariableSpec("1", "x", position.format("x", "west"))),
         "wavelength": coordinate("wavelength", wl, VariableSpec("nm", "wavelength",
                                                                 "vacuum wavelength"))},
        title="Image of the lunar disc", references=_REFERENCES, parameters=parameters)


def _wavelengths(wavelength_nm) -> torch.Tensor:
    return torch.tensor([680.0, 550.0, 440.0] if wavelength_nm is None else wavelength_nm,
                        dtype=torch.float64)


def moon_disc_image(phase_angle_deg: float, bright_limb_angle_deg: float = 270.0,
                    n_pixels: int = 128, wavelength_nm=None, *,
                    sun_distance_m=ASTRONOMICAL_UNIT_M, distance_m=MEAN_EARTH_MOON_DISTANCE_M,
                    earthshine: bool = True, model: str = "hapke2012",
                    parameters="helfenstein1987") -> xr.Dataset:
    """Spectral radiance image of the lunar disc as a Dataset (Müller et al. 2012, Fig. 1).

    Parameters
    ----------
    phase_angle_deg, bright_limb_angle_deg : float
        Phase angle and position angle of the bright limb [degree].
    n_pixels : int
        Pixels across the lunar diameter.
    wavelength_nm : sequence of float, optional
        Wavelengths [nm]; default (680, 550, 440).
    sun_distance_m, distance_m, earthshine, model, parameters
        As in :func:`skytorch.moon.disc.disc_radiance` ([m], [m]).

    Returns
    -------
    xarray.Dataset
        ``radiance`` (y, x, wavelength) [W m-2 sr-1 nm-1]; x west and y north in lunar radii.
    """
    wl = _wavelengths(wavelength_nm)
    image = disc_image(torch.tensor(phase_angle_deg * DEGREE, dtype=torch.float64),
                       torch.tensor(bright_limb_angle_deg * DEGREE, dtype=torch.float64),
                       n_pixels=n_pixels, wavelength_nm=wl, sun_distance_m=sun_distance_m,
                       distance_m=distance_m, earthshine=earthshine, model=model,
                       parameters=parameters)
    return _disc_dataset(image, (), wl, n_pixels, {},
                         {"phase_angle_deg": float(phase_angle_deg),
                          "bright_limb_angle_deg": float(bright_limb_angle_deg),
                          "n_pixels": int(n_pixels)})


def moon_disc_images(geometry: xr.Dataset, n_pixels: int = 64,
                     wavelength_nm=None) -> xr.Dataset:
    """Disc images for every time of a :func:`moon_geometry` Dataset.

    Parameters
    ----------
    geometry : xarray.Dataset
        From :func:`moon_geometry` (``phase_angle``, ``bright_limb_angle``, ``distance``,
        ``sun_distance`` over ``time``).
    n_pixels : int
        Pixels across the lunar diameter.
    wavelength_nm : sequence of float, optional
        Wavelengths [nm]; default (680, 550, 440).

    Returns
    -------
    xarray.Dataset
        ``radiance`` (time, y, x, wavelength) [W m-2 sr-1 nm-1] with the actual Moon–Sun
        and Earth–Moon distances (earthshine included), north up, west to the right.
    """
    wl = _wavelengths(wavelength_nm)

    def tensor(name):
        return torch.as_tensor(np.asarray(geometry[name].values, dtype=float))

    image = disc_image(tensor("phase_angle") * DEGREE, tensor("bright_limb_angle") * DEGREE,
                       n_pixels=n_pixels, wavelength_nm=wl,
                       sun_distance_m=tensor("sun_distance"),
                       distance_m=tensor("distance"))
    return _disc_dataset(image, ("time",), wl, n_pixels,
                         {"time": geometry["time"].variable.copy()},
                         {"n_pixels": int(n_pixels)})
