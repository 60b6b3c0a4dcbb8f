r"""Refracted rays in a spherically symmetric atmosphere.

Astronomical refraction for an observer, optical depth along the bent path, rays from
space that graze the limb and leave again (the light that reaches a planet's umbra), and
the ray-deviation / contact-radius table of Schneegans et al. 2025 (their Fig. 6).

Two independent algorithms are provided:

``"bouguer"`` (default)
    The exact integrals for a spherically symmetric refractive index :math:`n(r)`.
    Along a ray, Bouguer's invariant :math:`b = n(r)\,r\sin z` is constant (:math:`z`
    the local zenith angle), so the bending and the path length are one-dimensional
    integrals over the radius (ref. 1, 2),

    .. math::

        \delta = \int \frac{-\,b\,\mathrm{d}n/\mathrm{d}r}{n\sqrt{u^2 - b^2}}\,|\mathrm{d}r|,
        \qquad
        s = \int \frac{u}{\sqrt{u^2 - b^2}}\,|\mathrm{d}r|,
        \qquad u(r) = n(r)\,r .

    The integrands diverge like :math:`(r - r_p)^{-1/2}` at the periapsis :math:`r_p`
    (where :math:`u(r_p) = b`), i.e. for every grazing ray and every ray leaving an
    observer horizontally. The substitution :math:`r = r_p + L t^2` with
    :math:`L = r_{top} - r_p` turns them into smooth, even functions of :math:`t`,

    .. math::

        \frac{|\mathrm{d}r|}{\sqrt{u^2 - b^2}} = \frac{2\sqrt{L}\,\mathrm{d}t}
        {\sqrt{m\,(u + b)}}, \qquad m = \frac{u - b}{r - r_p}
        = n(r) + r_p\,\frac{n(r) - n(r_p)}{r - r_p},

    with :math:`m` evaluated without cancellation (a divided difference that falls back to
    the mean slope when :math:`r \to r_p`). A ray from an observer at :math:`t_0`
    (negative when it first goes down) to the top is then the single interval
    :math:`t \in [t_0, 1]`, and a ray from space through the limb is
    :math:`2\int_0^1`; both are integrated by Gauss–Legendre quadrature. All lengths are
    handled as altitudes (:math:`h = r - R`), so float32 keeps its precision.

``"rk4"``
    Ray tracing of the eikonal equation :math:`\mathrm{d}(n\,\hat{\mathbf{d}})/\mathrm{d}s
    = \nabla n` in the plane of the ray with the classical Runge–Kutta scheme (the
    approach of Seron et al. 2004 and van der Werf 2008 that Schneegans et al. 2025 use,
    10 km steps), with the step also limited so that the altitude changes by at most
    ``max_dh_m`` per step. Rays land on the ground (no RK4 stage across the jump of
    :math:`\mathrm{d}n/\mathrm{d}r` there) and cross the planet on a straight chord. It
    shares no formula with the Bouguer integrals and serves as the independent check.

Model conventions (both methods): the refractive index is :math:`1 + \nu(h)` with
:math:`\nu` = ``atm.refractivity(h)`` inside the atmosphere, continued as a constant below
the ground (the rays that hit the ground are traced on through a planet of constant
index, as in ref. 3, so that every quantity stays continuous) and above the top (where
:math:`\nu_{top}` is ~1e-9 for Earth: no refraction occurs there and the jump to vacuum,
worth < 1e-8 rad, is ignored). The index is grey (``wavelength_nm=None``); its spectral
dependence changes refraction by < 0.02° (ref. 3).

References
----------
1. Auer, L. H. & Standish, E. M. 2000, "Astronomical refraction: computational method for
   all zenith angles", Astron. J. 119, 2472, doi:10.1086/301325.
2. Born, M. & Wolf, E. 1999, *Principles of Optics*, 7th ed., Cambridge University Press,
   §3.2 (Bouguer's formula), doi:10.1017/CBO9781139644181.
3. Schneegans, S., Gilg, J., Ahlers, V., Zachmann, G. & Gerndt, A. 2025, "Physically Based
   Real-Time Rendering of Eclipses", Computer Graphics Forum, doi:10.1111/cgf.70220.
4. Seron, F. J., Gutierrez, D., Gutierrez, G. & Cerezo, E. 2004, "Visualizing sunsets
   through inhomogeneous atmospheres", Proc. Computer Graphics International, 349,
   doi:10.1109/CGI.2004.1309232.
5. van der Werf, S. Y. 2008, "Comment on 'Improved ray tracing air mass numbers model'",
   Appl. Opt. 47, 153, doi:10.1364/AO.47.000153.
6. Bennett, G. G. 1982, "The calculation of astronomical refraction in marine navigation",
   J. Navigation 35, 255, doi:10.1017/S0373463300022037.
7. Kasten, F. & Young, A. T. 1989, "Revised optical air mass tables and approximation
   formula", Appl. Opt. 28, 4735, doi:10.1364/AO.28.004735.
8. Bruneton, E. 2017, "Precomputed Atmospheric Scattering: a New Implementation",
   https://ebruneton.github.io/precomputed_atmospheric_scattering/ (transmittance
   texture parametrisation).

Examples
--------
>>> import torch
>>> from skytorch.atmosphere.refraction import refraction_angle
>>> class Air:  # any object with these attributes works, e.g. Atmosphere.earth()
...     planet_radius_m, top_altitude_m, top_radius_m = 6.371e6, 1e5, 6.471e6
...     def refractivity(self, altitude_m, wavelength_nm=None):
...         return 2.77e-4 * torch.exp(-altitude_m / 8000.0)
>>> r = refraction_angle(Air(), torch.tensor(0.0, dtype=torch.float64))
>>> round(float(r) * 180 / torch.pi * 60)  # arcminutes at the apparent horizon
37
"""

from __future__ import annotations

import copy
import functools
import logging
import math

import numpy as np
import torch

from skytorch._validate import (
    broadcast_shape,
    check_choice,
    check_int,
    check_range,
    common_dtype,
)
from skytorch.atmosphere.geometry import texture_coordinates, texture_rays
from skytorch.atmosphere.optical_depth import check_rtol
from skytorch.atmosphere.rayleigh import refractivity_dispersion

__all__ = [
    "METHODS",
    "TABLE_PARAMETRISATIONS",
    "DeviationTable",
    "apparent_altitude",
    "bent_optical_depth",
    "deviation_table",
    "lookup_deviation",
    "refraction_angle",
    "trace_grazing_rays",
]

logger = logging.getLogger(__name__)

#: ray-path algorithms: exact Bouguer integrals (Gauss–Legendre) or RK4 ray tracing
METHODS = ("bouguer", "rk4")
#: parametrisations of the deviation table
TABLE_PARAMETRISATIONS = ("schneegans2025",)

DEFAULT_NODES = 64  #: Gauss–Legendre nodes of the Bouguer integrals
DEFAULT_STEP_M = 10e3  #: RK4 step along the ray (Schneegans et al. 2025, Seron et al. 2004)
DEFAULT_MAX_DH_M = 1e3  #: RK4 step limit: altitude change per step [m]
TABLE_NODES = 32  #: Gauss–Legendre nodes for the deviation table (0.02" from converged)
#: ... per panel when the profile has breakpoints (US 1976: 12 panels; 1e-4" from 32)
TABLE_PANEL_NODES = 16
#: RK4 steps that reach a kink of the refractivity profile end this far past it [m]
_KINK_OVERSHOOT_M = 1e-3


# --- small helpers -------------------------------------------------------------------------


@functools.lru_cache(maxsize=32)
def _legendre_unit(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre nodes and weights on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


def _gauss_nodes(n: int, dtype: torch.dtype, ndim: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Nodes and weights on [0, 1] shaped ``(n, 1, ..., 1)`` to lead ``ndim`` batch dims."""
    x, w = _legendre_unit(n)
    shape = (n,) + (1,) * ndim
    return (torch.as_tensor(x, dtype=dtype).reshape(shape),
            torch.as_tensor(w, dtype=dtype).reshape(shape))


def _needs_grad(atm) -> bool:
    """Whether any tensor held by the atmosphere (parameters, buffers, attributes) requires
    gradients, in which case derivatives are propagated to it."""
    if isinstance(atm, _Dispersive):
        return atm.factor.requires_grad or _needs_grad(atm.wrapped)
    if isinstance(atm, torch.nn.Module):
        tensors = list(atm.parameters()) + list(atm.buffers())
    else:
        tensors = [v for v in vars(atm).values() if isinstance(v, torch.Tensor)]
    return any(t.requires_grad for t in tensors)


def _breakpoints(atm, top: float, dtype: torch.dtype) -> torch.Tensor | None:
    """Altitudes where the refractivity profile has kinks, strictly inside (0, top) [m].

    Taken from ``atm.refractivity_breakpoints_m`` when the object defines it; for an
    :class:`~skytorch.atmosphere.Atmosphere` with the U.S. Standard Atmosphere 1976
    molecules, the layer boundaries of that standard. The Bouguer quadrature is split
    there (Gauss–Legendre converges slowly across a jump of dn/dr).
    """
    levels = getattr(atm, "refractivity_breakpoints_m", None)
    if levels is None and getattr(atm, "molecule_profile", None) == "us1976":
        from skytorch.atmosphere.model import _US1976_BREAKS_M as levels
    return _inside(levels, top, dtype)


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
    """Batch shape of the atmosphere's parameters (a dispersive wrapper's wavelengths
    count as batch dims); () for plain objects."""
    if isinstance(atm, _Dispersive):
        return tuple(broadcast_shape(_batch_shape(atm.wrapped), atm.factor.shape))
    return tuple(getattr(atm, "batch_shape", ()))


def _ray_shape(atm, **named) -> tuple[int, ...]:
    """Broadcast shape of the named ray inputs and the atmosphere's batch shape
    (ValueError naming every input and its shape, before any arithmetic)."""
    shapes = {name: tuple(value.shape) for name, value in named.items()}
    batch = _batch_shape(atm)
    try:
        return tuple(broadcast_shape(*shapes.values(), batch))
    except ValueError:
        listing = ", ".join(f"{name} {shape}" for name, shape in shapes.items())
        raise ValueError(f"shapes do not broadcast: {listing} and the atmosphere's "
                         f"parameters {batch}") from None


def _map_parameters(atm, transform):
    """The atmosphere with every parameter buffer replaced by ``transform(buffer)``
    (dispersive wrappers: the wrapped atmosphere's; plain objects are returned as they
    are)."""
    if isinstance(atm, _Dispersive):
        clone = copy.copy(atm)
        clone.wrapped = _map_parameters(atm.wrapped, transform)
        factor = atm.factor
        clone.factor = factor if factor.ndim == 0 else transform(factor)
        return clone
    if not hasattr(atm, "_with_parameters") or _batch_shape(atm) == ():
        return atm
    return atm._with_parameters(transform)


def _per_ray(atm, shape: tuple[int, ...]):
    """The atmosphere with its parameters laid out like the flattened rays of ``shape``
    (N,), or None when it has no batch dims (then every ray shares the parameters)."""
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
        self.parameters_need_grad = _needs_grad(atm)
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
        """The same geometry with the profile of ``atm`` (a per-ray view of the
        atmosphere for a subset of the rays; nothing is recomputed)."""
        clone = copy.copy(self)
        clone.atm = atm
        return clone

    def refractivity(self, altitude_m: torch.Tensor) -> torch.Tensor:
        """:math:`\\nu(h)` with the constant continuation outside [0, top]."""
        return self.atm.refractivity(torch.clamp(altitude_m, 0.0, self.top)).to(self.dtype)

    def refractivity_and_slope(self, altitude_m: torch.Tensor):
        """:math:`\\nu(h)` and :math:`\\mathrm{d}\\nu/\\mathrm{d}h` (0 outside [0, top]).

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
        """Altitude :math:`h_p` where :math:`u(h_p) = b`, given :math:`\\beta = b - R`.

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


def _divided_difference(nu, nu_q, slope, slope_q, dh):
    """(nu(h) - nu(q)) / (h - q) for h >= q, the mean slope for tiny ``dh`` (no cancellation)."""
    threshold = 1e-2 if nu.dtype == torch.float64 else 50.0
    far = dh > threshold
    safe = torch.where(far, dh, torch.ones_like(dh))
    return torch.where(far, (nu - nu_q) / safe, 0.5 * (slope + slope_q))


class _Rays:
    """Rays of one Bouguer invariant, parametrised by :math:`t` with r = r_p + L t^2."""

    def __init__(self, geometry: _Geometry, periapsis_altitude: torch.Tensor):
        self.geometry = geometry
        radius, top = geometry.radius, geometry.top
        self.h_p = periapsis_altitude
        # the profile is constant outside [0, top]: differences are taken from the
        # clamped periapsis q, with the one-sided slope there
        self.q = torch.clamp(self.h_p, 0.0, top)
        self.nu_p, self.slope_q = geometry.refractivity_and_slope(self.q)
        self.misses = self.h_p >= top
        length = top - self.h_p
        self.length = torch.clamp(length, min=1e-9 * top)
        # Bouguer invariant b = u(h_p) (the continued profile) and its altitude b - R
        self.b = (radius + self.h_p) * (1.0 + self.nu_p)
        self.hits = self.h_p < 0.0
        depth = torch.clamp(-self.h_p, min=torch.finfo(self.h_p.dtype).tiny)
        self.t_ground = torch.where(self.hits, torch.sqrt(depth / self.length),
                                    torch.zeros_like(self.h_p))

    def slope_ratio(self, altitude, nu, slope):
        """m = (u(h) - b) / (h - h_p) without cancellation, for h >= h_p."""
        top = self.geometry.top
        inner = torch.clamp(altitude, 0.0, top) - self.q
        dd = _divided_difference(nu, self.nu_p, slope, self.slope_q, inner)
        dh = altitude - self.h_p
        shrink = inner / torch.where(dh > 0.0, dh, torch.ones_like(dh))
        shrink = torch.where(dh > 0.0, shrink, torch.ones_like(dh))
        return 1.0 + nu + (self.geometry.radius + self.h_p) * dd * shrink

    def integrate(self, t_low, t_high, n_nodes, *, bending=True, coefficient=None):
        """Quadrature over ``t`` in [t_low, t_high] of the bending and path integrands.

        Returns the bending [rad] (*S,) and, with ``coefficient`` (a function of altitude
        returning (..., n) [1/m]), its path integral ``optical_depth`` (*S, n).
        """
        geometry = self.geometry
        t_low, t_high = torch.broadcast_tensors(t_low, t_high)
        if geometry.breakpoints is not None:
            # composite rule: panels between the t of the profile's kinks
            levels = geometry.breakpoints.reshape((-1,) + (1,) * self.h_p.dim())
            depth = torch.clamp(levels - self.h_p, min=torch.finfo(self.h_p.dtype).tiny)
            cuts = torch.minimum(torch.maximum(torch.sqrt(depth / self.length), t_low), t_high)
            edges = torch.cat([t_low.unsqueeze(0), cuts, t_high.unsqueeze(0)], dim=0)
            t_low, t_high = edges[:-1], edges[1:]
        ndim = t_low.dim()
        x, w = _gauss_nodes(n_nodes, geometry.dtype, ndim)
        span = t_high - t_low
        t = t_low + span * x
        weight = span * w
        if geometry.breakpoints is not None:  # fold the panel dimension into the nodes
            t = t.reshape((-1,) + t.shape[2:])
            weight = weight.reshape((-1,) + weight.shape[2:])
        altitude = self.h_p + self.length * t * t
        nu, slope = geometry.refractivity_and_slope(altitude)
        m = torch.clamp(self.slope_ratio(altitude, nu, slope), min=1e-6)
        u = (geometry.radius + altitude) * (1.0 + nu)
        jacobian = 2.0 * torch.sqrt(self.length) / torch.sqrt(m * (u + self.b))
        result = {}
        if bending:
            integrand = -slope * self.b / (1.0 + nu) * jacobian
            result["bending"] = (weight * integrand).sum(0)
        if coefficient is not None:
            k = coefficient(torch.clamp(altitude, 0.0, geometry.top)).to(geometry.dtype)
            path = (weight * u * jacobian).unsqueeze(-1)
            result["optical_depth"] = (path * k).sum(0)
        return result


#: quadrature names of the straight-ray integrators that mean the Bouguer integrals here
_METHOD_ALIASES = {"gauss": "bouguer"}


def _check_method(method: str, n_nodes, n_steps=None) -> tuple[str, int | None]:
    """Checked ``method`` and its Gauss–Legendre node count (``n_steps`` overrides
    ``n_nodes``; validated only for ``"bouguer"``, None for ``"rk4"``)."""
    method = check_choice("method", _METHOD_ALIASES.get(method, method), METHODS)
    if method != "bouguer":
        return method, None
    return method, check_int("n_nodes", n_nodes if n_steps is None else n_steps, low=2)


def _rk4_resolution(step_m, max_dh_m) -> tuple[float, float]:
    """Checked RK4 step along the ray and altitude-change limit per step [m]."""
    step_m = check_range("step_m", step_m, low=0.0, low_inclusive=False, unit=" m")
    max_dh_m = check_range("max_dh_m", max_dh_m, low=0.0, low_inclusive=False, unit=" m")
    return float(step_m), float(max_dh_m)


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


def _species_densities(atm, species):
    """Relative densities of ``species`` stacked on a trailing dimension (..., n_species)."""
    return lambda altitude: torch.stack([atm.relative_density(s, altitude) for s in species],
                                        dim=-1)


def _extinction_of(wavelength):
    """:func:`_extinction` as a function of the atmosphere (RK4: per-ray views)."""
    return lambda atm: _extinction(atm, wavelength)


def _species_densities_of(species):
    """:func:`_species_densities` as a function of the atmosphere."""
    return lambda atm: _species_densities(atm, species)


# --- observer rays --------------------------------------------------------------------------


def _check_elevation(name, value, dtype):
    """Altitude angle in [-pi/2, pi/2] (a few ulps of slack for float32 pi/2)."""
    limit = math.pi / 2 * (1.0 + 4.0 * torch.finfo(dtype).eps)
    value = check_range(name, value, -limit, limit, unit=" rad", dtype=dtype)
    return torch.clamp(value, -math.pi / 2, math.pi / 2)


def _observer_rays(atm, apparent_altitude_rad, altitude_m, dtype):
    """Geometry, rays and the signed start parameter t_0 for observer rays."""
    elevation = _check_elevation("apparent_altitude_rad", apparent_altitude_rad, dtype)
    height = check_range("altitude_m", altitude_m, low=0.0, unit=" m", dtype=dtype)
    # the rays carry the atmosphere's batch dims: quadrature nodes lead, so every ray
    # tensor must hold them (a scalar ray against batched parameters is expanded)
    shape = _ray_shape(atm, apparent_altitude_rad=elevation, altitude_m=height)
    elevation, height = elevation.expand(shape), height.expand(shape)
    geometry = _Geometry(atm, dtype)
    radius = geometry.radius
    nu0 = geometry.refractivity(height)
    u0 = (radius + height) * (1.0 + nu0)
    half = torch.sin(0.5 * elevation)
    # b - R = u0 cos(e) - R, written without cancellation at the horizon
    beta = height + nu0 * (radius + height) - 2.0 * u0 * half * half
    rays = _Rays(geometry, geometry.periapsis_altitude(beta))
    nu_h, slope_h = geometry.refractivity_and_slope(height)
    m0 = torch.clamp(rays.slope_ratio(height, nu_h, slope_h), min=1e-6)
    t0 = torch.sqrt(2.0 * u0 / (m0 * rays.length)) * half
    t0 = torch.clamp(t0, -1.0, 1.0)
    return geometry, rays, elevation, height, t0


def refraction_angle(
    atm,
    apparent_altitude_rad,
    altitude_m=0.0,
    *,
    method: str = "bouguer",
    n_nodes: int = DEFAULT_NODES,
    step_m: float = DEFAULT_STEP_M,
    max_dh_m: float = DEFAULT_MAX_DH_M,
    n_steps: int | None = None,
    wavelength_nm=None,
) -> torch.Tensor:
    r"""Astronomical refraction :math:`R` = apparent − true altitude [rad].

    Parameters
    ----------
    atm : Atmosphere or compatible
        Needs ``planet_radius_m``, ``top_altitude_m`` and ``refractivity(altitude_m)``.
    apparent_altitude_rad : float or Tensor (...)
        Apparent (refracted) altitude of the ray at the observer, in [−π/2, π/2] [rad].
    altitude_m : float or Tensor (...)
        Observer altitude above the surface, ≥ 0; above the top of the atmosphere works
        too [m]. Broadcasts with ``apparent_altitude_rad``.
    method : {"bouguer", "rk4"}
        Exact Bouguer integral (Gauss–Legendre, ``n_nodes``) or RK4 ray tracing
        (``step_m``, ``max_dh_m``).
    n_nodes : int
        Gauss–Legendre nodes (``"bouguer"``).
    step_m, max_dh_m : float
        RK4 step along the ray and largest altitude change per step [m] (``"rk4"``).
    n_steps : int, optional
        Alias of ``n_nodes`` (the name the straight-ray integrators use).
    wavelength_nm : float or Tensor (...), optional
        Vacuum wavelength [nm], broadcast with the rays like a batch dimension: the
        refractivity is scaled by the dispersion of air relative to 589.3 nm
        (:func:`skytorch.atmosphere.rayleigh.refractivity_dispersion`, Peck & Reeder
        1972). Default: grey (the refractivity as given, i.e. at 589.3 nm). With
        ``"rk4"`` one wavelength per call.

    Returns
    -------
    Tensor (...)
        Refraction [rad], the total bending of the ray from the observer to the top of
        the atmosphere; dtype of the inputs.

    Notes
    -----
    With :math:`b = n_0 r_0 \cos e` the Bouguer invariant of the ray,

    .. math:: R = \int_{\text{path}} \frac{-b\,n'(r)}{n\sqrt{n^2 r^2 - b^2}}\,|\mathrm{d}r|,

    evaluated over :math:`t \in [t_0, 1]` (module docstring). Below the horizon the path
    first descends to the periapsis; rays that hit the ground are continued through the
    planet with constant index (Schneegans et al. 2025), so :math:`R` stays smooth.

    Examples
    --------
    >>> import torch
    >>> class Air:
    ...     planet_radius_m, top_altitude_m, top_radius_m = 6.371e6, 1e5, 6.471e6
    ...     def refractivity(self, altitude_m, wavelength_nm=None):
    ...         return 2.77e-4 * torch.exp(-altitude_m / 8000.0)
    >>> e = torch.deg2rad(torch.tensor([45.0], dtype=torch.float64))
    >>> float(refraction_angle(Air(), e) * 206264.8).__round__()  # arcseconds
    57
    """
    method, n_nodes = _check_method(method, n_nodes, n_steps)
    _check_atmosphere(atm)
    dtype = common_dtype(apparent_altitude_rad, altitude_m)
    apparent_altitude_rad = _check_elevation("apparent_altitude_rad", apparent_altitude_rad,
                                             dtype)
    altitude_m = check_range("altitude_m", altitude_m, low=0.0, unit=" m", dtype=dtype)
    if wavelength_nm is not None:
        wavelength = _wavelengths(wavelength_nm, dtype, flat=False)
        if method == "rk4" and wavelength.numel() != 1:
            raise ValueError("method='rk4' takes one wavelength at a time; got wavelength_nm "
                             f"of shape {tuple(wavelength.shape)}")
        atm = _Dispersive(atm, wavelength.reshape(()) if method == "rk4" else wavelength)
    _ray_shape(atm, apparent_altitude_rad=apparent_altitude_rad, altitude_m=altitude_m)
    if method == "rk4":
        return _trace_observer_rk4(atm, apparent_altitude_rad, altitude_m, dtype, step_m,
                                   max_dh_m)["deviation_rad"]
    return _observer_bending(atm, apparent_altitude_rad, altitude_m, dtype, n_nodes)[0]


def _observer_bending(atm, apparent_altitude_rad, altitude_m, dtype, n_nodes):
    """Bouguer bending from an observer to space, with the rays and their t0."""
    geometry, rays, elevation, _, t0 = _observer_rays(atm, apparent_altitude_rad, altitude_m,
                                                      dtype)
    # The integrands are even in t, so a ray that first descends is the single interval
    # [t0, 1] through the periapsis t = 0 -- or [t_g, 1] + [t_g, -t0] when it hits the
    # ground (t_g > 0) or when the quadrature is split at the profile's kinks.
    down = t0 < 0.0
    split = down & (rays.hits | (geometry.breakpoints is not None))
    start = torch.where(split, rays.t_ground, t0)
    bending = rays.integrate(start, torch.ones_like(start), n_nodes)["bending"]
    extra = _integrate_where(rays, split, rays.t_ground, torch.maximum(-t0, rays.t_ground),
                             n_nodes)
    if extra is not None:
        bending = bending + extra["bending"]
    return torch.where(rays.misses, torch.zeros_like(bending), bending), rays, t0


def _integrate_where(rays, mask, t_low, t_high, n_nodes, *, bending=True, coefficient_of=None):
    """:meth:`_Rays.integrate` on the rays selected by ``mask`` only, zero elsewhere.

    ``coefficient_of(atm)`` gives the extinction as a function of altitude for an
    atmosphere (here a view of the selected rays' parameters when it is batched).
    """
    if not bool(mask.any()):
        return None
    shape = mask.shape
    flat = mask.reshape(-1)
    index = flat.nonzero().squeeze(-1)

    def pick(x):
        return torch.broadcast_to(x, shape).reshape(-1)[index]

    geometry = rays.geometry
    per_ray = _per_ray(geometry.atm, tuple(shape))
    if per_ray is None:
        view = geometry.atm
    else:
        view = _map_parameters(per_ray, lambda value: value if value.ndim == 0 else value[index])
        geometry = geometry.restricted(view)
    subset = _Rays(geometry, pick(rays.h_p))
    coefficient = None if coefficient_of is None else coefficient_of(view)
    result = subset.integrate(pick(t_low), pick(t_high), n_nodes, bending=bending,
                              coefficient=coefficient)
    output = {}
    for key, value in result.items():
        trailing = value.shape[1:]
        full = value.new_zeros((flat.numel(),) + trailing)
        full = full.index_put((index,), value)
        output[key] = full.reshape(shape + trailing)
    return output


def apparent_altitude(
    atm,
    true_altitude_rad,
    altitude_m=0.0,
    *,
    tolerance_rad: float = 1e-3 * math.pi / 648000.0,
    max_iterations: int = 30,
    method: str = "bouguer",
    n_nodes: int = DEFAULT_NODES,
    step_m: float = DEFAULT_STEP_M,
    max_dh_m: float = DEFAULT_MAX_DH_M,
    n_steps: int | None = None,
    wavelength_nm=None,
) -> torch.Tensor:
    r"""Apparent altitude of an object at a true (unrefracted) altitude [rad].

    Solves :math:`e - R(e) = e_{true}` for the apparent altitude :math:`e` by Newton's
    method (derivative by a central difference), the inverse of :func:`refraction_angle`.

    Parameters
    ----------
    atm : Atmosphere or compatible
        See :func:`refraction_angle`.
    true_altitude_rad : float or Tensor (...)
        True altitude [rad]; the solution must lie in [−π/2, π/2].
    altitude_m : float or Tensor (...)
        Observer altitude [m].
    tolerance_rad : float
        Convergence tolerance on the residual [rad] (default 0.001″; float32 stops at
        its rounding level, ~0.02″ near 1 rad).
    max_iterations : int
        Newton iterations at most.
    method, n_nodes, step_m, max_dh_m, n_steps, wavelength_nm
        As for :func:`refraction_angle`.

    Returns
    -------
    Tensor (...)
        Apparent altitude [rad]. The last Newton step carries the gradient, so
        derivatives are exact.

    Examples
    --------
    >>> import torch
    >>> class Air:
    ...     planet_radius_m, top_altitude_m, top_radius_m = 6.371e6, 1e5, 6.471e6
    ...     def refractivity(self, altitude_m, wavelength_nm=None):
    ...         return 2.77e-4 * torch.exp(-altitude_m / 8000.0)
    >>> e = apparent_altitude(Air(), torch.tensor(0.0, dtype=torch.float64))
    >>> round(float(e) * 180 / torch.pi * 60)  # the Sun's centre at true altitude 0
    30
    """
    _check_atmosphere(atm)
    dtype = common_dtype(true_altitude_rad, altitude_m)
    target = _check_elevation("true_altitude_rad", true_altitude_rad, dtype)
    height = check_range("altitude_m", altitude_m, low=0.0, unit=" m", dtype=dtype)
    tolerance = float(check_range("tolerance_rad", tolerance_rad, 0.0, low_inclusive=False,
                                  unit=" rad"))
    iterations = check_int("max_iterations", max_iterations, low=1)
    options = {"method": method, "n_nodes": n_nodes, "step_m": step_m, "max_dh_m": max_dh_m,
               "n_steps": n_steps, "wavelength_nm": wavelength_nm}
    _check_method(method, n_nodes, n_steps)
    _ray_shape(atm, true_altitude_rad=target, altitude_m=height)
    target, height = torch.broadcast_tensors(target, height)
    limit = math.pi / 2
    delta = 1e-6 if dtype == torch.float64 else 1e-3
    floor = 8 * torch.finfo(dtype).eps

    def residual(e):
        return e - refraction_angle(atm, e, height, **options) - target

    with torch.no_grad():
        e = torch.clamp(target + 0.01 * (target < 0.5), -limit, limit)
        for _ in range(iterations):
            lo = torch.clamp(e - delta, -limit, limit)
            hi = torch.clamp(e + delta, -limit, limit)
            derivative = (residual(hi) - residual(lo)) / (hi - lo)
            f = residual(e)
            e = torch.clamp(e - f / derivative, -limit, limit)
            if bool((f.abs() <= max(tolerance, float(floor))).all()):
                break
    needs_grad = (target.requires_grad or height.requires_grad
                  or (wavelength_nm is not None and isinstance(wavelength_nm, torch.Tensor)
                      and wavelength_nm.requires_grad) or _needs_grad(atm))
    if torch.is_grad_enabled() and needs_grad:
        e = e - residual(e) / derivative
    return e


def bent_optical_depth(
    atm,
    wavelength_nm,
    zenith_rad=0.0,
    altitude_m=0.0,
    *,
    method: str = "bouguer",
    n_nodes: int = DEFAULT_NODES,
    step_m: float = DEFAULT_STEP_M,
    max_dh_m: float = DEFAULT_MAX_DH_M,
    n_steps: int | None = None,
    per_species: bool = False,
    rtol: float = 1e-9,
) -> torch.Tensor | dict[str, torch.Tensor]:
    r"""Optical depth from an observer to space along the refracted ray.

    Parameters
    ----------
    atm : Atmosphere or compatible
        Also needs ``extinction_coefficient(altitude_m, wavelength_nm)`` [1/m].
    wavelength_nm : float or Tensor (n_wavelength,)
        Wavelengths [nm].
    zenith_rad : float or Tensor (...)
        Apparent zenith angle of the ray at the observer, in [0, π] [rad].
    altitude_m : float or Tensor (...)
        Observer altitude [m].
    method, n_nodes, step_m, max_dh_m
        See :func:`refraction_angle`; ``method="gauss"`` (the name of the straight-ray
        Gauss–Legendre integrator) means ``"bouguer"``.
    n_steps : int, optional
        Alias of ``n_nodes`` (the straight-ray integrators' name for their resolution).
    per_species : bool
        Return ``{"rayleigh", "aerosol", "ozone", "stratospheric_aerosol"}`` optical
        depths separately; needs an
        :class:`~skytorch.atmosphere.Atmosphere` (``relative_density`` and
        ``reference_extinction``).
    rtol : float
        Tolerance of the straight-ray ``"adaptive"`` integrator: checked (in (0, 1]) and
        otherwise unused here (the Gauss–Legendre rule has a fixed number of nodes).

    Returns
    -------
    Tensor (..., n_wavelength) or dict of Tensor
        Optical depth [1] along the bent path to the top of the atmosphere; for rays that
        hit the ground (below the horizon) the optical depth to the ground point.

    Notes
    -----
    :math:`\tau = \int k(h)\,\mathrm{d}s` with :math:`\mathrm{d}s = u\,|\mathrm{d}r| /
    \sqrt{u^2-b^2}`, integrated over :math:`t` like :func:`refraction_angle`. The
    relative air mass along refracted rays is the ratio of the Rayleigh optical depth to
    its zenith value (compared with Kasten & Young 1989 in the tests).

    Examples
    --------
    >>> import torch
    >>> class Air:
    ...     planet_radius_m, top_altitude_m, top_radius_m = 6.371e6, 1e5, 6.471e6
    ...     def refractivity(self, altitude_m, wavelength_nm=None):
    ...         return 2.77e-4 * torch.exp(-altitude_m / 8000.0)
    ...     def extinction_coefficient(self, altitude_m, wavelength_nm):
    ...         return 1.2e-5 * torch.exp(-altitude_m / 8000.0)[..., None] * (
    ...             550.0 / wavelength_nm) ** 4
    >>> tau = bent_optical_depth(Air(), [550.0], torch.tensor([0.0, 1.5], dtype=torch.float64))
    >>> tuple(tau.shape)
    (2, 1)
    """
    method, n_nodes = _check_method(method, n_nodes, n_steps)
    check_rtol(rtol)
    if not isinstance(per_species, bool):
        raise TypeError(f"per_species must be True or False; got {per_species!r}")
    _check_atmosphere(atm, "extinction_coefficient",
                      *(("relative_density", "reference_extinction") if per_species else ()))
    dtype = common_dtype(zenith_rad, altitude_m)
    limit = math.pi * (1.0 + 4.0 * torch.finfo(dtype).eps)
    zenith = check_range("zenith_rad", zenith_rad, 0.0, limit, unit=" rad", dtype=dtype)
    height = check_range("altitude_m", altitude_m, low=0.0, unit=" m", dtype=dtype)
    _ray_shape(atm, zenith_rad=zenith, altitude_m=height)
    wavelength = _wavelengths(wavelength_nm, dtype)
    if hasattr(atm, "_wavelength"):  # an Atmosphere: its spectral range
        wavelength = atm._wavelength(wavelength, dtype)
    elevation = torch.clamp(0.5 * math.pi - zenith, -0.5 * math.pi, 0.5 * math.pi)
    if per_species:
        species = ("rayleigh", "aerosol", "ozone", "stratospheric_aerosol")
        coefficient_of = _species_densities_of(species)
    else:
        coefficient_of = _extinction_of(wavelength)
    coefficient = coefficient_of(atm)
    if method == "rk4":
        tau = _trace_observer_rk4(atm, elevation, height, dtype, step_m, max_dh_m,
                                  coefficient=coefficient_of)["optical_depth"]
    else:
        geometry, rays, elevation, _, t0 = _observer_rays(atm, elevation, height, dtype)
        down = t0 < 0.0
        down_hit = down & rays.hits
        # up to the top: [t0, 1] (even integrand, through the periapsis t = 0), split into
        # [0, 1] + [0, -t0] where the quadrature has panels; rays hitting the ground: from
        # the ground to the observer, [t_g, -t0]
        split = down & ~rays.hits & (geometry.breakpoints is not None)
        low = torch.where(down_hit | split, rays.t_ground, t0)
        high = torch.where(down_hit, torch.maximum(-t0, rays.t_ground), torch.ones_like(t0))
        tau = rays.integrate(low, high, n_nodes, bending=False,
                             coefficient=coefficient)["optical_depth"]
        extra = _integrate_where(rays, split, torch.zeros_like(t0),
                                 torch.clamp(-t0, min=0.0), n_nodes, bending=False,
                                 coefficient_of=coefficient_of)
        if extra is not None:
            tau = tau + extra["optical_depth"]
        tau = torch.where(rays.misses.unsqueeze(-1), torch.zeros_like(tau), tau)
    if not per_species:
        return tau
    # columns of relative density times the model's reference-level coefficients
    reference = atm.reference_extinction(wavelength)
    return {s: tau[..., i, None] * reference[s].to(dtype) for i, s in enumerate(species)}


# --- rays from space through the limb ----------------------------------------------------------


def trace_grazing_rays(
    atm,
    impact_parameter_m=None,
    wavelength_nm=None,
    *,
    impact_altitude_m=None,
    periapsis_altitude_m=None,
    method: str = "bouguer",
    n_nodes: int = DEFAULT_NODES,
    step_m: float = DEFAULT_STEP_M,
    max_dh_m: float = DEFAULT_MAX_DH_M,
) -> dict[str, torch.Tensor]:
    r"""Rays from space that cross the limb and leave the atmosphere again.

    Give exactly one of ``impact_parameter_m`` (distance of the incoming straight ray from
    the planet's centre), ``impact_altitude_m`` (the same minus the planet radius; keeps
    float32 precision) or ``periapsis_altitude_m`` (altitude of the lowest point of the
    bent ray; below zero for rays that hit the ground, whose periapsis is virtual).

    Parameters
    ----------
    atm : Atmosphere or compatible
        Needs ``planet_radius_m``, ``top_altitude_m``, ``refractivity`` and, for the
        optical depth, ``extinction_coefficient``.
    impact_parameter_m : float or Tensor (...), optional
        Impact parameter [m].
    wavelength_nm : float or Tensor (n_wavelength,), optional
        Wavelengths for the optical depth [nm]; without it no optical depth is computed.
    impact_altitude_m, periapsis_altitude_m : float or Tensor (...), optional
        Alternatives to ``impact_parameter_m`` [m].
    method : {"bouguer", "rk4"}
        Exact Bouguer integrals or RK4 ray tracing.
    n_nodes : int
        Gauss–Legendre nodes per half ray (``"bouguer"``).
    step_m, max_dh_m : float
        RK4 step and altitude change limit [m] (``"rk4"``).

    Returns
    -------
    dict of Tensor
        ``deviation_rad`` (...) total bending [rad] (towards the planet);
        ``contact_radius_m`` (...) periapsis radius [m] (virtual, below the surface, for
        rays hitting the ground; the impact parameter for rays missing the atmosphere);
        ``contact_altitude_m`` (...) the same minus the planet radius [m];
        ``hits_ground`` (...) bool; ``optical_depth`` (..., n_wavelength) along the whole
        bent path (both halves; for rays hitting the ground the parts above the ground),
        absent without ``wavelength_nm``; ``impact_parameter_m`` and ``impact_altitude_m``
        (...) [m].

    Notes
    -----
    With :math:`u(r) = n(r)r` and the periapsis :math:`u(r_p) = b`, the deviation and
    optical depth are twice the half-path integrals from :math:`r_p` to the top:

    .. math::

        \Delta\theta = 2\int_{r_p}^{r_{top}} \frac{-b\,n'}{n\sqrt{u^2 - b^2}}\,\mathrm{d}r,
        \qquad
        \tau = 2\int_{r_p}^{r_{top}} \frac{k(r)\,u}{\sqrt{u^2 - b^2}}\,\mathrm{d}r,

    integrated over :math:`t` with :math:`r = r_p + L t^2` (no endpoint singularity). A
    ray hits the ground when :math:`b < n(R) R`. The incoming and outgoing asymptotes
    both have the impact parameter :math:`b/n_{top}`.

    Examples
    --------
    >>> import torch
    >>> class Air:
    ...     planet_radius_m, top_altitude_m, top_radius_m = 6.371e6, 1e5, 6.471e6
    ...     def refractivity(self, altitude_m, wavelength_nm=None):
    ...         return 2.77e-4 * torch.exp(-altitude_m / 8000.0)
    >>> rays = trace_grazing_rays(Air(), periapsis_altitude_m=torch.tensor([0.0, 10e3]))
    >>> [round(v, 2) for v in torch.rad2deg(rays["deviation_rad"]).tolist()]
    [1.24, 0.33]
    """
    method, n_nodes = _check_method(method, n_nodes)
    given = [name for name, value in (("impact_parameter_m", impact_parameter_m),
                                      ("impact_altitude_m", impact_altitude_m),
                                      ("periapsis_altitude_m", periapsis_altitude_m))
             if value is not None]
    if len(given) != 1:
        raise ValueError("give exactly one of impact_parameter_m, impact_altitude_m and "
                         f"periapsis_altitude_m; got {given or 'none'}")
    _check_atmosphere(atm, *(() if wavelength_nm is None else ("extinction_coefficient",)))
    dtype = common_dtype(impact_parameter_m, impact_altitude_m, periapsis_altitude_m)
    radius = float(atm.planet_radius_m)
    if impact_parameter_m is not None:
        b_geo = check_range("impact_parameter_m", impact_parameter_m, low=0.0, unit=" m",
                            dtype=dtype)
        impact_altitude_m = b_geo - radius
    wavelength = None if wavelength_nm is None else _wavelengths(wavelength_nm, dtype)
    if wavelength is not None and hasattr(atm, "_wavelength"):
        wavelength = atm._wavelength(wavelength, dtype)
    if method == "rk4":
        if periapsis_altitude_m is not None:
            raise ValueError("method='rk4' needs impact_parameter_m or impact_altitude_m")
        beta_geo = check_range("impact_altitude_m", impact_altitude_m, low=-radius,
                               unit=" m", dtype=dtype)
        return _trace_grazing_rk4(atm, beta_geo, wavelength, dtype, step_m, max_dh_m)
    geometry = _Geometry(atm, dtype)
    if periapsis_altitude_m is not None:
        h_p = check_range("periapsis_altitude_m", periapsis_altitude_m, low=-radius,
                          unit=" m", dtype=dtype)
        h_p = h_p.expand(_ray_shape(atm, periapsis_altitude_m=h_p))
    else:
        beta_geo = check_range("impact_altitude_m", impact_altitude_m, low=-radius,
                               unit=" m", dtype=dtype)
        beta_geo = beta_geo.expand(_ray_shape(atm, impact_altitude_m=beta_geo))
        # Bouguer invariant b = n_top * b_geo (the index is continued above the top)
        h_p = geometry.periapsis_altitude(beta_geo + geometry.nu_top * (radius + beta_geo))
    rays = _Rays(geometry, h_p)
    extinction = None if wavelength is None else _extinction(atm, wavelength)
    result = rays.integrate(rays.t_ground, torch.ones_like(h_p), n_nodes,
                            coefficient=extinction)
    zero = torch.zeros_like(h_p)
    output = {
        "deviation_rad": torch.where(rays.misses, zero, 2.0 * result["bending"]),
        "contact_radius_m": radius + h_p,
        "contact_altitude_m": h_p,
        "hits_ground": rays.hits,
    }
    if extinction is not None:
        tau = result["optical_depth"]
        output["optical_depth"] = torch.where(rays.misses.unsqueeze(-1), torch.zeros_like(tau),
                                              2.0 * tau)
    # geometric impact altitude b/n_top - R
    impact_alt = ((rays.b - radius * (1.0 + geometry.nu_top)) / (1.0 + geometry.nu_top)
                  if periapsis_altitude_m is not None else beta_geo)
    output["impact_altitude_m"] = impact_alt
    output["impact_parameter_m"] = radius + impact_alt
    return output


# --- RK4 ray tracing ------------------------------------------------------------------------------


def _rk4_trace(geometry, position, direction, coefficient, step_m, max_dh_m, max_length,
               stop_at_ground=False, per_ray=None):
    """Trace rays in the plane with RK4 until they leave the atmosphere upwards.

    With ``stop_at_ground`` a ray also stops once it is below the ground (optical depth
    from an observer to the ground).

    ``position`` (N, 2) [m] and ``direction`` (N, 2) unit vectors; ``coefficient`` a
    function of the atmosphere returning the extinction as a function of altitude (or
    None); ``per_ray`` the atmosphere with its parameters laid out like the N rays (a
    batched atmosphere), None when the rays share them. Returns the final direction, the
    minimum radius along the path and the optical depth (N, n_wl) or None.

    Every update is out of place (``index_put``, not item assignment), so that the
    traced rays carry gradients (backward through the whole march).
    """
    radius, top = geometry.radius, geometry.top
    dtype = position.dtype
    r_top = radius + top
    shared_coefficient = None if coefficient is None else coefficient(geometry.atm)

    def local(index):
        """Geometry and extinction for the rays ``index`` (None: all of them)."""
        if per_ray is None:
            return geometry, shared_coefficient
        view = per_ray if index is None else _map_parameters(
            per_ray, lambda value: value if value.ndim == 0 else value[index])
        return geometry.restricted(view), None if coefficient is None else coefficient(view)

    def index_and_gradient(p, geo):
        r = torch.linalg.vector_norm(p, dim=-1)
        nu, slope = geo.refractivity_and_slope(r - radius)
        return 1.0 + nu, slope.unsqueeze(-1) * p / r.unsqueeze(-1), r

    def extinction_at(r, k_of):
        h = r - radius
        inside = ((h >= 0.0) & (h <= top)).unsqueeze(-1)
        k = k_of(torch.clamp(h, 0.0, top)).to(dtype)
        return torch.where(inside, k, torch.zeros_like(k))

    def derivative(p, v, geo, k_of):
        n, grad, r = index_and_gradient(p, geo)
        dp = v / n.unsqueeze(-1)
        dk = extinction_at(r, k_of) if k_of is not None else None
        return dp, grad, dk

    geo_all, k_all = local(None)
    n0, _, r0 = index_and_gradient(position, geo_all)
    v = direction * n0.unsqueeze(-1)  # optical direction n d
    p = position
    tau = None
    if coefficient is not None:
        tau = torch.zeros_like(extinction_at(r0, k_all))
    r_min = r0
    travelled = torch.zeros_like(r0)
    radial = (p * v).sum(-1) / (r0 * n0)  # d r / d s = cos(local zenith angle)
    active = torch.arange(r0.numel())  # rays still in flight (the others are left alone)

    def finished(r, rad, length):
        stop = ((r >= r_top) & (rad >= 0.0)) | (length >= max_length)
        return stop | (r < radius) if stop_at_ground else stop

    active = active[~finished(r0, radial, travelled)]
    limit = torch.full_like(r0.detach(), math.inf)  # step limit after a rejected step
    kink_radii = None if geometry.kinks is None else radius + geometry.kinks.to(dtype)
    while active.numel():
        geo, k_of = local(active)
        pa, va, rad = p[active], v[active], radial[active]
        ra = torch.linalg.vector_norm(pa, dim=-1)
        ds = torch.minimum(torch.full_like(ra, step_m),
                           max_dh_m / torch.clamp(rad.abs(), min=1e-12))
        k1p, k1v, k1k = derivative(pa, va, geo, k_of)
        if kink_radii is not None:
            # end the step just past a kink of the profile (dn/dr jumps there: a step
            # across it would make the scheme first order)
            to_kink = _distance_to_spheres(pa, va, k1v, kink_radii)
            ds = torch.where(to_kink <= ds, to_kink + _KINK_OVERSHOOT_M, ds)
        # land on the ground rather than step across it (dn/dr jumps there): the
        # straight-line distance to the sphere r = R, in a form without cancellation
        # (stop 0.1 % short first, so that no RK4 stage falls below the ground, where
        # dn/dr = 0; the last stretch, <= 1 m, is then a negligible first-order error)
        ds = torch.minimum(ds, limit[active])
        meets, to_ground = _straight_to_ground(pa, va, ra, radius)
        meets = meets & (to_ground <= ds)
        lands = meets & (to_ground <= 1.0)
        ds = torch.where(lands, to_ground, torch.where(meets, 0.999 * to_ground, ds))
        h2 = ds.unsqueeze(-1)
        k2p, k2v, k2k = derivative(pa + 0.5 * h2 * k1p, va + 0.5 * h2 * k1v, geo, k_of)
        k3p, k3v, k3k = derivative(pa + 0.5 * h2 * k2p, va + 0.5 * h2 * k2v, geo, k_of)
        k4p, k4v, k4k = derivative(pa + h2 * k3p, va + h2 * k3v, geo, k_of)
        p_new = pa + h2 / 6.0 * (k1p + 2.0 * k2p + 2.0 * k3p + k4p)
        v_new = va + h2 / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        # a curved ray can cross the ground where the straight line misses it: reject the
        # step and retry shorter (linear interpolation of the radius, 0.1 % short)
        r_trial = torch.linalg.vector_norm(p_new, dim=-1)
        crossed = (r_trial < radius) & (ra >= radius) & ~lands
        accept = ~crossed
        with torch.no_grad():  # the retry length only chooses the next step
            retry = torch.where(
                crossed, 0.999 * ds * (ra - radius) / torch.clamp(ra - r_trial, min=1e-30),
                torch.full_like(ds, math.inf))
        limit = limit.index_put((active,), retry)
        p_new = torch.where(accept.unsqueeze(-1), p_new, pa)
        v_new = torch.where(accept.unsqueeze(-1), v_new, va)
        ds = torch.where(accept, ds, torch.zeros_like(ds))
        if tau is not None:
            increment = h2 / 6.0 * (k1k + 2.0 * k2k + 2.0 * k3k + k4k)
            tau = tau.index_put((active,), tau[active] + increment * accept.unsqueeze(-1))
        # minimum radius: a parabola through the radial speeds at both ends of the step
        r_min_active = r_min[active]
        if bool(lands.any()) and not stop_at_ground:
            # through the planet, where the index is constant: a straight chord
            p_new, chord, closest = _chord_through_ground(p_new, v_new, radius, lands)
            r_min_active = torch.minimum(r_min_active, closest)
            ds = ds + chord
        n_new, _, r_new = index_and_gradient(p_new, geo)
        rad_new = (p_new * v_new).sum(-1) / (r_new * n_new)
        curvature = (rad_new - rad) / torch.clamp(ds, min=1e-30)
        turning = (rad < 0.0) & (rad_new >= 0.0) & (curvature > 0.0) & accept
        safe = torch.where(turning, curvature, torch.ones_like(curvature))
        vertex = ra - rad * rad / (2.0 * safe)
        candidate = torch.where(turning, vertex, torch.minimum(ra, r_new))
        r_min = r_min.index_put((active,), torch.minimum(r_min_active, candidate))
        p = p.index_put((active,), p_new)
        v = v.index_put((active,), v_new)
        radial = radial.index_put((active,), rad_new)
        travelled_active = travelled[active] + ds
        travelled = travelled.index_put((active,), travelled_active)
        stop = finished(r_new, rad_new, travelled_active)
        if stop_at_ground:
            stop = stop | lands
        active = active[~stop]
    direction_out = v / torch.linalg.vector_norm(v, dim=-1, keepdim=True)
    return direction_out, r_min, tau


def _distance_to_spheres(position, velocity, gradient, radii):
    """Path length [m] to the first crossing of any sphere r = ``radii`` (K,) farther than
    :data:`_KINK_OVERSHOOT_M` (inf when none), (N,).

    The estimate never lies beyond the crossing, so that a step of that length ends
    before the sphere (or within :data:`_KINK_OVERSHOOT_M` past it) and the next steps
    approach it. A ray bends towards the centre, so it leaves a sphere after the
    straight line does (``a = 1`` below). It meets a sphere below it before the straight
    line does: there the ray is continued as the parabola ``p + s d + s^2 c / 2`` with
    twice the curvature vector at the start, ``c = (grad n - (grad n . d) d) / n`` (the
    curvature grows downwards), so that ``|p(s)|^2 = r^2 + 2 (p.d) s + a s^2`` with
    ``a = 1 + 2 p.c``. Near roots are written without cancellation:
    ``q / (-p.d + sqrt(disc))`` from outside a sphere and ``-q / (p.d + sqrt(disc))``
    from inside it when moving out, ``q = r^2 - rho^2``, ``disc = (p.d)^2 - a q``.
    """
    n = torch.linalg.vector_norm(velocity, dim=-1, keepdim=True)
    direction = velocity / n
    along = (position * direction).sum(-1, keepdim=True)
    r = torch.linalg.vector_norm(position, dim=-1, keepdim=True)
    across = ((position * gradient).sum(-1, keepdim=True)
              - along * (direction * gradient).sum(-1, keepdim=True))
    excess = (r - radii) * (r + radii)
    outside = excess > 0.0
    a = torch.where(outside, torch.clamp(1.0 + 2.0 * across / n, min=0.1), 1.0)
    disc = along * along - a * excess
    root = torch.sqrt(torch.clamp(disc, min=0.0))
    # from outside: the near root when the ray comes down and meets the sphere
    meets = outside & (along < 0.0) & (disc >= 0.0)
    inward = excess / torch.where(meets, root - along, torch.ones_like(root))
    # from inside (or on) the sphere: the forward root
    outward = torch.where(along > 0.0, -excess / torch.where(along > 0.0, along + root, 1.0),
                          root - along)
    distance = torch.where(outside, torch.where(meets, inward, math.inf), outward)
    distance = torch.where(distance > _KINK_OVERSHOOT_M, distance, math.inf)
    return distance.min(-1).values


def _straight_to_ground(position, velocity, r, radius):
    """Whether a straight ray from above the ground meets the sphere r = R, and where.

    Returns (bool, distance [m]); the near root is written as c / (-p.d + sqrt(disc)).
    """
    direction = velocity / torch.linalg.vector_norm(velocity, dim=-1, keepdim=True)
    along = (position * direction).sum(-1)
    excess = (r - radius) * (r + radius)
    disc = along * along - excess
    meets = (along < 0.0) & (disc >= 0.0) & (excess >= 0.0)
    root = torch.sqrt(torch.clamp(disc, min=0.0))
    denominator = torch.where(meets, root - along, torch.ones_like(root))
    return meets, torch.where(meets, excess / denominator, torch.full_like(r, math.inf))


def _chord_through_ground(position, velocity, radius, mask):
    """Move the rays in ``mask`` straight through the sphere r = R to where they leave it.

    Returns the new positions, the chord lengths and the chords' closest approach to the
    centre (the virtual periapsis; +inf where not moved).
    """
    direction = velocity / torch.linalg.vector_norm(velocity, dim=-1, keepdim=True)
    along = (position * direction).sum(-1)
    r2 = (position * position).sum(-1)
    disc = torch.clamp(along * along - (r2 - radius * radius), min=0.0)
    chord = torch.where(mask, torch.clamp(-along + torch.sqrt(disc), min=0.0),
                        torch.zeros_like(along))
    closest = torch.sqrt(torch.clamp(r2 - along * along, min=0.0))
    closest = torch.where(mask, closest, torch.full_like(closest, math.inf))
    moved = position + chord.unsqueeze(-1) * direction
    # put the exit point on (a micrometre above) the ground, not below it by rounding,
    # so that the next step sees the index gradient at the ground
    r_exit = torch.linalg.vector_norm(moved, dim=-1, keepdim=True)
    moved = torch.where(mask.unsqueeze(-1), moved * ((radius + 1e-6) / r_exit), moved)
    return moved, chord, closest


def _clockwise_angle(d0, d1):
    """Angle by which ``d1`` is rotated clockwise from ``d0`` (bending towards the planet)."""
    cross = d0[..., 0] * d1[..., 1] - d0[..., 1] * d1[..., 0]
    dot = (d0 * d1).sum(-1)
    return torch.atan2(-cross, dot)


def _rk4_max_length(geometry) -> float:
    """Path length after which an RK4 ray is stopped [m]: far beyond any ray's exit."""
    r_top = geometry.radius + geometry.top
    return 4.0 * math.sqrt(r_top**2 - geometry.radius**2) + 4.0 * geometry.top


def _trace_observer_rk4(atm, elevation, altitude_m, dtype, step_m, max_dh_m, coefficient=None):
    elevation = _check_elevation("apparent_altitude_rad", elevation, dtype)
    height = check_range("altitude_m", altitude_m, low=0.0, unit=" m", dtype=dtype)
    step_m, max_dh_m = _rk4_resolution(step_m, max_dh_m)
    shape = _ray_shape(atm, apparent_altitude_rad=elevation, altitude_m=height)
    elevation, height = elevation.expand(shape), height.expand(shape)
    geometry = _Geometry(atm, dtype)
    e = elevation.reshape(-1)
    r0 = geometry.radius + height.reshape(-1)
    position = torch.stack([torch.zeros_like(r0), r0], dim=-1)
    direction = torch.stack([torch.cos(e), torch.sin(e)], dim=-1)
    max_length = _rk4_max_length(geometry)
    final, r_min, tau = _rk4_trace(geometry, position, direction, coefficient, step_m,
                                   max_dh_m, max_length, stop_at_ground=coefficient is not None,
                                   per_ray=_per_ray(atm, shape))
    if coefficient is not None:
        return {"optical_depth": tau.reshape(shape + (tau.shape[-1],))}
    return {"deviation_rad": _clockwise_angle(direction, final).reshape(shape),
            "contact_radius_m": r_min.reshape(shape)}


def _trace_grazing_rk4(atm, beta_geo, wavelength, dtype, step_m, max_dh_m):
    step_m, max_dh_m = _rk4_resolution(step_m, max_dh_m)
    shape = _ray_shape(atm, impact_altitude_m=beta_geo)
    beta_geo = beta_geo.expand(shape)
    geometry = _Geometry(atm, dtype)
    radius = geometry.radius
    r_top = radius + geometry.top
    b = radius + beta_geo.reshape(-1)
    chord = torch.sqrt(torch.clamp((r_top - b) * (r_top + b), min=0.0))
    position = torch.stack([-chord, b], dim=-1)
    direction = torch.stack([torch.ones_like(b), torch.zeros_like(b)], dim=-1)
    extinction = None if wavelength is None else _extinction_of(wavelength)
    max_length = _rk4_max_length(geometry)
    final, r_min, tau = _rk4_trace(geometry, position, direction, extinction, step_m,
                                   max_dh_m, max_length, per_ray=_per_ray(atm, shape))
    output = {
        "deviation_rad": _clockwise_angle(direction, final).reshape(shape),
        "contact_radius_m": r_min.reshape(shape),
        "contact_altitude_m": (r_min - radius).reshape(shape),
        "hits_ground": (r_min < radius).reshape(shape),
        "impact_altitude_m": beta_geo,
        "impact_parameter_m": radius + beta_geo,
    }
    if tau is not None:
        output["optical_depth"] = tau.reshape(shape + (tau.shape[-1],))
    return output


# --- deviation / contact-radius table (Schneegans et al. 2025, Fig. 6) --------------------------


def _table_specs():
    from skytorch.dataset import VariableSpec

    return {
        "x_r": VariableSpec("1", "altitude texture coordinate",
                            "x_r = rho / H with rho = sqrt(r^2 - R^2), H = sqrt(R_top^2 - R^2) "
                            "(Schneegans et al. 2025, eq. 2)."),
        "x_mu": VariableSpec("1", "direction texture coordinate",
                             "x_mu = (d - d_min) / (d_max - d_min), d the straight-line distance "
                             "to the top of the atmosphere (Schneegans et al. 2025, eq. 2); "
                             "0 is the zenith, 1 the ray tangent to the ground."),
        "altitude": VariableSpec("m", "ray origin altitude",
                                 "Altitude of the ray's origin above the surface.", "altitude"),
        "view_zenith_angle": VariableSpec("degree", "view zenith angle",
                                          "Zenith angle of the ray direction at its origin."),
        "deviation": VariableSpec("degree", "ray deviation",
                                  "Angle between the ray direction at its origin and where it "
                                  "leaves the atmosphere (towards the planet), i.e. the "
                                  "astronomical refraction for an observer at the origin."),
        "contact_radius": VariableSpec("m", "contact radius",
                                       "Smallest distance of the ray from the planet's centre; "
                                       "for rays hitting the ground the virtual periapsis of "
                                       "the ray continued through a planet of constant index."),
        "contact_altitude": VariableSpec("m", "contact altitude",
                                         "contact_radius minus the planet radius; negative for "
                                         "rays blocked by the planet."),
    }


def deviation_table(
    atm,
    n_altitude: int = 512,
    n_angle: int = 256,
    *,
    parametrisation: str = "schneegans2025",
    method: str = "bouguer",
    n_nodes: int | None = None,
    step_m: float = DEFAULT_STEP_M,
    max_dh_m: float = DEFAULT_MAX_DH_M,
    dtype: torch.dtype = torch.float64,
    chunk_size: int = 16384,
    progress: bool = True,
):
    r"""Ray deviation and contact radius over ray origins and directions (Fig. 6, ref. 3).

    Parameters
    ----------
    atm : Atmosphere or compatible
        Needs ``planet_radius_m``, ``top_altitude_m`` and ``refractivity``.
    n_altitude, n_angle : int
        Samples of :math:`x_r` and :math:`x_\mu` (Schneegans et al. used 512 × 256).
    parametrisation : {"schneegans2025"}
        Texture coordinates of eq. 2 of ref. 3 (Bruneton's transmittance texture without
        the half-texel offsets): grid points at ``linspace(0, 1, n)``.
    method : {"bouguer", "rk4"}
        Ray-path algorithm (``"rk4"``: Schneegans' ray marching, ``step_m`` = 10 km).
    n_nodes : int, optional
        Gauss–Legendre nodes per panel of the Bouguer integrals (default
        :data:`TABLE_NODES`, or :data:`TABLE_PANEL_NODES` when the refractivity profile
        has breakpoints, e.g. the U.S. Standard Atmosphere 1976 of ``Atmosphere.earth()``).
    step_m, max_dh_m
        Resolution, see :func:`refraction_angle`.
    dtype : torch.dtype
        Computation dtype.
    chunk_size : int
        Rays per batch (memory bound).
    progress : bool
        Show a tqdm progress bar (only on a terminal).

    Returns
    -------
    xarray.Dataset
        Dimensions ``x_r`` (n_altitude) and ``x_mu`` (n_angle); variables ``deviation``
        [degree], ``contact_radius`` and ``contact_altitude`` [m] (x_r, x_mu), coordinates
        ``altitude`` (x_r) [m] and ``view_zenith_angle`` (x_r, x_mu) [degree].

    Notes
    -----
    Every ray starts inside the atmosphere and is followed to where it leaves it; rays
    that hit the ground continue through a planet of constant refractive index (ref. 3),
    so the table is smooth and the sign of ``contact_altitude`` tells which rays the
    planet blocks. Look values up with :class:`DeviationTable` or
    :func:`lookup_deviation`.

    Examples
    --------
    >>> import torch
    >>> class Air:
    ...     planet_radius_m, top_altitude_m, top_radius_m = 6.371e6, 1e5, 6.471e6
    ...     def refractivity(self, altitude_m, wavelength_nm=None):
    ...         return 2.77e-4 * torch.exp(-altitude_m / 8000.0)
    >>> ds = deviation_table(Air(), 8, 4, progress=False)
    >>> ds.deviation.dims
    ('x_r', 'x_mu')
    """
    from skytorch.dataset import build_dataset, coordinate, variable

    check_choice("parametrisation", parametrisation, TABLE_PARAMETRISATIONS)
    _check_atmosphere(atm)
    if _batch_shape(atm) != ():
        raise ValueError("deviation tables need an atmosphere with scalar parameters; got "
                         f"batch shape {_batch_shape(atm)} (build one table per member)")
    if n_nodes is None:
        n_nodes = (TABLE_NODES if _Geometry(atm, dtype).breakpoints is None
                   else TABLE_PANEL_NODES)
    method, checked_nodes = _check_method(method, n_nodes)
    n_altitude = check_int("n_altitude", n_altitude, low=2)
    n_angle = check_int("n_angle", n_angle, low=2)
    chunk_size = check_int("chunk_size", chunk_size, low=1)
    radius = float(atm.planet_radius_m)
    top_radius = radius + float(atm.top_altitude_m)
    x_r = torch.linspace(0.0, 1.0, n_altitude, dtype=dtype)
    x_mu = torch.linspace(0.0, 1.0, n_angle, dtype=dtype)
    altitude, mu = texture_rays(x_r[:, None], x_mu[None, :], radius, top_radius)
    altitude = altitude.expand(n_altitude, n_angle)
    elevation = torch.asin(mu)
    deviation = torch.empty_like(mu)
    contact = torch.empty_like(mu)
    flat_h, flat_e = altitude.reshape(-1), elevation.reshape(-1)
    flat_dev, flat_contact = deviation.view(-1), contact.view(-1)
    starts = range(0, flat_h.numel(), chunk_size)
    from tqdm.auto import tqdm

    bar = tqdm(starts, desc="deviation table", disable=not progress, leave=False)
    with torch.no_grad():
        for start in bar:
            part = slice(start, start + chunk_size)
            h, e = flat_h[part], flat_e[part]
            if method == "rk4":
                out = _trace_observer_rk4(atm, e, h, dtype, step_m, max_dh_m)
                flat_dev[part] = out["deviation_rad"]
                flat_contact[part] = out["contact_radius_m"] - radius
            else:
                bending, rays, t0 = _observer_bending(atm, e, h, dtype, checked_nodes)
                flat_dev[part] = bending
                flat_contact[part] = torch.where(t0 < 0.0, rays.h_p, h)
    logger.info("deviation table %d x %d (%s) computed", n_altitude, n_angle, method)
    specs = _table_specs()
    dims = ("x_r", "x_mu")
    data = {
        "deviation": variable(dims, torch.rad2deg(deviation), specs["deviation"]),
        "contact_radius": variable(dims, contact + radius, specs["contact_radius"]),
        "contact_altitude": variable(dims, contact, specs["contact_altitude"]),
    }
    coords = {
        "x_r": coordinate("x_r", x_r, specs["x_r"]),
        "x_mu": coordinate("x_mu", x_mu, specs["x_mu"]),
        "altitude": variable(("x_r",), altitude[:, 0], specs["altitude"]),
        "view_zenith_angle": variable(dims, torch.rad2deg(torch.acos(mu)),
                                      specs["view_zenith_angle"]),
    }
    parameters = {"parametrisation": parametrisation, "method": method,
                  "n_nodes": n_nodes if method == "bouguer" else None,
                  "step_m": step_m if method == "rk4" else None,
                  "max_dh_m": max_dh_m if method == "rk4" else None,
                  "planet_radius_m": radius, "top_altitude_m": float(atm.top_altitude_m)}
    if hasattr(atm, "parameters_dict"):
        parameters["atmosphere"] = atm.parameters_dict()
    return build_dataset(
        data, coords, title="Ray deviation and contact radius of refracted rays",
        references=[
            "Schneegans, S. et al. 2025, Physically Based Real-Time Rendering of Eclipses, "
            "Computer Graphics Forum, doi:10.1111/cgf.70220",
            "Auer, L. H. & Standish, E. M. 2000, Astron. J. 119, 2472, doi:10.1086/301325",
        ],
        parameters=parameters)


class DeviationTable(torch.nn.Module):
    """Batched bilinear look-up in a :func:`deviation_table` (layer 2 of the design).

    Parameters
    ----------
    dataset : xarray.Dataset
        Output of :func:`deviation_table`.

    Examples
    --------
    >>> import torch
    >>> class Air:
    ...     planet_radius_m, top_altitude_m, top_radius_m = 6.371e6, 1e5, 6.471e6
    ...     def refractivity(self, altitude_m, wavelength_nm=None):
    ...         return 2.77e-4 * torch.exp(-altitude_m / 8000.0)
    >>> table = DeviationTable(deviation_table(Air(), 16, 16, progress=False))
    >>> out = table(torch.tensor([0.0]), torch.tensor([0.5]))
    >>> sorted(out)
    ['contact_altitude_m', 'deviation_rad', 'hits_ground']
    """

    def __init__(self, dataset):
        super().__init__()
        import xarray as xr

        if not isinstance(dataset, xr.Dataset) or "deviation" not in dataset:
            raise TypeError("dataset must be an xarray.Dataset from deviation_table; got "
                            f"{type(dataset).__name__}")
        self.planet_radius_m = float(dataset.attrs["parameter_planet_radius_m"])
        self.top_altitude_m = float(dataset.attrs["parameter_top_altitude_m"])
        self.register_buffer("deviation_rad", torch.deg2rad(
            torch.as_tensor(dataset["deviation"].values, dtype=torch.float64)))
        self.register_buffer("contact_altitude_m", torch.as_tensor(
            dataset["contact_altitude"].values, dtype=torch.float64))

    def forward(self, altitude_m, zenith_rad) -> dict[str, torch.Tensor]:
        """Deviation [rad], contact altitude [m] and the ground-hit flag (...).

        Parameters
        ----------
        altitude_m : Tensor (...)
            Ray origin altitude, in [0, top] [m].
        zenith_rad : Tensor (...)
            Ray zenith angle at the origin [rad]; rays below the geometric horizon (outside
            the table) get the values of the ray tangent to the ground and
            ``hits_ground`` True.
        """
        dtype = common_dtype(altitude_m, zenith_rad)
        top = self.top_altitude_m
        height = check_range("altitude_m", altitude_m, 0.0, top, unit=" m", dtype=dtype)
        zenith = check_range("zenith_rad", zenith_rad, 0.0, math.pi, unit=" rad", dtype=dtype)
        try:
            broadcast_shape(height.shape, zenith.shape)
        except ValueError:
            raise ValueError(f"shapes do not broadcast: altitude_m {tuple(height.shape)}, "
                             f"zenith_rad {tuple(zenith.shape)}") from None
        height, zenith = torch.broadcast_tensors(height, zenith)
        x_r, x_mu = texture_coordinates(height, torch.cos(zenith), self.planet_radius_m,
                                            self.planet_radius_m + top)
        below = x_mu > 1.0
        deviation = _bilinear(self.deviation_rad.to(dtype), x_r, x_mu)
        contact = _bilinear(self.contact_altitude_m.to(dtype), x_r, x_mu)
        return {"deviation_rad": deviation, "contact_altitude_m": contact,
                "hits_ground": below | (contact < 0.0)}


def _bilinear(grid: torch.Tensor, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    """Bilinear interpolation of ``grid`` (n_x, n_y) sampled at linspace(0, 1) (clamped)."""
    n_x, n_y = grid.shape
    fx = torch.clamp(x, 0.0, 1.0) * (n_x - 1)
    fy = torch.clamp(y, 0.0, 1.0) * (n_y - 1)
    ix = torch.clamp(fx.detach().floor().long(), 0, n_x - 2)
    iy = torch.clamp(fy.detach().floor().long(), 0, n_y - 2)
    wx, wy = fx - ix, fy - iy
    g00, g01 = grid[ix, iy], grid[ix, iy + 1]
    g10, g11 = grid[ix + 1, iy], grid[ix + 1, iy + 1]
    return (g00 * (1 - wx) * (1 - wy) + g01 * (1 - wx) * wy + g10 * wx * (1 - wy)
            + g11 * wx * wy)


def lookup_deviation(table, altitude_m, zenith_rad) -> dict[str, torch.Tensor]:
    """Look rays up in a deviation table (Dataset or :class:`DeviationTable`).

    Parameters
    ----------
    table : xarray.Dataset or DeviationTable
        From :func:`deviation_table`.
    altitude_m, zenith_rad : Tensor (...)
        Ray origins and zenith angles [m], [rad].

    Returns
    -------
    dict of Tensor (...)
        ``deviation_rad``, ``contact_altitude_m``, ``hits_ground``.
    """
    if not isinstance(table, DeviationTable):
        table = DeviationTable(table)
    return table(altitude_m, zenith_rad)
