r"""Vertical density profiles of atmospheric constituents (dimensionless shapes).

Each profile returns the number density relative to a reference value as a function of
altitude above the planet's surface. Profiles are pure functions on tensors, broadcast
their arguments by torch rules and are differentiable.

Available shapes (``PROFILES``):

``"exponential"``
    :math:`\rho(h) = \exp(-h / H)` with scale height :math:`H`.
``"us1976"``
    Density ratio :math:`\rho(h)/\rho(0)` of the U.S. Standard Atmosphere 1976,
    computed from its defining temperature layers (ref. 1) by the hydrostatic equation
    up to 84.852 km geopotential altitude, continued isothermally above.
``"tent"``
    Ozone-like layer :math:`\max(0, 1 - |h - h_c| / w)` peaking at :math:`h_c` with
    half-width :math:`w` (ref. 2: 10–40 km, peak 25 km).

References
----------
1. NOAA, NASA, USAF 1976, *U.S. Standard Atmosphere, 1976*, NOAA-S/T 76-1562,
   Washington D.C.
2. Bruneton, E. 2017, "A qualitative and quantitative evaluation of 8 clear sky models",
   IEEE TVCG 24, 2641, doi:10.1109/TVCG.2016.2622272.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere.profiles import exponential, tent
>>> exponential(torch.tensor([0.0, 8000.0]), 8000.0)
tensor([1.0000, 0.3679])
>>> tent(torch.tensor([25e3, 40e3]), 25e3, 15e3)
tensor([1., 0.])
"""

from __future__ import annotations

import functools
import math

import torch

from skytorch._validate import as_tensor

__all__ = ["PROFILES", "SOUNDING_UNITS", "US1976_KINK_ALTITUDES_M", "US1976_SCALE_HEIGHT_M",
           "check_sounding", "exponential", "log_linear", "piecewise_linear", "tent", "us1976",
           "us1976_air_from_state", "us1976_pressure_ratio", "us1976_state", "us1976_temperature",
           "us1976_water_from_state"]

#: model keywords for the molecular profile ("sounding": a user's profile, see
#: :func:`check_sounding`)
PROFILES = ("exponential", "us1976", "sounding")

# --- U.S. Standard Atmosphere 1976 defining layers (ref. 1, Table 4) -------------------------
_US1976_EARTH_RADIUS_M = 6_356_766.0  #: radius used for geopotential altitude
_US1976_G0 = 9.80665  #: [m s^-2]
_US1976_MOLAR_MASS = 0.0289644  #: [kg mol^-1]
_US1976_GAS_CONSTANT = 8.31432  #: [J mol^-1 K^-1] (value of the standard)
_US1976_BASE_HEIGHT_M = (0.0, 11_000.0, 20_000.0, 32_000.0, 47_000.0, 51_000.0, 71_000.0,
                         84_852.0)
_US1976_LAPSE_K_PER_M = (-6.5e-3, 0.0, 1.0e-3, 2.8e-3, 0.0, -2.8e-3, -2.0e-3, 0.0)
_US1976_T0 = 288.15

#: scale height used to place integration levels for the US 1976 profile [m]
US1976_SCALE_HEIGHT_M = 8_000.0


def _us1976_layers() -> tuple[list[float], list[float], list[float]]:
    """Return base temperature [K] and log density ratio at each layer base (ref. 1)."""
    g_over_r = _US1976_G0 * _US1976_MOLAR_MASS / _US1976_GAS_CONSTANT
    temperatures = [_US1976_T0]
    log_pressures = [0.0]
    for i in range(len(_US1976_BASE_HEIGHT_M) - 1):
        dh = _US1976_BASE_HEIGHT_M[i + 1] - _US1976_BASE_HEIGHT_M[i]
        lapse = _US1976_LAPSE_K_PER_M[i]
        t_base = temperatures[-1]
        t_top = t_base + lapse * dh
        if lapse == 0.0:
            dlogp = -g_over_r * dh / t_base
        else:
            dlogp = -g_over_r / lapse * math.log(t_top / t_base)
        temperatures.append(t_top)
        log_pressures.append(log_pressures[-1] + dlogp)
    log_density = [lp - math.log(t / _US1976_T0)
                   for lp, t in zip(log_pressures, temperatures, strict=True)]
    return temperatures, log_pressures, log_density


_US1976_TEMPERATURE, _, _US1976_LOG_DENSITY = _us1976_layers()

#: geometric altitudes of the US 1976 layer bases above the ground, z = r0 H / (r0 - H)
#: [m]: the lapse rate, hence the density gradient, jumps there (kinks of the profile)
US1976_KINK_ALTITUDES_M = tuple(_US1976_EARTH_RADIUS_M * h / (_US1976_EARTH_RADIUS_M - h)
                                for h in _US1976_BASE_HEIGHT_M[1:])


def exponential(altitude_m, scale_height_m) -> torch.Tensor:
    r"""Exponential profile :math:`\exp(-h/H)`.

    Parameters
    ----------
    altitude_m : Tensor (...)
        Altitude above the surface [m].
    scale_height_m : float or Tensor (...)
        Scale height :math:`H` [m]; broadcasts with ``altitude_m``.

    Returns
    -------
    Tensor (...)
        Relative density [1].
    """
    altitude_m = as_tensor("altitude_m", altitude_m)
    return torch.exp(altitude_m * (-1.0 / scale_height_m))


def tent(altitude_m, center_m, half_width_m) -> torch.Tensor:
    r"""Tent (triangular) layer :math:`\max(0, 1 - |h - h_c|/w)`.

    Parameters
    ----------
    altitude_m : Tensor (...)
        Altitude [m].
    center_m : float or Tensor (...)
        Altitude of the peak :math:`h_c` [m].
    half_width_m : float or Tensor (...)
        Half width :math:`w` [m]; the layer spans :math:`h_c \pm w` and its integral
        over altitude is :math:`w`.

    Returns
    -------
    Tensor (...)
        Relative density [1], 1 at the peak.
    """
    altitude_m = as_tensor("altitude_m", altitude_m)
    return torch.clamp(1.0 - torch.abs(altitude_m - center_m) / half_width_m, min=0.0)


def tent_column(center_m, half_width_m, top_m) -> torch.Tensor:
    r"""Integral of :func:`tent` from the ground to ``top_m`` [m] (truncated at both).

    With the tent's cumulative integral :math:`F(h)`: :math:`(h - h_c + w)^2 / (2w)` on
    :math:`[h_c - w, h_c]`, :math:`w - (h_c + w - h)^2 / (2w)` on :math:`[h_c, h_c + w]`
    (0 below, :math:`w` above), the column is :math:`F(h_{top}) - F(0)`; :math:`w` when
    the whole tent lies between the ground and the top.

    Parameters
    ----------
    center_m, half_width_m : Tensor (...)
        Peak altitude and half width [m] of :func:`tent`.
    top_m : float
        Altitude of the top of the atmosphere [m].

    Returns
    -------
    Tensor (...)
        Column height [m].
    """
    def cumulative(h):
        below = torch.minimum(torch.clamp(h - center_m + half_width_m, min=0.0), half_width_m)
        above = torch.minimum(torch.clamp(center_m + half_width_m - h, min=0.0), half_width_m)
        return torch.where(h <= center_m, below * below / (2.0 * half_width_m),
                           half_width_m - above * above / (2.0 * half_width_m))

    zero = torch.zeros_like(center_m)
    return cumulative(zero + top_m) - cumulative(zero)


def us1976(altitude_m) -> torch.Tensor:
    r"""Density ratio :math:`\rho(z)/\rho(0)` of the U.S. Standard Atmosphere 1976.

    Parameters
    ----------
    altitude_m : Tensor (...)
        Geometric altitude [m] (converted to geopotential altitude internally).

    Returns
    -------
    Tensor (...)
        Density relative to sea level [1]. Below the surface the lowest layer is
        continued; above 84.852 km geopotential altitude the layer is isothermal at
        186.87 K (the standard's molecular-weight change is neglected).

    Notes
    -----
    In a layer with base :math:`H_b`, temperature :math:`T_b` and lapse rate
    :math:`L \ne 0`: :math:`T = T_b + L (H - H_b)`,
    :math:`p/p_b = (T/T_b)^{-g_0 M / (R L)}`; with :math:`L = 0`:
    :math:`p/p_b = \exp(-g_0 M (H - H_b)/(R T_b))`. Density ratio
    :math:`(p/p_0)(T_0/T)`. Geopotential altitude :math:`H = r_0 z/(r_0 + z)`.
    """
    return torch.exp(_us1976_state(as_tensor("altitude_m", altitude_m))[0])


def us1976_temperature(altitude_m) -> torch.Tensor:
    """Temperature of the U.S. Standard Atmosphere 1976 [K] at geometric altitude [m].

    Same layers and continuations as :func:`us1976`.
    """
    return _us1976_state(as_tensor("altitude_m", altitude_m))[1]


def us1976_pressure_ratio(altitude_m) -> torch.Tensor:
    """Pressure of the U.S. Standard Atmosphere 1976 relative to sea level [1].

    At geometric altitude [m] (same layers and continuations as :func:`us1976`).
    """
    log_density, temperature = _us1976_state(as_tensor("altitude_m", altitude_m))
    return torch.exp(log_density) * (temperature / _US1976_T0)


def us1976_state(altitude_m: torch.Tensor, layer_altitude_m: torch.Tensor | None = None
                 ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    r"""One evaluation of the U.S. Standard Atmosphere 1976.

    Shared by the profiles that follow it (:attr:`skytorch.atmosphere.constituents.Profile.state`).

    Parameters
    ----------
    altitude_m : Tensor (...)
        Geometric altitude [m].
    layer_altitude_m : Tensor, optional
        An altitude [m] in the same layer of the standard as each ``altitude_m`` (broadcasting
        against it, e.g. one per quadrature piece that does not cross a layer boundary): the
        layer is looked up there, once for all the points that share it. Near a boundary a
        point on its other side takes the neighbouring layer's formula, which is continuous
        there (the temperature and the density have kinks, not jumps).

    Returns
    -------
    altitude_m, density_ratio, pressure_ratio : Tensor (...)
        The altitude itself [m], :func:`us1976` [1] and the pressure ratio as the density
        ratio times :math:`T(\max(z, 0))/T_0` [1] (below the ground the density is
        continued and the temperature held at its ground value, as the gas profiles of
        :mod:`skytorch.atmosphere.gases` do).

    Raises
    ------
    ValueError
        ``layer_altitude_m`` does not broadcast against ``altitude_m``.

    Examples
    --------
    >>> import torch
    >>> _, density, pressure = us1976_state(torch.tensor([0.0, 11_000.0], dtype=torch.float64))
    >>> [round(float(v), 4) for v in pressure]   # 22 699.9 Pa at 11 km geometric (ref. 1)
    [1.0, 0.224]
    >>> bool(torch.equal(density, us1976(torch.tensor([0.0, 11_000.0], dtype=torch.float64))))
    True
    """
    if layer_altitude_m is not None:
        try:
            torch.broadcast_shapes(altitude_m.shape, layer_altitude_m.shape)
        except RuntimeError:
            raise ValueError(f"layer_altitude_m of shape {tuple(layer_altitude_m.shape)} does "
                             f"not broadcast against altitude_m of shape "
                             f"{tuple(altitude_m.shape)}") from None
    log_density, temperature = _us1976_state(altitude_m, layer_altitude_m)
    density = torch.exp(log_density)
    # the temperature exceeds T_0 only below the ground (the lowest layer continued), where
    # it is held at T_0: min(T, T_0)
    held = torch.clamp(temperature, max=_US1976_T0)
    return altitude_m, density, density * (held * (1.0 / _US1976_T0))


def us1976_air_from_state(state, exponent, power) -> torch.Tensor:
    r""":math:`\rho^{power}\,(p/p_0)^{exponent}` of a :func:`us1976_state` [1]."""
    return _times_power(_power(state[1], power), state[2], exponent)


def us1976_water_from_state(state, scale_height_m, exponent) -> torch.Tensor:
    r""":math:`e^{-z/H_w}\,(p/p_0)^{exponent}` of a :func:`us1976_state` [1]."""
    return _times_power(torch.exp(state[0] * (-1.0 / scale_height_m)), state[2], exponent)


def _times_power(value: torch.Tensor, base: torch.Tensor, exponent) -> torch.Tensor:
    """Return ``value * base ** exponent`` (``value`` itself for a constant exponent 0)."""
    if not isinstance(exponent, torch.Tensor) or not exponent.requires_grad:
        if float(exponent) == 0.0:
            return value
    return value * _power(base, exponent)


def _power(base: torch.Tensor, exponent) -> torch.Tensor:
    """Return ``base ** exponent`` of a positive ``base``.

    By a multiplication or a square root for a constant exponent of 0, 1/2, 1 or 2 (equal to the
    power within rounding; a general power costs an exponential and a logarithm per element).
    """
    if isinstance(exponent, torch.Tensor) and (exponent.requires_grad or exponent.numel() != 1):
        return base ** exponent
    value = float(exponent)
    if value == 1.0:
        return base
    if value == 2.0:
        return base * base
    if value == 0.5:
        return torch.sqrt(base)
    if value == 0.0:
        return torch.ones_like(base)
    return base ** exponent


def _geopotential(z: torch.Tensor) -> torch.Tensor:
    """Geopotential altitude [m] of the geometric altitude z [m]."""
    return _US1976_EARTH_RADIUS_M * z / (_US1976_EARTH_RADIUS_M + z)


def _us1976_state(z: torch.Tensor, layer_z: torch.Tensor | None = None
                  ) -> tuple[torch.Tensor, torch.Tensor]:
    """Log density ratio [1] and temperature [K] of the standard at geometric altitude z.

    The layer of each point is that of ``layer_z`` (broadcasting against ``z``) when given.
    """
    geopotential = _geopotential(z)
    # the constants of each point's layer, gathered once (the lowest layer is continued
    # below the ground, the highest above 84.852 km; bucketize gives 0 ... n_layer - 1)
    tables = _us1976_tables(geopotential.dtype, geopotential.device)
    layer_h = geopotential if layer_z is None else _geopotential(layer_z)
    layer = torch.bucketize(layer_h.detach(), tables["base"][1:], right=True)
    base, lapse, t_base, log_density_base, per_log, per_height = (
        tables[key].index_select(0, layer.reshape(-1)).reshape(layer.shape)
        for key in ("base", "lapse", "temperature", "log_density", "per_log_temperature",
                    "per_height"))
    dh = geopotential - base
    temperature = torch.addcmul(t_base, lapse, dh)
    # log p = log p_b - g M/(R L) log(T/T_b) in a layer with a lapse rate L, and
    # log p_b - g M (H - H_b)/(R T_b) in an isothermal one (the other coefficient is 0);
    # log rho = log p - log(T/T_0) = log rho_b - (g M/(R L) + 1) log(T/T_b) - ...
    log_density = log_density_base - per_log * torch.log(temperature / t_base) - per_height * dh
    return log_density, temperature


@functools.lru_cache(maxsize=8)
def _us1976_tables(dtype: torch.dtype, device: torch.device) -> dict[str, torch.Tensor]:
    """Constants of the standard's layers.

    Bases [m], lapse rates [K/m], base temperatures [K], log density ratios and the
    coefficients of the log density: g M/(R L) + 1 [1] of log(T/T_b) where L != 0,
    g M/(R T_b) [1/m] of H - H_b where L = 0 (the first zero in isothermal layers, the
    second in the others).
    """
    g_over_r = _US1976_G0 * _US1976_MOLAR_MASS / _US1976_GAS_CONSTANT
    values = {"base": _US1976_BASE_HEIGHT_M, "lapse": _US1976_LAPSE_K_PER_M,
              "temperature": _US1976_TEMPERATURE, "log_density": _US1976_LOG_DENSITY,
              "per_log_temperature": tuple(0.0 if lapse == 0.0 else g_over_r / lapse + 1.0
                                           for lapse in _US1976_LAPSE_K_PER_M),
              "per_height": tuple(g_over_r / t_base if lapse == 0.0 else 0.0
                                  for lapse, t_base in zip(_US1976_LAPSE_K_PER_M,
                                                           _US1976_TEMPERATURE, strict=True))}
    return {key: torch.tensor(value, dtype=dtype, device=device)
            for key, value in values.items()}


# --- user soundings ----------------------------------------------------------------------
#: accepted ``units`` attributes of the sounding's variables (checked when present)
SOUNDING_UNITS = {
    "altitude": ("m", "meter", "meters", "metre", "metres"),
    "pressure": ("Pa", "pascal", "pascals"),
    "temperature": ("K", "kelvin"),
    "ozone_number_density": ("m-3", "m^-3", "m**-3", "1/m3", "1/m^3", "m-3 (molecules)"),
    "h2o_vmr": ("1", "", "mol/mol", "mol mol-1", "mol mol^-1", "m3/m3"),
}
#: Boltzmann constant [J/K] (exact, SI 2019)
_BOLTZMANN = 1.380649e-23


def check_sounding(profile) -> dict[str, torch.Tensor]:  # noqa: C901 (one check per sounding column)
    """Return a user sounding as checked float64 tensors.

    Parameters
    ----------
    profile : xarray.Dataset
        One-dimensional variables (or coordinates) of equal length >= 2: ``altitude``
        [m] above the planet's surface, strictly increasing, the first at or below 0 m;
        ``pressure`` [Pa], positive and strictly decreasing; ``temperature`` [K],
        positive; optionally ``ozone_number_density`` [m-3] (>= 0, not all zero) and
        ``h2o_vmr`` [1] (volume mixing ratio in [0, 1)). A ``units`` attribute, where
        present, must be one of :data:`SOUNDING_UNITS`.

    Returns
    -------
    dict of Tensor (level,)
        ``altitude_m``, ``pressure_pa``, ``temperature_k``, ``number_density_m3``
        (:math:`p/(kT)`) and, when given, ``ozone_number_density_m3`` and ``h2o_vmr``.

    Raises
    ------
    TypeError
        ``profile`` is not an xarray.Dataset.
    ValueError
        A variable missing, not 1-D, of another length, not finite, out of range, not
        monotonic, or with other units; the message names it.
    """
    import numpy as np
    import xarray as xr

    if not isinstance(profile, xr.Dataset):
        raise TypeError("profile must be an xarray.Dataset with altitude [m], pressure [Pa] "
                        f"and temperature [K]; got {type(profile).__name__}")
    values = {}
    for name in ("altitude", "pressure", "temperature", "ozone_number_density", "h2o_vmr"):
        if name not in profile.variables:
            if name in ("altitude", "pressure", "temperature"):
                raise ValueError(f"profile lacks the variable {name!r} (needs altitude [m], "
                                 "pressure [Pa], temperature [K]; optional "
                                 "ozone_number_density [m-3], h2o_vmr [1])")
            continue
        variable = profile.variables[name]
        units = variable.attrs.get("units")
        if units is not None and str(units).strip() not in SOUNDING_UNITS[name]:
            raise ValueError(f"profile variable {name!r} has units {units!r}; expected one "
                             f"of {SOUNDING_UNITS[name]}")
        array = np.asarray(variable.values, dtype=np.float64)
        if array.ndim != 1:
            raise ValueError(f"profile variable {name!r} must be 1-D (one value per level); "
                             f"got shape {array.shape}")
        if not np.isfinite(array).all():
            raise ValueError(f"profile variable {name!r} holds NaN or inf at level(s) "
                             f"{np.flatnonzero(~np.isfinite(array)).tolist()}")
        values[name] = array
    n_level = values["altitude"].size
    for name, array in values.items():
        if array.size != n_level:
            raise ValueError(f"profile variable {name!r} has {array.size} levels, altitude "
                             f"{n_level}")
    if n_level < 2:
        raise ValueError(f"profile needs at least 2 levels; got {n_level}")
    altitude, pressure, temperature = (values[k] for k in ("altitude", "pressure",
                                                            "temperature"))

    def first(mask):
        return int(np.flatnonzero(mask)[0])

    if not (np.diff(altitude) > 0).all():
        i = first(np.diff(altitude) <= 0)
        raise ValueError("profile altitude must increase strictly; got "
                         f"{altitude[i]} m then {altitude[i + 1]} m at levels {i}, {i + 1}")
    if altitude[0] > 0.0:
        raise ValueError(f"profile altitude must start at or below the ground (0 m); got "
                         f"{altitude[0]} m")
    for name, array in (("pressure", pressure), ("temperature", temperature)):
        if not (array > 0).all():
            i = first(array <= 0)
            raise ValueError(f"profile {name} must be > 0; got {array[i]} at level {i}")
    if not (np.diff(pressure) < 0).all():
        i = first(np.diff(pressure) >= 0)
        raise ValueError("profile pressure must decrease strictly with altitude; got "
                         f"{pressure[i]} Pa then {pressure[i + 1]} Pa at levels {i}, {i + 1}")
    result = {"altitude_m": altitude, "pressure_pa": pressure, "temperature_k": temperature,
              "number_density_m3": pressure / (_BOLTZMANN * temperature)}
    if "ozone_number_density" in values:
        ozone = values["ozone_number_density"]
        if (ozone < 0).any() or not (ozone > 0).any():
            raise ValueError("profile ozone_number_density must be >= 0 and not all zero; "
                             f"got min {ozone.min()}, max {ozone.max()} m-3")
        result["ozone_number_density_m3"] = ozone
    if "h2o_vmr" in values:
        vmr = values["h2o_vmr"]
        if (vmr < 0).any() or (vmr >= 1).any():
            raise ValueError("profile h2o_vmr must be in [0, 1); got min "
                             f"{vmr.min()}, max {vmr.max()}")
        result["h2o_vmr"] = vmr
    return {key: torch.tensor(value, dtype=torch.float64) for key, value in result.items()}


def _segment(altitude_m, nodes_m):
    """Index of the node interval holding each altitude (the end intervals continue)."""
    return torch.bucketize(altitude_m.detach(), nodes_m[1:-1].contiguous(), right=True)


def log_linear(altitude_m, nodes_m, log_values) -> torch.Tensor:
    r""":math:`\exp` of the linear interpolation of ``log_values`` at ``altitude_m``.

    Piecewise exponential between the nodes (exact for isothermal layers); below the
    first and above the last node the end intervals continue (above the top: the
    exponential decay of the top layer, i.e. its scale height).

    Parameters
    ----------
    altitude_m : Tensor (...)
        Altitude [m].
    nodes_m : Tensor (level,)
        Increasing node altitudes [m].
    log_values : Tensor (level,)
        Natural logarithm of the values at the nodes.

    Returns
    -------
    Tensor (...)
    """
    altitude_m = as_tensor("altitude_m", altitude_m)
    nodes_m = nodes_m.to(altitude_m.dtype)
    log_values = log_values.to(altitude_m.dtype)
    i = _segment(altitude_m, nodes_m)
    h0, h1 = nodes_m[i], nodes_m[i + 1]
    v0, v1 = log_values[i], log_values[i + 1]
    return torch.exp(v0 + (v1 - v0) / (h1 - h0) * (altitude_m - h0))


def piecewise_linear(altitude_m, nodes_m, values, above: float | None = 0.0) -> torch.Tensor:
    """Linear interpolation of ``values`` at ``altitude_m`` between increasing nodes.

    Below the first node the first interval continues; above the last node the value is
    ``above`` (``None``: the last value is held).
    """
    altitude_m = as_tensor("altitude_m", altitude_m)
    nodes_m = nodes_m.to(altitude_m.dtype)
    values = values.to(altitude_m.dtype)
    i = _segment(altitude_m, nodes_m)
    h0, h1 = nodes_m[i], nodes_m[i + 1]
    v0, v1 = values[i], values[i + 1]
    inside = v0 + (v1 - v0) * torch.clamp((altitude_m - h0) / (h1 - h0), max=1.0)
    if above is None:
        return inside
    return torch.where(altitude_m > nodes_m[-1], torch.full_like(inside, above), inside)


def log_linear_column(nodes_m, log_values, start_m: float = 0.0) -> torch.Tensor:
    r""":math:`\int_{start}^{\infty}` of :func:`log_linear` [m x value] in closed form.

    The top interval's exponential continues to infinity (it must decay).
    """
    h = nodes_m
    v = log_values
    lo = torch.clamp(h[:-1], min=start_m)
    hi = torch.clamp(h[1:], min=start_m)
    slope = (v[1:] - v[:-1]) / (h[1:] - h[:-1])
    a = v[:-1] + slope * (lo - h[:-1])
    b = v[:-1] + slope * (hi - h[:-1])
    flat = slope.abs() < 1e-15
    safe = torch.where(flat, torch.ones_like(slope), slope)
    pieces = torch.where(flat, torch.exp(a) * (hi - lo), (torch.exp(b) - torch.exp(a)) / safe)
    last = slope[-1]
    if not bool(last < 0):
        raise ValueError("profile: the number density must decrease in the top layer (it is "
                         "continued above the top with that layer's scale height)")
    return pieces.sum() + torch.exp(v[-1]) / (-last)
