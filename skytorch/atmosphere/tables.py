"""Transmittance look-up table (Bruneton parametrisation) with a disk cache.

The table stores the optical depth from a point at radius :math:`r` along direction
cosine :math:`\\mu` to the top of the atmosphere, for rays that do not meet the ground,
on the texture coordinates of Bruneton (ref. 1, ``GetTransmittanceTextureUvFromRMu``):

.. math::

    H = \\sqrt{R_t^2 - R^2},\\quad \\rho = \\sqrt{r^2 - R^2},\\quad x_r = \\rho / H,

    d_{min} = R_t - r,\\quad d_{max} = \\rho + H,\\quad
    x_\\mu = (d - d_{min})/(d_{max} - d_{min}),

with :math:`d` the distance to the top. Samples lie on the unit range, including both
ends; along :math:`x_\\mu` they are uniform (:math:`x = k/(n-1)`). Along :math:`x_r` they
have nodes at the altitudes where a density profile has a kink (the ozone tent's base,
peak and top) and are graded towards the kink above them (:func:`radius_nodes`): below
a kink the column of near-horizontal rays behaves like :math:`(h_k - h)^{3/2}`, and
uniform samples interpolated it with 20 % errors at 256 x 64 (ozone at 595 nm, 40 km).
Look-ups interpolate bilinearly in :math:`(x_r, x_\\mu)`. Optical depths between two
points, and to the ground, follow from differences of two look-ups (ref. 1,
``GetTransmittance``). Because the per-species path integrals do not depend on
wavelength, the table's cost is that of ``n_r * n_mu`` rays times three species.

Tables are cached on disk as netCDF files named by a SHA-256 hash of every parameter
that affects them (the atmosphere's parameters, the wavelengths, the resolution, the
quadrature and a format version). The cache directory is ``$SKYTORCH_CACHE_DIR`` or
``~/.cache/skytorch``. A file that cannot be read, or whose stored key, shapes or values
do not match, is rebuilt.

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

from skytorch._validate import check_finite, check_int, common_dtype
from skytorch.atmosphere.geometry import (
    distance_to_ground,
    ray_hits_ground,
    texture_coordinates,
    texture_rays,
)
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
    "cache_directory",
    "cached_transmittance_table",
    "radius_nodes",
    "table_key",
    "transmittance_table",
]

logger = logging.getLogger(__name__)

#: bump when the layout or the numerics of the table change (invalidates caches)
TABLE_FORMAT_VERSION = 2

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
    """The :math:`x_r = \\rho/H` samples of a table (n_r,), kinks of the profiles on nodes.

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
    kinks = atmosphere._levels("ozone", torch.float64).reshape(-1).tolist()
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


def transmittance_table(atmosphere, wavelength_nm, *, n_mu: int = 256, n_r: int = 64,
                        method: str = "gauss", n_steps: int | None = None):
    """Compute the transmittance table as a Dataset.

    Parameters
    ----------
    atmosphere : Atmosphere
        With scalar (unbatched) parameters.
    wavelength_nm : Tensor (wavelength,)
        Wavelengths [nm].
    n_mu, n_r : int
        Samples along :math:`x_\\mu` and :math:`x_r` (Bruneton: 256 x 64).
    method, n_steps
        Quadrature of the column integrals (:meth:`Atmosphere.optical_depth`).

    Returns
    -------
    xarray.Dataset
        Dims ``x_r``, ``x_mu``, ``wavelength``; variables ``optical_depth``,
        ``transmittance`` (x_r, x_mu, wavelength), ``altitude`` (x_r) [m],
        ``zenith_angle`` (x_r, x_mu) [degree]; attribute ``cache_key``.
    """
    n_mu = check_int("n_mu", n_mu, 2)
    n_r = check_int("n_r", n_r, 2)
    if atmosphere.batch_shape != ():
        raise ValueError("transmittance tables need an Atmosphere with scalar parameters; "
                         f"got batch shape {tuple(atmosphere.batch_shape)} (loop over the "
                         "sweep)")
    wavelength = atmosphere._wavelength(wavelength_nm, torch.float64)
    x_r = radius_nodes(atmosphere, n_r)
    x_mu = torch.linspace(0.0, 1.0, n_mu, dtype=torch.float64)
    altitude, mu = texture_rays(x_r[:, None], x_mu[None, :], atmosphere.planet_radius_m,
                                atmosphere.top_radius_m)
    # the last column is the ray tangent to the ground: nudge it above the horizon so that
    # it counts as reaching the top (continuity with its neighbours)
    mu = torch.where(x_mu[None, :] == 1.0, mu * (1.0 - 1e-12), mu)
    tau = atmosphere.optical_depth(wavelength, torch.acos(mu), altitude, method=method,
                                   n_steps=n_steps)
    key = table_key(atmosphere, wavelength, n_mu, n_r, method, n_steps)
    data_vars = {
        "optical_depth": variable(("x_r", "x_mu", "wavelength"), tau, VariableSpec(
            "1", "optical depth to the top of the atmosphere",
            "Slant optical depth from (r, mu) to the top of the atmosphere along a straight "
            "ray (all constituents).")),
        "transmittance": variable(("x_r", "x_mu", "wavelength"), torch.exp(-tau), VariableSpec(
            "1", "transmittance to the top of the atmosphere",
            "exp(-optical_depth).", "atmosphere_transmittance")),
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
    }
    parameters = dict(atmosphere.parameters_dict())
    parameters.update({"n_mu": n_mu, "n_r": n_r, "method": method,
                       "n_steps": -1 if n_steps is None else n_steps,
                       "table_format": TABLE_FORMAT_VERSION})
    return build_dataset(data_vars, coords, title="Transmittance look-up table",
                         references=_REFERENCES, parameters=parameters, cache_key=key)


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
    """The transmittance table from the disk cache, computed and stored if absent or bad.

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

    wavelength = atmosphere._wavelength(wavelength_nm, torch.float64)
    key = table_key(atmosphere, wavelength, n_mu, n_r, method, n_steps)
    directory = Path(cache_dir) if cache_dir is not None else cache_directory()
    path = directory / f"transmittance_{key[:24]}.nc"
    if path.is_file():
        try:
            dataset = open_dataset(path)
        except Exception as error:  # noqa: BLE001 - any unreadable file is rebuilt
            logger.warning("unreadable table cache %s (%s); rebuilding", path, error)
        else:
            if _valid(dataset, key, wavelength.numel(), n_mu, n_r):
                logger.debug("transmittance table from cache %s", path)
                return dataset
            logger.warning("stale or inconsistent table cache %s; rebuilding", path)
    disable = (not os.isatty(2)) if progress is None else not progress
    with tqdm(total=1, desc="transmittance table", disable=disable) as bar:
        dataset = transmittance_table(atmosphere, wavelength, n_mu=n_mu, n_r=n_r,
                                      method=method, n_steps=n_steps)
        bar.update(1)
    to_netcdf(dataset, path)
    logger.info("transmittance table written to %s", path)
    return dataset


class TransmittanceTable(nn.Module):
    """Batched bilinear look-ups in a transmittance table.

    Parameters
    ----------
    optical_depth : Tensor (x_r, x_mu, wavelength)
        Table of optical depths to the top.
    wavelength_nm : Tensor (wavelength,)
        Its wavelengths [nm].
    planet_radius_m, top_radius_m : float
        Radii the table was computed for [m].
    x_r : Tensor (x_r,), optional
        The increasing :math:`x_r` samples from 0 to 1 (default uniform).
    """

    def __init__(self, optical_depth, wavelength_nm, planet_radius_m: float,
                 top_radius_m: float, x_r=None):
        super().__init__()
        self.register_buffer("table", torch.tensor(np.array(optical_depth, dtype=np.float64)))
        self.register_buffer("wavelength_nm",
                             torch.tensor(np.array(wavelength_nm, dtype=np.float64)))
        n_r = self.table.shape[0]
        nodes = (torch.linspace(0.0, 1.0, n_r, dtype=torch.float64) if x_r is None
                 else torch.tensor(np.array(x_r, dtype=np.float64)))
        if nodes.shape != (n_r,) or not bool((nodes[1:] > nodes[:-1]).all()):
            raise ValueError(f"x_r must be {n_r} increasing samples; got {nodes.tolist()}")
        self.register_buffer("x_r", nodes)
        self.planet_radius_m = float(planet_radius_m)
        self.top_radius_m = float(top_radius_m)

    @classmethod
    def from_dataset(cls, dataset) -> TransmittanceTable:
        """From a Dataset of :func:`transmittance_table` (or the cache)."""
        parameters = json.loads(dataset.attrs["parameters"])
        planet = parameters["planet_radius_m"]
        return cls(dataset["optical_depth"].values, dataset["wavelength"].values, planet,
                   planet + parameters["top_altitude_m"], dataset["x_r"].values)

    @classmethod
    def build(cls, atmosphere, wavelength_nm, *, cache: bool = False, **kwargs
              ) -> TransmittanceTable:
        """Compute (or, with ``cache=True``, load from the disk cache) a table."""
        if cache:
            dataset = cached_transmittance_table(atmosphere, wavelength_nm, **kwargs)
        else:
            dataset = transmittance_table(atmosphere, wavelength_nm, **kwargs)
        return cls.from_dataset(dataset)

    def _lookup(self, altitude, mu):
        """Bilinear interpolation at (altitude, mu) (rays missing the ground) -> (...,
        wavelength)."""
        x_r, x_mu = texture_coordinates(altitude, mu, self.planet_radius_m, self.top_radius_m)
        x_r, x_mu = torch.clamp(x_r, 0.0, 1.0), torch.clamp(x_mu, 0.0, 1.0)
        table = self.table.to(x_r.dtype)
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

    def optical_depth(self, zenith_rad, altitude_m=0.0) -> torch.Tensor:
        """Optical depth from the observer to the top or to the ground (..., wavelength).

        Parameters
        ----------
        zenith_rad : Tensor (...)
            Zenith angle of the view direction [rad].
        altitude_m : Tensor (...)
            Observer altitude [m], between 0 and the top.

        Notes
        -----
        Rays meeting the ground at :math:`(R, \\mu_g)`:
        :math:`\\tau = \\tau_{top}(R, -\\mu_g) - \\tau_{top}(r, -\\mu)` (ref. 1).
        """
        dtype = common_dtype(zenith_rad, altitude_m)
        zenith = check_finite("zenith_rad", zenith_rad, dtype=dtype)
        altitude = check_finite("altitude_m", altitude_m, dtype=dtype)
        r = self.planet_radius_m + altitude
        mu = torch.cos(zenith)
        r, mu = torch.broadcast_tensors(r, mu)
        hits = ray_hits_ground(r, mu, self.planet_radius_m)
        up = self._lookup(r - self.planet_radius_m, torch.where(hits, -mu, mu))
        d = distance_to_ground(r, mu, self.planet_radius_m)
        planet = self.planet_radius_m
        # mu at the ground point (looking down) from r mu + d = R mu_g
        mu_ground = torch.clamp((r * mu + d) / planet, -1.0, 0.0)
        from_ground = self._lookup(torch.zeros_like(r), -mu_ground)
        down = torch.clamp(from_ground - up, min=0.0)
        return torch.where(hits[..., None], down, up)

    def transmittance(self, zenith_rad, altitude_m=0.0) -> torch.Tensor:
        """:math:`e^{-\\tau}` of :meth:`optical_depth` (..., wavelength) [1]."""
        return torch.exp(-self.optical_depth(zenith_rad, altitude_m))
