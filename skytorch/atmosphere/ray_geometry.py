r"""Ray geometry shared by the refraction algorithms.

The refractive-index profile of an atmosphere and the checks and adapters every ray computation goes
through.

:class:`_Geometry` holds the planet radius, the top of the atmosphere and the profile
:math:`\nu(h) = n(h) - 1` continued as a constant below the ground and above the top (the
model conventions of :mod:`skytorch.atmosphere.refraction`), its slope
:math:`\mathrm{d}\nu/\mathrm{d}h` by autograd, the altitudes where the profile has kinks,
and the periapsis of a ray from its Bouguer invariant (Newton's method). The helpers
check an atmosphere-like object, broadcast ray inputs against its batched parameters,
lay those parameters out per ray, wrap it with the dispersion of air
(:class:`_Dispersive`) and turn it into extinction or species-density functions of
altitude. The Bouguer integrals (:mod:`skytorch.atmosphere.bouguer`), the RK4 tracer
(:mod:`skytorch.atmosphere.ray_tracer`) and the deviation tables
(:mod:`skytorch.atmosphere.deviation_tables`) build on it; the public functions are in
:mod:`skytorch.atmosphere.refraction`.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere.ray_geometry import ExponentialAir as Air
>>> from skytorch.atmosphere.ray_geometry import _Geometry
>>> geometry = _Geometry(Air(), torch.float64)
>>> h = torch.tensor(10e3, dtype=torch.float64)
>>> beta = h + geometry.refractivity(h) * (geometry.radius + h)  # b - R of the ray
>>> round(float(geometry.periapsis_altitude(beta)), 6)  # its lowest point [m]
10000.0
"""

from __future__ import annotations

import copy
import math

import torch

from skytorch._validate import broadcast_shape, check_choice, check_int, check_range
from skytorch.atmosphere.rayleigh import refractivity_dispersion

__all__ = ["METHODS", "ExponentialAir"]

#: ray-path algorithms: exact Bouguer integrals (Gauss–Legendre) or RK4 ray tracing
METHODS = ("bouguer", "rk4")


class ExponentialAir:
    r"""A minimal atmosphere-like object: :math:`n - 1 = 2.77\times10^{-4}\,e^{-h/8\,km}`.

    Planet radius 6 371 km, top of the atmosphere at 100 km: everything the ray functions
    need (``planet_radius_m``, ``top_altitude_m``, ``top_radius_m``, ``refractivity``),
    for examples and closed-form checks; any object with these attributes works, e.g.
    ``Atmosphere.earth()``.

    Examples
    --------
    >>> import torch
    >>> float(ExponentialAir().refractivity(torch.tensor(0.0, dtype=torch.float64)))
    0.000277
    """

    planet_radius_m, top_altitude_m, top_radius_m = 6.371e6, 1e5, 6.471e6

    def refractivity(self, altitude_m, wavelength_nm=None):
        """Refractivity n - 1 at ``altitude_m`` [m] (grey: ``wavelength_nm`` unused) [1]."""
        return 2.77e-4 * torch.exp(-altitude_m / 8000.0)


def _needs_grad(atm) -> bool:
    """Whether any tensor held by the atmosphere requires gradients.

    Any of its parameters, buffers and attributes; derivatives are then propagated to it.
    """
    if isinstance(atm, _Dispersive):
        return atm.factor.requires_grad or _needs_grad(atm.wrapped)
    if isinstance(atm, torch.nn.Module):
        tensors = list(atm.parameters()) + list(atm.buffers())
    else:
        tensors = [v for v in vars(atm).values() if isinstance(v, torch.Tensor)]
    return any(t.requires_grad for t in tensors)


def _refractivity_needs_grad(atm, top: float, dtype: torch.dtype) -> bool:
    """Whether the refractivity profile depends on a tensor that requires gradients.

    Autograd's own record of the dependence: the profile evaluated (gradients enabled) at a
    few altitudes of [0, top] that do not require gradients. False when only other
    parameters require them (an aerosol optical depth, an ozone column): the rays' geometry
    then carries no graph, and derivatives flow through the columns alone.
    """
    if not _needs_grad(atm):
        return False
    with torch.enable_grad():
        probe = torch.linspace(0.0, top, 5, dtype=dtype)
        return bool(atm.refractivity(probe).requires_grad)


def _breakpoints(atm, top: float, dtype: torch.dtype) -> torch.Tensor | None:
    """Altitudes where the refractivity profile has kinks, strictly inside (0, top) [m].

    Taken from ``atm.refractivity_breakpoints_m`` when the object defines it (an
    :class:`~skytorch.atmosphere.Atmosphere` does: the layer boundaries of the U.S.
    Standard Atmosphere 1976 for its ``"us1976"`` refractivity profile, none for the
    exponential one); None for objects without it. The Bouguer quadrature is split
    there (Gauss–Legendre converges slowly across a jump of dn/dr).
    """
    return _inside(getattr(atm, "refractivity_breakpoints_m", None), top, dtype)


def _inside(levels, top: float, dtype: torch.dtype) -> torch.Tensor | None:
    """Sorted ``levels`` strictly inside (0, top) as a tensor, None when there are none."""
    if levels is None:
        return None
    levels = sorted(v for v in torch.as_tensor(levels, dtype=torch.float64).reshape(-1).tolist()
                    if 0.0 < v < top)
    return torch.tensor(levels, dtype=dtype) if levels else None


def _check_atmosphere(atm, *attributes: str) -> None:
    """TypeError unless ``atm`` has the attributes the ray tracer needs."""
    needed = ("planet_radius_m", "top_altitude_m", "refractivity", *attributes)
    missing = [name for name in needed if not hasattr(atm, name)]
    if missing:
        raise TypeError(
            "atm must be an Atmosphere (or an object with planet_radius_m, top_altitude_m "
            f"and refractivity(altitude_m)); got {type(atm).__name__} without "
            f"{', '.join(missing)}")


def _batch_shape(atm) -> tuple[int, ...]:
    """Batch shape of the atmosphere's parameters; () for plain objects.

    A dispersive wrapper's wavelengths count as batch dims.
    """
    if isinstance(atm, _Dispersive):
        return tuple(broadcast_shape(_batch_shape(atm.wrapped), atm.factor.shape))
    return tuple(getattr(atm, "batch_shape", ()))


def _ray_shape(atm, **named) -> tuple[int, ...]:
    """Broadcast shape of the named ray inputs and the atmosphere's batch shape.

    ValueError naming every input and its shape, before any arithmetic.
    """
    shapes = {name: tuple(value.shape) for name, value in named.items()}
    batch = _batch_shape(atm)
    try:
        return tuple(broadcast_shape(*shapes.values(), batch))
    except ValueError:
        listing = ", ".join(f"{name} {shape}" for name, shape in shapes.items())
        raise ValueError(f"shapes do not broadcast: {listing} and the atmosphere's "
                         f"parameters {batch}") from None


def _map_parameters(atm, transform):
    """Return the atmosphere with every parameter buffer replaced by ``transform(buffer)``.

    Dispersive wrappers: the wrapped atmosphere's; plain objects are returned as they are.
    """
    if isinstance(atm, _Dispersive):
        clone = copy.copy(atm)
        clone.wrapped = _map_parameters(atm.wrapped, transform)
        factor = atm.factor
        clone.factor = factor if factor.ndim == 0 else transform(factor)
        return clone
    if not hasattr(atm, "with_parameters") or _batch_shape(atm) == ():
        return atm
    return atm.with_parameters(transform)


def _per_ray(atm, shape: tuple[int, ...]):
    """Return the atmosphere with its parameters laid out like the flattened rays of ``shape`` (N,).

    Or None when it has no batch dims (then every ray shares the parameters).
    """
    if _batch_shape(atm) == ():
        return None
    count = math.prod(shape)
    return _map_parameters(
        atm, lambda value: value if value.ndim == 0 else value.expand(shape).reshape(count))


class _Geometry:
    """Planet radius, top altitude and the refractive-index profile of an atmosphere.

    Only ``atm.planet_radius_m``, ``atm.top_altitude_m`` and ``atm.refractivity`` are
    used, so any object with these attributes works.
    """

    def __init__(self, atm, dtype: torch.dtype):
        _check_atmosphere(atm)
        self.atm = atm
        self.dtype = dtype
        self.radius = float(atm.planet_radius_m)
        self.top = float(atm.top_altitude_m)
        if not (self.radius > 0 and self.top > 0):
            raise ValueError(
                f"atmosphere needs planet_radius_m > 0 and top_altitude_m > 0; got "
                f"{self.radius!r} and {self.top!r}")
        self.breakpoints = _breakpoints(atm, self.top, dtype)
        kinks = getattr(atm, "refractivity_kinks_m", None)
        #: altitudes where dn/dh jumps, inside (0, top) [m] (RK4 steps end there)
        self.kinks = (self.breakpoints if kinks is None
                      else _inside(kinks, self.top, dtype))
        self.parameters_need_grad = _refractivity_needs_grad(atm, self.top, dtype)
        zero = torch.zeros((), dtype=dtype)
        self.nu0, slope0 = self.refractivity_and_slope(zero)
        self.nu_top = self.refractivity(zero + self.top)
        # m at the ground: u'(R) = 1 + nu0 + R nu'(0) must stay > 0 (no ducting)
        ground_slope = float((1.0 + self.nu0.detach() + self.radius * slope0.detach()).min())
        if not ground_slope > 0.0:
            raise ValueError(
                "the refractive-index profile traps horizontal rays (d(n r)/dr = "
                f"{ground_slope:.3g} <= 0 at the ground); Bouguer integrals need n r to grow "
                "with r")

    def restricted(self, atm) -> _Geometry:
        """Return the same geometry with the profile of ``atm``.

        A per-ray view of the atmosphere for a subset of the rays; nothing is recomputed.
        """
        clone = copy.copy(self)
        clone.atm = atm
        return clone

    def with_levels(self, levels) -> _Geometry:
        """Return the same geometry with the Bouguer quadrature also split at ``levels`` [m].

        e.g. the breakpoints of the species' profiles, for their path columns.
        """
        own = [] if self.breakpoints is None else self.breakpoints.tolist()
        clone = copy.copy(self)
        clone.breakpoints = _inside(sorted(set(own) | set(levels)), self.top, self.dtype)
        return clone

    def refractivity(self, altitude_m: torch.Tensor) -> torch.Tensor:
        r""":math:`\nu(h)` with the constant continuation outside [0, top]."""
        return self.atm.refractivity(torch.clamp(altitude_m, 0.0, self.top)).to(self.dtype)

    def refractivity_and_slope(self, altitude_m: torch.Tensor):
        r""":math:`\nu(h)` and :math:`\mathrm{d}\nu/\mathrm{d}h` (0 outside [0, top]).

        The slope comes from autograd through ``atm.refractivity`` (exact for any
        differentiable profile); with gradients enabled it keeps its own graph so that
        derivatives of the bending integrals are exact too.
        """
        clamped = torch.clamp(altitude_m, 0.0, self.top)
        # derivatives of the result are needed: keep the slope's own graph
        graph = torch.is_grad_enabled() and (clamped.requires_grad or self.parameters_need_grad)
        with torch.enable_grad():
            leaf = clamped if clamped.requires_grad else clamped.detach().requires_grad_(True)
            nu = self.atm.refractivity(leaf).to(self.dtype)
            if nu.shape != leaf.shape:  # a batched profile: one slope per element
                leaf = leaf.expand(nu.shape)
                nu = self.atm.refractivity(leaf).to(self.dtype)
            if nu.requires_grad:
                (slope,) = torch.autograd.grad(nu, leaf, torch.ones_like(nu), create_graph=graph)
            else:  # constant profile
                slope = torch.zeros_like(nu)
        if not graph:
            nu = nu.detach()
        # one-sided derivatives at the ground and at the top
        inside = (altitude_m >= 0.0) & (altitude_m <= self.top)
        slope = torch.where(inside, slope, torch.zeros_like(slope))
        if not graph:
            slope = slope.detach()
        return nu, slope

    def periapsis_altitude(self, impact_altitude: torch.Tensor) -> torch.Tensor:
        r"""Altitude :math:`h_p` where :math:`u(h_p) = b`, given :math:`\beta = b - R`.

        Closed forms below the ground and above the top (constant index there), Newton
        iterations in between (from above the root: u is increasing and, for the usual
        profiles, convex, so the iterates do not overshoot; they are also clamped to the
        interval). The last Newton step carries the gradient, which makes the derivative
        exact (implicit function theorem).
        """
        radius, top = self.radius, self.top
        beta = impact_altitude
        below = (beta - self.nu0 * radius) / (1.0 + self.nu0)
        above = (beta - self.nu_top * radius) / (1.0 + self.nu_top)
        tol = 1e-9 * top if self.dtype == torch.float64 else 1e-7 * top
        with torch.no_grad():
            h = torch.clamp(beta, 0.0, top)
            for _ in range(60):
                nu, slope = self.refractivity_and_slope(h)
                f = h + nu * (radius + h) - beta
                fprime = 1.0 + nu + (radius + h) * slope
                update = torch.clamp(h - f / fprime, 0.0, top)
                change = (update - h).abs()
                h = update
                if bool((change <= tol).all()):  # (the clamp stops rays outside [0, top])
                    break
            _, slope = self.refractivity_and_slope(h)
            fprime = 1.0 + self.refractivity(h) + (radius + h) * slope
        nu = self.refractivity(h)
        newton = h - (h + nu * (radius + h) - beta) / fprime
        is_below = beta < self.nu0 * radius
        is_above = beta > top + self.nu_top * (radius + top)
        return torch.where(is_below, below, torch.where(is_above, above, newton))



#: quadrature names of the straight-ray integrators that mean the Bouguer integrals here
_METHOD_ALIASES = {"gauss": "bouguer"}


def _check_method(method: str, n_nodes, n_steps=None) -> tuple[str, int | None]:
    """Return checked ``method`` and its Gauss–Legendre node count.

    ``n_steps`` overrides ``n_nodes``; validated only for ``"bouguer"``, None for ``"rk4"``.
    """
    method = check_choice("method", _METHOD_ALIASES.get(method, method), METHODS)
    if method != "bouguer":
        return method, None
    return method, check_int("n_nodes", n_nodes if n_steps is None else n_steps, low=2)


def _wavelengths(wavelength_nm, dtype, flat: bool = True):
    wavelength_nm = check_range("wavelength_nm", wavelength_nm, low=0.0, low_inclusive=False,
                                unit=" nm", dtype=dtype)
    return wavelength_nm.reshape(-1) if flat else wavelength_nm


class _Dispersive:
    """An atmosphere whose refractivity is scaled by the dispersion of air at a wavelength.

    ``wavelength_nm`` (...) broadcasts with the rays like a batch dimension of the
    atmosphere; everything but ``refractivity`` is the wrapped atmosphere's.
    """

    def __init__(self, atm, wavelength_nm: torch.Tensor):
        self.wrapped = atm
        self.factor = refractivity_dispersion(wavelength_nm)
        self.planet_radius_m = atm.planet_radius_m
        self.top_altitude_m = atm.top_altitude_m
        for name in ("refractivity_breakpoints_m", "refractivity_kinks_m", "molecule_profile"):
            if hasattr(atm, name):
                setattr(self, name, getattr(atm, name))

    def refractivity(self, altitude_m, wavelength_nm=None):
        return self.wrapped.refractivity(altitude_m) * self.factor.to(
            torch.as_tensor(altitude_m).dtype)

    def extinction_coefficient(self, altitude_m, wavelength_nm):
        return self.wrapped.extinction_coefficient(altitude_m, wavelength_nm)


def _extinction(atm, wavelength):
    """Total extinction coefficient as a function of altitude, (..., n_wavelength) [1/m]."""
    return lambda altitude: atm.extinction_coefficient(altitude, wavelength)


def _extinction_of(wavelength):
    """:func:`_extinction` as a function of the atmosphere (RK4: per-ray views)."""
    return lambda atm: _extinction(atm, wavelength)


def _constituents(atm, wavelength, dtype):
    """Return ``atm.constituents(wavelength, dtype)``, or None without constituents.

    For an :class:`~skytorch.atmosphere.Atmosphere`: every species, with its optical-depth law; None
    for an object without constituents (its ``extinction_coefficient`` is then integrated along the
    path).
    """
    if not hasattr(atm, "constituents"):
        return None
    return atm.constituents(wavelength, dtype)


def _species_levels(constituents) -> tuple[float, ...]:
    """Return the absolute breakpoints of the species' profiles [m].

    Kinks, layer edges and peaks of every member of a batched atmosphere, where the quadrature of
    their path columns is split; profiles with breakpoints relative to the path (smooth
    exponentials) add none.
    """
    levels = set()
    for profile in constituents.profiles.values():
        if profile.breakpoints_m is not None:
            levels.update(profile.breakpoints_m.detach().reshape(-1).tolist())
    return tuple(sorted(levels))


def _integrated_species(constituents) -> tuple[str, ...]:
    """Names of the species whose path columns are integrated.

    The absent ones, ``vanishes``, have zero columns.
    """
    return tuple(s.name for s in constituents.species if not s.vanishes)


def _profile_densities(atm, names, dtype):
    """Return the relative densities of the species ``names`` as a function of altitude.

    From ``atm.profiles(dtype)``, stacked on a trailing dimension, (..., n_species).
    """
    profiles = atm.profiles(dtype)
    chosen = [profiles[name] for name in names]

    def densities(altitude):
        if not chosen:
            return altitude.new_zeros(altitude.shape + (0,))
        # a profile takes its samples on a trailing dim (after the batch dims); a state
        # shared by several profiles (the U.S. Standard Atmosphere of the gases) is
        # evaluated once at these samples
        samples, states = altitude[..., None], {}
        return torch.stack([profile._evaluate(samples, 0, states)[..., 0]
                            for profile in chosen], dim=-1)

    return densities


def _profile_densities_of(names, dtype):
    """:func:`_profile_densities` as a function of the atmosphere (per-ray views)."""
    return lambda atm: _profile_densities(atm, names, dtype)


def _columns_optical_depth(constituents, names, columns, per_species: bool):
    """Optical depth from the path columns (..., len(names)) [m] of the species ``names``.

    The others' columns are zero; through :meth:`Constituents.optical_depth`, the one place where
    columns become optical depths (nonlinear laws included).
    """
    zero = columns.new_zeros(columns.shape[:-1])
    by_name = {name: columns[..., names.index(name)] if name in names else zero
               for name in constituents.names}
    return constituents.optical_depth(by_name, per_species=per_species)



def _check_elevation(name, value, dtype):
    """Altitude angle in [-pi/2, pi/2] (a few ulps of slack for float32 pi/2)."""
    limit = math.pi / 2 * (1.0 + 4.0 * torch.finfo(dtype).eps)
    value = check_range(name, value, -limit, limit, unit=" rad", dtype=dtype)
    return torch.clamp(value, -math.pi / 2, math.pi / 2)
