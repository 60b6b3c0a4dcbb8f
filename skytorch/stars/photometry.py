"""Star photometry: V-band extinction from the atmosphere model, air mass, colour, brightness.

Extinction is not a fixed coefficient: the V-band magnitude loss of a star is computed
from the atmosphere's spectral optical depth along the (refracted) path,
``Δm = −2.5 log10(∫ F R_V e^{−τ} dλ / ∫ F R_V dλ)`` with a black-body spectrum F of the
star's temperature (from B−V, Ballesteros 2012) and the Johnson V response R_V (Bessell
1990). Evaluating that integral for 9 000 stars × 1 440 times would cost minutes, so
:func:`extinction_table` evaluates it once on a grid of apparent altitudes (dense near
the horizon) for a range of B−V, and fits the colour dependence per altitude by a line —
the classical first- and second-order extinction ``Δm = A(h) + B(h) (B−V)`` (Hardie 1962)
— which :func:`extinction` then interpolates. The table error is measured in
``experiments/stars_accuracy_cost.py``.

References
----------
1. Bessell, M. S. 1990, "UBVRI passbands", PASP 102, 1181, doi:10.1086/132749.
2. Ballesteros, F. J. 2012, "New insights into black bodies", EPL 97, 34008,
   doi:10.1209/0295-5075/97/34008.
3. Hardie, R. H. 1962, "Photoelectric reductions", in Astronomical Techniques, ed.
   W. A. Hiltner (Univ. of Chicago Press), p. 178 (first/second-order extinction).
4. Kasten, F., Young, A. T. 1989, "Revised optical air mass tables and approximation
   formula", Appl. Opt. 28, 4735, doi:10.1364/AO.28.004735.
5. Müller, S., Engel, J., Döllner, J. 2012, "Single-Pass Rendering of Day and Night Sky
   Phenomena", Proc. VMV 2012, §4.2 (relative brightness 2.512^(m_a − m)), §4.3.

Examples
--------
>>> import torch
>>> from skytorch.stars.photometry import relative_brightness
>>> float(relative_brightness(torch.tensor(1.0), control_magnitude=6.0))
100.0
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping

import torch

from skytorch._cache import MemoryCache, atmosphere_key, clone_tables, value_key
from skytorch._memory import Scratch
from skytorch._validate import (
    as_tensor,
    check_broadcastable,
    check_choice,
    check_finite,
    check_flag,
    check_int,
    check_positive,
    check_range,
)
from skytorch.spectrum import (
    BV_RANGE_MAG,
    blackbody_radiance,
    bv_to_temperature,
    spectrum_to_xyz,
    srgb_transfer,
    temperature_to_srgb,
    v_band_response,
    xyz_to_linear_srgb,
)

__all__ = [
    "COLOR_BV_GRID",
    "COLOR_WAVELENGTHS_NM",
    "EXTINCTION_METHODS",
    "apparent_color",
    "apparent_color_table",
    "apparent_horizon",
    "star_color",
    "star_color_table",
    "star_table_pays_off",
    "bv_to_srgb",
    "extinction",
    "extinction_coefficient",
    "extinction_table",
    "relative_brightness",
    "grid_altitudes",
    "lerp",
    "table_lookup",
    "table_low",
]

logger = logging.getLogger(__name__)

#: ``"path"``: V-band optical depth integrated along the (refracted) path for every
#: altitude; ``"airmass"``: zenith optical depth times the Kasten & Young (1989) air mass
EXTINCTION_METHODS = ("path", "airmass")
#: 2.5 log10(e): magnitudes per unit optical depth
MAG_PER_OPTICAL_DEPTH = 2.5 / math.log(10.0)
#: V band sampled for the extinction integral [nm]
V_BAND_WAVELENGTHS_NM = (470.0, 700.0, 47)
#: B−V values over which the colour term is fitted [mag]
BV_FIT_GRID = (-0.3, 2.0, 24)
#: wavelengths of the apparent-colour integral: 380–780 nm every 10 nm [nm]
COLOR_WAVELENGTHS_NM = (380.0, 780.0, 41)
#: B−V nodes of the apparent-colour table (the clamping range of :func:`bv_to_srgb`) [mag]
COLOR_BV_GRID = (BV_RANGE_MAG[0], BV_RANGE_MAG[1], 71)
#: margin of the tables' first node above the apparent horizon of an elevated observer
#: [rad] (:func:`apparent_horizon`)
HORIZON_MARGIN_RAD = 1e-9
#: stars per block while :func:`star_color_table` is built
STAR_BLOCK = 256
#: shape parameter of the altitude grid h = H (x² + c x)/(1 + c), x ∈ [0, 1]
GRID_SHAPE = 0.05
_HALF_PI = 0.5 * math.pi
#: 0.4 ln 10: 10^(−0.4 m) = exp(−_POGSON_E m)
_POGSON_E = 0.4 * math.log(10.0)


#: extinction and colour tables of recent (atmosphere parameters, arguments), keyed by value:
#: a table costs 0.8-0.9 s to integrate and 0.1 ms to find again (docs/stars.md, "Caches")
_TABLES = MemoryCache(8, copy=clone_tables)


def relative_brightness(magnitude, control_magnitude: float = 6.0) -> torch.Tensor:
    """Brightness relative to a star of the control magnitude, 10^(0.4 (m_a − m)).

    Parameters
    ----------
    magnitude : array_like
        ``(...)`` apparent magnitude m [mag].
    control_magnitude : float
        m_a [mag]: the magnitude rendered with intensity 1 (Müller et al. 2012, §4.2,
        e.g. the observer's current sensitivity).

    Returns
    -------
    torch.Tensor
        ``(...)`` ratio [1]; Müller's 2.512^(m_a − m) with the exact Pogson ratio
        100^(1/5) = 2.51189.
    """
    m = check_finite("magnitude", magnitude)
    m_a = check_range("control_magnitude", control_magnitude, -30.0, 40.0, unit=" mag")
    return brightness_ratio(m, float(m_a))


def brightness_ratio(magnitude: torch.Tensor, control_magnitude: float,
                     out: torch.Tensor | None = None) -> torch.Tensor:
    """Unchecked kernel of :func:`relative_brightness`: 10^(0.4 (m_a − m)).

    Parameters
    ----------
    magnitude : torch.Tensor
        ``(...)`` apparent magnitude m [mag], finite.
    control_magnitude : float
        m_a [mag].
    out : torch.Tensor, optional
        Receives the result (may be ``magnitude`` itself; not while gradients are
        recorded).

    Returns
    -------
    torch.Tensor
        ``(...)`` ratio [1].
    """
    # exp(−0.4 ln 10 (m − m_a)) in float64: one scaled sum and one exp (pow with a scalar
    # base costs ~10× an exp); within 1 ulp of 10^(0.4 (m_a − m)) in float64, and
    # correctly rounded (exact powers of ten, 1 at m = m_a) in lower precisions
    shift = torch.tensor(_POGSON_E * control_magnitude, dtype=torch.float64)
    if magnitude.dtype == torch.float64:
        return torch.exp(torch.add(shift, magnitude, alpha=-_POGSON_E, out=out), out=out)
    ratio = torch.add(shift, magnitude.to(torch.float64), alpha=-_POGSON_E).exp_()
    return ratio.to(magnitude.dtype) if out is None else out.copy_(ratio)


def bv_to_srgb(bv) -> torch.Tensor:
    """Display colour of stars from B−V: Ballesteros (2012) temperature → black body → sRGB.

    Parameters
    ----------
    bv : array_like
        ``(star,)`` B−V [mag]; values outside [−0.5, 3.0] are clamped to that range.

    Returns
    -------
    torch.Tensor
        ``(star, 3)`` gamma-encoded sRGB in [0, 1], largest component 1
        (:func:`skytorch.spectrum.temperature_to_srgb`).

    Notes
    -----
    Catalogues repeat B−V values (8 916 Hipparcos stars have 1 911 distinct ones): without
    gradients each distinct value is converted once.
    """
    value = check_range("bv", bv, -5.0, 10.0, unit=" mag").clamp(*BV_RANGE_MAG)
    if value.requires_grad and torch.is_grad_enabled():
        return temperature_to_srgb(bv_to_temperature(value))
    distinct, inverse = torch.unique(value, return_inverse=True)
    return temperature_to_srgb(bv_to_temperature(distinct))[inverse]


# --- altitude grid ---------------------------------------------------------------------------


def grid_altitudes(n_nodes: int, low_rad: float = 0.0,
                   dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """Nodes of the altitude tables, ``(n_nodes,)`` [rad] from ``low_rad`` to π/2.

    Uniform in x ∈ [0, 1] with h = low + (π/2 − low)(x² + c x)/(1 + c), c = 0.05: dense
    near the horizon (0.017° spacing for 256 nodes) and 0.7° at the zenith.
    """
    x = torch.linspace(0.0, 1.0, n_nodes, dtype=torch.float64)
    span = _HALF_PI - low_rad
    return (low_rad + span * (x * x + GRID_SHAPE * x) / (1.0 + GRID_SHAPE)).to(dtype)


def apparent_horizon(atmosphere, altitude_m: float, refraction: bool = True) -> float:
    """Apparent altitude [rad] of the horizon (the ground) for an observer at ``altitude_m``.

    0 at the surface. An elevated observer sees below the astronomical horizon, down to
    minus the apparent dip (refracted rays) or the geometric dip (straight rays) of
    :func:`skytorch.atmosphere.refraction.horizon_dip` — e.g. −1.62° (−1.76°
    geometric) from 3 km. The returned altitude is :data:`HORIZON_MARGIN_RAD` above it:
    the tables' first node is a ray that grazes the ground and climbs to space (at the
    dip itself rounding may put its periapsis under the ground, where the path, and its
    optical depth, would end).
    """
    if altitude_m <= 0.0:
        return 0.0
    from skytorch.atmosphere.refraction import horizon_dip

    dip = horizon_dip(atmosphere, torch.tensor(float(altitude_m), dtype=torch.float64))
    return -float(dip["apparent_dip_rad" if refraction else "geometric_dip_rad"]) \
        + HORIZON_MARGIN_RAD


def table_low(table: dict[str, torch.Tensor]) -> float:
    """First apparent-altitude node of a table [rad] (0 without ``apparent_altitude_rad``)."""
    nodes = table.get("apparent_altitude_rad")
    return 0.0 if nodes is None else float(nodes[0])


def table_lookup(altitude_rad: torch.Tensor, n_nodes: int, low_rad: float = 0.0,
                 scratch: Scratch | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """Index and weight of altitudes on the grid of :func:`grid_altitudes`.

    Altitudes are clamped to [low_rad, π/2] (below the grid the lowest node is used).

    Parameters
    ----------
    altitude_rad : torch.Tensor
        Apparent altitudes [rad].
    n_nodes : int
        Nodes of the grid.
    low_rad : float
        First node [rad].
    scratch : skytorch._memory.Scratch, optional
        Buffers of a loop over chunks that the results are written into (an enabled one
        only while no gradients are recorded).

    Returns
    -------
    index : torch.Tensor (int64), weight : torch.Tensor
        Same shape as the input; value = t[index] + weight (t[index+1] − t[index]).
    """
    scratch = Scratch(enabled=False) if scratch is None else scratch
    shape, dtype = altitude_rad.shape, altitude_rad.dtype
    c = GRID_SHAPE
    # x = (√(c² + 4 h) − c)/2 · (n − 1), h = (clamp(altitude) − low)(1 + c)/span: each
    # affine step one scaled sum with a 0-d tensor (a pass over the data each)
    x = scratch("lookup_x", shape, dtype)
    x = torch.clamp(altitude_rad, low_rad, _HALF_PI, out=x)
    in_place = x if scratch.enabled else None
    scale = 4.0 * (1.0 + c) / (_HALF_PI - low_rad)
    x = torch.add(torch.tensor(c * c - low_rad * scale, dtype=dtype), x, alpha=scale,
                  out=in_place)
    x = torch.sqrt(x, out=in_place)
    half_span = 0.5 * (n_nodes - 1)
    x = torch.add(torch.tensor(-c * half_span, dtype=dtype), x, alpha=half_span,
                  out=in_place)
    floor = torch.floor(x.detach(), out=scratch("lookup_floor", shape, dtype))
    floor = floor.clamp_(0, n_nodes - 2)
    weight = torch.sub(x, floor, out=in_place)
    index = scratch("lookup_index", shape, torch.int64)
    return (floor.to(torch.int64) if index is None else index.copy_(floor)), weight


def lerp(table: torch.Tensor, index: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
    """Linear interpolation ``table[i] + w (table[i + 1] − table[i])`` (two gathers)."""
    slope = torch.diff(table, append=table[-1:])
    return table[index] + weight * slope[index]


# --- extinction --------------------------------------------------------------------------------


def check_atmosphere(name: str, atmosphere, methods=("optical_depth",)):
    """Return ``atmosphere`` if it has the methods used here, else raise ``TypeError``.

    Any object with the :class:`skytorch.atmosphere.Atmosphere` methods is accepted (the
    tests use small stand-ins); strings, numbers and ``None`` are not.
    """
    missing = [m for m in methods if not callable(getattr(atmosphere, m, None))]
    if missing or isinstance(atmosphere, (str, bytes, bool, int, float)):
        raise TypeError(f"{name} must be a skytorch.atmosphere.Atmosphere (with "
                        f"{', '.join(methods)}); got {type(atmosphere).__name__}: "
                        f"{atmosphere!r:.60}")
    return atmosphere


def _check_table(name: str, table, keys) -> None:
    if not isinstance(table, Mapping) or any(k not in table for k in keys):
        raise TypeError(f"{name} must be the dict returned by {name}() with keys "
                        f"{tuple(keys)}; got {type(table).__name__}")


def _star_inputs(bv, apparent_altitude_rad):
    """B−V (star,) and apparent altitude (..., star) as tensors, checked to broadcast."""
    altitude = check_finite("apparent_altitude_rad", as_tensor("apparent_altitude_rad",
                                                               apparent_altitude_rad))
    bv = check_finite("bv", as_tensor("bv", bv, dtype=altitude.dtype))
    check_broadcastable(bv=bv, apparent_altitude_rad=altitude)
    return bv, altitude


def _cache_key(atmosphere, altitude_m, n_nodes, refraction, method) -> str | None:
    """Value key of a table (``None``: an atmosphere without ``parameters_dict``)."""
    key = atmosphere_key(atmosphere)
    return None if key is None else value_key("photometry", key, float(altitude_m), n_nodes,
                                              refraction, method)


def _slant_optical_depth(atmosphere, wavelength: torch.Tensor, heights: torch.Tensor,
                         altitude_m: float, refraction: bool) -> torch.Tensor:
    """Optical depth (n_nodes, n_wavelength) along the paths at apparent altitudes."""
    tau = atmosphere.optical_depth(wavelength, _HALF_PI - heights, altitude_m,
                                   **({"refraction": True} if refraction else {}))
    return tau.reshape(heights.numel(), wavelength.numel())


def extinction_table(atmosphere, altitude_m: float = 0.0, *, n_nodes: int = 256,
                     refraction: bool = True, method: str = "path",
                     cache: bool = True) -> dict[str, torch.Tensor]:
    """V-band extinction and air mass tabulated against apparent altitude.

    Parameters
    ----------
    atmosphere : skytorch.atmosphere.Atmosphere
        The atmosphere (scalar parameters).
    altitude_m : float
        Observer altitude above the surface [m].
    n_nodes : int
        Grid nodes between the apparent horizon (:func:`apparent_horizon`: 0 at the
        surface, below it for an elevated observer) and the zenith (see
        :func:`table_lookup`).
    refraction : bool
        Integrate along refracted rays (``atmosphere.optical_depth(..., refraction=True)``)
        or straight ones.
    method : {"path", "airmass"}
        ``"path"``: the optical depth along the path for every altitude; ``"airmass"``:
        the zenith optical depth times the Kasten & Young (1989) air mass (a
        plane-parallel shortcut, compared in the accuracy experiment; its grid starts at
        the astronomical horizon, 0, at every observer altitude).
    cache : bool
        Reuse a table computed earlier for an atmosphere with the same parameters and the
        same arguments (the 8 most recent tables are kept, keyed by the atmosphere's
        ``parameters_dict()`` values; each call gets its own copy).

    Returns
    -------
    dict of float64 torch.Tensor, each (n_nodes,)
        ``apparent_altitude_rad`` (the grid), ``offset`` A and ``colour`` B of
        Δm = A + B (B−V) [mag, mag/mag], ``airmass`` (slant over vertical V-band optical
        depth for B−V = 0.65), ``fit_error`` (largest |residual| of the line over
        −0.3 ≤ B−V ≤ 2.0 [mag]).

    Notes
    -----
    For each B−V of the fit grid, F_λ = B_λ(T(B−V)) and Δm = −2.5 log10(Σ F R_V e^{−τ} /
    Σ F R_V) over 470–700 nm (47 samples); then a least-squares line in B−V per altitude.
    """
    check_atmosphere("atmosphere", atmosphere)
    check_choice("method", method, EXTINCTION_METHODS)
    refraction = check_flag("refraction", refraction)
    cache = check_flag("cache", cache)
    n_nodes = check_int("n_nodes", n_nodes, 8, 100_000)
    altitude = float(check_range("altitude_m", altitude_m, 0.0, 1e5, unit=" m"))
    if cache:
        return _TABLES.get(_cache_key(atmosphere, altitude, n_nodes, refraction, method),
                           lambda: _extinction_table(atmosphere, altitude, n_nodes, refraction,
                                                     method))
    return _extinction_table(atmosphere, altitude, n_nodes, refraction, method)


def _extinction_table(atmosphere, altitude: float, n_nodes: int, refraction: bool,
                      method: str) -> dict[str, torch.Tensor]:
    """Compute the table of :func:`extinction_table` (checked arguments, not cached)."""
    dtype = torch.float64
    # the plane-parallel air mass has no path below the astronomical horizon
    low = apparent_horizon(atmosphere, altitude, refraction) if method == "path" else 0.0
    heights = grid_altitudes(n_nodes, low, dtype)
    wavelength = torch.linspace(*V_BAND_WAVELENGTHS_NM[:2], V_BAND_WAVELENGTHS_NM[2],
                                dtype=dtype)
    with torch.no_grad():
        if method == "path":
            tau = _slant_optical_depth(atmosphere, wavelength, heights, altitude, refraction)
        else:
            from skytorch.atmosphere.optical_depth import kasten_young_air_mass

            tau_zenith = atmosphere.optical_depth(wavelength, torch.zeros((), dtype=dtype),
                                                  altitude)
            tau = kasten_young_air_mass(_HALF_PI - heights)[:, None] * tau_zenith
        bv = torch.linspace(*BV_FIT_GRID[:2], BV_FIT_GRID[2], dtype=dtype)
        weights = (blackbody_radiance(wavelength, bv_to_temperature(bv)[:, None])
                   * v_band_response(wavelength))
        weights = weights / weights.sum(-1, keepdim=True)  # (bv, wl)
        # Δm(h, bv) with log-sum-exp for large optical depths
        log_t = torch.logsumexp(torch.log(weights)[None] - tau[:, None, :], dim=-1)
        delta_m = -MAG_PER_OPTICAL_DEPTH * log_t  # (h, bv)
        design = torch.stack([torch.ones_like(bv), bv], dim=-1)
        coefficients = torch.linalg.lstsq(design, delta_m.T).solution  # (2, h)
        residual = (design @ coefficients).T - delta_m
        sun_like = torch.argmin((bv - 0.65).abs())
        airmass = delta_m[:, sun_like] / delta_m[-1, sun_like]
    return {"apparent_altitude_rad": heights, "offset": coefficients[0],
            "colour": coefficients[1], "airmass": airmass,
            "fit_error": residual.abs().amax(dim=-1)}


def extinction(bv: torch.Tensor, apparent_altitude_rad: torch.Tensor,
               table: dict[str, torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
    """Extinction [mag] and air mass of stars from an :func:`extinction_table`.

    Parameters
    ----------
    bv : torch.Tensor, shape (star,)
        B−V [mag].
    apparent_altitude_rad : torch.Tensor, shape (time, star)
        Apparent (refracted) altitude [rad]; below the table's first node (the apparent
        horizon, :func:`apparent_horizon`) the horizon values are returned (finite; such
        stars are flagged not visible by the caller).
    table : dict
        From :func:`extinction_table`.

    Returns
    -------
    delta_m, airmass : torch.Tensor, each (time, star), dtype of the altitude
    """
    _check_table("extinction_table", table, ("offset", "colour", "airmass"))
    bv, apparent_altitude_rad = _star_inputs(bv, apparent_altitude_rad)
    dtype = apparent_altitude_rad.dtype
    n_nodes = table["offset"].numel()
    index, weight = table_lookup(apparent_altitude_rad, n_nodes, table_low(table))
    offset = lerp(table["offset"].to(dtype), index, weight)
    colour = lerp(table["colour"].to(dtype), index, weight)
    airmass = lerp(table["airmass"].to(dtype), index, weight)
    return offset + colour * bv.to(dtype), airmass


def extinction_coefficient(atmosphere, altitude_m: float = 0.0, bv: float = 0.65,
                           wavelength_nm: float | None = None) -> torch.Tensor:
    """Zenith extinction coefficient k [mag per air mass] of the atmosphere model.

    Parameters
    ----------
    atmosphere : skytorch.atmosphere.Atmosphere
        May carry batch dimensions.
    altitude_m : float
        Observer altitude [m].
    bv : float
        B−V of the star [mag] (V-band integral with a black body of that colour).
    wavelength_nm : float, optional
        Wavelength [nm]: the monochromatic coefficient 1.0857 τ(λ) there instead of the
        V band.

    Returns
    -------
    torch.Tensor
        ``(*batch)`` k [mag/airmass]: the magnitude loss at the zenith, which equals the
        slope of Δm against air mass where τ ∝ air mass.
    """
    check_atmosphere("atmosphere", atmosphere)
    altitude_m = float(check_range("altitude_m", altitude_m, 0.0, 1e5, unit=" m"))
    bv = float(check_range("bv", bv, -5.0, 10.0, unit=" mag"))
    dtype = torch.float64
    zenith = torch.zeros((), dtype=dtype)
    if wavelength_nm is not None:
        wl = check_positive("wavelength_nm", wavelength_nm, unit=" nm", dtype=dtype)
        if wl.numel() != 1:
            raise ValueError(f"wavelength_nm must be one wavelength; got shape "
                             f"{tuple(wl.shape)}")
        wl = wl.reshape(1)
        return MAG_PER_OPTICAL_DEPTH * atmosphere.optical_depth(wl, zenith, altitude_m)[..., 0]
    wavelength = torch.linspace(*V_BAND_WAVELENGTHS_NM[:2], V_BAND_WAVELENGTHS_NM[2],
                                dtype=dtype)
    tau = atmosphere.optical_depth(wavelength, zenith, altitude_m)
    temperature = bv_to_temperature(torch.tensor(float(bv), dtype=dtype))
    weights = blackbody_radiance(wavelength, temperature) * v_band_response(wavelength)
    weights = weights / weights.sum()
    return -MAG_PER_OPTICAL_DEPTH * torch.logsumexp(torch.log(weights) - tau, dim=-1)


# --- apparent colour ---------------------------------------------------------------------------


def apparent_color_table(atmosphere, altitude_m: float = 0.0, *, n_nodes: int = 256,
                         refraction: bool = True, cache: bool = True
                         ) -> dict[str, torch.Tensor]:
    """Linear sRGB of black-body stars seen through the atmosphere, by apparent altitude.

    Parameters
    ----------
    atmosphere : skytorch.atmosphere.Atmosphere
        The atmosphere (scalar parameters).
    altitude_m : float
        Observer altitude above the surface [m].
    n_nodes : int
        Apparent-altitude nodes between the apparent horizon (:func:`apparent_horizon`)
        and the zenith
        (:func:`grid_altitudes`).
    refraction : bool
        Optical depth along refracted (True) or straight paths.
    cache : bool
        Reuse a table computed earlier for an atmosphere with the same parameters and the
        same arguments (the 8 most recent tables are kept, keyed by the atmosphere's
        ``parameters_dict()`` values; each call gets its own copy).

    Returns
    -------
    dict of float64 torch.Tensor
        ``apparent_altitude_rad`` (n_nodes,), ``bv`` (n_bv,) the B−V nodes of
        :data:`COLOR_BV_GRID` and ``linear_srgb`` (n_nodes, n_bv, 3): linear sRGB with
        the largest component 1 (negative, out-of-gamut components clipped to 0).

    Notes
    -----
    XYZ(h, B−V) = ∫ B_λ(T(B−V)) e^{−τ(λ, h)} x̄ȳz̄(λ) dλ over 380–780 nm every 10 nm
    (:data:`COLOR_WAVELENGTHS_NM`, piecewise-linear spectra integrated against the 1-nm
    CIE 1931 functions by :func:`skytorch.spectrum.spectrum_to_xyz`), with τ the
    atmosphere's optical depth along the path. e^{−τ} is scaled by e^{min_λ τ} per
    altitude before the integral, so the colour stays defined where the light itself
    underflows (τ ≫ 100 at the horizon).
    """
    check_atmosphere("atmosphere", atmosphere)
    refraction = check_flag("refraction", refraction)
    cache = check_flag("cache", cache)
    n_nodes = check_int("n_nodes", n_nodes, 8, 100_000)
    altitude = float(check_range("altitude_m", altitude_m, 0.0, 1e5, unit=" m"))
    if cache:
        return _TABLES.get(_cache_key(atmosphere, altitude, n_nodes, refraction, "colour"),
                           lambda: _apparent_color_table(atmosphere, altitude, n_nodes,
                                                         refraction))
    return _apparent_color_table(atmosphere, altitude, n_nodes, refraction)


def _apparent_color_table(atmosphere, altitude: float, n_nodes: int,
                          refraction: bool) -> dict[str, torch.Tensor]:
    """Compute the table of :func:`apparent_color_table` (checked arguments, not cached)."""
    dtype = torch.float64
    heights = grid_altitudes(n_nodes, apparent_horizon(atmosphere, altitude, refraction), dtype)
    wavelength = torch.linspace(*COLOR_WAVELENGTHS_NM[:2], COLOR_WAVELENGTHS_NM[2],
                                dtype=dtype)
    bv = torch.linspace(*COLOR_BV_GRID[:2], COLOR_BV_GRID[2], dtype=dtype)
    with torch.no_grad():
        tau = _slant_optical_depth(atmosphere, wavelength, heights, altitude, refraction)
        transmittance = torch.exp(-(tau - tau.amin(dim=-1, keepdim=True)))  # (h, wl)
        source = blackbody_radiance(wavelength, bv_to_temperature(bv)[:, None])  # (bv, wl)
        xyz = spectrum_to_xyz(transmittance[:, None, :] * source, wavelength)
        linear = xyz_to_linear_srgb(xyz).clamp_min(0.0)
        linear = linear / linear.amax(dim=-1, keepdim=True)
    return {"apparent_altitude_rad": heights, "bv": bv, "linear_srgb": linear}


def apparent_color(bv: torch.Tensor, apparent_altitude_rad: torch.Tensor,
                   table: dict[str, torch.Tensor], gamma: bool = True) -> torch.Tensor:
    """Colour of stars after the spectral extinction along their paths (reddening).

    Parameters
    ----------
    bv : torch.Tensor, shape (star,)
        B−V [mag]; clamped to :data:`COLOR_BV_GRID`'s range like :func:`bv_to_srgb`.
    apparent_altitude_rad : torch.Tensor, shape (time, star)
        Apparent altitude [rad]; below the horizon the horizon colour (finite).
    table : dict
        From :func:`apparent_color_table`.
    gamma : bool
        Gamma-encoded sRGB (True) or linear.

    Returns
    -------
    torch.Tensor, shape (time, star, 3)
        sRGB in [0, 1] with the largest linear component 1, dtype of the altitude.

    Notes
    -----
    Per star, the table is interpolated linearly in B−V, renormalised and (optionally)
    gamma-encoded once on its altitude nodes (:func:`star_color_table`); per star and
    time one linear interpolation in altitude follows (:func:`star_color`). With fewer
    than n_nodes/2 instants per star (e.g. 482 000 Gaia stars at one instant) the same
    B−V interpolation, renormalisation and gamma are done only at the two altitude nodes
    around each star instead (same values, O(time · star) instead of O(nodes · star)).
    On the 256-node grid this differs from the direct spectral integral by < 2e-3
    (``tests/test_stars_photometry.py``).
    """
    _check_table("apparent_color_table", table, ("bv", "linear_srgb"))
    bv, apparent_altitude_rad = _star_inputs(bv, apparent_altitude_rad)
    if bv.ndim != 1 or apparent_altitude_rad.shape[-1:] != bv.shape:
        raise ValueError(f"bv must have shape (star,) and apparent_altitude_rad (time, star); "
                         f"got {tuple(bv.shape)} and {tuple(apparent_altitude_rad.shape)}")
    gamma = check_flag("gamma", gamma)
    dtype = apparent_altitude_rad.dtype
    n_nodes = table["linear_srgb"].shape[0]
    if not star_table_pays_off(apparent_altitude_rad.shape[:-1].numel(), table):
        lower, w = _bv_weights(bv.to(dtype), table["bv"])
        linear = table["linear_srgb"].to(dtype)
        index, weight = table_lookup(apparent_altitude_rad, n_nodes, table_low(table))

        def node_colour(node):
            return _normalised_colour(linear[node, lower + 1], linear[node, lower], w, gamma)

        below = node_colour(index)
        return torch.addcmul(below, weight[..., None], node_colour(index + 1) - below)
    per_star = star_color_table(bv.to(dtype), table, gamma)
    return star_color(apparent_altitude_rad, per_star)


def _bv_weights(bv: torch.Tensor, grid: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Lower B−V node (star,) and its weight (star, 1) on the uniform grid ``grid``."""
    step = float(grid[1] - grid[0])
    x = (bv.clamp(float(grid[0]), float(grid[-1])) - float(grid[0])) / step
    lower = x.detach().floor().clamp(0, grid.numel() - 2)
    return lower.long(), (x - lower)[:, None]


def _normalised_colour(upper: torch.Tensor, lower: torch.Tensor, w: torch.Tensor,
                       gamma: bool) -> torch.Tensor:
    """Blend two linear colours (…, 3), scale the largest component to 1, encode."""
    colour = upper * w + lower * (1.0 - w)
    colour = colour / colour.amax(dim=-1, keepdim=True)
    return srgb_transfer(colour) if gamma else colour


def star_table_pays_off(n_instants: int, table: dict[str, torch.Tensor]) -> bool:
    """Whether :func:`star_color_table` is cheaper than two nodes per star and instant.

    The per-star table costs O(nodes · star), the look-up at the two nodes around each
    star O(instants · star): the table pays off from n_nodes/2 instants per star.
    """
    return 2 * n_instants >= table["linear_srgb"].shape[0]


def star_color_table(bv: torch.Tensor, table: dict[str, torch.Tensor], gamma: bool = True
                     ) -> dict[str, torch.Tensor]:
    """Colour of each star on the altitude nodes of an :func:`apparent_color_table`.

    Parameters
    ----------
    bv : torch.Tensor, shape (star,)
        B−V [mag] (clamped to :data:`COLOR_BV_GRID`'s range); its dtype is the table's.
    table : dict
        From :func:`apparent_color_table`.
    gamma : bool
        Gamma-encoded sRGB (True) or linear.

    Returns
    -------
    dict of torch.Tensor
        ``values`` and ``slopes`` (row, 3): the colour at node i of the table row block
        that starts at ``offsets[s]`` (star s's colour at node i is row
        ``offsets[s] + i``) and its difference to node i + 1; ``n_nodes`` (int),
        ``offsets`` (star,) and ``low_rad`` (float, the first node). Input of
        :func:`star_color`. Without gradients the stars that share a B−V share one
        block (8 916 Hipparcos stars have 1 911 distinct values), and ``rows`` (row, 6)
        holds ``values`` and ``slopes`` side by side (``values`` and ``slopes`` are
        views of it): :func:`star_color` gathers both with one look-up.
    """
    _check_table("apparent_color_table", table, ("bv", "linear_srgb"))
    bv = check_finite("bv", as_tensor("bv", bv))
    if bv.ndim != 1:
        raise ValueError(f"bv must have shape (star,); got {tuple(bv.shape)}")
    gamma = check_flag("gamma", gamma)
    by_bv = table["linear_srgb"].to(bv.dtype).transpose(0, 1).contiguous()  # (bv, h, 3)
    n_nodes = by_bv.shape[1]
    if (torch.is_grad_enabled() and bv.requires_grad) or by_bv.requires_grad:
        lower, w = _bv_weights(bv, table["bv"])
        values = _normalised_colour(by_bv[lower + 1], by_bv[lower], w[:, :, None], gamma)
        slopes = torch.diff(values, dim=1, append=values[:, -1:]).reshape(-1, 3)
        return {"values": values.reshape(-1, 3), "slopes": slopes, "n_nodes": n_nodes,
                "offsets": n_nodes * torch.arange(bv.numel()), "low_rad": table_low(table)}
    distinct, inverse = torch.unique(bv, return_inverse=True)
    rows = _distinct_colour_rows(distinct, by_bv, table["bv"], gamma)
    flat = rows.view(-1, 6)
    return {"values": flat[:, :3], "slopes": flat[:, 3:], "rows": flat, "n_nodes": n_nodes,
            "offsets": n_nodes * inverse.reshape(-1), "low_rad": table_low(table)}


def _distinct_colour_rows(bv: torch.Tensor, by_bv: torch.Tensor, grid: torch.Tensor,
                          gamma: bool) -> torch.Tensor:
    """Return (bv, node, 6): the colour at each node and its difference to the next node.

    Built in blocks of :data:`STAR_BLOCK` B−V values, which keeps the temporaries small;
    the last node's difference is 0 (as ``torch.diff`` with the last node appended).
    """
    lower, w = _bv_weights(bv, grid)
    w = w[:, :, None]
    rows = torch.empty(bv.numel(), by_bv.shape[1], 6, dtype=bv.dtype)
    for start in range(0, bv.numel(), STAR_BLOCK):
        block = slice(start, start + STAR_BLOCK)
        rows[block, :, :3] = _normalised_colour(by_bv[lower[block] + 1], by_bv[lower[block]],
                                                w[block], gamma)
    torch.sub(rows[:, 1:, :3], rows[:, :-1, :3], out=rows[:, :-1, 3:])
    rows[:, -1, 3:] = 0.0
    return rows


def star_color(apparent_altitude_rad: torch.Tensor, per_star: dict[str, torch.Tensor],
               out: torch.Tensor | None = None, scratch: Scratch | None = None
               ) -> torch.Tensor:
    """Look the colour of every star up at its apparent altitude.

    Parameters
    ----------
    apparent_altitude_rad : torch.Tensor, shape (time, star)
        Apparent altitude [rad] (not checked: the internal path of :func:`apparent_color`
        and :func:`skytorch.stars.observe_tensors`); below the horizon the horizon colour.
    per_star : dict
        From :func:`star_color_table`, for the same stars.
    out : torch.Tensor, optional
        Contiguous (time, star, 3) tensor written in place (not while gradients are
        recorded).
    scratch : skytorch._memory.Scratch, optional
        Buffers of a loop over chunks for the temporaries (an enabled one only while no
        gradients are recorded).

    Returns
    -------
    torch.Tensor, shape (time, star, 3)
        Colour interpolated linearly in altitude between the table's nodes.

    Notes
    -----
    The three channels of a node are gathered as one row (:func:`torch.index_select`);
    with the table's ``rows`` one gather brings the colour and its slope together.
    """
    index, weight = table_lookup(apparent_altitude_rad, per_star["n_nodes"],
                                 per_star["low_rad"], scratch)
    flat = index.add_(per_star["offsets"]).reshape(-1)
    shape = (*apparent_altitude_rad.shape, 3)
    values, slopes = per_star["values"], per_star["slopes"]
    if weight.requires_grad or values.requires_grad:
        colour = torch.addcmul(torch.index_select(values, 0, flat),
                               torch.index_select(slopes, 0, flat), weight.reshape(-1, 1))
        if out is not None:
            out.copy_(colour.reshape(shape))
            return out
        return colour.reshape(shape)
    rows = None if out is None else out.view(-1, 3)
    if "rows" in per_star:  # values and slopes side by side: one gather
        gathered = torch.index_select(
            per_star["rows"], 0, flat,
            out=None if scratch is None else scratch("colour_rows", (flat.numel(), 6),
                                                     values.dtype))
        colour = torch.addcmul(gathered[:, :3], gathered[:, 3:], weight.reshape(-1, 1),
                               out=rows)
        return colour.reshape(shape)
    colour = torch.index_select(values, 0, flat, out=rows)
    gathered = None if scratch is None else scratch("colour_slopes", (flat.numel(), 3),
                                                    slopes.dtype)
    colour.addcmul_(torch.index_select(slopes, 0, flat, out=gathered), weight.reshape(-1, 1))
    return colour.reshape(shape)
