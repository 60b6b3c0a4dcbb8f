r"""Skyglow of whole cities by PCA + azimuthal FFT convolution (Dobashi et al. 2023 §3.3).

:meth:`SkyglowModel.precompute` tabulates the single-scattering kernel
(:mod:`skytorch.skyglow.kernel`) on a grid of view azimuths θ, elevations φ, source
distances r, source altitudes h_c and observer altitudes h_o, compresses the images of
each observer altitude with PCA (:mod:`skytorch.skyglow.basis`) and keeps the basis
images' Fourier transforms over azimuth. :meth:`SkyglowModel.render` then evaluates

.. math::

    L(θ, φ) = \sum_k \mathcal F^{-1}_θ\big[\mathcal F_θ[H_k]\,\mathcal F_θ[B_k]\big],
    \qquad H_k(θ_c) = \sum_{r, h_c} F(θ_c, r, h_c)\, c_k(r, h_c)

(eq. 7–9, with eq. 8's radial integral as a sum over the polar cells' flux ``F``).

Conventions: ``x`` is east and ``y`` north [m]; azimuth is measured from north through
east; elevation cells are centred, ``φ_j = (j + ½) 90°/N_φ``; azimuths are
``θ_i = i 360°/N_θ``. A lighting cell's flux is distributed (bilinearly, conserving flux)
over the four polar nodes around it — in azimuth, distance and, with a terrain, source
altitude; cells beyond ``max_distance_m`` are ignored and cells closer than the first
distance node are assigned to it.

The kernel is symmetric about the source's azimuth, b(θ) = b(−θ): only
``N_θ//2 + 1`` azimuths are integrated and the rest mirrored, and the bases' Fourier
transforms are real, so only their real parts are stored.

References
----------
1. Dobashi, Y., Ishikawa, N. & Iwasaki, K. 2023, ACM Trans. Graph. 42, 219,
   doi:10.1145/3618337.
2. Garstang, R. H. 1986, PASP 98, 364, doi:10.1086/131768.
"""

from __future__ import annotations

import json
import logging
import math
import os
import sys
import time
import warnings
from collections.abc import Mapping

import numpy as np
import torch
from torch import nn

from skytorch._angles import wrap_to_turn
from skytorch._validate import (
    as_tensor,
    check_choice,
    check_finite,
    check_flag,
    check_int,
    check_positive,
    check_range,
    refuse_gradient,
)
from skytorch.constants import NATURAL_MAG_RANGE
from skytorch.skyglow.basis import fit_basis, resolve_components
from skytorch.skyglow.kernel import EMISSION_FUNCTIONS, Medium, converged_steps, kernel_radiance
from skytorch.skyglow.lamps import luminance_weights
from skytorch.skyglow.multiple_scattering import higher_order_radiance
from skytorch.skyglow.units import (
    NATURAL_ZENITH_SKY_MAG_ARCSEC2,
    artificial_to_natural_ratio,
    naked_eye_limiting_magnitude,
    total_mag_arcsec2,
)

__all__ = ["DISTANCE_SPACINGS", "RESAMPLINGS", "SkyglowModel", "SplatPlan", "light_map_arrays"]

logger = logging.getLogger(__name__)

#: how the distance nodes are spaced
DISTANCE_SPACINGS = ("linear", "quadratic")

#: how a light map is resampled to the polar grid (see ``SkyglowModel.radiance_per_lumen``)
RESAMPLINGS = ("splat", "sample")

REFERENCES = (
    "Dobashi, Y., Ishikawa, N. & Iwasaki, K. 2023, Efficient Visualization of Light "
    "Pollution for the Night Sky, ACM Trans. Graph. 42, 219, doi:10.1145/3618337",
    "Garstang, R. H. 1986, Model for artificial night-sky illumination, PASP 98, 364, "
    "doi:10.1086/131768",
    "Falchi, F. et al. 2016, The new world atlas of artificial night sky brightness, "
    "Sci. Adv. 2, e1600377, doi:10.1126/sciadv.1600377",
)


def _grid(n: int, value_range) -> torch.Tensor:
    low, high = (float(v) for v in value_range)
    if n == 1:
        return torch.tensor([low], dtype=torch.float64)
    return torch.linspace(low, high, n, dtype=torch.float64)


def distance_edges(max_distance_m: float, n_distance: int, spacing: str) -> torch.Tensor:
    """Edges of the distance cells [m] (n_distance + 1,)."""
    check_choice("distance_spacing", spacing, DISTANCE_SPACINGS)
    x = torch.linspace(0.0, 1.0, n_distance + 1, dtype=torch.float64)
    return max_distance_m * (x if spacing == "linear" else x**2)


def _linear_weights(grid: torch.Tensor, value: torch.Tensor):
    """Return the lower index and the upper node's weight of linear interpolation on ``grid``.

    Values beyond the grid are clamped to its ends.
    """
    n = grid.numel()
    if n == 1:
        return torch.zeros_like(value, dtype=torch.long), torch.zeros_like(value)
    grid = grid.to(value.dtype)
    j = (torch.searchsorted(grid, value.detach().contiguous(), right=True) - 1).clamp(0, n - 2)
    w = ((value - grid[j]) / (grid[j + 1] - grid[j])).clamp(0.0, 1.0)
    return j, w


#: from this many observers on, :meth:`SkyglowModel.convolve` keeps them innermost
_MANY_OBSERVERS = 16

#: largest splat plan (corner × observer × cell entries) that a model keeps for reuse
SPLAT_PLAN_ENTRIES = 2**21



def _plain(value, single: bool):
    """Observer positions/altitudes for the Dataset attributes, as given by the user."""
    value = torch.as_tensor(value).detach()
    return value[0].tolist() if single and value.ndim >= 1 and value.shape[0] == 1 else (
        value.tolist())


#: tolerance beyond the tabulated altitude range before a warning [m]
_ALTITUDE_SLACK_M = 1.0


def _warn_outside(name: str, values: torch.Tensor, grid: torch.Tensor) -> None:
    """Warn when altitudes fall outside the tabulated range (they are clamped to it)."""
    if values.numel() == 0:
        return
    with torch.no_grad():
        low, high = float(grid[0]), float(grid[-1])
        outside = (values < low - _ALTITUDE_SLACK_M) | (values > high + _ALTITUDE_SLACK_M)
        if bool(outside.any()):
            warnings.warn(
                f"{name}: {int(outside.sum())} value(s) outside the model's tabulated range "
                f"[{low:g}, {high:g}] m (e.g. {float(values[outside][0]):g} m) are clamped "
                "to it; precompute with a wider altitude range", UserWarning, stacklevel=4)


#: bound on |x| and |y| of observer positions in the map frame [m]: the flat map of
#: :mod:`skytorch.skyglow` means nothing beyond the Earth's radius
OBSERVER_XY_LIMIT_M = 1.0e7
#: highest observer altitude [m]: the top of the atmosphere of the kernels
#: (:class:`skytorch.skyglow.kernel.Medium` of an Earth atmosphere)
OBSERVER_ALTITUDE_MAX_M = 100_000.0


def check_model(name: str, model) -> SkyglowModel:
    """Return ``model`` if it is a :class:`SkyglowModel`, else raise ``TypeError``."""
    if not isinstance(model, SkyglowModel):
        raise TypeError(f"{name} must be a SkyglowModel (SkyglowModel.precompute or "
                        f"SkyglowModel.load); got {type(model).__name__}: {model!r:.60}")
    return model


def observer_positions(observer_xy, dtype: torch.dtype | None = None
                       ) -> tuple[torch.Tensor, bool]:
    """Observer positions as an (observer, 2) tensor, and whether one (2,) was given.

    Raises
    ------
    TypeError
        For non-numeric input.
    ValueError
        For NaN/inf, |x| or |y| above :data:`OBSERVER_XY_LIMIT_M`, or a shape other than
        (2,) or (observer, 2) with at least one observer.
    """
    xy = check_range("observer_xy", observer_xy, -OBSERVER_XY_LIMIT_M, OBSERVER_XY_LIMIT_M,
                     unit=" m", dtype=dtype)
    if xy.ndim == 1 and xy.shape[0] == 2:
        return xy.reshape(1, 2), True
    if xy.ndim == 2 and xy.shape[1] == 2 and xy.shape[0] >= 1:
        return xy, False
    raise ValueError(f"observer_xy must have shape (2,) or (observer, 2) [m]; got shape "
                     f"{tuple(xy.shape)}")


def observer_altitudes(observer_altitude_m, n_observers: int,
                       dtype: torch.dtype | None = None) -> torch.Tensor:
    """Observer altitudes (observer,) [m]: one value for all observers or one for each.

    Raises ``ValueError`` for NaN/inf, values outside [0, :data:`OBSERVER_ALTITUDE_MAX_M`]
    or a count other than 1 or ``n_observers``.
    """
    h_o = check_range("observer_altitude_m", observer_altitude_m, 0.0, OBSERVER_ALTITUDE_MAX_M,
                      unit=" m", dtype=dtype)
    if h_o.ndim > 1 or h_o.numel() not in (1, n_observers):
        raise ValueError(f"observer_altitude_m must be one value or one per observer "
                         f"({n_observers},); got shape {tuple(h_o.shape)}")
    return h_o.reshape(-1).expand(n_observers) if h_o.numel() == 1 else h_o.reshape(-1)


def _stack_fits(fits, image_shape, sample_shape):
    """Stack per-observer-altitude PCA fits, padding with zero components to a common M.

    Returns basis (ho, K, *image_shape), coefficients (ho, *sample_shape, K) and the
    explained variance ratio (ho, K - 1).
    """
    n_ho, n_k = len(fits), max(f.basis.shape[0] for f in fits)
    basis = torch.zeros(n_ho, n_k, *image_shape, dtype=torch.float64)
    coefficients = torch.zeros(n_ho, *sample_shape, n_k, dtype=torch.float64)
    ratio = torch.zeros(n_ho, n_k - 1, dtype=torch.float64)
    for j, fit in enumerate(fits):
        k = fit.basis.shape[0]
        basis[j, :k] = fit.basis.reshape(k, *image_shape)
        coefficients[j, ..., :k] = fit.coefficients.reshape(*sample_shape, k)
        ratio[j, :k - 1] = fit.explained_variance_ratio
    return basis, coefficients, ratio


def _check_tables(model) -> None:
    """Raise ``ValueError`` unless the model's buffers have consistent shapes, finite values.

    A truncated or corrupted file must not become a model.
    """
    sizes = {name: getattr(model, name).numel() for name in (
        "azimuth_rad", "elevation_rad", "distance_m", "distance_edges_m",
        "source_altitude_m", "observer_altitude_m", "wavelength_nm")}
    problems = _shape_problems(model, sizes)
    for name in ("azimuth_rad", "elevation_rad", "distance_m", "distance_edges_m",
                 "source_altitude_m", "observer_altitude_m", "wavelength_nm", "basis",
                 "coefficients", "explained_variance_ratio"):
        if not bool(torch.isfinite(getattr(model, name)).all()):
            problems.append(f"{name} holds NaN or infinite values")
    if not problems:
        problems = _grid_problems(model)
    if problems:
        raise ValueError("the skyglow model's tables are inconsistent (a corrupted or "
                         "truncated file?): " + "; ".join(problems))


def _shape_problems(model, sizes: dict[str, int]) -> list[str]:
    """List how the shapes of the model's tables disagree with its grids."""
    n_t, n_p, n_r = sizes["azimuth_rad"], sizes["elevation_rad"], sizes["distance_m"]
    n_hc, n_ho, n_wl = (sizes["source_altitude_m"], sizes["observer_altitude_m"],
                        sizes["wavelength_nm"])
    basis, coefficients = model.basis, model.coefficients
    problems = []
    if basis.ndim != 5 or tuple(basis.shape[:1]) + tuple(basis.shape[2:]) != (
            n_ho, n_t, n_p, n_wl):
        problems.append(f"basis has shape {tuple(basis.shape)}, expected "
                        f"({n_ho}, component, {n_t}, {n_p}, {n_wl})")
    elif coefficients.shape != (n_ho, n_r, n_hc, basis.shape[1]):
        problems.append(f"coefficients have shape {tuple(coefficients.shape)}, expected "
                        f"({n_ho}, {n_r}, {n_hc}, {basis.shape[1]})")
    if sizes["distance_edges_m"] != n_r + 1:
        problems.append(f"{sizes['distance_edges_m']} distance edges for {n_r} distances")
    if min(n_t, n_p, n_r, n_hc, n_ho, n_wl) < 1 or n_t < 2:
        problems.append(f"empty grid (sizes {sizes})")
    return problems


def _grid_problems(model) -> list[str]:
    """List how the model's grids depart from uniform azimuths and increasing nodes."""
    problems = []
    n_t = model.azimuth_rad.numel()
    steps = torch.diff(model.azimuth_rad)
    uniform = bool(torch.allclose(steps, torch.full_like(steps, 2 * math.pi / n_t),
                                  rtol=1e-9, atol=1e-12))
    if not uniform or abs(float(model.azimuth_rad[0])) > 1e-12:
        problems.append("azimuth_rad is not the uniform grid i 2π/N from 0")
    for name in ("distance_edges_m", "source_altitude_m", "observer_altitude_m"):
        values = getattr(model, name)
        if values.numel() > 1 and not bool((torch.diff(values) > 0).all()):
            problems.append(f"{name} is not increasing")
    return problems


def polar_offsets(dx: torch.Tensor, dy: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Return the distance and azimuth of cells east ``dx`` and north ``dy`` of an observer.

    The distance is ``√(dx² + dy²)`` [m], the azimuth ``atan2(dx, dy)`` in [0, 2π) [rad].

    Differentiable everywhere: for a cell exactly at the observer (r = 0, where neither
    is differentiable) the distance 0 and azimuth 0 come with zero gradients instead of
    the NaN of ``sqrt`` and ``atan2`` at the origin.
    """
    r2 = dx * dx + dy * dy
    at_observer = r2 == 0
    safe_dx = torch.where(at_observer, torch.ones_like(dx), dx)
    r = torch.sqrt(torch.where(at_observer, torch.ones_like(r2), r2))
    r = torch.where(at_observer, torch.zeros_like(r), r)
    azimuth = wrap_to_turn(torch.atan2(safe_dx, dy), 2 * math.pi)
    return r, torch.where(at_observer, torch.zeros_like(azimuth), azimuth)


def _dataset_light_map(light_map):
    """Return flux (y, x), x (x,), y (y,) and altitude (y, x) or None of a Dataset map [m]."""
    missing = [k for k in ("flux", "x", "y") if k not in light_map]
    if missing:
        raise ValueError(f"light_map must have a variable 'flux' on (y, x) with "
                         f"coordinates 'x' and 'y' [m]; missing {missing}")
    if set(light_map["flux"].dims) != {"y", "x"}:
        raise ValueError(f"light_map flux must have the dimensions (y, x); got "
                         f"{light_map['flux'].dims}")
    da = light_map["flux"].transpose("y", "x")
    if not (np.issubdtype(da.dtype, np.floating) or np.issubdtype(da.dtype, np.integer)):
        # a mask (bool) or text is not a flux in lumens
        raise TypeError(f"light_map['flux'] must hold numbers [lm]; got dtype {da.dtype}")
    for name in ("x", "y", "altitude"):
        units = light_map[name].attrs.get("units") if name in light_map else None
        if units is not None and str(units).strip() not in ("m", "metre", "meter", "metres",
                                                           "meters"):
            raise ValueError(f"light_map['{name}'] must be in metres (units 'm'); got units "
                             f"{units!r}")
    flux = torch.tensor(np.array(da.values, dtype=np.float64))
    x_m = torch.tensor(np.array(light_map["x"].values, dtype=np.float64))
    y_m = torch.tensor(np.array(light_map["y"].values, dtype=np.float64))
    altitude_m = None
    if "altitude" in light_map:
        altitude_m = torch.tensor(np.array(
            light_map["altitude"].transpose("y", "x").values, dtype=np.float64))
    return flux, x_m, y_m, altitude_m


def light_map_arrays(light_map, x_m=None, y_m=None, altitude_m=None):
    """Cell coordinates and fluxes of a light map, validated.

    Parameters
    ----------
    light_map : xarray.Dataset or Tensor (y, x)
        A Dataset with variable ``flux`` [lm] on dimensions ``(y, x)`` with coordinates in
        metres east (``x``) and north (``y``), and optionally ``altitude`` [m] on the same
        grid; or a flux tensor with ``x_m`` and ``y_m`` given.
    x_m, y_m : Tensor (x,), (y,)
        Cell-centre coordinates for a tensor map [m].
    altitude_m : Tensor (y, x), optional
        Source altitudes for a tensor map [m].

    Returns
    -------
    dict with Tensors ``flux``, ``x``, ``y``, ``altitude`` (all (y, x): per cell) and the
    coordinates ``x_coord (x,)``, ``y_coord (y,)``.

    Raises
    ------
    ValueError
        For NaN/infinite or negative flux (naming the cell), NaN/infinite coordinates, a
        Dataset without ``flux``/``x``/``y``, or mismatched shapes.
    TypeError
        For a light map that is neither a Dataset nor numeric.
    """
    if not isinstance(light_map, torch.Tensor) and hasattr(light_map, "data_vars"):
        given = [name for name, value in (("x_m", x_m), ("y_m", y_m)) if value is not None]
        if given:
            raise ValueError(f"{', '.join(given)}: coordinates of a tensor light_map; a "
                             f"Dataset light_map has its own x and y")
        flux, x_m, y_m, dataset_altitude = _dataset_light_map(light_map)
        if dataset_altitude is not None and altitude_m is not None:
            raise ValueError("altitude_m: the Dataset light_map has its own 'altitude'; give "
                             "one of them")
        altitude_m = altitude_m if dataset_altitude is None else dataset_altitude
    else:
        flux = as_tensor("light_map", light_map)
        if x_m is None or y_m is None:
            raise ValueError("a tensor light_map needs x_m and y_m coordinates [m]")
        x_m = as_tensor("x_m", x_m, dtype=flux.dtype).reshape(-1)
        y_m = as_tensor("y_m", y_m, dtype=flux.dtype).reshape(-1)
    check_finite("x_m", x_m)
    check_finite("y_m", y_m)
    if flux.ndim != 2 or flux.shape != (y_m.numel(), x_m.numel()):
        raise ValueError(f"light_map flux must have shape (y, x) = ({y_m.numel()}, "
                         f"{x_m.numel()}) (the lengths of y_m and x_m); got "
                         f"{tuple(flux.shape)}")
    with torch.no_grad():
        for bad, what in ((~torch.isfinite(flux), "finite"), (flux < 0, "non-negative")):
            if bool(bad.any()):
                iy, ix = (int(i) for i in torch.nonzero(bad)[0])
                raise ValueError(
                    f"light_map flux must be {what}; cell (y={iy}, x={ix}) at "
                    f"x={float(x_m[ix]):.6g} m, y={float(y_m[iy]):.6g} m has "
                    f"{float(flux[iy, ix])!r} lm ({int(bad.sum())} offending cell"
                    f"{'s' * (int(bad.sum()) > 1)})")
    if altitude_m is None:
        altitude_m = torch.zeros_like(flux)
    else:
        altitude_m = check_range("altitude_m", altitude_m, unit=" m").to(flux.dtype)
        if tuple(altitude_m.shape) != tuple(flux.shape):
            raise ValueError(f"altitude_m must have the light_map flux's shape "
                             f"{tuple(flux.shape)}; got {tuple(altitude_m.shape)}")
    x_m, y_m = x_m.to(flux.dtype), y_m.to(flux.dtype)
    return {"flux": flux, "x": x_m[None, :].expand_as(flux), "y": y_m[:, None].expand_as(flux),
            "altitude": altitude_m, "x_coord": x_m, "y_coord": y_m}


class SplatPlan:
    """Indices and weights that splat cell fluxes onto an observer set's polar nodes.

    Built by :meth:`SkyglowModel.splat_plan`; :meth:`apply` maps fluxes (cell,) to
    (observer, azimuth, distance, source_altitude) [lm] with one gather, one multiply and
    one ``index_add`` over int32 indices.

    Attributes
    ----------
    index : Tensor (corner · pair,)
        Flat polar node of each corner of each (observer, cell) pair.
    weight : Tensor (corner, pair)
        Bilinear weights (zero beyond ``max_distance_m``).
    cell : Tensor (pair,)
        Cell of each pair.
    """

    def __init__(self, *, index, weight, cell, shape, n_cells, outside_cells, altitude_m,
                 source_altitude_m):
        self.index, self.weight, self.cell = index, weight, cell
        self.shape, self.n_cells = tuple(shape), int(n_cells)
        self._outside_cells, self._altitude = outside_cells, altitude_m
        self._source_altitude_m = source_altitude_m

    @property
    def n_entries(self) -> int:
        """Number of (corner, observer, cell) entries."""
        return self.index.numel()

    def apply(self, flux: torch.Tensor) -> torch.Tensor:
        """Map cell fluxes ``flux`` (cell,) [lm] to polar node fluxes [lm].

        The result is (observer, azimuth, distance, source_altitude), differentiable in
        ``flux``.
        """
        flux = flux.reshape(-1)
        if flux.numel() != self.n_cells:
            raise ValueError(f"flux must have {self.n_cells} cells; got {flux.numel()}")
        if self._outside_cells.numel():
            lit = flux.detach()[self._outside_cells] != 0
            _warn_outside("source altitude", self._altitude[self._outside_cells[lit]],
                          self._source_altitude_m)
        values = self.weight.to(flux.dtype) * flux.index_select(0, self.cell)
        n_t, n_r, n_h, n_obs = self.shape
        out = values.new_zeros(n_t * n_r * n_h * n_obs)
        out.index_add_(0, self.index, values.reshape(-1))
        return out.reshape(n_t, n_r, n_h, n_obs).permute(3, 0, 1, 2)


def _radiance_description(parameters: Mapping) -> str:
    """Describe the panorama's radiance: which orders of scattering it holds."""
    orders = parameters.get("scattering_orders", 1)
    times = "any number of" if orders == "converged" else f"up to {orders}"
    light = ("Singly scattered light of the city lights" if orders == 1 else
             f"Light of the city lights scattered {times} times (single-scattering kernel "
             "plus the Monte-Carlo radiance of the higher orders)")
    return (f"{light} (PCA + FFT convolution, Dobashi et al. 2023), lamp power averaged "
            "over each wavelength's band.")


def _multiple_scattering_record(summaries, n_paths: int) -> dict:
    """Summarise the Monte-Carlo factors of the observer altitudes (for attrs).

    Only the coarse grid and the factors' range and largest error: the record is
    serialised into every rendered Dataset's attributes, so it stays small;
    :func:`~skytorch.skyglow.multiple_scattering.higher_order_radiance` gives the
    factors themselves.
    """
    first = summaries[0]
    return {
        "method": "backward Monte Carlo, skytorch.skyglow.multiple_scattering",
        "paths_per_line_of_sight": n_paths, "orders": first["orders"],
        "distance_m": first["distance_m"].tolist(),
        "azimuth_deg": torch.rad2deg(first["azimuth_rad"]).tolist(),
        "elevation_deg": torch.rad2deg(first["elevation_rad"]).tolist(),
        "factor_min": min(float(s["factor"].min()) for s in summaries),
        "factor_max": max(float(s["factor"].max()) for s in summaries),
        "largest_error": max(float(s["factor_error"].max()) for s in summaries),
    }


def _check_medium(medium, atmosphere, wavelength_nm, phase_functions) -> None:
    """ValueError where ``precompute``'s own settings differ from the reused medium's."""
    if not isinstance(medium, Medium):
        raise TypeError(f"medium must be a skytorch.skyglow.kernel.Medium; got "
                        f"{type(medium).__name__}")
    own = medium.atmosphere
    same = atmosphere is own or (
        callable(getattr(atmosphere, "parameters_dict", None))
        and callable(getattr(own, "parameters_dict", None))
        and atmosphere.parameters_dict() == own.parameters_dict())
    if not same:
        raise ValueError("atmosphere must be the one the medium was built from (the kernel "
                         "uses the medium's tables); got another atmosphere")
    if wavelength_nm is not None:
        asked = as_tensor("wavelength_nm", wavelength_nm, dtype=torch.float64).reshape(-1)
        if asked.shape != medium.wavelength_nm.shape or not torch.equal(
                asked, medium.wavelength_nm):
            raise ValueError(f"wavelength_nm must be omitted or the medium's "
                             f"{medium.wavelength_nm.tolist()} nm; got {asked.tolist()}")
    if phase_functions is not None:
        raise ValueError("phase_functions must be omitted with a medium (it holds its own)")


class SkyglowModel(nn.Module):
    """Precomputed PCA + FFT skyglow tables for one atmosphere.

    Build it with :meth:`precompute` (or :meth:`load`); render with :meth:`render`.

    Buffers
    -------
    azimuth_rad (azimuth,), elevation_rad (elevation,), distance_m (distance,),
    distance_edges_m (distance + 1,), source_altitude_m (source_altitude,),
    observer_altitude_m (observer_altitude,), wavelength_nm (wavelength,);
    basis (observer_altitude, component, azimuth, elevation, wavelength) with component 0
    the mean image and coefficients (observer_altitude, distance, source_altitude,
    component), whose product is the kernel per unit flux [m^-2 sr^-1]: with
    ``normalize=True`` (the default) the basis of the normalised kernels is [1] and the
    coefficients carry [m^-2 sr^-1], with ``normalize=False`` the other way round;
    basis_fft (observer_altitude, frequency, component, elevation · wavelength), the real
    Fourier transform of the bases over azimuth;
    pollution_level (observer_altitude, distance, source_altitude), Q of eq. 10.

    Examples
    --------
    >>> from skytorch.atmosphere import Atmosphere
    >>> from skytorch.skyglow.citymap import synthetic_city
    >>> model = SkyglowModel.precompute(Atmosphere.earth(turbidity=2.0), n_azimuth=16,
    ...                                 n_elevation=4, n_distance=8, n_components=4,
    ...                                 n_steps=4, progress=False)
    >>> sky = model.render(synthetic_city(20e3, 1e3), observer_xy=(5e3, 0.0))
    >>> sky["luminance"].dims
    ('elevation', 'azimuth')
    >>> bool(sky["total_brightness"].max() < 22.0)
    True
    """

    def __init__(self, *, azimuth_rad, elevation_rad, distance_m, distance_edges_m,
                 source_altitude_m, observer_altitude_m, wavelength_nm, basis, coefficients,
                 explained_variance_ratio, parameters: Mapping[str, object]):
        super().__init__()
        for name, value in (("azimuth_rad", azimuth_rad), ("elevation_rad", elevation_rad),
                            ("distance_m", distance_m), ("distance_edges_m", distance_edges_m),
                            ("source_altitude_m", source_altitude_m),
                            ("observer_altitude_m", observer_altitude_m),
                            ("wavelength_nm", wavelength_nm), ("basis", basis),
                            ("coefficients", coefficients),
                            ("explained_variance_ratio", explained_variance_ratio)):
            self.register_buffer(name, torch.as_tensor(value, dtype=torch.float64))
        self.parameters_used = dict(parameters)
        _check_tables(self)
        self.medium: Medium | None = None
        self.kernel: torch.Tensor | None = None
        n_ho, n_k, n_t, n_p, n_wl = self.basis.shape
        spectrum = torch.fft.rfft(self.basis, dim=2)  # (ho, K, f, φ, λ)
        imaginary = float(spectrum.imag.abs().amax()) if spectrum.numel() else 0.0
        scale = float(spectrum.real.abs().amax()) if spectrum.numel() else 1.0
        if not (imaginary <= 1e-6 * max(scale, 1e-300)):  # NaN tables fail too
            raise ValueError(
                f"basis images are not mirror-symmetric (|Im FFT| / max = "
                f"{imaginary / max(scale, 1e-300):.3g}, at most 1e-6 expected): the tables "
                "are corrupted; rebuild the model with SkyglowModel.precompute")
        self.register_buffer("basis_fft", spectrum.real.permute(0, 2, 1, 3, 4).reshape(
            n_ho, n_t // 2 + 1, n_k, n_p * n_wl).contiguous())
        gram = torch.einsum("hkx,hlx->hkl", self.basis.reshape(n_ho, n_k, -1),
                            self.basis.reshape(n_ho, n_k, -1))
        q2 = torch.einsum("hrsk,hkl,hrsl->hrs", self.coefficients, gram, self.coefficients)
        self.register_buffer("pollution_level", q2.clamp_min(0.0).sqrt())
        self._cast: dict = {}

    # ------------------------------------------------------------------ construction ---
    @property
    def n_components(self) -> int:
        """Number M of principal components (the mean image not counted)."""
        return self.basis.shape[1] - 1

    @classmethod
    def precompute(cls, atmosphere, n_azimuth: int = 256, n_elevation: int = 64,  # noqa: C901 (defaults, checks)
                   max_distance_m: float = 20_000.0, n_distance: int = 128,
                   n_components=32, emission: str = "garstang1986",
                   n_source_altitude: int = 1, n_observer_altitude: int = 1, *,
                   source_altitude_range_m=(0.0, 1000.0),
                   observer_altitude_range_m=(0.0, 1000.0), wavelength_nm=None,
                   emission_parameters: Mapping[str, float] | None = None,
                   n_steps: int | None = 8, quadrature_tolerance: float = 1e-3,
                   source_radius_m: float | None = None, distance_spacing: str = "linear",
                   normalize: bool = True, phase_functions=None, progress: bool = True,
                   keep_kernel: bool = False, chunk_size: int = 4096,
                   medium: Medium | None = None, quadrature: str = "single",
                   compute_dtype: torch.dtype = torch.float64,
                   n_workers: int | None = None, scattering_orders: int | str = 1,
                   multiple_scattering_paths: int = 1000) -> SkyglowModel:
        """Tabulate kernels, fit the PCA basis and transform it over azimuth.

        Parameters
        ----------
        atmosphere : skytorch.atmosphere.Atmosphere
            One parameter set (scalar turbidity); its extinction, scattering
            coefficients and phase functions define the kernel.
        n_azimuth, n_elevation : int
            Panorama size N_θ × N_φ (Dobashi: 256 × 64).
        max_distance_m : float
            Largest source distance R [m] (Dobashi: 10 km).
        n_distance : int
            Distance cells N_r (Dobashi: 128).
        n_components : int or float
            M, or a cumulative explained-variance threshold in (0, 1).
        emission : str
            Upward emission function, one of ``EMISSION_FUNCTIONS``.
        n_source_altitude, n_observer_altitude : int
            N_hc and N_ho, spread evenly over the altitude ranges [m].
        source_altitude_range_m, observer_altitude_range_m : (float, float)
            Altitude ranges [m] (Dobashi: 0–1000 m with 16 nodes each); one node sits at
            the low end. ``parameters_used`` records the nodes' range.
        wavelength_nm : Tensor (wavelength,), optional
            Default ``spectrum.wavelength_grid("rgb")``.
        emission_parameters : mapping, optional
            ``{"F": 0.1, "G": 0.15}`` for Garstang, ``{"beam_exponent": 8}`` for Dobashi.
        quadrature : {"single", "split"}
            View-ray quadrature (see :func:`~skytorch.skyglow.kernel.kernel_radiance`).
        n_steps : int or None
            Half the Gauss nodes per view ray. Default 8 (16 nodes): against 1024 nodes
            the kernel's error is 0.014 % mean and 0.36 % at most over random geometries
            including grazing rays (``docs/accuracy.md``), far below the error of the
            map's polar resampling. ``None``: chosen by
            :func:`~skytorch.skyglow.kernel.converged_steps` for ``quadrature_tolerance``
            (1e-3 picks 32, four times the cost).
        source_radius_m : float, optional
            Regularising source radius [m]; default half the first distance cell.
        distance_spacing : {"linear", "quadratic"}
            Distance nodes evenly spaced (Dobashi) or denser near the observer.
        normalize : bool
            PCA on samples divided by their RMS (equal relative accuracy at all r).
        progress : bool
            tqdm progress bar (only on a TTY).
        keep_kernel : bool
            Keep the raw kernel tensor in ``model.kernel`` (for studies of M; memory!).
        medium : Medium, optional
            Reuse atmosphere tables built before from ``atmosphere`` (the same object, or
            one with the same ``parameters_dict()``); its wavelengths and phase functions
            are the model's, so ``wavelength_nm`` must then be omitted or the same and
            ``phase_functions`` omitted.
        compute_dtype : torch.dtype
            dtype of the kernel quadrature; the PCA and the stored tables are float64.
            float32 is about twice as fast and, with the kernel's cancellation-free
            geometry, within 0.01 % of float64 even on grazing rays (0.0073 % at most,
            ``docs/skyglow.md``): the recommended choice for large grids such as the
            paper's (``benchmarks/bench_skyglow.py --paper``).
        n_workers : int, optional
            Threads that compute observer altitudes concurrently, each with serial
            operations (torch's and the BLAS thread counts are set to 1 while they run and
            restored after). Default ``torch.get_num_threads()``; 1 computes them one after
            another with the current thread settings. The result does not depend on it.
        scattering_orders : int or "converged"
            1 (default): the single-scattering kernel of Dobashi et al. 2023. N ≥ 2 or
            ``"converged"``: the radiance of the orders 2 … N added to the kernel before the
            PCA, measured per observer altitude by backward Monte Carlo on a coarse grid of
            lines of sight and interpolated
            (:func:`~skytorch.skyglow.multiple_scattering.higher_order_radiance`, sources at
            the middle of ``source_altitude_range_m``); the coarse factors (all orders over
            the first) and their errors are summarised in
            ``parameters_used["multiple_scattering"]``.
        multiple_scattering_paths : int
            Monte-Carlo paths per coarse line of sight and wavelength (the factor's
            standard error falls as its inverse square root; ``docs/skyglow.md``).

        Returns
        -------
        SkyglowModel
        """
        n_azimuth = check_int("n_azimuth", n_azimuth, low=2)
        n_elevation = check_int("n_elevation", n_elevation, low=1)
        n_distance = check_int("n_distance", n_distance, low=1)
        n_source_altitude = check_int("n_source_altitude", n_source_altitude, low=1)
        n_observer_altitude = check_int("n_observer_altitude", n_observer_altitude, low=1)
        if n_workers is not None:
            n_workers = check_int("n_workers", n_workers, low=1)
        check_positive("max_distance_m", max_distance_m, unit=" m")
        check_choice("emission", emission, EMISSION_FUNCTIONS)
        check_choice("distance_spacing", distance_spacing, DISTANCE_SPACINGS)
        for name, value in (("source_altitude_range_m", source_altitude_range_m),
                            ("observer_altitude_range_m", observer_altitude_range_m)):
            pair = check_range(name, value, 0.0, OBSERVER_ALTITUDE_MAX_M, unit=" m",
                               dtype=torch.float64)
            if pair.shape != (2,) or float(pair[0]) > float(pair[1]):
                raise ValueError(f"{name} must be (low, high) [m] with low <= high; got "
                                 f"{value!r:.60}")
        normalize = check_flag("normalize", normalize)
        progress = check_flag("progress", progress)
        if scattering_orders != "converged":
            scattering_orders = check_int("scattering_orders", scattering_orders, low=1,
                                          high=1000)
        multiple_scattering_paths = check_int("multiple_scattering_paths",
                                              multiple_scattering_paths, low=2)
        keep_kernel = check_flag("keep_kernel", keep_kernel)
        chunk_size = check_int("chunk_size", chunk_size, low=1)
        if compute_dtype not in (torch.float64, torch.float32):
            raise TypeError(f"compute_dtype must be torch.float64 or torch.float32; got "
                            f"{compute_dtype!r:.60}")
        if medium is not None:
            _check_medium(medium, atmosphere, wavelength_nm, phase_functions)
        elif wavelength_nm is None:
            from skytorch.spectrum import wavelength_grid

            wavelength_nm = wavelength_grid("rgb")
        started = time.perf_counter()
        if medium is None:
            medium = Medium(atmosphere, wavelength_nm, phase_functions=phase_functions)
        wavelength = medium.wavelength_nm
        n_components = resolve_components(n_components, n_distance * n_source_altitude,
                                          n_azimuth * n_elevation * wavelength.numel())
        edges = distance_edges(float(max_distance_m), n_distance, distance_spacing)
        distance = 0.5 * (edges[1:] + edges[:-1])
        azimuth = torch.arange(n_azimuth, dtype=torch.float64) * (2 * math.pi / n_azimuth)
        elevation = (torch.arange(n_elevation, dtype=torch.float64) + 0.5) * (
            0.5 * math.pi / n_elevation)
        source_altitude = _grid(n_source_altitude, source_altitude_range_m)
        observer_altitude = _grid(n_observer_altitude, observer_altitude_range_m)
        if source_radius_m is None:
            source_radius_m = 0.5 * float(edges[1] - edges[0])
        kernel_arguments = {"emission": emission, "emission_parameters": emission_parameters,
                            "source_radius_m": float(source_radius_m),
                            "quadrature": quadrature}
        kernel_arguments_ms = {key: kernel_arguments[key] for key in
                               ("emission", "emission_parameters", "source_radius_m")}
        if n_steps is None:
            n_steps, change = converged_steps(medium, quadrature_tolerance, **kernel_arguments)
            logger.info("kernel quadrature: %d nodes per half ray (relative change %.2g)",
                        n_steps, change)
        n_steps = check_int("n_steps", n_steps, low=1)
        half = n_azimuth // 2 + 1
        mirror = torch.tensor([min(i, n_azimuth - i) for i in range(n_azimuth)])
        from tqdm.auto import tqdm

        bar = tqdm(total=n_observer_altitude * n_distance, desc="skyglow kernels",
                   unit="distance", disable=not progress or not sys.stderr.isatty())
        # multiplicity of the integrated azimuths in the full circle (the PCA of the half
        # images with these weights is that of the full images)
        multiplicity = torch.tensor([1.0 if i in (0, n_azimuth - i) else 2.0
                                     for i in range(half)], dtype=torch.float64)
        feature_weights = multiplicity[:, None].expand(
            half, n_elevation * wavelength.numel()).reshape(-1)
        block = max(1, 4 * chunk_size // (half * n_elevation * n_source_altitude))

        def fit_altitude(h_o):
            """Kernels and PCA of one observer altitude -> (fit, kernel or None, seconds)."""
            table = torch.empty(n_distance, n_source_altitude, half, n_elevation,
                                wavelength.numel(), dtype=torch.float64)
            clock, cpu_clock = time.perf_counter(), time.thread_time()
            for start in range(0, n_distance, block):
                stop = min(start + block, n_distance)
                values = kernel_radiance(
                    medium, azimuth[:half, None].to(compute_dtype),
                    elevation[None, :].to(compute_dtype),
                    distance[start:stop, None, None, None].to(compute_dtype),
                    source_altitude[:, None, None].to(compute_dtype), h_o.to(compute_dtype),
                    n_steps=n_steps, chunk_size=chunk_size, **kernel_arguments)
                table[start:stop] = values.to(torch.float64)
                bar.update(stop - start)
            ms_summary = None
            if scattering_orders != 1:
                higher, ms_summary = higher_order_radiance(
                    medium, distance, azimuth[:half], elevation,
                    float(source_altitude.mean()), float(h_o),
                    scattering_orders=scattering_orders, n_paths=multiple_scattering_paths,
                    **kernel_arguments_ms)
                table += higher[:, None]
            seconds = [time.perf_counter() - clock, time.thread_time() - cpu_clock]
            clock, cpu_clock = time.perf_counter(), time.thread_time()
            fit = fit_basis(table.reshape(n_distance * n_source_altitude, -1), n_components,
                            normalize=normalize, feature_weights=feature_weights)
            fit.basis = fit.basis.reshape(-1, half, n_elevation * wavelength.numel())[
                :, mirror].reshape(fit.basis.shape[0], -1)
            seconds += [time.perf_counter() - clock, time.thread_time() - cpu_clock]
            return fit, (table[:, :, mirror] if keep_kernel else None), seconds, ms_summary

        workers = min(n_workers or torch.get_num_threads(), n_observer_altitude)
        if workers > 1:
            # observer altitudes are independent: one per thread, each running its
            # operations serially (no intra-op or BLAS threads), which keeps every core
            # busy; the kernel's cache-sized chunks leave intra-op parallelism idle
            from concurrent.futures import ThreadPoolExecutor

            from threadpoolctl import threadpool_limits

            previous_threads = torch.get_num_threads()
            torch.set_num_threads(1)
            try:
                with threadpool_limits(1), ThreadPoolExecutor(workers) as pool:
                    results = list(pool.map(fit_altitude, observer_altitude))
            finally:
                torch.set_num_threads(previous_threads)
        else:
            results = [fit_altitude(h_o) for h_o in observer_altitude]
        fits = [fit for fit, _, _, _ in results]
        kernels = [kernel for _, kernel, _, _ in results if kernel is not None]
        kernel_seconds, kernel_cpu_seconds, pca_seconds, pca_cpu_seconds = (
            sum(seconds[i] for _, _, seconds, _ in results) for i in range(4))
        bar.close()
        basis, coefficients, ratio = _stack_fits(
            fits, (n_azimuth, n_elevation, wavelength.numel()), (n_distance, n_source_altitude))
        n_k = basis.shape[1]
        atmosphere_parameters = (atmosphere.parameters_dict()
                                 if hasattr(atmosphere, "parameters_dict") else
                                 {"description": repr(atmosphere)})
        parameters = {
            "n_azimuth": n_azimuth, "n_elevation": n_elevation,
            "max_distance_m": float(max_distance_m), "n_distance": n_distance,
            "distance_spacing": distance_spacing, "n_components_requested": n_components,
            "n_components": n_k - 1, "emission": emission,
            "emission_parameters": dict(emission_parameters or {}),
            "n_source_altitude": n_source_altitude, "n_observer_altitude": n_observer_altitude,
            # the tabulated nodes' range (one node: the range's low end)
            "source_altitude_range_m": [float(source_altitude[0]), float(source_altitude[-1])],
            "observer_altitude_range_m": [float(observer_altitude[0]),
                                          float(observer_altitude[-1])],
            "n_steps": n_steps, "quadrature_tolerance": float(quadrature_tolerance),
            "quadrature": quadrature,
            "source_radius_m": float(source_radius_m), "normalize": bool(normalize),
            "compute_dtype": str(compute_dtype).replace("torch.", ""),
            "atmosphere": atmosphere_parameters,
            "precompute_seconds": time.perf_counter() - started,
            # kernel and PCA times are summed over the observer altitudes (and so over the
            # worker threads: with several workers they exceed the wall time)
            "precompute_workers": workers,
            "precompute_kernel_seconds": kernel_seconds,
            "precompute_pca_seconds": pca_seconds,
            "precompute_kernel_cpu_seconds": kernel_cpu_seconds,
            "precompute_pca_cpu_seconds": pca_cpu_seconds,
            "precompute_threads": torch.get_num_threads(),
            "scattering_orders": scattering_orders,
        }
        if scattering_orders != 1:
            parameters["multiple_scattering"] = _multiple_scattering_record(
                [summary for _, _, _, summary in results], multiple_scattering_paths)
        model = cls(azimuth_rad=azimuth, elevation_rad=elevation, distance_m=distance,
                    distance_edges_m=edges, source_altitude_m=source_altitude,
                    observer_altitude_m=observer_altitude, wavelength_nm=wavelength,
                    basis=basis, coefficients=coefficients, explained_variance_ratio=ratio,
                    parameters=parameters)
        model.medium = medium
        if keep_kernel:
            model.kernel = torch.stack(kernels)
        return model

    def refit(self, n_components, normalize: bool | None = None) -> SkyglowModel:
        """Return a new model with another number of components, from the kept kernel.

        Requires ``keep_kernel=True`` at :meth:`precompute`.
        """
        if self.kernel is None:
            raise ValueError("refit needs the kernel: precompute with keep_kernel=True")
        normalize = self.parameters_used["normalize"] if normalize is None else normalize
        normalize = check_flag("normalize", normalize)
        n_ho, n_r, n_hc, n_t, n_p, n_wl = self.kernel.shape
        # as in precompute: the PCA of the half images (azimuths 0..N/2 weighted by their
        # multiplicity in the circle) mirrored, so that the bases are exactly symmetric
        half = n_t // 2 + 1
        mirror = torch.tensor([min(i, n_t - i) for i in range(n_t)])
        multiplicity = torch.tensor([1.0 if i in (0, n_t - i) else 2.0 for i in range(half)],
                                    dtype=torch.float64)
        feature_weights = multiplicity[:, None].expand(half, n_p * n_wl).reshape(-1)
        fits = []
        for k in self.kernel:
            fit = fit_basis(k[:, :, :half].reshape(n_r * n_hc, -1), n_components,
                            normalize=normalize, feature_weights=feature_weights)
            fit.basis = fit.basis.reshape(-1, half, n_p * n_wl)[:, mirror].reshape(
                fit.basis.shape[0], -1)
            fits.append(fit)
        basis, coefficients, ratio = _stack_fits(fits, (n_t, n_p, n_wl), (n_r, n_hc))
        n_k = basis.shape[1]
        parameters = dict(self.parameters_used, n_components_requested=n_components,
                          n_components=n_k - 1, normalize=bool(normalize))
        model = type(self)(
            azimuth_rad=self.azimuth_rad, elevation_rad=self.elevation_rad,
            distance_m=self.distance_m, distance_edges_m=self.distance_edges_m,
            source_altitude_m=self.source_altitude_m,
            observer_altitude_m=self.observer_altitude_m, wavelength_nm=self.wavelength_nm,
            basis=basis, coefficients=coefficients, explained_variance_ratio=ratio,
            parameters=parameters)
        model.medium, model.kernel = self.medium, self.kernel
        return model

    # ---------------------------------------------------------------------- runtime ---
    def _buffer(self, name: str, dtype: torch.dtype) -> torch.Tensor:
        value = getattr(self, name)
        if value.dtype == dtype:
            return value
        key = (name, dtype)
        if key not in self._cast:
            self._cast[key] = value.to(dtype)
        return self._cast[key]

    def polar_flux(self, x_m, y_m, flux, altitude_m, observer_xy) -> torch.Tensor:
        """Flux of the lighting cells distributed over the polar nodes of each observer.

        Parameters
        ----------
        x_m, y_m, flux, altitude_m : Tensor (cell,)
            Cell centres east/north [m], fluxes [lm] and source altitudes [m].
        observer_xy : Tensor (observer, 2)
            Observer positions east/north [m].

        Returns
        -------
        Tensor (observer, azimuth, distance, source_altitude)
            Flux per polar node [lm]; the total over nodes equals the flux of the cells
            within ``max_distance_m``.
        """
        flux = as_tensor("flux", flux)
        dtype = flux.dtype
        altitude_m = as_tensor("altitude_m", altitude_m, dtype=dtype)
        if flux.numel() != altitude_m.numel():
            raise ValueError(f"flux and altitude_m must have one value per cell; got "
                             f"{flux.numel()} and {altitude_m.numel()}")
        flux, altitude_m = flux.reshape(-1), altitude_m.reshape(-1)
        _warn_outside("source altitude", altitude_m[flux.detach() != 0], self.source_altitude_m)
        base, corners, shape = self._splat_corners(x_m, y_m, altitude_m, observer_xy, dtype)
        out = torch.zeros(math.prod(shape), dtype=dtype)
        flux = flux[None, :]
        for offset, weight in corners:  # in place: a copy of `out` per corner costs more
            out.index_add_(0, (base + offset).reshape(-1), (weight * flux).reshape(-1))
        return out.reshape(shape).permute(3, 0, 1, 2)

    def _splat_corners(self, x_m, y_m, altitude_m, observer_xy, dtype):
        """Return the splat corners of every (observer, cell) pair.

        That is the flat polar index of each pair's first corner, the corners' (offset,
        weight) and the storage shape (azimuth, distance, source_altitude, observer);
        weights are zero beyond ``max_distance_m``.
        """
        x_m = as_tensor("x_m", x_m, dtype=dtype).reshape(-1)
        y_m = as_tensor("y_m", y_m, dtype=dtype).reshape(-1)
        altitude_m = as_tensor("altitude_m", altitude_m, dtype=dtype).reshape(-1)
        if not x_m.numel() == y_m.numel() == altitude_m.numel():
            raise ValueError(f"x_m, y_m and altitude_m must have one value per cell; got "
                             f"{x_m.numel()}, {y_m.numel()} and {altitude_m.numel()}")
        observer_xy, _ = observer_positions(observer_xy, dtype)
        n_t = self.azimuth_rad.numel()
        n_r = self.distance_m.numel()
        n_h = self.source_altitude_m.numel()
        n_obs = observer_xy.shape[0]
        dx = x_m[None, :] - observer_xy[:, 0:1].contiguous()
        dy = y_m[None, :] - observer_xy[:, 1:2].contiguous()
        r, azimuth = polar_offsets(dx, dy)
        ft = azimuth * (n_t / (2 * math.pi))
        i0 = ft.detach().floor().clamp(0, n_t - 1)
        wt = ft - i0
        if self.parameters_used.get("distance_spacing", "linear") == "linear" and n_r > 1:
            # evenly spaced nodes: the cell index without a search
            u = r * (n_r / float(self.distance_edges_m[-1])) - 0.5
            jr = u.detach().floor().clamp(0, n_r - 2)
            wr = (u - jr).clamp(0.0, 1.0)
            jr = jr.long()
        else:
            jr, wr = _linear_weights(self._buffer("distance_m", dtype), r)
        inside = r <= float(self.distance_edges_m[-1])
        jh, wh = _linear_weights(self._buffer("source_altitude_m", dtype),
                                 altitude_m[None, :].expand_as(r))
        # one flat index per pair into storage ordered (azimuth, r, h_c, observer) — the
        # layout :meth:`convolve` multiplies without a copy; the other corners are offsets
        # from it (the azimuth offset wraps around from the last node to the first)
        i0 = i0.long()
        base = ((i0 * n_r + jr) * n_h + jh) * n_obs + torch.arange(n_obs)[:, None]
        wrap = n_r * n_h * n_obs * torch.where(i0 == n_t - 1, 1 - n_t, 1)
        corners = [(torch.zeros_like(base), inside.to(dtype))]
        for stride, w, n in ((wrap, wt, 2), (n_h * n_obs, wr, n_r), (n_obs, wh, n_h)):
            if n > 1:
                corners = [item for offset, value in corners for item in (
                    (offset, value * (1 - w)), (offset + stride, value * w))]
        return base, corners, (n_t, n_r, n_h, n_obs)

    def splat_plan(self, x_m, y_m, altitude_m, observer_xy, *, dtype=None,
                   compact: bool = True) -> SplatPlan:
        """Return the linear map from cell fluxes to polar node fluxes, for reuse across renders.

        Each cell's flux is distributed bilinearly over the four polar nodes (azimuth ×
        distance; × 2 source-altitude nodes with a terrain) around it, as seen from each
        observer. The indices and weights depend only on the geometry, so a plan built once
        per map grid and observer set turns every later splat into one gather, one multiply
        and one ``index_add`` (:meth:`radiance_per_lumen` keeps the last plan).

        Parameters
        ----------
        x_m, y_m, altitude_m : Tensor (cell,)
            Cell centres east/north [m] and source altitudes [m].
        observer_xy : Tensor (observer, 2)
            Observer positions east/north [m].
        dtype : torch.dtype, optional
            dtype of the weights (default that of ``x_m``).
        compact : bool
            Drop the (observer, cell) pairs beyond ``max_distance_m`` (they carry no flux).

        Returns
        -------
        SplatPlan
            ``plan.apply(flux)`` gives (observer, azimuth, distance, source_altitude).
        """
        dtype = x_m.dtype if dtype is None else dtype
        base, corners, shape = self._splat_corners(x_m, y_m, altitude_m, observer_xy, dtype)
        n_t, n_r, n_h, n_obs = shape
        n_cells = base.shape[1]
        altitude_m = altitude_m.to(dtype).reshape(-1)
        index = torch.stack([base + offset for offset, _ in corners])  # (corner, obs, cell)
        weight = torch.stack([value for _, value in corners])
        cell = torch.arange(n_cells).expand(n_obs, n_cells)
        if compact:
            keep = weight.detach().sum(dim=0) > 0  # within max_distance_m
            index, weight, cell = index[:, keep], weight[:, keep], cell[keep]
        else:
            index, weight, cell = (v.reshape(*v.shape[:-2], -1) for v in (index, weight, cell))
        n_nodes = n_obs * n_t * n_r * n_h
        small = torch.int32 if max(n_nodes, n_cells) < 2**31 else torch.int64
        index, cell = index.to(small), cell.to(small)
        low, high = float(self.source_altitude_m[0]), float(self.source_altitude_m[-1])
        with torch.no_grad():
            beyond = ((altitude_m < low - _ALTITUDE_SLACK_M)
                      | (altitude_m > high + _ALTITUDE_SLACK_M))
        return SplatPlan(index=index.reshape(-1), weight=weight, cell=cell,
                         shape=(n_t, n_r, n_h, n_obs), n_cells=n_cells,
                         outside_cells=torch.nonzero(beyond)[:, 0], altitude_m=altitude_m,
                         source_altitude_m=self.source_altitude_m)

    def polar_sample(self, cells: Mapping[str, torch.Tensor], observer_xy,
                     oversampling: int = 1) -> torch.Tensor:
        """Flux of a gridded light map on the polar nodes by sampling its flux density.

        The map's flux per unit area is interpolated bilinearly (one ``grid_sample``) at
        ``oversampling²`` points in each polar cell (the azimuth cell around θ_i times the
        distance cell), and multiplied by the points' areas r δr δθ. The cost depends on
        the polar grid and the number of observers only, not on the number of lighting
        cells; unlike :meth:`polar_flux` the flux is conserved only as well as the polar
        cells resolve the map (maps much finer than the polar cells are undersampled).

        Parameters
        ----------
        cells : mapping
            From :func:`light_map_arrays`: ``flux`` (y, x) on the evenly spaced
            coordinates ``x_coord`` (x,), ``y_coord`` (y,) [m], and ``altitude`` (y, x).
        observer_xy : Tensor (observer, 2)
            Observer positions east/north [m].
        oversampling : int
            Sample points per polar cell along azimuth and along distance.

        Returns
        -------
        Tensor (observer, azimuth, distance, source_altitude)
            Flux per polar node [lm].
        """
        flux = cells["flux"]
        dtype = flux.dtype
        s = check_int("oversampling", oversampling, low=1)
        if "x_coord" not in cells or flux.ndim != 2:
            raise ValueError("resampling='sample' needs a gridded light map (y, x)")
        x_c, y_c = cells["x_coord"].to(dtype), cells["y_coord"].to(dtype)
        spacing = []
        for name, c in (("x", x_c), ("y", y_c)):
            step = torch.diff(c)
            rtol = 1e-6 if c.dtype == torch.float64 else 1e-4  # float32 coordinates round
            if c.numel() < 2 or not bool(step[0] > 0) or not bool(
                    torch.allclose(step, step[0], rtol=rtol, atol=0.0)):
                # a decreasing coordinate (north-up rasters: y falls) gave negative light
                raise ValueError(f"resampling='sample' needs an evenly spaced increasing '{name}' "
                                 "coordinate with at least two cells (reverse a decreasing one, "
                                 "e.g. light_map.sortby('y'), or use resampling='splat')")
            spacing.append(step[0])
        dx, dy = spacing
        n_t, n_r, n_h = (self.azimuth_rad.numel(), self.distance_m.numel(),
                         self.source_altitude_m.numel())
        n_obs = observer_xy.shape[0]
        d_theta = 2 * math.pi / n_t
        sub = (torch.arange(s, dtype=dtype) + 0.5) / s - 0.5
        theta = (self._buffer("azimuth_rad", dtype)[:, None] + d_theta * sub).reshape(-1)
        edges = self._buffer("distance_edges_m", dtype)
        width = edges[1:] - edges[:-1]
        r = (edges[:-1, None] + width[:, None] * (sub + 0.5)).reshape(-1)  # (R·s,)
        area = (r * torch.repeat_interleave(width / s, s) * (d_theta / s))  # (R·s,)
        px = observer_xy[:, :1, None] + r * torch.sin(theta)[:, None]  # (obs, T·s, R·s)
        py = observer_xy[:, 1:, None] + r * torch.cos(theta)[:, None]
        gx = (px - x_c[0]) * (2 / (dx * x_c.numel())) + (1 / x_c.numel() - 1)
        gy = (py - y_c[0]) * (2 / (dy * y_c.numel())) + (1 / y_c.numel() - 1)
        grid = torch.stack([gx, gy], dim=-1).reshape(1, n_obs * n_t * s, n_r * s, 2)
        channels = [flux / (dx * dy)]
        if n_h > 1:
            channels.append(cells["altitude"].to(dtype))
        image = torch.stack(channels)[None]
        sampled = torch.nn.functional.grid_sample(image, grid, mode="bilinear",
                                                  padding_mode="zeros", align_corners=False)
        sampled = sampled[0].reshape(len(channels), n_obs, n_t, s, n_r, s)
        weight = sampled[0] * area.reshape(n_r, s)[None, None, None]
        if n_h == 1:
            return weight.sum(dim=(2, 4))[..., None]
        jh, wh = _linear_weights(self._buffer("source_altitude_m", dtype), sampled[1])
        out = weight.new_zeros(n_obs, n_t, s, n_r, s, n_h)
        out = out.scatter_add(-1, jh[..., None], (weight * (1 - wh))[..., None])
        out = out.scatter_add(-1, (jh + 1).clamp(max=n_h - 1)[..., None],
                              (weight * wh)[..., None])
        return out.sum(dim=(2, 4))

    def convolve(self, polar: torch.Tensor, observer_altitude_index: int) -> torch.Tensor:
        """Per-unit-flux radiance from polar node fluxes for one observer altitude node.

        Parameters
        ----------
        polar : Tensor (observer, azimuth, distance, source_altitude)
            Flux per polar node [lm] (from :meth:`polar_flux`).
        observer_altitude_index : int
            Which observer-altitude node's tables to use.

        Returns
        -------
        Tensor (observer, elevation, azimuth, wavelength)
            ``Σ_sources flux · b`` [lm m^-2 sr^-1], eq. 5–9.
        """
        dtype = polar.dtype
        n_obs, n_t, n_r, n_h = polar.shape
        n_p, n_wl = self.elevation_rad.numel(), self.wavelength_nm.numel()
        coefficients = self._buffer("coefficients", dtype)[observer_altitude_index]
        n_k = coefficients.shape[-1]
        if n_obs < _MANY_OBSERVERS:
            basis_fft = self._buffer("basis_fft", dtype)[observer_altitude_index]
            # H_k(θ) with azimuth last, so that the FFT runs over contiguous memory
            h = torch.matmul(coefficients.reshape(n_r * n_h, n_k).T,
                             polar.reshape(n_obs, n_t, n_r * n_h).transpose(1, 2))
            h_fft = torch.view_as_real(torch.fft.rfft(h, dim=-1))  # (observer, K, f, 2)
            n_f = h_fft.shape[2]
            # the bases' spectra are real: real and imaginary parts of H multiply them alike
            stacked = h_fft.permute(2, 0, 3, 1).reshape(n_f, 2 * n_obs, n_k)
            product = torch.bmm(stacked, basis_fft)  # (frequency, observer · 2, φ·λ)
            product = product.reshape(n_f, n_obs, 2, n_p * n_wl).permute(1, 3, 0, 2)
            spectrum = torch.view_as_complex(product.contiguous())  # (observer, φ·λ, f)
            radiance = torch.fft.irfft(spectrum, n=n_t, dim=-1)  # (observer, φ·λ, azimuth)
            return radiance.reshape(n_obs, n_p, n_wl, n_t).transpose(2, 3)
        # many observers: layout (azimuth, ..., observer) throughout, so that the
        # observers (and real/imaginary parts) stay the fastest-varying index and no step
        # needs a transposing copy (``polar`` from :meth:`polar_flux` is such a view)
        key = ("basis_fft_transposed", dtype)
        if key not in self._cast:  # (ho, frequency, φ·λ, K)
            self._cast[key] = self.basis_fft.transpose(-1, -2).to(dtype).contiguous()
        basis_t = self._cast[key][observer_altitude_index]
        polar_t = polar.permute(1, 2, 3, 0).reshape(n_t, n_r * n_h, n_obs)
        h = torch.matmul(coefficients.reshape(n_r * n_h, n_k).T, polar_t)  # (θ, K, observer)
        h_fft = torch.view_as_real(torch.fft.rfft(h, dim=0))  # (frequency, K, observer, 2)
        n_f = h_fft.shape[0]
        product = torch.bmm(basis_t, h_fft.reshape(n_f, n_k, 2 * n_obs))
        spectrum = torch.view_as_complex(product.reshape(n_f, n_p * n_wl, n_obs, 2))
        radiance = torch.fft.irfft(spectrum, n=n_t, dim=0)  # (azimuth, φ·λ, observer)
        return radiance.reshape(n_t, n_p, n_wl, n_obs).permute(3, 1, 0, 2)

    def rendered_altitude(self, observer_altitude_m) -> torch.Tensor:
        """Altitudes [m] at which the tables render observers of ``observer_altitude_m``.

        The tabulated observer altitudes are interpolated between their nodes and held at
        the ends beyond them (with a warning from :meth:`observer_altitude_weights`): a
        one-node model renders every observer at its node.
        """
        grid = self.observer_altitude_m
        value = torch.as_tensor(observer_altitude_m, dtype=torch.float64).detach()
        return value.clamp(float(grid[0]), float(grid[-1]))

    def observer_altitude_weights(self, observer_altitude_m: torch.Tensor):
        """Lower node index and weight of the upper node for each observer altitude."""
        grid = self.observer_altitude_m
        observer_altitude_m = check_range("observer_altitude_m", observer_altitude_m, 0.0,
                                          OBSERVER_ALTITUDE_MAX_M, unit=" m")
        _warn_outside("observer_altitude_m", observer_altitude_m, grid)
        return _linear_weights(grid, observer_altitude_m.to(torch.float64))

    def _reusable_plan(self, cells, observer_xy, dtype) -> SplatPlan | None:
        """Return the cached splat plan of this geometry (built if needed), or None if too big."""
        observer_xy, _ = observer_positions(observer_xy, dtype)
        n_cells = cells["flux"].numel()
        corners = 4 * (2 if self.source_altitude_m.numel() > 1 else 1)
        if observer_xy.shape[0] * n_cells * corners > SPLAT_PLAN_ENTRIES or any(
                cells[k].requires_grad for k in ("x", "y", "altitude")) or (
                observer_xy.requires_grad):
            return None  # too big to keep, or differentiated through the geometry
        with torch.no_grad():
            if "x_coord" in cells and "y_coord" in cells:
                geometry = (cells["x_coord"], cells["y_coord"], cells["altitude"])
            else:
                geometry = (cells["x"], cells["y"], cells["altitude"])
            geometry = tuple(g.detach() for g in geometry) + (observer_xy.detach(),)
            cached = self.__dict__.get("_splat_cache")
            if cached is not None and cached[0] == (dtype, tuple(cells["flux"].shape)) and all(
                    a.shape == b.shape and torch.equal(a, b)
                    for a, b in zip(cached[1], geometry, strict=True)):
                return cached[2]
            plan = self.splat_plan(*(cells[k].reshape(-1) for k in ("x", "y", "altitude")),
                                   observer_xy, dtype=dtype)
            self.__dict__["_splat_cache"] = ((dtype, tuple(cells["flux"].shape)),
                                             tuple(g.clone() for g in geometry), plan)
        return plan

    def radiance_per_lumen(self, cells: Mapping[str, torch.Tensor], observer_xy,  # noqa: C901 (checks, resampling modes)
                           observer_altitude_m=0.0, *, resampling: str = "splat",
                           oversampling: int = 1, max_pairs: int = 4_000_000,
                           reuse_splat: bool = True) -> torch.Tensor:
        """``Σ_cells flux · b`` for each observer (the tensor core of :meth:`render`).

        Parameters
        ----------
        cells : mapping
            ``flux``, ``x``, ``y``, ``altitude`` tensors of the same shape (from
            :func:`light_map_arrays`; any shape, flattened).
        observer_xy : Tensor (observer, 2) or (2,)
            Observer positions [m].
        observer_altitude_m : Tensor (observer,) or scalar
            Observer altitudes [m]; interpolated linearly between the tabulated nodes.
        resampling : {"splat", "sample"}
            How the map reaches the polar grid: ``"splat"`` distributes each lit cell's
            flux over its four polar nodes (:meth:`polar_flux`; exact flux, cost ∝ lit
            cells, or ∝ cells in range with a reused :class:`SplatPlan`); ``"sample"``
            samples a gridded map's flux density in each polar cell
            (:meth:`polar_sample`; cost independent of the number of cells).
        oversampling : int
            Sample points per polar cell and axis for ``"sample"``.
        max_pairs : int
            Bound on observer × cell pairs handled at once (memory).
        reuse_splat : bool
            For ``"splat"``: keep the :class:`SplatPlan` of the last map geometry
            (coordinates, altitudes, observers, dtype) and reuse it while they stay the
            same, so that renders of new fluxes on the same grid skip the polar
            coordinates (plans of up to :data:`SPLAT_PLAN_ENTRIES` entries).

        Returns
        -------
        Tensor (observer, elevation, azimuth, wavelength)
        """
        check_choice("resampling", resampling, RESAMPLINGS)
        oversampling = check_int("oversampling", oversampling, low=1, high=64)
        if oversampling != 1 and resampling != "sample":
            raise ValueError(f"oversampling applies to resampling='sample'; got "
                             f"oversampling={oversampling} with resampling={resampling!r}")
        max_pairs = check_int("max_pairs", max_pairs, low=1)
        reuse_splat = check_flag("reuse_splat", reuse_splat)
        if not isinstance(cells, Mapping) or any(
                k not in cells for k in ("flux", "x", "y", "altitude")):
            raise TypeError("cells must be the mapping of light_map_arrays() with flux, x, y "
                            f"and altitude; got {type(cells).__name__}")
        flux = cells["flux"]
        dtype = flux.dtype
        if any(tuple(cells[k].shape) != tuple(flux.shape) and cells[k].numel() != flux.numel()
               for k in ("x", "y", "altitude")):
            raise ValueError("cells flux, x, y and altitude must have one value per cell; got "
                             "shapes " + ", ".join(f"{k} {tuple(cells[k].shape)}"
                                                   for k in ("flux", "x", "y", "altitude")))
        observer_xy, _ = observer_positions(observer_xy, dtype)
        n_obs = observer_xy.shape[0]
        h_o = observer_altitudes(observer_altitude_m, n_obs, dtype)
        plan = None
        if resampling == "splat" and reuse_splat:
            plan = self._reusable_plan(cells, observer_xy, dtype)
        if plan is not None:
            polar_cells = None
        elif resampling == "sample":
            polar_cells = cells
        elif flux.requires_grad:
            flux, x, y, altitude = (cells[k].reshape(-1).to(dtype)
                                    for k in ("flux", "x", "y", "altitude"))
        else:  # only the lit cells (the coordinates are often expanded views: no copies)
            lit = flux != 0
            flux, x, y, altitude = (cells[k].expand_as(lit)[lit].to(dtype)
                                    for k in ("flux", "x", "y", "altitude"))
        j, w = self.observer_altitude_weights(h_o)
        n_p, n_t = self.elevation_rad.numel(), self.azimuth_rad.numel()
        n_wl = self.wavelength_nm.numel()
        per_observer = (self.azimuth_rad.numel() * self.distance_m.numel() * oversampling**2
                        if resampling == "sample" else flux.numel())
        step = n_obs if plan is not None else max(1, max_pairs // max(per_observer, 1))
        pieces = []
        for start in range(0, n_obs, step):
            stop = min(start + step, n_obs)
            if plan is not None:
                polar = plan.apply(flux)
            elif resampling == "sample":
                polar = self.polar_sample(polar_cells, observer_xy[start:stop], oversampling)
            else:
                polar = self.polar_flux(x, y, flux, altitude, observer_xy[start:stop])
            if self.observer_altitude_m.numel() == 1:
                pieces.append(self.convolve(polar, 0))
            else:
                pieces.append(self._convolve_between_altitudes(
                    polar, j[start:stop], w[start:stop].to(dtype), (n_p, n_t, n_wl)))
        return pieces[0] if len(pieces) == 1 else torch.cat(pieces)

    def _convolve_between_altitudes(self, polar: torch.Tensor, jj: torch.Tensor,
                                    ww: torch.Tensor, shape: tuple[int, int, int]
                                    ) -> torch.Tensor:
        """Convolve polar fluxes with the kernels of the two observer-altitude nodes.

        Each observer's image is the linear blend ``(1 - w) K_j + w K_{j+1}`` of the
        convolutions at the nodes ``jj`` and ``jj + 1`` around its altitude; ``shape`` is
        (elevation, azimuth, wavelength) of one image.
        """
        result = torch.zeros(polar.shape[0], *shape, dtype=ww.dtype)
        for node in torch.unique(torch.cat([jj, jj + 1])).tolist():
            if node >= self.observer_altitude_m.numel():
                continue
            weight = torch.where(jj == node, 1 - ww, torch.zeros_like(ww)) + torch.where(
                jj + 1 == node, ww, torch.zeros_like(ww))
            # a node of weight 0 still has a derivative with respect to the altitude (an
            # observer exactly at a node): kept where the weights carry a gradient
            use = ((jj == node) | (jj + 1 == node)) if ww.requires_grad else weight > 0
            if not bool(use.any()):
                continue
            part = self.convolve(polar[use], node)
            result = result.index_add(0, torch.nonzero(use)[:, 0],
                                      part * weight[use][:, None, None, None])
        return result

    def render(self, light_map, observer_xy=(0.0, 0.0), observer_altitude_m=0.0, *,
               lamp="white", x_m=None, y_m=None, altitude_m=None,
               natural_mag_arcsec2: float | None = None, as_dataset: bool = True,
               resampling: str = "splat", oversampling: int = 1):
        """Skyglow panorama(s) of a light map (Dobashi et al. 2023, eq. 5–9).

        Parameters
        ----------
        light_map : xarray.Dataset or Tensor (y, x)
            Variable ``flux`` [lm] on ``(y, x)`` in metres east/north, optional
            ``altitude`` [m] (see :func:`light_map_arrays`).
        observer_xy : array_like (2,) or (observer, 2)
            Observer position(s) in the map's coordinates [m], finite, |x|, |y| ≤
            :data:`OBSERVER_XY_LIMIT_M`.
        observer_altitude_m : float or array_like (observer,)
            Observer altitude(s) [m] in [0, :data:`OBSERVER_ALTITUDE_MAX_M`]; beyond the
            tabulated range they are clamped to it with a warning.
        lamp : str or (wavelength_nm, spectrum)
            Lamp spectrum (:data:`skytorch.skyglow.lamps.LAMPS`) giving the spectral
            power of one lumen.
        x_m, y_m, altitude_m : Tensor, optional
            Coordinates for a tensor light map.
        natural_mag_arcsec2 : float, optional
            Natural zenith brightness added in ``total_brightness``, within
            :data:`skytorch.constants.NATURAL_MAG_RANGE` (14–26; default 22.0) [mag arcsec^-2].
        as_dataset : bool
            Return a Dataset (default) or a dict of tensors.
        resampling, oversampling
            Polar resampling of the map (see :meth:`radiance_per_lumen`).

        Returns
        -------
        xarray.Dataset
            ``radiance`` (observer, elevation, azimuth, wavelength) spectral radiance
            [W m^-2 sr^-1 nm^-1]; ``luminance`` (observer, elevation, azimuth) [cd m^-2];
            ``artificial_ratio`` [1] (to the natural zenith sky), ``total_brightness``
            [mag arcsec^-2] (natural + artificial) and the naked-eye
            ``limiting_magnitude`` [mag]. The ``observer`` dimension is dropped for a single
            observer given as ``(2,)``.

        Raises
        ------
        ValueError
            For a bad light map (see :func:`light_map_arrays`), observer positions or
            altitudes outside their ranges or of the wrong shape (checked before any
            arithmetic), and an unknown lamp or resampling.
        TypeError
            For non-numeric inputs, a malformed lamp spectrum or a non-boolean option.
        """
        as_dataset = check_flag("as_dataset", as_dataset)
        check_choice("resampling", resampling, RESAMPLINGS)
        natural = NATURAL_ZENITH_SKY_MAG_ARCSEC2 if natural_mag_arcsec2 is None else float(
            check_range("natural_mag_arcsec2", natural_mag_arcsec2, *NATURAL_MAG_RANGE,
                        unit=" mag/arcsec^2"))
        cells = light_map_arrays(light_map, x_m, y_m, altitude_m)
        observer_xy, single = observer_positions(observer_xy, cells["flux"].dtype)
        observer_altitude_m = observer_altitudes(observer_altitude_m, observer_xy.shape[0],
                                                 cells["flux"].dtype)
        weights, band_power = luminance_weights(lamp, self.wavelength_nm)
        per_lumen = self.radiance_per_lumen(cells, observer_xy, observer_altitude_m,
                                            resampling=resampling, oversampling=oversampling)
        dtype = per_lumen.dtype
        luminance = per_lumen @ weights.to(dtype)
        radiance = per_lumen * band_power.to(dtype)
        outputs = {"radiance": radiance, "luminance": luminance}
        if single:
            outputs = {k: v[0] for k, v in outputs.items()}
        if not as_dataset:
            return outputs
        refuse_gradient("render with as_dataset=True (as_dataset=False keeps the graph)",
                        **{name: value for name, value in cells.items()
                           if torch.is_tensor(value)},
                        observer_xy=observer_xy, observer_altitude_m=observer_altitude_m,
                        lamp_spectrum=None if isinstance(lamp, str) else lamp[1])
        return self._dataset(outputs, cells, observer_xy, observer_altitude_m, lamp, natural,
                             single, resampling=resampling, oversampling=oversampling)

    def _dataset(self, outputs, cells, observer_xy, observer_altitude_m, lamp, natural,
                 single, **resampling):
        from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable

        prefix = () if single else ("observer",)
        luminance = outputs["luminance"].detach()
        data = {
            "radiance": variable((*prefix, "elevation", "azimuth", "wavelength"),
                                 outputs["radiance"], VariableSpec(
                "W m-2 sr-1 nm-1", "artificial sky spectral radiance",
                _radiance_description(self.parameters_used))),
            "luminance": variable((*prefix, "elevation", "azimuth"), luminance, VariableSpec(
                "cd m-2", "artificial sky luminance",
                "K_m ∫ s(λ) V(λ) b(λ) dλ summed over the lighting cells.")),
            "artificial_ratio": variable(
                (*prefix, "elevation", "azimuth"),
                artificial_to_natural_ratio(luminance, natural), VariableSpec(
                    "1", "artificial to natural sky brightness ratio",
                    f"Artificial luminance over the natural zenith sky of {natural} "
                    "mag arcsec-2 V (Falchi et al. 2016).")),
            "total_brightness": variable(
                (*prefix, "elevation", "azimuth"), total_mag_arcsec2(luminance, natural),
                VariableSpec("mag arcsec-2", "total sky surface brightness (V)",
                             "Natural zenith sky plus artificial luminance, "
                             "m = -2.5 log10(L / 10.8e4 cd m-2) (Falchi et al. 2016).")),
        }
        data["limiting_magnitude"] = variable(
            (*prefix, "elevation", "azimuth"),
            naked_eye_limiting_magnitude(data["total_brightness"].values), VariableSpec(
                "mag", "naked-eye limiting magnitude",
                "Faintest star visible against this sky (Schaefer 1990 threshold model)."))
        coords = self._panorama_coords()
        if not single:
            xy = torch.as_tensor(observer_xy).detach().to(torch.float64).reshape(-1, 2)
            n = xy.shape[0]
            coords["observer"] = coordinate("observer", np.arange(n), VariableSpec(
                "1", "observer index", "Index of the observer position."))
            coords["observer_x"] = variable(("observer",), xy[:, 0], VariableSpec(
                "m", "observer easting", "Observer position east in the map frame."))
            coords["observer_y"] = variable(("observer",), xy[:, 1], VariableSpec(
                "m", "observer northing", "Observer position north in the map frame."))
        lamp_name = lamp if isinstance(lamp, str) else "custom spectrum"
        parameters = dict(self.parameters_used, lamp=lamp_name,
                          observer_xy=_plain(observer_xy, single),
                          observer_altitude_m=_plain(observer_altitude_m, single),
                          observer_altitude_rendered_m=_plain(
                              self.rendered_altitude(observer_altitude_m), single),
                          natural_mag_arcsec2=natural, **resampling,
                          total_flux_lm=float(cells["flux"].detach().sum()))
        return build_dataset(data, coords, title="Artificial skyglow panorama",
                             references=list(REFERENCES), parameters=parameters)

    def _panorama_coords(self):
        from skytorch.dataset import VariableSpec, coordinate

        return {
            "elevation": coordinate("elevation", torch.rad2deg(self.elevation_rad), VariableSpec(
                "degree", "elevation", "Elevation of the view direction above the horizon "
                "(cell centres).")),
            "azimuth": coordinate("azimuth", torch.rad2deg(self.azimuth_rad), VariableSpec(
                "degree", "azimuth", "Azimuth of the view direction from north through east.")),
            "wavelength": coordinate("wavelength", self.wavelength_nm, VariableSpec(
                "nm", "wavelength", "Vacuum wavelength.", "radiation_wavelength")),
        }

    # ------------------------------------------------------------------------ files ---
    def to_dataset(self):
        """Return the tables and every precompute parameter as a Dataset (for netCDF)."""
        from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable

        n_k = self.basis.shape[1]
        coords = self._panorama_coords()
        coords.update({
            "distance": coordinate("distance", self.distance_m, VariableSpec(
                "m", "source distance", "Ground distance of the distance-cell centres.")),
            "distance_edge": coordinate("distance_edge", self.distance_edges_m, VariableSpec(
                "m", "distance cell edge", "Edges of the distance cells.")),
            "source_altitude": coordinate("source_altitude", self.source_altitude_m,
                                          VariableSpec("m", "source altitude",
                                                       "Altitude of the light source.")),
            "observer_altitude": coordinate("observer_altitude", self.observer_altitude_m,
                                            VariableSpec("m", "observer altitude",
                                                         "Altitude of the observer.")),
            "component": coordinate("component", np.arange(n_k), VariableSpec(
                "1", "basis index", "0: mean image; 1..M: principal components.")),
            "principal_component": coordinate("principal_component", np.arange(1, n_k),
                                              VariableSpec("1", "principal component index",
                                                           "Index k of B_k, k >= 1.")),
        })
        # the kernel's unit m-2 sr-1 is on the coefficients of normalised kernels' bases
        normalized = bool(self.parameters_used.get("normalize", True))
        basis_units, coefficient_units = ("1", "m-2 sr-1") if normalized else ("m-2 sr-1", "1")
        data = {
            "basis": variable(("observer_altitude", "component", "azimuth", "elevation",
                               "wavelength"), self.basis, VariableSpec(
                basis_units, "basis images B_k", "Mean and principal components of the "
                + ("normalised " if normalized else "") + "kernel images (Dobashi et al. "
                "2023, eq. 4).")),
            "coefficients": variable(("observer_altitude", "distance", "source_altitude",
                                      "component"), self.coefficients, VariableSpec(
                coefficient_units, "basis coefficients c_k", "Kernel radiance per unit flux "
                "is sum_k c_k B_k.")),
            "explained_variance_ratio": variable(
                ("observer_altitude", "principal_component"), self.explained_variance_ratio,
                VariableSpec("1", "explained variance ratio",
                             "Fraction of the normalised kernels' variance per component.")),
        }
        return build_dataset(data, coords, title="Skyglow PCA + FFT model",
                             references=list(REFERENCES), parameters=self.parameters_used)

    def save(self, path):
        """Write the model to a netCDF file (atomic); returns the path.

        The file's attribute ``tables_sha256`` is the SHA-256 of the stored tables, which
        :meth:`load` verifies.
        """
        from skytorch.dataset import to_netcdf

        ds = self.to_dataset()
        ds.attrs["tables_sha256"] = _tables_digest(ds)
        return to_netcdf(ds, path)

    @classmethod
    def load(cls, path) -> SkyglowModel:
        """Read a model written by :meth:`save`.

        Raises
        ------
        FileNotFoundError
            If there is no file at ``path``.
        ValueError
            If the file is not a readable skyglow model, its tables do not match the
            ``tables_sha256`` recorded by :meth:`save`, or they are inconsistent (shapes,
            non-finite values, a basis that is not mirror-symmetric): the file is
            corrupted and the model must be rebuilt.
        """
        from skytorch.dataset import open_dataset

        if not isinstance(path, (str, os.PathLike)):
            raise TypeError(f"path must be a str or os.PathLike; got {type(path).__name__}")
        try:
            ds = open_dataset(path)
        except FileNotFoundError:
            raise
        except Exception as error:  # noqa: BLE001 - any failure to parse the bytes
            # (netCDF4 raises OSError, RuntimeError, AttributeError, UnicodeDecodeError ...)
            raise ValueError(f"cannot read a skyglow model from {path} (corrupted or "
                             f"truncated; rebuild it): {type(error).__name__}: {error}"
                             ) from error
        try:
            missing = [name for name in _TABLE_VARIABLES if name not in ds.variables]
            if missing or "parameters" not in ds.attrs:
                raise ValueError(f"missing {missing or 'the parameters attribute'}")
            recorded = ds.attrs.get("tables_sha256")
            if recorded is not None and recorded != _tables_digest(ds):
                raise ValueError("its tables do not match the SHA-256 recorded when it was "
                                 "saved")
            parameters = json.loads(ds.attrs["parameters"])
            if not isinstance(parameters, dict):
                raise ValueError("the parameters attribute is not a JSON object")

            def t(name):
                return torch.tensor(np.array(ds[name].values, dtype=np.float64))

            return cls(azimuth_rad=torch.deg2rad(t("azimuth")),
                       elevation_rad=torch.deg2rad(t("elevation")), distance_m=t("distance"),
                       distance_edges_m=t("distance_edge"),
                       source_altitude_m=t("source_altitude"),
                       observer_altitude_m=t("observer_altitude"),
                       wavelength_nm=t("wavelength"), basis=t("basis"),
                       coefficients=t("coefficients"),
                       explained_variance_ratio=t("explained_variance_ratio"),
                       parameters=parameters)
        except (ValueError, KeyError, TypeError, RuntimeError, OSError, AttributeError,
                IndexError) as error:
            raise ValueError(f"{path} is not a valid skyglow model file (corrupted or "
                             f"truncated; rebuild it): {error}") from error


#: the variables of a saved model, in the order of their digest
_TABLE_VARIABLES = ("azimuth", "elevation", "wavelength", "distance", "distance_edge",
                    "source_altitude", "observer_altitude", "basis", "coefficients",
                    "explained_variance_ratio")


def _tables_digest(ds) -> str:
    """SHA-256 of the float64 bytes (and shapes) of a model Dataset's tables."""
    import hashlib

    digest = hashlib.sha256()
    for name in _TABLE_VARIABLES:
        values = np.ascontiguousarray(np.asarray(ds[name].values, dtype=np.float64))
        digest.update(f"{name}{values.shape}".encode())
        digest.update(values.tobytes())
    return digest.hexdigest()
