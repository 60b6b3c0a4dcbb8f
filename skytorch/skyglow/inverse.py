"""Inverse tools: which lights cause the skyglow, and how to reduce them.

* :func:`pollution_influence` — light-pollution level of each lighting cell at the
  observer, ``Q_i = L_i Q(r_i, h_i, h_o)`` (Dobashi et al. 2023, eq. 10–11), where
  ``Q(r, h_c, h_o)`` is the root-sum-square of the source's kernel image over the
  panorama and wavelengths. Eq. 10 writes it as ``sqrt(Σ_k c_k²)``, exact for an
  uncentred orthonormal basis; with the mean image as basis 0 it is ``sqrt(cᵀ G c)`` with
  the basis Gram matrix ``G`` (precomputed as ``model.pollution_level``).
* :func:`skyglow_influence` — influence ``S_i = Σ_l s_i(θ_l, φ_l)`` of each cell on a sky
  region (eq. 13–14), computed exactly for the renderer's representation as
  ``S_i = L_i ∂(Σ_l L(θ_l, φ_l))/∂L_i`` by automatic differentiation through
  :meth:`SkyglowModel.render` (the skyglow is linear in the fluxes).
* :func:`reduction_factors` — Dobashi's strategy (eq. 12),
  ``γ_i = clip((Q_i − Q_a)/(Q_b − Q_a), 0, 1) γ_usr``, and :func:`apply_reduction`
  ``L_i ← (1 − γ_i) L_i``.
* :func:`minimal_reduction` — beyond the paper: the smallest total reduction of flux
  (lumens switched off) that brings the mean luminance of a sky region down to a target,
  by sequential linear programming on gradients obtained through the renderer.

References
----------
1. Dobashi, Y., Ishikawa, N. & Iwasaki, K. 2023, ACM Trans. Graph. 42, 219,
   doi:10.1145/3618337.

Examples
--------
>>> from skytorch.atmosphere import Atmosphere
>>> from skytorch.skyglow import SkyglowModel, synthetic_city
>>> model = SkyglowModel.precompute(Atmosphere.earth(), n_azimuth=16, n_elevation=4,
...                                 n_distance=8, n_components=4, n_steps=4, progress=False)
>>> city = synthetic_city(20e3, 2e3, centre_xy=(6e3, 0.0))
>>> east = sky_region(model, elevation_deg=(0, 30), azimuth_deg=(45, 135))
>>> plan = minimal_reduction(model, city, east, target_fraction=0.5)
>>> round(plan.attrs["parameter_final_luminance_cd_m2"]
...       / plan.attrs["parameter_initial_luminance_cd_m2"], 3)
0.5
"""

from __future__ import annotations

import logging

import numpy as np
import torch
import xarray as xr

from skytorch._validate import as_tensor, check_finite, check_int, check_range
from skytorch.skyglow.lamps import luminance_weights
from skytorch.skyglow.model import (
    SkyglowModel,
    _linear_weights,
    check_flag,
    check_model,
    light_map_arrays,
    observer_altitudes,
    observer_positions,
)

__all__ = [
    "apply_reduction",
    "minimal_reduction",
    "pollution_influence",
    "reduction_factors",
    "region_luminance",
    "sky_region",
    "skyglow_influence",
]

logger = logging.getLogger(__name__)


def sky_region(model: SkyglowModel, elevation_deg=(0.0, 90.0), azimuth_deg=(0.0, 360.0)
               ) -> torch.Tensor:
    """Boolean mask (elevation, azimuth) of panorama pixels inside a sky region.

    Azimuth ranges may wrap through north, e.g. ``(330, 30)``.
    """
    check_model("model", model)
    lo, hi = _pair("elevation_deg", elevation_deg, -90.0, 90.0)
    if lo > hi:
        raise ValueError(f"elevation_deg must be (low, high) with low <= high; got "
                         f"{elevation_deg}")
    first, last = _pair("azimuth_deg", azimuth_deg, -720.0, 720.0)
    el = torch.rad2deg(model.elevation_rad)
    az = torch.rad2deg(model.azimuth_rad)
    a0, a1 = first % 360.0, last % 360.0
    in_el = (el >= lo) & (el <= hi)
    if last - first >= 360.0:
        in_az = torch.ones_like(az, dtype=torch.bool)
    elif a0 <= a1:
        in_az = (az >= a0) & (az <= a1)
    else:
        in_az = (az >= a0) | (az <= a1)
    mask = in_el[:, None] & in_az[None, :]
    if not bool(mask.any()):
        raise ValueError(f"the sky region elevation {elevation_deg}, azimuth {azimuth_deg} "
                         "contains no pixel of the model's panorama")
    return mask


def _pair(name: str, value, low: float, high: float) -> tuple[float, float]:
    """Two finite numbers within [low, high] [deg]."""
    pair = check_range(name, value, low, high, unit=" deg", dtype=torch.float64)
    if pair.shape != (2,):
        raise ValueError(f"{name} must be a pair (low, high) [deg]; got shape "
                         f"{tuple(pair.shape)}")
    return float(pair[0]), float(pair[1])


def check_region(model: SkyglowModel, region) -> torch.Tensor:
    """Return a boolean (elevation, azimuth) mask of the panorama with at least one pixel."""
    if region is None or isinstance(region, (str, bytes)):
        raise TypeError(f"region must be a boolean mask (elevation, azimuth), e.g. from "
                        f"sky_region(); got {region!r:.60}")
    try:
        mask = torch.as_tensor(region)
    except (TypeError, ValueError, RuntimeError) as error:
        raise TypeError(f"region must be a boolean mask (elevation, azimuth); got "
                        f"{type(region).__name__}") from error
    if mask.dtype != torch.bool:
        raise TypeError(f"region must be a boolean mask (elevation, azimuth); got dtype "
                        f"{mask.dtype}")
    expected = (model.elevation_rad.numel(), model.azimuth_rad.numel())
    if tuple(mask.shape) != expected:
        raise ValueError(f"region must have the panorama's shape (elevation, azimuth) = "
                         f"{expected}; got {tuple(mask.shape)}")
    if not bool(mask.any()):
        raise ValueError("region selects no pixel of the panorama")
    return mask


def _one_observer(observer_xy, observer_altitude_m, dtype):
    xy, single = observer_positions(observer_xy, dtype)
    if xy.shape[0] != 1:
        raise ValueError(f"observer_xy must be one position (2,) [m] here; got shape "
                         f"{tuple(torch.as_tensor(observer_xy).shape)}")
    return xy, observer_altitudes(observer_altitude_m, 1, dtype)


def _dataset(name, values, cells, spec, title, parameters):
    from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable

    coords = {
        "x": coordinate("x", cells["x_coord"], VariableSpec("m", "easting",
                                                            "Cell centre east.")),
        "y": coordinate("y", cells["y_coord"], VariableSpec("m", "northing",
                                                            "Cell centre north.")),
    }
    data = {name: variable(("y", "x"), values.detach(), spec)}
    return build_dataset(data, coords, title=title, references=[
        "Dobashi, Y., Ishikawa, N. & Iwasaki, K. 2023, ACM Trans. Graph. 42, 219, "
        "doi:10.1145/3618337"], parameters=parameters)


def pollution_influence(model: SkyglowModel, light_map, observer_xy=(0.0, 0.0),
                        observer_altitude_m=0.0, *, as_dataset: bool = True, x_m=None,
                        y_m=None, altitude_m=None):
    """Light-pollution level ``Q_i`` of every lighting cell (eq. 10–11).

    Parameters
    ----------
    model : SkyglowModel
    light_map : xarray.Dataset or Tensor (y, x)
        See :func:`~skytorch.skyglow.model.light_map_arrays`.
    observer_xy : array_like (2,)
        Observer position [m].
    observer_altitude_m : float
        Observer altitude [m].
    as_dataset : bool
        Return a Dataset (default) or the tensor.
    x_m, y_m, altitude_m : Tensor, optional
        Coordinates for a tensor light map (see :func:`light_map_arrays`).

    Returns
    -------
    xarray.Dataset with ``pollution_level`` (y, x) [lm m^-2 sr^-1] (or the tensor)
        ``L_i Q(r_i, h_i, h_o)``; zero beyond ``max_distance_m``.
    """
    check_model("model", model)
    as_dataset = check_flag("as_dataset", as_dataset)
    cells = light_map_arrays(light_map, x_m, y_m, altitude_m)
    flux = cells["flux"]
    dtype = flux.dtype
    xy, h_o = _one_observer(observer_xy, observer_altitude_m, dtype)
    xy = xy[0]
    r = torch.sqrt((cells["x"] - xy[0]) ** 2 + (cells["y"] - xy[1]) ** 2)
    q_table = model.pollution_level.to(dtype)  # (ho, r, hc)
    j_o, w_o = model.observer_altitude_weights(h_o)
    n_o = q_table.shape[0]
    q_ho = (1 - w_o.to(dtype)) * q_table[int(j_o)] + (
        w_o.to(dtype) * q_table[min(int(j_o) + 1, n_o - 1)])  # (r, hc)
    jr, wr = _linear_weights(model.distance_m, r)
    jh, wh = _linear_weights(model.source_altitude_m, cells["altitude"])
    n_r, n_h = q_ho.shape
    jr1 = (jr + 1).clamp(max=n_r - 1)
    jh1 = (jh + 1).clamp(max=n_h - 1)
    q = ((1 - wr) * ((1 - wh) * q_ho[jr, jh] + wh * q_ho[jr, jh1])
         + wr * ((1 - wh) * q_ho[jr1, jh] + wh * q_ho[jr1, jh1]))
    q = torch.where(r <= float(model.distance_edges_m[-1]), q, torch.zeros_like(q))
    result = flux * q
    if not as_dataset:
        return result
    from skytorch.dataset import VariableSpec

    return _dataset("pollution_level", result, cells, VariableSpec(
        "lm m-2 sr-1", "light-pollution level Q_i",
        "Cell flux times the root-sum-square of its unit kernel image over the panorama "
        "(Dobashi et al. 2023, eq. 10-11)."), "Light-pollution influence of each cell",
        {"observer_xy": xy.tolist(), "observer_altitude_m": float(h_o[0])})


def region_luminance(model: SkyglowModel, flux: torch.Tensor, cells, region: torch.Tensor,
                     observer_xy, observer_altitude_m, lamp) -> torch.Tensor:
    """Mean luminance [cd m^-2] over the region's pixels for the given fluxes (y, x)."""
    check_model("model", model)
    region = check_region(model, region)
    flux = as_tensor("flux", flux)
    if not isinstance(cells, dict) or "flux" not in cells:
        raise TypeError(f"cells must be the mapping of light_map_arrays(); got "
                        f"{type(cells).__name__}")
    if tuple(flux.shape) != tuple(cells["flux"].shape):
        raise ValueError(f"flux must have the light map's shape {tuple(cells['flux'].shape)}; "
                         f"got {tuple(flux.shape)}")
    xy, h_o = _one_observer(observer_xy, observer_altitude_m, flux.dtype)
    weights, _ = luminance_weights(lamp, model.wavelength_nm)
    cells = dict(cells, flux=flux)
    per_lumen = model.radiance_per_lumen(cells, xy, h_o)[0]
    luminance = per_lumen @ weights.to(flux.dtype)
    return luminance[region].mean()


def skyglow_influence(model: SkyglowModel, light_map, region, observer_xy=(0.0, 0.0),
                      observer_altitude_m=0.0, *, lamp="white", as_dataset: bool = True,
                      x_m=None, y_m=None, altitude_m=None):
    """Influence ``S_i`` of every lighting cell on a sky region (eq. 13–14).

    Parameters
    ----------
    model : SkyglowModel
    light_map : xarray.Dataset or Tensor (y, x)
    region : Tensor (elevation, azimuth) of bool
        Pixels of the region (e.g. from :func:`sky_region`).
    observer_xy, observer_altitude_m, lamp
        As in :meth:`SkyglowModel.render` (one observer).
    as_dataset : bool
        Return a Dataset (default) or the tensor.
    x_m, y_m, altitude_m : Tensor, optional
        Coordinates for a tensor light map (see :func:`light_map_arrays`).

    Returns
    -------
    xarray.Dataset with ``skyglow_influence`` (y, x) [cd m^-2] (or the tensor)
        Luminance that each cell adds, summed over the region's pixels; the cells'
        values add up to the region's total luminance.
    """
    check_model("model", model)
    as_dataset = check_flag("as_dataset", as_dataset)
    region = check_region(model, region)
    cells = light_map_arrays(light_map, x_m, y_m, altitude_m)
    xy, h_o = _one_observer(observer_xy, observer_altitude_m, cells["flux"].dtype)
    flux = cells["flux"].detach().clone().requires_grad_(True)
    mean = region_luminance(model, flux, cells, region, observer_xy, observer_altitude_m, lamp)
    (gradient,) = torch.autograd.grad(mean * region.sum(), flux)
    result = cells["flux"].detach() * gradient
    if not as_dataset:
        return result
    from skytorch.dataset import VariableSpec

    return _dataset("skyglow_influence", result, cells, VariableSpec(
        "cd m-2", "skyglow influence S_i",
        "Luminance added by the cell, summed over the sky region's pixels (Dobashi et al. "
        "2023, eq. 13-14), by automatic differentiation through the renderer."),
        "Skyglow influence of each cell on a sky region",
        {"observer_xy": xy[0].tolist(), "observer_altitude_m": float(h_o[0]),
         "region_pixels": int(region.sum())})


def reduction_factors(influence, q_a: float, q_b: float, gamma_user: float = 1.0
                      ) -> torch.Tensor:
    """Dobashi's reduction rates γ_i = clip((Q_i − Q_a)/(Q_b − Q_a), 0, 1) γ_usr (eq. 12).

    Parameters
    ----------
    influence : Tensor (...)
        Q_i or S_i of each cell.
    q_a, q_b : float
        Cells below ``q_a`` are kept; with ``gamma_user = 1`` cells above ``q_b`` are
        switched off. ``q_b > q_a``.
    gamma_user : float
        Overall strength in [0, 1].
    """
    if isinstance(influence, xr.DataArray):  # pollution_influence's variable, (y, x)
        influence = influence.values
    influence = check_finite("influence", influence)
    gamma_user = float(check_range("gamma_user", gamma_user, 0.0, 1.0))
    q_a = float(check_finite("q_a", q_a))
    q_b = float(check_finite("q_b", q_b))
    if not q_b > q_a:
        raise ValueError(f"q_b must be larger than q_a; got q_a={q_a}, q_b={q_b}")
    return ((influence - q_a) / (q_b - q_a)).clamp(0.0, 1.0) * gamma_user


def apply_reduction(light_map, gamma):
    """Return a copy of the light map with fluxes ``(1 − γ_i) L_i``.

    ``gamma`` is on the cells (y, x) — a number, an array (y, x) as
    :func:`reduction_factors` returns, or a DataArray with dimensions ``y`` and ``x`` —
    and is applied by dimension name, whatever the order of the map's ``flux``.
    """
    if not hasattr(light_map, "data_vars") or "flux" not in light_map:
        raise TypeError(f"light_map must be a Dataset with a variable 'flux' (y, x); got "
                        f"{type(light_map).__name__}")
    flux = light_map["flux"]
    if set(flux.dims) != {"y", "x"}:
        raise ValueError(f"light_map['flux'] must have the dimensions (y, x); got {flux.dims}")
    if isinstance(gamma, xr.DataArray):
        if set(gamma.dims) - {"y", "x"}:
            raise ValueError(f"gamma must have the dimensions (y, x); got {gamma.dims}")
        gamma = gamma.transpose(*[d for d in ("y", "x") if d in gamma.dims]).values
    values = check_range("gamma", gamma, 0.0, 1.0, dtype=torch.float64).detach().numpy()
    cells = (flux.sizes["y"], flux.sizes["x"])
    try:
        shape = np.broadcast_shapes(values.shape, cells)
    except ValueError:
        shape = None
    if shape != cells:
        raise ValueError(f"gamma of shape {values.shape} does not broadcast to the light "
                         f"map's cells (y, x) = {cells}")
    kept = xr.DataArray(1.0 - np.broadcast_to(values, cells), dims=("y", "x"))
    out = light_map.copy()
    out["flux"] = (flux * kept).transpose(*flux.dims)
    out["flux"].attrs = dict(flux.attrs)
    return out


def minimal_reduction(model: SkyglowModel, light_map, region, target_luminance_cd_m2=None, *,
                      target_fraction: float | None = None, observer_xy=(0.0, 0.0),
                      observer_altitude_m=0.0, lamp="white", max_iterations: int = 10,
                      tolerance: float = 1e-6, as_dataset: bool = True, x_m=None, y_m=None,
                      altitude_m=None):
    """Smallest total flux reduction bringing a sky region to a target brightness.

    Minimises ``Σ_i γ_i L_i`` (lumens switched off) over ``γ ∈ [0, 1]^n`` subject to
    ``mean_region L((1 − γ) L) ≤ target``. Each iteration evaluates the region's mean
    luminance and its gradient with respect to γ by automatic differentiation through
    :meth:`SkyglowModel.render`, and solves the linearised problem exactly (a fractional
    knapsack: cells are dimmed in decreasing order of luminance removed per lumen). The
    skyglow is linear in the fluxes, so the first step is already optimal; further steps
    only correct round-off.

    Parameters
    ----------
    model, light_map
        As in :meth:`SkyglowModel.render`.
    region : Tensor (elevation, azimuth) of bool
    target_luminance_cd_m2 : float, optional
        Target mean luminance of the region [cd m^-2].
    target_fraction : float, optional
        Alternatively the target as a fraction of the current value, in [0, 1] (0: every
        cell that lights the region switched off).
    max_iterations : int
    tolerance : float
        Relative tolerance on the constraint, in [0, 1).
    as_dataset : bool
        Return a Dataset (default) or a dict of tensors and numbers.
    x_m, y_m, altitude_m : Tensor, optional
        Coordinates for a tensor light map (see :func:`light_map_arrays`).

    Returns
    -------
    xarray.Dataset
        ``reduction`` γ (y, x) [1] and ``flux`` (y, x) [lm] after the reduction; attributes
        ``initial_luminance``, ``final_luminance``, ``target_luminance`` [cd m^-2] and
        ``removed_flux_lm``.
    """
    check_model("model", model)
    as_dataset = check_flag("as_dataset", as_dataset)
    region = check_region(model, region)
    max_iterations = check_int("max_iterations", max_iterations, low=1, high=10_000)
    tolerance = float(check_range("tolerance", tolerance, 0.0, 1.0, high_inclusive=False))
    if (target_luminance_cd_m2 is None) == (target_fraction is None):
        raise ValueError("give exactly one of target_luminance_cd_m2 and target_fraction")
    if target_fraction is not None:
        check_range("target_fraction", target_fraction, 0.0, 1.0)
    else:
        check_range("target_luminance_cd_m2", target_luminance_cd_m2, 0.0)
    cells = light_map_arrays(light_map, x_m, y_m, altitude_m)
    _one_observer(observer_xy, observer_altitude_m, cells["flux"].dtype)
    flux0 = cells["flux"].detach()
    with torch.no_grad():
        initial = float(region_luminance(model, flux0, cells, region, observer_xy,
                                         observer_altitude_m, lamp))
    if target_fraction is not None:
        target = float(target_fraction) * initial
    else:
        target = float(check_range("target_luminance_cd_m2", target_luminance_cd_m2, 0.0))
    gamma = torch.zeros_like(flux0)
    current = initial
    for iteration in range(max_iterations):
        if current <= target * (1 + tolerance):
            break
        g = gamma.clone().requires_grad_(True)
        value = region_luminance(model, flux0 * (1 - g), cells, region, observer_xy,
                                 observer_altitude_m, lamp)
        (gradient,) = torch.autograd.grad(value, g)
        # linearised problem: value + Σ grad_i (γ'_i − γ_i) ≤ target, minimise Σ γ'_i L_i
        gain = (-gradient).clamp_min(0.0).reshape(-1)  # luminance removed per unit γ
        cost = flux0.reshape(-1)
        # need = Σ gain_i γ'_i required (gain = −grad); fill cells with the best gain /
        # cost first
        need = float(value.detach()) - target - float((gradient * gamma).sum())
        ratio = torch.where(cost > 0, gain / cost.clamp_min(1e-300), torch.zeros_like(gain))
        order = torch.argsort(ratio, descending=True)
        sorted_gain = gain[order]
        before = torch.cumsum(sorted_gain, 0) - sorted_gain  # removed by better cells
        take = ((need - before) / sorted_gain.clamp_min(1e-300)).clamp(0.0, 1.0)
        take = torch.where(sorted_gain > 0, take, torch.zeros_like(take))
        new = torch.zeros_like(cost)
        new[order] = take
        gamma = new.reshape(flux0.shape)
        with torch.no_grad():
            current = float(region_luminance(model, flux0 * (1 - gamma), cells, region,
                                             observer_xy, observer_altitude_m, lamp))
        logger.info("minimal_reduction iteration %d: region luminance %.6g (target %.6g)",
                    iteration, current, target)
    removed = float((gamma * flux0).sum())
    if not as_dataset:
        return {"reduction": gamma, "flux": flux0 * (1 - gamma), "final_luminance": current,
                "initial_luminance": initial, "target_luminance": target,
                "removed_flux_lm": removed}
    from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable

    coords = {
        "x": coordinate("x", cells["x_coord"], VariableSpec("m", "easting", "Cell centre.")),
        "y": coordinate("y", cells["y_coord"], VariableSpec("m", "northing", "Cell centre.")),
    }
    data = {
        "reduction": variable(("y", "x"), gamma, VariableSpec(
            "1", "flux reduction rate", "Fraction of the cell's flux to switch off.")),
        "flux": variable(("y", "x"), flux0 * (1 - gamma), VariableSpec(
            "lm", "luminous flux after reduction", "Remaining flux of each cell.")),
    }
    return build_dataset(data, coords, title="Minimal light reduction for a sky region",
                         references=["Dobashi, Y., Ishikawa, N. & Iwasaki, K. 2023, ACM "
                                     "Trans. Graph. 42, 219, doi:10.1145/3618337"],
                         parameters={"target_luminance_cd_m2": target,
                                     "initial_luminance_cd_m2": initial,
                                     "final_luminance_cd_m2": current,
                                     "removed_flux_lm": removed, "lamp": str(lamp),
                                     "region_pixels": int(region.sum())})
