r"""Zodiacal light: sunlight scattered by interplanetary dust (Leinert et al. 1998, §8).

The brightness at 0.5 µm seen from the Earth is Leinert et al.'s Table 17, tabulated
against the helio-ecliptic longitude :math:`\lambda - \lambda_\odot` and the ecliptic
latitude :math:`\beta` of the line of sight (shipped as
``data/leinert1998_zodiacal_table17.csv``); it is interpolated bilinearly in
:math:`\log_{10}` brightness. The spectrum is the solar one reddened as Leinert et al.'s
§8.1 says (a reddening linear in log wavelength, 0.9 per decade below 500 nm and 0.48
above), checked in the tests against their Table 19 spectrum at 90° elongation.

References
----------
1. Leinert, Ch. et al. 1998, "The 1997 reference of diffuse night sky brightness",
   A&AS 127, 1, doi:10.1051/aas:1998105 (§2 units, §8.1 colour, Tables 17 and 19).
2. Aldering, G. 2001, SNAP sky background model, LBNL report LBNL-51157.
3. ASTM G173-03 extraterrestrial solar spectrum (:func:`skytorch.spectrum.solar_irradiance`).

Examples
--------
>>> import math, torch
>>> b = zodiacal_brightness_500(torch.tensor(math.pi / 2), torch.tensor(0.0))
>>> round(float(b) / TABLE_UNIT_W_M2_SR_NM)      # Table 17 at (90°, 0°)
259
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import torch

from skytorch._data import data_path
from skytorch._validate import as_tensor, check_finite
from skytorch.spectrum import solar_irradiance

__all__ = [
    "S10_W_M2_SR_NM",
    "TABLE_UNIT_W_M2_SR_NM",
    "ZODIACAL_LATITUDES_DEG",
    "ZODIACAL_LONGITUDES_DEG",
    "zodiacal_brightness_500",
    "zodiacal_colour",
    "zodiacal_spectral_radiance",
]

#: unit of Table 17: 1e-8 W m^-2 sr^-1 µm^-1 = 1e-11 W m^-2 sr^-1 nm^-1
TABLE_UNIT_W_M2_SR_NM = 1e-11
#: one S10 (a 10th-magnitude solar-type star per square degree) at 0.5 µm: 1.28e-8
#: W m^-2 sr^-1 µm^-1 (Leinert et al. 1998, §2) [W m^-2 sr^-1 nm^-1]
S10_W_M2_SR_NM = 1.28e-11
#: helio-ecliptic longitudes of the table's rows [degree]
ZODIACAL_LONGITUDES_DEG = (0, 5, 10, 15, 20, 25, 30, 35, 40, 45, 60, 75, 90, 105, 120, 135,
                           150, 165, 180)
#: ecliptic latitudes of the table's columns [degree]
ZODIACAL_LATITUDES_DEG = (0, 5, 10, 15, 20, 25, 30, 45, 60, 75, 90)
#: reddening slopes per decade of wavelength below and above 500 nm (Leinert et al. 1998, §8.1)
_COLOUR_BLUE, _COLOUR_RED = 0.9, 0.48
#: width of the band over which the solar spectrum is averaged for the colour ratio [nm]
_COLOUR_BAND_NM = 40.0


@lru_cache(maxsize=1)
def _log_table() -> np.ndarray:
    """Return log10 of Table 17 (19, 11), its empty solar-vicinity cells filled.

    Each empty cell (elongation below ~15°, only ever above the horizon in daylight or
    bright twilight with the Sun less than 15° below it) takes the value of the first
    filled cell at larger longitude in its latitude column, so the brightness stays finite
    and continuous; there it is a lower bound, not a measurement.
    """
    lines = [line for line in data_path("leinert1998_zodiacal_table17.csv").read_text()
             .splitlines() if line.strip() and not line.startswith("#")]
    table = np.array([[float(cell) if cell else np.nan for cell in line.split(",")[1:]]
                      for line in lines[1:]])
    if table.shape != (len(ZODIACAL_LONGITUDES_DEG), len(ZODIACAL_LATITUDES_DEG)):
        raise ValueError(f"leinert1998_zodiacal_table17.csv has shape {table.shape}")
    for j in range(table.shape[1]):
        column = table[:, j]
        for i in range(len(column) - 2, -1, -1):
            if np.isnan(column[i]):
                column[i] = column[i + 1]
    return np.log10(table)


def _bracket(value: torch.Tensor, nodes: tuple) -> tuple[torch.Tensor, torch.Tensor]:
    grid = torch.tensor(nodes, dtype=value.dtype)
    index = torch.searchsorted(grid, value.detach().contiguous(), right=True) - 1
    index = index.clamp(0, len(nodes) - 2)
    low, high = grid[index], grid[index + 1]
    return index, (value - low) / (high - low)


def zodiacal_brightness_500(helio_ecliptic_lon_rad, ecliptic_lat_rad) -> torch.Tensor:
    r"""Zodiacal light at 500 nm from Leinert et al.'s Table 17 [W m^-2 sr^-1 nm^-1].

    Parameters
    ----------
    helio_ecliptic_lon_rad : array_like
        ``(...)`` ecliptic longitude of the line of sight minus that of the Sun [rad]
        (any value; the table is symmetric in it).
    ecliptic_lat_rad : array_like
        ``(...)`` ecliptic latitude of the line of sight [rad], in [−π/2, π/2] (symmetric).

    Returns
    -------
    torch.Tensor
        ``(...)`` spectral radiance at 500 nm above the atmosphere, seen from 1 AU in the
        symmetry plane [W m^-2 sr^-1 nm^-1]; divide by :data:`S10_W_M2_SR_NM` for S10.

    Notes
    -----
    Bilinear in :math:`\log_{10} I` over (:math:`|\lambda-\lambda_\odot|` folded to
    [0°, 180°], :math:`|\beta|`). The solar-vicinity cells the table leaves empty
    (elongation ≲ 15°) hold the nearest tabulated value at larger longitude (see
    :func:`_log_table`): a lower bound there.
    """
    lon = check_finite("helio_ecliptic_lon_rad", helio_ecliptic_lon_rad)
    lat = check_finite("ecliptic_lat_rad", ecliptic_lat_rad)
    lon, lat = torch.broadcast_tensors(lon, lat)
    dtype = lon.dtype if lon.is_floating_point() else torch.float64
    folded = torch.rad2deg(torch.abs(torch.atan2(torch.sin(lon), torch.cos(lon)))).to(dtype)
    beta = torch.rad2deg(torch.abs(lat.to(dtype)))
    if bool((beta > 90.0 + 1e-9).any()):
        raise ValueError(f"ecliptic_lat_rad must be in [-pi/2, pi/2]; got a value of "
                         f"{float(beta.max()):.6g} degree in magnitude")
    table = torch.as_tensor(_log_table(), dtype=dtype)
    i, u = _bracket(folded, ZODIACAL_LONGITUDES_DEG)
    j, v = _bracket(beta.clamp(max=90.0), ZODIACAL_LATITUDES_DEG)
    n_lat = len(ZODIACAL_LATITUDES_DEG)
    flat = table.reshape(-1)

    def at(a, b):
        return flat[a * n_lat + b]

    log_value = ((1 - u) * (1 - v) * at(i, j) + u * (1 - v) * at(i + 1, j)
                 + (1 - u) * v * at(i, j + 1) + u * v * at(i + 1, j + 1))
    return TABLE_UNIT_W_M2_SR_NM * 10.0 ** log_value


def zodiacal_colour(wavelength_nm) -> torch.Tensor:
    r"""Reddening of the zodiacal light relative to the Sun, 1 at 500 nm.

    Parameters
    ----------
    wavelength_nm : array_like
        ``(wavelength,)`` [nm].

    Returns
    -------
    torch.Tensor
        ``(wavelength,)`` :math:`f(\lambda) = 1 + 0.9 \log_{10}(\lambda / 500)` below
        500 nm and :math:`1 + 0.48 \log_{10}(\lambda / 500)` above (Leinert et al. 1998,
        §8.1, the colour of the zodiacal light at 90° elongation relative to the solar
        spectrum, fitted for 0.2–2.5 µm; the coefficients as used by Aldering 2001 for
        the SNAP sky model).

    Notes
    -----
    Leinert et al. (1998, §8.1): the colour is solar from 0.2 to 2 µm "with a moderate
    amount of reddening". The stronger reddening at small elongations is not modelled.
    The tests compare it with Leinert et al.'s Table 19 spectrum divided by the solar one.

    Examples
    --------
    >>> import torch
    >>> c = zodiacal_colour(torch.tensor([450.0, 500.0, 650.0]))
    >>> bool(c[0] < 1.0 < c[2]), round(float(c[1]), 6)
    (True, 1.0)
    """
    wavelength = as_tensor("wavelength_nm", wavelength_nm)
    dtype = wavelength.dtype if wavelength.is_floating_point() else torch.float64
    wl = check_finite("wavelength_nm", wavelength.to(dtype))
    if bool((wl <= 0).any()):
        raise ValueError(f"wavelength_nm must be > 0 nm; got {float(wl.min())} nm")
    log_ratio = torch.log10(wl / 500.0)
    slope = torch.where(wl < 500.0, _COLOUR_BLUE, _COLOUR_RED).to(dtype)
    return 1.0 + slope * log_ratio


def zodiacal_spectral_radiance(helio_ecliptic_lon_rad, ecliptic_lat_rad,
                               wavelength_nm) -> torch.Tensor:
    r"""Spectral radiance of the zodiacal light above the atmosphere [W m^-2 sr^-1 nm^-1].

    Parameters
    ----------
    helio_ecliptic_lon_rad, ecliptic_lat_rad : array_like
        ``(...)`` direction, as in :func:`zodiacal_brightness_500` [rad].
    wavelength_nm : array_like
        ``(wavelength,)`` [nm], within 280–4000 nm.

    Returns
    -------
    torch.Tensor
        ``(..., wavelength)`` :math:`I_{500}\,c(\lambda)\,E_\odot(\lambda)/\bar E_\odot(500)`:
        the solar spectrum (its Fraunhofer lines kept) reddened by
        :func:`zodiacal_colour` and scaled to Table 17 at 500 nm (the 40 nm mean of the
        solar spectrum there, as Table 17 is broad-band).
    """
    level = zodiacal_brightness_500(helio_ecliptic_lon_rad, ecliptic_lat_rad)
    wavelength = as_tensor("wavelength_nm", wavelength_nm, dtype=level.dtype).reshape(-1)
    solar = solar_irradiance(wavelength)
    solar_500 = solar_irradiance(torch.tensor(500.0, dtype=level.dtype),
                                 bandwidth_nm=_COLOUR_BAND_NM)
    shape = solar * zodiacal_colour(wavelength) / solar_500
    return level[..., None] * shape

