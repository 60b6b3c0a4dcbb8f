r"""The shadow of a planet with a refracting, absorbing atmosphere.

:class:`Shadow` gives the illuminance ``I / I_sun`` at any point behind (or beside) a
spherical occluder: sunlight passing above the atmosphere plus sunlight refracted and
attenuated through the atmosphere ring around the limb, integrated over the limb-darkened
solar disc.

Method (spherical symmetry, no per-point images)
------------------------------------------------
Let a point ``P`` lie at distance ``L`` from the occluder's centre. Seen from ``P`` the
occluder's centre is the direction ``c``, the Sun's centre is at angular distance
``sigma`` from ``c`` with angular radius ``rho_s``. A ray that leaves the atmosphere
towards ``P`` with (geometric) impact parameter ``b = R + beta`` is seen at angular radius
``theta = asin(b / L)`` from ``c``, at ring azimuth ``psi``. Traced back, it was bent
towards the occluder by ``delta(beta)`` in the plane through ``c``: it comes from the sky
direction at signed angular radius

.. math::

    a(\beta) = \arcsin\frac{R + \beta}{L} - k\,\delta(\beta), \qquad
    k = \frac{D}{|S - P|}

from ``c`` on the same great circle (``k`` converts the bend at the limb, a distance ``D``
from the Sun, into the angle seen from ``P``). Radiance is conserved along rays apart from
extinction, so ``P`` receives

.. math::

    E = \int_{\beta_{min}}^{\beta_{top}} T(\beta, \lambda)\,F(|a(\beta)|)\,
        \frac{(R + \beta)\,d\beta}{L\sqrt{L^2 - (R + \beta)^2}} ,
    \qquad F(\alpha) = \int_0^{2\pi} I_\odot(\gamma(\alpha, \psi))\,d\psi ,

with ``hav gamma = hav(alpha - sigma) + sin(alpha) sin(sigma) hav(psi)`` the distance from
the Sun's centre and ``I_sun`` the limb-darkened radiance (zero outside the disc). ``F`` is
the radiance integrated along a circle through the offset solar disc: the arc inside the
disc has half-angle ``psi_max``, ``hav psi_max = (hav rho_s - hav(alpha - sigma)) /
(sin alpha sin sigma)``, and the substitution ``psi = psi_max (1 - v^2)`` removes the
square-root behaviour at the limb (Gauss–Legendre in ``v``). ``a(beta)`` increases except
in thin folds below the kinks of a layered profile where the upper layer has the steeper
refractivity gradient (U.S. 1976: 11, 20, 32 and 71 km; the bending there grows upwards
like ``-sqrt(beta_j - beta)``), so the breakpoints of ``F`` (``|a| = |sigma - rho_s|`` and
``sigma + rho_s``, up to three crossings each near a fold) are bracketed between nodes
where ``a`` is monotone (a coarse grid, the kinks and the folds' tops) and refined by
safeguarded Newton steps; the ``beta`` integral is split there (only the pieces where the
circle meets the solar disc are integrated); each piece is integrated
with a Gauss–Legendre rule after the substitution ``s = (1 - cos pi t)/2`` that absorbs
the square roots at both ends. ``delta(beta)`` and ``T(beta, lambda) = exp(-tau)`` come from
:func:`skytorch.atmosphere.refraction.trace_grazing_rays`, tabulated once per atmosphere
on a grid dense near the ground (``beta = beta_min + (beta_top - beta_min) s^2``, uniform
in ``s``; with a kinked refractivity profile such as US 1976 the rows are graded towards
each kink and the integral is also split there) and interpolated with cubic Catmull–Rom
splines, piece by piece. The result is normalised by the
unobstructed solar irradiance ``2 pi C(rho_s)``, ``C = int_0^rho_s I sin(gamma) d gamma``,
and the direct light passing above the atmosphere, :func:`sun_visible_fraction` with the
top of the atmosphere as occluder, is added.

With refraction and extinction switched off the ring integral is the flux of the solar
disc inside the annulus between the ground and the top of the atmosphere, so the result
is the airless occlusion exactly (tested). Every term is positive, so deep-umbra values
(``1e-8`` and below) keep their relative accuracy.

Options: a cloud-top altitude below which rays are blocked (on a fraction of the limb),
terrain attenuation near the
ground (rays with periapsis altitude ``h`` weighted by ``clamp(h / (2 h_terrain), 0, 1)``,
Schneegans et al. 2025 §5.2, mean land elevation 240 m for Earth), and sunlight scattered
once by the atmosphere ring towards the point (``scattering=True``, straight legs, the
method in :mod:`skytorch.eclipse.shadow_scattering`; Schneegans et al. find it to matter
after volcanic eruptions and for dusty atmospheres such as Mars).

References
----------
1. Schneegans, S., Gilg, J., Ahlers, V., Zachmann, G., Gerndt, A. 2025, "Physically
   Based Real-Time Rendering of Eclipses", Computer Graphics Forum,
   doi:10.1111/cgf.70220 (shadow with refraction, limb views, terrain, eq. 1).
2. Link, F. 1969, *Eclipse Phenomena in Astronomy*, Springer,
   doi:10.1007/978-3-642-86689-9 (refraction theory of the Earth's shadow).
3. Vollmer, M., Gedzelman, S. D. 2008, "Simulating irradiance and color of the eclipsed
   moon", Appl. Opt. 47, H52, doi:10.1364/AO.47.000H52.
4. García Muñoz, A., Pallé, E. 2011, "Lunar eclipse theory revisited: Scattered sunlight in
   both the quiescent and the volcanically perturbed atmosphere", JQSRT 112, 1609,
   doi:10.1016/j.jqsrt.2011.03.017.

Examples
--------
>>> import torch
>>> from skytorch.eclipse.shadow import Shadow
>>> shadow = Shadow.earth(n_altitude=101)
>>> i = shadow.relative_illuminance(3.844e8, torch.tensor([0.0, 1e7]), [680.0, 440.0])
>>> bool((i[0] < 1e-2).all()), [round(v, 6) for v in i[1].tolist()]
(True, [1.0, 1.0])
"""

from __future__ import annotations

import contextlib
import logging
import math

import torch
from torch import nn

from skytorch._validate import (
    as_tensor,
    broadcast_shape,
    check_broadcastable,
    check_choice,
    check_flag,
    check_int,
    check_positive,
    check_range,
    common_dtype,
)
from skytorch.atmosphere.rayleigh import WAVELENGTH_RANGE_NM
from skytorch.atmosphere.refraction import trace_grazing_rays
from skytorch.constants import (
    ASTRONOMICAL_UNIT_M,
    EARTH_MEAN_RADIUS_M,
    MARS_MEAN_RADIUS_M,
    SUN_RADIUS_M,
)
from skytorch.eclipse.occlusion import (
    LIMB_DARKENING_LAWS,
    _angle_from_haversine,
    _haversine,
    _law_coefficients,
    _safe_sqrt,
    sun_visible_fraction,
)
from skytorch.eclipse.occlusion import _nodes as _unit_gauss
from skytorch.eclipse.shadow_multiple_scattering import (
    multiple_scattered_illuminance as _multiple_scattered_illuminance,
)
from skytorch.eclipse.shadow_multiple_scattering import (
    multiple_scattered_radiance as _multiple_scattered_radiance,
)
from skytorch.eclipse.shadow_scattering import (
    ScatteringProfile,
    scattered_illuminance,
    scattered_radiance,
)

__all__ = [
    "EARTH_MEAN_TERRAIN_HEIGHT_M",
    "LimbCloudCover",
    "MARS_SEMI_MAJOR_AXIS_M",
    "RingProfile",
    "Shadow",
    "shadow_angles",
    "solar_arc_integral",
    "solar_normalisation",
]

logger = logging.getLogger(__name__)

#: mean land elevation used for terrain attenuation (Schneegans et al. 2025, §5.2) [m]
EARTH_MEAN_TERRAIN_HEIGHT_M = 240.0
#: semi-major axis of Mars' orbit, 1.523679 AU (Standish & Williams, JPL) [m]
MARS_SEMI_MAJOR_AXIS_M = 1.523679 * ASTRONOMICAL_UNIT_M
#: default number of nodes of the altitude table (uniform in sqrt(altitude))
DEFAULT_N_ALTITUDE = 401
#: default Gauss–Legendre nodes per piece of the ring (impact-parameter) integral, for a
#: smooth refractivity profile and for one with kinks (US 1976 layers)
DEFAULT_RING_NODES = 12
DEFAULT_RING_NODES_KINKED = 16
#: default Gauss–Legendre nodes on the arc through the solar disc
DEFAULT_ARC_NODES = 8
#: equal sub-pieces per piece of the ring integral (composite Gauss–Legendre), for a smooth
#: profile and for one with kinks, whose nodes already cut the integral into short pieces
DEFAULT_SPLIT = 2
DEFAULT_SPLIT_KINKED = 1
#: safeguarded Newton steps for the breakpoints inside a monotone bracket (converged to
#: ~1e-13 in the table coordinate; a step leaving the bracket bisects instead)
_ROOT_STEPS = 6
#: bisection steps for the fold of ``a(beta)`` below a kink (~1e-8 of a row in ``s``)
_FOLD_STEPS = 24
#: members of a batched atmosphere bend light alike when their deviations agree to this
#: relative tolerance and their periapsis altitudes to _SAME_PERIAPSIS_M [m]: the
#: batched trace's rounding (1 ulp), far below any difference of refractivity
_SAME_BENDING_RTOL = 1e-12
_SAME_PERIAPSIS_M = 1e-6
#: relative singular-value cut-off of the optical-depth table (reconstruction ~1e-12)
_RANK_TOLERANCE = 1e-13
#: stride of the coarse grid that brackets the breakpoints before the Newton steps
_COARSE_STRIDE = 4
#: points per chunk in the ring integral (bounds the temporaries to ~100 MB)
_CHUNK = 4096


def solar_normalisation(sun_radius_rad, limb_darkening=0.6, law: str = "linear",
                        n_nodes: int = 16) -> torch.Tensor:
    r"""Irradiance of the unobstructed solar disc in units of the central radiance.

    Parameters
    ----------
    sun_radius_rad : Tensor (...)
        Angular radius of the Sun ``rho_s`` [rad].
    limb_darkening, law
        As in :func:`~skytorch.eclipse.occlusion.sun_visible_fraction`.
    n_nodes : int
        Gauss–Legendre nodes in ``mu`` (the integrand is a polynomial times a smooth factor:
        16 nodes are exact to rounding).

    Returns
    -------
    Tensor (...)
        :math:`2\pi C(\rho_s)` [sr], with
        :math:`C = \sin^2\rho_s\int_0^1 I(\mu)\,\mu\,d\mu / \sqrt{1 - (1 - \mu^2)\sin^2\rho_s}`
        (``r = sin(gamma)/sin(rho_s)``, ``mu = sqrt(1 - r^2)``).

    Examples
    --------
    >>> import math
    >>> round(float(solar_normalisation(0.01, 0.0)) / (math.pi * 0.01**2), 4)
    1.0
    """
    rho_s = as_tensor("sun_radius_rad", sun_radius_rad)
    a0, a1, a2 = _law_coefficients(law, limb_darkening, rho_s.dtype)
    x, w = _unit_gauss(check_int("n_nodes", n_nodes, low=2))
    mu = torch.as_tensor(x, dtype=rho_s.dtype)
    weight = torch.as_tensor(w, dtype=rho_s.dtype)
    b = (torch.sin(rho_s) ** 2).unsqueeze(-1)
    radiance = (a0.unsqueeze(-1) + a1.unsqueeze(-1) * mu + a2.unsqueeze(-1) * mu * mu)
    integrand = radiance * mu / torch.sqrt(1.0 - (1.0 - mu * mu) * b)
    return 2.0 * math.pi * b.squeeze(-1) * (integrand * weight).sum(-1)


def solar_arc_integral(alpha_rad, sun_radius_rad, separation_rad, coefficients,
                       n_nodes: int = DEFAULT_ARC_NODES, azimuth_weight=None) -> torch.Tensor:
    r"""Limb-darkened solar radiance integrated along a circle on the sky.

    Parameters
    ----------
    alpha_rad : Tensor (...)
        Angular radius of the circle around the occluder's centre ``alpha >= 0`` [rad].
    sun_radius_rad, separation_rad : Tensor (...)
        Sun's angular radius ``rho_s`` and the separation ``sigma`` between the Sun's
        centre and the circle's centre [rad].
    coefficients : tuple of Tensor (...)
        ``(a0, a1, a2)`` of ``I(mu) = a0 + a1 mu + a2 mu^2`` (central radiance ``a0 + a1 +
        a2``).
    n_nodes : int
        Gauss–Legendre nodes on the arc.
    azimuth_weight : callable, optional
        ``azimuth_weight(psi)`` -> weights of the arc's azimuths ``psi >= 0`` [rad], for
        ``psi`` of shape ``(..., n_nodes)``: the mean of the weights at ``+psi`` and
        ``-psi``, of shape ``(..., n_nodes)`` or ``(..., K, n_nodes)`` for ``K`` weightings
        at once; the integral becomes :math:`\int I\,W(\psi)\,d\psi` (a part of the
        ring, e.g. one latitude band of the limb). Default 1.

    Returns
    -------
    Tensor (...) or (..., K)
        :math:`F(\alpha) = \int_0^{2\pi} I(\gamma(\alpha, \psi))\,d\psi` [rad].

    Notes
    -----
    :math:`\operatorname{hav}\gamma = \operatorname{hav}(\alpha - \sigma)
    + \sin\alpha\sin\sigma\operatorname{hav}\psi`; the arc inside the disc,
    :math:`|\psi| \le \psi_{max}`, is integrated with :math:`\psi = \psi_{max}(1 - v^2)`.
    For a uniform disc ``F = 2 psi_max`` (the arc length).
    """
    a0, a1, a2 = coefficients
    alpha, rho_s, sigma = alpha_rad, sun_radius_rad, separation_rad
    tiny = torch.finfo(alpha.dtype).tiny
    hav_offset = _haversine(alpha - sigma)
    product = torch.sin(alpha) * torch.sin(sigma)
    numerator = _haversine(rho_s) - hav_offset
    full = numerator >= product
    ratio = torch.where(full, torch.ones_like(numerator),
                        numerator / torch.where(full, 1.0, torch.clamp(product, min=tiny)))
    psi_max = _angle_from_haversine(ratio)
    x, w = _unit_gauss(n_nodes)
    half_arc = torch.as_tensor(0.5 * (1.0 - x * x), dtype=alpha.dtype)  # psi / (2 psi_max)
    weight = torch.as_tensor(2.0 * x * w, dtype=alpha.dtype)
    hav_psi = torch.sin(psi_max.unsqueeze(-1) * half_arc).square()
    hav_gamma = torch.addcmul(hav_offset.unsqueeze(-1), product.unsqueeze(-1), hav_psi)
    scale = (4.0 / torch.sin(rho_s).square()).unsqueeze(-1)
    # 1 - 4 hav(gamma) (1 - hav(gamma)) / sin^2(rho_s) = 1 - (sin(gamma) / sin(rho_s))^2
    one = torch.ones((), dtype=alpha.dtype)
    mu = _safe_sqrt(torch.addcmul(one, hav_gamma * (hav_gamma - 1.0), scale))
    if azimuth_weight is None:
        # the weights of v sum to 1 (int_0^1 2v dv): the constant term needs no quadrature
        mean = a0 + a1 * (mu @ weight)
        if bool((a2 != 0).any()):
            mean = mean + a2 * (mu.square() @ weight)
        return 2.0 * psi_max * mean
    share = azimuth_weight(2.0 * psi_max.unsqueeze(-1) * half_arc)
    extra = share.dim() - mu.dim()  # K weightings at once: (..., K, n_nodes)
    if extra:
        mu = mu.unsqueeze(-2)
        a0, a1, a2, psi_max = (x.unsqueeze(-1) for x in (a0, a1, a2, psi_max))
    mean = a0 * (share @ weight) + a1 * ((mu * share) @ weight)
    if bool((a2 != 0).any()):
        mean = mean + a2 * ((mu.square() * share) @ weight)
    return 2.0 * psi_max * mean


def shadow_angles(distance_m, offset_m, sun_distance_m, sun_radius_m, occluder_radius_m):
    """Angles seen from a point in the shadow cone.

    Parameters
    ----------
    distance_m : Tensor (...)
        Distance behind the occluder's centre along the anti-Sun axis [m] (negative on the
        day side).
    offset_m : Tensor (...)
        Distance from the anti-Sun axis [m], >= 0.
    sun_distance_m, sun_radius_m, occluder_radius_m : float or Tensor (...)
        Sun–occluder distance, solar radius and occluder radius [m].

    Returns
    -------
    dict of Tensor (...)
        ``centre_distance_m`` (L, point to occluder centre), ``sun_range_m`` (point to Sun),
        ``sun_radius_rad``, ``occluder_radius_rad`` and ``separation_rad`` (angle between
        the Sun's and the occluder's centres), exact for the planar triangle
        Sun–occluder–point.
    """
    d, rho = distance_m, offset_m
    centre = torch.hypot(d, rho)
    sun_range = torch.hypot(sun_distance_m + d, rho)
    separation = torch.atan2(rho, d) - torch.atan2(rho, sun_distance_m + d)
    with torch.no_grad():
        inside = sun_range <= sun_radius_m
        if bool(inside.any()):
            raise ValueError(f"sun_distance_m: a point lies within the Sun (radius "
                             f"{float(torch.as_tensor(sun_radius_m).max()):.6g} m of its "
                             "centre): the Sun–occluder distance must put the points outside "
                             "it")
    return {
        "centre_distance_m": centre,
        "sun_range_m": sun_range,
        "sun_radius_rad": torch.asin(sun_radius_m / sun_range),
        "occluder_radius_rad": torch.asin(torch.clamp(occluder_radius_m / centre, max=1.0)),
        "separation_rad": separation,
    }


# --- cubic interpolation on a uniform grid -------------------------------------------------


def _spline_coefficients(values: torch.Tensor) -> torch.Tensor:
    """Catmull–Rom cubic coefficients per interval of a uniform grid.

    ``values`` (N, C) at ``s_k = k / (N - 1)``; returns (N - 1, 4, C) with
    ``f(s) = c0 + c1 t + c2 t^2 + c3 t^3`` on interval ``k``, ``t = s (N - 1) - k``. Ghost
    rows by quadratic extrapolation close the ends.
    """
    first = 3.0 * values[0] - 3.0 * values[1] + values[2]
    last = 3.0 * values[-1] - 3.0 * values[-2] + values[-3]
    padded = torch.cat([first[None], values, last[None]], dim=0)
    p0, p1, p2, p3 = padded[:-3], padded[1:-2], padded[2:-1], padded[3:]
    c1 = 0.5 * (p2 - p0)
    c2 = p0 - 2.5 * p1 + 2.0 * p2 - 0.5 * p3
    c3 = 0.5 * (p3 - p0) + 1.5 * (p1 - p2)
    return torch.stack([p1, c1, c2, c3], dim=1).contiguous()


def _spline(coefficients: torch.Tensor, s: torch.Tensor) -> torch.Tensor:
    """Evaluate :func:`_spline_coefficients` at ``s`` in [0, 1] -> (*s.shape, C)."""
    n = coefficients.shape[0]
    x = torch.clamp(s, 0.0, 1.0) * n
    i = torch.clamp(torch.floor(x.detach()), 0, n - 1).long()
    t = (x - i.to(x.dtype)).unsqueeze(-1)
    rows = coefficients.index_select(0, i.reshape(-1)).reshape(*i.shape, 4, -1)
    c0, c1, c2, c3 = rows.unbind(-2)
    # Horner's rule with fused multiply-adds (three passes over the gathered rows)
    return torch.addcmul(c0, t, torch.addcmul(c1, t, torch.addcmul(c2, t, c3)))


class _ImpactGrid:
    """Impact altitude ``beta(s)`` on the table coordinate ``s`` in [0, 1].

    Without kinks ``beta = beta_min + (beta_top - beta_min) sigma^2`` with ``sigma = s``
    (dense near the ground). Each kink ``beta_j`` of the profile (an impact altitude where
    the bending varies like ``sqrt(beta_j - beta)`` from below) becomes a node: the range
    of ``sigma`` is cut at ``sigma_j`` and every piece below a kink is mapped from its
    stretch of ``s`` by ``sigma = sigma_a + (sigma_b - sigma_a) x (2 - x)`` (``x`` from 0
    to 1 along the piece). Then ``beta_j - beta`` is quadratic in ``s`` near the kink and
    the square root becomes linear: a cubic per piece interpolates it.
    """

    def __init__(self, beta_min_m: float, beta_top_m: float, n_rows: int, kinks_m=()):
        self.beta_min_m, self.span = float(beta_min_m), float(beta_top_m) - float(beta_min_m)
        intervals = n_rows - 1
        nodes, sigmas = [0], [0.0]
        for kink in sorted(float(k) for k in kinks_m):
            if not self.beta_min_m < kink < float(beta_top_m):
                continue
            sigma = math.sqrt((kink - self.beta_min_m) / self.span)
            index = round(sigma * intervals)
            # at least two intervals per piece (a cubic with end extrapolation)
            if index - nodes[-1] >= 2 and intervals - index >= 2:
                nodes.append(index)
                sigmas.append(sigma)
        nodes.append(intervals)
        sigmas.append(1.0)
        #: row indices where the pieces start and end (first 0, last n_rows - 1)
        self.nodes = tuple(nodes)
        self.kinks_m = tuple(self.beta_min_m + self.span * x * x for x in sigmas[1:-1])
        self._s = torch.tensor(nodes, dtype=torch.float64) / intervals
        self._sigma = torch.tensor(sigmas, dtype=torch.float64)

    @property
    def pieces(self) -> list[tuple[int, int]]:
        """First and last row of each piece."""
        return list(zip(self.nodes[:-1], self.nodes[1:], strict=True))

    def _piece(self, value, edges):
        """Index of the piece holding ``value`` (edges: the pieces' lower/upper bounds)."""
        inner = edges[1:-1].to(value.dtype)
        return torch.clamp(torch.searchsorted(inner, value.detach().contiguous(), right=True),
                           0, len(self.nodes) - 2)

    def _bounds(self, j, dtype):
        s, sigma = self._s.to(dtype), self._sigma.to(dtype)
        return s[j], s[j + 1], sigma[j], sigma[j + 1], j < len(self.nodes) - 2

    def sigma(self, s: torch.Tensor):
        """``sigma`` and ``d sigma / d s`` at the table coordinate ``s``."""
        if len(self.nodes) == 2:
            return s, torch.ones_like(s)
        s_a, s_b, sigma_a, sigma_b, graded = self._bounds(self._piece(s, self._s), s.dtype)
        x = (s - s_a) / (s_b - s_a)
        g = torch.where(graded, x * (2.0 - x), x)
        slope = torch.where(graded, 2.0 * (1.0 - x), torch.ones_like(x))
        ratio = (sigma_b - sigma_a) / (s_b - s_a)
        return sigma_a + (sigma_b - sigma_a) * g, ratio * slope

    def beta(self, s: torch.Tensor) -> torch.Tensor:
        sigma, _ = self.sigma(s)
        return self.beta_min_m + self.span * sigma * sigma

    def beta_and_slope(self, s: torch.Tensor):
        """:meth:`beta` and d beta / d s [m], from one evaluation of :meth:`sigma`."""
        sigma, slope = self.sigma(s)
        return self.beta_min_m + self.span * sigma * sigma, 2.0 * self.span * sigma * slope

    def s_of_beta(self, beta_m: torch.Tensor) -> torch.Tensor:
        sigma = torch.sqrt(torch.clamp((beta_m - self.beta_min_m) / self.span, 0.0, 1.0))
        if len(self.nodes) == 2:
            return sigma
        s_a, s_b, sigma_a, sigma_b, graded = self._bounds(self._piece(sigma, self._sigma),
                                                          sigma.dtype)
        y = torch.clamp((sigma - sigma_a) / (sigma_b - sigma_a), 0.0, 1.0)
        x = torch.where(graded, y / (1.0 + torch.sqrt(1.0 - y)), y)
        return s_a + (s_b - s_a) * x


class RingProfile:
    """Bending and transmittance of the atmosphere ring, tabulated in impact altitude.

    Rows ``k = 0 .. n-1`` are at ``s_k = k / (n - 1)``, impact altitude ``beta_k =
    beta_min + (beta_top - beta_min) s_k^2`` (dense near the ground); with kinks of the
    refractivity profile (``kink_betas_m``) the rows are graded towards each kink from
    below and the table is interpolated piece by piece (:class:`_ImpactGrid`).

    Attributes
    ----------
    beta_min_m, beta_top_m : float
        Impact altitudes of the lowest transmitting ray (ground or cloud top) and of the
        top of the atmosphere [m].
    split_betas_m : tuple of float
        Impact altitudes where the ray weight has a kink (terrain ramp top, cloud top) or
        the refractivity profile has one (table nodes) [m]; the ring quadrature is split
        there.
    kink_betas_m : tuple of float
        Impact altitudes of the rays whose lowest point is at a kink of the refractivity
        profile, that are nodes of the table [m].
    terrain_height_m, cloud_top_m, cloud_fraction : float or None
        Ray weights, see :func:`_ray_weight`.
    cloud_cover : LimbCloudCover or None
        Clear-line-of-sight probability of the limb rays by periapsis altitude (the cloud
        profile), a further ray weight.
    deviation_rad : Tensor (n,)
        Total bending [rad].
    optical_depth : Tensor (n, n_wavelength) or (n, n_batch, n_wavelength)
        Optical depth along the bent path [1], per member of a batch of atmospheres.
    periapsis_altitude_m : Tensor (n,)
        Lowest altitude of each ray [m].
    cloud_split_m : Tensor () or None
        Impact altitude of the ray grazing the cloud tops [m], a split of the ring
        quadrature that keeps its graph: the quadrature nodes move with it, so the
        derivative of the ring integral with respect to the cloud-top altitude carries the
        boundary term of the step in the ray weight (Leibniz rule) exactly.
    """

    def __init__(self, beta_min_m, beta_top_m, deviation_rad, optical_depth,
                 periapsis_altitude_m, terrain_height_m=None, split_betas_m=(),
                 cloud_top_m=0.0, cloud_fraction=0.0, kink_betas_m=(), cloud_split_m=None,
                 cloud_cover=None):
        self.beta_min_m = float(beta_min_m)
        self.cloud_cover = cloud_cover
        self.beta_top_m = float(beta_top_m)
        self.deviation_rad = deviation_rad
        self.optical_depth = optical_depth
        self.periapsis_altitude_m = periapsis_altitude_m
        self.terrain_height_m = terrain_height_m
        self.grid = _ImpactGrid(beta_min_m, beta_top_m, int(deviation_rad.shape[0]),
                                kink_betas_m)
        self.kink_betas_m = self.grid.kinks_m
        fixed = tuple(float(b) for b in split_betas_m)
        moving = () if cloud_split_m is None else (float(cloud_split_m.detach()),)
        self.split_betas_m = fixed + moving + self.kink_betas_m
        self._splits = ([torch.tensor(b, dtype=torch.float64) for b in fixed]
                        + ([] if cloud_split_m is None
                           else [cloud_split_m.to(torch.float64).reshape(())])
                        + [torch.tensor(b, dtype=torch.float64) for b in self.kink_betas_m])
        self.cloud_top_m = float(cloud_top_m)
        self.cloud_fraction = float(cloud_fraction)
        # the optical depth is a sum over species of (profile integral) x (cross-section):
        # a matrix of low rank; interpolate its few factors instead of every wavelength.
        # A batch of atmospheres (n, n_batch, n_wl) shares the wavelength basis: the
        # factors of all members become columns of one interpolation table
        optical = optical_depth.to(torch.float64)
        if optical.dim() == 2:
            optical = optical[:, None, :]
        n_rows, self.n_batch, n_wl = optical.shape
        if optical.requires_grad:
            # carrying gradients (w.r.t. the atmosphere): the optical depths themselves are
            # the factors (the SVD's derivative is ill-conditioned at its truncated rank)
            self.rank = n_wl
            self.optical_factors = optical.reshape(n_rows, self.n_batch * n_wl)
            self.optical_basis = torch.eye(n_wl, dtype=torch.float64)
        else:
            u, sv, vh = torch.linalg.svd(optical.reshape(n_rows * self.n_batch, n_wl),
                                         full_matrices=False)
            rank = (int((sv > _RANK_TOLERANCE * sv[:1].clamp_min(1e-300)).sum())
                    if sv.numel() else 0)
            self.rank = rank
            self.optical_factors = (u[:, :rank] * sv[:rank]).reshape(n_rows,
                                                                     self.n_batch * rank)
            self.optical_basis = vh[:rank]
        self._cache: dict = {}

    @property
    def n_altitude(self) -> int:
        """Number of altitude nodes of the ray-traced deviation table."""
        return int(self.deviation_rad.shape[0])

    def beta(self, s: torch.Tensor) -> torch.Tensor:
        """Impact altitude [m] at the table coordinate ``s``."""
        return self.grid.beta(s)

    def s_of_beta(self, beta_m):
        """Table coordinate of the impact altitude ``beta_m`` [m] (float or Tensor)."""
        if isinstance(beta_m, torch.Tensor):
            return self.grid.s_of_beta(beta_m)
        return float(self.grid.s_of_beta(torch.tensor(float(beta_m), dtype=torch.float64)))

    def split_coordinates(self, dtype: torch.dtype) -> list[torch.Tensor]:
        """Table coordinates ``s`` of :attr:`split_betas_m` as 0-d tensors.

        The cloud split's keeps its graph (see ``cloud_split_m``).
        """
        return [self.grid.s_of_beta(beta.to(dtype)) for beta in self._splits]

    def _piecewise_spline(self, values: torch.Tensor) -> torch.Tensor:
        """:func:`_spline_coefficients` of each piece of the grid, concatenated."""
        return torch.cat([_spline_coefficients(values[a:b + 1]) for a, b in self.grid.pieces])

    def tables(self, dtype: torch.dtype) -> dict[str, torch.Tensor]:
        """Return padded interpolation tables cast to ``dtype`` (cached)."""
        if dtype not in self._cache:
            deviation = self.deviation_rad.to(dtype)[:, None]
            periapsis = self.periapsis_altitude_m.to(dtype)[:, None]
            factors = self.optical_factors.to(dtype)
            # bracket nodes of the breakpoint search: a coarse grid and every kink
            coarse = sorted(set(range(0, self.n_altitude, _COARSE_STRIDE))
                            | set(self.grid.nodes))
            every = torch.cat([deviation, periapsis, factors], dim=-1)
            spline = self._piecewise_spline(deviation)
            s = torch.linspace(0.0, 1.0, self.n_altitude, dtype=dtype)
            self._cache[dtype] = {
                "deviation": spline,
                "all": self._piecewise_spline(every),
                "basis": self.optical_basis.to(dtype),
                "nodes": deviation[coarse, 0],
                "nodes_s": s[coarse],
                "nodes_beta": self.beta(s[coarse]),
                "folds": self._folds(spline, deviation, s, coarse),
            }
        return self._cache[dtype]

    def _folds(self, spline, deviation, s, coarse) -> list[tuple]:
        """Find the kinks below which the bending grows upwards, and where its rise starts.

        There ``d beta / d s = 0`` (graded grid) and ``a' = -k delta'`` has the sign of
        ``-delta'`` at the kink (see :func:`_fold_tops`). Returns per fold the kink's
        column among the bracket nodes, the rise of the bending from the start of its
        rising stretch to the kink [rad], and the stretch's ends ``s``.
        """
        folds = []
        for first, last in self.grid.pieces[:-1]:
            # slope of the piece's last interval at its upper end (t = 1), from below
            _, c1, c2, c3 = spline[last - 1, :, 0].tolist()
            if c1 + 2.0 * c2 + 3.0 * c3 <= 0.0:
                continue
            start = last - 1  # the bending rises on the intervals start .. last - 1
            while start > first and float(spline[start - 1, 1, 0]) >= 0.0:
                start -= 1
            rise = float(deviation[last, 0] - deviation[start, 0])
            folds.append((coarse.index(last), rise, s[start], s[last]))
        return folds


def _ray_weight(periapsis_m: torch.Tensor, profile: RingProfile) -> torch.Tensor:
    """Fraction of the rays with periapsis altitude ``h`` not blocked by terrain or clouds.

    Terrain: ``clamp(h / (2 h_terrain), 0, 1)`` (Schneegans et al. 2025 §5.2); clouds: a
    fraction ``f`` of the limb has tops at ``h_c``, so rays below pass with ``1 - f``;
    a cloud profile (:class:`LimbCloudCover`): its clear-line-of-sight probability.
    """
    weight = torch.ones_like(periapsis_m)
    if profile.terrain_height_m is not None:
        weight = torch.clamp(periapsis_m / (2.0 * profile.terrain_height_m), 0.0, 1.0)
    if profile.cloud_fraction > 0.0 and profile.cloud_top_m > 0.0:
        weight = weight * torch.where(periapsis_m < profile.cloud_top_m,
                                      1.0 - profile.cloud_fraction, 1.0)
    cover = getattr(profile, "cloud_cover", None)
    if cover is not None:
        weight = weight * cover.clear_fraction(periapsis_m)
    return weight


class LimbCloudCover:
    r"""Cloud profile of the limb: the chance that a grazing ray passes the cloud tops.

    A ray whose lowest point is at altitude ``h`` crosses the limb below any cloud top
    ``z > h`` along a chord of length ``2 sqrt(2 R (z - h))`` (~±200 km for
    ``z - h = 3 km``), much longer than a nadir view. The profile is the nadir cloud-top
    climatology ``f(z)``, the fraction of the area covered by clouds with tops above ``z``
    (piecewise linear between ``altitude_m`` nodes, constant outside them), raised to an
    effective number ``n`` of independent cloud fields along the limb chord:

    .. math::

        P_{clear}(h) = (1 - f(h))^{n} .

    ``n = 1`` is the nadir cover itself (a single deck ``f = cloud_fraction`` below
    ``cloud_top_altitude_m`` is the case of two nodes with a step); a larger ``n`` states
    that the long limb chord meets more clouds than a vertical column. The clouds met are
    opaque: a cirrus of vertical optical depth 0.03 has a slant optical depth ~30-100
    times larger along the limb chord.

    Parameters
    ----------
    altitude_m : sequence of float or Tensor (k,)
        Nodes [m], ``k >= 2``, strictly increasing, >= 0 (fixed; not differentiated).
    cover : sequence of float or Tensor (k,)
        ``f`` at the nodes [1], in [0, 1], non-increasing with altitude. A tensor that
        requires a gradient keeps it (:meth:`clear_fraction` is differentiable in it).
    limb_exponent : float or Tensor ()
        ``n`` [1], in [0, 1000]; a tensor that requires a gradient keeps it.
    name : str
        Label for Dataset attributes.

    Examples
    --------
    >>> cover = LimbCloudCover([0.0, 3000.0, 9000.0], [0.6, 0.3, 0.0], limb_exponent=2.0)
    >>> [round(v, 4) for v in cover.clear_fraction(torch.tensor([0.0, 6000.0, 1e4])).tolist()]
    [0.16, 0.7225, 1.0]
    """

    def __init__(self, altitude_m, cover, limb_exponent=1.0, *, name: str = "custom"):
        altitude = check_range("altitude_m", altitude_m, 0.0, unit=" m", dtype=torch.float64)
        values = check_range("cover", cover, 0.0, 1.0, dtype=torch.float64)
        if altitude.ndim != 1 or altitude.shape[0] < 2:
            raise ValueError("altitude_m must be a 1-d sequence of at least 2 nodes; got "
                             f"shape {tuple(altitude.shape)}")
        if values.shape != altitude.shape:
            raise ValueError(f"cover must have the shape of altitude_m {tuple(altitude.shape)}; "
                             f"got {tuple(values.shape)}")
        if bool((torch.diff(altitude.detach()) <= 0.0).any()):
            raise ValueError("altitude_m must be strictly increasing; got "
                             f"{altitude.detach().tolist()}")
        if bool((torch.diff(values.detach()) > 0.0).any()):
            raise ValueError("cover (the fraction with cloud tops above each altitude) must "
                             f"not increase with altitude; got {values.detach().tolist()}")
        exponent = check_range("limb_exponent", limb_exponent, 0.0, 1000.0,
                               dtype=torch.float64)
        if exponent.ndim != 0:
            raise ValueError("limb_exponent must be a number or a 0-d tensor; got shape "
                             f"{tuple(exponent.shape)}")
        self.altitude_m = altitude.detach()
        self.cover = values
        self.limb_exponent = exponent
        self.name = str(name)

    @property
    def kink_altitudes_m(self) -> tuple[float, ...]:
        """Node altitudes [m], where :meth:`clear_fraction` has kinks (quadrature splits)."""
        return tuple(float(z) for z in self.altitude_m)

    @property
    def requires_grad(self) -> bool:
        """Whether the cover or the exponent requires a gradient."""
        return bool(self.cover.requires_grad or self.limb_exponent.requires_grad)

    def cover_at(self, altitude_m: torch.Tensor) -> torch.Tensor:
        """Nadir fraction ``f`` [1] with cloud tops above ``altitude_m`` [m] (any shape)."""
        z = self.altitude_m.to(altitude_m.dtype)
        cover = self.cover.to(altitude_m.dtype)
        index = torch.clamp(torch.searchsorted(z, altitude_m.detach().contiguous(),
                                               right=True), 1, z.shape[0] - 1)
        z0, z1 = z[index - 1], z[index]
        t = torch.clamp((altitude_m - z0) / (z1 - z0), 0.0, 1.0)
        return cover[index - 1] + t * (cover[index] - cover[index - 1])

    def clear_fraction(self, periapsis_m: torch.Tensor) -> torch.Tensor:
        """Clear-line-of-sight probability ``(1 - f(h))^n`` [1] of rays with periapsis ``h``.

        Parameters
        ----------
        periapsis_m : Tensor (...)
            Lowest altitude of the rays [m].

        Returns
        -------
        Tensor (...)
            In [0, 1], dtype of ``periapsis_m``; exactly 0 where ``f = 1`` and ``n > 0``
            (finite gradients there).
        """
        clear = 1.0 - self.cover_at(periapsis_m)
        exponent = self.limb_exponent.to(periapsis_m.dtype)
        positive = clear > 0.0
        safe = torch.where(positive, clear, torch.ones_like(clear))
        return torch.where(positive, safe ** exponent,
                           torch.zeros_like(clear) if float(exponent.detach()) > 0.0
                           else torch.ones_like(clear))

    def parameters_dict(self) -> dict:
        """Return nodes, cover and exponent (for Dataset attributes)."""
        return {"name": self.name, "altitude_m": self.altitude_m.tolist(),
                "cover": self.cover.detach().tolist(),
                "limb_exponent": float(self.limb_exponent.detach())}

    def __repr__(self) -> str:
        """Name, node count and exponent."""
        return (f"LimbCloudCover(name={self.name!r}, nodes={self.altitude_m.shape[0]}, "
                f"limb_exponent={float(self.limb_exponent.detach()):.4g})")


def _spline_slope(coefficients: torch.Tensor, s: torch.Tensor):
    """Value and derivative d/ds of :func:`_spline_coefficients` at ``s`` -> (*s.shape, C)."""
    n = coefficients.shape[0]
    x = torch.clamp(s, 0.0, 1.0) * n
    i = torch.clamp(torch.floor(x), 0, n - 1).long()
    t = (x - i.to(x.dtype)).unsqueeze(-1)
    rows = coefficients.index_select(0, i.reshape(-1)).reshape(*i.shape, 4, -1)
    c0, c1, c2, c3 = rows.unbind(-2)
    return c0 + t * (c1 + t * (c2 + t * c3)), n * (c1 + t * (2.0 * c2 + 3.0 * t * c3))


def _apparent_angle(profile: RingProfile, tables, s, centre, scale, radius: float,
                    slope: bool = False):
    """Apparent angle ``a(beta(s))`` of the ring seen from the points [rad] (and d/ds).

    ``centre`` and ``scale`` broadcast with ``s``.
    """
    if not slope:
        deviation = _spline(tables["deviation"], s)[..., 0]
        return torch.asin((radius + profile.beta(s)) / centre) - scale * deviation
    deviation, ddev = (x[..., 0] for x in _spline_slope(tables["deviation"], s))
    beta, dbeta_ds = profile.grid.beta_and_slope(s)
    b = radius + beta
    return (torch.asin(b / centre) - scale * deviation,
            dbeta_ds / torch.sqrt((centre - b) * (centre + b)) - scale * ddev)


def _fold_tops(profile: RingProfile, tables, centre, scale, radius: float, coarse,
               edges) -> torch.Tensor:
    """Local maxima of ``a(s)`` below the kinks where the bending grows upwards -> (n, F).

    Just below a kink whose upper layer has the steeper refractivity gradient (the U.S.
    1976 tropopause, 20, 32 and 71 km) the bending grows with the impact altitude like
    ``-sqrt(beta_j - beta)``, faster than the geometric term: ``a(beta)`` folds back
    (the 11 km fold spans ~80 m of impact altitude and ~1e-4 rad of ``a`` at the Moon).
    On the graded table ``d beta / d s = 0`` at the kink, so ``a'`` there is
    ``-k delta'`` and the fold is known from the table. An edge of ``F`` is crossed more
    than once near a fold only if it lies between ``a`` at the kink and the fold's top,
    which is below ``a(kink) + k (delta(kink) - delta(start of the rise))`` (tested with
    twice that rise, a margin for the spline between the rows); for those points the top
    (``a' = 0``) is found by bisection on the rising stretch, for the others the kink
    itself is returned (``coarse``: ``a`` at the bracket nodes).
    """
    n = centre.shape[0]
    tops = []
    for column, rise, lower, upper in tables["folds"]:
        a_kink = coarse[:, column:column + 1]
        window = (edges >= a_kink) & (edges <= a_kink + 2.0 * rise * scale[:, None])
        top = upper.expand(n).clone()
        need = torch.nonzero(window.any(dim=1)).squeeze(-1)
        if need.numel():
            c, k = centre[need], scale[need]
            lo, hi = lower.expand(need.shape[0]), upper.expand(need.shape[0])
            for _ in range(_FOLD_STEPS):
                mid = 0.5 * (lo + hi)
                _, da = _apparent_angle(profile, tables, mid, c, k, radius, slope=True)
                lo, hi = torch.where(da > 0, mid, lo), torch.where(da > 0, hi, mid)
            top[need] = 0.5 * (lo + hi)
        tops.append(top)
    if not tops:
        return centre.new_zeros((n, 0))
    return torch.stack(tops, dim=-1)


def _breakpoints(profile: RingProfile, tables, centre, separation, sun_radius, scale,
                 radius: float) -> torch.Tensor:
    """Table coordinates ``s`` where ``a(beta(s))`` crosses the edges of ``F`` -> (n, C).

    ``a`` is monotone between the bracket nodes (every ``_COARSE_STRIDE``-th row, the
    kinks, and the fold tops of :func:`_fold_tops`): each sign change of ``a - edge``
    between two nodes is one crossing, refined by safeguarded Newton steps on the cubic
    spline (a step that leaves the bracket bisects it; converged to ~1e-13 in ``s``). An
    edge can be crossed up to three times near a fold. Rows are padded with 1.0 (``C`` is
    the largest number of crossings of a point).
    """
    edges = torch.stack([-(separation + sun_radius), -(separation - sun_radius).abs(),
                         (separation - sun_radius).abs(), separation + sun_radius], dim=-1)
    n = centre.shape[0]
    nodes_s = tables["nodes_s"].expand(n, -1)
    coarse = (torch.asin((radius + tables["nodes_beta"]) / centre[:, None])
              - scale[:, None] * tables["nodes"])
    tops = _fold_tops(profile, tables, centre, scale, radius, coarse, edges)
    if tops.shape[1]:
        a_tops = _apparent_angle(profile, tables, tops, centre[:, None], scale[:, None],
                                 radius)
        nodes_s, order = torch.sort(torch.cat([nodes_s, tops], dim=1), dim=1)
        coarse = torch.cat([coarse, a_tops], dim=1).gather(1, order)
    below = coarse[:, :, None] <= edges[:, None, :]  # (n, K, 4)
    point, interval, edge = torch.nonzero(below[:, :-1] != below[:, 1:], as_tuple=True)
    if point.numel() == 0:
        return centre.new_ones((n, 0))
    target = edges[point, edge]
    lo, hi = nodes_s[point, interval], nodes_s[point, interval + 1]
    a_lo, a_hi = coarse[point, interval], coarse[point, interval + 1]
    rising = a_hi > a_lo
    s = lo + (hi - lo) * ((target - a_lo) / (a_hi - a_lo)).clamp(0.0, 1.0)
    centre, scale = centre[point], scale[point]
    for _ in range(_ROOT_STEPS):
        a, da = _apparent_angle(profile, tables, s, centre, scale, radius, slope=True)
        excess = a - target
        past = (excess > 0) == rising  # s lies above the crossing
        lo, hi = torch.where(past, lo, s), torch.where(past, s, hi)
        newton = s - excess / torch.where(da != 0, da, 1.0)
        inside = (newton >= lo) & (newton <= hi) & (da != 0)
        s = torch.where(inside, newton, 0.5 * (lo + hi))
    count = torch.bincount(point, minlength=n)
    first = torch.cumsum(count, 0) - count
    slot = torch.arange(point.numel()) - first[point]
    result = centre.new_ones((n, int(count.max())))
    result[point, slot] = s
    return result


def _ring_chunk(profile: RingProfile, centre, sun_radius, separation, scale, coefficients,
                n_ring: int, n_arc: int, radius: float, n_split: int = 1,
                limb=None) -> torch.Tensor:
    """Ring integral for 1-D tensors of points -> (n_point, n_batch, n_wl), unnormalised.

    Only the non-empty pieces of the ``beta`` integral (between breakpoints of ``F``, the
    terrain and cloud kinks) are integrated: (point, piece) pairs are gathered, integrated
    and summed back per point. ``limb``: ``(position_angles (n_angle,), window)``: for
    every point at each of these position angles, only the part of the limb where
    ``window.weight(limb position angle)`` is non-zero -> (n_point, n_angle, n_batch, n_wl).
    """
    dtype = centre.dtype
    tables = profile.tables(dtype)
    n_point = centre.shape[0]
    with torch.no_grad():
        # the breakpoints of F depend on the geometry and the bending only, and the
        # integrand is continuous there: their motion adds nothing to a derivative
        breaks = _breakpoints(profile, tables, centre, separation, sun_radius, scale, radius)
    # pieces between the breakpoints of F and the splits (the cloud top's keeps its graph:
    # the nodes move with it, see RingProfile); only the lit ones, where the circle of
    # angle |a| meets the solar disc, are integrated
    ends = [centre.new_zeros((n_point, 1)), breaks, centre.new_ones((n_point, 1))]
    ends += [split.reshape(1, 1).expand(n_point, 1) for split in
             profile.split_coordinates(dtype)]
    bounds = torch.sort(torch.cat(ends, dim=1), dim=1).values
    lo, hi = bounds[:, :-1], bounds[:, 1:]
    with torch.no_grad():
        middle = _apparent_angle(profile, tables, 0.5 * (lo + hi), centre[:, None],
                                 scale[:, None], radius).abs()
        lit = (middle < (separation + sun_radius)[:, None]) & (
            (separation < sun_radius)[:, None] | (middle > (separation - sun_radius)[:, None]))
    point, piece = torch.nonzero((hi > lo).detach() & lit, as_tuple=True)
    lo, hi = lo[point, piece], hi[point, piece]  # (n_pair,)
    if n_split > 1:  # composite rule: equal sub-pieces
        fraction = torch.arange(n_split + 1, dtype=dtype) / n_split
        edges_s = lo.unsqueeze(-1) + (hi - lo).unsqueeze(-1) * fraction
        lo, hi = edges_s[..., :-1], edges_s[..., 1:]  # (n_pair, n_split)
    else:
        lo, hi = lo[:, None], hi[:, None]
    x, w = _unit_gauss(n_ring)
    t = torch.as_tensor(x, dtype=dtype)
    wt = torch.as_tensor(w, dtype=dtype)
    shape = 0.5 * (1.0 - torch.cos(math.pi * t))
    slope = 0.5 * math.pi * torch.sin(math.pi * t) * wt
    s = (lo.unsqueeze(-1) + (hi - lo).unsqueeze(-1) * shape).flatten(1)  # (n_pair, m)
    ds = ((hi - lo).unsqueeze(-1) * slope).flatten(1)
    centre, sun_radius, separation, scale = (x.index_select(0, point)[:, None] for x in
                                             (centre, sun_radius, separation, scale))
    coefficients = tuple(c.index_select(0, point)[:, None] for c in coefficients)
    values = _spline(tables["all"], s)  # (n_pair, m, 2 + rank)
    deviation, periapsis = values[..., 0], values[..., 1]
    beta, dbeta_ds = profile.grid.beta_and_slope(s)
    b = radius + beta
    a = torch.asin(b / centre) - scale * deviation
    arc = solar_arc_integral(a.abs(), sun_radius, separation, coefficients, n_nodes=n_arc,
                             azimuth_weight=_limb_weight(limb, a))
    solid = b / (centre * torch.sqrt((centre - b) * (centre + b)))
    weight = solid * dbeta_ds * ds
    weight = weight * _ray_weight(periapsis, profile)
    # exp(-max(tau, 0)) in place on the (n_pair, m, n_batch, n_wl) temporary
    factors = values[..., 2:].reshape(*values.shape[:-1], profile.n_batch, profile.rank)
    transmittance = factors @ -tables["basis"]
    if transmittance.requires_grad:
        transmittance = torch.exp(torch.clamp(transmittance, max=0.0))
    else:
        transmittance = transmittance.clamp_(max=0.0).exp_()
    if limb is None:
        pairs = torch.einsum("pm,pmbl->pbl", weight * arc, transmittance)
    else:  # arc (n_pair, m, n_angle): one beta integral, every position angle
        pairs = torch.einsum("pma,pmbl->pabl", weight.unsqueeze(-1) * arc, transmittance)
    return pairs.new_zeros((n_point, *pairs.shape[1:])).index_add(0, point, pairs)


def _limb_weight(limb, apparent: torch.Tensor):
    """Weights of the arc's azimuths for a window on the limb (None without one).

    A ray at apparent angle ``a > 0`` left the limb at position angle ``angle ± psi`` (the
    side of the Sun's offset, which is the point's own position angle around the axis), one
    with ``a < 0`` on the opposite side, ``angle + pi ± psi``. Returns weights
    ``(n_pair, m, n_angle, n_arc)`` for arc azimuths ``(n_pair, m, n_arc)``.
    """
    if limb is None:
        return None
    angles, window = limb
    far = math.pi * (apparent < 0).to(apparent.dtype).detach()
    base = (angles.to(apparent.dtype) + far.unsqueeze(-1)).unsqueeze(-1)  # (p, m, angle, 1)

    def weight(psi):
        psi = psi.unsqueeze(-2)
        return 0.5 * (window.weight(base + psi) + window.weight(base - psi))

    return weight


def ring_illuminance(profile: RingProfile, centre_distance_m, sun_radius_rad, separation_rad,
                     deviation_scale, coefficients, occluder_radius_m: float,
                     n_ring: int = DEFAULT_RING_NODES,
                     n_arc: int = DEFAULT_ARC_NODES,
                     n_split: int = 1, position_angle_rad=None,
                     limb_window=None) -> torch.Tensor:
    """Irradiance through the atmosphere ring, in units of the central solar radiance.

    Parameters
    ----------
    profile : RingProfile
        Tabulated bending and optical depth.
    centre_distance_m, sun_radius_rad, separation_rad, deviation_scale : Tensor (...)
        ``L`` [m], ``rho_s`` [rad], ``sigma`` [rad] and ``k`` [1] (module docstring).
    coefficients : tuple of Tensor (...)
        Limb-darkening polynomial ``(a0, a1, a2)``.
    occluder_radius_m : float
        Planet radius ``R`` [m].
    n_ring, n_arc : int
        Gauss–Legendre nodes per ring piece and on the solar arc.
    n_split : int
        Equal sub-pieces per piece (composite rule).
    position_angle_rad : Tensor (n_angle,), optional
        With ``limb_window``: position angles around the shadow's axis [rad] (from the
        direction in which the window's position angles are counted) at which every point
        is evaluated; the result gets an ``n_angle`` dimension before ``n_batch``.
    limb_window : object with ``weight(position_angle_rad) -> Tensor``, optional
        Keep only the light through the part of the limb where the weight is non-zero
        (e.g. :class:`skytorch.eclipse.terminator.LimbLatitudeWindow`, one latitude band).

    Returns
    -------
    Tensor (..., n_batch, n_wavelength) or (..., n_angle, n_batch, n_wavelength)
        Ring irradiance [sr] (divide by :func:`solar_normalisation` for I / I_sun), per
        member of the profile's batch of atmospheres (``n_batch = 1`` for one).
    """
    if (limb_window is None) != (position_angle_rad is None):
        raise ValueError("limb_window and position_angle_rad go together; got "
                         f"limb_window={limb_window!r}, position_angle_rad "
                         f"{'given' if position_angle_rad is not None else 'None'}")
    angles = None
    if position_angle_rad is not None:
        angles = torch.as_tensor(position_angle_rad).detach().reshape(-1)
    tensors = torch.broadcast_tensors(centre_distance_m, sun_radius_rad, separation_rad,
                                      deviation_scale, *coefficients)
    shape = tensors[0].shape
    flat = [x.reshape(-1) for x in tensors]
    per_angle = () if angles is None else (angles.shape[0],)
    n_wl = profile.optical_depth.shape[-1]
    centre, sun_radius, separation, scale = flat[:4]
    with torch.no_grad():
        # points whose ring cannot see the Sun: the apparent angles of the ring lie
        # between these bounds (a is not monotone below some kinks, see _fold_tops) and
        # miss the solar disc (both signs of a)
        deviation = profile.deviation_rad.to(centre.dtype)
        a_low = (torch.asin((occluder_radius_m + profile.beta_min_m) / centre)
                 - scale * deviation.max())
        a_high = (torch.asin((occluder_radius_m + profile.beta_top_m) / centre)
                  - scale * deviation.min())
        gap = (separation - sun_radius).abs()
        outer = separation + sun_radius
        dark = (a_low > outer) | (a_high < -outer) | (
            (separation >= sun_radius) & (a_low > -gap) & (a_high < gap))
        active = torch.nonzero(~dark).squeeze(-1)
    n_batch = profile.n_batch
    result = flat[0].new_zeros((flat[0].shape[0], *per_angle, n_batch, n_wl))
    if active.numel() == 0:
        return (result.reshape(*shape, *per_angle, n_batch, n_wl)
                + 0.0 * flat[0].reshape(*shape, *(1,) * (len(per_angle) + 2)))
    chosen = [x.index_select(0, active) for x in flat]
    limb = None if angles is None else (angles, limb_window)
    pieces = []
    for start in range(0, chosen[0].shape[0], _CHUNK):
        part = [x[start:start + _CHUNK] for x in chosen]
        pieces.append(_ring_chunk(profile, *part[:4], tuple(part[4:]), n_ring, n_arc,
                                  occluder_radius_m, n_split, limb))
    result = result.index_put((active,), torch.cat(pieces))
    return result.reshape(*shape, *per_angle, n_batch, n_wl)


def _broadcast_batch(values: torch.Tensor, batch_shape: tuple[int, ...]) -> torch.Tensor:
    """``(*G, n_batch, n_wl)`` per point and member -> ``(*broadcast(G, B), n_wl)``.

    Picks, for every element of the broadcast shape, the point and the member that torch's
    broadcasting pairs there.
    """
    points = values.shape[:-2]
    shape = broadcast_shape(points, batch_shape)
    flat = values.reshape(-1, *values.shape[-2:])
    point = torch.arange(flat.shape[0]).reshape(points).expand(shape)
    member = torch.arange(flat.shape[1]).reshape(batch_shape).expand(shape)
    return flat[point, member]


def _check_wavelength(wavelength_nm, dtype) -> torch.Tensor:
    """Return the wavelengths as a checked 1-D tensor [nm].

    Finite and within the atmosphere's range [nm]
    (:data:`skytorch.atmosphere.rayleigh.WAVELENGTH_RANGE_NM`, also for an airless occluder, so that
    a shadow accepts one range).
    """
    wavelength = check_range("wavelength_nm", wavelength_nm, *WAVELENGTH_RANGE_NM,
                             unit=" nm", dtype=dtype)
    if wavelength.ndim > 1:
        raise ValueError("wavelength_nm must be a number or a 1-D array; got shape "
                         f"{tuple(wavelength.shape)}")
    wavelength = wavelength.reshape(-1)
    if wavelength.numel() == 0:
        raise ValueError("wavelength_nm must hold at least one wavelength; got none")
    return wavelength


class _NoRefraction:
    """Wraps an atmosphere with its refractivity switched off (straight rays)."""

    def __init__(self, atmosphere):
        self._atmosphere = atmosphere
        self.planet_radius_m = atmosphere.planet_radius_m
        self.top_altitude_m = atmosphere.top_altitude_m
        self.top_radius_m = atmosphere.top_radius_m
        self.batch_shape = getattr(atmosphere, "batch_shape", torch.Size())

    def refractivity(self, altitude_m, wavelength_nm=None):
        return torch.zeros_like(torch.as_tensor(altitude_m))

    def extinction_coefficient(self, altitude_m, wavelength_nm):
        return self._atmosphere.extinction_coefficient(altitude_m, wavelength_nm)

    def constituents(self, wavelength_nm, dtype=None):
        # the straight rays' optical depths from the species' path columns, as for the
        # refracted ones (band laws of the gases on the whole path)
        return self._atmosphere.constituents(wavelength_nm, dtype)

    def profiles(self, dtype=torch.float64):
        return self._atmosphere.profiles(dtype)


def _atmosphere_gradients(atmosphere) -> list[str]:
    """Names of the parameters of ``atmosphere`` that require a gradient (none if off)."""
    if atmosphere is None or not torch.is_grad_enabled():
        return []
    return [name for name, value in (*atmosphere.named_parameters(),
                                     *atmosphere.named_buffers()) if value.requires_grad]


#: atmosphere parameters that change the extinction only, not the refractivity: the
#: ring's gradient with respect to them is complete (the bending, the lowest ray and the
#: quadrature nodes do not depend on them)
EXTINCTION_PARAMETERS = ("angstrom_beta", "angstrom_alpha", "aerosol_scale_height_m",
                         "aerosol_single_scattering_albedo", "aerosol_asymmetry", "ozone_du",
                         "ozone_peak_altitude_m", "ozone_half_width_m", "ozone_temperature_k",
                         "stratospheric_aerosol_optical_depth",
                         "stratospheric_aerosol_altitude_m", "stratospheric_aerosol_width_m",
                         "precipitable_water_cm")


def _refuse_atmosphere_gradients(atmosphere, what: str) -> None:
    """Raise if a parameter of ``atmosphere`` requires a gradient that ``what`` would drop.

    Used where the computation tabulates without gradients (the single-scattering kernel,
    the (u, v) shadow table): refuse rather than detach silently.
    """
    names = _atmosphere_gradients(atmosphere)
    if names:
        raise ValueError(
            f"{what} is not differentiable with respect to the atmosphere: atmosphere "
            f"parameters {names} require a gradient; Shadow.relative_illuminance (without "
            "scattering) is. Pass detached values, e.g. Atmosphere.earth(turbidity="
            "t.detach()), or take derivatives by finite differences")


class Shadow(nn.Module):
    """Shadow cone of a spherical occluder with (optionally) a refracting atmosphere.

    Parameters
    ----------
    occluder_radius_m : float
        Radius of the solid body [m] (overridden by the atmosphere's planet radius).
    sun_distance_m : float
        Default Sun–occluder distance [m].
    atmosphere : Atmosphere or None or False
        The occluder's atmosphere; ``None`` or ``False``: airless. A batched atmosphere
        (e.g. ``Atmosphere.earth(turbidity=t[:, None], ozone_du=o[None, :])``, batch shape
        ``B``) is evaluated for all members at once; its members must share the
        refractivity (parameters of the extinction only, such as turbidity and ozone).
        Parameters that require a gradient (``Atmosphere.earth(turbidity=t)`` with
        ``t.requires_grad``) give :meth:`relative_illuminance` a gradient with respect to
        them through the optical depths of the ring (the ring table is then rebuilt on
        every call instead of cached). Only the extinction parameters
        (:data:`EXTINCTION_PARAMETERS`) may require one with refraction on (the bending
        is not differentiated); ``scattering=True`` refuses them all (``ValueError``).
    sun_radius_m : float
        Solar radius [m].
    refraction, extinction : bool
        Switch the bending and the optical depth of the ring on or off.
    cloud_top_altitude_m : float or Tensor ()
        Cloud tops [m]: rays whose lowest point is below are blocked (0: the ground).
        Given as a tensor it is a parameter of the model: the deck is then a step in the
        ray weight (``1 - cloud_fraction`` below the tops, also for a closed deck) on a
        ring table that starts at the ground, and the ring quadrature is split at the ray
        grazing the tops with nodes that move with it, so :meth:`relative_illuminance`
        (and :class:`~skytorch.eclipse.shadow_table.ShadowTable`) has the exact
        derivative with respect to it (the boundary term of the step; a step inside the
        integrand alone would give zero). The value is the same model as for a float
        (a closed deck as the lower end of the table): they differ by the table's
        interpolation only (``docs/eclipse_shadow.md``). Not differentiable at 0 (the
        step is then at the lower end of the integral: zero gradient, one-sided).
    cloud_fraction : float
        Fraction of the limb covered by those clouds (1: a closed deck; 0.5: half the
        rays below the cloud tops pass).
    cloud_cover : LimbCloudCover, optional
        A cloud profile instead of the single deck: rays with periapsis ``h`` pass with
        its clear-line-of-sight probability (``LimbCloudCover.clear_fraction``); the
        ring quadrature is split at the rays grazing its nodes. Its cover and exponent
        given as tensors that require a gradient keep it in :meth:`relative_illuminance`
        and :class:`~skytorch.eclipse.shadow_table.ShadowTable` (not with
        ``scattering=True``: ``ValueError``). Exclusive with a cloud deck
        (``cloud_top_altitude_m > 0``).
    terrain_height_m : float or None
        Mean terrain height for the linear attenuation of rays with periapsis between 0 and
        twice this height [m] (Schneegans et al. 2025 §5.2); ``None``: off.
    limb_darkening, law
        Solar limb darkening (see :func:`sun_visible_fraction`).
    n_altitude : int
        Rows of the ring table (uniform in ``sqrt`` of the impact altitude).
    n_ring, n_arc : int
        Gauss–Legendre nodes per piece of the ring integral and on the solar arc.
        ``n_ring=None`` (default): 12, or 16 when the refractivity profile has kinks.
    n_split : int or None
        Equal sub-pieces per piece of the ring integral. ``None`` (default): 2, or 1 when
        the refractivity profile has kinks (the US 1976 layer boundaries already split the
        integral; 16 x 1 nodes halve the cost of 12 x 2 at a 99th-percentile error of 7e-5
        against 64 x 12, see ``docs/eclipse.md``).
    trace_nodes : int
        Gauss–Legendre nodes of the Bouguer ray integrals.
    scattering : bool
        Add the sunlight scattered once by the atmosphere towards the point
        (:mod:`skytorch.eclipse.shadow_scattering`).
    scattering_resolution : float
        Factor on the node counts of the scattered component (impact parameter 32,
        in-plane Sun angle 64, path 48, ring azimuth 12 at 1).
    name : str
        Label for Datasets.

    Examples
    --------
    >>> shadow = Shadow.earth(atmosphere=False)
    >>> round(float(shadow.relative_illuminance(3.844e8, 4.0e6, 550.0)[0]), 6)
    0.0
    """

    def __init__(self, *, occluder_radius_m: float, sun_distance_m: float, atmosphere=None,
                 sun_radius_m: float = SUN_RADIUS_M, refraction: bool = True,
                 extinction: bool = True, cloud_top_altitude_m: float = 0.0,
                 cloud_fraction: float = 1.0, cloud_cover: LimbCloudCover | None = None,
                 terrain_height_m: float | None = None, limb_darkening=0.6,
                 law: str = "linear", n_altitude: int = DEFAULT_N_ALTITUDE,
                 n_ring: int | None = None, n_arc: int = DEFAULT_ARC_NODES,
                 n_split: int | None = None, trace_nodes: int = 64,
                 scattering: bool = False, scattering_resolution: float = 1.0,
                 name: str = "custom"):
        super().__init__()
        if atmosphere is False:
            atmosphere = None
        if atmosphere is not None:
            from skytorch.atmosphere import Atmosphere

            if not isinstance(atmosphere, Atmosphere):
                raise TypeError("atmosphere must be a skytorch Atmosphere, None or False; got "
                                f"{type(atmosphere).__name__}: {atmosphere!r:.60}")
        self.batch_shape = (tuple(getattr(atmosphere, "batch_shape", ()))
                            if atmosphere is not None else ())
        self.atmosphere = atmosphere
        radius = atmosphere.planet_radius_m if atmosphere is not None else occluder_radius_m
        self.occluder_radius_m = float(check_positive("occluder_radius_m", radius, unit=" m"))
        self.top_radius_m = (atmosphere.top_radius_m if atmosphere is not None
                             else self.occluder_radius_m)
        self.sun_distance_m = float(check_positive("sun_distance_m", sun_distance_m,
                                                   unit=" m"))
        self.sun_radius_m = float(check_positive("sun_radius_m", sun_radius_m, unit=" m"))
        self.refraction = check_flag("refraction", refraction)
        self.extinction = check_flag("extinction", extinction)
        top = atmosphere.top_altitude_m if atmosphere is not None else 0.0
        cloud_top = check_range("cloud_top_altitude_m", cloud_top_altitude_m, 0.0,
                                max(top, 0.0), unit=" m", dtype=torch.float64)
        if cloud_top.ndim != 0:
            raise ValueError("cloud_top_altitude_m must be a number or a 0-d tensor; got "
                             f"shape {tuple(cloud_top.shape)}")
        self.cloud_top_altitude_m = float(cloud_top.detach())
        #: the cloud-top altitude as a tensor parameter (None when given as a number)
        self.cloud_top_parameter = (cloud_top if isinstance(cloud_top_altitude_m, torch.Tensor)
                                    else None)
        self.cloud_fraction = float(check_range("cloud_fraction", cloud_fraction, 0.0, 1.0))
        if cloud_cover is not None:
            if not isinstance(cloud_cover, LimbCloudCover):
                raise TypeError("cloud_cover must be a LimbCloudCover or None; got "
                                f"{type(cloud_cover).__name__}: {cloud_cover!r:.60}")
            if self.cloud_top_parameter is not None or self.cloud_top_altitude_m > 0.0:
                raise ValueError("give either a cloud deck (cloud_top_altitude_m > 0) or a "
                                 "cloud profile (cloud_cover), not both; got "
                                 f"cloud_top_altitude_m={self.cloud_top_altitude_m:.6g} m "
                                 f"and cloud_cover={cloud_cover!r}")
        self.cloud_cover = cloud_cover
        if terrain_height_m is not None:
            terrain_height_m = float(check_positive("terrain_height_m", terrain_height_m,
                                                    unit=" m"))
        self.terrain_height_m = terrain_height_m
        check_choice("law", law, LIMB_DARKENING_LAWS)
        self.law = law
        self.register_buffer("limb_darkening",
                             as_tensor("limb_darkening", limb_darkening).to(torch.float64))
        _law_coefficients(law, self.limb_darkening, torch.float64)  # validate
        self.n_altitude = check_int("n_altitude", n_altitude, low=8)
        self.n_ring = None if n_ring is None else check_int("n_ring", n_ring, low=2, high=256)
        self.n_arc = check_int("n_arc", n_arc, low=2, high=256)
        self.n_split = (None if n_split is None
                        else check_int("n_split", n_split, low=1, high=64))
        self.trace_nodes = check_int("trace_nodes", trace_nodes, low=4)
        self.scattering = check_flag("scattering", scattering)
        self.scattering_resolution = float(check_positive(
            "scattering_resolution", scattering_resolution))
        self.name = str(name)
        self._profiles: dict = {}
        self._scattering_profiles: dict = {}

    # ------------------------------------------------------------------ presets
    @classmethod
    def earth(cls, atmosphere=None, **kwargs) -> Shadow:
        """Return the Earth's shadow; ``atmosphere=None`` uses ``Atmosphere.earth()``.

        Pass ``atmosphere=False`` for the airless Earth (radius 6371 km).
        """
        return cls._preset("earth", atmosphere, EARTH_MEAN_RADIUS_M, ASTRONOMICAL_UNIT_M,
                           kwargs)

    @classmethod
    def mars(cls, atmosphere=None, **kwargs) -> Shadow:
        """Return the shadow of Mars at its mean distance from the Sun (1.5237 AU).

        ``atmosphere=None`` uses ``Atmosphere.mars()``; ``False`` gives the airless planet.
        """
        return cls._preset("mars", atmosphere, MARS_MEAN_RADIUS_M, MARS_SEMI_MAJOR_AXIS_M,
                           kwargs)

    @classmethod
    def _preset(cls, planet, atmosphere, radius_m, sun_distance_m, kwargs) -> Shadow:
        """Shadow of ``planet`` (``Atmosphere.<planet>()`` when ``atmosphere`` is None)."""
        if atmosphere is None:
            from skytorch.atmosphere import Atmosphere

            atmosphere = getattr(Atmosphere, planet)()
        options = {"occluder_radius_m": radius_m, "sun_distance_m": sun_distance_m,
                   "name": planet}
        options.update(kwargs)
        return cls(atmosphere=atmosphere, **options)

    def extra_repr(self) -> str:
        """Name, radii [m] and the effects modelled, for the module's repr."""
        return (f"name={self.name!r}, radius={self.occluder_radius_m:.0f} m, "
                f"top={self.top_radius_m:.0f} m, refraction={self.refraction}, "
                f"extinction={self.extinction}, scattering={self.scattering}")

    def parameters_dict(self) -> dict:
        """Return settings of this shadow model (for Dataset attributes)."""
        result = {
            "shadow": self.name, "occluder_radius_m": self.occluder_radius_m,
            "top_radius_m": self.top_radius_m, "sun_distance_m": self.sun_distance_m,
            "sun_radius_m": self.sun_radius_m, "refraction": self.refraction,
            "extinction": self.extinction, "cloud_top_altitude_m": self.cloud_top_altitude_m,
            "cloud_fraction": self.cloud_fraction,
            "cloud_cover": ("none" if self.cloud_cover is None
                            else self.cloud_cover.parameters_dict()),
            "terrain_height_m": self.terrain_height_m if self.terrain_height_m else "none",
            "limb_darkening": self.limb_darkening.tolist(), "limb_darkening_law": self.law,
            "n_altitude": self.n_altitude, "n_arc": self.n_arc,
            "scattering": self.scattering,
            "scattering_resolution": self.scattering_resolution,
        }
        result["n_ring"], result["n_split"] = self.ring_quadrature()
        if self.atmosphere is not None and hasattr(self.atmosphere, "parameters_dict"):
            result["atmosphere"] = self.atmosphere.parameters_dict()
        return result

    # ------------------------------------------------------------------ ring table
    def ring_quadrature(self, profile: RingProfile | None = None) -> tuple[int, int]:
        """Nodes per piece and sub-pieces of the ring integral (``profile``: its kinks)."""
        kinked = bool(profile.kink_betas_m if profile is not None
                      else getattr(self.atmosphere, "refractivity_kinks_m", ()))
        n_ring = self.n_ring or (DEFAULT_RING_NODES_KINKED if kinked else DEFAULT_RING_NODES)
        n_split = self.n_split or (DEFAULT_SPLIT_KINKED if kinked else DEFAULT_SPLIT)
        return n_ring, n_split

    def ring_profile(self, wavelength_nm) -> RingProfile | None:  # noqa: C901 (one cached build)
        """Tabulated ring (bending, optical depth) for these wavelengths (cached).

        Returns ``None`` for an airless occluder.
        """
        if self.atmosphere is None:
            return None
        wavelength = _check_wavelength(wavelength_nm, torch.float64)
        key = tuple(round(float(x), 9) for x in wavelength)
        # with atmosphere parameters that require a gradient the optical depths carry it
        # and the profile is rebuilt on every call (a cached graph would be stale)
        requiring = _atmosphere_gradients(self.atmosphere)
        cloud_parameter = self.cloud_top_parameter
        cloud_gradient = (cloud_parameter is not None and cloud_parameter.requires_grad
                          and torch.is_grad_enabled())
        differentiable = bool(requiring) or cloud_gradient
        bending = [name for name in requiring if name not in EXTINCTION_PARAMETERS]
        if bending and self.refraction:
            raise ValueError(
                "the eclipse shadow is differentiable with respect to the atmosphere's "
                f"extinction parameters {EXTINCTION_PARAMETERS} only; atmosphere parameters "
                f"{bending} require a gradient and change the refractivity (the bending of "
                "the grazing rays is not differentiated): pass them detached, or use "
                "refraction=False")
        if key in self._profiles and not differentiable:
            return self._profiles[key]
        atm = self.atmosphere if self.refraction else _NoRefraction(self.atmosphere)
        top = float(atm.top_altitude_m)
        # a cloud top given as a tensor is a step in the ray weight (closed or not) with a
        # split that keeps its graph; a number closes the table at a closed deck
        closed = self.cloud_fraction >= 1.0 and cloud_parameter is None
        lowest_altitude = self.cloud_top_altitude_m if closed else 0.0

        def impact_of(periapsis):
            # one value for every member of a batched atmosphere (they share the
            # refractivity, checked below on the traced table)
            rays = trace_grazing_rays(atm, periapsis_altitude_m=torch.tensor(
                periapsis, dtype=torch.float64))
            return float(rays["impact_altitude_m"].reshape(-1)[0])

        with torch.no_grad():
            beta_min = impact_of(lowest_altitude)
            splits = []
            if self.terrain_height_m is not None:
                h_t = min(2.0 * self.terrain_height_m, top)
                if h_t > lowest_altitude:
                    splits.append(impact_of(h_t))
            if (cloud_parameter is None and not closed and self.cloud_fraction > 0.0
                    and self.cloud_top_altitude_m > 0.0):
                splits.append(impact_of(self.cloud_top_altitude_m))
            if self.cloud_cover is not None:
                splits += [impact_of(z) for z in self.cloud_cover.kink_altitudes_m
                           if lowest_altitude < z < top]
            # kinks of the refractivity profile (e.g. the US 1976 layer bases): table nodes
            kinks = [impact_of(h) for h in getattr(atm, "refractivity_kinks_m", ())
                     if lowest_altitude < h < top]
            grid = _ImpactGrid(beta_min, top, self.n_altitude, kinks)
            beta = grid.beta(torch.linspace(0.0, 1.0, self.n_altitude, dtype=torch.float64))
            logger.info("tracing %d grazing rays x %d wavelengths", beta.numel(),
                        wavelength.numel())
            batch = self.batch_shape
            with torch.enable_grad() if differentiable else contextlib.nullcontext():
                rays = trace_grazing_rays(
                    atm, impact_altitude_m=beta.reshape(-1, *(1,) * len(batch)),
                    wavelength_nm=wavelength, n_nodes=self.trace_nodes)
            deviation = rays["deviation_rad"].detach().to(torch.float64).reshape(
                beta.shape[0], -1)
            periapsis = rays["contact_altitude_m"].detach().to(torch.float64).reshape(
                beta.shape[0], -1)
            # members that differ in extinction only bend alike up to the rounding of
            # the batched trace (1 ulp, differing between CPUs' vector lanes): compared
            # with a tolerance far below any difference of refractivity
            if deviation.shape[1] > 1 and not (
                    torch.allclose(deviation, deviation[:, :1].expand_as(deviation),
                                   rtol=_SAME_BENDING_RTOL, atol=0.0)
                    and torch.allclose(periapsis, periapsis[:, :1].expand_as(periapsis),
                                       rtol=0.0, atol=_SAME_PERIAPSIS_M)):
                raise ValueError("the members of the batched atmosphere bend light differently; "
                                 "Shadow batches atmospheres that differ in extinction only "
                                 "(turbidity, ozone): build one Shadow per refractivity")
            deviation, periapsis = deviation[:, 0], periapsis[:, 0]
        # the bending and the ray geometry place the nodes (no gradient needed: the
        # integrand is continuous where they move it); the optical depths keep theirs
        optical = rays["optical_depth"] if differentiable else rays["optical_depth"].detach()
        optical = optical.to(torch.float64).expand(
            beta.shape[0], *batch, wavelength.shape[0]).reshape(
            beta.shape[0], -1, wavelength.shape[0])
        if not self.extinction:
            optical = torch.zeros_like(optical)
        profile = RingProfile(beta_min, top, deviation, optical, periapsis,
                              self.terrain_height_m, splits,
                              cloud_top_m=0.0 if closed else self.cloud_top_altitude_m,
                              cloud_fraction=0.0 if closed else self.cloud_fraction,
                              kink_betas_m=grid.kinks_m,
                              cloud_split_m=self._cloud_split(atm, top),
                              cloud_cover=self.cloud_cover)
        if not differentiable:
            self._profiles[key] = profile
        return profile

    def _cloud_split(self, atm, top: float):
        """Impact altitude [m] of the ray grazing a cloud-top parameter, with its graph.

        ``None`` without a cloud-top tensor, or for tops at the ground or the top of the
        atmosphere (no split inside the ring).
        """
        cloud = self.cloud_top_parameter
        if cloud is None or self.cloud_fraction <= 0.0 or not 0.0 < float(cloud.detach()) < top:
            return None
        rays = trace_grazing_rays(atm, periapsis_altitude_m=cloud)
        impact = rays["impact_altitude_m"].reshape(-1)[0]
        return impact.to(torch.float64)

    def scattering_profile(self, wavelength_nm):
        """Tabulated single-scattering kernel for these wavelengths (cached).

        Returns ``None`` for an airless occluder or with ``scattering=False``.
        """
        if self.atmosphere is None or not self.scattering:
            return None
        _refuse_atmosphere_gradients(self.atmosphere, "the scattered light (scattering=True)")
        if (self.cloud_top_parameter is not None and self.cloud_top_parameter.requires_grad
                and torch.is_grad_enabled()):
            raise ValueError("the scattered light (scattering=True) is not differentiable "
                             "with respect to cloud_top_altitude_m (its kernel is tabulated "
                             "without gradients): pass the cloud top detached, or "
                             "scattering=False")
        if (self.cloud_cover is not None and self.cloud_cover.requires_grad
                and torch.is_grad_enabled()):
            raise ValueError("the scattered light (scattering=True) is not differentiable "
                             "with respect to cloud_cover (its kernel is tabulated without "
                             "gradients): pass its cover and limb_exponent detached, or "
                             "scattering=False")
        wavelength = _check_wavelength(wavelength_nm, torch.float64)
        key = tuple(round(float(x), 9) for x in wavelength)
        if key not in self._scattering_profiles:
            self._scattering_profiles[key] = self._new_scattering_profile(wavelength)
        return self._scattering_profiles[key]

    def _new_scattering_profile(self, wavelength, impact_radius_m=None) -> ScatteringProfile:
        """Scattering kernel with this shadow's terrain, clouds and resolution.

        Over the ring's quadrature nodes, or (``impact_radius_m``) on given lines of sight.
        """
        lowest = self._lowest_line_of_sight_m()
        return ScatteringProfile(
            self.atmosphere, wavelength, lowest_altitude_m=lowest,
            ray_weight=self._scattering_ray_weight(), resolution=self.scattering_resolution,
            blocking_radius_m=self.occluder_radius_m + lowest, impact_radius_m=impact_radius_m)

    def _scattering_ray_weight(self):
        """Weight of a scattering line of sight by its tangent altitude [m] (terrain, clouds)."""
        closed = self.cloud_fraction >= 1.0
        weights = RingProfile(0.0, 1.0, torch.zeros(3), torch.zeros(3, 1), torch.zeros(3),
                              self.terrain_height_m,
                              cloud_top_m=0.0 if closed else self.cloud_top_altitude_m,
                              cloud_fraction=0.0 if closed else self.cloud_fraction,
                              cloud_cover=self.cloud_cover)
        return lambda h: _ray_weight(h, weights)

    def multiple_scattered_illuminance(self, distance_m, offset_m, tables, *,
                                       sun_distance_m=None, scattering_orders="converged",
                                       n_impact: int = 16, n_azimuth: int = 8
                                       ) -> torch.Tensor:
        """Illuminance of the light scattered two or more times into the shadow.

        Relative to the unobstructed Sun, to add to :meth:`relative_illuminance` (which
        holds the single scattering with ``scattering=True``): the final gather of the
        occluder's multiple-scattering ``tables`` along every line of sight through the
        ring (:func:`skytorch.eclipse.shadow_multiple_scattering.
        multiple_scattered_illuminance`), with this shadow's lowest line of sight, terrain
        and clouds. Seconds per point.

        Parameters
        ----------
        distance_m, offset_m : Tensor (...)
            As :meth:`relative_illuminance` [m].
        tables : ScatteringTables
            Built for this shadow's atmosphere (scalar parameters) at the wavelengths
            wanted (:func:`skytorch.atmosphere.multiple_scattering.precompute_scattering`).
        sun_distance_m : float or Tensor (...), optional
            Sun-occluder distance [m]; default the preset's.
        scattering_orders : int or "converged"
            N >= 2: the orders 2..N.
        n_impact, n_azimuth : int
            Nodes over the ring's impact parameter and azimuth.

        Returns
        -------
        Tensor (..., n_wavelength)
        """
        if self.atmosphere is None:
            raise ValueError("an airless occluder scatters no light into its shadow")
        if self.batch_shape:
            raise ValueError("multiple_scattered_illuminance takes a shadow of an atmosphere "
                             f"with scalar parameters; got batch shape {self.batch_shape}")
        dtype = common_dtype(distance_m, offset_m)
        angles = self._geometry(distance_m, offset_m, sun_distance_m, dtype)
        scale = (self.sun_distance_m if sun_distance_m is None
                 else angles["sun_distance_m"]) / angles["sun_range_m"]
        return _multiple_scattered_illuminance(
            tables, self.atmosphere, angles["centre_distance_m"], angles["separation_rad"],
            scale, lowest_altitude_m=self._lowest_line_of_sight_m(),
            ray_weight=self._scattering_ray_weight(), scattering_orders=scattering_orders,
            n_impact=n_impact, n_azimuth=n_azimuth)

    # ------------------------------------------------------------------ illuminance
    def _geometry(self, distance_m, offset_m, sun_distance_m, dtype):
        distance = check_range("distance_m", distance_m, unit=" m", dtype=dtype)
        offset = check_range("offset_m", offset_m, 0.0, unit=" m", dtype=dtype)
        sun_distance = self.sun_distance_m if sun_distance_m is None else check_positive(
            "sun_distance_m", sun_distance_m, unit=" m").to(dtype)
        shapes = {"distance_m": distance, "offset_m": offset}
        if sun_distance_m is not None:
            shapes["sun_distance_m"] = sun_distance
        check_broadcastable(**shapes)
        if self.batch_shape:
            shape = broadcast_shape(distance.shape, offset.shape,
                                    () if sun_distance_m is None else sun_distance.shape)
            try:
                broadcast_shape(shape, self.batch_shape)
            except ValueError:
                raise ValueError(
                    f"the geometry (distance_m, offset_m) of shape {tuple(shape)} does not "
                    f"broadcast with the atmosphere's batch shape {self.batch_shape}: give "
                    "it trailing singleton dimensions") from None
        angles = shadow_angles(distance, offset, sun_distance, self.sun_radius_m,
                               self.top_radius_m)
        with torch.no_grad():
            inside = angles["centre_distance_m"] <= self.top_radius_m
            if bool(inside.any()):
                index = tuple(int(i) for i in torch.nonzero(inside)[0])
                value = float(angles["centre_distance_m"][index])
                what = ("the occluder" if value <= self.occluder_radius_m
                        else "the occluder's atmosphere")
                raise ValueError(
                    f"point (distance_m, offset_m) lies inside {what}: distance from the "
                    f"centre {value:.6g} m at index {index}; valid: > {self.top_radius_m:.6g} m "
                    "(top of the atmosphere)")
        angles["sun_distance_m"] = sun_distance
        return angles

    def relative_illuminance(self, distance_m, offset_m, wavelength_nm,
                             sun_distance_m=None) -> torch.Tensor:
        """Illuminance relative to the unobstructed Sun at points in the shadow cone.

        Parameters
        ----------
        distance_m : Tensor (...)
            Distance behind the occluder's centre along the anti-Sun axis [m].
        offset_m : Tensor (...)
            Distance from the anti-Sun axis [m] (>= 0).
        wavelength_nm : float or Tensor (n_wavelength,)
            Wavelengths [nm].
        sun_distance_m : float or Tensor (...), optional
            Sun–occluder distance [m]; default the preset's.

        Returns
        -------
        Tensor (..., n_wavelength)
            ``I / I_sun`` in [0, 1] (1 outside the penumbra), dtype of the geometry inputs;
            with ``scattering=True`` the scattered light is added everywhere (up to ~1e-3
            of sunlight beside the Earth's limb, 2e-7 outside the penumbra at the Moon).
            With a batched atmosphere (batch shape ``B``) the geometry broadcasts with
            ``B`` by torch rules: ``(*broadcast(..., B), n_wavelength)``; give the
            geometry trailing singleton dims (``distance_m[..., None, None]`` for a 2-D
            ``B``) to get every point for every member, ``(..., *B, n_wavelength)``, at the
            cost of one geometry evaluation per point (the ring weights are shared by the
            members, only the transmittances differ).

        Raises
        ------
        ValueError
            For a point inside the occluder or its atmosphere.
        """
        return self._relative_illuminance(distance_m, offset_m, wavelength_nm, sun_distance_m)

    def _relative_illuminance(self, distance_m, offset_m, wavelength_nm, sun_distance_m=None,
                              profile=None, position_angle_rad=None, limb_window=None,
                              direct_light: bool = True) -> torch.Tensor:
        """:meth:`relative_illuminance` with a prepared ring profile (``None``: build it).

        With ``limb_window`` (and the points' ``position_angle_rad`` around the axis) only
        the light refracted through that part of the limb is kept (the direct sunlight
        too unless ``direct_light=False``); scattering cannot be windowed and raises.
        """
        dtype = common_dtype(distance_m, offset_m)
        wavelength = _check_wavelength(wavelength_nm, dtype)
        angles = self._geometry(distance_m, offset_m, sun_distance_m, dtype)
        n_wl = wavelength.shape[0]
        centre = angles["centre_distance_m"]
        rho_s = angles["sun_radius_rad"]
        sigma = angles["separation_rad"]
        limb = self.limb_darkening.to(dtype)
        direct = sun_visible_fraction(rho_s, angles["occluder_radius_rad"], sigma, limb,
                                      self.law)
        if not direct_light:
            direct = torch.zeros_like(direct)
        if limb_window is not None:
            position_angle_rad = self._window_angles(position_angle_rad, dtype)
        if profile is None:
            profile = self.ring_profile(wavelength)
        if profile is None:
            return direct.unsqueeze(-1).expand(*direct.shape, n_wl)
        coefficients = _law_coefficients(self.law, limb, dtype)
        scale = (self.sun_distance_m if sun_distance_m is None
                 else angles["sun_distance_m"]) / angles["sun_range_m"]
        n_ring, n_split = self.ring_quadrature(profile)
        ring = ring_illuminance(profile, centre, rho_s, sigma, scale, coefficients,
                                self.occluder_radius_m, n_ring, self.n_arc, n_split,
                                position_angle_rad=position_angle_rad,
                                limb_window=limb_window)
        normalisation = solar_normalisation(rho_s, limb, self.law)
        if position_angle_rad is not None:  # (..., n_angle, 1, n_wl): one member
            total = direct[..., None, None] + ring[..., 0, :] / normalisation[..., None, None]
            return total
        total = direct[..., None, None] + ring / normalisation[..., None, None]
        scattering = self.scattering_profile(wavelength)
        if scattering is not None:
            total = total + scattered_illuminance(scattering, centre, sigma, scale)
        if not self.batch_shape:
            return total.squeeze(-2)
        return _broadcast_batch(total, self.batch_shape)

    forward = relative_illuminance

    def _window_angles(self, position_angle_rad, dtype) -> torch.Tensor:
        """Return checked 1-D position angles; refuse a shadow a limb window cannot cut."""
        if (self.scattering or self.batch_shape or self.atmosphere is None
                or not (self.refraction or self.extinction)):
            raise ValueError("a limb window keeps part of the light refracted through one "
                             "atmosphere: build the shadow unbatched, with refraction or "
                             "extinction and with scattering=False (the single-scattered "
                             "light is not windowed)")
        angles = as_tensor("position_angle_rad", position_angle_rad, dtype=dtype).detach()
        if angles.ndim != 1:
            raise ValueError("position_angle_rad must be a 1-D tensor of the position angles "
                             "at which every point is evaluated; got shape "
                             f"{tuple(angles.shape)}")
        return angles

    # ------------------------------------------------------------------ limb view
    def limb_view(self, distance_m, offset_m, wavelength_nm, *, n_azimuth: int = 256,
                  n_altitude: int = 16, oversample: int = 4,
                  sun_distance_m=None, tables=None) -> dict[str, torch.Tensor]:
        """Radiance of the atmosphere ring seen from points in the shadow.

        The ring is divided into ``n_azimuth`` bins of ring azimuth ``psi`` (0 towards the
        Sun's centre, counted around the occluder's centre) and ``n_altitude`` bins of
        impact altitude between the lowest transmitting ray and the top of the
        atmosphere; each bin holds the mean radiance over it (``oversample``² samples),
        so a refracted solar image smaller than a bin is not lost.

        Parameters
        ----------
        distance_m, offset_m : Tensor (...)
            Point in the shadow [m] (see :meth:`relative_illuminance`).
        wavelength_nm : Tensor (n_wavelength,)
            Wavelengths [nm].
        n_azimuth, n_altitude, oversample : int
            Image size and supersampling per bin. The altitude bins span the lowest
            transmitting refracted ray to the top of the atmosphere, or with
            ``scattering=True`` the ground (or a closed cloud deck's top) to the top.
        sun_distance_m : float or Tensor (...), optional
            Sun–occluder distance [m].
        tables : ScatteringTables, optional
            The atmosphere's multiple-scattering tables at ``wavelength_nm``: with
            ``scattering=True``, adds the light scattered two or more times at the centre
            of every bin (:func:`~skytorch.eclipse.shadow_multiple_scattering.
            multiple_scattered_radiance`; ~30 ms per bin and point).

        Returns
        -------
        dict of Tensor
            ``radiance`` (..., altitude, azimuth, n_wavelength): radiance relative to the
            radiance at the centre of the solar disc [1] (the refracted solar image plus,
            with ``scattering=True``, the single-scattered light of every line of sight:
            :func:`~skytorch.eclipse.shadow_scattering.scattered_radiance`, whose part is
            also returned as ``scattered_radiance``, and with ``tables`` the orders >= 2,
            also returned as ``multiple_scattered_radiance``); ``altitude_m`` (altitude,) impact
            altitude of the bin centres [m]; ``azimuth_rad`` (azimuth,) [rad];
            ``elevation_rad`` (..., altitude) apparent angular radius from the occluder's
            centre [rad]; ``solid_angle_sr`` (..., altitude, azimuth) [sr].
        """
        n_azimuth = check_int("n_azimuth", n_azimuth, low=1)
        n_altitude = check_int("n_altitude", n_altitude, low=1)
        oversample = check_int("oversample", oversample, low=1)
        scattering_tables = tables
        dtype = common_dtype(distance_m, offset_m)
        wavelength = _check_wavelength(wavelength_nm, dtype)
        angles = self._geometry(distance_m, offset_m, sun_distance_m, dtype)
        profile = self.ring_profile(wavelength)
        if profile is None:
            raise ValueError("limb_view needs an occluder with an atmosphere")
        if self.batch_shape:
            raise ValueError("limb_view needs an unbatched atmosphere; got batch shape "
                             f"{self.batch_shape}")
        tables = profile.tables(dtype)
        # with scattering the image reaches down to the lowest line of sight (the lines
        # below the lowest transmitting refracted ray still scatter sunlight)
        lowest = self._lowest_line_of_sight_m() if self.scattering else profile.beta_min_m
        span = profile.beta_top_m - lowest
        shape = angles["centre_distance_m"].shape
        # sample points: altitude (uniform in beta within each bin), azimuth
        n_b, n_p = n_altitude * oversample, n_azimuth * oversample
        beta = lowest + span * (torch.arange(n_b, dtype=dtype) + 0.5) / n_b
        psi = (torch.arange(n_p, dtype=dtype) + 0.5) * (2.0 * math.pi / n_p) - math.pi
        refracted = beta >= profile.beta_min_m  # no refracted light below the lowest ray
        values = _spline(tables["all"], profile.s_of_beta(
            torch.where(refracted, beta, torch.full_like(beta, profile.beta_min_m))))
        deviation, periapsis = values[:, 0], values[:, 1]
        optical = values[:, 2:] @ tables["basis"]
        centre = angles["centre_distance_m"][..., None]
        b = self.occluder_radius_m + beta
        scale = ((self.sun_distance_m if sun_distance_m is None
                  else angles["sun_distance_m"]) / angles["sun_range_m"])[..., None]
        a = torch.asin(b / centre) - scale * deviation  # (..., n_b)
        sigma = angles["separation_rad"][..., None, None]
        rho_s = angles["sun_radius_rad"][..., None, None]
        # distance from the Sun's centre of the source direction (a, psi)
        hav_gamma = (_haversine(a[..., :, None] - sigma) + torch.sin(a[..., :, None])
                     * torch.sin(sigma) * _haversine(psi))
        r2 = 4.0 * hav_gamma * (1.0 - hav_gamma) / torch.sin(rho_s) ** 2
        inside = (hav_gamma < _haversine(rho_s)) & (r2 < 1.0)
        mu = _safe_sqrt(1.0 - r2)
        a0, a1, a2 = _law_coefficients(self.law, self.limb_darkening.to(dtype), dtype)
        radiance = torch.where(inside, a0 + a1 * mu + a2 * mu * mu, 0.0) / (a0 + a1 + a2)
        transmittance = torch.exp(-torch.clamp(optical, min=0.0)) * _ray_weight(
            periapsis, profile)[:, None] * refracted[:, None]  # (n_b, n_wl)
        image = radiance[..., None] * transmittance[:, None, :]  # (..., n_b, n_p, n_wl)
        scattered = self._scattered_limb(wavelength, b, psi, angles, scale[..., 0])
        if scattered is not None:
            image = image + scattered

        def bins(samples):
            samples = samples.reshape(*shape, n_altitude, oversample, n_azimuth, oversample, -1)
            return samples.mean(dim=(-4, -2))

        image = bins(image)
        edges = lowest + span * torch.arange(n_altitude + 1, dtype=dtype) / n_altitude
        higher = self._multiple_scattered_limb(
            scattering_tables, self.occluder_radius_m + 0.5 * (edges[:-1] + edges[1:]),
            psi.reshape(n_azimuth, oversample).mean(-1), angles, scale[..., 0])
        if higher is not None:
            image = image + higher
        theta_edges = torch.asin((self.occluder_radius_m + edges) / centre)
        solid = (torch.cos(theta_edges[..., :-1]) - torch.cos(theta_edges[..., 1:])) * (
            2.0 * math.pi / n_azimuth)
        centres_b = 0.5 * (edges[:-1] + edges[1:])
        out = {
            "radiance": image,
            "altitude_m": centres_b,
            "azimuth_rad": psi.reshape(n_azimuth, oversample).mean(-1),
            "elevation_rad": torch.asin((self.occluder_radius_m + centres_b) / centre),
            "solid_angle_sr": solid[..., :, None].expand(*shape, n_altitude, n_azimuth),
        }
        if scattered is not None:
            out["scattered_radiance"] = bins(scattered)
        if higher is not None:
            out["multiple_scattered_radiance"] = higher
        return out

    def _multiple_scattered_limb(self, tables, impact_radius_m, azimuth_rad, angles, scale):
        """Orders >= 2 of the limb's bin centres relative to the Sun's centre, or ``None``.

        (..., n_b, n_p, n_wavelength); ``None`` without ``tables``.
        """
        if tables is None:
            return None
        if not self.scattering:
            raise ValueError("limb_view(tables=...) adds the orders >= 2 to the scattered "
                             "light: build the shadow with scattering=True")
        radiance = _multiple_scattered_radiance(
            tables, self.atmosphere, angles["centre_distance_m"], angles["separation_rad"],
            scale, impact_radius_m, azimuth_rad, ray_weight=self._scattering_ray_weight())
        normalisation = solar_normalisation(angles["sun_radius_rad"],
                                            self.limb_darkening.to(scale.dtype), self.law)
        return radiance * normalisation[..., None, None, None]

    def _lowest_line_of_sight_m(self) -> float:
        """Tangent altitude of the lowest line of sight through the atmosphere [m].

        The ground, or the top of a closed cloud deck.
        """
        return self.cloud_top_altitude_m if self.cloud_fraction >= 1.0 else 0.0

    def _scattered_limb(self, wavelength, impact_radius_m, azimuth_rad, angles, scale):
        """Single-scattered radiance of the limb samples relative to the Sun's centre.

        (..., n_b, n_p, n_wavelength), or ``None`` with ``scattering=False``.
        """
        if self.scattering_profile(wavelength) is None:
            return None
        lines = self._new_scattering_profile(wavelength.to(torch.float64),
                                             impact_radius_m=impact_radius_m.detach())
        radiance = scattered_radiance(lines, angles["centre_distance_m"],
                                      angles["separation_rad"], scale, azimuth_rad)
        normalisation = solar_normalisation(angles["sun_radius_rad"],
                                            self.limb_darkening.to(scale.dtype), self.law)
        # E_sun / L_centre [sr]: radiance per unit irradiance -> relative to the centre
        return radiance[..., 0, :] * normalisation[..., None, None, None]
