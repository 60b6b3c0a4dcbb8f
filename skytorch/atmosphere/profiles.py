"""Vertical density profiles of atmospheric constituents (dimensionless shapes).

Each profile returns the number density relative to a reference value as a function of
altitude above the planet's surface. Profiles are pure functions on tensors, broadcast
their arguments by torch rules and are differentiable.

Available shapes (``PROFILES``):

``"exponential"``
    :math:`\\rho(h) = \\exp(-h / H)` with scale height :math:`H`.
``"us1976"``
    Density ratio :math:`\\rho(h)/\\rho(0)` of the U.S. Standard Atmosphere 1976,
    computed from its defining temperature layers (ref. 1) by the hydrostatic equation
    up to 84.852 km geopotential altitude, continued isothermally above.
``"tent"``
    Ozone-like layer :math:`\\max(0, 1 - |h - h_c| / w)` peaking at :math:`h_c` with
    half-width :math:`w` (ref. 2: 10–40 km, peak 25 km).

References
----------
1. NOAA, NASA, USAF 1976, *U.S. Standard Atmosphere, 1976*, NOAA-S/T 76-1562,
   Washington D.C.
2. Bruneton, E. 2017, "A qualitative and quantitative evaluation of 8 clear sky models",
   IEEE TVCG 24, 2641, doi:10.1109/TVCG.2016.2622272.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere.profiles import exponential, tent
>>> exponential(torch.tensor([0.0, 8000.0]), 8000.0)
tensor([1.0000, 0.3679])
>>> tent(torch.tensor([25e3, 40e3]), 25e3, 15e3)
tensor([1., 0.])
"""

from __future__ import annotations

import functools
import math

import torch

from skytorch._validate import as_tensor

__all__ = ["PROFILES", "US1976_KINK_ALTITUDES_M", "US1976_SCALE_HEIGHT_M", "exponential",
           "tent", "us1976"]

#: model keywords for the molecular profile
PROFILES = ("exponential", "us1976")

# --- U.S. Standard Atmosphere 1976 defining layers (ref. 1, Table 4) -------------------------
_US1976_EARTH_RADIUS_M = 6_356_766.0  #: radius used for geopotential altitude
_US1976_G0 = 9.80665  #: [m s^-2]
_US1976_MOLAR_MASS = 0.0289644  #: [kg mol^-1]
_US1976_GAS_CONSTANT = 8.31432  #: [J mol^-1 K^-1] (value of the standard)
_US1976_BASE_HEIGHT_M = (0.0, 11_000.0, 20_000.0, 32_000.0, 47_000.0, 51_000.0, 71_000.0,
                         84_852.0)
_US1976_LAPSE_K_PER_M = (-6.5e-3, 0.0, 1.0e-3, 2.8e-3, 0.0, -2.8e-3, -2.0e-3, 0.0)
_US1976_T0 = 288.15

#: scale height used to place integration levels for the US 1976 profile [m]
US1976_SCALE_HEIGHT_M = 8_000.0


def _us1976_layers() -> tuple[list[float], list[float], list[float]]:
    """Base temperature [K] and log density ratio at each layer base (ref. 1)."""
    g_over_r = _US1976_G0 * _US1976_MOLAR_MASS / _US1976_GAS_CONSTANT
    temperatures = [_US1976_T0]
    log_pressures = [0.0]
    for i in range(len(_US1976_BASE_HEIGHT_M) - 1):
        dh = _US1976_BASE_HEIGHT_M[i + 1] - _US1976_BASE_HEIGHT_M[i]
        lapse = _US1976_LAPSE_K_PER_M[i]
        t_base = temperatures[-1]
        t_top = t_base + lapse * dh
        if lapse == 0.0:
            dlogp = -g_over_r * dh / t_base
        else:
            dlogp = -g_over_r / lapse * math.log(t_top / t_base)
        temperatures.append(t_top)
        log_pressures.append(log_pressures[-1] + dlogp)
    log_density = [lp - math.log(t / _US1976_T0)
                   for lp, t in zip(log_pressures, temperatures, strict=True)]
    return temperatures, log_pressures, log_density


_US1976_TEMPERATURE, _US1976_LOG_PRESSURE, _ = _us1976_layers()

#: geometric altitudes of the US 1976 layer bases above the ground, z = r0 H / (r0 - H)
#: [m]: the lapse rate, hence the density gradient, jumps there (kinks of the profile)
US1976_KINK_ALTITUDES_M = tuple(_US1976_EARTH_RADIUS_M * h / (_US1976_EARTH_RADIUS_M - h)
                                for h in _US1976_BASE_HEIGHT_M[1:])


def exponential(altitude_m, scale_height_m) -> torch.Tensor:
    """Exponential profile :math:`\\exp(-h/H)`.

    Parameters
    ----------
    altitude_m : Tensor (...)
        Altitude above the surface [m].
    scale_height_m : float or Tensor (...)
        Scale height :math:`H` [m]; broadcasts with ``altitude_m``.

    Returns
    -------
    Tensor (...)
        Relative density [1].
    """
    altitude_m = as_tensor("altitude_m", altitude_m)
    return torch.exp(altitude_m * (-1.0 / scale_height_m))


def tent(altitude_m, center_m, half_width_m) -> torch.Tensor:
    """Tent (triangular) layer :math:`\\max(0, 1 - |h - h_c|/w)`.

    Parameters
    ----------
    altitude_m : Tensor (...)
        Altitude [m].
    center_m : float or Tensor (...)
        Altitude of the peak :math:`h_c` [m].
    half_width_m : float or Tensor (...)
        Half width :math:`w` [m]; the layer spans :math:`h_c \\pm w` and its integral
        over altitude is :math:`w`.

    Returns
    -------
    Tensor (...)
        Relative density [1], 1 at the peak.
    """
    altitude_m = as_tensor("altitude_m", altitude_m)
    return torch.clamp(1.0 - torch.abs(altitude_m - center_m) / half_width_m, min=0.0)


def us1976(altitude_m) -> torch.Tensor:
    """Density ratio :math:`\\rho(z)/\\rho(0)` of the U.S. Standard Atmosphere 1976.

    Parameters
    ----------
    altitude_m : Tensor (...)
        Geometric altitude [m] (converted to geopotential altitude internally).

    Returns
    -------
    Tensor (...)
        Density relative to sea level [1]. Below the surface the lowest layer is
        continued; above 84.852 km geopotential altitude the layer is isothermal at
        186.87 K (the standard's molecular-weight change is neglected).

    Notes
    -----
    In a layer with base :math:`H_b`, temperature :math:`T_b` and lapse rate
    :math:`L \\ne 0`: :math:`T = T_b + L (H - H_b)`,
    :math:`p/p_b = (T/T_b)^{-g_0 M / (R L)}`; with :math:`L = 0`:
    :math:`p/p_b = \\exp(-g_0 M (H - H_b)/(R T_b))`. Density ratio
    :math:`(p/p_0)(T_0/T)`. Geopotential altitude :math:`H = r_0 z/(r_0 + z)`.
    """
    z = as_tensor("altitude_m", altitude_m)
    geopotential = _US1976_EARTH_RADIUS_M * z / (_US1976_EARTH_RADIUS_M + z)
    g_over_r = _US1976_G0 * _US1976_MOLAR_MASS / _US1976_GAS_CONSTANT
    # the constants of each point's layer, gathered once (the lowest layer is continued
    # below the ground, the highest above 84.852 km)
    tables = _us1976_tables(geopotential.dtype, geopotential.device)
    layer = torch.clamp(torch.bucketize(geopotential.detach(), tables["base"][1:], right=True),
                        0, len(_US1976_BASE_HEIGHT_M) - 1)
    base, lapse, t_base, log_p_base = (tables[key][layer] for key in
                                       ("base", "lapse", "temperature", "log_pressure"))
    dh = geopotential - base
    isothermal = lapse == 0.0
    safe_lapse = torch.where(isothermal, torch.ones_like(lapse), lapse)
    temperature = torch.clamp(t_base + lapse * dh, min=1.0)
    log_p = log_p_base - g_over_r * torch.where(
        isothermal, dh / t_base, torch.log(temperature / t_base) / safe_lapse)
    return torch.exp(log_p - torch.log(temperature / _US1976_T0))


@functools.lru_cache(maxsize=8)
def _us1976_tables(dtype: torch.dtype, device: torch.device) -> dict[str, torch.Tensor]:
    """Layer bases [m], lapse rates [K/m], base temperatures [K] and log pressure ratios."""
    values = {"base": _US1976_BASE_HEIGHT_M, "lapse": _US1976_LAPSE_K_PER_M,
              "temperature": _US1976_TEMPERATURE, "log_pressure": _US1976_LOG_PRESSURE}
    return {key: torch.tensor(value, dtype=dtype, device=device)
            for key, value in values.items()}
