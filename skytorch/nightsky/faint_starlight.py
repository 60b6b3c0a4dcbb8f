r"""The Milky Way fainter than the catalogue: Pioneer 10/11 starlight minus the catalogue.

The total light of the stars fainter than V ≈ 6.5 and of the diffuse galactic light, seen
from beyond the zodiacal cloud, is Leinert et al.'s (1998) Table 35: the Pioneer 10/11
Imaging Photopolarimeter map of Toller (1981) at 0.44 µm, in S10(sun) on a grid of
galactic longitude (every 10°) and latitude (−80° … +80°, 4° to 10° apart), shipped as
``data/leinert1998_starlight_table35.csv``. The catalogue stars of
:func:`skytorch.nightsky.starlight.catalogue_starlight_map` already give the part of that
light from the Gaia DR3 stars (G < 10) other than those of V ≤ 6.5; the part fainter than
the catalogue is

.. math:: L_{\rm faint}(l_k, b_i) = L_{\rm Pioneer}(l_k, b_i)
          - \langle L_{\rm cat}(6.5)\rangle_{ik},

the table minus the mean of the catalogue map without the points of V ≤ 6.5 over the
table cell of each node (longitude l_k ± 5°, latitude between the midpoints to the
neighbouring nodes; the ±80° cells reach the poles). A scene adds the catalogue map of
its own point-star limit (every catalogued star it does not draw) and this faint part
(G > 10 and the diffuse galactic light), so no star is counted twice, whatever the limit.
The faint part is positive at every node (smallest 6.3 S10, at l = 320°, b = −80°; it
is 51–54 % of the table at |b| = 80° and 74–77 % within |b| ≤ 8°).

Between nodes the faint part is interpolated bilinearly in (l, b), periodic in l; from
|b| = 80° to the poles it goes linearly to the mean of the ±80° row (the table stops at
80°; a single value at each pole keeps it continuous).

The table is in the blue (0.44 µm) S10(sun) unit: it is read as the V radiance of a
source of solar colour, which is how :mod:`skytorch.scene.natural_sky` draws starlight
(solar spectral shape). Integrated starlight is somewhat redder than the Sun away from
the plane, so the V level may be ~10 % higher than read here (Leinert et al. 1998,
§10); the table's own accuracy is ~10 %. The whole-sky total of the model (point stars
+ catalogue + faint part) is V = −6.75, against −6.60 for Seares et al. (1925) as quoted
by Roach & Megill (1961) (docs/nightsky.md).

References
----------
1. Leinert, Ch. et al. 1998, A&AS 127, 1, doi:10.1051/aas:1998105 (§10, Table 35).
2. Toller, G. N. 1981, PhD thesis, State University of New York at Stony Brook
   (Pioneer 10/11 background starlight).
3. Roach, F. E. & Megill, L. R. 1961, ApJ 133, 228 (integrated starlight over the sky;
   Seares et al. 1925).
"""

from __future__ import annotations

import math

import numpy as np
import torch

from skytorch._data import data_path
from skytorch._validate import as_tensor
from skytorch.nightsky.starlight import (
    GAIA_LIMIT_G,
    V_MINUS_G,
    catalogue_starlight_map,
    galactic_coordinates,
)

__all__ = [
    "CATALOGUE_LIMIT_V",
    "PIONEER_BRIGHT_LIMIT_V",
    "S10_V_RADIANCE",
    "faint_starlight_table",
    "faint_starlight_v_radiance",
    "pioneer_starlight_table",
]

#: V at the catalogue's limit G = 10 for a star of the mean field colour (V − G = 0.153) [mag]
CATALOGUE_LIMIT_V = GAIA_LIMIT_G + V_MINUS_G
#: stars brighter than this were removed from the Pioneer map (Leinert et al. 1998 §10) [mag]
PIONEER_BRIGHT_LIMIT_V = 6.5
#: one S10: a V = 10 star per square degree, at the V zero point 3.631e-11 W m^-2 nm^-1
#: (Bessell et al. 1998) [W m^-2 sr^-1 nm^-1]
S10_V_RADIANCE = 3.631e-11 * 10.0 ** (-4.0) / (math.pi / 180.0) ** 2
_TABLE = "leinert1998_starlight_table35.csv"


def pioneer_starlight_table() -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Leinert et al. (1998) Table 35, the Pioneer 10/11 starlight, as V radiance.

    Returns
    -------
    lat_deg : torch.Tensor, float64, shape (25,)
        Galactic latitude of the rows, −80 … 80 [deg].
    lon_deg : torch.Tensor, float64, shape (36,)
        Galactic longitude of the columns, 0 … 350 [deg].
    radiance : torch.Tensor, float64, shape (25, 36)
        Starlight of stars fainter than V ≈ 6.5 plus the diffuse galactic light
        [W m^-2 sr^-1 nm^-1]: the table's S10(sun) times :data:`S10_V_RADIANCE`.
    """
    rows = [line for line in data_path(_TABLE).read_text().splitlines()
            if line and not line.startswith("#")]
    header = rows[0].split(",")
    values = np.array([[float(x) for x in row.split(",")] for row in rows[1:]])
    if header[0] != "b_deg" or values.shape != (25, 37):
        raise ValueError(f"{_TABLE} must have a b_deg column and 36 longitudes in 25 rows; "
                         f"got {header[:2]}… and shape {values.shape}")
    lon = np.array([float(name[1:]) for name in header[1:]])
    return (torch.from_numpy(values[:, 0].copy()), torch.from_numpy(lon),
            torch.from_numpy(values[:, 1:] * S10_V_RADIANCE))


def _cell_means(catalogue: np.ndarray, lat_deg: np.ndarray, lon_deg: np.ndarray) -> np.ndarray:
    """Mean of a (n_lon, n_lat) equal-area map over the cell of each table node (lat, lon)."""
    n_lon, n_lat = catalogue.shape
    if n_lon % 36:
        raise ValueError(f"n_lon must be a multiple of 36 (10° table columns); got {n_lon}")
    per = n_lon // 36
    # columns of node l_k: cell centres within l_k ± 5°, i.e. a shift by half a column
    shifted = np.roll(catalogue, per // 2, axis=0).reshape(36, per, n_lat).mean(axis=1)
    sin_edges = np.linspace(-1.0, 1.0, n_lat + 1)
    centre_deg = np.degrees(np.arcsin(0.5 * (sin_edges[1:] + sin_edges[:-1])))
    bounds = np.concatenate([[-90.0], 0.5 * (lat_deg[1:] + lat_deg[:-1]), [90.0]])
    row = np.searchsorted(bounds, centre_deg, side="right") - 1
    counts = np.bincount(row, minlength=lat_deg.size)
    if (counts == 0).any():
        raise ValueError(f"n_lat = {n_lat} leaves table rows without a map cell; use >= 90")
    sums = np.zeros((lat_deg.size, 36))
    np.add.at(sums, row, shifted.T)
    return sums / counts[:, None]


def faint_starlight_table(n_lon: int = 360, n_lat: int = 180
                          ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Starlight fainter than the catalogue at the Table 35 nodes [W m^-2 sr^-1 nm^-1].

    Parameters
    ----------
    n_lon, n_lat : int
        Grid of the catalogue map that is averaged over each table cell (a multiple of 36
        in longitude; at least 90 in sin latitude).

    Returns
    -------
    lat_deg, lon_deg : torch.Tensor, float64, shapes (25,) and (36,)
        The table's galactic latitudes and longitudes [deg].
    radiance : torch.Tensor, float64, shape (25, 36)
        Pioneer 10/11 starlight (V > 6.5 and diffuse galactic light) minus the mean of the
        catalogue map without the points of V ≤ 6.5 over each node's cell: stars with
        G > 10 and the diffuse galactic light. Not clipped: a negative value would mean more
        catalogue light than the table in a cell (none is).
    """
    n_lon, n_lat = int(n_lon), int(n_lat)
    if n_lon < 36 or n_lat < 90:
        raise ValueError(f"n_lon must be >= 36 and n_lat >= 90; got {n_lon}, {n_lat}")
    lat, lon, pioneer = pioneer_starlight_table()
    catalogue = catalogue_starlight_map(PIONEER_BRIGHT_LIMIT_V, n_lon, n_lat).numpy()
    means = _cell_means(catalogue, lat.numpy(), lon.numpy())
    return lat, lon, pioneer - torch.from_numpy(means)


def faint_starlight_v_radiance(icrs_unit: torch.Tensor,
                               table: tuple[torch.Tensor, torch.Tensor, torch.Tensor]
                               ) -> torch.Tensor:
    """Interpolate a :func:`faint_starlight_table` in ICRS directions [W m^-2 sr^-1 nm^-1].

    Parameters
    ----------
    icrs_unit : torch.Tensor, shape (..., 3)
        Unit vectors of the directions (ICRS).
    table : tuple of torch.Tensor
        ``(lat_deg (n_b,), lon_deg (n_l,), radiance (n_b, n_l))`` on a regular longitude
        grid starting at 0°, latitudes increasing.

    Returns
    -------
    torch.Tensor, shape (...)
        Bilinear in (l, b), periodic in l; beyond the outermost rows linear in b to the
        mean of that row at the pole.

    Examples
    --------
    In S10 at the north galactic pole and towards the galactic centre:

    >>> from skytorch.nightsky.starlight import ICRS_TO_GALACTIC
    >>> poles = torch.tensor([ICRS_TO_GALACTIC[2], ICRS_TO_GALACTIC[0]], dtype=torch.float64)
    >>> faint = faint_starlight_v_radiance(poles, faint_starlight_table())
    >>> [round(v) for v in (faint / S10_V_RADIANCE).tolist()]
    [16, 236]
    """
    lat_deg, lon_deg, radiance = table
    vectors = as_tensor("icrs_unit", icrs_unit)
    if vectors.shape[-1:] != (3,):
        raise ValueError(f"icrs_unit must have a last dimension of 3; got {tuple(vectors.shape)}")
    n_l = lon_deg.numel()
    step = 360.0 / n_l
    expected = torch.arange(n_l, dtype=torch.float64) * step
    if radiance.shape != (lat_deg.numel(), n_l) or not torch.allclose(
            lon_deg.to(torch.float64), expected):
        raise ValueError(f"table must be (lat_deg, lon_deg = 0, {step:g}, …, radiance of shape "
                         f"(lat, lon)); got shapes {tuple(lat_deg.shape)}, "
                         f"{tuple(lon_deg.shape)}, {tuple(radiance.shape)}")
    lon, lat = galactic_coordinates(vectors)
    dtype = lon.dtype
    poles = radiance.mean(dim=1, keepdim=True).expand(-1, n_l)
    grid = torch.cat([poles[:1], radiance, poles[-1:]]).to(dtype)
    nodes = torch.cat([lat_deg.new_tensor([-90.0]), lat_deg, lat_deg.new_tensor([90.0])])
    nodes = nodes.to(dtype)
    b = torch.rad2deg(lat)
    i = (torch.searchsorted(nodes, b.reshape(-1).contiguous(), right=True) - 1).clamp(
        0, nodes.numel() - 2).reshape(b.shape)
    fb = (b - nodes[i]) / (nodes[i + 1] - nodes[i])
    x = torch.rad2deg(lon) / step
    j = torch.floor(x).long() % n_l
    fl = x - torch.floor(x)
    j1 = (j + 1) % n_l
    low = grid[i, j] * (1 - fl) + grid[i, j1] * fl
    high = grid[i + 1, j] * (1 - fl) + grid[i + 1, j1] * fl
    return low * (1 - fb) + high * fb
