r"""Ozone absorption: temperature-dependent cross-sections, 214–1100 nm, and the column.

Absolute values: Serdyuchenko et al. (ref. 1), measured at 223 K and 243 K, shipped as
means over 1 nm bins ``[λ - 0.5, λ + 0.5)`` of vacuum wavelength centred on each whole
nanometre from 214 to 1100 nm (:data:`OZONE_RANGE_NM`; the Hartley, Huggins, Chappuis
and Wulf bands). The resolution of :func:`ozone_cross_section` is therefore 1 nm: it
interpolates these bin means linearly in wavelength. A wavelength outside 214–1100 nm
raises ``ValueError`` naming ``wavelength_nm``, the value and the range (no
extrapolation, no clamp).

Temperature (valid :data:`OZONE_TEMPERATURE_RANGE_K` = 203–293 K): linear in :math:`T`
between the two measured temperatures; outside them the measured spectrum nearest in
temperature is scaled by the relative temperature dependence of Bogumil et al. (ref. 2;
203, 223, 243, 273, 293 K, the same 1 nm bins), itself linear in :math:`T` between its
temperatures:

.. math::

    \sigma(\lambda, T) = \sigma_S(\lambda, 223\,K)\,
    \frac{\sigma_B(\lambda, T)}{\sigma_B(\lambda, 223\,K)} \; (T < 223\,K), \qquad
    \sigma_S(\lambda, 243\,K)\,
    \frac{\sigma_B(\lambda, T)}{\sigma_B(\lambda, 243\,K)} \; (T > 243\,K).

Why: Serdyuchenko's set is the more accurate absolute scale (Bogumil's is about 5 %
higher in the Chappuis band, ref. 1), Bogumil's five temperatures span the atmosphere's;
the ratio keeps the two measured spectra exactly and is continuous at 223 and 243 K.
Where Bogumil's data are missing or noise-dominated (below 230 nm, above 1000 nm, where
its 243 and 273 K spectra are zero or negative in the source; :data:`RATIO_RANGE_NM`),
the nearest measured spectrum is used unchanged below 223 K and above 243 K (the
temperature dependence there is not known; the 300 DU optical depth above 1000 nm is
below 1e-4).

In an :class:`~skytorch.atmosphere.Atmosphere` the ozone layer has one temperature,
``ozone_temperature_k``; by default the layer-weighted mean of the U.S. Standard
Atmosphere 1976 temperature over the ozone tent (:func:`ozone_effective_temperature`:
222.9 K for the default tent 10–40 km), the effective-temperature approximation of
SMARTS (ref. 3).

References
----------
1. Serdyuchenko, A., Gorshelev, V., Weber, M., Chehade, W. & Burrows, J. P. 2014,
   "High spectral resolution ozone absorption cross-sections – Part 2: Temperature
   dependence", Atmos. Meas. Tech. 7, 625, doi:10.5194/amt-7-625-2014.
2. Bogumil, K. et al. 2003, "Measurements of molecular absorption spectra with the
   SCIAMACHY pre-flight model", J. Photochem. Photobiol. A 157, 167,
   doi:10.1016/S1010-6030(03)00062-5 (version 4.0, Chehade & Weber 2011).
3. Gueymard, C. A. 1995, "SMARTS2, a simple model of the atmospheric radiative transfer
   of sunshine", FSEC-PF-270-95 (effective ozone temperature).

Examples
--------
>>> import torch
>>> from skytorch.atmosphere.ozone import ozone_cross_section
>>> ozone_cross_section(torch.tensor([602.0]), temperature_k=223.0)
tensor([5.1666e-25])
>>> ozone_cross_section(torch.tensor([310.0, 320.0]),
...                     temperature_k=torch.tensor([[223.0], [243.0]]))
tensor([[8.6533e-24, 2.4929e-24],
        [8.8947e-24, 2.5661e-24]])
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import torch

from skytorch._data import data_path
from skytorch._validate import as_tensor, check_broadcastable, check_finite, check_range
from skytorch.atmosphere.profiles import us1976_temperature

__all__ = ["OZONE_RANGE_NM", "OZONE_REFERENCE_TEMPERATURE_K", "OZONE_TABLE",
           "OZONE_TEMPERATURE_RANGE_K", "RATIO_RANGE_NM", "ozone_cross_section",
           "ozone_effective_temperature"]

#: shipped tables (``data/``): absolute values and relative temperature dependence
OZONE_TABLE = "ozone_cross_section_serdyuchenko2014.csv"
OZONE_RATIO_TABLE = "ozone_cross_section_bogumil2003.csv"
#: wavelengths covered [nm] (1 nm bins centred on whole nanometres)
OZONE_RANGE_NM = (214.0, 1100.0)
#: temperatures covered [K] (those of Bogumil et al. 2003)
OZONE_TEMPERATURE_RANGE_K = (203.0, 293.0)
#: default temperature of :func:`ozone_cross_section` [K] (the colder measured spectrum)
OZONE_REFERENCE_TEMPERATURE_K = 223.0
#: wavelengths where Bogumil's temperature dependence is used [nm]
RATIO_RANGE_NM = (230.0, 1000.0)
#: temperature nodes of the combined table [K]
_NODES_K = (203.0, 223.0, 243.0, 273.0, 293.0)


def check_wavelength_range(wavelength_nm, range_nm, source: str, hint: str = "") -> torch.Tensor:
    """Return ``wavelength_nm`` as a finite tensor inside ``range_nm`` [nm] of a shipped table.

    ValueError naming the first wavelength outside, the range, ``source`` (what covers the
    range) and the count of offending elements, followed by ``hint``; no extrapolation.
    Shared by the ozone cross-sections and the gas tables of
    :mod:`skytorch.atmosphere.gases`.
    """
    low, high = range_nm
    wavelength = check_finite("wavelength_nm", wavelength_nm)
    with torch.no_grad():
        outside = (wavelength < low) | (wavelength > high)
        if bool(outside.any()):
            bad = float(wavelength[outside].reshape(-1)[0])
            raise ValueError(
                f"wavelength_nm must be in [{low}, {high}] nm (the range of {source}); got "
                f"{bad} nm ({int(outside.sum())} offending element(s)){hint}")
    return wavelength


def _read(name: str) -> np.ndarray:
    path = data_path(name)
    with open(path, encoding="utf-8") as handle:
        header = 0
        for line in handle:
            if not line.startswith("#"):
                break
            header += 1
    return np.loadtxt(path, delimiter=",", skiprows=header + 1)


@lru_cache(maxsize=1)
def _table() -> tuple[np.ndarray, np.ndarray]:
    """Wavelength grid (n,) [nm] and cross-sections at :data:`_NODES_K` (5, n) [m^2]."""
    serdyuchenko = _read(OZONE_TABLE)
    bogumil = _read(OZONE_RATIO_TABLE)
    grid = serdyuchenko[:, 0]
    if not (np.all(np.diff(grid) == 1.0) and grid[0] == OZONE_RANGE_NM[0]
            and grid[-1] == OZONE_RANGE_NM[1]):
        raise ValueError(f"{OZONE_TABLE} is not on the 1 nm grid {OZONE_RANGE_NM}")
    s223, s243 = serdyuchenko[:, 1], serdyuchenko[:, 2]
    ratio = np.ones((5, grid.size))
    low, high = RATIO_RANGE_NM
    rows = np.searchsorted(bogumil[:, 0], grid)
    use = (grid >= low) & (grid <= high)
    b = bogumil[rows[use], 1:]  # 203, 223, 243, 273, 293 K
    if not (np.all(b > 0.0) and np.all(bogumil[rows[use], 0] == grid[use])):
        raise ValueError(f"{OZONE_RATIO_TABLE} has non-positive values in {RATIO_RANGE_NM} nm")
    ratio[0, use] = b[:, 0] / b[:, 1]
    ratio[3, use] = b[:, 3] / b[:, 2]
    ratio[4, use] = b[:, 4] / b[:, 2]
    nodes = np.stack([s223 * ratio[0], s223, s243, s243 * ratio[3], s243 * ratio[4]])
    return grid, nodes


@lru_cache(maxsize=4)
def _tensors(dtype: torch.dtype) -> tuple[torch.Tensor, torch.Tensor]:
    grid, nodes = _table()
    return (torch.tensor(_NODES_K, dtype=dtype),
            torch.as_tensor(np.ascontiguousarray(nodes), dtype=dtype))


def ozone_cross_section(wavelength_nm, temperature_k=OZONE_REFERENCE_TEMPERATURE_K
                        ) -> torch.Tensor:
    """Ozone absorption cross-section [m^2] at a temperature, 214–1100 nm.

    Parameters
    ----------
    wavelength_nm : Tensor (...)
        Vacuum wavelength [nm], in :data:`OZONE_RANGE_NM` = [214, 1100] nm.
    temperature_k : float or Tensor (...)
        Temperature [K], in :data:`OZONE_TEMPERATURE_RANGE_K` = [203, 293] K (default
        223 K); broadcasts with ``wavelength_nm``.

    Returns
    -------
    Tensor (broadcast(wavelength_nm, temperature_k))
        Cross-section [m^2 per molecule]: the 1 nm bin means interpolated linearly in
        wavelength (1 nm resolution) and piecewise linearly in temperature (module
        docstring); dtype of the inputs (float64 for Python numbers).

    Raises
    ------
    ValueError
        A wavelength outside 214–1100 nm or a temperature outside 203–293 K (naming
        the parameter, the value and the range; no extrapolation), NaN or inf, shapes
        that do not broadcast.
    TypeError
        Inputs that are not numbers.
    """
    low = OZONE_RANGE_NM[0]
    wavelength = check_wavelength_range(
        wavelength_nm, OZONE_RANGE_NM, "the shipped ozone cross-sections",
        "; use an atmosphere with ozone_du=0 outside it")
    t_low, t_high = OZONE_TEMPERATURE_RANGE_K
    if isinstance(temperature_k, bool):
        raise TypeError(f"temperature_k must be a number or a tensor; got {temperature_k!r}")
    temperature = check_range("temperature_k", as_tensor("temperature_k", temperature_k),
                              t_low, t_high, unit=" K")
    shape = check_broadcastable(wavelength_nm=wavelength, temperature_k=temperature)
    dtype = torch.promote_types(wavelength.dtype, temperature.dtype) if isinstance(
        temperature_k, torch.Tensor) else wavelength.dtype
    wavelength = wavelength.to(dtype)
    temperature = temperature.to(dtype)
    nodes_k, sigma = _tensors(dtype)
    n = sigma.shape[1]
    # wavelength: the grid is 214, 215, ..., 1100 nm
    x = wavelength - low
    i = torch.clamp(torch.floor(x.detach()).long(), 0, n - 2)
    u = x - i.to(dtype)
    # temperature: nodes 203, 223, 243, 273, 293 K
    j = torch.clamp(torch.bucketize(temperature.detach(), nodes_k, right=True) - 1, 0, 3)
    t0 = nodes_k[j]
    v = (temperature - t0) / (nodes_k[j + 1] - t0)
    i, u, j, v = (value.expand(shape) for value in torch.broadcast_tensors(i, u, j, v))
    at = sigma[j, i] * (1.0 - u) + sigma[j, i + 1] * u
    above = sigma[j + 1, i] * (1.0 - u) + sigma[j + 1, i + 1] * u
    return at * (1.0 - v) + above * v


#: nodes of the tent average (per half of the tent; trapezoid rule)
_TENT_NODES = 801


def ozone_effective_temperature(peak_altitude_m, half_width_m) -> torch.Tensor:
    r"""Ozone-weighted mean U.S. Standard Atmosphere 1976 temperature over a tent layer [K].

    Parameters
    ----------
    peak_altitude_m, half_width_m : float or Tensor (...)
        Peak altitude and half width of the tent :math:`\max(0, 1 - |h - h_c|/w)` [m]
        (:func:`skytorch.atmosphere.profiles.tent`), broadcasting together.

    Returns
    -------
    Tensor (...)
        :math:`\int \rho(h) T(h)\,dh / \int \rho(h)\,dh` over the part of the tent
        above the ground [K] (trapezoid rule on 1601 nodes; differentiable).

    Examples
    --------
    >>> round(float(ozone_effective_temperature(25e3, 15e3)), 1)
    222.9
    """
    center = check_range("peak_altitude_m", peak_altitude_m, 0.0, low_inclusive=False,
                         unit=" m")
    width = check_range("half_width_m", half_width_m, 0.0, low_inclusive=False, unit=" m")
    check_broadcastable(peak_altitude_m=center, half_width_m=width)
    dtype = torch.promote_types(center.dtype, width.dtype)
    center, width = center.to(dtype)[..., None], width.to(dtype)[..., None]
    x = torch.linspace(-1.0, 1.0, 2 * _TENT_NODES - 1, dtype=dtype)
    altitude = center + width * x
    weight = (1.0 - x.abs()) * (altitude >= 0.0)
    temperature = us1976_temperature(torch.clamp(altitude, min=0.0))
    return torch.trapezoid(weight * temperature, x) / torch.trapezoid(weight, x)
