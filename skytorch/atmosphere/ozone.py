"""Ozone absorption: shipped Chappuis-band cross-sections and the column in Dobson units.

The cross-sections (360–830 nm, 10 nm bins) are those measured at 233 K by Serdyuchenko
et al. (ref. 1, IUP Bremen), averaged over ``[λ, λ + 10 nm)`` bins as in Bruneton's
reference implementation (ref. 2); each bin value is assigned to its lower edge, as
there, and interpolated linearly in between. Outside 360–830 nm (:data:`OZONE_RANGE_NM`)
there is no data: :func:`ozone_cross_section` raises ``ValueError`` naming the
wavelength and the range rather than extrapolating (the Hartley–Huggins bands below
360 nm absorb orders of magnitude more than the edge value).

References
----------
1. Serdyuchenko, A., Gorshelev, V., Weber, M., Chehade, W. & Burrows, J. P. 2014,
   "High spectral resolution ozone absorption cross-sections – Part 2: Temperature
   dependence", Atmos. Meas. Tech. 7, 625, doi:10.5194/amt-7-625-2014.
2. Bruneton, E. 2017, "A qualitative and quantitative evaluation of 8 clear sky models",
   IEEE TVCG 24, 2641, doi:10.1109/TVCG.2016.2622272 (demo table of
   precomputed_atmospheric_scattering).

Examples
--------
>>> import torch
>>> from skytorch.atmosphere.ozone import ozone_cross_section
>>> ozone_cross_section(torch.tensor([600.0]))
tensor([5.0190e-25])
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import torch

from skytorch._data import data_path
from skytorch._validate import check_finite

__all__ = ["OZONE_RANGE_NM", "OZONE_TABLE", "ozone_cross_section"]

#: shipped table (``data/``)
OZONE_TABLE = "ozone_cross_section_serdyuchenko2014_233k.csv"
#: wavelengths covered by the shipped table [nm]
OZONE_RANGE_NM = (360.0, 830.0)


@lru_cache(maxsize=1)
def _table() -> tuple[torch.Tensor, torch.Tensor]:
    values = np.loadtxt(data_path(OZONE_TABLE), delimiter=",", comments="#", skiprows=4)
    return (torch.as_tensor(np.ascontiguousarray(values[:, 0]), dtype=torch.float64),
            torch.as_tensor(np.ascontiguousarray(values[:, 1]), dtype=torch.float64))


def ozone_cross_section(wavelength_nm) -> torch.Tensor:
    """Ozone absorption cross-section [m^2] at 233 K.

    Parameters
    ----------
    wavelength_nm : Tensor (...)
        Wavelength [nm], in :data:`OZONE_RANGE_NM` (360–830 nm).

    Returns
    -------
    Tensor (...)
        Cross-section [m^2], linear interpolation in the shipped table.

    Raises
    ------
    ValueError
        For a wavelength outside 360–830 nm (no extrapolation), NaN or inf.
    """
    low, high = OZONE_RANGE_NM
    wavelength_nm = check_finite("wavelength_nm", wavelength_nm)
    with torch.no_grad():
        outside = (wavelength_nm < low) | (wavelength_nm > high)
        if bool(outside.any()):
            bad = float(wavelength_nm[outside].reshape(-1)[0])
            raise ValueError(
                f"wavelength_nm must be in [{low}, {high}] nm (the range "
                f"of the shipped ozone cross-sections); got {bad} nm ({int(outside.sum())} "
                "offending element(s)); use an atmosphere with ozone_du=0 outside it")
    grid, sigma = _table()
    grid = grid.to(wavelength_nm.dtype)
    sigma = sigma.to(wavelength_nm.dtype)
    x = wavelength_nm
    index = torch.clamp(torch.searchsorted(grid, x.detach().contiguous(), right=True) - 1,
                        0, grid.numel() - 2)
    x0 = grid[index]
    weight = (x - x0) / (grid[index + 1] - x0)
    return sigma[index] * (1.0 - weight) + sigma[index + 1] * weight
