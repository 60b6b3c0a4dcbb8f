"""Ray–sphere geometry in a spherically symmetric atmosphere, stable near the horizon.

A ray starts at radius ``r`` from the planet's centre with direction cosine ``mu`` to the
local zenith. Along the ray, the signed distance from the point of closest approach is
:math:`t`, with :math:`r(t)^2 = p^2 + t^2`, impact parameter
:math:`p^2 = r^2 (1 - \\mu^2)` and observer at :math:`t_0 = r\\mu`.

The textbook forms of the intersection distances (ref. 1, functions
``DistanceToTopAtmosphereBoundary`` and ``DistanceToBottomAtmosphereBoundary``) subtract
nearly equal numbers for rays close to the horizon or starting on a boundary. Here the
discriminants are written as :math:`r^2\\mu^2 + (R_t - r)(R_t + r)` and
:math:`r^2\\mu^2 - (r - R)(r + R)` (no cancellation of the large :math:`r^2` terms) and
the root that would cancel is taken from the product of the roots, :math:`d_1 d_2 = c`
(the "citardauq" form), so distances keep full relative precision in float32 for rays
tangent to the ground, grazing the top or starting exactly on a boundary.

References
----------
1. Bruneton, E. 2017, "Precomputed Atmospheric Scattering: a New Implementation",
   https://ebruneton.github.io/precomputed_atmospheric_scattering/ (functions.glsl).
2. Bruneton, E. & Neyret, F. 2008, "Precomputed Atmospheric Scattering",
   Computer Graphics Forum 27, 1079, doi:10.1111/j.1467-8659.2008.01245.x.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere.geometry import distance_to_top
>>> r = torch.tensor(6_371_000.0, dtype=torch.float64)
>>> float(distance_to_top(r, torch.tensor(1.0, dtype=torch.float64), r + 100e3))
100000.0
"""

from __future__ import annotations

import math

import torch

__all__ = [
    "distance_to_ground",
    "distance_to_top",
    "ray_hits_ground",
    "ray_segment",
    "safe_sqrt",
    "texture_coordinates",
    "texture_rays",
]


def safe_sqrt(x: torch.Tensor) -> torch.Tensor:
    """:math:`\\sqrt{\\max(x, 0)}` with a finite (zero) gradient where ``x <= 0``."""
    tiny = torch.finfo(x.dtype).tiny
    return torch.sqrt(torch.clamp(x, min=tiny)) * (x > 0)


def _discriminant_top(r, mu, top_radius):
    """:math:`r^2\\mu^2 + (R_t - r)(R_t + r) = R_t^2 - p^2`."""
    return (r * mu) ** 2 + (top_radius - r) * (top_radius + r)


def _discriminant_ground(r, mu, planet_radius):
    """:math:`r^2\\mu^2 - (r - R)(r + R) = R^2 - p^2`."""
    return (r * mu) ** 2 - (r - planet_radius) * (r + planet_radius)


def _safe_divide(numerator, denominator):
    """``numerator / denominator`` with 0 where the denominator is 0 (and finite grads)."""
    zero = denominator == 0
    return torch.where(zero, torch.zeros_like(numerator),
                       numerator / torch.where(zero, torch.ones_like(denominator), denominator))


def distance_to_top(r, mu, top_radius) -> torch.Tensor:
    """Distance along the ray to where it leaves the top of the atmosphere [m].

    Parameters
    ----------
    r : Tensor (...)
        Radius of the ray's origin [m], ``r <= top_radius``.
    mu : Tensor (...)
        Cosine of the ray's zenith angle [1].
    top_radius : float or Tensor (...)
        Radius of the top of the atmosphere [m].

    Returns
    -------
    Tensor (...)
        Distance :math:`d = -r\\mu + \\sqrt{r^2\\mu^2 + R_t^2 - r^2} \\ge 0` [m], computed as
        :math:`(R_t^2 - r^2)/(r\\mu + \\sqrt{\\cdot})` for upward rays.
    """
    disc = _discriminant_top(r, mu, top_radius)
    root = safe_sqrt(disc)
    c = (top_radius - r) * (top_radius + r)
    upward = _safe_divide(c, r * mu + root)
    downward = -r * mu + root
    return torch.clamp(torch.where(mu >= 0, upward, downward), min=0.0)


def distance_to_ground(r, mu, planet_radius) -> torch.Tensor:
    """Distance along the ray to the ground [m] (meaningful where :func:`ray_hits_ground`).

    Parameters
    ----------
    r : Tensor (...)
        Radius of the ray's origin [m], ``r >= planet_radius``.
    mu : Tensor (...)
        Cosine of the zenith angle [1].
    planet_radius : float or Tensor (...)
        Planet radius [m].

    Returns
    -------
    Tensor (...)
        :math:`d = -r\\mu - \\sqrt{r^2\\mu^2 - (r^2 - R^2)}`, computed as
        :math:`(r^2 - R^2)/(-r\\mu + \\sqrt{\\cdot})` [m]; for rays that miss the ground
        the distance to the point of closest approach's projection,
        :math:`(r^2 - R^2)/(-r\\mu)` clamped at 0 (as in ref. 1, never NaN).
    """
    disc = _discriminant_ground(r, mu, planet_radius)
    root = safe_sqrt(disc)
    c = (r - planet_radius) * (r + planet_radius)
    distance = _safe_divide(c, -r * mu + root)
    return torch.where(mu < 0, torch.clamp(distance, min=0.0), torch.zeros_like(distance))


def ray_hits_ground(r, mu, planet_radius) -> torch.Tensor:
    """Whether the ray from ``r`` with cosine ``mu`` meets the planet (bool, (...)).

    A ray tangent to the ground (discriminant exactly 0) counts as hitting it; a ray on
    the ground pointing horizontally does not, where "horizontally" allows for the
    rounding of cos(pi/2) (|mu| <= 8 eps, 5e-7 in float32).
    """
    mu = torch.as_tensor(mu)
    tolerance = 8.0 * torch.finfo(mu.dtype).eps if mu.is_floating_point() else 0.0
    return (mu < -tolerance) & (_discriminant_ground(r, mu, planet_radius) >= 0)


def ray_segment(r, mu, planet_radius, top_radius) -> dict[str, torch.Tensor]:
    """The part of a straight ray inside the atmosphere, in the :math:`t` parametrisation.

    Parameters
    ----------
    r : Tensor (...)
        Radius of the origin [m], ``>= planet_radius`` (may be above the top).
    mu : Tensor (...)
        Cosine of the zenith angle [1].
    planet_radius, top_radius : float or Tensor (...)
        Radii of the ground and of the top of the atmosphere [m].

    Returns
    -------
    dict of Tensor (...)
        ``t_start``, ``t_end`` [m]: signed positions (relative to the point of closest
        approach) where the ray enters (or starts) and leaves the atmosphere, with
        ``t_end >= t_start``; ``excess_sq`` :math:`= p^2 - R^2` [m^2] computed without
        cancellation; ``hits_ground`` (bool); ``length`` [m] = ``t_end - t_start``.

    Notes
    -----
    Altitude along the ray: :math:`h(t) = (p^2 - R^2 + t^2)/(\\sqrt{R^2 + p^2 - R^2 + t^2}
    + R)`. An origin above the top starts at :math:`t = -\\sqrt{R_t^2 - p^2}` if the ray
    descends into the atmosphere, otherwise the segment is empty.
    """
    hits = ray_hits_ground(r, mu, planet_radius)
    disc_ground = _discriminant_ground(r, mu, planet_radius)
    disc_top = _discriminant_top(r, mu, top_radius)
    excess_sq = -disc_ground  # p^2 - R^2
    t_top = safe_sqrt(disc_top)
    t_ground = -safe_sqrt(disc_ground)
    t_end = torch.where(hits, t_ground, t_top)
    t_obs = r * mu
    outside = r > top_radius
    enters = (mu < 0) & (disc_top > 0)
    t_start = torch.where(outside, torch.where(enters, -t_top, t_end), t_obs)
    t_start = torch.minimum(t_start, t_end)
    return {"t_start": t_start, "t_end": t_end, "excess_sq": excess_sq, "hits_ground": hits,
            "length": t_end - t_start}


def texture_rays(x_r, x_mu, planet_radius, top_radius) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Ray origin altitude and zenith cosine at texture coordinates (Bruneton 2017).

    Parameters
    ----------
    x_r, x_mu : Tensor (...)
        Texture coordinates in [0, 1] (broadcast): ``x_r`` the altitude coordinate,
        ``x_mu`` the direction coordinate (0: zenith, 1: the ray tangent to the ground).
    planet_radius, top_radius : float
        Radii of the ground and of the top of the atmosphere [m].

    Returns
    -------
    tuple of Tensor (...)
        Altitude of the ray origin [m] (computed as :math:`\rho^2/(r + R)`, without
        cancellation) and the cosine of the ray's zenith angle [1].

    Notes
    -----
    :math:`H = \sqrt{R_t^2 - R^2}`, :math:`\rho = x_r H`, :math:`r = \sqrt{\rho^2 + R^2}`,
    distance to the top :math:`d = d_{min} + x_\mu (d_{max} - d_{min})` with
    :math:`d_{min} = R_t - r`, :math:`d_{max} = \rho + H`, and
    :math:`\mu = (H^2 - \rho^2 - d^2)/(2 r d)` (1 where :math:`d = 0`): Bruneton's
    ``GetRMuFromTransmittanceTextureUv`` without the half-texel offsets, the
    parametrisation of Schneegans et al. 2025 (eq. 2) for their deviation table.

    Examples
    --------
    >>> import torch
    >>> h, mu = texture_rays(torch.tensor([0.0, 1.0]), torch.tensor([1.0, 0.0]), 6.371e6,
    ...                      6.471e6)
    >>> [round(float(v)) for v in h], [round(float(v), 6) for v in mu]
    ([0, 100000], [0.0, 1.0])
    """
    horizon = math.sqrt(top_radius**2 - planet_radius**2)
    rho = x_r * horizon
    r = torch.sqrt(rho * rho + planet_radius**2)
    d_min = top_radius - r
    d_max = rho + horizon
    d = d_min + x_mu * (d_max - d_min)
    safe_d = torch.where(d > 0.0, d, torch.ones_like(d))
    mu = torch.where(d > 0.0, (horizon**2 - rho * rho - d * d) / (2.0 * r * safe_d),
                     torch.ones_like(d))
    return rho * rho / (r + planet_radius), torch.clamp(mu, -1.0, 1.0)


def texture_coordinates(altitude_m, mu, planet_radius, top_radius
                        ) -> tuple[torch.Tensor, torch.Tensor]:
    """Inverse of :func:`texture_rays`: texture coordinates ``(x_r, x_mu)`` (...).

    Parameters
    ----------
    altitude_m : Tensor (...)
        Altitude of the ray origin, in [0, top] [m].
    mu : Tensor (...)
        Cosine of the ray's zenith angle [1].
    planet_radius, top_radius : float
        Radii of the ground and of the top of the atmosphere [m].

    Returns
    -------
    tuple of Tensor (...)
        ``x_r`` and ``x_mu``, in [0, 1] for rays that miss the ground; ``x_mu > 1`` below
        the geometric horizon (not clamped, so callers can tell).
    """
    horizon = math.sqrt(top_radius**2 - planet_radius**2)
    r = planet_radius + altitude_m
    rho = safe_sqrt(altitude_m * (r + planet_radius))
    d = distance_to_top(r, mu, top_radius)
    d_min = top_radius - r
    d_max = rho + horizon
    span = torch.clamp(d_max - d_min, min=1e-9 * top_radius)
    return rho / horizon, (d - d_min) / span
