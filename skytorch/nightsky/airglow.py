r"""Airglow: emission of a thin layer near 90 km, its zenith level and solar-cycle change.

* Geometry: a thin uniformly emitting layer at height :math:`h` is crossed at zenith
  distance :math:`z` over a path longer than the vertical one by the van Rhijn (1921)
  factor :math:`V(z) = [1 - ((R + h_o)/(R + h))^2 \sin^2 z]^{-1/2}`.
* Level: the ESO sky model (Noll et al. 2012) gives a zenith V = 21.83 mag arcsec⁻² for
  Paranal at new Moon, 130 sfu, zodiacal light of (135°, 90°) included (SkyCalc 1.4.3
  broad-band output); taking that zodiacal light (Leinert et al. 1998 Table 17, 77 units,
  V = 23.3) away leaves the airglow (with the model's scattered starlight and lower
  atmosphere, a few per cent):
  :data:`AIRGLOW_ZENITH_V_130SFU` = 22.14 mag arcsec⁻², as observed (extinction included).
* Solar cycle: the airglow continuum of the ESO model scales as
  :math:`a + b\,S` with the monthly mean 10.7 cm solar flux :math:`S` [sfu], (a, b) =
  (0.2068, 0.006139 sfu⁻¹) for the 543 nm continuum (Noll et al. 2012, §3.4; the
  coefficients of the model's ``airglow_cont.dat``, 1 at 129 sfu, the mean of its data);
  here it scales all of the V-band airglow (the 557.7 nm line's own law is not used).

References
----------
1. van Rhijn, P. J. 1921, Publ. Astron. Lab. Groningen 31, 1.
2. Noll, S. et al. 2012, A&A 543, A92, doi:10.1051/0004-6361/201219040.
3. Krisciunas, K. 1997, PASP 109, 1181, doi:10.1086/133993 (V sky brightness over a
   sunspot cycle, correlated with the 10.7 cm flux).
4. Patat, F. 2008, A&A 481, 575, doi:10.1051/0004-6361:20079279.

Examples
--------
>>> round(float(airglow_zenith_mag(130.0)), 2)
22.14
"""

from __future__ import annotations

import math

import torch

from skytorch._validate import check_finite, check_range

__all__ = [
    "AIRGLOW_HEIGHT_M",
    "AIRGLOW_SOLAR_COEFFICIENTS",
    "AIRGLOW_ZENITH_V_130SFU",
    "airglow_solar_factor",
    "airglow_zenith_mag",
    "layer_path_factor",
    "van_rhijn",
]

#: height of the emitting layer [m] (OI 557.7 nm and the continuum peak near 90–97 km)
AIRGLOW_HEIGHT_M = 90_000.0
#: ESO sky-model solar-activity law of the 543 nm continuum: (a, b [1/sfu]) in a + b S
AIRGLOW_SOLAR_COEFFICIENTS = (0.2068, 0.006139)
#: total zenith V of the ESO sky model at Paranal, new Moon, 130 sfu [mag arcsec^-2]
SKYCALC_ZENITH_V_130SFU = 21.83
#: zodiacal light in that SkyCalc output, (135°, 90°): Table 17's 77 units [mag arcsec^-2]
SKYCALC_ZODIACAL_V = 23.33
#: the airglow's share of it, observed at the zenith [V mag arcsec^-2]
AIRGLOW_ZENITH_V_130SFU = -2.5 * math.log10(10.0 ** (-0.4 * SKYCALC_ZENITH_V_130SFU)
                                            - 10.0 ** (-0.4 * SKYCALC_ZODIACAL_V))
#: solar flux range of the law [sfu] (the cycle runs from ~65 to ~250)
SOLAR_FLUX_RANGE_SFU = (50.0, 400.0)


def airglow_solar_factor(solar_flux_sfu) -> torch.Tensor:
    """Airglow relative to its level at 130 sfu, (a + b S) / (a + 130 b).

    Parameters
    ----------
    solar_flux_sfu : array_like
        ``(...)`` monthly mean 10.7 cm solar radio flux [sfu = 1e-22 W m^-2 Hz^-1], in
        [50, 400].

    Returns
    -------
    torch.Tensor
        ``(...)`` factor (0.63 at 70 sfu, 1.42 at 200 sfu).
    """
    flux = check_range("solar_flux_sfu", solar_flux_sfu, *SOLAR_FLUX_RANGE_SFU, unit=" sfu")
    a, b = AIRGLOW_SOLAR_COEFFICIENTS
    return (a + b * flux) / (a + b * 130.0)


def airglow_zenith_mag(solar_flux_sfu=130.0) -> torch.Tensor:
    """Observed zenith V surface brightness of the airglow [mag arcsec^-2].

    Parameters
    ----------
    solar_flux_sfu : array_like
        ``(...)`` 10.7 cm solar flux [sfu], in [50, 400].

    Returns
    -------
    torch.Tensor
        ``(...)`` :data:`AIRGLOW_ZENITH_V_130SFU` − 2.5 log10 of
        :func:`airglow_solar_factor` (22.64 at 70 sfu, 21.76 at 200 sfu).
    """
    factor = airglow_solar_factor(solar_flux_sfu)
    return AIRGLOW_ZENITH_V_130SFU - 2.5 * torch.log10(factor)


def van_rhijn(zenith_rad, *, layer_height_m: float = AIRGLOW_HEIGHT_M,
              planet_radius_m: float = 6_371_000.0,
              observer_height_m: float = 0.0) -> torch.Tensor:
    r"""Path through a thin emitting layer relative to the vertical (van Rhijn 1921).

    Parameters
    ----------
    zenith_rad : array_like
        ``(...)`` zenith distance of the line of sight [rad], in [0, π/2] (at the
        observer; views below the horizon are the caller's to mask).
    layer_height_m, planet_radius_m, observer_height_m : float
        Layer height, planet radius and observer height [m], observer below the layer.

    Returns
    -------
    torch.Tensor
        ``(...)`` :math:`[1 - ((R + h_o)/(R + h))^2 \sin^2 z]^{-1/2}`: 1 at the zenith,
        6.01 at the horizon for 90 km on the Earth.

    Examples
    --------
    >>> import math
    >>> round(float(van_rhijn(math.pi / 2)), 2)
    6.01
    """
    zenith = check_finite("zenith_rad", zenith_rad)
    # the heights in float64: their ratio is 1 - 1e-2, cast to the zenith's dtype once formed
    planet_radius_m = check_range("planet_radius_m", planet_radius_m, 0.0,
                                  low_inclusive=False, unit=" m", dtype=torch.float64)
    layer_height_m = check_range("layer_height_m", layer_height_m, 0.0,
                                 low_inclusive=False, unit=" m", dtype=torch.float64)
    observer_height_m = check_finite("observer_height_m", observer_height_m,
                                     dtype=torch.float64)
    if not bool(((observer_height_m >= 0.0) & (observer_height_m < layer_height_m)).all()):
        raise ValueError(f"observer_height_m must be in [0, layer_height_m = "
                         f"{float(layer_height_m.max())} m); got "
                         f"{observer_height_m.tolist()} m")
    ratio = ((planet_radius_m + observer_height_m)
             / (planet_radius_m + layer_height_m)).to(zenith.dtype)
    sine = torch.sin(zenith)
    return torch.rsqrt(1.0 - ratio * ratio * sine * sine)


def layer_path_factor(cos_zenith, altitude_m, *, layer_height_m: float = AIRGLOW_HEIGHT_M,
                      planet_radius_m: float = 6_371_000.0) -> torch.Tensor:
    r"""Path through the thin layer, relative to the vertical, of rays from any altitude.

    The van Rhijn factor :math:`[1 - ((R + h)/(R + h_L))^2 (1 - \mu^2)]^{-1/2}` of the ray
    that reaches altitude ``h`` from local zenith cosine ``mu`` (of either sign: a ray from
    slightly below the local horizontal has crossed the layer on its way down to the
    point), and 0 at points at or above the layer (its light reaches them from below,
    where the air is negligible). The incoming airglow of
    :func:`skytorch.nightsky.scattered_light.scattered_diffuse_radiance`, per unit zenith
    emission.

    Parameters
    ----------
    cos_zenith : Tensor (...)
        Local zenith cosine of the incoming ray's direction (towards the layer) [1].
    altitude_m : Tensor (...)
        Altitude of the point [m].
    layer_height_m, planet_radius_m : float
        Height of the layer and the planet's radius [m].

    Returns
    -------
    Tensor (...)
        Path factor [1] (1 at the zenith below the layer).
    """
    layer = planet_radius_m + layer_height_m
    radius = planet_radius_m + altitude_m
    sin2 = (radius / layer) ** 2 * (1.0 - cos_zenith * cos_zenith)
    below = (altitude_m < layer_height_m) & (sin2 < 1.0)
    return torch.where(below, 1.0 / torch.sqrt(torch.where(below, 1.0 - sin2, 1.0)), 0.0)
