r"""Sunlight scattered more than once by the occluder's atmosphere into its shadow.

:mod:`skytorch.eclipse.shadow_scattering` adds the light scattered once by the atmosphere
ring towards a point ``P`` in the shadow. This module adds the orders >= 2: the radiance
of every line of sight from ``P`` through the ring is the final gather
(:func:`skytorch.atmosphere.final_gather.higher_orders_gathered`) of the radiance field
of the occluder's multiple-scattering tables
(:func:`skytorch.atmosphere.multiple_scattering.precompute_scattering`) along that line,
and the ring is integrated over its solid angle as for the single scattering.

Geometry
--------
With ``c`` the direction from ``P`` to the occluder's centre (distance ``L``) and the Sun
at angle ``sigma`` from ``c`` on ``P``'s sky, a line of sight at angle ``theta`` from ``c``
(impact parameter ``b = L sin(theta)``) and ring azimuth ``psi`` (0 towards the Sun) enters
the atmosphere at the point ``E`` of the top sphere nearest ``P``. The line is handed to the
gather as seen by an observer at ``E`` (altitude: the top of the atmosphere) looking along
it, with the Sun's direction in ``E``'s local frame (the Sun's direction is taken as seen
from ``P``: the ring is ~``L`` closer to the Sun, which changes the direction by
``L / D`` ≈ 0.15 deg for the Moon, against the ~1 deg scale of the light's change across the
limb, and its irradiance by ``k^2``, applied as for the single scattering). Unlike the
single-scattering kernel, the gather follows the exact three-dimensional geometry of every
line (no in-plane reduction of the Sun's angle).

The illuminance relative to the unobstructed Sun is

.. math::

    \frac{E_{ms}}{E_\odot} = k^{-2}\int_{b_{low}}^{r_{top}}\int_0^{2\pi}
        \frac{L_{2..N}(b,\psi)}{E_\odot}\,\frac{b\,db\,d\psi}{L\sqrt{L^2 - b^2}}

by Gauss-Legendre in ``sqrt((b - b_low) / (r_top - b_low))`` (dense near the ground, where
the limb is brightest and refracted rays come from) and in ``psi`` over ``[0, pi]``
(mirror symmetry of the ring about the plane of ``P``, the centre and the Sun).

Approximations: straight lines of sight and straight sunlight (no refraction; the
refracted direct light is :class:`~skytorch.eclipse.shadow.Shadow`'s), those of the
tables and of the gather (docs/multiple_scattering_validation.md), the tables' field zero
where the Sun is more than 18 deg below the local horizon, a point Sun. Lines of sight
below ``lowest_altitude_m`` (a closed cloud deck) are left out, as in the single
scattering.

Cost: ``n_impact * n_azimuth`` lines of sight per point, each ``n_view * 2 n_mu * n_phi``
table look-ups (about 20 ms at the gather's defaults): seconds per point in the shadow.
"""

from __future__ import annotations

import math

import torch

from skytorch._quadrature import unit_nodes
from skytorch._validate import check_int, check_positive, check_range
from skytorch.atmosphere.final_gather import LINES_PER_CALL, higher_orders_gathered

__all__ = ["limb_line_geometry", "multiple_scattered_illuminance",
           "multiple_scattered_radiance", "ring_integral"]


def limb_line_geometry(centre_distance_m, separation_rad, impact_radius_m, azimuth_rad,
                       top_radius_m: float):
    """Local geometry of ring lines of sight where they enter the atmosphere.

    Parameters
    ----------
    centre_distance_m, separation_rad : Tensor (...)
        ``L`` [m] and ``sigma`` [rad] of the point in the shadow (module docstring).
    impact_radius_m, azimuth_rad : Tensor (...)
        Impact parameter ``b`` [m] (below ``top_radius_m``) and ring azimuth ``psi``
        (0 towards the Sun) [rad] of the lines of sight; broadcast with the above.
    top_radius_m : float
        Radius of the top of the atmosphere [m].

    Returns
    -------
    view_zenith, sun_zenith, sun_azimuth : Tensor (...)
        At the entry point, in its local (north, east, up) frame with north in the plane
        of the line of sight (so the line's azimuth is 0) [rad].
    """
    big_l, sigma, b, psi = torch.broadcast_tensors(
        torch.as_tensor(centre_distance_m), torch.as_tensor(separation_rad),
        torch.as_tensor(impact_radius_m), torch.as_tensor(azimuth_rad))
    sin_t = b / big_l
    cos_t = torch.sqrt((1.0 - sin_t) * (1.0 + sin_t))
    zero = torch.zeros_like(big_l)
    view = torch.stack([sin_t * torch.cos(psi), sin_t * torch.sin(psi), cos_t], -1)
    point = torch.stack([zero, zero, -big_l], -1)  # P, the occluder's centre at the origin
    half_chord = torch.sqrt((top_radius_m - b) * (top_radius_m + b))
    up = (point + (big_l * cos_t - half_chord)[..., None] * view) / top_radius_m
    cos_view = (view * up).sum(-1)
    north = view - cos_view[..., None] * up
    north = north / torch.linalg.vector_norm(north, dim=-1, keepdim=True)
    east = torch.linalg.cross(up, north, dim=-1)
    sun = torch.stack([torch.sin(sigma), zero, torch.cos(sigma)], -1)
    view_zenith = torch.acos(torch.clamp(cos_view, -1.0, 1.0))
    sun_zenith = torch.acos(torch.clamp((sun * up).sum(-1), -1.0, 1.0))
    sun_azimuth = torch.atan2((sun * east).sum(-1), (sun * north).sum(-1))
    return view_zenith, sun_zenith, sun_azimuth


def multiple_scattered_illuminance(tables, atmosphere, centre_distance_m, separation_rad,
                                   deviation_scale, *, lowest_altitude_m: float = 0.0,
                                   ray_weight=None, scattering_orders="converged",
                                   n_impact: int = 16,
                                   n_azimuth: int = 8, n_view: int = 32, n_mu: int = 16,
                                   n_phi: int = 64) -> torch.Tensor:
    r"""Illuminance of the orders >= 2 in the shadow, relative to the unobstructed Sun.

    Parameters
    ----------
    tables : ScatteringTables
        Of ``atmosphere`` (scalar parameters) at the wavelengths of the result.
    atmosphere : Atmosphere
        The occluder's atmosphere.
    centre_distance_m, separation_rad, deviation_scale : Tensor (...)
        ``L`` [m], ``sigma`` [rad] and ``k = D / |S - P|`` [1] of the points
        (:mod:`skytorch.eclipse.shadow_scattering`).
    lowest_altitude_m : float
        Lowest tangent altitude of the lines of sight (a closed cloud deck) [m].
    ray_weight : callable, optional
        Weight of a line of sight by its tangent altitude [m] -> [1] (terrain, partial
        clouds), as in the single scattering.
    scattering_orders : int or "converged"
        N >= 2: the orders 2..N (:func:`~skytorch.atmosphere.final_gather.
        higher_orders_gathered`).
    n_impact, n_azimuth : int
        Gauss-Legendre nodes over the ring's impact parameter and over ``psi`` in
        ``[0, pi]``, >= 1.
    n_view, n_mu, n_phi : int
        The gather's quadrature along each line of sight.

    Returns
    -------
    Tensor (..., wavelength)
        :math:`E_{ms} / E_\odot` [1].
    """
    dtype = tables.wavelength_nm.dtype
    altitude = torch.tensor(tables.top_altitude_m, dtype=dtype)

    def gathered(view_zenith, sun_zenith, sun_azimuth):
        return higher_orders_gathered(
            tables, atmosphere, altitude, view_zenith, torch.zeros_like(view_zenith),
            sun_zenith, sun_azimuth, scattering_orders=scattering_orders, n_view=n_view,
            n_mu=n_mu, n_phi=n_phi)

    return ring_integral(gathered, tables.planet_radius_m, tables.top_altitude_m,
                         centre_distance_m, separation_rad, deviation_scale,
                         lowest_altitude_m=lowest_altitude_m, ray_weight=ray_weight,
                         n_impact=n_impact, n_azimuth=n_azimuth, dtype=dtype)


def multiple_scattered_radiance(tables, atmosphere, centre_distance_m, separation_rad,
                                deviation_scale, impact_radius_m, azimuth_rad, *,
                                ray_weight=None, scattering_orders="converged",
                                n_view: int = 32, n_mu: int = 16, n_phi: int = 64
                                ) -> torch.Tensor:
    r"""Radiance of the orders >= 2 of given ring lines of sight, per unit solar irradiance.

    The image of the ring's multiply scattered light seen from points in the shadow:
    :math:`k^{-2} w(b) L_{2..N}(b, \psi) / E_\odot` [sr^-1] (module docstring; ``w`` the
    ray weight of terrain and clouds); its integral over the ring's solid angle is
    :func:`multiple_scattered_illuminance`.

    Parameters
    ----------
    tables, atmosphere, scattering_orders, n_view, n_mu, n_phi
        As :func:`multiple_scattered_illuminance`.
    centre_distance_m, separation_rad, deviation_scale : Tensor (...)
        ``L`` [m], ``sigma`` [rad], ``k`` [1] of the points.
    impact_radius_m : Tensor (n_impact,)
        Impact parameters ``b`` of the lines of sight [m], above the ground and below the
        top of the atmosphere.
    azimuth_rad : Tensor (n_azimuth,)
        Ring azimuths ``psi`` (0 towards the Sun) [rad].
    ray_weight : callable, optional
        Weight of a line of sight by its tangent altitude [m] -> [1].

    Returns
    -------
    Tensor (..., n_impact, n_azimuth, wavelength)
    """
    dtype = tables.wavelength_nm.dtype
    planet, top = tables.planet_radius_m, tables.planet_radius_m + tables.top_altitude_m
    shape, flat = _points(centre_distance_m, separation_rad, deviation_scale, top, dtype)
    b = check_range("impact_radius_m", impact_radius_m, planet, top, unit=" m",
                    dtype=dtype).reshape(-1)
    psi = check_range("azimuth_rad", azimuth_rad, dtype=dtype).reshape(-1)
    view_zenith, sun_zenith, sun_azimuth = limb_line_geometry(
        flat[0], flat[1], b[:, None], psi[None, :], top)  # (p, n_b, n_psi)
    altitude = torch.tensor(tables.top_altitude_m, dtype=dtype)
    radiance = higher_orders_gathered(
        tables, atmosphere, altitude, view_zenith, torch.zeros_like(view_zenith), sun_zenith,
        sun_azimuth, scattering_orders=scattering_orders, n_view=n_view, n_mu=n_mu,
        n_phi=n_phi)  # (p, n_b, n_psi, wl)
    weight = 1.0 / (flat[2] * flat[2])
    if ray_weight is not None:
        weight = weight * ray_weight(b - planet)[:, None]
    radiance = radiance * weight[..., None]
    return radiance.reshape(*shape, *radiance.shape[1:])


def ring_integral(line_radiance, planet_radius_m: float, top_altitude_m: float,
                  centre_distance_m, separation_rad, deviation_scale, *,
                  lowest_altitude_m: float = 0.0, ray_weight=None, n_impact: int = 16,
                  n_azimuth: int = 8, dtype=torch.float64) -> torch.Tensor:
    r"""Illuminance at points in the shadow from a radiance of the ring's lines of sight.

    :math:`k^{-2}\iint L(b, \psi)\,b\,db\,d\psi / (L\sqrt{L^2 - b^2})` (module
    docstring) with ``line_radiance(view_zenith, sun_zenith, sun_azimuth)`` giving the
    radiance per unit solar irradiance (n, wavelength) [sr^-1] of lines of sight given by
    their geometry at the entry point (:func:`limb_line_geometry`; the observer at the top
    of the atmosphere, view azimuth 0), called with at most :data:`LINES_PER_CALL` lines.

    Returns
    -------
    Tensor (..., wavelength)
        Illuminance over the unobstructed solar irradiance [1].
    """
    n_impact = check_int("n_impact", n_impact, 1)
    n_azimuth = check_int("n_azimuth", n_azimuth, 1)
    planet, top = planet_radius_m, planet_radius_m + top_altitude_m
    lowest = float(check_range("lowest_altitude_m", lowest_altitude_m, 0.0, top_altitude_m,
                               unit=" m", dtype=torch.float64))
    shape, flat = _points(centre_distance_m, separation_rad, deviation_scale, top, dtype)
    x, w = unit_nodes(n_impact, dtype)  # on [0, 1]
    low = planet + lowest
    b = low + (top - low) * x * x
    weight_b = 2.0 * (top - low) * x * w  # db
    if ray_weight is not None:
        weight_b = weight_b * ray_weight(b - planet)
    y, v = unit_nodes(n_azimuth, dtype)
    psi, weight_psi = math.pi * y, 2.0 * math.pi * v  # both halves of the ring
    view_zenith, sun_zenith, sun_azimuth = limb_line_geometry(
        flat[0], flat[1], b[:, None], psi[None, :], top)  # (p, n_b, n_psi)
    lines = [t.reshape(-1) for t in (view_zenith, sun_zenith, sun_azimuth)]
    parts = [line_radiance(*(t[first:first + LINES_PER_CALL] for t in lines))
             for first in range(0, lines[0].shape[0], LINES_PER_CALL)]
    radiance = torch.cat(parts).reshape(*view_zenith.shape, -1)  # (p, n_b, n_psi, wl)
    sin_t = b[:, None] / flat[0]  # (p, n_b, 1)
    solid = sin_t / (flat[0] * torch.sqrt((1.0 - sin_t) * (1.0 + sin_t))) * weight_b[:, None]
    weight = solid * weight_psi / (flat[2] * flat[2])  # (p, n_b, n_psi)
    illuminance = (radiance * weight[..., None]).sum((1, 2))
    return illuminance.reshape(*shape, illuminance.shape[-1])


def _points(centre_distance_m, separation_rad, deviation_scale, top_radius_m: float, dtype):
    """Check points in the shadow; return their shape and ``L``, ``sigma``, ``k`` (p, 1, 1)."""
    big_l = check_range("centre_distance_m", centre_distance_m, top_radius_m, unit=" m",
                        dtype=dtype)
    sigma = check_range("separation_rad", separation_rad, 0.0, math.pi, dtype=dtype)
    scale = check_positive("deviation_scale", deviation_scale, dtype=dtype)
    big_l, sigma, scale = torch.broadcast_tensors(big_l, sigma, scale)
    return big_l.shape, [t.reshape(-1, 1, 1) for t in (big_l, sigma, scale)]
