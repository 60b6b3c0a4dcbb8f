"""Naive skyglow reference: direct accumulation of the kernel over the lighting cells.

For every lighting cell and every view direction of the model's panorama the
single-scattering kernel is integrated along the view ray (eq. 1–3 of Dobashi et al.
2023, the "naive method" of their §5.1) with the same physics and quadrature as the
precomputation — no PCA, no FFT. Two placements of the sources:

* ``sources="cells"`` — each Cartesian lighting cell at its exact distance, azimuth and
  altitude (the physical reference);
* ``sources="polar"`` — the cells' flux distributed over the model's polar nodes exactly as
  :meth:`SkyglowModel.render` does, so that the difference to ``render`` is the PCA
  truncation alone.

References
----------
1. Dobashi, Y., Ishikawa, N. & Iwasaki, K. 2023, ACM Trans. Graph. 42, 219,
   doi:10.1145/3618337.
"""

from __future__ import annotations

import torch

from skytorch._validate import check_choice, check_int
from skytorch.skyglow.kernel import Medium, kernel_radiance
from skytorch.skyglow.lamps import luminance_weights
from skytorch.skyglow.model import (
    SkyglowModel,
    check_flag,
    check_model,
    light_map_arrays,
    observer_altitudes,
    observer_positions,
    polar_offsets,
)
from skytorch.skyglow.units import NATURAL_ZENITH_SKY_MAG_ARCSEC2

__all__ = ["NAIVE_SOURCES", "kernel_table_sum", "naive_radiance_per_lumen", "render_naive"]

#: source placements of the naive reference
NAIVE_SOURCES = ("cells", "polar")


def _kernel_arguments(model: SkyglowModel) -> dict:
    p = model.parameters_used
    return {"emission": p["emission"], "emission_parameters": p.get("emission_parameters"),
            "source_radius_m": p["source_radius_m"], "n_steps": int(p["n_steps"]),
            "quadrature": p.get("quadrature", "single")}


def _accumulate(model, medium, theta_c, r, h_c, h_o, flux, chunk):
    """Σ flux_i b(θ − θ_i, φ, r_i, h_i, h_o) over sources (n,) for one observer."""
    azimuth = model.azimuth_rad.to(flux.dtype)
    elevation = model.elevation_rad.to(flux.dtype)
    n_p, n_t = elevation.numel(), azimuth.numel()
    total = torch.zeros(n_p, n_t, model.wavelength_nm.numel(), dtype=flux.dtype)
    per_source = n_p * n_t
    step = max(1, chunk // per_source)
    for start in range(0, flux.numel(), step):
        sl = slice(start, start + step)
        relative = azimuth[None, None, :] - theta_c[sl, None, None]
        b = kernel_radiance(medium, relative, elevation[None, :, None], r[sl, None, None],
                            h_c[sl, None, None], h_o, chunk_size=chunk,
                            **_kernel_arguments(model))
        total = total + (flux[sl, None, None, None] * b).sum(dim=0)
    return total


def naive_radiance_per_lumen(model: SkyglowModel, cells, observer_xy, observer_altitude_m=0.0,
                             *, sources: str = "cells", medium=None,
                             chunk_size: int = 65536) -> torch.Tensor:
    """``Σ_cells flux · b`` by direct kernel integration.

    Parameters
    ----------
    model : SkyglowModel
        Supplies the panorama grid, kernel settings and (unless ``medium`` is given) the
        atmosphere tables it was precomputed with.
    cells : mapping
        From :func:`~skytorch.skyglow.model.light_map_arrays`.
    observer_xy : array_like (2,) or (observer, 2)
    observer_altitude_m : float or array_like (observer,)
    sources : {"cells", "polar"}
    medium : Medium, optional
        Atmosphere tables (needed for a model read from a file).

    Returns
    -------
    Tensor (observer, elevation, azimuth, wavelength)
    """
    check_model("model", model)
    check_choice("sources", sources, NAIVE_SOURCES)
    chunk_size = check_int("chunk_size", chunk_size, low=1)
    medium = medium if medium is not None else model.medium
    if medium is None:
        raise ValueError("render_naive needs the atmosphere tables: pass medium=Medium(atm, "
                         "model.wavelength_nm) for a model loaded from a file")
    if not isinstance(medium, Medium):
        raise TypeError(f"medium must be a skytorch.skyglow.kernel.Medium; got "
                        f"{type(medium).__name__}: {medium!r:.60}")
    if medium.wavelength_nm.numel() != model.wavelength_nm.numel() or not bool(
            torch.allclose(medium.wavelength_nm, model.wavelength_nm.to(torch.float64))):
        raise ValueError(f"medium must hold the model's wavelengths "
                         f"{model.wavelength_nm.tolist()} nm; got "
                         f"{medium.wavelength_nm.tolist()} nm")
    if not isinstance(cells, dict) or any(k not in cells for k in ("flux", "x", "y",
                                                                     "altitude")):
        raise TypeError("cells must be the mapping of light_map_arrays() with flux, x, y "
                        f"and altitude; got {type(cells).__name__}")
    flux = cells["flux"].reshape(-1)
    dtype = flux.dtype
    observer_xy, _ = observer_positions(observer_xy, dtype)
    h_o = observer_altitudes(observer_altitude_m, observer_xy.shape[0], dtype)
    results = []
    for i in range(observer_xy.shape[0]):
        if sources == "cells":
            keep = flux != 0
            dx = cells["x"].reshape(-1)[keep] - observer_xy[i, 0]
            dy = cells["y"].reshape(-1)[keep] - observer_xy[i, 1]
            r, theta = polar_offsets(dx, dy)
            inside = r <= float(model.distance_edges_m[-1])
            theta = theta[inside]
            h_c = cells["altitude"].reshape(-1)[keep][inside]
            results.append(_accumulate(model, medium, theta, r[inside], h_c, h_o[i],
                                       flux[keep][inside], chunk_size))
            continue
        polar = model.polar_flux(cells["x"].reshape(-1), cells["y"].reshape(-1), flux,
                                 cells["altitude"].reshape(-1), observer_xy[i:i + 1])[0]
        it, ir, ih = torch.nonzero(polar, as_tuple=True)
        j, w = model.observer_altitude_weights(h_o[i:i + 1])
        total = 0.0
        for node, weight in ((int(j), 1 - float(w)), (int(j) + 1, float(w))):
            if weight == 0 or node >= model.observer_altitude_m.numel():
                continue
            total = total + weight * _accumulate(
                model, medium, model.azimuth_rad.to(dtype)[it], model.distance_m.to(dtype)[ir],
                model.source_altitude_m.to(dtype)[ih], model.observer_altitude_m[node].to(dtype),
                polar[it, ir, ih], chunk_size)
        results.append(total if isinstance(total, torch.Tensor) else torch.zeros(
            model.elevation_rad.numel(), model.azimuth_rad.numel(),
            model.wavelength_nm.numel(), dtype=dtype))
    return torch.stack(results)


def render_naive(model: SkyglowModel, light_map, observer_xy=(0.0, 0.0),
                 observer_altitude_m=0.0, *, lamp="white", sources: str = "cells",
                 medium=None, x_m=None, y_m=None, altitude_m=None, as_dataset: bool = True):
    """Skyglow panorama by direct accumulation over lighting cells (the reference).

    Same arguments, checks and output as :meth:`SkyglowModel.render`, plus ``sources``
    (see the module notes) and ``medium`` (a :class:`~skytorch.skyglow.kernel.Medium` at
    the model's wavelengths). With ``sources="cells"`` the kernel is integrated at the
    observer's own altitude, also outside the model's tabulated altitudes (recorded as
    ``observer_altitude_rendered_m``; ``render`` clamps to the table there).

    Examples
    --------
    >>> from skytorch.atmosphere import Atmosphere
    >>> from skytorch.skyglow import SkyglowModel
    >>> from skytorch.skyglow.citymap import point_sources
    >>> model = SkyglowModel.precompute(Atmosphere.earth(), n_azimuth=8, n_elevation=2,
    ...                                 n_distance=4, n_components=2, n_steps=4,
    ...                                 progress=False)
    >>> ds = render_naive(model, point_sources(2, 20e3, 2e3))
    >>> ds["luminance"].dims
    ('elevation', 'azimuth')
    """
    check_model("model", model)
    as_dataset = check_flag("as_dataset", as_dataset)
    cells = light_map_arrays(light_map, x_m, y_m, altitude_m)
    observer_xy, single = observer_positions(observer_xy, cells["flux"].dtype)
    observer_altitude_m = observer_altitudes(observer_altitude_m, observer_xy.shape[0],
                                             cells["flux"].dtype)
    weights, band_power = luminance_weights(lamp, model.wavelength_nm)
    per_lumen = naive_radiance_per_lumen(model, cells, observer_xy, observer_altitude_m,
                                         sources=sources, medium=medium)
    outputs = {"radiance": per_lumen * band_power.to(per_lumen.dtype),
               "luminance": per_lumen @ weights.to(per_lumen.dtype)}
    if single:
        outputs = {k: v[0] for k, v in outputs.items()}
    if not as_dataset:
        return outputs
    ds = model._dataset(outputs, cells, observer_xy, observer_altitude_m, lamp,
                        NATURAL_ZENITH_SKY_MAG_ARCSEC2, single)
    ds.attrs["title"] = f"Artificial skyglow panorama, naive reference (sources={sources})"
    if sources == "cells":  # integrated at the observer's own altitude, not the model's nodes
        ds.attrs["parameter_observer_altitude_rendered_m"] = ds.attrs[
            "parameter_observer_altitude_m"]
    return ds


def kernel_table_sum(model: SkyglowModel, polar: torch.Tensor, node: int = 0) -> torch.Tensor:
    """Compute the naive sum on the model's grid from its stored kernel table (no PCA, no FFT).

    ``Σ_{i,j,k} F(θ_i, r_j, h_k) b(θ − θ_i, φ, r_j, h_k, h_o)`` with the kernel values kept
    by ``SkyglowModel.precompute(..., keep_kernel=True)`` — the same numbers
    :func:`naive_radiance_per_lumen` integrates with ``sources="polar"``, without
    integrating them again.

    Parameters
    ----------
    model : SkyglowModel
        With ``model.kernel``.
    polar : Tensor (azimuth, distance, source_altitude)
        Flux per polar node (one observer, from :meth:`SkyglowModel.polar_flux`).
    node : int
        Observer-altitude node.

    Returns
    -------
    Tensor (elevation, azimuth, wavelength)
    """
    check_model("model", model)
    if model.kernel is None:
        raise ValueError("kernel_table_sum needs precompute(..., keep_kernel=True)")
    node = check_int("node", node, 0, model.kernel.shape[0] - 1)
    expected = (model.azimuth_rad.numel(), model.distance_m.numel(),
                model.source_altitude_m.numel())
    if not isinstance(polar, torch.Tensor) or tuple(polar.shape) != expected:
        raise ValueError(f"polar must be a tensor of shape (azimuth, distance, "
                         f"source_altitude) = {expected}; got "
                         f"{tuple(getattr(polar, 'shape', ())) or type(polar).__name__}")
    kernel = model.kernel[node].to(polar.dtype)  # (r, hc, θ, φ, λ)
    total = torch.zeros(kernel.shape[2:], dtype=polar.dtype)  # (θ, φ, λ)
    for i in torch.nonzero(polar.abs().sum(dim=(1, 2)))[:, 0].tolist():
        image = torch.einsum("rh,rhtpw->tpw", polar[i], kernel)
        total += torch.roll(image, shifts=i, dims=0)  # b(θ − θ_i)
    return total.permute(1, 0, 2)
