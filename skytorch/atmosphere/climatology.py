r"""Climatological model atmospheres: the AFGL 1986 profiles as soundings.

Anderson et al. (1986) tabulated six model atmospheres from 0 to 120 km (50 levels) that
radiative-transfer codes (MODTRAN, libRadtran, LOWTRAN) use as latitude and season
climatologies: ``tropical`` (15° N, annual), ``midlatitude_summer`` and
``midlatitude_winter`` (45° N, July and January), ``subarctic_summer`` and
``subarctic_winter`` (60° N, July and January) and ``us_standard`` (the U.S. Standard
Atmosphere 1976). :func:`afgl_profile` returns one as a sounding for
``Atmosphere.earth(profile=...)`` (pressure, temperature, ozone and water vapour per
level); :func:`afgl_columns` the ozone and water-vapour columns an ``Atmosphere`` needs.

The tropopause is what differs most for limb paths: near 17 km and 195 K in the tropics,
9–11 km and 217–225 K at 60°; the warmer tropical troposphere holds more air above 10 km
(250 hPa at 10.5 km against 200 hPa at 60° in winter).

References
----------
1. Anderson, G. P., Clough, S. A., Kneizys, F. X., Chetwynd, J. H., Shettle, E. P. 1986,
   AFGL Atmospheric Constituent Profiles (0–120 km), AFGL-TR-86-0110, Environmental
   Research Papers 954, Air Force Geophysics Laboratory, Hanscom AFB.
2. Berk, A. et al., MODTRAN 6 user's manual, "Model atmospheres", Table 1 (column
   amounts of the six atmospheres).

Examples
--------
>>> from skytorch.atmosphere.climatology import afgl_columns, afgl_profile
>>> profile = afgl_profile("tropical")
>>> float(profile.temperature.sel(level=16).values), float(profile.altitude[16].values)
(197.0, 16000.0)
>>> columns = afgl_columns("subarctic_winter")
>>> round(columns["ozone_du"]), round(columns["precipitable_water_cm"], 2)
(377, 0.42)
"""

from __future__ import annotations

import csv
from functools import lru_cache

import numpy as np
import xarray as xr

from skytorch._data import data_path
from skytorch._validate import check_choice

__all__ = ["AFGL_FILE", "AFGL_PROFILES", "afgl_columns", "afgl_profile"]

#: the shipped tables (``data/afgl1986_profiles.csv``)
AFGL_FILE = "afgl1986_profiles.csv"
#: the model atmospheres of Anderson et al. 1986, Tables 1a-1f
AFGL_PROFILES = ("tropical", "midlatitude_summer", "midlatitude_winter", "subarctic_summer",
                 "subarctic_winter", "us_standard")

_BOLTZMANN = 1.380649e-23  # [J K^-1]
_AVOGADRO = 6.02214076e23  # [mol^-1]
_DOBSON_PER_M2 = 2.6867e20  # molecules m^-2 per Dobson unit
_WATER_MOLAR_MASS = 0.018015  # [kg mol^-1]
_WATER_DENSITY = 1000.0  # [kg m^-3] liquid, for precipitable water


@lru_cache(maxsize=1)
def _tables() -> dict[str, dict[str, np.ndarray]]:
    """Read the shipped file once: profile -> column -> (level,) float64 (read-only)."""
    rows: dict[str, list[list[float]]] = {}
    with data_path(AFGL_FILE).open(newline="") as handle:
        reader = csv.reader(line for line in handle if not line.startswith("#"))
        header = next(reader)
        for record in reader:
            rows.setdefault(record[0], []).append([float(value) for value in record[1:]])
    tables = {}
    for name, values in rows.items():
        array = np.array(values, dtype=np.float64)
        array.setflags(write=False)
        tables[name] = {column: array[:, k] for k, column in enumerate(header[1:])}
    return tables


def afgl_profile(name: str) -> xr.Dataset:
    """Return one AFGL 1986 model atmosphere as a sounding.

    Parameters
    ----------
    name : str
        One of :data:`AFGL_PROFILES`.

    Returns
    -------
    xarray.Dataset
        Over ``level`` (50, 0–120 km): ``altitude`` [m], ``pressure`` [Pa],
        ``temperature`` [K], ``ozone_number_density`` [m-3] and ``h2o_vmr`` [1], the form
        ``Atmosphere.earth(profile=...)`` takes
        (:func:`skytorch.atmosphere.profiles.check_sounding`).
    """
    name = check_choice("name", name, AFGL_PROFILES)
    table = _tables()[name]
    pressure = table["pressure_hpa"] * 100.0
    temperature = table["temperature_k"]
    air = pressure / (_BOLTZMANN * temperature)
    level = np.arange(pressure.size)
    return xr.Dataset(
        {"pressure": ("level", pressure, {"units": "Pa", "long_name": "pressure"}),
         "temperature": ("level", temperature.copy(), {"units": "K"}),
         "ozone_number_density": ("level", table["o3_ppmv"] * 1e-6 * air,
                                  {"units": "m-3", "long_name": "ozone number density"}),
         "h2o_vmr": ("level", table["h2o_ppmv"] * 1e-6,
                     {"units": "1", "long_name": "water vapour volume mixing ratio"})},
        coords={"level": level,
                "altitude": ("level", table["altitude_km"] * 1000.0, {"units": "m"})},
        attrs={"title": f"AFGL 1986 model atmosphere: {name}",
               "references": "Anderson et al. 1986, AFGL-TR-86-0110, Tables 1a-1f"})


def afgl_columns(name: str) -> dict[str, float]:
    """Vertical columns of ozone [DU] and water vapour [cm precipitable] of a profile.

    Trapezoids in altitude of the number densities at the 50 levels (those
    ``Atmosphere.earth(profile=...)`` interpolates linearly).

    Parameters
    ----------
    name : str
        One of :data:`AFGL_PROFILES`.

    Returns
    -------
    dict
        ``ozone_du`` [DU] and ``precipitable_water_cm`` [cm].
    """
    profile = afgl_profile(name)
    altitude = profile.altitude.values
    air = profile.pressure.values / (_BOLTZMANN * profile.temperature.values)
    ozone = np.trapezoid(profile.ozone_number_density.values, altitude) / _DOBSON_PER_M2
    water = np.trapezoid(profile.h2o_vmr.values * air, altitude)  # molecules m^-2
    water_cm = water / _AVOGADRO * _WATER_MOLAR_MASS / _WATER_DENSITY * 100.0
    return {"ozone_du": float(ozone), "precipitable_water_cm": float(water_cm)}
