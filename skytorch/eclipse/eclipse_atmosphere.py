r"""The Earth's atmosphere and clouds on the date of a lunar eclipse.

:func:`eclipse_atmosphere` builds the :class:`~skytorch.atmosphere.Atmosphere` through which
the sunlight reaching the Moon in the umbra passes on a given date; :func:`eclipse_shadow`
adds the clouds and returns the :class:`~skytorch.eclipse.shadow.Shadow`. Ingredients:

* **stratospheric sulfate aerosol**: the global, annual mean optical depth at 550 nm of
  the eclipse year from ``data/stratospheric_aod.csv`` (readings of Sato et al. 1993 and
  GloSSAC, Thomason et al. 2018, with post-eruption values for El Chichón 1982, Pinatubo
  1991, Calbuco 2015 and Hunga Tonga 2022; about ±30 % in volcanic years, ±0.002 in
  quiescent ones), as the Atmosphere's sulfate layer with the vertical profile of the
  LOWTRAN 7 stratospheric model whose optical depth is nearest the year's
  (:func:`stratospheric_model`: background, moderate, high or extreme volcanic; Shettle &
  Fenn 1979, ref. 10), the mean of its two seasons (the terminator crosses both
  hemispheres);
* **tropospheric aerosol**: a global annual mean optical depth at 550 nm of 0.12
  (Kinne et al. 2013, the MAC-v1 climatology: 0.12 globally) with the Preetham Ångström
  exponent 1.3 and the 1.2 km scale height;
* **ozone**: a global mean column of 300 DU (WMO 2018 ozone assessment: the 1964–1980
  global mean about 306 DU, 2014–2017 about 2 % lower);
* **clouds** (:func:`eclipse_shadow` only), by default the cloud profile of
  :func:`cloud_climatology` (``clouds="rossow1999"``): the ISCCP global cloud amounts of
  the low, middle and high classes (tops below 680 hPa, 680–440 hPa, above 440 hPa;
  Rossow & Schiffer 1999) with the tops spread evenly over each class (high tops up to
  16 km, the top of the tropical cirrus, Nazaryan et al. 2008), turned into a limb
  clear-line-of-sight probability ``(1 - f(h))^n`` whose exponent ``n`` makes the
  probability at a tangent altitude of 7 km the one measured by solar occultation (SAGE:
  successful penetrations to 7 km about 30 % of the time in the tropics, up to 60 % at
  higher latitudes, Woodbury & McCormick 1983, 1986), averaged along the terminator.
  ``clouds="deck"`` keeps the former single deck (tops 5 km, fraction 0.66, ISCCP total
  amount and the 5–6 km mean top height of Stubenrauch et al. 2013): rays whose lowest
  point is below the tops pass with weight ``1 - cloud_fraction``.

The split: the :class:`~skytorch.atmosphere.Atmosphere` holds what extinguishes the light
along a ray (molecules, aerosols, ozone, gases), the :class:`~skytorch.eclipse.shadow.Shadow`
holds what blocks rays by their lowest point (ground, terrain, cloud tops:
``cloud_cover``, or ``cloud_top_altitude_m`` and ``cloud_fraction``; ``terrain_height_m``),
because a cloud is an opaque boundary of the ring integral, not an extinction
coefficient.

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
7. Woodbury, G. E., McCormick, M. P. 1983, Global distributions of cirrus clouds
   determined from SAGE data, Geophys. Res. Lett. 10, 1180, doi:10.1029/GL010i012p01180;
   1986, Zonal and geographical distributions of cirrus clouds determined from SAGE data,
   J. Geophys. Res. 91, 2775, doi:10.1029/JD091iD02p02775.
8. Nazaryan, H., McCormick, M. P., Menzel, W. P. 2008, Global characterization of cirrus
   clouds using CALIPSO data, J. Geophys. Res. 113, D16211, doi:10.1029/2007JD009481.
9. U.S. Standard Atmosphere 1976, NOAA-S/T 76-1562 (pressure levels 680 hPa at 3.24 km,
   440 hPa at 6.51 km).
10. Shettle, E. P. & Fenn, R. W. 1979, Models for the Aerosols of the Lower Atmosphere and
    the Effects of Humidity Variations on their Optical Properties, AFGL-TR-79-0214; the
    stratospheric profiles as tabulated in LOWTRAN 7 (Kneizys, F. X. et al. 1988,
    AFGL-TR-88-0177).
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
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import torch

from skytorch._data import data_path
from skytorch._validate import as_tensor, check_choice, check_range
from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.aerosol import (
    STRATOSPHERIC_MODELS,
    STRATOSPHERIC_PROFILES,
    stratospheric_model_optical_depth,
)
from skytorch.atmosphere.climatology import afgl_columns, afgl_profile
from skytorch.atmosphere.model import AEROSOL_OPTICAL_DEPTH_RANGE
from skytorch.eclipse.circumstances import _parse_one
from skytorch.eclipse.shadow import LimbCloudCover, Shadow
from skytorch.eclipse.shadow_mixture import ShadowMixture
from skytorch.eclipse.terminator import LimbLatitudeWindow, terminator_band_shares
from skytorch.ephemeris import parse_times, sun_moon_vectors

__all__ = [
    "CLOUD_CLASS_AMOUNTS",
    "CLOUD_CLASS_TOPS_M",
    "CLOUD_FRACTION",
    "CLOUD_MODELS",
    "CLOUD_TOP_ALTITUDE_M",
    "LIMB_CLEAR_7KM",
    "SAGE_CLEAR_7KM",
    "OZONE_DU",
    "STRATOSPHERIC_AOD_FILE",
    "TERMINATOR_BAND_BOUNDARIES_DEG",
    "TERMINATOR_MODELS",
    "TROPICAL_TERMINATOR_SHARE",
    "TROPOSPHERIC_AOD_550",
    "cloud_climatology",
    "eclipse_atmosphere",
    "eclipse_shadow",
    "stratospheric_aod",
    "stratospheric_model",
    "terminator_bands",
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
#: ISCCP global cloud amounts as seen from above of the low (tops below 680 hPa),
#: middle (680-440 hPa) and high (above 440 hPa) classes [1] (Rossow & Schiffer 1999;
#: sum 0.66, the total amount)
CLOUD_CLASS_AMOUNTS = (0.27, 0.19, 0.20)
#: altitudes bounding the classes' tops [m]: ground, 680 hPa and 440 hPa in the U.S.
#: 1976 atmosphere, and 16 km, the highest tropical cirrus tops (Nazaryan et al. 2008)
CLOUD_CLASS_TOPS_M = (0.0, 3240.0, 6510.0, 16000.0)
#: SAGE solar occultations penetrating to a tangent altitude of 7 km [1]: ~0.30 in the
#: tropics, up to 0.60 at higher latitudes (Woodbury & McCormick 1983, 1986)
SAGE_CLEAR_7KM = {"tropics": 0.30, "extratropics": 0.60, "altitude_m": 7000.0}
#: latitudes separating the limb atmospheres of ``terminator="latitude_bands"`` [deg]: the
#: midpoints between the AFGL profiles' latitudes (tropical 15, mid-latitude 45, sub-arctic
#: 60 deg; Anderson et al. 1986)
TERMINATOR_BAND_BOUNDARIES_DEG = (-52.5, -30.0, 30.0, 52.5)
#: ways to describe the limb atmosphere along the terminator (:func:`eclipse_shadow`)
TERMINATOR_MODELS = ("global", "latitude_bands", "latitude_bands_mean")
#: share of the terminator's length within 25 deg of the equator (a great circle through
#: the poles: 50/180; 0.31 at a solar declination of 23.4 deg)
TROPICAL_TERMINATOR_SHARE = 0.28
#: the terminator's mean clear-line-of-sight probability at 7 km: the SAGE values weighted
#: by the tropical share of the terminator (0.516) [1]
LIMB_CLEAR_7KM = (TROPICAL_TERMINATOR_SHARE * SAGE_CLEAR_7KM["tropics"]
                  + (1.0 - TROPICAL_TERMINATOR_SHARE) * SAGE_CLEAR_7KM["extratropics"])
#: cloud models of :func:`eclipse_shadow`
CLOUD_MODELS = ("rossow1999", "deck", "none")


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


def stratospheric_model(date=None, stratospheric_aod_550=None) -> str:
    """LOWTRAN 7 stratospheric aerosol model of a date: the nearest in optical depth.

    The model of :data:`skytorch.atmosphere.aerosol.STRATOSPHERIC_MODELS` (Shettle & Fenn
    1979, ref. 10: background 0.0070, moderate volcanic 0.027, high volcanic 0.085,
    extreme volcanic 0.27 at 550 nm) whose vertical optical depth is nearest, in its
    logarithm, the record's for the date's year (:func:`stratospheric_aod`), so that the
    layer's shape is a property of the date and does not change while its optical depth is
    fitted (:func:`~skytorch.eclipse.retrieval.retrieve_atmosphere`). For a date outside
    the record, or without a date, the given ``stratospheric_aod_550`` chooses.

    Parameters
    ----------
    date : str, datetime or datetime64, optional
        Date of the eclipse (UTC).
    stratospheric_aod_550 : float or Tensor (), optional
        Vertical optical depth at 550 nm [1], in [0, 100]; used where the record has no
        value (0: the background model).

    Returns
    -------
    str
        A name of ``STRATOSPHERIC_MODELS`` (the mean of its seasons; the latitude bands of
        :func:`terminator_bands` append their season).

    Examples
    --------
    >>> stratospheric_model("1992-12-09"), stratospheric_model("2004-10-28")
    ('high_volcanic', 'background')
    """
    if stratospheric_aod_550 is not None:  # checked even where the record decides
        stratospheric_aod_550 = check_range("stratospheric_aod_550", as_tensor(
            "stratospheric_aod_550", stratospheric_aod_550).detach(), 0.0, 100.0)
    if date is not None:
        moment = _parse_one("date", date, parse_times)
        years, _ = _record()
        if years[0] <= int(str(np.datetime_as_string(moment, "Y"))) <= years[-1]:
            stratospheric_aod_550 = stratospheric_aod(moment)
    if stratospheric_aod_550 is None:
        raise ValueError("stratospheric_model needs a date in the record's years or a "
                         "stratospheric_aod_550; got neither")
    aod = float(torch.as_tensor(stratospheric_aod_550))
    if aod == 0.0:  # no layer: any shape; the quiet stratosphere's
        return STRATOSPHERIC_MODELS[0]
    return min(STRATOSPHERIC_MODELS,
               key=lambda model: abs(np.log(stratospheric_model_optical_depth(model) / aod)))


def _layer_profile(date, stratospheric_aod_550, stratospheric_profile) -> str:
    """Return the stratospheric profile asked for, or the date's model (ValueError if unknown)."""
    if stratospheric_profile is None:
        return stratospheric_model(date, stratospheric_aod_550)
    return check_choice("stratospheric_profile", stratospheric_profile,
                        STRATOSPHERIC_PROFILES)


def eclipse_atmosphere(date, *, tropospheric_aod=TROPOSPHERIC_AOD_550, ozone_du=OZONE_DU,
                       stratospheric_aod_550=None, stratospheric_profile=None) -> Atmosphere:
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
    stratospheric_profile : str, optional
        Vertical profile of the layer, a name of
        :data:`skytorch.atmosphere.aerosol.STRATOSPHERIC_PROFILES` (``"gaussian"``: the
        Atmosphere's 20 km, σ 3 km layer); default :func:`stratospheric_model` of the date.

    Returns
    -------
    skytorch.atmosphere.Atmosphere
        ``Atmosphere.earth`` (U.S. 1976 molecules, 1.4 cm water) with these optical depths;
        tensors given with ``requires_grad`` keep their graph. Named
        ``"eclipse YYYY-MM-DD"``.
    """
    moment = _parse_one("date", date, parse_times)
    # named as given here (Atmosphere.earth would name its aerosol_optical_depth)
    tropospheric_aod = check_range("tropospheric_aod", as_tensor(
        "tropospheric_aod", tropospheric_aod), *AEROSOL_OPTICAL_DEPTH_RANGE)
    if stratospheric_aod_550 is None:
        stratospheric_aod_550 = stratospheric_aod(moment)
    stratospheric_aod_550 = check_range("stratospheric_aod_550", stratospheric_aod_550,
                                        0.0, 100.0)
    profile = _layer_profile(moment, stratospheric_aod_550, stratospheric_profile)
    return Atmosphere.earth(aerosol_optical_depth=tropospheric_aod, ozone_du=ozone_du,
                            stratospheric_aerosol_optical_depth=stratospheric_aod_550,
                            stratospheric_aerosol_profile=profile,
                            name=f"eclipse {np.datetime_as_string(moment, 'D')}")


def cloud_climatology(limb_clear_7km=None, *, amounts=CLOUD_CLASS_AMOUNTS) -> LimbCloudCover:
    r"""Limb cloud profile of the global-mean cloud-top climatology (ISCCP classes, SAGE).

    The nadir cover ``f(z)`` (fraction of the area with cloud tops above ``z``) falls
    linearly within each ISCCP class, from the total amount at the ground to 0 at 16 km
    (tops spread evenly over ``CLOUD_CLASS_TOPS_M``). The limb exponent ``n`` makes
    ``(1 - f(7 km))^n`` the probability that a solar occultation reaches 7 km:

    .. math::

        n = rac{\ln P_{SAGE}(7\,km)}{\ln(1 - f(7\,km))}, \qquad
        P_{SAGE} = s\,P_{tropics} + (1 - s)\,P_{extratropics}

    with ``s`` the tropical share of the terminator (``TROPICAL_TERMINATOR_SHARE``). The
    occultation path is the eclipse ray's own geometry (a solar limb path at the
    terminator, sunrise or sunset), so the measured probability already contains the
    long limb chord and the semi-transparent cirrus that it sees as opaque.

    Parameters
    ----------
    limb_clear_7km : float or Tensor (), optional
        Clear-line-of-sight probability at 7 km [1], in (0, 1); default the terminator
        mean of Woodbury & McCormick's 0.30 (tropics) and 0.60 (higher latitudes), 0.516.
        Their range 0.30-0.60 is the uncertainty of the profile.
    amounts : sequence of 3 float or Tensor (3,)
        Low, middle and high cloud amounts [1] (sum <= 1); default ISCCP.

    Returns
    -------
    skytorch.eclipse.shadow.LimbCloudCover
        Named ``"rossow1999"``; tensors that require a gradient keep it.

    Examples
    --------
    >>> cover = cloud_climatology()
    >>> round(float(cover.limb_exponent), 2)
    3.15
    >>> import torch
    >>> [round(v, 3) for v in cover.clear_fraction(torch.tensor([0.0, 7e3, 16e3])).tolist()]
    [0.034, 0.516, 1.0]
    """
    if limb_clear_7km is None:
        limb_clear_7km = LIMB_CLEAR_7KM
    clear = check_range("limb_clear_7km", limb_clear_7km, 0.0, 1.0, low_inclusive=False,
                        high_inclusive=False, dtype=torch.float64)
    amounts = check_range("amounts", amounts, 0.0, 1.0, dtype=torch.float64)
    if amounts.shape != (3,) or float(amounts.detach().sum()) > 1.0:
        raise ValueError("amounts must be the 3 cloud amounts (low, middle, high) with a sum "
                         f"<= 1; got {amounts.detach().tolist()}")
    low, middle, high = amounts.unbind()
    zero = torch.zeros((), dtype=torch.float64)
    cover = torch.stack([low + middle + high, middle + high, high, zero])
    tops = torch.tensor(CLOUD_CLASS_TOPS_M, dtype=torch.float64)
    profile = LimbCloudCover(tops, cover, 1.0)
    at_7km = profile.cover_at(torch.tensor(SAGE_CLEAR_7KM["altitude_m"], dtype=torch.float64))
    exponent = torch.log(clear) / torch.log1p(-at_7km)
    return LimbCloudCover(tops, cover, exponent, name="rossow1999")


@dataclass(frozen=True)
class TerminatorBand:
    """One latitude band of the terminator: its share, limb atmosphere and limb clouds."""

    #: band label: its latitudes, e.g. ``"30..52.5 deg"``
    name: str
    #: AFGL 1986 model atmosphere of the band (one of
    #: :data:`~skytorch.atmosphere.climatology.AFGL_PROFILES`)
    profile: str
    #: share of the terminator's length [1]
    weight: float
    #: the band's atmosphere (AFGL temperature, pressure, ozone and water vapour; the
    #: global-mean tropospheric aerosol and the year's stratospheric layer)
    atmosphere: Atmosphere
    #: the band's limb cloud profile (SAGE tropics or extratropics at 7 km)
    cloud_cover: LimbCloudCover
    #: the band's part of the limb by position angle around the shadow's axis
    window: LimbLatitudeWindow


def _band_profiles(month: int) -> tuple[str, ...]:
    """AFGL profile of each band, south pole to north pole, for a month (1-12)."""
    north = "summer" if 4 <= month <= 9 else "winter"
    south = "winter" if north == "summer" else "summer"
    return (f"subarctic_{south}", f"midlatitude_{south}", "tropical",
            f"midlatitude_{north}", f"subarctic_{north}")


def terminator_bands(date, *, tropospheric_aod=TROPOSPHERIC_AOD_550,
                     stratospheric_aod_550=None, stratospheric_profile=None
                     ) -> tuple[TerminatorBand, ...]:
    """Limb atmospheres along the terminator of ``date``: five latitude bands.

    The terminator is cut at ``TERMINATOR_BAND_BOUNDARIES_DEG`` (30 and 52.5 deg north and
    south) into a tropical band, two mid-latitude and two polar caps; each gets the AFGL
    1986 model atmosphere of its latitude and season (April-September: summer in the
    north, winter in the south; October-March the reverse), with that profile's ozone and
    water-vapour columns (AFGL: 277-377 DU, more than the 300 DU global mean of
    :func:`eclipse_atmosphere`), the global-mean tropospheric aerosol and the year's
    stratospheric layer, and the limb cloud profile of :func:`cloud_climatology` with the
    SAGE probability of its zone (tropical band 0.30 at 7 km, the others 0.60). The share
    of each band is its share of the terminator's length at the Sun's declination
    (:func:`~skytorch.eclipse.terminator.terminator_band_shares`).

    Parameters
    ----------
    date : str, datetime or datetime64
        Date (or time) of the eclipse (UTC).
    tropospheric_aod, stratospheric_aod_550 : float or Tensor ()
        As in :func:`eclipse_atmosphere`.
    stratospheric_profile : str, optional
        As in :func:`eclipse_atmosphere`, for every band; default the date's
        :func:`stratospheric_model` in each band's season (the tropical band: the mean of
        the two seasons).

    Returns
    -------
    tuple of TerminatorBand
        South pole to north pole.

    Examples
    --------
    >>> bands = terminator_bands("2015-09-28")
    >>> [(b.profile, round(b.weight, 3)) for b in bands][:3]
    [('subarctic_winter', 0.208), ('midlatitude_winter', 0.125), ('tropical', 0.334)]
    """
    moment = _parse_one("date", date, parse_times)
    # named as given here (Atmosphere.earth would name its aerosol_optical_depth)
    tropospheric_aod = check_range("tropospheric_aod", as_tensor(
        "tropospheric_aod", tropospheric_aod), *AEROSOL_OPTICAL_DEPTH_RANGE)
    if stratospheric_aod_550 is None:
        stratospheric_aod_550 = stratospheric_aod(moment)
    sun = sun_moon_vectors(np.array([moment]), frames=("tod",))["sun_tod_m"][0]
    declination = torch.asin(sun[2] / torch.linalg.norm(sun))
    shares = terminator_band_shares(declination, TERMINATOR_BAND_BOUNDARIES_DEG)
    month = int(str(np.datetime_as_string(moment, "M"))[5:7])
    edges = (-90.0, *TERMINATOR_BAND_BOUNDARIES_DEG, 90.0)
    covers = {zone: cloud_climatology(SAGE_CLEAR_7KM[zone])
              for zone in ("tropics", "extratropics")}
    model = _layer_profile(moment, stratospheric_aod_550, stratospheric_profile)
    bands = []
    for k, profile in enumerate(_band_profiles(month)):
        columns = afgl_columns(profile)
        layer = model
        if stratospheric_profile is None and profile != "tropical":
            layer += "_spring_summer" if profile.endswith("summer") else "_fall_winter"
        atmosphere = Atmosphere.earth(
            aerosol_optical_depth=tropospheric_aod, profile=afgl_profile(profile),
            precipitable_water_cm=columns["precipitable_water_cm"],
            stratospheric_aerosol_optical_depth=stratospheric_aod_550,
            stratospheric_aerosol_profile=layer,
            name=f"eclipse {np.datetime_as_string(moment, 'D')} {profile}")
        zone = "tropics" if profile == "tropical" else "extratropics"
        window = LimbLatitudeWindow(edges[k], edges[k + 1], float(declination))
        bands.append(TerminatorBand(f"{edges[k]:g}..{edges[k + 1]:g} deg", profile,
                                    float(shares[k]), atmosphere, covers[zone], window))
    return tuple(bands)


def eclipse_shadow(date, *, clouds="rossow1999", cloud_top_altitude_m=None,  # noqa: C901 (three models, their refusals)
                   cloud_fraction=None, cloud_cover=None, atmosphere=None,
                   terminator="global", tropospheric_aod=None, stratospheric_aod_550=None,
                   stratospheric_profile=None, **shadow_options):
    """Build the Earth's shadow of ``date``: :func:`eclipse_atmosphere` and the clouds.

    Parameters
    ----------
    date : str, datetime or datetime64
        Date of the eclipse (UTC).
    terminator : {"global", "latitude_bands", "latitude_bands_mean"}
        ``"global"``: one global-mean limb atmosphere (:func:`eclipse_atmosphere`);
        ``"latitude_bands"``: a :class:`~skytorch.eclipse.shadow_mixture.ShadowMixture` of
        the five bands of :func:`terminator_bands` (AFGL profiles by latitude and season,
        SAGE clouds by zone), each on its part of the limb, so that the shadow is resolved
        in direction around the axis where the position angles are given (the lunar light
        curves give them); ``"latitude_bands_mean"``: the same bands weighted by their
        shares of the terminator, the azimuthal mean. ``atmosphere`` and ``cloud_cover``
        must be None with either.
    tropospheric_aod, stratospheric_aod_550 : float or Tensor (), optional
        Aerosol optical depths at 550 nm of :func:`eclipse_atmosphere` (global) or of
        every band (:func:`terminator_bands`); default the climatology and the year's
        record. Not with ``atmosphere`` (which has its own).
    stratospheric_profile : str, optional
        Vertical profile of the stratospheric layer (:func:`eclipse_atmosphere`,
        :func:`terminator_bands`); default the date's :func:`stratospheric_model`. Not
        with ``atmosphere``.
    clouds : {"rossow1999", "deck", "none"}
        ``"rossow1999"``: the limb cloud profile ``cloud_cover`` (default
        :func:`cloud_climatology`); ``"deck"``: one deck of ``cloud_top_altitude_m`` and
        ``cloud_fraction``; ``"none"``: no clouds.
    cloud_top_altitude_m : float or Tensor ()
        For ``"deck"``: cloud-top altitude [m] below which rays pass with weight
        ``1 - cloud_fraction``; default 5 km.
    cloud_fraction : float
        For ``"deck"``: fraction of the limb covered by clouds, in [0, 1]; default 0.66.
    cloud_cover : LimbCloudCover, optional
        For ``"rossow1999"``: the profile; default ``cloud_climatology()``.
    atmosphere : Atmosphere, optional
        Default ``eclipse_atmosphere(date)``.
    **shadow_options
        Other keywords of :class:`~skytorch.eclipse.shadow.Shadow` (an unknown one raises
        TypeError there).

    Returns
    -------
    skytorch.eclipse.shadow.Shadow or skytorch.eclipse.shadow_mixture.ShadowMixture
    """
    check_choice("clouds", clouds, CLOUD_MODELS)
    check_choice("terminator", terminator, TERMINATOR_MODELS)
    # a cloud setting of another model would be ignored: refused
    deck = sorted(name for name, value in (("cloud_top_altitude_m", cloud_top_altitude_m),
                                           ("cloud_fraction", cloud_fraction))
                  if value is not None)
    if deck and clouds != "deck":
        raise ValueError(f"{', '.join(deck)}: settings of clouds='deck', unused with "
                         f"clouds={clouds!r}")
    if cloud_cover is not None and clouds != "rossow1999":
        raise ValueError(f"cloud_cover: the profile of clouds='rossow1999', unused with "
                         f"clouds={clouds!r}")
    aerosols = {key: value for key, value in (("tropospheric_aod", tropospheric_aod),
                                              ("stratospheric_aod_550", stratospheric_aod_550),
                                              ("stratospheric_profile", stratospheric_profile))
                if value is not None}
    if aerosols and atmosphere is not None:
        raise ValueError(f"give the aerosol settings {sorted(aerosols)} or an "
                         "atmosphere, not both (the atmosphere has its own)")
    if terminator != "global":
        if atmosphere is not None or cloud_cover is not None:
            raise ValueError(f"terminator={terminator!r} builds the atmosphere and clouds of "
                             "each band: give atmosphere=None and cloud_cover=None (got "
                             f"{type(atmosphere).__name__}, {type(cloud_cover).__name__})")
        bands = terminator_bands(date, **aerosols)
        shadows = [eclipse_shadow(date, clouds=clouds, cloud_top_altitude_m=cloud_top_altitude_m,
                                  cloud_fraction=cloud_fraction, atmosphere=band.atmosphere,
                                  cloud_cover=(band.cloud_cover if clouds == "rossow1999"
                                               else None), **shadow_options)
                   for band in bands]
        windows = ([band.window for band in bands] if terminator == "latitude_bands"
                   else None)
        return ShadowMixture(shadows, [band.weight for band in bands],
                             names=[f"{band.name} {band.profile}" for band in bands],
                             limb_windows=windows)
    if atmosphere is None:
        atmosphere = eclipse_atmosphere(date, **aerosols)
    if clouds == "deck":
        return Shadow.earth(atmosphere, cloud_top_altitude_m=CLOUD_TOP_ALTITUDE_M
                            if cloud_top_altitude_m is None else cloud_top_altitude_m,
                            cloud_fraction=CLOUD_FRACTION if cloud_fraction is None
                            else cloud_fraction, **shadow_options)
    if clouds == "none":
        return Shadow.earth(atmosphere, **shadow_options)
    cover = cloud_climatology() if cloud_cover is None else cloud_cover
    return Shadow.earth(atmosphere, cloud_cover=cover, **shadow_options)
