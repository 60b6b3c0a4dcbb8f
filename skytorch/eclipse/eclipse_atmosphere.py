r"""The Earth's atmosphere and clouds on the date of a lunar eclipse.

:func:`eclipse_atmosphere` builds the :class:`~skytorch.atmosphere.Atmosphere` through which
the sunlight reaching the Moon in the umbra passes on a given date; :func:`eclipse_shadow`
adds the clouds and returns the :class:`~skytorch.eclipse.shadow.Shadow`. Ingredients:

* **stratospheric sulfate aerosol**: the global, annual mean optical depth at 550 nm of
  the eclipse year from ``data/stratospheric_aod.csv`` (readings of Sato et al. 1993 and
  GloSSAC, Thomason et al. 2018, with post-eruption values for El Chichón 1982, Pinatubo
  1991, Calbuco 2015 and Hunga Tonga 2022; about ±30 % in volcanic years, ±0.002 in
  quiescent ones), as the Atmosphere's Gaussian sulfate layer (peak 20 km, σ 3 km);
* **tropospheric aerosol**: a global annual mean optical depth at 550 nm of 0.12
  (Kinne et al. 2013, the MAC-v1 climatology: 0.12 globally) with the Preetham Ångström
  exponent 1.3 and the 1.2 km scale height;
* **ozone**: a global mean column of 300 DU (WMO 2018 ozone assessment: the 1964–1980
  global mean about 306 DU, 2014–2017 about 2 % lower);
* **clouds** (:func:`eclipse_shadow` only): a cloud deck with tops at 5 km covering
  a fraction 0.66 of the limb (ISCCP: global cloud amount 66 %, Rossow & Schiffer 1999;
  the mean cloud-top height of the ISCCP/CALIPSO climatologies is 5–6 km, Stubenrauch
  et al. 2013). The rays whose lowest point is below the tops pass with weight
  ``1 - cloud_fraction``.

The split: the :class:`~skytorch.atmosphere.Atmosphere` holds what extinguishes the light
along a ray (molecules, aerosols, ozone, gases), the :class:`~skytorch.eclipse.shadow.Shadow`
holds what blocks rays by their lowest point (ground, terrain, cloud tops:
``cloud_top_altitude_m``, ``cloud_fraction``, ``terrain_height_m``), because a cloud is an
opaque boundary of the ring integral, not an extinction coefficient.

Everything is a global mean: the terminator crosses all latitudes and the limb average is
a global one to first order; the seasonal and latitudinal structure is not modelled.
Nothing here is fitted to eclipse observations.

References
----------
1. Sato, M., Hansen, J. E., McCormick, M. P., Pollack, J. B. 1993, J. Geophys. Res. 98,
   22987, doi:10.1029/93JD02553.
2. Thomason, L. W. et al. 2018, Earth Syst. Sci. Data 10, 469,
   doi:10.5194/essd-10-469-2018.
3. Kinne, S. et al. 2013, MAC-v1: A new global aerosol climatology for climate studies,
   J. Adv. Model. Earth Syst. 5, 704, doi:10.1002/jame.20035.
4. Rossow, W. B., Schiffer, R. A. 1999, Advances in understanding clouds from ISCCP,
   Bull. Am. Meteorol. Soc. 80, 2261, doi:10.1175/1520-0477(1999)080<2261:AIUCFI>2.0.CO;2.
5. Stubenrauch, C. J. et al. 2013, Assessment of global cloud datasets from satellites,
   Bull. Am. Meteorol. Soc. 94, 1031, doi:10.1175/BAMS-D-12-00117.1.
6. WMO 2018, Scientific Assessment of Ozone Depletion: 2018, Global Ozone Research and
   Monitoring Project Report 58, ch. 3.

Examples
--------
>>> from skytorch.eclipse import eclipse_atmosphere, stratospheric_aod
>>> round(stratospheric_aod("1992-12-09"), 3), round(stratospheric_aod("2004-10-28"), 3)
(0.11, 0.005)
>>> atm = eclipse_atmosphere("2015-09-28")
>>> round(float(atm.stratospheric_aerosol_optical_depth), 3), float(atm.ozone_du)
(0.008, 300.0)
"""

from __future__ import annotations

import csv
from functools import lru_cache

import numpy as np

from skytorch._data import data_path
from skytorch._validate import check_range
from skytorch.atmosphere import Atmosphere
from skytorch.eclipse.circumstances import _parse_one
from skytorch.eclipse.shadow import Shadow
from skytorch.ephemeris import parse_times

__all__ = [
    "CLOUD_FRACTION",
    "CLOUD_TOP_ALTITUDE_M",
    "OZONE_DU",
    "STRATOSPHERIC_AOD_FILE",
    "TROPOSPHERIC_AOD_550",
    "eclipse_atmosphere",
    "eclipse_shadow",
    "stratospheric_aod",
]

#: the shipped record of annual global stratospheric optical depths
STRATOSPHERIC_AOD_FILE = "stratospheric_aod.csv"
#: global annual mean tropospheric aerosol optical depth at 550 nm (Kinne et al. 2013)
TROPOSPHERIC_AOD_550 = 0.12
#: global mean total ozone column [DU] (WMO 2018)
OZONE_DU = 300.0
#: cloud-top altitude of the deck blocking the lowest limb rays [m] (ISCCP/CALIPSO mean)
CLOUD_TOP_ALTITUDE_M = 5000.0
#: global cloud amount (ISCCP, Rossow & Schiffer 1999)
CLOUD_FRACTION = 0.66


@lru_cache(maxsize=1)
def _record() -> tuple[np.ndarray, np.ndarray]:
    """Years and optical depths of ``data/stratospheric_aod.csv`` (sorted, read once)."""
    with open(data_path(STRATOSPHERIC_AOD_FILE), newline="", encoding="utf-8") as handle:
        rows = [row for row in csv.DictReader(line for line in handle
                                              if not line.startswith("#"))]
    years = np.array([int(row["year"]) for row in rows])
    aod = np.array([float(row["aod_550"]) for row in rows])
    if np.any(np.diff(years) != 1):
        raise ValueError(f"{STRATOSPHERIC_AOD_FILE}: years must be consecutive")
    return years, aod


def stratospheric_aod(date) -> float:
    """Global annual mean stratospheric aerosol optical depth at 550 nm of ``date``'s year.

    Parameters
    ----------
    date : str, datetime or datetime64
        A UTC date or time in a year of the record (1979–2023).

    Returns
    -------
    float
        The vertical optical depth [1] of the year (no interpolation between years).

    Raises
    ------
    ValueError
        A date outside the record's years (naming ``date``).
    """
    moment = _parse_one("date", date, parse_times)
    year = int(str(np.datetime_as_string(moment, "Y")))
    years, aod = _record()
    if not years[0] <= year <= years[-1]:
        raise ValueError(f"date must be in the years {years[0]}..{years[-1]} of "
                         f"{STRATOSPHERIC_AOD_FILE}; got {np.datetime_as_string(moment, 'D')}")
    return float(aod[year - years[0]])


def eclipse_atmosphere(date, *, tropospheric_aod=TROPOSPHERIC_AOD_550, ozone_du=OZONE_DU,
                       stratospheric_aod_550=None) -> Atmosphere:
    """Build the atmosphere of ``date``: climatological troposphere, the year's stratosphere.

    Parameters
    ----------
    date : str, datetime or datetime64
        Date of the eclipse (UTC), in 1979–2023 unless ``stratospheric_aod_550`` is given.
    tropospheric_aod : float or Tensor
        Vertical tropospheric aerosol optical depth at 550 nm [1], in [0, 100]; default
        the global mean 0.12.
    ozone_du : float or Tensor
        Ozone column [DU]; default the global mean 300 DU.
    stratospheric_aod_550 : float or Tensor, optional
        Vertical optical depth at 550 nm of the stratospheric sulfate layer [1], in
        [0, 100]; default :func:`stratospheric_aod` of the date's year.

    Returns
    -------
    skytorch.atmosphere.Atmosphere
        ``Atmosphere.earth`` (U.S. 1976 molecules, 1.4 cm water) with these optical depths;
        tensors given with ``requires_grad`` keep their graph. Named
        ``"eclipse YYYY-MM-DD"``.
    """
    moment = _parse_one("date", date, parse_times)
    if stratospheric_aod_550 is None:
        stratospheric_aod_550 = stratospheric_aod(moment)
    stratospheric_aod_550 = check_range("stratospheric_aod_550", stratospheric_aod_550,
                                        0.0, 100.0)
    return Atmosphere.earth(aerosol_optical_depth=tropospheric_aod, ozone_du=ozone_du,
                            stratospheric_aerosol_optical_depth=stratospheric_aod_550,
                            name=f"eclipse {np.datetime_as_string(moment, 'D')}")


def eclipse_shadow(date, *, cloud_top_altitude_m=CLOUD_TOP_ALTITUDE_M,
                   cloud_fraction=CLOUD_FRACTION, atmosphere=None, **shadow_options):
    """Build the Earth's shadow of ``date``: :func:`eclipse_atmosphere` and a cloud deck.

    Parameters
    ----------
    date : str, datetime or datetime64
        Date of the eclipse (UTC).
    cloud_top_altitude_m : float or Tensor ()
        Cloud-top altitude [m] below which rays pass with weight ``1 - cloud_fraction``;
        default 5 km.
    cloud_fraction : float
        Fraction of the limb covered by clouds, in [0, 1]; default 0.66.
    atmosphere : Atmosphere, optional
        Default ``eclipse_atmosphere(date)``.
    **shadow_options
        Other keywords of :class:`~skytorch.eclipse.shadow.Shadow` (an unknown one raises
        TypeError there).

    Returns
    -------
    skytorch.eclipse.shadow.Shadow
    """
    if atmosphere is None:
        atmosphere = eclipse_atmosphere(date)
    return Shadow.earth(atmosphere, cloud_top_altitude_m=cloud_top_altitude_m,
                        cloud_fraction=cloud_fraction, **shadow_options)
