r"""The independent ray tracer: RK4 integration of the eikonal equation.

:math:`\mathrm{d}(n\,\hat{\mathbf{d}})/\mathrm{d}s = \nabla n` is integrated in the plane
of the ray with the classical Runge–Kutta scheme (Seron et al. 2004, van der Werf 2008;
10 km steps as in Schneegans et al. 2025), the step also limited so that the altitude
changes by at most ``max_dh_m``; steps end just past the kinks of the profile, rays land
on the ground and cross the planet on a straight chord (the ``"rk4"`` method of
:mod:`skytorch.atmosphere.refraction`). It shares no formula with the Bouguer integrals
(:mod:`skytorch.atmosphere.bouguer`) and serves as their independent check.

References
----------
1. Seron, F. J., Gutierrez, D., Gutierrez, G. & Cerezo, E. 2004, "Visualizing sunsets
   through inhomogeneous atmospheres", Proc. Computer Graphics International, 349,
   doi:10.1109/CGI.2004.1309232.
2. van der Werf, S. Y. 2008, "Comment on 'Improved ray tracing air mass numbers model'",
   Appl. Opt. 47, 153, doi:10.1364/AO.47.000153.
3. Schneegans, S., Gilg, J., Ahlers, V., Zachmann, G. & Gerndt, A. 2025, "Physically Based
   Real-Time Rendering of Eclipses", Computer Graphics Forum, doi:10.1111/cgf.70220.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere.ray_geometry import ExponentialAir as Air
>>> from skytorch.atmosphere.ray_tracer import _trace_observer_rk4
>>> zero = torch.zeros(1, dtype=torch.float64)
>>> out = _trace_observer_rk4(Air(), zero, zero, torch.float64, 10e3, 1e3)
>>> round(float(out["deviation_rad"][0]) * 180 / torch.pi * 60)  # the Bouguer value
37
"""

from __future__ import annotations

import math

import torch

from skytorch._validate import check_range
from skytorch.atmosphere.ray_geometry import (
    _check_elevation,
    _Geometry,
    _map_parameters,
    _per_ray,
    _ray_shape,
)

__all__ = ["DEFAULT_MAX_DH_M", "DEFAULT_STEP_M"]

DEFAULT_STEP_M = 10e3  #: RK4 step along the ray (Schneegans et al. 2025, Seron et al. 2004)
DEFAULT_MAX_DH_M = 1e3  #: RK4 step limit: altitude change per step [m]
#: RK4 steps that reach a kink of the refractivity profile end this far past it [m]
_KINK_OVERSHOOT_M = 1e-3


def _rk4_resolution(step_m, max_dh_m) -> tuple[float, float]:
    """Return checked RK4 step along the ray and altitude-change limit per step [m]."""
    step_m = check_range("step_m", step_m, low=0.0, low_inclusive=False, unit=" m")
    max_dh_m = check_range("max_dh_m", max_dh_m, low=0.0, low_inclusive=False, unit=" m")
    return float(step_m), float(max_dh_m)



def _rk4_trace(geometry, position, direction, coefficient, step_m, max_dh_m, max_length,  # noqa: C901 (one RK4 loop with its stops)
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
    """Path length [m] to the first crossing of any sphere r = ``radii`` (K,).

    Only crossings farther than :data:`_KINK_OVERSHOOT_M` count; inf when none; shape (N,).

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
        # rays that never enter the air: a zero column that keeps the inputs' graph (a
        # zero gradient, as the Bouguer path gives), not a constant
        tau = tau + 0.0 * (r0 + e)[:, None]
        return {"optical_depth": tau.reshape(shape + (tau.shape[-1],))}
    return {"deviation_rad": _clockwise_angle(direction, final).reshape(shape),
            "contact_radius_m": r_min.reshape(shape)}


def _trace_grazing_rk4(atm, beta_geo, coefficient_of, dtype, step_m, max_dh_m):
    """RK4 rays from space through the limb.

    ``optical_depth`` is the path integral of ``coefficient_of(atm)`` (None: none).
    """
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
    extinction = coefficient_of
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
