"""Astronomers' units of sky brightness.

* Luminance L [cd m^-2] and V-band surface brightness m [mag arcsec^-2] are related by
  ``L = 10.8e4 · 10^(−0.4 m)`` (Falchi et al. 2016, Supplementary Materials).
* 1 nanolambert (nL) = 1e-9 L, with 1 lambert = 10^4/π cd m^-2 (Garstang 1986 quotes sky
  brightness in nL).
* The artificial-to-natural ratio divides artificial luminance by the natural zenith sky
  luminance, 22.0 mag arcsec^-2 V by default (Falchi et al. 2016).
* Bortle (2001) classes 1–9 from the total (natural + artificial) zenith brightness; the
  Bortle scale is descriptive (naked-eye limiting magnitude, Milky Way, zodiacal light),
  the mag arcsec^-2 boundaries used here are the approximate correspondence in common use
  (e.g. Wikipedia "Bortle scale"): 21.75, 21.6, 21.3, 20.4, 19.3, 18.5, 18.0, 17.5.

References
----------
1. Falchi, F. et al. 2016, "The new world atlas of artificial night sky brightness",
   Sci. Adv. 2, e1600377, doi:10.1126/sciadv.1600377.
2. Bortle, J. E. 2001, "Introducing the Bortle Dark-Sky Scale", Sky & Telescope 101(2),
   126.
3. Garstang, R. H. 1986, PASP 98, 364, doi:10.1086/131768.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from skytorch._validate import as_tensor, check_finite, check_range
from skytorch.constants import (
    CANDELA_PER_M2_AT_ZERO_MAG_ARCSEC2,
    NATURAL_MAG_RANGE,
    NATURAL_ZENITH_SKY_MAG_ARCSEC2,
)

__all__ = [
    "BORTLE_LIMITS_MAG_ARCSEC2",
    "CANDELA_PER_M2_PER_NANOLAMBERT",
    "artificial_to_natural_ratio",
    "bortle_class",
    "luminance_to_mag_arcsec2",
    "luminance_to_nanolambert",
    "mag_arcsec2_to_luminance",
    "nanolambert_to_luminance",
    "naked_eye_limiting_magnitude",
    "natural_luminance",
    "total_mag_arcsec2",
    "visible_star_count",
]

#: 1 nL = 1e-9 lambert = 1e-9 · 10^4/π cd m^-2
CANDELA_PER_M2_PER_NANOLAMBERT = 1e-9 * 1e4 / math.pi
#: lower brightness limits [mag arcsec^-2] of Bortle classes 1..8 (class 9 below the last)
BORTLE_LIMITS_MAG_ARCSEC2 = (21.75, 21.6, 21.3, 20.4, 19.3, 18.5, 18.0, 17.5)


def luminance_to_mag_arcsec2(luminance_cd_m2) -> torch.Tensor:
    """V-band surface brightness [mag arcsec^-2] of a luminance [cd m^-2] (> 0).

    >>> round(float(luminance_to_mag_arcsec2(mag_arcsec2_to_luminance(22.0))), 6)
    22.0
    """
    luminance = check_range("luminance_cd_m2", luminance_cd_m2, 0.0, low_inclusive=False,
                            unit=" cd/m^2")
    return -2.5 * torch.log10(luminance / CANDELA_PER_M2_AT_ZERO_MAG_ARCSEC2)


def mag_arcsec2_to_luminance(mag_arcsec2) -> torch.Tensor:
    """Luminance [cd m^-2] of a V-band surface brightness [mag arcsec^-2]."""
    m = check_finite("mag_arcsec2", mag_arcsec2)
    return CANDELA_PER_M2_AT_ZERO_MAG_ARCSEC2 * torch.pow(10.0, -0.4 * m)


def luminance_to_nanolambert(luminance_cd_m2) -> torch.Tensor:
    """Luminance in nanolamberts [nL]."""
    return check_finite("luminance_cd_m2", luminance_cd_m2) / CANDELA_PER_M2_PER_NANOLAMBERT


def nanolambert_to_luminance(nanolambert) -> torch.Tensor:
    """Luminance [cd m^-2] of a brightness in nanolamberts."""
    return check_finite("nanolambert", nanolambert) * CANDELA_PER_M2_PER_NANOLAMBERT


def natural_luminance(natural_mag_arcsec2: float = NATURAL_ZENITH_SKY_MAG_ARCSEC2):
    """Natural zenith sky luminance [cd m^-2] (22.0 mag arcsec^-2: 1.71e-4 cd m^-2).

    ``natural_mag_arcsec2`` [V mag arcsec^-2] must lie in
    :data:`skytorch.constants.NATURAL_MAG_RANGE` (14–26).
    """
    return mag_arcsec2_to_luminance(check_range("natural_mag_arcsec2", natural_mag_arcsec2,
                                                *NATURAL_MAG_RANGE, unit=" mag arcsec-2"))


def artificial_to_natural_ratio(luminance_cd_m2,
                                natural_mag_arcsec2: float = NATURAL_ZENITH_SKY_MAG_ARCSEC2):
    """Artificial luminance divided by the natural zenith luminance [1]."""
    luminance = check_finite("luminance_cd_m2", luminance_cd_m2)
    return luminance / natural_luminance(natural_mag_arcsec2).to(luminance.dtype)


def total_mag_arcsec2(artificial_luminance_cd_m2,
                      natural_mag_arcsec2: float = NATURAL_ZENITH_SKY_MAG_ARCSEC2):
    """Surface brightness of natural plus artificial light [mag arcsec^-2]."""
    luminance = check_range("artificial_luminance_cd_m2", artificial_luminance_cd_m2, 0.0)
    natural = natural_luminance(natural_mag_arcsec2).to(luminance.dtype)
    return luminance_to_mag_arcsec2(luminance + natural)


def bortle_class(mag_arcsec2) -> torch.Tensor:
    """Bortle class (1 darkest … 9 inner city) of a total zenith brightness.

    Parameters
    ----------
    mag_arcsec2 : array_like (...)
        Total (natural + artificial) V-band zenith brightness [mag arcsec^-2].

    Returns
    -------
    Tensor (...) of int64

    Examples
    --------
    >>> bortle_class([22.0, 21.0, 17.0]).tolist()
    [1, 4, 9]
    """
    m = as_tensor("mag_arcsec2", mag_arcsec2)
    check_finite("mag_arcsec2", m)
    limits = torch.tensor(BORTLE_LIMITS_MAG_ARCSEC2, dtype=m.dtype)
    # number of limits the sky is brighter (smaller m) than, plus one
    return 1 + (m[..., None] < limits).sum(dim=-1)



def naked_eye_limiting_magnitude(mag_arcsec2) -> torch.Tensor:
    """Naked-eye limiting V magnitude against a sky of ``mag_arcsec2`` [mag].

    Schaefer's (1990) threshold model as implemented by
    :func:`skytorch.stars.visibility.limiting_magnitude`.
    """
    from skytorch.stars.visibility import limiting_magnitude

    return limiting_magnitude(mag_arcsec2)


def visible_star_count(limiting_magnitude_mag, *, hemisphere: bool = True) -> torch.Tensor:
    """Count the catalogue stars brighter than a limiting magnitude.

    Counts Hipparcos stars (:func:`skytorch.stars.bright_stars`, V ≤ 8) brighter than the
    limit; with ``hemisphere`` half the celestial sphere's count (one observer's sky,
    ignoring extinction near the horizon and the stars' actual positions).

    Parameters
    ----------
    limiting_magnitude_mag : array_like (...)
        Limiting V magnitude [mag] (e.g. of the zenith).

    Returns
    -------
    Tensor (...)
    """
    from skytorch.stars import bright_stars

    limit = check_range("limiting_magnitude_mag", limiting_magnitude_mag, -30.0, 8.0,
                        unit=" mag")
    vmag = torch.as_tensor(np.sort(bright_stars(8.0)["vmag"].values), dtype=limit.dtype)
    count = torch.searchsorted(vmag, limit.reshape(-1).contiguous(), right=True).reshape(
        limit.shape).to(limit.dtype)
    return 0.5 * count if hemisphere else count
