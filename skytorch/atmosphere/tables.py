r"""Transmittance look-up table (Bruneton parametrisation) with a disk cache.

The table stores the optical depth from a point at radius :math:`r` along direction
cosine :math:`\mu` to the top of the atmosphere, for rays that do not meet the ground,
on the texture coordinates of Bruneton (ref. 1, ``GetTransmittanceTextureUvFromRMu``):

.. math::

    H = \sqrt{R_t^2 - R^2},\quad \rho = \sqrt{r^2 - R^2},\quad x_r = \rho / H,

    d_{min} = R_t - r,\quad d_{max} = \rho + H,\quad
    x_\mu = (d - d_{min})/(d_{max} - d_{min}),

with :math:`d` the distance to the top. Samples lie on the unit range, including both
ends; along :math:`x_\mu` they are uniform (:math:`x = k/(n-1)`). Along :math:`x_r` they
have nodes at the altitudes where a density profile has a kink (the ozone tent's base,
peak and top) and are graded towards the kink above them (:func:`radius_nodes`): below
a kink the column of near-horizontal rays behaves like :math:`(h_k - h)^{3/2}`, and
uniform samples interpolated it with 20 % errors at 256 x 64 (ozone at 595 nm, 40 km).
Look-ups interpolate bilinearly in :math:`(x_r, x_\mu)`. Optical depths between two
points, and to the ground, follow from differences of two look-ups (ref. 1,
``GetTransmittance``). Because the per-species path integrals do not depend on
wavelength, the table's cost is that of ``n_r * n_mu`` rays times three species.

Tables are cached on disk as netCDF files named by a SHA-256 hash of every parameter
that affects them (the atmosphere's parameters, the wavelengths, the resolution, the
quadrature and a format version), each with a record of its content checksum and that
hash beside it (:mod:`skytorch._cache`). The cache directory is ``$SKYTORCH_CACHE_DIR``
or ``~/.cache/skytorch``. A file whose bytes changed, that cannot be read, or whose
stored key, shapes or values do not match, is deleted and rebuilt, never served.

A :class:`TransmittanceTable` records the wavelengths, the grid and the hash of the
atmosphere it was built for; :meth:`TransmittanceTable.check_compatible` (called by
:func:`skytorch.atmosphere.scattering.single_scattering_radiance`) refuses it for
another atmosphere or other wavelengths.

References
----------
1. Bruneton, E. 2017, "Precomputed Atmospheric Scattering: a New Implementation",
   https://ebruneton.github.io/precomputed_atmospheric_scattering/.
2. Bruneton, E. & Neyret, F. 2008, "Precomputed Atmospheric Scattering",
   Computer Graphics Forum 27, 1079, doi:10.1111/j.1467-8659.2008.01245.x.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere import Atmosphere
>>> from skytorch.atmosphere.tables import TransmittanceTable
>>> atm = Atmosphere.earth(turbidity=2.0)
>>> table = TransmittanceTable.build(atm, torch.tensor([440.0, 550.0, 680.0]), n_mu=64,
...                                  n_r=16)
>>> table.optical_depth(torch.tensor([0.0, 1.0])).shape
torch.Size([2, 3])
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
from pathlib import Path

import numpy as np
import torch
from torch import nn

from skytorch._validate import (
    broadcast_shape,
    check_choice,
    check_finite,
    check_int,
    check_positive,
    check_range,
    check_zenith,
    common_dtype,
    refuse_gradient,
)
from skytorch.atmosphere import profiles as _profiles
from skytorch.atmosphere.geometry import (
    _distance_to_ground,
    _ray_hits_ground,
    _texture_coordinates,
    _texture_rays,
)
from skytorch.atmosphere.inputs import check_atmosphere, wavelength_tensor
from skytorch.atmosphere.optical_depth import METHODS
from skytorch.dataset import (
    VariableSpec,
    build_dataset,
    coordinate,
    open_dataset,
    to_netcdf,
    variable,
)

__all__ = [
    "TransmittanceTable",
    "atmosphere_hash",
    "cache_directory",
    "cached_transmittance_table",
    "radius_nodes",
    "table_key",
    "transmittance_table",
]

logger = logging.getLogger(__name__)

#: bump when the layout or the numerics of the table change (invalidates caches)
TABLE_FORMAT_VERSION = 5

_REFERENCES = [
    "Bruneton, E. 2017, Precomputed Atmospheric Scattering: a New Implementation, "
    "https://ebruneton.github.io/precomputed_atmospheric_scattering/",
    "Bruneton, E. & Neyret, F. 2008, Computer Graphics Forum 27, 1079, "
    "doi:10.1111/j.1467-8659.2008.01245.x",
]


def cache_directory() -> Path:
    """``$SKYTORCH_CACHE_DIR`` if set, else ``~/.cache/skytorch``."""
    return Path(os.environ.get("SKYTORCH_CACHE_DIR") or Path.home() / ".cache" / "skytorch")


#: grading exponent of the x_r samples towards a kink above them (see radius_nodes)
_KINK_GRADING = 1.7


def radius_nodes(atmosphere, n_r: int) -> torch.Tensor:
    r"""Return the :math:`x_r = \rho/H` samples of a table (n_r,), kinks of the profiles on nodes.

    The unit range is cut at the :math:`x_r` of every profile kink inside the atmosphere
    (the ozone tent's base, peak and top); the ``n_r - 1`` intervals are shared among the
    pieces in proportion to their lengths (at least one each) and are uniform within a
    piece. Below a kink the column of near-horizontal rays behaves like
    :math:`(h_k - h)^{3/2}`, so in the pieces between two kinks the samples are graded
    towards the upper one, :math:`x = a + (b - a)(1 - (1 - u)^{1.7})` with :math:`u`
    uniform (at 256 x 64 this cuts the worst look-up error from 19 % to 4.9 %, see
    docs/accuracy.md); the lowest piece, where molecules and aerosols dominate, and the
    highest stay uniform. With fewer intervals than pieces the samples are uniform.
    """
    planet, top = atmosphere.planet_radius_m, atmosphere.top_radius_m
    horizon = math.sqrt(top ** 2 - planet ** 2)
    kinks = atmosphere.profiles(torch.float64)["ozone"].breakpoints_m.reshape(-1).tolist()
    if atmosphere.molecule_profile == "us1976":
        kinks += list(_profiles.US1976_KINK_ALTITUDES_M)
    cuts = sorted({math.sqrt(h * (2.0 * planet + h)) / horizon for h in kinks
                   if 0.0 < h < atmosphere.top_altitude_m})
    edges = [0.0, *cuts, 1.0]
    lengths = [b - a for a, b in zip(edges[:-1], edges[1:], strict=True)]
    n_intervals = n_r - 1
    if n_intervals < len(lengths):
        return torch.linspace(0.0, 1.0, n_r, dtype=torch.float64)
    counts = [max(1, round(n_intervals * length)) for length in lengths]
    while sum(counts) != n_intervals:
        # adjust the piece whose interval length is furthest from the mean
        step = 1 if sum(counts) < n_intervals else -1
        spacing = [length / count for length, count in zip(lengths, counts, strict=True)]
        candidates = [k for k in range(len(counts)) if step > 0 or counts[k] > 1]
        k = (max if step > 0 else min)(candidates, key=lambda index: spacing[index])
        counts[k] += step
    pieces = []
    for k, (a, b, count) in enumerate(zip(edges[:-1], edges[1:], counts, strict=True)):
        u = torch.linspace(0.0, 1.0, count + 1, dtype=torch.float64)[:-1]
        grading = _KINK_GRADING if 0 < k < len(lengths) - 1 else 1.0
        pieces.append(a + (b - a) * (1.0 - (1.0 - u) ** grading))
    return torch.cat([*pieces, torch.ones(1, dtype=torch.float64)])


def atmosphere_hash(atmosphere) -> str:
    """SHA-256 hex digest of an atmosphere's parameters (:meth:`Atmosphere.parameters_dict`).

    Two atmospheres with the same hash give the same optical depths; a table records the
    hash of the atmosphere it was built for.
    """
    text = json.dumps(atmosphere.parameters_dict(), sort_keys=True, default=float)
    return hashlib.sha256(text.encode()).hexdigest()


def table_key(atmosphere, wavelength_nm, n_mu: int, n_r: int, method: str,
              n_steps: int | None) -> str:
    """SHA-256 hex digest of every parameter that affects the table."""
    payload = {
        "kind": "transmittance", "format": TABLE_FORMAT_VERSION,
        "atmosphere": atmosphere.parameters_dict(),
        "wavelength_nm": [float(w) for w in torch.as_tensor(wavelength_nm).reshape(-1)],
        "n_mu": n_mu, "n_r": n_r, "method": method, "n_steps": n_steps,
    }
    text = json.dumps(payload, sort_keys=True, default=float)
    return hashlib.sha256(text.encode()).hexdigest()


def _check_build(atmosphere, wavelength_nm, n_mu, n_r, method, n_steps):
    """Return checked arguments of a table build (TypeError/ValueError naming the parameter)."""
    check_atmosphere("atmosphere", atmosphere)
    refuse_gradient("a transmittance table", atmosphere=atmosphere,
                    wavelength_nm=wavelength_nm)
    n_mu = check_int("n_mu", n_mu, 2)
    n_r = check_int("n_r", n_r, 2)
    check_choice("method", method, METHODS)
    if n_steps is not None:
        n_steps = check_int("n_steps", n_steps, 1)
    if atmosphere.batch_shape != ():
        raise ValueError("transmittance tables need an Atmosphere with scalar parameters; "
                         f"got batch shape {tuple(atmosphere.batch_shape)} (loop over the "
                         "sweep)")
    wavelength = wavelength_tensor(wavelength_nm, torch.float64)
    if wavelength.numel() == 0:
        raise ValueError("wavelength_nm must hold at least one wavelength; got none")
    return wavelength, n_mu, n_r, n_steps


def transmittance_table(atmosphere, wavelength_nm, *, n_mu: int = 256, n_r: int = 64,
                        method: str = "gauss", n_steps: int | None = None):
    r"""Compute the transmittance table as a Dataset.

    Parameters
    ----------
    atmosphere : Atmosphere
        With scalar (unbatched) parameters.
    wavelength_nm : Tensor (wavelength,)
        Wavelengths [nm].
    n_mu, n_r : int
        Samples along :math:`x_\mu` and :math:`x_r` (Bruneton: 256 x 64), >= 2.
    method, n_steps
        Quadrature of the column integrals (:meth:`Atmosphere.optical_depth`).

    Returns
    -------
    xarray.Dataset
        Dims ``x_r``, ``x_mu``, ``wavelength``; variables ``optical_depth``,
        ``transmittance`` (x_r, x_mu, wavelength), ``altitude`` (x_r) [m],
        ``zenith_angle`` (x_r, x_mu) [degree]; attributes ``cache_key`` (every input) and
        ``atmosphere_sha256`` (:func:`atmosphere_hash`).
    """
    wavelength, n_mu, n_r, n_steps = _check_build(atmosphere, wavelength_nm, n_mu, n_r,
                                                  method, n_steps)
    x_r = radius_nodes(atmosphere, n_r)
    x_mu = torch.linspace(0.0, 1.0, n_mu, dtype=torch.float64)
    altitude, mu = _texture_rays(x_r[:, None], x_mu[None, :], atmosphere.planet_radius_m,
                                 atmosphere.top_radius_m)
    # the last column is the ray tangent to the ground: nudge it above the horizon so that
    # it counts as reaching the top (continuity with its neighbours)
    mu = torch.where(x_mu[None, :] == 1.0, mu * (1.0 - 1e-12), mu)
    # the columns once; the optical depth at every wavelength follows from them
    columns = atmosphere.column_integrals(torch.acos(mu), altitude, method=method,
                                          n_steps=n_steps)
    tau = atmosphere.constituents(wavelength).optical_depth(columns)
    species = list(columns)
    column = torch.stack([columns[name] for name in species], dim=-1)
    key = table_key(atmosphere, wavelength, n_mu, n_r, method, n_steps)
    data_vars = {
        "optical_depth": variable(("x_r", "x_mu", "wavelength"), tau, VariableSpec(
            "1", "optical depth to the top of the atmosphere",
            "Slant optical depth from (r, mu) to the top of the atmosphere along a straight "
            "ray (all constituents).")),
        "transmittance": variable(("x_r", "x_mu", "wavelength"), torch.exp(-tau), VariableSpec(
            "1", "transmittance to the top of the atmosphere",
            "exp(-optical_depth).", "atmosphere_transmittance")),
        "column": variable(("x_r", "x_mu", "species"), column, VariableSpec(
            "m", "path column of each species to the top of the atmosphere",
            "Integral of the species' relative density along the straight ray from (r, mu) "
            "to the top [m]: additive along a path, so that rays meeting the ground and "
            "species with a nonlinear law of their column are looked up exactly.")),
        "altitude": variable(("x_r",), altitude[:, 0], VariableSpec(
            "m", "altitude of the ray origin", "r - planet radius.", "altitude")),
        "zenith_angle": variable(("x_r", "x_mu"), torch.rad2deg(torch.acos(mu)), VariableSpec(
            "degree", "zenith angle of the ray", "Angle between the ray and the local "
            "vertical at its origin.", "zenith_angle")),
    }
    coords = {
        "x_r": coordinate("x_r", x_r, VariableSpec(
            "1", "radius texture coordinate",
            "sqrt(r^2 - R^2) / sqrt(R_t^2 - R^2); uniform between profile kinks, which are "
            "nodes")),
        "x_mu": coordinate("x_mu", x_mu, VariableSpec(
            "1", "direction texture coordinate",
            "(d - d_min) / (d_max - d_min), d the distance to the top")),
        "wavelength": coordinate("wavelength", wavelength, VariableSpec(
            "nm", "wavelength", "Vacuum wavelength.", "radiation_wavelength")),
        "species": coordinate("species", species, VariableSpec(
            "1", "species", "Constituent of the atmosphere (skytorch.atmosphere.SPECIES).")),
    }
    parameters = dict(atmosphere.parameters_dict())
    parameters.update({"n_mu": n_mu, "n_r": n_r, "method": method,
                       "n_steps": -1 if n_steps is None else n_steps,
                       "table_format": TABLE_FORMAT_VERSION})
    return build_dataset(data_vars, coords, title="Transmittance look-up table",
                         references=_REFERENCES, parameters=parameters, cache_key=key,
                         atmosphere_sha256=atmosphere_hash(atmosphere))


def _valid(dataset, key: str, n_wavelength: int, n_mu: int, n_r: int) -> bool:
    try:
        tau = dataset["optical_depth"].values
        return (dataset.attrs.get("cache_key") == key
                and tau.shape == (n_r, n_mu, n_wavelength)
                and bool(np.isfinite(tau).all()) and bool((tau >= 0).all()))
    except (KeyError, AttributeError, ValueError):
        return False


def cached_transmittance_table(atmosphere, wavelength_nm, *, n_mu: int = 256, n_r: int = 64,
                               method: str = "gauss", n_steps: int | None = None,
                               cache_dir: str | os.PathLike | None = None,
                               progress: bool | None = None):
    """Return the transmittance table from the disk cache, computed and stored if absent or bad.

    The file is written with :func:`skytorch._cache.write_verified` (a record of its
    SHA-256 and of the parameter hash beside it) and read with
    :func:`skytorch._cache.read_verified`: a file whose bytes changed (corruption, a
    table with other values written over it) or that was built for other parameters is
    deleted and rebuilt, never served.

    Parameters
    ----------
    atmosphere, wavelength_nm, n_mu, n_r, method, n_steps
        As for :func:`transmittance_table`.
    cache_dir : path, optional
        Cache directory (default :func:`cache_directory`).
    progress : bool, optional
        Show a progress bar while building (default: only on a terminal).

    Returns
    -------
    xarray.Dataset
    """
    from tqdm.auto import tqdm

    from skytorch._cache import read_verified, write_verified

    wavelength, n_mu, n_r, n_steps = _check_build(atmosphere, wavelength_nm, n_mu, n_r,
                                                  method, n_steps)
    if progress is not None and not isinstance(progress, bool):
        raise TypeError(f"progress must be True, False or None; got {progress!r}")
    key = table_key(atmosphere, wavelength, n_mu, n_r, method, n_steps)
    directory = Path(cache_dir) if cache_dir is not None else cache_directory()
    path = directory / f"transmittance_{key[:24]}.nc"

    def read(file):
        dataset = open_dataset(file)
        if not _valid(dataset, key, wavelength.numel(), n_mu, n_r):
            raise ValueError("stale or inconsistent table (key, shape or values)")
        return dataset

    dataset = read_verified(path, key, read)
    if dataset is not None:
        logger.debug("transmittance table from cache %s", path)
        return dataset
    disable = (not os.isatty(2)) if progress is None else not progress
    with tqdm(total=1, desc="transmittance table", disable=disable) as bar:
        dataset = transmittance_table(atmosphere, wavelength, n_mu=n_mu, n_r=n_r,
                                      method=method, n_steps=n_steps)
        bar.update(1)
    write_verified(path, key, lambda file: to_netcdf(dataset, file))
    logger.info("transmittance table written to %s", path)
    return dataset


class TransmittanceTable(nn.Module):
    """Batched bilinear look-ups in a transmittance table.

    The table records what it was built for -- its wavelengths, its grid (``x_r``
    samples and ``n_mu``), the radii and, when built from an atmosphere, the hash of its
    parameters (:func:`atmosphere_hash`) -- and :meth:`check_compatible` refuses a use
    with another atmosphere or other wavelengths.

    Parameters
    ----------
    optical_depth : Tensor (x_r, x_mu, wavelength)
        Table of optical depths to the top (finite, >= 0).
    wavelength_nm : Tensor (wavelength,)
        Its wavelengths [nm].
    planet_radius_m, top_radius_m : float
        Radii the table was computed for [m].
    x_r : Tensor (x_r,), optional
        The increasing :math:`x_r` samples from 0 to 1 (default uniform).
    atmosphere_sha256 : str, optional
        :func:`atmosphere_hash` of the atmosphere the table was computed for (set by
        :meth:`build` and :meth:`from_dataset`); without it only the wavelengths and
        the radii can be checked.
    columns : Tensor (x_r, x_mu, species), optional
        Path columns of each species to the top [m], with ``constituents`` (at the
        table's wavelengths, species in the same order): look-ups then interpolate the
        columns and form the optical depth with
        :meth:`~skytorch.atmosphere.constituents.Constituents.optical_depth`, exact for
        rays meeting the ground and for species with a nonlinear law of their column
        (band models). Without them the optical depths are interpolated (exact only for
        linear species on rays that miss the ground).
    constituents : Constituents, optional
        See ``columns``.
    """

    def __init__(self, optical_depth, wavelength_nm, planet_radius_m: float,  # noqa: C901 (a flat list of argument checks)
                 top_radius_m: float, x_r=None, *, atmosphere_sha256: str | None = None,
                 columns=None, constituents=None):
        super().__init__()
        table = check_finite("optical_depth", torch.as_tensor(
            np.array(optical_depth, dtype=np.float64)))
        if table.ndim != 3 or min(table.shape[:2]) < 2 or table.shape[2] < 1:
            raise ValueError("optical_depth must have shape (x_r >= 2, x_mu >= 2, "
                             f"wavelength >= 1); got {tuple(table.shape)}")
        if bool((table < 0).any()):
            raise ValueError("optical_depth must be >= 0 everywhere")
        self.register_buffer("table", table.clone())
        wavelength = check_positive("wavelength_nm", torch.as_tensor(
            np.array(wavelength_nm, dtype=np.float64)).reshape(-1), unit=" nm")
        if wavelength.numel() != table.shape[2]:
            raise ValueError(f"wavelength_nm has {wavelength.numel()} values for a table of "
                             f"{table.shape[2]} wavelengths")
        self.register_buffer("wavelength_nm", wavelength.clone())
        n_r = self.table.shape[0]
        nodes = (torch.linspace(0.0, 1.0, n_r, dtype=torch.float64) if x_r is None
                 else torch.tensor(np.array(x_r, dtype=np.float64)))
        if (nodes.shape != (n_r,) or not bool((nodes[1:] > nodes[:-1]).all())
                or float(nodes[0]) != 0.0 or float(nodes[-1]) != 1.0):
            raise ValueError(f"x_r must be {n_r} increasing samples from 0 to 1; got "
                             f"{nodes.tolist()}")
        self.register_buffer("x_r", nodes)
        planet = float(check_positive("planet_radius_m", planet_radius_m, unit=" m"))
        top = float(check_positive("top_radius_m", top_radius_m, unit=" m"))
        if not top > planet:
            raise ValueError(f"top_radius_m must be > planet_radius_m; got {top} <= {planet}")
        self.planet_radius_m = planet
        self.top_radius_m = top
        if atmosphere_sha256 is not None and not isinstance(atmosphere_sha256, str):
            raise TypeError(f"atmosphere_sha256 must be a string; got {atmosphere_sha256!r}")
        self.atmosphere_sha256 = atmosphere_sha256
        if (columns is None) != (constituents is None):
            raise ValueError("columns and constituents go together (both or neither)")
        self.constituents = constituents
        if columns is not None:
            column = check_finite("columns", torch.as_tensor(
                np.array(columns, dtype=np.float64)))
            names = tuple(constituents.names)
            if column.shape != (*table.shape[:2], len(names)):
                raise ValueError(f"columns must have shape {(*table.shape[:2], len(names))} "
                                 f"(x_r, x_mu, one per species {names}); got "
                                 f"{tuple(column.shape)}")
            if tuple(constituents.batch_shape) != ():
                raise ValueError("constituents of a table must be unbatched")
            self.register_buffer("columns", column.clone())
        else:
            self.columns = None

    @property
    def n_mu(self) -> int:
        r"""Samples along :math:`x_\mu`."""
        return int(self.table.shape[1])

    @property
    def top_altitude_m(self) -> float:
        """Altitude of the top of the atmosphere [m]."""
        return self.top_radius_m - self.planet_radius_m

    @classmethod
    def from_dataset(cls, dataset, constituents=None) -> TransmittanceTable:
        """From a Dataset of :func:`transmittance_table` (or the cache).

        With ``constituents`` (of the table's atmosphere at its wavelengths) the look-ups
        use the Dataset's per-species ``column`` (see the class parameters).
        """
        parameters = json.loads(dataset.attrs["parameters"])
        planet = parameters["planet_radius_m"]
        columns = None
        if constituents is not None:
            species = [str(name) for name in dataset["species"].values]
            if species != list(constituents.names):
                raise ValueError(f"the table's species {species} are not those of the "
                                 f"constituents {list(constituents.names)}")
            columns = dataset["column"].values
        return cls(dataset["optical_depth"].values, dataset["wavelength"].values, planet,
                   planet + parameters["top_altitude_m"], dataset["x_r"].values,
                   atmosphere_sha256=dataset.attrs.get("atmosphere_sha256"),
                   columns=columns, constituents=constituents)

    @classmethod
    def build(cls, atmosphere, wavelength_nm, *, cache: bool = False, n_mu: int = 256,
              n_r: int = 64, method: str = "gauss", n_steps: int | None = None,
              cache_dir: str | os.PathLike | None = None, progress: bool | None = None
              ) -> TransmittanceTable:
        """Compute (or, with ``cache=True``, load from the disk cache) a table.

        The keywords are those of :func:`transmittance_table` (and, with the cache,
        ``cache_dir`` and ``progress`` of :func:`cached_transmittance_table`).
        """
        if not isinstance(cache, bool):
            raise TypeError(f"cache must be True or False; got {cache!r}")
        options = {"n_mu": n_mu, "n_r": n_r, "method": method, "n_steps": n_steps}
        if cache:
            dataset = cached_transmittance_table(atmosphere, wavelength_nm, cache_dir=cache_dir,
                                                 progress=progress, **options)
        else:
            if cache_dir is not None:
                raise TypeError("cache_dir applies with cache=True only")
            dataset = transmittance_table(atmosphere, wavelength_nm, **options)
        return cls.from_dataset(dataset, atmosphere.constituents(
            torch.tensor(np.array(dataset["wavelength"].values, dtype=np.float64))))

    def check_compatible(self, atmosphere=None, wavelength_nm=None) -> None:
        """Refuse (ValueError naming ``table``) a use the table was not built for.

        Parameters
        ----------
        atmosphere : Atmosphere, optional
            Must have the table's radii and, when the table records one, its parameter
            hash.
        wavelength_nm : Tensor (wavelength,), optional
            Must equal the table's wavelengths (same count, equal to 1e-9 nm).
        """
        if wavelength_nm is not None:
            wavelength = torch.as_tensor(wavelength_nm).detach().to(torch.float64).reshape(-1)
            ours = self.wavelength_nm
            if wavelength.shape != ours.shape or not bool(
                    ((wavelength - ours).abs() <= 1e-9).all()):
                raise ValueError(
                    f"table was built for wavelength_nm {ours.tolist()}; got "
                    f"{wavelength.tolist()} (build a table for these wavelengths)")
        if atmosphere is not None:
            if (abs(float(atmosphere.planet_radius_m) - self.planet_radius_m) > 1e-6
                    or abs(float(atmosphere.top_radius_m) - self.top_radius_m) > 1e-6):
                raise ValueError(
                    f"table was built for radii {self.planet_radius_m} m and "
                    f"{self.top_radius_m} m; the atmosphere has {atmosphere.planet_radius_m} m "
                    f"and {atmosphere.top_radius_m} m")
            if self.atmosphere_sha256 is not None:
                if getattr(atmosphere, "batch_shape", ()) != ():
                    raise ValueError("table was built for one atmosphere; got an atmosphere "
                                     f"with batch shape {tuple(atmosphere.batch_shape)}")
                if atmosphere_hash(atmosphere) != self.atmosphere_sha256:
                    raise ValueError(
                        "table was built for another atmosphere (parameter hash "
                        f"{self.atmosphere_sha256[:12]}..., this one "
                        f"{atmosphere_hash(atmosphere)[:12]}...): build a table for it")

    def _lookup(self, altitude, mu, table=None):
        """Bilinear interpolation of ``table`` at (altitude, mu) -> (..., last dim of the table).

        ``table`` defaults to the optical depths; for rays missing the ground.
        """
        x_r, x_mu = _texture_coordinates(altitude, mu, self.planet_radius_m,
                                         self.top_radius_m)
        x_r, x_mu = torch.clamp(x_r, 0.0, 1.0), torch.clamp(x_mu, 0.0, 1.0)
        table = (self.table if table is None else table).to(x_r.dtype)
        n_r, n_mu, n_wl = table.shape
        nodes = self.x_r.to(x_r.dtype)
        i = torch.clamp(torch.searchsorted(nodes, x_r.detach().contiguous(), right=True) - 1,
                        0, n_r - 2)
        fm = x_mu * (n_mu - 1)
        j = torch.clamp(fm.detach().floor().long(), 0, n_mu - 2)
        wr = ((x_r - nodes[i]) / (nodes[i + 1] - nodes[i]))[..., None]
        wm = (fm - j)[..., None]
        flat = table.reshape(n_r * n_mu, n_wl)

        def at(a, b):
            return flat[a * n_mu + b]

        return ((1 - wr) * ((1 - wm) * at(i, j) + wm * at(i, j + 1))
                + wr * ((1 - wm) * at(i + 1, j) + wm * at(i + 1, j + 1)))

    def optical_depth(self, zenith_rad, altitude_m=0.0, *, wavelength_nm=None
                      ) -> torch.Tensor:
        r"""Optical depth from the observer to the top or to the ground (..., wavelength).

        Parameters
        ----------
        zenith_rad : Tensor (...)
            Zenith angle of the view direction [rad] (finite).
        altitude_m : Tensor (...)
            Observer altitude [m], between 0 and the top of the atmosphere (the range of
            the table; ValueError outside it). Broadcasts with ``zenith_rad``.
        wavelength_nm : Tensor (wavelength,), optional
            The wavelengths the caller expects; ValueError if the table was built for
            others.

        Notes
        -----
        Rays meeting the ground at :math:`(R, \mu_g)`:
        :math:`\tau = \tau_{top}(R, -\mu_g) - \tau_{top}(r, -\mu)` (ref. 1).
        """
        dtype = common_dtype(zenith_rad, altitude_m)
        zenith = check_zenith(zenith_rad, dtype=dtype)
        # (checked in the input's precision, then cast)
        altitude = check_range("altitude_m", altitude_m, 0.0, self.top_altitude_m,
                               unit=" m (the table's range)").to(dtype)
        try:
            broadcast_shape(zenith.shape, altitude.shape)
        except ValueError:
            raise ValueError(f"shapes do not broadcast: zenith_rad {tuple(zenith.shape)}, "
                             f"altitude_m {tuple(altitude.shape)}") from None
        if wavelength_nm is not None:
            self.check_compatible(wavelength_nm=wavelength_nm)
        return self.lookup(zenith, altitude)

    def lookup(self, zenith, altitude) -> torch.Tensor:
        """Return :meth:`optical_depth` (..., wavelength) of checked tensors, without the checks.

        ``altitude`` in [0, top] [m], finite ``zenith`` [rad], same dtype.
        """
        r = self.planet_radius_m + altitude
        mu = torch.cos(zenith)
        r, mu = torch.broadcast_tensors(r, mu)
        shape = r.shape
        r, mu = r.reshape(-1), mu.reshape(-1)  # boolean indexing of 0-d tensors adds a dim
        hits = _ray_hits_ground(r, mu, self.planet_radius_m)
        table = self.columns
        up = self._lookup(r - self.planet_radius_m, torch.where(hits, -mu, mu), table)
        value = up
        if bool(hits.any()):
            # rays meeting the ground: the column from the ground point, for those rays only
            r_hit, mu_hit = r[hits], mu[hits]
            d = _distance_to_ground(r_hit, mu_hit, self.planet_radius_m)
            planet = self.planet_radius_m
            # mu at the ground point (looking down) from r mu + d = R mu_g
            mu_ground = torch.clamp((r_hit * mu_hit + d) / planet, -1.0, 0.0)
            from_ground = self._lookup(torch.zeros_like(r_hit), -mu_ground, table)
            # (additive columns: exact; optical depths: exact for linear species only)
            value = up.index_put((hits,), torch.clamp(from_ground - up[hits], min=0.0))
        value = value.reshape(*shape, value.shape[-1])
        if table is None:
            return value
        columns = dict(zip(self.constituents.names, value.unbind(-1), strict=True))
        return self.constituents.optical_depth(columns)

    def transmittance(self, zenith_rad, altitude_m=0.0, *, wavelength_nm=None
                      ) -> torch.Tensor:
        r""":math:`e^{-\tau}` of :meth:`optical_depth` (..., wavelength) [1]."""
        return torch.exp(-self.optical_depth(zenith_rad, altitude_m,
                                             wavelength_nm=wavelength_nm))
