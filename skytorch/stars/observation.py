"""The night sky of a catalogue seen from one site: positions, magnitudes, colours, visibility.

:func:`observe` is the Dataset layer; :func:`observe_tensors` the tensor layer that the
benchmark times. Refraction and extinction come from the atmosphere model through two
small tables per call (:func:`refraction_table`, :func:`skytorch.stars.photometry.
extinction_table`), evaluated once for the site and interpolated for all stars and times.

References
----------
1. Müller, S., Engel, J., Döllner, J. 2012, "Single-Pass Rendering of Day and Night Sky
   Phenomena", Proc. VMV 2012, §4 (stars), §5 (day–night factor).
2. Schaefer, B. E. 1990, "Telescopic limiting magnitudes", PASP 102, 212,
   doi:10.1086/132629.
3. Young, A. T. 1967, "Photometric error analysis. VI.", AJ 72, 747, doi:10.1086/110303.
"""

from __future__ import annotations

import json
import logging
import math

import numpy as np
import torch
import xarray as xr

from skytorch._cache import MemoryCache, atmosphere_key, clone_tables, value_key
from skytorch._memory import Scratch
from skytorch._validate import (
    check_broadcastable,
    check_choice,
    check_finite,
    check_int,
    check_range,
    refuse_gradient,
)
from skytorch.constants import EARTH_MEAN_RADIUS_M
from skytorch.dataset import VariableSpec, build_dataset, coordinate, time_coordinate, variable
from skytorch.ephemeris import check_observer, parse_times, sun_moon
from skytorch.moon.sky import nanolambert_to_mag_arcsec2
from skytorch.stars.photometry import (
    apparent_color,
    apparent_color_table,
    apparent_horizon,
    brightness_ratio,
    bv_to_srgb,
    check_atmosphere,
    check_flag,
    extinction_table,
    grid_altitudes,
    lerp,
    star_color,
    star_color_table,
    star_table_pays_off,
    table_lookup,
    table_low,
)
from skytorch.stars.positions import (
    aberration_operators,
    horizontal_planes,
    star_vectors,
    time_operators,
)
from skytorch.stars.scintillation import scintillation_law, twinkle
from skytorch.stars.visibility import (
    VISIBILITY_MODELS,
    count_true,
    count_visible,
    limiting_magnitude,
    muller_day_night_factor,
)

__all__ = ["observe", "observe_tensors", "refract", "refraction_table", "site_tables"]

logger = logging.getLogger(__name__)

#: times processed together (keeps the temporaries in cache)
TIME_CHUNK = 32
#: squared floor of the horizontal component (keeps d altitude finite at the zenith)
_TINY = 1e-30
#: refraction tables of recent (atmosphere parameters, altitude, nodes), keyed by value: a
#: table costs about 0.5 s to trace and 0.1 ms to find again (docs/stars.md, "Caches")
_REFRACTION_TABLES = MemoryCache(8, copy=clone_tables)


def refraction_table(atmosphere, altitude_m: float = 0.0, n_nodes: int = 256
                     ) -> dict[str, torch.Tensor]:
    """Ray-traced refraction tabulated against true altitude.

    Parameters
    ----------
    atmosphere : skytorch.atmosphere.Atmosphere
    altitude_m : float
        Observer altitude [m].
    n_nodes : int
        Nodes of the table (:func:`skytorch.stars.photometry.grid_altitudes`).

    Returns
    -------
    dict of float64 torch.Tensor
        ``true_altitude_rad`` (n_nodes,) from the true altitude of the apparent horizon
        (about −0.57° at sea level, −2.47° from 3 km) to π/2, ``refraction_rad``
        (n_nodes,) apparent − true, and ``low_rad`` (0-d) the first node.

    Notes
    -----
    ``atmosphere.refraction`` is evaluated on a grid of 4 n_nodes apparent altitudes in
    [h₀, π/2] (dense near the horizon), giving true = apparent − R; R is then resampled
    on the true-altitude grid by linear interpolation. h₀ is the apparent horizon,
    :func:`skytorch.stars.photometry.apparent_horizon`: 0 at the surface, minus the
    apparent dip of the horizon for an elevated observer, who sees below the
    astronomical horizon.

    The tables of the 8 most recent (atmosphere parameters, ``altitude_m``, ``n_nodes``)
    are kept in memory, keyed by the atmosphere's ``parameters_dict()`` values (two equal
    atmospheres share a table; :func:`skytorch._cache.atmosphere_key`); every call returns
    its own copy. An atmosphere without ``parameters_dict`` is traced on every call.
    """
    check_atmosphere("atmosphere", atmosphere, ("refraction",))
    altitude_m = float(check_range("altitude_m", altitude_m, 0.0, 1e5, unit=" m"))
    n_nodes = check_int("n_nodes", n_nodes, 8, 100_000)
    key = atmosphere_key(atmosphere)
    if key is not None:
        key = value_key("refraction_table", key, altitude_m, n_nodes)
    return _REFRACTION_TABLES.get(
        key, lambda: _trace_refraction_table(atmosphere, altitude_m, n_nodes))


def _trace_refraction_table(atmosphere, altitude_m: float, n_nodes: int
                            ) -> dict[str, torch.Tensor]:
    """Trace the table of :func:`refraction_table` (checked arguments, not cached)."""
    with torch.no_grad():
        apparent = grid_altitudes(4 * n_nodes, apparent_horizon(atmosphere, altitude_m),
                                  torch.float64)
        bend = atmosphere.refraction(apparent, altitude_m).to(torch.float64).reshape(-1)
        true = apparent - bend
        low = float(true[0])
        nodes = grid_altitudes(n_nodes, low, torch.float64)
        resampled = np.interp(nodes.numpy(), true.numpy(), bend.numpy())
    return {"true_altitude_rad": nodes, "refraction_rad": torch.from_numpy(resampled),
            "low_rad": torch.tensor(low, dtype=torch.float64)}


def refract(true_altitude_rad: torch.Tensor, table: dict[str, torch.Tensor]) -> torch.Tensor:
    """Apparent altitude [rad] from true altitude with a :func:`refraction_table`.

    Below the table (the source is below the apparent horizon) the refraction of the
    lowest node is added, keeping the altitude continuous and finite.
    """
    low = float(table["low_rad"])
    index, weight = table_lookup(true_altitude_rad, table["refraction_rad"].numel(), low)
    return true_altitude_rad + lerp(table["refraction_rad"].to(true_altitude_rad.dtype),
                                    index, weight)


#: fine uniform grid of true altitude used for the per-star lookups [deg]
LOOKUP_LOW_DEG = -2.0
LOOKUP_STEP_DEG = 0.01


def site_tables(refraction: dict[str, torch.Tensor] | None,
                extinction_tab: dict[str, torch.Tensor] | None,
                dtype: torch.dtype = torch.float64) -> dict[str, torch.Tensor]:
    """Refraction, extinction and air mass resampled on a fine uniform true-altitude grid.

    Parameters
    ----------
    refraction : dict or None
        :func:`refraction_table` (``None``: no refraction).
    extinction_tab : dict or None
        :func:`skytorch.stars.photometry.extinction_table` (``None``: no extinction, air
        mass 1/sin h capped at 40).
    dtype : torch.dtype
        dtype of the returned tables.

    Returns
    -------
    dict
        ``values`` (4, n) and ``slopes`` (4, n): refraction [rad], extinction offset A
        and colour term B [mag], air mass, on true altitudes −2° … 90° every 0.01° (the
        last node's slope 0);
        ``pairs`` (4, n), complex: ``values + i slopes``, both gathered by one look-up
        (``low_rad``, ``step_rad``; from further down for an elevated observer, whose
        horizon lies below −2°); ``horizon_rad``: the apparent altitude of the horizon
        (the ground), the first node of the extinction table
        (:func:`skytorch.stars.photometry.apparent_horizon`; 0 without tables).

    Notes
    -----
    The accurate tables (dense near the horizon) are evaluated once at the 9 201 fine
    nodes; per star and time the lookup is then one index computation and four
    gathers. Linear resampling of a piecewise-linear function on a 0.01° grid changes it
    by < 1e-6 mag and < 0.01″.
    """
    horizon = (table_low(extinction_tab) if extinction_tab is not None
               else float(refraction["low_rad"] + refraction["refraction_rad"][0])
               if refraction is not None else 0.0)
    lowest = math.degrees(float(refraction["low_rad"]) if refraction is not None else horizon)
    low_deg = LOOKUP_LOW_DEG if lowest >= LOOKUP_LOW_DEG + 0.5 else math.floor(lowest - 0.5)
    low, step = math.radians(low_deg), math.radians(LOOKUP_STEP_DEG)
    count = int(round((90.0 - low_deg) / LOOKUP_STEP_DEG)) + 1
    true = low + step * torch.arange(count, dtype=torch.float64)
    true[-1] = 0.5 * math.pi
    with torch.no_grad():
        bend = (refract(true, refraction) - true if refraction is not None
                else torch.zeros_like(true))
        apparent = true + bend
        if extinction_tab is not None:
            index, weight = table_lookup(apparent, extinction_tab["offset"].numel(),
                                         table_low(extinction_tab))
            offset = lerp(extinction_tab["offset"], index, weight)
            colour = lerp(extinction_tab["colour"], index, weight)
            airmass = lerp(extinction_tab["airmass"], index, weight)
        else:
            offset = colour = torch.zeros_like(true)
            airmass = 1.0 / torch.sin(apparent).clamp_min(1.0 / 40.0)
    values = torch.stack([bend, offset, colour, airmass]).to(dtype)
    slopes = torch.diff(values, dim=-1, append=values[:, -1:])
    pairs = torch.view_as_complex(torch.stack([values, slopes], dim=-1))
    return {"values": values, "slopes": slopes, "pairs": pairs, "low_rad": low,
            "step_rad": step, "count": count, "horizon_rad": horizon}


#: observer elevation accepted by :func:`observe` [m]: within the ephemeris' range and the
#: ranges of the extinction tables (>= 0) and of the scintillation law (<= 10 km)
ELEVATION_RANGE_M = (0.0, 1.0e4)
#: columns a catalogue Dataset must have (dimension ``star``)
CATALOG_VARIABLES = ("ra", "dec", "pm_ra", "pm_dec", "parallax", "vmag", "bv")
#: computation dtypes of :func:`observe`
OBSERVE_DTYPES = (torch.float64, torch.float32)


def _check_catalog(catalog) -> xr.Dataset:
    if not isinstance(catalog, xr.Dataset):
        raise TypeError("catalog must be an xarray.Dataset of stars (bright_stars(), "
                        f"read_bsc5()); got {type(catalog).__name__}: {catalog!r:.60}")
    missing = [name for name in CATALOG_VARIABLES if name not in catalog]
    if missing:
        raise ValueError(f"catalog must have the variables {CATALOG_VARIABLES}; missing "
                         f"{missing}")
    return catalog


def _catalog_epoch(catalog: xr.Dataset) -> float:
    """Return the epoch of the catalogue's positions [Julian year] (attrs, default 2000)."""
    epoch = catalog.attrs.get("epoch_jyear", 2000.0)
    if isinstance(epoch, (bool, str)) or not isinstance(epoch, (int, float, np.number)):
        raise TypeError(f"catalog.attrs['epoch_jyear'] must be a number (Julian year); got "
                        f"{epoch!r:.40}")
    return float(check_range("catalog.attrs['epoch_jyear']", float(epoch), 1000.0, 3000.0,
                             unit=" yr"))


def _parse_times(times) -> np.ndarray:
    """:func:`skytorch.ephemeris.parse_times`, its errors prefixed with the parameter name."""
    try:
        return parse_times(times)
    except (ValueError, TypeError) as error:
        if str(error).startswith("times"):
            raise
        raise type(error)(f"times: {error}") from error


def _observer_arrays(lat_deg, lon_deg, elevation_m):
    """Return the observer coordinates as 1-d float arrays of one common length.

    Raises ValueError naming the parameters and their shapes otherwise.
    """
    arrays = {}
    for name, value in (("lat_deg", lat_deg), ("lon_deg", lon_deg),
                        ("elevation_m", elevation_m)):
        tensor = check_finite(name, value, dtype=torch.float64)
        if tensor.ndim > 1:
            raise ValueError(f"{name} must be a number or a 1-d array (observer,); got shape "
                             f"{tuple(tensor.shape)}")
        arrays[name] = tensor.reshape(-1).numpy()
        if arrays[name].size == 0:
            raise ValueError(f"{name} must hold at least one observer; got an empty array")
    shape = check_broadcastable(**{k: torch.from_numpy(v) for k, v in arrays.items()})
    return tuple(np.broadcast_to(v, shape).copy() for v in arrays.values())


def _observe_several(catalog, times, lat_deg, lon_deg, elevation_m, atmosphere, refraction,
                     **options) -> xr.Dataset:
    """:func:`observe` for several observers, stacked along a leading ``observer`` dim."""
    lat, lon, elevation = _observer_arrays(lat_deg, lon_deg, elevation_m)
    # independent twinkle sequences: one seed per observer from the given one
    seeds = [int(np.random.SeedSequence([options["seed"], k]).generate_state(1, np.uint64)[0]
                 >> np.uint64(1)) for k in range(lat.size)]
    parts = [observe(catalog, times, float(a), float(b), float(c), atmosphere, refraction,
                     **{**options, "seed": seed})
             for a, b, c, seed in zip(lat, lon, elevation, seeds, strict=True)]
    per_observer = [name for name, var in parts[0].data_vars.items() if "time" in var.dims]
    stacked = xr.concat([part[per_observer] for part in parts], dim="observer",
                        coords="minimal", compat="override", combine_attrs="override")
    result = parts[0].drop_vars(per_observer).merge(stacked, combine_attrs="override")
    specs = {"lat": ("degree_north", "latitude", "Geodetic (WGS84) latitude.", "latitude"),
             "lon": ("degree_east", "longitude", "East longitude.", "longitude"),
             "elevation": ("m", "elevation", "Height above the WGS84 ellipsoid.", None)}
    coords = {"observer": coordinate("observer", np.arange(lat.size), VariableSpec(
        "1", "observer index", "Position in the list of observers."))}
    for (name, (units, long_name, text, standard)), values in zip(
            specs.items(), (lat, lon, elevation), strict=True):
        coords[name] = variable("observer", values, VariableSpec(units, long_name, text,
                                                                 standard))
    result = result.assign_coords(coords)
    for key in ("parameter_lat_deg", "parameter_lon_deg", "parameter_elevation_m"):
        result.attrs.pop(key, None)
    observers = {"lat_deg": lat.tolist(), "lon_deg": lon.tolist(),
                 "elevation_m": elevation.tolist()}
    parameters = json.loads(result.attrs.get("parameters", "{}"))
    parameters.update(observers, seed=int(options["seed"]))
    result.attrs["parameters"] = json.dumps(parameters, default=str)
    result.attrs["parameter_seed"] = int(options["seed"])
    result.attrs["observers"] = json.dumps(observers)
    return result


def _lerp_take(values: torch.Tensor, slopes: torch.Tensor, index: torch.Tensor,
               weight: torch.Tensor) -> torch.Tensor:
    """``values[i] + slopes[i] w`` with :func:`torch.take` (faster than advanced indexing)."""
    return torch.addcmul(torch.take(values, index), torch.take(slopes, index), weight)


def _lerp_pairs(pairs: torch.Tensor, index: torch.Tensor, weight: torch.Tensor,
                scratch: Scratch, out: torch.Tensor) -> torch.Tensor:
    """:func:`_lerp_take` with one gather of the (value, slope) pairs (enabled scratch).

    The same product and sum as :func:`_lerp_take` (one ``addcmul``), hence the same
    values.
    """
    taken = torch.view_as_real(torch.take(pairs, index,
                                          out=scratch("pairs", index.shape, pairs.dtype)))
    return torch.addcmul(taken[..., 0], taken[..., 1], weight, out=out)


def _node_and_weight(x: torch.Tensor, scratch: Scratch, name: str
                     ) -> tuple[torch.Tensor, torch.Tensor]:
    """Split fractional node coordinates x into the node below (int64) and the weight.

    At the last node (x = n − 1) the index is the last node and the weight 0, whose slope
    the tables set to 0. With ``scratch`` enabled the weight overwrites ``x``.
    """
    floor = torch.floor(x.detach(), out=scratch(name + "_floor", x.shape, x.dtype))
    index = scratch(name, x.shape, torch.int64)
    index = floor.long() if index is None else index.copy_(floor)
    return index, torch.sub(x, floor, out=x if scratch.enabled else None)


def _observe_chunk(stars_t: torch.Tensor, operators: torch.Tensor, vmag: torch.Tensor,
                   bv: torch.Tensor, tables: dict, scratch: Scratch,
                   rows: dict[str, torch.Tensor], color_table: dict | None = None
                   ) -> dict[str, torch.Tensor]:
    """Apparent altitude, azimuth, magnitude and air mass of the stars at a chunk of times.

    With ``scratch`` enabled every result is written into ``rows`` (the output's rows of
    the chunk) and every temporary into the scratch buffers; otherwise (gradients) the
    results are new tensors, returned for the caller to copy. With a ``color_table``
    (:func:`skytorch.stars.photometry.star_color_table`) also the apparent ``color``.
    """
    dtype = stars_t.dtype
    shape = (operators.shape[0], stars_t.shape[1])
    names = ("altitude", "azimuth", "magnitude", "airmass", "color")
    rows = {name: rows.get(name) if scratch.enabled else None for name in names}
    south, west, up = horizontal_planes(stars_t, operators,
                                        out=scratch("planes", (3 * shape[0], shape[1]), dtype))
    if scratch.enabled:
        horizontal = torch.hypot(south, west, out=scratch("horizontal", shape, dtype))
    else:  # hypot's gradient is NaN at the zenith
        horizontal = torch.sqrt(torch.addcmul(south * south, west, west) + _TINY)
    true = torch.atan2(up, horizontal, out=scratch("true", shape, dtype))
    azimuth = torch.atan2(west, south, out=rows["azimuth"])
    azimuth = torch.add(azimuth, math.pi, out=rows["azimuth"])
    # x = (true − low)/step on the uniform grid, clamped to its nodes
    shift = torch.tensor(-tables["low_rad"] / tables["step_rad"], dtype=dtype)
    x = torch.add(shift, true, alpha=1.0 / tables["step_rad"], out=scratch("x", shape, dtype))
    x = torch.clamp(x, 0.0, float(tables["count"] - 1), out=x if scratch.enabled else None)
    index, weight = _node_and_weight(x, scratch, "index")

    def lookup(row: int, out: torch.Tensor | None) -> torch.Tensor:
        if scratch.enabled:
            return _lerp_pairs(tables["pairs"][row], index, weight, scratch, out)
        return _lerp_take(tables["values"][row], tables["slopes"][row], index, weight)

    altitude = torch.add(lookup(0, rows["altitude"]), true, out=rows["altitude"])
    colour_term = lookup(2, scratch("colour_term", shape, dtype))
    magnitude = torch.addcmul(lookup(1, rows["magnitude"]), colour_term, bv,
                              out=rows["magnitude"])
    magnitude = torch.add(magnitude, vmag, out=rows["magnitude"])
    result = {"altitude": altitude, "azimuth": azimuth, "magnitude": magnitude,
              "airmass": lookup(3, rows["airmass"])}
    if color_table is not None:
        result["color"] = star_color(altitude, color_table, out=rows["color"], scratch=scratch)
    return result


def observe_tensors(stars: torch.Tensor, vmag: torch.Tensor, bv: torch.Tensor,
                    operators: torch.Tensor, velocity_m_s: torch.Tensor | None,
                    refraction: dict[str, torch.Tensor] | None,
                    extinction_tab: dict[str, torch.Tensor] | None,
                    time_chunk: int = TIME_CHUNK,
                    color_table: dict[str, torch.Tensor] | None = None
                    ) -> dict[str, torch.Tensor]:
    """Apparent altitude, azimuth, magnitude, air mass (and colour) of all stars at all times.

    Parameters
    ----------
    stars : torch.Tensor, shape (star, 8)
        :func:`skytorch.stars.positions.star_vectors`; its dtype is the output dtype.
    vmag, bv : torch.Tensor, shape (star,)
        V magnitude and B−V [mag].
    operators : torch.Tensor, shape (time, 3, 8)
    velocity_m_s : torch.Tensor or None, shape (time, 3)
        Observer's barycentric velocity [m/s] from
        :func:`skytorch.stars.positions.time_operators`; ``None`` skips aberration.
    refraction : dict or None
        :func:`refraction_table`; ``None`` for geometric altitudes.
    extinction_tab : dict or None
        :func:`skytorch.stars.photometry.extinction_table`; ``None`` for magnitudes above
        the atmosphere (air mass from the plane-parallel 1/sin h, capped at 40).
    time_chunk : int
        Times processed per step.
    color_table : dict, optional
        :func:`skytorch.stars.photometry.star_color_table` of the same stars: adds the
        apparent colour, looked up per chunk of times.

    Returns
    -------
    dict of torch.Tensor, each (time, star)
        ``altitude`` and ``azimuth`` [rad], ``magnitude`` [mag] (V after extinction;
        below the horizon the horizon extinction, finite), ``airmass`` [1] and
        ``above_horizon`` (bool, apparent altitude at or above the apparent horizon: 0
        at the surface, minus the dip of the horizon for an elevated observer); with
        ``color_table`` also
        ``color`` (time, star, 3), as :func:`skytorch.stars.photometry.apparent_color`.

    Notes
    -----
    Per chunk of times: one GEMM with aberration folded into the operators
    (:func:`skytorch.stars.positions.aberration_operators`), altitude
    ``atan2(up, √(n² + e² + 1e-30))`` (finite gradients at the zenith), azimuth from
    north through east, and one lookup in :func:`site_tables` for refraction,
    extinction and air mass.
    """
    dtype = stars.dtype
    n_time, n_star = operators.shape[0], stars.shape[0]
    out = {name: torch.empty(n_time, n_star, dtype=dtype)
           for name in ("altitude", "azimuth", "magnitude", "airmass")}
    if color_table is not None:
        if color_table["offsets"].numel() != n_star:
            raise ValueError(f"color_table must be built for the {n_star} stars; got "
                             f"{color_table['offsets'].numel()}")
        out["color"] = torch.empty(n_time, n_star, 3, dtype=dtype)
    vmag = vmag.to(dtype)
    bv = bv.to(dtype)
    if velocity_m_s is not None:
        operators = aberration_operators(operators, velocity_m_s)
    # negated north and east rows: azimuth = atan2(−e, −n) + π lands in [0, 2π]
    operators = operators * torch.tensor([-1.0, -1.0, 1.0], dtype=operators.dtype)[:, None]
    stars_t = stars.T.contiguous()
    tables = site_tables(refraction, extinction_tab, dtype)
    needs_grad = torch.is_grad_enabled() and any(
        t.requires_grad for t in (stars, vmag, bv, operators))
    scratch = Scratch(enabled=not needs_grad)
    for start in range(0, n_time, time_chunk):
        sl = slice(start, min(start + time_chunk, n_time))
        chunk = _observe_chunk(stars_t, operators[sl], vmag, bv, tables, scratch,
                               {name: value[sl] for name, value in out.items()},
                               color_table)
        if needs_grad:  # the chunk's values are new tensors: copy them in
            for name, value in chunk.items():
                out[name][sl] = value
    out["above_horizon"] = out["altitude"] >= tables["horizon_rad"]
    return out


_SPECS = {
    "altitude": VariableSpec("degree", "apparent altitude",
                             "Topocentric altitude above the horizontal plane: proper motion, "
                             "parallax, annual + diurnal aberration, precession-nutation, "
                             "and refraction when enabled."),
    "azimuth": VariableSpec("degree", "azimuth",
                            "Azimuth from north through east."),
    "magnitude": VariableSpec("mag", "apparent V magnitude after extinction",
                              "V magnitude seen through the atmosphere along the refracted "
                              "path; below the horizon the horizon value (see visible)."),
    "airmass": VariableSpec("1", "relative air mass",
                            "Slant over vertical V-band optical depth of the atmosphere "
                            "model along the path."),
    "above_horizon": VariableSpec("1", "star above the horizon",
                                  "True where the apparent altitude is at or above "
                                  "the apparent horizon (0 at the surface; minus the "
                                  "refracted dip of the horizon for an elevated "
                                  "observer, the geometric dip without an atmosphere)."),
    "visible": VariableSpec("1", "star visible to the naked eye",
                            "Above the horizon and brighter than the limiting magnitude "
                            "(with visibility='muller2012' the limit plus 2.5 log10 of "
                            "day_night_factor, Mueller et al. 2012)."),
    "relative_brightness": VariableSpec(
        "1", "relative brightness", "10^(0.4 (m_a - m)) times the day-night factor "
        "(Mueller et al. 2012), 0 below the horizon."),
    "scintillation_index": VariableSpec(
        "1", "scintillation index", "Relative intensity variance (Young 1967); 0 without an "
        "atmosphere."),
    "twinkle": VariableSpec("1", "relative intensity (twinkling)",
                            "Seeded log-normal intensity sequence I/<I> with the "
                            "scintillation index of the star."),
    "limiting_magnitude": VariableSpec(
        "mag", "naked-eye limiting magnitude",
        "Faintest V visible against the sky background (Schaefer 1990)."),
    "sky_brightness": VariableSpec(
        "mag arcsec-2", "sky surface brightness at the star",
        "V sky background interpolated from the background Dataset at the star's "
        "apparent altitude and azimuth."),
    "n_visible": VariableSpec("1", "number of visible stars",
                              "Stars above the horizon brighter than the limiting magnitude "
                              "(with visibility='muller2012' the limit plus 2.5 log10 of "
                              "day_night_factor): the count of visible."),
    "day_night_factor": VariableSpec(
        "1", "day-night visibility factor",
        "(1 + (sin h_sun + 1.14)^32)^(-1/2) (Mueller et al. 2012, section 5)."),
    "color": VariableSpec("1", "apparent star colour (sRGB)",
                          "Gamma-encoded sRGB (largest linear component 1) of a black body "
                          "at the Ballesteros (2012) temperature of B-V, seen through the "
                          "atmosphere: spectral extinction along the refracted path "
                          "reddens stars near the horizon; below the horizon the horizon "
                          "colour."),
    "color_exoatmospheric": VariableSpec(
        "1", "star colour above the atmosphere (sRGB)",
        "Gamma-encoded sRGB (largest linear component 1) of a black body at the "
        "Ballesteros (2012) temperature of B-V, without extinction."),
    "vmag": VariableSpec("mag", "V magnitude above the atmosphere", "Catalogue V."),
    "bv": VariableSpec("mag", "B-V colour index", "Catalogue B-V."),
}


def _site_atmosphere_tables(atmosphere, elevation: float, refraction: bool):
    """Return the refraction and extinction tables of a site (``None`` where not used)."""
    if atmosphere is None:
        return None, None
    return (refraction_table(atmosphere, elevation) if refraction else None,
            extinction_table(atmosphere, elevation, refraction=refraction))


def _colour_source(atmosphere, elevation: float, refraction: bool, bv: torch.Tensor,
                   n_time: int):
    """Return the apparent-colour table of a site and, where it pays off, per star.

    ``(None, None)`` without an ``atmosphere`` (none, or no reddening asked).
    """
    if atmosphere is None:
        return None, None
    table = apparent_color_table(atmosphere, elevation, refraction=refraction)
    per_star = star_color_table(bv, table) if star_table_pays_off(n_time, table) else None
    return table, per_star


def _star_colours(bv: torch.Tensor, result: dict[str, torch.Tensor], table
                  ) -> tuple[torch.Tensor, torch.Tensor]:
    """Return the apparent (time, star, 3) and exo-atmospheric (star, 3) colours.

    The apparent colour is ``result["color"]`` where :func:`observe_tensors` looked it
    up, else :func:`apparent_color` at the two nodes around each star; without a
    ``table`` it repeats the exo-atmospheric colour over time.
    """
    altitude = result["altitude"]
    color_exo = bv_to_srgb(bv).to(altitude.dtype)
    if "color" in result:
        return result["color"], color_exo
    if table is None:
        return color_exo.expand(altitude.shape[0], *color_exo.shape), color_exo
    return apparent_color(bv, altitude, table), color_exo


def _brightness_and_scintillation(result: dict[str, torch.Tensor], control_magnitude: float,
                                  factor: torch.Tensor | None, aperture_m: float,
                                  exposure_s: float, elevation: float,
                                  atmosphere: bool = True, time_chunk: int = TIME_CHUNK
                                  ) -> tuple[torch.Tensor, torch.Tensor]:
    """Return the relative brightness and the scintillation index (time, star).

    The brightness is 0 below the horizon and scaled by the day-night ``factor`` (time,)
    when given; the scintillation index is taken at the air mass (at least 1), and is 0
    without an ``atmosphere`` (no air, no scintillation). Computed per chunk of times,
    which keeps the temporaries small.
    """
    magnitude, above, airmass = (result[name] for name in
                                 ("magnitude", "above_horizon", "airmass"))
    brightness, scint = torch.empty_like(magnitude), torch.empty_like(magnitude)
    coefficient, exponent = scintillation_law(aperture_m, exposure_s, elevation)
    # coefficient X^p as exp(p ln X + ln coefficient): pow with a scalar exponent is
    # several times slower than log and exp
    log_coefficient = torch.tensor(math.log(coefficient), dtype=magnitude.dtype)
    for start in range(0, magnitude.shape[0], time_chunk):
        sl = slice(start, start + time_chunk)
        chunk = brightness_ratio(magnitude[sl], control_magnitude, out=brightness[sl])
        chunk.mul_(above[sl])
        if factor is not None:
            chunk.mul_(factor[sl, None])
        chunk = torch.clamp(airmass[sl], min=1.0, out=scint[sl]).log_()
        torch.add(log_coefficient, chunk, alpha=exponent, out=chunk).exp_()
    if not atmosphere:
        scint.zero_()
    return brightness, scint


def _day_night_factor(times: np.ndarray, lat: float, lon: float, elevation: float,
                      dtype: torch.dtype) -> torch.Tensor:
    """Compute Müller et al.'s day-night factor (time,) from the Sun's altitude."""
    sun = sun_moon(times, lat, lon, elevation)
    return muller_day_night_factor(torch.deg2rad(
        torch.as_tensor(sun["sun_altitude"].values, dtype=dtype)))


def _twinkle(scint: torch.Tensor, samples: int, interval_s: float, seed: int):
    """Return the ``twinkle`` variable (time, star, sample) and its ``sample`` coordinate."""
    sequence = twinkle(scint, samples, sample_interval_s=interval_s, seed=seed)
    return (variable(("time", "star", "sample"), sequence, _SPECS["twinkle"]),
            coordinate("sample", interval_s * np.arange(samples),
                       VariableSpec("s", "time within the twinkle sequence",
                                    "Seconds from its start.")))


#: units accepted for a per-direction background: surface brightness or luminance
BACKGROUND_UNITS = {
    "sky_brightness": ("mag arcsec-2", "mag/arcsec^2", "mag/arcsec2", "mag arcsec^-2"),
    "luminance": ("cd m-2", "cd/m^2", "cd/m2", "nL", "nanolambert"),
}
#: candela per square metre in one nanolambert: 1 L = 10⁴/π cd m⁻²
CD_M2_PER_NANOLAMBERT = 1e-5 / math.pi


def _background_variable(background) -> tuple[xr.DataArray, str]:
    """Check a per-direction background Dataset; return its variable and its name."""
    if not isinstance(background, xr.Dataset):
        raise TypeError("background must be an xarray.Dataset with 'sky_brightness' [mag "
                        "arcsec-2] or 'luminance' [cd m-2 or nL] over (altitude, azimuth) "
                        f"[degree]; got {type(background).__name__}: {background!r:.60}")
    names = [name for name in BACKGROUND_UNITS if name in background]
    if len(names) != 1:
        raise ValueError("background must have exactly one of the variables "
                         f"{tuple(BACKGROUND_UNITS)}; got {sorted(background.data_vars)}")
    name = names[0]
    var = background[name]
    units = str(var.attrs.get("units", ""))
    if units not in BACKGROUND_UNITS[name]:
        raise ValueError(f"background[{name!r}].attrs['units'] must be one of "
                         f"{BACKGROUND_UNITS[name]}; got {units!r}")
    extra = set(var.dims) - {"time", "altitude", "azimuth"}
    if {"altitude", "azimuth"} - set(var.dims) or extra:
        raise ValueError(f"background[{name!r}] must have the dimensions (altitude, azimuth) "
                         f"and optionally time; got {var.dims}")
    for coord, low, high in (("altitude", -90.0, 90.0), ("azimuth", 0.0, 360.0)):
        values = np.asarray(var[coord].values, dtype=float)
        if values.size < 2 or not np.all(np.diff(values) > 0) or values[0] < low \
                or values[-1] > high:
            raise ValueError(f"background coordinate {coord!r} must increase strictly "
                             f"within [{low}, {high}] degree with at least 2 values; got "
                             f"{values!r:.80}")
    return var, name


def _background_sky(background, n_time: int, altitude_rad: torch.Tensor,
                    azimuth_rad: torch.Tensor, above: torch.Tensor) -> torch.Tensor:
    """Sky surface brightness [mag arcsec⁻²] (time, star) where each star is in the sky.

    Bilinear in (altitude, azimuth), periodic in azimuth. A star above the horizon outside
    the background's altitudes raises; below the horizon (never visible) the nearest row.
    """
    var, name = _background_variable(background)
    var = var.transpose(*[d for d in ("time", "altitude", "azimuth") if d in var.dims])
    if "time" in var.dims and var.sizes["time"] != n_time:
        raise ValueError(f"background has {var.sizes['time']} times; observe has {n_time}")
    dtype = altitude_rad.dtype
    if not (np.issubdtype(var.dtype, np.floating) or np.issubdtype(var.dtype, np.integer)):
        raise TypeError(f"background[{name!r}] must hold numbers; got dtype {var.dtype}")
    values = torch.tensor(np.array(var.values, dtype=np.float64), dtype=dtype)
    if "time" not in var.dims:
        values = values.expand(n_time, *values.shape)
    values = check_finite(f"background[{name!r}]", values)
    if name == "luminance":
        scale = CD_M2_PER_NANOLAMBERT if var.attrs["units"].startswith("cd") else 1.0
        if bool((values <= 0).any()):
            raise ValueError("background['luminance'] must be > 0 everywhere")
        values = nanolambert_to_mag_arcsec2(values / scale)
    # the range of Schaefer's threshold model (skytorch.stars.visibility.limiting_magnitude)
    check_range(f"background[{name!r}] as a surface brightness", values, -20.0, 40.0,
                unit=" mag/arcsec^2")
    alt_nodes = torch.tensor(np.array(var["altitude"].values, float), dtype=dtype)
    az_nodes = torch.tensor(np.array(var["azimuth"].values, float), dtype=dtype)
    # periodic azimuth: the first column again at +360°
    az_nodes = torch.cat([az_nodes, az_nodes[:1] + 360.0])
    values = torch.cat([values, values[..., :1]], dim=-1)
    alt_deg, az_deg = torch.rad2deg(altitude_rad), torch.rad2deg(azimuth_rad)
    outside = above & ((alt_deg < alt_nodes[0]) | (alt_deg > alt_nodes[-1]))
    if bool(outside.any()):
        raise ValueError(
            f"background altitudes {float(alt_nodes[0])}..{float(alt_nodes[-1])} degree do "
            f"not cover the stars above the horizon (altitudes "
            f"{float(alt_deg[above].min()):.3f}..{float(alt_deg[above].max()):.3f} degree; "
            "an elevated observer sees down to the dip of the horizon, "
            "skytorch.stars.photometry.apparent_horizon)")
    alt_deg = alt_deg.clamp(float(alt_nodes[0]), float(alt_nodes[-1]))  # below the horizon
    az_deg = torch.where(az_deg < az_nodes[0], az_deg + 360.0, az_deg)
    i = torch.searchsorted(alt_nodes, alt_deg.contiguous()).clamp(1, alt_nodes.numel() - 1)
    j = torch.searchsorted(az_nodes, az_deg.contiguous()).clamp(1, az_nodes.numel() - 1)
    u = (alt_deg - alt_nodes[i - 1]) / (alt_nodes[i] - alt_nodes[i - 1])
    v = (az_deg - az_nodes[j - 1]) / (az_nodes[j] - az_nodes[j - 1])
    n_alt, n_az = values.shape[-2], values.shape[-1]
    flat = values.reshape(n_time, n_alt * n_az)

    def corner(a, b):
        return torch.gather(flat, 1, a * n_az + b)

    return ((1 - u) * ((1 - v) * corner(i - 1, j - 1) + v * corner(i - 1, j))
            + u * ((1 - v) * corner(i, j - 1) + v * corner(i, j)))


def _background_at_times(background, times: np.ndarray):
    """Return the background's rows of ``times`` by their labels (a time coordinate).

    Without a ``time`` coordinate (no time dimension, or one without labels) the background
    is returned as given: one sky for every time, or one row per time in order.
    """
    if background is None or "time" not in background.coords:
        return background
    labels = background["time"].values
    if not np.issubdtype(labels.dtype, np.datetime64):
        raise ValueError(f"background's time coordinate must hold instants (datetime64); got "
                         f"dtype {labels.dtype}")
    wanted = times.astype("datetime64[ns]")
    missing = ~np.isin(wanted, labels.astype("datetime64[ns]"))
    if missing.any():
        raise ValueError(f"background has no row for the times {wanted[missing][:3]}"
                         f"{' ...' if missing.sum() > 3 else ''} (its times "
                         f"{labels.min()}..{labels.max()})")
    return background.sel(time=wanted)


def _check_sky(sky_brightness_mag_arcsec2, background) -> torch.Tensor:
    """Check the two forms of the sky background; return the scalar-per-time values."""
    if background is not None and sky_brightness_mag_arcsec2 is not None:
        raise ValueError("give either sky_brightness_mag_arcsec2 or background, not both")
    if background is not None:
        _background_variable(background)
    return check_range("sky_brightness_mag_arcsec2",
                       22.0 if sky_brightness_mag_arcsec2 is None
                       else sky_brightness_mag_arcsec2,
                       -20.0, 40.0, unit=" mag/arcsec^2", dtype=torch.float64)


def _visibility(result: dict[str, torch.Tensor], sky_values: torch.Tensor, background,
                visibility: str, factor: torch.Tensor | None):
    """Return the sky [mag arcsec⁻²], limiting magnitude, visible flags and counts.

    Sky and limit are (time,) for the scalar-per-time background, (time, star) for a
    per-direction ``background`` Dataset.
    """
    magnitude, above = result["magnitude"], result["above_horizon"]
    n_time = magnitude.shape[0]
    if background is None:
        sky = sky_values.reshape(-1).expand(n_time).to(magnitude.dtype)
        limit = limiting_magnitude(sky)
        visible, count = count_visible(magnitude, above, limit, visibility, factor)
        return sky, limit, visible, count
    sky = _background_sky(background, n_time, result["altitude"], result["azimuth"], above)
    limit = limiting_magnitude(sky)
    shifted = limit if factor is None else limit + 2.5 * torch.log10(factor)[:, None]
    visible = torch.le(magnitude, shifted).logical_and_(above)
    return sky, limit, visible, count_true(visible)


def observe(catalog: xr.Dataset, times, lat_deg: float, lon_deg: float,
            elevation_m: float = 0.0, atmosphere=None, refraction: bool = True, *,
            sky_brightness_mag_arcsec2=None, background: xr.Dataset | None = None,
            control_magnitude: float = 6.0,
            visibility: str = "schaefer1990", aperture_m: float = 0.007,
            exposure_s: float = 0.1, twinkle_samples: int = 0,
            twinkle_interval_s: float = 0.01, seed: int = 0, reddening: bool = True,
            dtype: torch.dtype = torch.float64) -> xr.Dataset:
    """Apparent positions, magnitudes, colours and visibility of catalogue stars.

    Parameters
    ----------
    catalog : xarray.Dataset
        Dimension ``star`` with ``ra``, ``dec`` [degree], ``pm_ra``, ``pm_dec`` [mas/yr],
        ``parallax`` [mas], ``vmag``, ``bv`` [mag] (:func:`skytorch.stars.bright_stars`,
        :func:`skytorch.stars.read_bsc5`); attribute ``epoch_jyear`` (default 2000.0).
    times : str, datetime, datetime64 or a list/array of them
        UTC instants (dimension ``time``) within
        :data:`skytorch.ephemeris.TIME_MIN` … :data:`skytorch.ephemeris.TIME_MAX`
        (1899-07-29T00:30 … 2053-10-08T23:30, both included), the range of every
        ephemeris function.
    lat_deg, lon_deg : float or array_like (observer,)
        Geodetic latitude in [−90, 90] and east longitude in [−180, 360) [deg] (the
        ranges of :func:`skytorch.ephemeris.check_observer`); arrays (broadcast with
        ``elevation_m``) give several observers along a leading ``observer`` dimension.
    elevation_m : float or array_like (observer,)
        Height of the observer in [0, 10 000] m (:data:`ELEVATION_RANGE_M`); also the
        altitude of the observer in the atmosphere. An elevated observer sees stars below
        the astronomical horizon, down to the refracted dip of the horizon
        (:func:`skytorch.stars.photometry.apparent_horizon`, −1.62° from 3 km), with
        their refraction and extinction along the rays that pass low over the ground.
    atmosphere : skytorch.atmosphere.Atmosphere, optional
        Default ``Atmosphere.earth()`` (turbidity 2, 300 DU). Pass ``False`` for no
        atmosphere (geometric altitudes, magnitudes above the atmosphere).
    refraction : bool
        Refract the altitudes with the atmosphere's ray-traced refraction.
    sky_brightness_mag_arcsec2 : float or array_like (time,), optional
        Sky background in V [mag arcsec⁻²] for the limiting magnitude, one value per time
        (default 22.0, a dark site); not together with ``background``.
    background : xarray.Dataset, optional
        Sky background per direction: ``sky_brightness`` [mag arcsec⁻², units
        ``"mag arcsec-2"``] or ``luminance`` [``"cd m-2"`` or ``"nL"``] over
        ``(altitude, azimuth)`` [degree coordinates, increasing; azimuth from north
        through east, periodic], optionally with a leading ``time`` of the same length as
        ``times``. Each star's limiting magnitude is computed from the sky where it is
        (bilinear interpolation); ``limiting_magnitude`` and ``sky_brightness`` become
        (time, star). The altitudes must cover every star above the horizon.
    control_magnitude : float
        m_a of the relative brightness 10^(0.4 (m_a − m)) [mag].
    visibility : {"schaefer1990", "muller2012"}
        Visibility model (:func:`skytorch.stars.visibility.count_visible`); with
        ``"muller2012"`` the Sun's altitude sets the day–night factor, which also scales
        the relative brightness.
    aperture_m, exposure_s : float
        Aperture [m] and exposure [s] of the scintillation index (default: the eye).
    twinkle_samples : int
        When > 0, add ``twinkle`` (time, star, sample): a seeded random sequence of
        relative intensities with the scintillation index of each star
        (:func:`skytorch.stars.scintillation.twinkle`), ``twinkle_interval_s`` apart.
    twinkle_interval_s : float
        Sample spacing of the twinkle sequence [s] (correlation time 10 ms).
    seed : int
        Seed of the twinkle sequence. Several observers scintillate independently: observer
        k draws with the seed of ``numpy.random.SeedSequence([seed, k])``.
    reddening : bool
        ``color`` after the spectral extinction along each path (default); False skips
        that step (about half of the Dataset's cost for 9 000 stars × 1 440 times) and
        repeats the exo-atmospheric colour over time.
    dtype : torch.dtype
        Computation dtype of the per-star quantities (float64 or float32).

    Returns
    -------
    xarray.Dataset
        Dimensions ``time``, ``star`` (and ``channel`` for the colours): ``altitude``,
        ``azimuth`` [degree], ``magnitude`` [mag], ``airmass``, ``above_horizon``,
        ``visible``, ``relative_brightness``, ``scintillation_index``, ``color`` (time,
        star, channel: the apparent sRGB colour after the spectral extinction along the
        path, :func:`skytorch.stars.photometry.apparent_color`); per time
        ``limiting_magnitude`` and ``n_visible`` (and ``day_night_factor``); per star
        ``color_exoatmospheric`` (star, channel), ``vmag``, ``bv`` and the catalogue's
        ``hip``/``hr`` when present.

    Notes
    -----
    Positions agree with skyfield's ``observe().apparent().altaz()`` to a few mas
    (largest 0.2″ away from the Sun; gravitational light deflection by the Sun, 0.47″ at
    1° from it, is not modelled). Stars below the horizon keep finite magnitudes (the
    horizon extinction) and are flagged by ``above_horizon``/``visible``.

    Examples
    --------
    >>> from skytorch.stars import bright_stars, observe
    >>> ds = observe(bright_stars(2.0), "2025-09-07T20:00", 52.5, 13.4)
    >>> sorted(ds.sizes.items())
    [('channel', 3), ('star', 50), ('time', 1)]
    """
    _check_catalog(catalog)
    refuse_gradient("observe", lat_deg=lat_deg, lon_deg=lon_deg, elevation_m=elevation_m,
                    atmosphere=atmosphere,
                    sky_brightness_mag_arcsec2=sky_brightness_mag_arcsec2,
                    control_magnitude=control_magnitude, aperture_m=aperture_m,
                    exposure_s=exposure_s)
    check_choice("visibility", visibility, VISIBILITY_MODELS)
    refraction = check_flag("refraction", refraction)
    reddening = check_flag("reddening", reddening)
    if dtype not in OBSERVE_DTYPES:
        raise TypeError(f"dtype must be one of {OBSERVE_DTYPES}; got {dtype!r:.60}")
    if atmosphere is not None and atmosphere is not False:
        check_atmosphere("atmosphere", atmosphere,
                         ("optical_depth", "refraction") if refraction else ("optical_depth",))
    check_range("control_magnitude", control_magnitude, -30.0, 40.0, unit=" mag")
    check_range("aperture_m", aperture_m, 1e-4, 100.0, unit=" m")
    check_range("exposure_s", exposure_s, 1e-6, 1e5, unit=" s")
    check_range("twinkle_interval_s", twinkle_interval_s, 1e-9, 1e6, unit=" s")
    twinkle_samples = check_int("twinkle_samples", twinkle_samples, 0, 100_000)
    check_int("seed", seed, 0, 2**63 - 1)
    sky_values = _check_sky(sky_brightness_mag_arcsec2, background)
    if any(np.ndim(v) > 0 for v in (lat_deg, lon_deg, elevation_m)):
        return _observe_several(catalog, times, lat_deg, lon_deg, elevation_m, atmosphere,
                                refraction, sky_brightness_mag_arcsec2=sky_brightness_mag_arcsec2,
                                background=background,
                                control_magnitude=control_magnitude, visibility=visibility,
                                aperture_m=aperture_m, exposure_s=exposure_s,
                                twinkle_samples=twinkle_samples,
                                twinkle_interval_s=twinkle_interval_s, seed=seed,
                                reddening=reddening, dtype=dtype)
    # the ephemeris' ranges (one definition), the elevation also within the atmosphere
    # tables and Young's scintillation law
    lat_t, lon_t, _ = check_observer(lat_deg, lon_deg, 0.0)
    lat, lon = float(lat_t), float(lon_t)
    elevation = float(check_range("elevation_m", elevation_m, *ELEVATION_RANGE_M, unit=" m"))
    values = _parse_times(times)
    if sky_values.ndim > 1 or sky_values.numel() not in (1, values.size):
        raise ValueError(f"sky_brightness_mag_arcsec2 must be a number or have one value per "
                         f"time ({values.size},); got shape {tuple(sky_values.shape)}")
    if atmosphere is None:
        from skytorch.atmosphere import Atmosphere

        atmosphere = Atmosphere.earth()
    has_atmosphere = atmosphere is not False
    stars = star_vectors(catalog["ra"].values, catalog["dec"].values,
                         catalog["pm_ra"].values, catalog["pm_dec"].values,
                         catalog["parallax"].values, dtype=dtype)
    # the catalogue's magnitudes: finite, from the Sun's to far beyond any catalogue
    vmag = check_range("catalog['vmag']", torch.as_tensor(catalog["vmag"].values,
                                                          dtype=dtype), -30.0, 40.0,
                       unit=" mag")
    bv = torch.as_tensor(catalog["bv"].values, dtype=dtype)
    operators, velocity = time_operators(values, lat, lon, elevation,
                                         epoch_jyear=_catalog_epoch(catalog))
    refraction_tab, extinction_tab = _site_atmosphere_tables(
        atmosphere if has_atmosphere else None, elevation, refraction)
    colour_table, per_star = _colour_source(
        atmosphere if has_atmosphere and reddening else None, elevation, refraction, bv,
        values.size)
    result = observe_tensors(stars, vmag, bv, operators, velocity, refraction_tab,
                             extinction_tab, color_table=per_star)
    if not has_atmosphere and elevation > 0.0:
        # no air: the ground's horizon is the geometric one, acos(R / (R + h)) below 0
        dip = math.acos(EARTH_MEAN_RADIUS_M / (EARTH_MEAN_RADIUS_M + elevation))
        result["above_horizon"] = result["altitude"] >= -dip
    factor = (_day_night_factor(values, lat, lon, elevation, dtype)
              if visibility == "muller2012" else None)
    sky, limit, visible, count = _visibility(result, sky_values,
                                             _background_at_times(background, values),
                                             visibility,
                                             factor)
    brightness, scint = _brightness_and_scintillation(result, control_magnitude, factor,
                                                      aperture_m, exposure_s, elevation,
                                                      has_atmosphere)
    color, color_exo = _star_colours(bv, result, colour_table)

    ts = ("time", "star")
    data_vars = {
        # the radians are not used further: degrees in place
        "altitude": variable(ts, result["altitude"].rad2deg_(), _SPECS["altitude"]),
        "azimuth": variable(ts, result["azimuth"].rad2deg_(), _SPECS["azimuth"]),
        "magnitude": variable(ts, result["magnitude"], _SPECS["magnitude"]),
        "airmass": variable(ts, result["airmass"], _SPECS["airmass"]),
        "above_horizon": variable(ts, result["above_horizon"], _SPECS["above_horizon"]),
        "visible": variable(ts, visible, _SPECS["visible"]),
        "relative_brightness": variable(ts, brightness, _SPECS["relative_brightness"]),
        "scintillation_index": variable(ts, scint, _SPECS["scintillation_index"]),
        "limiting_magnitude": variable("time" if background is None else ts, limit,
                                       _SPECS["limiting_magnitude"]),
        "n_visible": variable("time", count, _SPECS["n_visible"]),
        "color": variable(("time", "star", "channel"), color, _SPECS["color"]),
        "color_exoatmospheric": variable(("star", "channel"), color_exo,
                                         _SPECS["color_exoatmospheric"]),
        "vmag": variable("star", vmag, _SPECS["vmag"]),
        "bv": variable("star", bv, _SPECS["bv"]),
    }
    if background is not None:
        data_vars["sky_brightness"] = variable(ts, sky, _SPECS["sky_brightness"])
    if factor is not None:
        data_vars["day_night_factor"] = variable("time", factor, _SPECS["day_night_factor"])
    coords_extra = {}
    if twinkle_samples > 0:
        data_vars["twinkle"], coords_extra["sample"] = _twinkle(
            scint, twinkle_samples, twinkle_interval_s, seed)
    data_vars.update({name: catalog[name].variable.copy() for name in ("hip", "hr", "name")
                      if name in catalog})
    coords = {
        "time": time_coordinate(values),
        "star": catalog["star"].variable.copy() if "star" in catalog.coords else coordinate(
            "star", np.arange(stars.shape[0]), VariableSpec("1", "star index", "Row.")),
        "channel": coordinate("channel", np.array(["R", "G", "B"]),
                              VariableSpec("1", "sRGB channel", "Red, green, blue.")),
        **coords_extra,
    }
    parameters = {
        "lat_deg": lat, "lon_deg": lon, "elevation_m": elevation,
        "atmosphere": json.dumps(atmosphere.parameters_dict(), default=str)
        if has_atmosphere and hasattr(atmosphere, "parameters_dict") else "none",
        "refraction": bool(refraction and has_atmosphere), "control_magnitude":
        float(control_magnitude), "visibility": visibility, "aperture_m": float(aperture_m),
        "exposure_s": float(exposure_s), "twinkle_samples": int(twinkle_samples),
        "seed": int(seed), "reddening": bool(reddening and has_atmosphere),
        "dtype": str(dtype).replace("torch.", ""),
        "sky_brightness_mag_arcsec2": ("background Dataset" if background is not None
                                       else sky_values.numpy()),
        "catalog": catalog.attrs.get("title", ""),
    }
    return build_dataset(
        data_vars, coords, title="Apparent stars",
        references=["Mueller, Engel & Doellner 2012, VMV, doi:10.2312/PE/VMV/VMV12/055-062",
                    "Schaefer 1990, PASP 102, 212, doi:10.1086/132629",
                    "Young 1967, AJ 72, 747, doi:10.1086/110303",
                    "Ballesteros 2012, EPL 97, 34008, doi:10.1209/0295-5075/97/34008"],
        parameters=parameters)

