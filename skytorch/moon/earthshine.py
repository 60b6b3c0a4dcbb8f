"""Earthshine: sunlight reflected by the Earth onto the Moon.

Two descriptions, compared in docs/moon.md:

``earthshine_muller2012``
    Müller et al.'s (2012, eq. 4) polynomial in the lunar phase angle φ [rad]::

        E_em(φ) = −0.0061 φ³ + 0.0289 φ² − 0.0105 sin φ

    a relative intensity in their rendering units (it enters eq. 3 beside the sunlit term
    k_λ a F, with colour β_e = (0.88, 0.96, 1.00)). They quote a maximum difference of 3 %
    to van de Hulst's (1980) formula. It is slightly *negative* for φ < 0.37 rad (21°).

``earthshine_irradiance_ratio`` (physical)
    The Earth seen from the Moon is at phase angle ≈ π − φ. Treating it as a Lambert
    sphere of Bond albedo A (geometric albedo p = 2A/3), the irradiance it sheds on the
    Moon, relative to the solar irradiance there, is::

        E_earth / E_sun = p Φ(π − φ) (R_E / d)²,
        Φ(a) = [sin a + (π − a) cos a] / π          (Lambert sphere phase function)

    with R_E the Earth's radius and d the Earth–Moon distance. With A = 0.297 (Goode et
    al. 2001, from earthshine photometry) and d = 384 400 km this is 5.4e-5 at new Moon,
    the classic ≈ 1e-4 ratio of the ashen light to sunlight (Danjon).

References
----------
1. Müller, T., Engel, J., Döllner, J. 2012, "Single-Pass Rendering of Day and Night Sky
   Phenomena", Proc. VMV, doi:10.2312/PE/VMV/VMV12/055-062, eq. 3–4.
2. van de Hulst, H. C. 1980, *Multiple Light Scattering*, vol. 2, Academic Press.
3. Goode, P. R. et al. 2001, "Earthshine observations of the Earth's reflectance",
   Geophys. Res. Lett. 28, 1671, doi:10.1029/2000GL012580 (Bond albedo 0.297 ± 0.005).
4. Russell, H. N. 1916, "On the albedo of the planets and their satellites", ApJ 43, 173,
   doi:10.1086/142244 (Lambert-sphere phase law and the relation p = 2A/3).

Examples
--------
>>> import math, torch
>>> from skytorch.moon.earthshine import earthshine_irradiance_ratio
>>> ratio = earthshine_irradiance_ratio(torch.tensor(math.pi))  # new Moon: full Earth
>>> 4e-5 < float(ratio) < 7e-5
True
"""

from __future__ import annotations

import math

import torch

from skytorch._validate import as_tensor, check_broadcastable, check_range, common_dtype
from skytorch.constants import EARTH_MEAN_RADIUS_M, MEAN_EARTH_MOON_DISTANCE_M

__all__ = [
    "EARTH_BOND_ALBEDO",
    "MULLER2012_EARTHSHINE_COLOUR",
    "earth_angular_radius",
    "earthshine_irradiance_ratio",
    "earthshine_muller2012",
    "lambert_phase_function",
]

#: Earth's Bond albedo from earthshine photometry (Goode et al. 2001)
EARTH_BOND_ALBEDO = 0.297

#: Müller et al. (2012) earthshine colour beta_e at the RGB wavelengths (680, 550, 440) nm
MULLER2012_EARTHSHINE_COLOUR = (0.88, 0.96, 1.00)


def _phase(phase_angle_rad, dtype=None):
    return check_range("phase_angle_rad", as_tensor("phase_angle_rad", phase_angle_rad,
                                                    dtype=dtype), 0.0, math.pi, unit=" rad")


def earthshine_muller2012(phase_angle_rad) -> torch.Tensor:
    """Müller et al. (2012, eq. 4) earthshine intensity E_em(φ) (relative units).

    Parameters
    ----------
    phase_angle_rad : Tensor (...)
        Lunar phase angle φ in [0, π] [rad] (0 = full Moon).

    Returns
    -------
    Tensor (...)
        −0.0061 φ³ + 0.0289 φ² − 0.0105 sin φ: 0 at full Moon, 0.0961 at new Moon,
        slightly negative below φ ≈ 0.37 rad (returned as published).
    """
    phi = _phase(phase_angle_rad)
    return -0.0061 * phi**3 + 0.0289 * phi**2 - 0.0105 * torch.sin(phi)


def lambert_phase_function(phase_angle_rad) -> torch.Tensor:
    """Disc-integrated phase function of a Lambert sphere, Φ(0) = 1 (Russell 1916).

    ``Φ(a) = [sin a + (π − a) cos a] / π``; Φ(π/2) = 1/π, Φ(π) = 0.
    """
    a = _phase(phase_angle_rad)
    # rounding near a = π would give -1e-12; the phase function is non-negative
    return ((torch.sin(a) + (math.pi - a) * torch.cos(a)) / math.pi).clamp_min(0.0)


def earth_angular_radius(distance_m=MEAN_EARTH_MOON_DISTANCE_M) -> torch.Tensor:
    """Angular radius of the Earth seen from the Moon, asin(R_E / d) [rad]."""
    d = check_range("distance_m", as_tensor("distance_m", distance_m), EARTH_MEAN_RADIUS_M,
                    low_inclusive=False, unit=" m")
    return torch.asin(EARTH_MEAN_RADIUS_M / d)


def earthshine_irradiance_ratio(phase_angle_rad, *, distance_m=MEAN_EARTH_MOON_DISTANCE_M,
                                bond_albedo: float = EARTH_BOND_ALBEDO) -> torch.Tensor:
    """Irradiance of earthlight at the Moon relative to sunlight there (physical model).

    Parameters
    ----------
    phase_angle_rad : Tensor (...)
        Lunar phase angle φ in [0, π] [rad]; the Earth's phase seen from the Moon is π − φ.
    distance_m : float or Tensor (...)
        Earth–Moon distance [m], larger than the Earth's radius.
    bond_albedo : float or Tensor (...)
        Earth's Bond albedo A in [0, 1] (Lambert sphere: geometric albedo 2A/3); a tensor
        keeps its gradient.

    Returns
    -------
    Tensor (...)
        E_earth / E_sun = (2A/3) Φ(π − φ) (R_E / d)² (dimensionless).
    """
    dtype = common_dtype(phase_angle_rad, distance_m)
    phi = _phase(phase_angle_rad, dtype)
    # a tensor albedo keeps its gradient (a fit of the Earth's albedo to earthshine)
    bond_albedo = check_range("bond_albedo", bond_albedo, 0.0, 1.0, dtype=dtype)
    d = check_range("distance_m", distance_m, EARTH_MEAN_RADIUS_M, low_inclusive=False,
                    unit=" m", dtype=dtype)
    check_broadcastable(phase_angle_rad=phi, distance_m=d, bond_albedo=bond_albedo)
    ratio = (EARTH_MEAN_RADIUS_M / d) ** 2
    return (2.0 / 3.0) * bond_albedo * lambert_phase_function(math.pi - phi) * ratio
