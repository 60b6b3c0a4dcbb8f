r"""Ray–sphere geometry in a spherically symmetric atmosphere, stable near the horizon.

A ray starts at radius ``r`` from the planet's centre with direction cosine ``mu`` to the
local zenith. Along the ray, the signed distance from the point of closest approach is
:math:`t`, with :math:`r(t)^2 = p^2 + t^2`, impact parameter
:math:`p^2 = r^2 (1 - \mu^2)` and observer at :math:`t_0 = r\mu`.

The textbook forms of the intersection distances (ref. 1, functions
``DistanceToTopAtmosphereBoundary`` and ``DistanceToBottomAtmosphereBoundary``) subtract
nearly equal numbers for rays close to the horizon or starting on a boundary. Here the
discriminants are written as :math:`r^2\mu^2 + (R_t - r)(R_t + r)` and
:math:`r^2\mu^2 - (r - R)(r + R)` (no cancellation of the large :math:`r^2` terms) and
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

from skytorch._validate import broadcast_shape, check_range, common_dtype

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
    r""":math:`\sqrt{\max(x, 0)}` with a finite (zero) gradient where ``x <= 0``."""
    tiny = torch.finfo(x.dtype).tiny
    return torch.sqrt(torch.clamp(x, min=tiny)) * (x > 0)


def _discriminant_top(r, mu, top_radius):
    r""":math:`r^2\mu^2 + (R_t - r)(R_t + r) = R_t^2 - p^2`."""
    return (r * mu) ** 2 + (top_radius - r) * (top_radius + r)


def _discriminant_ground(r, mu, planet_radius):
    r""":math:`r^2\mu^2 - (r - R)(r + R) = R^2 - p^2`."""
    return (r * mu) ** 2 - (r - planet_radius) * (r + planet_radius)


def _safe_divide(numerator, denominator):
    """``numerator / denominator`` with 0 where the denominator is 0 (and finite grads)."""
    zero = denominator == 0
    return torch.where(zero, torch.zeros_like(numerator),
                       numerator / torch.where(zero, torch.ones_like(denominator), denominator))


def _distance_to_top(r, mu, top_radius) -> torch.Tensor:
    """Implement :func:`distance_to_top` (inputs already checked)."""
    disc = _discriminant_top(r, mu, top_radius)
    root = safe_sqrt(disc)
    c = (top_radius - r) * (top_radius + r)
    upward = _safe_divide(c, r * mu + root)
    downward = -r * mu + root
    return torch.clamp(torch.where(mu >= 0, upward, downward), min=0.0)


def _distance_to_ground(r, mu, planet_radius) -> torch.Tensor:
    """Implement :func:`distance_to_ground` (inputs already checked)."""
    disc = _discriminant_ground(r, mu, planet_radius)
    root = safe_sqrt(disc)
    c = (r - planet_radius) * (r + planet_radius)
    distance = _safe_divide(c, -r * mu + root)
    return torch.where(mu < 0, torch.clamp(distance, min=0.0), torch.zeros_like(distance))


def _ray_hits_ground(r, mu, planet_radius) -> torch.Tensor:
    """Implement :func:`ray_hits_ground` (inputs already checked)."""
    mu = torch.as_tensor(mu)
    tolerance = 8.0 * torch.finfo(mu.dtype).eps if mu.is_floating_point() else 0.0
    return (mu < -tolerance) & (_discriminant_ground(r, mu, planet_radius) >= 0)


def _ray_segment(r, mu, planet_radius, top_radius) -> dict[str, torch.Tensor]:
    """Implement :func:`ray_segment` (inputs already checked)."""
    hits = _ray_hits_ground(r, mu, planet_radius)
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


def _texture_rays(x_r, x_mu, planet_radius, top_radius) -> tuple[torch.Tensor, torch.Tensor]:
    """Implement :func:`texture_rays` (inputs already checked)."""
    horizon = math.sqrt(top_radius**2 - planet_radius**2)
    rho = x_r * horizon
    r = torch.sqrt(rho * rho + planet_radius**2)
    d_min = top_radius - r
    d_max = rho + horizon
    d = d_min + x_mu * (d_max - d_min)
    safe_d = torch.where(d > 0.0, d, torch.ones_like(d))
    # H^2 - rho^2 - d^2 = (H - d)(H + d) - rho^2 with H - d = (1 - x_mu)(d_max - d_min) - rho
    # (d_max = rho + H): no cancellation of the large squares, and exactly -rho(2H + 2 rho)
    # (mu = -rho/r, the ray tangent to the ground) at x_mu = 1
    numerator = ((1.0 - x_mu) * (d_max - d_min) - rho) * (horizon + d) - rho * rho
    mu = torch.where(d > 0.0, numerator / (2.0 * r * safe_d), torch.ones_like(d))
    return rho * rho / (r + planet_radius), torch.clamp(mu, -1.0, 1.0)


def _texture_coordinates(altitude_m, mu, planet_radius, top_radius
                        ) -> tuple[torch.Tensor, torch.Tensor]:
    """Implement :func:`texture_coordinates` (inputs already checked)."""
    horizon = math.sqrt(top_radius**2 - planet_radius**2)
    r = planet_radius + altitude_m
    rho = safe_sqrt(altitude_m * (r + planet_radius))
    d = _distance_to_top(r, mu, top_radius)
    d_min = top_radius - r
    d_max = rho + horizon
    span = torch.clamp(d_max - d_min, min=1e-9 * top_radius)
    return rho / horizon, (d - d_min) / span


# --- public, checked entry points ---------------------------------------------------------------


def _radius(name: str, value) -> float | torch.Tensor:
    """Return a sphere radius [m]: a positive finite number or tensor."""
    if isinstance(value, bool):
        raise TypeError(f"{name} must be a number [m]; got {value!r}")
    if isinstance(value, (int, float)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a finite radius > 0 m; got {value!r}")
        return float(value)
    return check_range(name, value, 0.0, low_inclusive=False, unit=" m")


def _ray(r, mu, **radii):
    """Return checked ray origin radius, direction cosine and radii, broadcastable together."""
    dtype = common_dtype(r, mu, *radii.values())
    r = check_range("r", r, 0.0, unit=" m", dtype=dtype)
    mu = check_range("mu", mu, -1.0 - _MU_SLACK, 1.0 + _MU_SLACK, dtype=dtype)
    mu = torch.clamp(mu, -1.0, 1.0)
    checked = {name: _radius(name, value) for name, value in radii.items()}
    shapes = {"r": tuple(r.shape), "mu": tuple(mu.shape)}
    shapes.update({name: tuple(value.shape) for name, value in checked.items()
                   if isinstance(value, torch.Tensor)})
    try:
        broadcast_shape(*shapes.values())
    except ValueError:
        listing = ", ".join(f"{name} {shape}" for name, shape in shapes.items())
        raise ValueError(f"shapes do not broadcast: {listing}") from None
    return r, mu, checked


#: slack on |mu| <= 1 for cosines of rounded angles
_MU_SLACK = 1e-6


def distance_to_top(r, mu, top_radius) -> torch.Tensor:
    r"""Distance along the ray to where it leaves the top of the atmosphere [m].

    Parameters
    ----------
    r : Tensor (...)
        Radius of the ray's origin [m], ``r <= top_radius``.
    mu : Tensor (...)
        Cosine of the ray's zenith angle, in [-1, 1] [1].
    top_radius : float or Tensor (...)
        Radius of the top of the atmosphere [m], > 0.

    Returns
    -------
    Tensor (...)
        Distance :math:`d = -r\mu + \sqrt{r^2\mu^2 + R_t^2 - r^2} \ge 0` [m], computed as
        :math:`(R_t^2 - r^2)/(r\mu + \sqrt{\cdot})` for upward rays.

    Raises
    ------
    ValueError
        NaN/inf, a negative radius, :math:`|\mu| > 1` or shapes that do not broadcast.
    """
    r, mu, radii = _ray(r, mu, top_radius=top_radius)
    return _distance_to_top(r, mu, radii["top_radius"])


def distance_to_ground(r, mu, planet_radius) -> torch.Tensor:
    r"""Distance along the ray to the ground [m] (meaningful where :func:`ray_hits_ground`).

    Parameters
    ----------
    r : Tensor (...)
        Radius of the ray's origin [m], ``r >= planet_radius``.
    mu : Tensor (...)
        Cosine of the zenith angle, in [-1, 1] [1].
    planet_radius : float or Tensor (...)
        Planet radius [m], > 0.

    Returns
    -------
    Tensor (...)
        :math:`d = -r\mu - \sqrt{r^2\mu^2 - (r^2 - R^2)}`, computed as
        :math:`(r^2 - R^2)/(-r\mu + \sqrt{\cdot})` [m]; for rays that miss the ground
        the distance to the point of closest approach's projection,
        :math:`(r^2 - R^2)/(-r\mu)` clamped at 0 (as in ref. 1, never NaN).
    """
    r, mu, radii = _ray(r, mu, planet_radius=planet_radius)
    return _distance_to_ground(r, mu, radii["planet_radius"])


def ray_hits_ground(r, mu, planet_radius) -> torch.Tensor:
    """Whether the ray from ``r`` with cosine ``mu`` meets the planet (bool, (...)).

    A ray tangent to the ground (discriminant exactly 0) counts as hitting it; a ray on
    the ground pointing horizontally does not, where "horizontally" allows for the
    rounding of cos(pi/2) (|mu| <= 8 eps, 5e-7 in float32).

    Examples
    --------
    >>> import torch
    >>> ray_hits_ground(torch.tensor([6.371e6, 6.371e6]), torch.tensor([-0.1, 0.1]), 6.371e6)
    tensor([ True, False])
    """
    r, mu, radii = _ray(r, mu, planet_radius=planet_radius)
    return _ray_hits_ground(r, mu, radii["planet_radius"])


def ray_segment(r, mu, planet_radius, top_radius) -> dict[str, torch.Tensor]:
    r"""Return the part of a straight ray inside the atmosphere, in the :math:`t` parametrisation.

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
    Altitude along the ray: :math:`h(t) = (p^2 - R^2 + t^2)/(\sqrt{R^2 + p^2 - R^2 + t^2}
    + R)`. An origin above the top starts at :math:`t = -\sqrt{R_t^2 - p^2}` if the ray
    descends into the atmosphere, otherwise the segment is empty.
    """
    r, mu, radii = _ray(r, mu, planet_radius=planet_radius, top_radius=top_radius)
    return _ray_segment(r, mu, radii["planet_radius"], radii["top_radius"])


def _spheres(planet_radius, top_radius) -> tuple[float, float]:
    planet = _radius("planet_radius", planet_radius)
    top = _radius("top_radius", top_radius)
    if not (isinstance(planet, float) and isinstance(top, float)):
        raise TypeError("planet_radius and top_radius must be numbers [m] here")
    if not top > planet:
        raise ValueError(f"top_radius must be > planet_radius; got {top!r} <= {planet!r}")
    return planet, top


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
    parametrisation of Schneegans et al. 2025 (eq. 2) for their deviation table. The
    numerator is evaluated as :math:`(H - d)(H + d) - \rho^2` with
    :math:`H - d = (1 - x_\mu)(d_{max} - d_{min}) - \rho`, so that the ray tangent to
    the ground (:math:`x_\mu = 1`) gets :math:`\mu = -\rho/r` to rounding (0 on the
    ground, not :math:`-10^{-8}`).

    Examples
    --------
    >>> import torch
    >>> h, mu = texture_rays(torch.tensor([0.0, 1.0]), torch.tensor([1.0, 0.0]), 6.371e6,
    ...                      6.471e6)
    >>> [round(float(v)) for v in h], [round(float(v), 6) for v in mu]
    ([0, 100000], [0.0, 1.0])
    """
    planet, top = _spheres(planet_radius, top_radius)
    dtype = common_dtype(x_r, x_mu)
    x_r = check_range("x_r", x_r, 0.0, 1.0, dtype=dtype)
    x_mu = check_range("x_mu", x_mu, 0.0, 1.0, dtype=dtype)
    try:
        broadcast_shape(x_r.shape, x_mu.shape)
    except ValueError:
        raise ValueError(f"shapes do not broadcast: x_r {tuple(x_r.shape)}, x_mu "
                         f"{tuple(x_mu.shape)}") from None
    return _texture_rays(x_r, x_mu, planet, top)


def texture_coordinates(altitude_m, mu, planet_radius, top_radius
                        ) -> tuple[torch.Tensor, torch.Tensor]:
    """Inverse of :func:`texture_rays`: texture coordinates ``(x_r, x_mu)`` (...).

    Parameters
    ----------
    altitude_m : Tensor (...)
        Altitude of the ray origin, in [0, top] [m].
    mu : Tensor (...)
        Cosine of the ray's zenith angle, in [-1, 1] [1].
    planet_radius, top_radius : float
        Radii of the ground and of the top of the atmosphere [m].

    Returns
    -------
    tuple of Tensor (...)
        ``x_r`` and ``x_mu``, in [0, 1] for rays that miss the ground; ``x_mu > 1`` below
        the geometric horizon (not clamped, so callers can tell).
    """
    planet, top = _spheres(planet_radius, top_radius)
    dtype = common_dtype(altitude_m, mu)
    altitude = check_range("altitude_m", altitude_m, 0.0, top - planet, unit=" m",
                           dtype=dtype)
    mu = check_range("mu", mu, -1.0 - _MU_SLACK, 1.0 + _MU_SLACK, dtype=dtype)
    try:
        broadcast_shape(altitude.shape, mu.shape)
    except ValueError:
        raise ValueError(f"shapes do not broadcast: altitude_m {tuple(altitude.shape)}, mu "
                         f"{tuple(mu.shape)}") from None
    return _texture_coordinates(altitude, torch.clamp(mu, -1.0, 1.0), planet, top)
