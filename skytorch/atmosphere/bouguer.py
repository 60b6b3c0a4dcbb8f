r"""The exact Bouguer integrals of a ray in a spherically symmetric atmosphere.

Along a ray the invariant :math:`b = n(r)\,r\sin z` is constant, so the bending and the
path length are one-dimensional integrals over the radius; the substitution
:math:`r = r_p + L t^2` removes their :math:`(r - r_p)^{-1/2}` singularity at the
periapsis and Gauss–Legendre quadrature (split into panels at the profile's kinks)
integrates them (the ``"bouguer"`` method of :mod:`skytorch.atmosphere.refraction`, whose
docstring gives the formulas; Auer & Standish 2000, Born & Wolf 1999 §3.2). :class:`_Rays`
holds the rays of one invariant; the functions below follow observer rays to space and
rays from space through the limb.

References
----------
1. Auer, L. H. & Standish, E. M. 2000, "Astronomical refraction: computational method for
   all zenith angles", Astron. J. 119, 2472, doi:10.1086/301325.
2. Born, M. & Wolf, E. 1999, *Principles of Optics*, 7th ed., Cambridge University Press,
   §3.2 (Bouguer's formula), doi:10.1017/CBO9781139644181.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere.ray_geometry import ExponentialAir as Air
>>> from skytorch.atmosphere.bouguer import _observer_bending
>>> zero = torch.zeros(1, dtype=torch.float64)
>>> bending, rays, t0 = _observer_bending(Air(), zero, zero, torch.float64, 64)
>>> round(float(bending[0]) * 180 / torch.pi * 60)  # horizon refraction [arcmin]
37
"""

from __future__ import annotations

import torch

from skytorch._quadrature import unit_nodes
from skytorch._validate import check_range
from skytorch.atmosphere.ray_geometry import (
    _check_elevation,
    _Geometry,
    _map_parameters,
    _per_ray,
    _ray_shape,
)

__all__ = ["DEFAULT_NODES", "TABLE_NODES", "TABLE_PANEL_NODES"]

DEFAULT_NODES = 64  #: Gauss–Legendre nodes of the Bouguer integrals
TABLE_NODES = 32  #: Gauss–Legendre nodes for the deviation table (0.02" from converged)
#: ... per panel when the profile has breakpoints (US 1976: 12 panels; 1e-4" from 32)
TABLE_PANEL_NODES = 16


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
        """Return m = (u(h) - b) / (h - h_p) without cancellation, for h >= h_p."""
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
        x, w = unit_nodes(n_nodes, geometry.dtype, ndim)
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


def _observer_rays(atm, apparent_altitude_rad, altitude_m, dtype, levels=()):
    """Geometry, rays and the signed start parameter t_0 for observer rays.

    ``levels``: further altitudes where the quadrature is split [m].
    """
    elevation = _check_elevation("apparent_altitude_rad", apparent_altitude_rad, dtype)
    height = check_range("altitude_m", altitude_m, low=0.0, unit=" m", dtype=dtype)
    # the rays carry the atmosphere's batch dims: quadrature nodes lead, so every ray
    # tensor must hold them (a scalar ray against batched parameters is expanded)
    shape = _ray_shape(atm, apparent_altitude_rad=elevation, altitude_m=height)
    elevation, height = elevation.expand(shape), height.expand(shape)
    geometry = _Geometry(atm, dtype)
    if levels:
        geometry = geometry.with_levels(levels)
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


def _observer_bending(atm, apparent_altitude_rad, altitude_m, dtype, n_nodes):
    """Bouguer bending from an observer to space, with the rays and their t0."""
    geometry, rays, elevation, _, t0 = _observer_rays(atm, apparent_altitude_rad, altitude_m,
                                                      dtype)
    # The integrands are even in t, so a ray that first descends is the single interval
    # [t0, 1] through the periapsis t = 0 -- or [t_g, 1] + [t_g, -t0] when it hits the
    # ground (t_g > 0) or when the quadrature is split at the profile's kinks.
    return _bending_from(geometry, rays, t0, n_nodes), rays, t0


def _bending_from(geometry, rays, t0, n_nodes):
    """Bending [rad] of rays from their start parameter ``t0`` to space."""
    down = t0 < 0.0
    split = down & (rays.hits | (geometry.breakpoints is not None))
    start = torch.where(split, rays.t_ground, t0)
    bending = rays.integrate(start, torch.ones_like(start), n_nodes)["bending"]
    extra = _integrate_where(rays, split, rays.t_ground, torch.maximum(-t0, rays.t_ground),
                             n_nodes)
    if extra is not None:
        bending = bending + extra["bending"]
    return torch.where(rays.misses, torch.zeros_like(bending), bending)


def _grazing_observer_bending(atm, height, dtype, n_nodes):
    r"""Bending [rad] of the ray from observers at ``height`` that grazes the ground.

    The periapsis of that ray is the ground itself, so the rays are built with
    :math:`h_p = 0` and :math:`t_0 = -\sqrt{h/L}` exactly. Through the apparent dip,
    Bouguer's invariant and a solved periapsis, float32 would place the periapsis a few
    tenths of a millimetre off, where the bending of rays that hit the ground varies like
    the square root of the depth (1″ at 0.5 mm for an observer at 10 km).
    """
    shape = _ray_shape(atm, altitude_m=height)
    height = height.expand(shape)
    geometry = _Geometry(atm, dtype)
    rays = _Rays(geometry, torch.zeros_like(height))
    t0 = -torch.sqrt(torch.clamp(height, max=geometry.top) / rays.length)
    return _bending_from(geometry, rays, t0, n_nodes)


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


def _observer_optical_depth(atm, elevation, height, dtype, n_nodes, coefficient_of,
                            levels=()):
    """Optical depth (..., n) from observers to space along the bent rays.

    To the ground for rays that hit it; ``coefficient_of(atm)`` gives the extinction (or the
    species' densities) as a function of altitude (see :func:`_integrate_where`); the quadrature is
    also split at ``levels`` [m].
    """
    coefficient = coefficient_of(atm)
    geometry, rays, elevation, _, t0 = _observer_rays(atm, elevation, height, dtype, levels)
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
    return tau


def _trace_grazing_bouguer(atm, coefficient_of, dtype, n_nodes, *, impact_altitude_m,
                           periapsis_altitude_m, levels=()):
    """Rays from space through the limb.

    The outputs of :func:`skytorch.atmosphere.refraction.trace_grazing_rays`: one of
    ``impact_altitude_m`` and ``periapsis_altitude_m`` is given (the other None); ``optical_depth``
    is the path integral of ``coefficient_of(atm)`` (None: none), its quadrature also split at
    ``levels`` [m] (the bending keeps the refractivity's panels).
    """
    radius = float(atm.planet_radius_m)
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
    extinction = None if coefficient_of is None else coefficient_of(atm)
    column_geometry = geometry.with_levels(levels) if levels else geometry
    same_panels = (column_geometry.breakpoints is None) == (geometry.breakpoints is None) and (
        geometry.breakpoints is None
        or torch.equal(column_geometry.breakpoints, geometry.breakpoints))
    if extinction is None or same_panels:
        result = rays.integrate(rays.t_ground, torch.ones_like(h_p), n_nodes,
                                coefficient=extinction)
    else:  # the columns on their own panels
        result = rays.integrate(rays.t_ground, torch.ones_like(h_p), n_nodes)
        column_rays = _Rays(column_geometry, h_p)
        result.update(column_rays.integrate(column_rays.t_ground, torch.ones_like(h_p),
                                            n_nodes, bending=False, coefficient=extinction))
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
