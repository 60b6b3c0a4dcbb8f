r"""Fraction of a limb-darkened solar disc left visible by a spherical occluder.

The Sun is a disc of angular radius ``rho_s`` with a radially symmetric, limb-darkened
radiance; the occluder is a disc (spherical cap) of angular radius ``rho_o`` whose centre
lies at angular separation ``d`` from the Sun's centre. The geometry is exact on the
celestial sphere (spherical caps), so the occluder may be huge (Earth seen from low orbit,
``rho_o`` up to 90 degrees) or tiny (Phobos in front of the Sun, an annular transit).

Method
------
The blocked flux is the integral of the radiance over the lens (the part of the solar
disc inside the occluder). Because the radiance depends only on the angular distance
``theta`` from the Sun's centre, Green's theorem in the polar coordinates
``(theta, psi)`` about the Sun's centre turns the area integral into a contour integral,

.. math::

    B = \iint_{\text{lens}} I(\theta)\, \sin\theta\, d\theta\, d\psi
      = \oint_{\partial\,\text{lens}} C(\theta)\, d\psi ,
    \qquad C(\theta) = \int_0^\theta I(\theta')\sin\theta'\, d\theta' ,

as in the Green's-theorem transit models of Pál (2012). The contour is made of the arc of
the solar limb inside the occluder (half-angle ``alpha`` seen from the Sun's centre; it
contributes ``2 alpha C(rho_s)`` in closed form) and the arc of the occluder's rim inside
the solar disc (half-angle ``phi_max`` seen from the occluder's centre). On that arc the
integrand is smooth except for a square-root behaviour where it meets the limb. The rim
is parametrised by ``t = tan(phi / 16)``, in which ``hav phi`` and ``d phi = 16 r dt``
with ``r = 1 / (1 + t^2)`` are rational (no sine per node; the poles at ``t = +-i`` stay
far from ``[0, tan(pi / 16)]``); the substitution
``t = t_max (1 - v^2)`` removes the square root and a fixed Gauss–Legendre rule in ``v``
converges exponentially. ``C`` has a closed form for the linear and quadratic laws
in the projected radius ``r = sin(theta) / sin(rho_s)`` (the exact projection of a sphere
seen from a finite distance); the factor ``1/cos(theta)`` of the solid-angle element is
expanded in powers of ``sin^2(rho_s)`` (exact to 1e-9 for ``rho_s`` up to 0.2 rad).

Spherical trigonometry of the triangle (Sun centre, occluder centre, rim point) is written
with haversines, ``hav x = sin^2(x/2)``, which keep full relative precision for small
angles and at tangency:

.. math::

    \operatorname{hav}\theta = \operatorname{hav}(d-\rho_o)
        + \sin d \sin\rho_o \operatorname{hav}\varphi ,\qquad
    \operatorname{hav}\alpha = \frac{\sin\frac{\rho_o-d+\rho_s}{2}
        \sin\frac{\rho_o+d-\rho_s}{2}}{\sin d\sin\rho_s} ,

    \frac{d\psi}{d\varphi}\sin^2\theta = \sin\rho_o\,[\sin(\rho_o-d)
        + 2\sin d\cos\rho_o\operatorname{hav}\varphi] .

The half-angles ``alpha`` and ``phi_max`` are computed from their haversines and the
complements ``cos^2(x/2)``, each a product of sines of angles that are formed exactly
where they are small, so that both keep full precision at every tangency (``phi_max ->
pi`` at inner tangency, ``alpha -> pi`` where the Sun is about to be hidden).

Gradients are exact at every tangency too. Both half-angles have infinite derivatives
there, but their contributions cancel analytically (Leibniz rule: the rim integrand at
``phi_max`` is ``2 C(rho_s) d psi / d phi``, and ``alpha = psi(phi_max)``): the graph holds
the rim nodes fixed and differentiates ``alpha`` as the azimuth ``psi`` of the fixed rim
point, so no divergent terms are formed; the radial profile on the rim is differentiated
in ``w^2`` (its derivative there is finite at the limb) by a custom autograd function.
Measured against an independent reference (tests/test_eclipse_gradients.py) the
derivatives are within 1.2e-6 / rho_s from 1e-19 rad off inner tangency upwards.

References
----------
1. Schneegans, S., Gilg, J., Ahlers, V., Zachmann, G., Gerndt, A. 2025, "Physically
   Based Real-Time Rendering of Eclipses", Computer Graphics Forum, eq. (1) (linear limb
   darkening, u = 0.6), doi:10.1111/cgf.70024.
2. Pál, A. 2012, "Light-curve modelling for mutual transits", MNRAS 420, 1630,
   doi:10.1111/j.1365-2966.2011.20151.x (Green's theorem for occulted flux).
3. Mandel, K., Agol, E. 2002, "Analytic Light Curves for Planetary Transit Searches",
   ApJ 580, L171, doi:10.1086/345520 (quadratic limb-darkening law; uniform-disc overlap).
4. Claret, A. 2000, "A new non-linear limb-darkening law for LTE stellar atmosphere
   models", A&A 363, 1081 (limb-darkening laws).
"""

from __future__ import annotations

import math
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from functools import lru_cache

import numpy as np
import torch

from skytorch._quadrature import legendre_unit
from skytorch._validate import (
    as_tensor,
    check_broadcastable,
    check_choice,
    check_int,
    check_range,
    common_dtype,
)

__all__ = [
    "LIMB_DARKENING_LAWS",
    "MAX_SUN_RADIUS_RAD",
    "MIN_SUN_RADIUS_RAD",
    "limb_darkening_profile",
    "sun_visible_fraction",
]

#: limb-darkening laws understood by :func:`sun_visible_fraction`
LIMB_DARKENING_LAWS = ("linear", "quadratic")
#: largest angular radius of the light source [rad]; the series in sin^2(rho_s) used for
#: the solid-angle factor is truncated at 1e-9 relative below it
MAX_SUN_RADIUS_RAD = 0.2
#: smallest angular radius of the light source [rad] (the Sun seen from 3 kpc)
MIN_SUN_RADIUS_RAD = 1e-8
#: default number of Gauss-Legendre nodes on the occluder's rim (worst error 5.2e-8, median
#: 2e-12 over random configurations; see
#: experiments/eclipse_geometry_accuracy_cost.py)
DEFAULT_NODES = 8
#: configurations per chunk of the per-configuration work with gradients
_CHUNK = 262_144
#: rows per sub-chunk of the rim quadrature: keeps the (rows, n_nodes) temporaries in the
#: CPU cache
_NODE_CHUNK = 16_384
#: configurations per chunk without gradients on one thread: the few dozen temporaries of
#: the per-configuration work stay in the CPU cache
_SERIAL_CHUNK = 32_768
#: rim rows per sub-chunk without gradients on one thread: the (n_nodes, rows) node
#: buffers stay in the L2 cache (CPU time 155 ns per configuration at 4096 rows against
#: 283 ns at 16384, 8 nodes, measured side by side with an earlier kernel)
_SERIAL_RIM_ROWS = 4_096
#: without gradients on several threads: configurations per task, and the largest array
#: (elements) of a task, below ATen's grain size (32768) so that every operation runs on
#: the calling thread (see _thread_pool)
_TASK_ELEMENTS = 32_000

# binomial series of 1/sqrt(1 - b t) = sum_n c_n (b t)^n, c_n = C(2n, n) / 4^n
_SERIES = tuple(math.comb(2 * n, n) / 4.0**n for n in range(8))


class _SafeSqrt(torch.autograd.Function):
    """sqrt(max(x, 0)) with derivative 0 (instead of inf) where x <= 0."""

    @staticmethod
    def forward(ctx, x):
        y = torch.sqrt(torch.clamp(x, min=0.0))
        ctx.save_for_backward(y)
        return y

    @staticmethod
    def backward(ctx, grad):
        (y,) = ctx.saved_tensors
        positive = y > 0
        return torch.where(positive, grad / (2.0 * torch.where(positive, y, 1.0)), 0.0)


def _safe_sqrt(x: torch.Tensor) -> torch.Tensor:
    if torch.is_grad_enabled() and x.requires_grad:
        return _SafeSqrt.apply(x)
    return torch.sqrt(torch.clamp(x, min=0.0))


def _angle_from_haversine(h: torch.Tensor) -> torch.Tensor:
    """Angle ``x`` in [0, pi] with ``hav x = h`` (``h`` clamped to [0, 1]), finite gradient."""
    h = torch.clamp(h, 0.0, 1.0)
    if torch.is_grad_enabled() and h.requires_grad:
        return 2.0 * torch.atan2(_safe_sqrt(h), _safe_sqrt(1.0 - h))
    return 2.0 * torch.asin(torch.sqrt(h))


def _haversine(x: torch.Tensor) -> torch.Tensor:
    return torch.sin(0.5 * x) ** 2


def _nodes(n_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [0, 1] (:func:`skytorch._quadrature.legendre_unit`).

    As writable copies of its read-only cached arrays.
    """
    x, w = legendre_unit(n_nodes)
    return x.copy(), w.copy()


def _series_terms(b: torch.Tensor) -> int:
    """Return number of terms of the 1/cos(theta) series needed for ~1e-9 relative accuracy."""
    b_max = float(b.detach().max()) if b.numel() else 0.0
    for n in range(1, len(_SERIES)):
        if _SERIES[n] * b_max**n < 1e-9:
            return n
    return len(_SERIES)


def _law_coefficients(law: str, limb_darkening, dtype) -> tuple[torch.Tensor, ...]:
    """Coefficients (a0, a1, a2) of I(mu) = a0 + a1 mu + a2 mu^2 for a law."""
    if law == "linear":
        u = check_range("limb_darkening", limb_darkening, 0.0, 1.0, dtype=dtype)
        return 1.0 - u, u, torch.zeros_like(u)
    coefficients = as_tensor("limb_darkening", limb_darkening, dtype=dtype)
    if coefficients.ndim == 0 or coefficients.shape[-1] != 2:
        raise ValueError(
            "limb_darkening for the quadratic law must be a pair (u1, u2) in its last "
            f"dimension; got shape {tuple(coefficients.shape)}"
        )
    u1 = check_range("limb_darkening[..., 0]", coefficients[..., 0], 0.0, 1.0)
    u2 = check_range("limb_darkening[..., 1]", coefficients[..., 1], -1.0, 1.0)
    with torch.no_grad():
        bad = (u1 + u2 > 1.0) | (u1 + 2.0 * u2 < 0.0)
        if bool(bad.any()):
            raise ValueError(
                "quadratic limb darkening needs u1 + u2 <= 1 and u1 + 2 u2 >= 0 (radiance "
                f"positive and decreasing to the limb); got u1={u1[bad].flatten()[0].item()}, "
                f"u2={u2[bad].flatten()[0].item()}"
            )
    return 1.0 - u1 - u2, u1 + 2.0 * u2, -u2


def limb_darkening_profile(mu, limb_darkening=0.6, law: str = "linear") -> torch.Tensor:
    """Relative radiance of the solar disc ``I(mu) / I(1)``.

    Parameters
    ----------
    mu : array_like
        Cosine of the emergence angle on the solar surface, ``sqrt(1 - r^2)`` with ``r`` the
        projected radius in units of the solar radius [1].
    limb_darkening : float or array_like
        ``u`` for the linear law; ``(..., 2)`` pairs ``(u1, u2)`` for the quadratic law.
    law : {"linear", "quadratic"}
        ``I = 1 - u (1 - mu)`` or ``I = 1 - u1 (1 - mu) - u2 (1 - mu)^2``.

    Returns
    -------
    torch.Tensor
        Relative radiance, broadcast shape of the inputs.

    Examples
    --------
    >>> float(limb_darkening_profile(0.0, 0.6))
    0.4
    """
    check_choice("law", law, LIMB_DARKENING_LAWS)
    mu = check_range("mu", mu, 0.0, 1.0)
    a0, a1, a2 = _law_coefficients(law, limb_darkening, mu.dtype)
    return a0 + a1 * mu + a2 * mu * mu


@lru_cache(maxsize=16)
def _series_matrix(n_terms: int) -> np.ndarray:
    """Coefficients of ``(1 + w) K(t)`` as polynomials in ``w = sqrt(1 - t)``.

    ``K(t) = C(t) / t`` is the flux within projected radius ``r = sqrt(t)`` divided by
    ``r^2``, with ``C(t) = 1/2 int_0^t I(mu(t')) / sqrt(1 - b t') dt'``, ``mu = sqrt(1 - t')``
    and ``b = sin^2(rho_s)``. Expanding ``1 / sqrt(1 - b t') = sum_n c_n (b t')^n`` gives,
    for the three terms of ``I = a0 + a1 mu + a2 mu^2``,

    * ``mu^0``: ``K0 = 1/2 sum_n c_n b^n t^n / (n + 1)``,
    * ``mu^1``: ``(1 + w) K1 = sum_n c_n b^n sum_j C(n, j) (-1)^j S_(2j+3)(w) / (2j + 3)``
      with ``S_m(w) = 1 + w + ... + w^(m-1)`` (from ``(1 - w^m) / t = S_m / (1 + w)``),
    * ``mu^2``: ``K2 = 1/2 sum_n c_n b^n t^n (1/(n+1) - t/(n+2))``,

    all written without cancellation near ``t = 0``. Returns an array
    ``(3, n_terms, degree + 1)``: law term, power of ``b``, power of ``w``.
    """
    poly = np.polynomial.polynomial
    t = np.array([1.0, 0.0, -1.0])  # t = 1 - w^2
    one_plus_w = np.array([1.0, 1.0])
    degree = 2 * n_terms + 1
    matrix = np.zeros((3, n_terms, degree + 1))
    for n in range(n_terms):
        t_n = poly.polypow(t, n)
        k0 = poly.polymul(one_plus_w, 0.5 * _SERIES[n] * t_n / (n + 1))
        k1 = np.zeros(1)
        for j in range(n + 1):
            m = 2 * j + 3
            k1 = poly.polyadd(k1, (-1) ** j * math.comb(n, j) / m * np.ones(m))
        k1 = _SERIES[n] * k1
        k2 = poly.polymul(
            one_plus_w,
            0.5 * _SERIES[n] * poly.polysub(t_n / (n + 1), poly.polymul(t_n, t) / (n + 2)))
        for row, coefficients in enumerate((k0, k1, k2)):
            matrix[row, n, : len(coefficients)] = coefficients
    return matrix


def _radial_coefficients(b, *law_weights, matrix=None) -> torch.Tensor:
    """Coefficients ``(..., degree + 1)`` of ``(1 + w) K`` in powers of ``w``.

    ``law_weights`` are ``a0, a1, a2`` (or fewer rows of ``matrix``, the
    :func:`_series_matrix` as a tensor, given to skip its construction).
    """
    if matrix is None:
        matrix = torch.as_tensor(_series_matrix(_series_terms(b)), dtype=b.dtype)
    n_terms = matrix.shape[1]
    coefficients = 0.0
    for law, a in enumerate(law_weights):
        series = matrix[law, -1]  # Horner in b
        for n in range(n_terms - 2, -1, -1):
            series = matrix[law, n] + b.unsqueeze(-1) * series
        coefficients = coefficients + a.unsqueeze(-1) * series
    return coefficients


def _radial_coefficients_(b, law_weights, matrix, out, series) -> torch.Tensor:
    """:func:`_radial_coefficients` without gradients, node-major ``(power, m)``.

    Written into ``out`` (``series``, same shape, is overwritten).
    """
    b = b.unsqueeze(0)
    columns = matrix.unsqueeze(-1)  # (law, n, power, 1)
    out.zero_()
    for law, a in enumerate(law_weights):
        series.copy_(columns[law, -1].expand_as(series))
        for n in range(matrix.shape[1] - 2, -1, -1):
            torch.addcmul(columns[law, n], b, series, out=series)
        out.addcmul_(a.unsqueeze(0), series)
    return out


def _haversine_quotient(numerator: torch.Tensor, denominator: torch.Tensor,
                        full: torch.Tensor) -> torch.Tensor:
    """``numerator / denominator`` clamped to [0, 1]: the haversine of an angle in [0, pi].

    Where ``full`` is true the quotient is set to exactly 1 (containment, decided from the
    radii, so that rounding at inner tangency cannot leave the quotient at ``1 - eps``,
    which would shift the angle by ``sqrt(eps)``). The denominator is raised to
    ``|numerator|`` (the quotient is clamped there anyway) and to ``tiny^(3/4)`` (below the
    smallest ``sin d sin rho`` reached with ``d >= sqrt(tiny)`` and ``rho_s >= 1e-8``), so
    that neither the value nor the derivative overflows when the denominator vanishes (zero
    separation: Sun behind the occluder's centre, or the occluder centred on the disc).
    """
    floor = torch.finfo(numerator.dtype).tiny ** 0.75
    safe = torch.maximum(torch.clamp(denominator, min=floor), numerator.abs())
    return torch.clamp(torch.where(full, 1.0, numerator / safe), 0.0, 1.0)


def _sqrt_(x: torch.Tensor, scratch: torch.Tensor) -> torch.Tensor:
    """``sqrt(max(x, eps^2))`` in place, as ``x * rsqrt(x)`` (no gradients).

    Within 1.5 ulp of ``sqrt`` above ``eps``. For quantities of order 1 (cosines, the
    ``w`` of the radial profile): ATen's float64 ``sqrt`` goes through MKL's vector library
    and took 1.7 ns per element against 0.8 ns for ``rsqrt`` on the benchmark machine. The
    floor keeps results and their squares far from subnormals, which slow every later
    operation. ``scratch`` (same shape) is overwritten.
    """
    x.clamp_(min=torch.finfo(x.dtype).eps ** 2)
    return x.mul_(torch.rsqrt(x, out=scratch))


def _haversine_quotient_(numerator: torch.Tensor, denominator: torch.Tensor,
                         full: torch.Tensor | None, scratch: torch.Tensor,
                         fill: float = 1.0) -> torch.Tensor:
    """:func:`_haversine_quotient` without gradients.

    Written into ``numerator`` (``denominator`` and ``scratch`` are overwritten; where ``full`` is
    true the quotient is ``fill``, 1 by default; ``full=None`` sets nothing).
    """
    floor = torch.finfo(numerator.dtype).tiny ** 0.75
    safe = torch.maximum(denominator.clamp_(min=floor), torch.abs(numerator, out=scratch),
                         out=denominator)
    quotient = numerator.div_(safe)
    if full is not None:
        quotient.masked_fill_(full, fill)
    return quotient.clamp_(0.0, 1.0)


def _sixteenth_tangent(hav_phi: torch.Tensor, cos2_half_phi: torch.Tensor) -> torch.Tensor:
    """``tan(phi / 16)`` from ``hav(phi)`` and ``cos^2(phi / 2) = 1 - hav(phi)``.

    Both in [0, 1] (the complement given separately keeps ``phi`` accurate near ``pi``).
    """
    tangent = torch.sqrt(hav_phi) / (1.0 + torch.sqrt(cos2_half_phi))  # tan(phi / 4)
    for _ in range(2):  # half-angle tangent: tan(x / 2) = tan x / (1 + sqrt(1 + tan^2 x))
        tangent = tangent / (1.0 + torch.sqrt(1.0 + tangent * tangent))
    return tangent


def _half_angles(rho_s, rho_o, d, hidden, inside):
    """Haversines and their complements of ``alpha`` and ``phi_max`` (no gradients).

    With ``S = sin((d + rho_o + rho_s) / 2)``, ``O = sin((rho_o + rho_s - d) / 2)``,
    ``P = sin((d + rho_o - rho_s) / 2)`` and ``Q = sin((d + rho_s - rho_o) / 2)`` (the
    half-angle formulas of the triangle Sun centre, occluder centre, intersection point):
    ``hav alpha = O P / (sin d sin rho_s)``, ``cos^2(alpha / 2) = S Q / (sin d sin rho_s)``,
    ``hav phi_max = O Q / (sin d sin rho_o)`` and
    ``cos^2(phi_max / 2) = S P / (sin d sin rho_o)``. Each factor is a sine of a small angle
    formed exactly near the tangency it describes, so that both angles keep full relative
    precision next to ``0`` and next to ``pi`` (inner tangency: ``phi_max -> pi``; the Sun
    about to be hidden: ``alpha -> pi``), where ``1 - hav`` would lose them.
    """
    half_d = 0.5 * d
    half_sum = 0.5 * (rho_o + rho_s)
    half_difference = 0.5 * (rho_o - rho_s)
    outer = torch.sin(half_sum - half_d)
    plus = torch.sin(half_sum + half_d)
    p = torch.sin(half_d + half_difference)
    q = torch.sin(half_d - half_difference)
    sin_d = torch.sin(d)
    denominator_s = sin_d * torch.sin(rho_s)
    denominator_o = sin_d * torch.sin(rho_o)
    hav_alpha = _haversine_quotient(outer * p, denominator_s, hidden)
    cos2_alpha = _haversine_quotient(plus * q, denominator_s, torch.zeros_like(hidden))
    cos2_alpha = torch.where(hidden, 0.0, cos2_alpha)
    hav_phi = _haversine_quotient(outer * q, denominator_o, inside)
    cos2_phi = torch.where(inside, 0.0, _haversine_quotient(plus * p, denominator_o,
                                                           torch.zeros_like(inside)))
    return hav_alpha, cos2_alpha, hav_phi, cos2_phi


class _RimProfile(torch.autograd.Function):
    """``P(w) / (1 + w)`` with ``w = sqrt(max(u, 0))`` and ``P(w) = sum_k c_k w^k``.

    This is ``K = C(theta) / sin^2(theta)`` on the rim, ``u = w^2 = 1 - r^2`` with ``r``
    the projected radius. ``K`` is a smooth function of ``u`` plus ``w^3`` times one (the
    radiance has a square root at the limb; its integral ``C`` has ``w^3``), so
    ``dK/du`` is finite at the limb although ``dw/du`` is not: with
    ``e_j = (j + 1) c_(j+1) + (j - 1) c_j``,
    ``dK/du = sum_(j>=1) e_j w^(j-1) / (2 (1 + w)^2)`` (the ``j = 0`` term, ``c_1 - c_0``,
    vanishes because ``dK/dw = 0`` at ``w = 0``). Written out so that no derivative of a
    square root is taken next to the limb.

    ``u``: ``(rows, n_nodes)``; ``coefficients``: ``(rows or 1, degree + 1)``.
    """

    @staticmethod
    def forward(ctx, u, coefficients):
        w = torch.sqrt(torch.clamp(u, min=0.0))
        degree = coefficients.shape[-1] - 1
        poly = coefficients[:, degree : degree + 1].expand_as(w)
        for k in range(degree - 1, -1, -1):
            poly = torch.addcmul(coefficients[:, k : k + 1], poly, w)
        ctx.save_for_backward(w, coefficients)
        return poly / (1.0 + w)

    @staticmethod
    def backward(ctx, grad):
        w, coefficients = ctx.saved_tensors
        degree = coefficients.shape[-1] - 1
        one_plus_w = 1.0 + w
        grad_u = grad_c = None
        if ctx.needs_input_grad[0]:
            c = [coefficients[:, k : k + 1] for k in range(degree + 1)]
            e = [(j + 1) * (c[j + 1] if j < degree else 0.0) + (j - 1) * c[j]
                 for j in range(1, degree + 1)]
            slope = e[-1].expand_as(w)
            for j in range(len(e) - 2, -1, -1):
                slope = torch.addcmul(e[j], slope, w)
            grad_u = grad * slope / (2.0 * one_plus_w * one_plus_w)
        if ctx.needs_input_grad[1]:
            scaled = grad / one_plus_w
            columns = []
            power = torch.ones_like(w)
            for _ in range(degree + 1):
                columns.append((scaled * power).sum(-1))
                power = power * w
            grad_c = torch.stack(columns, dim=-1)
            if coefficients.shape[0] == 1:
                grad_c = grad_c.sum(0, keepdim=True)
        return grad_u, grad_c


def _visible_fraction_flat(rho_s, rho_o, d, coefficients, s, weight):
    """Core of :func:`sun_visible_fraction` on 1-D tensors (one chunk), with gradients.

    Tensors of length 1 (a scalar Sun radius or limb darkening) broadcast against the chunk.
    ``s = 1 - v^2`` and ``weight = 2 v w_GL`` are the rim nodes and weights.

    Gradients (Leibniz rule): ``f = 1 - alpha / pi - R(phi_max) / (2 pi C(rho_s))`` with
    ``R`` the rim integral up to ``phi_max``. Both ``alpha`` and ``phi_max`` have infinite
    derivatives at tangency, and their terms cancel: the integrand of ``R`` at
    ``phi_max`` is ``2 C(rho_s) d psi / d phi`` (``psi``: azimuth of the rim point about
    the Sun's centre), and ``alpha = psi(phi_max)``, so that
    ``d alpha - (d psi / d phi) d phi_max = (d psi / d x)`` at fixed ``phi``. The graph
    therefore holds ``phi_max`` (the quadrature nodes) fixed and differentiates ``alpha``
    as ``psi(phi_max; rho_o, d)`` at that fixed rim point,
    ``tan psi = sin phi sin rho_o / (sin d cos rho_o - cos d sin rho_o cos phi)``; the values
    are those of the accurate half-angle formulas (:func:`_half_angles`). This gives the
    exact derivative with no divergent terms to cancel.
    """
    hidden = d <= rho_o - rho_s  # Sun entirely behind the occluder
    inside = d <= rho_s - rho_o  # occluder entirely on the disc (transit, antumbra)
    # a separation below sqrt(tiny) changes the fraction by < 1e-140 but would underflow
    d = torch.clamp(d, min=torch.finfo(d.dtype).tiny ** 0.5)
    half_d = 0.5 * d
    sin_d = torch.sin(d)
    sin_s = torch.sin(rho_s)
    sin_o = torch.sin(rho_o)
    cos_o = torch.cos(rho_o)
    b = sin_s * sin_s
    with torch.no_grad():
        hav_alpha, cos2_alpha, hav_phi, cos2_phi = _half_angles(
            rho_s.detach(), rho_o.detach(), d.detach(), hidden, inside)
        alpha_value = 2.0 * torch.atan2(torch.sqrt(hav_alpha), torch.sqrt(cos2_alpha))
        sixteenth_tangent_max = _sixteenth_tangent(hav_phi, cos2_phi)
        sin_phi_max = 2.0 * torch.sqrt(hav_phi * cos2_phi)
        cos_phi_max = cos2_phi - hav_phi
        partial = ~(hidden | inside) & (hav_phi > 0.0) & (cos2_phi > 0.0)
    alpha = alpha_value
    if torch.is_grad_enabled() and (d.requires_grad or rho_o.requires_grad):
        # azimuth about the Sun's centre of the fixed rim point at phi_max (zero gradient
        # where there is no partial overlap: alpha is constant there)
        y = torch.where(partial, sin_phi_max * sin_o, 0.0)
        x = torch.where(partial, sin_d * cos_o - torch.cos(d) * sin_o * cos_phi_max, 1.0)
        psi = torch.atan2(y, x)
        alpha = alpha_value + (psi - psi.detach())
    # hav(d - rho_o) and sin(rho_o - d) from the half angle
    half_o_d = 0.5 * rho_o - half_d
    sin_half, cos_half = torch.sin(half_o_d), torch.cos(half_o_d)
    hav_o_d = sin_half * sin_half
    sin_o_d = 2.0 * sin_half * cos_half
    sin_d_o = sin_d * sin_o
    total = coefficients[:, 0]  # (1 + w) K at w = 0, i.e. C(rho_s) / sin^2(rho_s)

    # rim of the occluder on sub-chunks that keep the (chunk, n_nodes) arrays in cache
    rim = (sixteenth_tangent_max, hav_o_d, sin_d_o, sin_o_d, 2.0 * sin_d * cos_o,
           -4.0 / b, coefficients)
    n = d.shape[0]
    if n <= _NODE_CHUNK:
        integral = _rim_integral(*rim, s, weight)
    else:
        integral = torch.cat([
            _rim_integral(*(x if x.shape[0] == 1 else x[start : start + _NODE_CHUNK]
                            for x in rim), s, weight)
            for start in range(0, n, _NODE_CHUNK)])
    arc = integral * (16.0 * sixteenth_tangent_max) * sin_o / (b * total)
    fraction = torch.clamp(1.0 - (alpha + arc) / math.pi, 0.0, 1.0)
    return torch.where(hidden, 0.0, fraction)


def _rim_integral(sixteenth_tangent_max, hav_o_d, sin_d_o, sin_o_d, two_sin_d_cos_o,
                  minus_4_over_b, coefficients, s, weight) -> torch.Tensor:
    """Gauss–Legendre sum over the occluder's rim, with gradients (fixed nodes).

    On the rim ``t = tan(phi / 16) = t_max s_k``, ``r = 1 / (1 + t^2)``,
    ``hav(phi) = 64 [t r (2 r - 1) (1 - 8 t^2 r^2)]^2`` and ``d phi = 16 r dt``; returns
    ``sum_k weight_k r_k f_k`` with
    ``f = (1 + w) K / (1 + w) * J``, ``hav(theta) = hav(d - rho_o) + sin d sin rho_o
    hav(phi)``, ``w^2 = 1 - sin^2(theta) / b`` and the Jacobian
    ``J = sin(rho_o - d) + 2 sin d cos(rho_o) hav(phi)``. ``t_max`` carries no gradient
    (see :func:`_visible_fraction_flat`).
    """
    t = torch.outer(sixteenth_tangent_max, s)
    r = 1.0 / (1.0 + t * t)
    half_sine = t * r  # sin(phi / 8) / 2
    hav_phi = 64.0 * (half_sine * (2.0 * r - 1.0) * (1.0 - 8.0 * half_sine * half_sine)) ** 2
    hav_theta = torch.addcmul(hav_o_d.unsqueeze(-1), sin_d_o.unsqueeze(-1), hav_phi)
    hav_theta = torch.addcmul(hav_theta, hav_theta, hav_theta, value=-1.0)  # sin^2/4
    one = torch.ones((), dtype=hav_phi.dtype)
    w2 = torch.addcmul(one, hav_theta, minus_4_over_b.unsqueeze(-1))
    radial = _RimProfile.apply(w2, coefficients)
    # d psi / d phi * sin^2(theta) / sin^2(rho_s) on the rim
    jacobian = torch.addcmul(sin_o_d.unsqueeze(-1), two_sin_d_cos_o.unsqueeze(-1), hav_phi)
    return (radial * jacobian * r) @ weight


class _Workspace:
    """Reusable 1-D buffers for the kernel without gradients (one per thread and call).

    Every temporary of :func:`_fraction_without_gradient` is written into one of these
    buffers instead of a fresh allocation: freeing megabytes of temporaries per chunk lets
    the C allocator return them to the system and fault them in again for the next chunk
    (measured: 140 000 page faults and 0.3 s system time per 1e7 configurations).
    """

    def __init__(self, capacity: int, n_nodes: int, rim_rows: int, n_powers: int,
                 dtype: torch.dtype):
        self.buffers = torch.empty((_WORKSPACE_BUFFERS, capacity), dtype=dtype)
        self.radial = torch.empty((2, n_powers, capacity), dtype=dtype)
        self.masks = torch.empty((2, capacity), dtype=torch.bool)
        self.rim = torch.empty((5, n_nodes, max(1, min(capacity, rim_rows))), dtype=dtype)
        self.integral = torch.empty(capacity, dtype=dtype)

    def slots(self, n: int):
        """Fresh views of length ``n``, one per call of the returned function."""
        views = iter(self.buffers[:, :n])

        def new() -> torch.Tensor:
            view = next(views, None)
            if view is None:
                raise RuntimeError("occlusion workspace exhausted: raise _WORKSPACE_BUFFERS")
            return view

        return new


#: buffers of length chunk for one evaluation of :func:`_fraction_without_gradient` (35
#: are used)
_WORKSPACE_BUFFERS = 36


def _fraction_without_gradient(rho_s, rho_o, d, radial, s, weight, out: torch.Tensor,
                               workspace: _Workspace) -> torch.Tensor:
    """Return same result as :func:`_visible_fraction_flat`, for inputs that need no gradient.

    Written for speed: six sines and no cosine per configuration (``sin d``, ``sin rho_o``
    and ``cos rho_o`` from the sines of the half angles; the cosines of half angles in
    [-pi/2, pi/2], where they are well conditioned, from square roots, most of them
    through :func:`_sqrt_`), no sine per rim node, the final normalisation folded into the
    rim Jacobian, and every
    temporary written into the buffers of ``workspace`` (the rim quadrature in sub-chunks
    of its rim rows, node-major). ``radial`` is either the coefficients of ``(1 + w) K``
    shared by the chunk, node-major ``(power, 1)``, or ``(matrix, a0, a1[, a2])`` to
    compute them per configuration (:func:`_radial_coefficients_`). Writes the fraction
    into ``out`` (same length as the chunk) and returns it.
    """
    n = d.shape[0]
    new = workspace.slots(n)
    scratch = new()
    one = torch.ones((), dtype=d.dtype)
    difference = torch.sub(rho_o, rho_s, out=new())
    hidden, inside = workspace.masks[:, :n]
    torch.le(d, difference, out=hidden)  # Sun entirely behind the occluder
    torch.le(d, torch.neg(difference, out=new()), out=inside)  # occluder on the disc
    half_d = torch.clamp(d, min=torch.finfo(d.dtype).tiny ** 0.5, out=new()).mul_(0.5)
    half_o = torch.mul(rho_o, 0.5, out=new())
    sin_half_d = torch.sin(half_d, out=new())
    cos_half_d = _sqrt_(torch.addcmul(one, sin_half_d, sin_half_d, value=-1.0, out=new()),
                        scratch)
    sin_half_o = torch.sin(half_o, out=new())
    cos_half_o = _sqrt_(torch.addcmul(one, sin_half_o, sin_half_o, value=-1.0, out=new()),
                        scratch)
    sin_d = torch.mul(sin_half_d, cos_half_d, out=new()).mul_(2.0)
    sin_o = torch.mul(sin_half_o, cos_half_o, out=new()).mul_(2.0)
    cos_o = torch.addcmul(one, sin_half_o, sin_half_o, value=-2.0, out=new())
    m = rho_s.shape[0]  # 1 for a scalar Sun radius
    sin_s = torch.sin(rho_s, out=new()[:m])
    b = torch.mul(sin_s, sin_s, out=new()[:m])
    if isinstance(radial, tuple):
        matrix, *law_weights = radial
        coefficients, series = workspace.radial[:, :, :n]
        coefficients = _radial_coefficients_(b, law_weights, matrix, coefficients, series)
    else:
        coefficients = radial
    half_difference = difference.mul_(0.5)
    half_sum = torch.add(half_o, rho_s, alpha=0.5, out=new())
    outer = torch.sub(half_sum, half_d, out=new()).sin_()  # sin((rho_o + rho_s - d) / 2)
    plus = half_sum.add_(half_d).sin_()  # sin((d + rho_o + rho_s) / 2)
    p = torch.add(half_difference, half_d, out=new()).sin_()  # sin((d + rho_o - rho_s) / 2)
    q = torch.sub(half_d, half_difference, out=new()).sin_()  # sin((d + rho_s - rho_o) / 2)
    sin_d_o = torch.mul(sin_d, sin_o, out=new())
    # alpha = 2 atan2(sqrt(hav alpha), sqrt(cos^2(alpha / 2))), both exact near their
    # tangency (see _half_angles); their common denominator sin d sin rho_s cancels in the
    # ratio. alpha needs no containment fix: the fraction is set to 0 where the Sun is
    # hidden (no overlap gives exactly alpha = 0 and t_max = 0)
    alpha = torch.mul(p, outer, out=new()).clamp_(min=0.0).sqrt_()
    cos_alpha = torch.mul(plus, q, out=new()).clamp_(min=0.0).sqrt_()
    alpha = torch.atan2(alpha, cos_alpha, out=alpha).mul_(2.0)
    # t_max = tan(phi_max / 16) from q = hav(phi_max) = sin^2(phi_max / 2) and its
    # complement c = cos^2(phi_max / 2): tan(phi_max / 4) = sqrt(q) / (1 + sqrt(c)); then
    # twice the half-angle tangent tan(x / 2) = tan x cos x / (1 + cos x),
    # cos(x / 2) = sqrt((1 + cos x) / 2)
    one_plus_cos = _haversine_quotient_(plus.mul_(p), new().copy_(sin_d_o), inside, scratch,
                                        fill=0.0)
    one_plus_cos = _sqrt_(one_plus_cos, scratch).add_(1.0)
    hav_phi_max = _haversine_quotient_(outer.mul_(q), torch.mul(sin_d, sin_o, out=new()),
                                       inside, scratch)
    sixteenth_tangent_max = hav_phi_max.sqrt_().div_(one_plus_cos)  # tan(phi_max / 4) so far
    cosine = new()
    for _ in range(2):
        _sqrt_(torch.mul(one_plus_cos, 0.5, out=cosine), scratch)
        torch.add(cosine, 1.0, out=one_plus_cos)
        sixteenth_tangent_max.mul_(cosine).div_(one_plus_cos)
    # sin and cos of (rho_o - d) / 2 in [-pi/2, pi/4] (the difference of the half angles is
    # formed before the sine: the angle-addition formula would cancel where rho_o ~ d)
    sin_half = half_o.sub_(half_d).sin_()
    cos_half = _sqrt_(torch.addcmul(one, sin_half, sin_half, value=-1.0, out=new()), scratch)
    # w^2 = 1 - 4 hav(theta) (1 - hav(theta)) / b with hav(theta) = A + B hav(phi) (A =
    # hav(rho_o - d), B = sin d sin rho_o), a quadratic in hav(phi) = 64 g with
    # g = [t r (2 r - 1) (1 - 8 t^2 r^2)]^2, t = tan(phi / 16), r = 1 / (1 + t^2):
    # w^2 = 1 - 4/b [A (1 - A) + 64 B (1 - 2 A) g - 4096 B^2 g^2]
    hav_o_d = torch.mul(sin_half, sin_half, out=new())
    minus_4_over_b = torch.reciprocal(b, out=new()[:m]).mul_(-4.0)
    w2_0 = torch.addcmul(hav_o_d, hav_o_d, hav_o_d, value=-1.0, out=new())
    w2_0.mul_(minus_4_over_b).add_(1.0)
    w2_1 = torch.addcmul(sin_d_o, sin_d_o, hav_o_d, value=-2.0, out=new())
    w2_1.mul_(minus_4_over_b).mul_(64.0)
    w2_2 = torch.mul(sin_d_o, sin_d_o, out=new()).mul_(minus_4_over_b).mul_(-4096.0)
    # Jacobian J = sin(rho_o - d) + 128 sin d cos(rho_o) g, with d phi = 16 t_max r dt' and
    # the normalisation 16 t_max sin(rho_o) / (pi b C(rho_s) / sin^2 rho_s) folded in
    scale = torch.mul(b, coefficients[0], out=new()[: max(m, coefficients.shape[-1])])
    scale.mul_(math.pi / 16.0)
    scale = torch.div(sin_o, scale, out=sin_o).mul_(sixteenth_tangent_max)
    jacobian_0 = torch.mul(sin_half, cos_half, out=new()).mul_(scale).mul_(2.0)
    jacobian_1 = torch.mul(sin_d, cos_o, out=new()).mul_(scale).mul_(128.0)

    # node-major (n_nodes, rows) arrays: the per-configuration rows broadcast along the
    # contiguous dimension (addcmul 3.7 times faster than with (rows, n_nodes) arrays and
    # broadcast columns, measured side by side)
    rows = workspace.rim.shape[-1]
    integral = workspace.integral[:n]
    degree = coefficients.shape[0] - 1
    per_row = [x.unsqueeze(0) for x in (w2_0, w2_1, w2_2, jacobian_0, jacobian_1)]
    shared = coefficients.shape[-1] == 1
    powers = [coefficients[k : k + 1] for k in range(degree + 1)]
    node_column = s.unsqueeze(-1)
    weight_row = weight.unsqueeze(0)
    minus_one = -one
    for start in range(0, n, rows):
        stop = min(start + rows, n)
        g, r, cosine, w, poly = workspace.rim[:, :, : stop - start]
        w2_0c, w2_1c, w2_2c, jacobian_0c, jacobian_1c = (x[:, start:stop] for x in per_row)
        c = powers if shared else [x[:, start:stop] for x in powers]
        t = torch.mul(node_column, sixteenth_tangent_max[start:stop], out=g)
        torch.addcmul(one, t, t, out=r).reciprocal_()
        torch.add(minus_one, r, alpha=2.0, out=cosine)  # cos(phi / 8)
        half_sine = t.mul_(r)  # sin(phi / 8) / 2
        torch.addcmul(one, half_sine, half_sine, value=-8.0, out=w)  # cos(phi / 4)
        g = half_sine.mul_(cosine).mul_(w).square_()  # hav(phi) / 64
        torch.addcmul(w2_1c, w2_2c, g, out=w)
        _sqrt_(torch.addcmul(w2_0c, w, g, out=w), poly)
        torch.addcmul(c[degree - 1], c[degree], w, out=poly)
        for k in range(degree - 2, -1, -1):
            torch.addcmul(c[k], poly, w, out=poly)
        jacobian = torch.addcmul(jacobian_0c, jacobian_1c, g, out=g).mul_(r)
        poly.mul_(jacobian).div_(w.add_(1.0))
        torch.mm(weight_row, poly, out=integral[start:stop].unsqueeze(0))
    fraction = torch.mul(alpha, -1.0 / math.pi, out=out).add_(1.0).sub_(integral)
    return fraction.clamp_(0.0, 1.0).masked_fill_(hidden, 0.0)


def _thread_pool(workers: int) -> ThreadPoolExecutor:
    """Threads that evaluate chunks of configurations concurrently.

    One pool per process: a pool inherited through ``fork`` has no threads in the child.
    """
    return _process_thread_pool(workers, os.getpid())


@lru_cache(maxsize=4)
def _process_thread_pool(workers: int, pid: int) -> ThreadPoolExecutor:
    """Threads that evaluate chunks of configurations concurrently.

    Every array of the kernel without gradients is smaller than ATen's grain size, so
    each operation runs serially on the thread that calls it, and parallelism comes from
    these threads taking chunks from a shared queue (the kernels release the GIL). On a
    shared machine this degrades gracefully: with intra-op parallelism every one of the
    thousands of operations waits at a barrier for all threads, and a thread descheduled
    by another process stalls them all (measured: 10 to 20 times slower than one thread
    at load 10 on 2 cores).
    """
    return ThreadPoolExecutor(max_workers=workers, thread_name_prefix="skytorch-occlusion")


def _checked_range(name, value, low, high, *, low_inclusive=True, unit="", dtype=None):
    """:func:`~skytorch._validate.check_range` in one pass over large inputs.

    ``aminmax`` (NaN propagates into both results, so NaN fails the comparison) decides;
    only an input out of range goes through ``check_range`` for its error message.
    """
    tensor = as_tensor(name, value, dtype=dtype)
    if tensor.numel() > 1:
        low_value, high_value = (float(x) for x in torch.aminmax(tensor.detach()))
        above = low_value >= low if low_inclusive else low_value > low
        if above and high_value <= high:
            return tensor
    return check_range(name, tensor, low, high, low_inclusive=low_inclusive, unit=unit)


def sun_visible_fraction(
    sun_radius_rad,
    occluder_radius_rad,
    separation_rad,
    limb_darkening=0.6,
    law: str = "linear",
    *,
    n_nodes: int = DEFAULT_NODES,
) -> torch.Tensor:
    r"""Fraction of the limb-darkened solar flux not blocked by a spherical occluder.

    Parameters
    ----------
    sun_radius_rad : array_like
        Angular radius of the solar disc ``rho_s`` [rad], in [1e-8, 0.2].
    occluder_radius_rad : array_like
        Angular radius of the occluder ``rho_o`` [rad], in (0, pi/2].
    separation_rad : array_like
        Angular distance between the centres ``d`` [rad], in [0, pi].
    limb_darkening : float or array_like
        Linear coefficient ``u`` in [0, 1] (default 0.6, Schneegans et al. 2025), or for
        ``law="quadratic"`` pairs ``(u1, u2)`` in the last dimension.
    law : {"linear", "quadratic"}
        Limb-darkening law, see :func:`limb_darkening_profile`.
    n_nodes : int
        Gauss–Legendre nodes on the occluder's rim (accuracy vs cost).

    Returns
    -------
    torch.Tensor
        Visible fraction in [0, 1], broadcast shape of the inputs, dtype of the inputs
        (float64 by default).

    Notes
    -----
    With ``I(mu) = a0 + a1 mu + a2 mu^2`` and ``K = C / sin^2(theta)``,

    .. math::

        B = 2\alpha C(\rho_s) + 2\int_0^{\varphi_{max}} K(\theta(\varphi))
            \sin\rho_o[\sin(\rho_o-d) + 2\sin d\cos\rho_o\operatorname{hav}\varphi]
            \,d\varphi, \qquad f = 1 - \frac{B}{2\pi C(\rho_s)} .

    For ``u = 0`` this is the exact circle–circle (cap–cap) lens area. See the module
    docstring for the derivation and references.

    Examples
    --------
    >>> import torch
    >>> f = sun_visible_fraction(4.65e-3, 4.65e-3, torch.tensor([0.0, 4.65e-3, 1e-2]))
    >>> [round(v, 4) for v in f.tolist()]
    [0.0, 0.6024, 1.0]
    """
    check_choice("law", law, LIMB_DARKENING_LAWS)
    n_nodes = check_int("n_nodes", n_nodes, low=2, high=256)
    dtype = common_dtype(sun_radius_rad, occluder_radius_rad, separation_rad)
    rho_s = _checked_range("sun_radius_rad", sun_radius_rad, MIN_SUN_RADIUS_RAD,
                        MAX_SUN_RADIUS_RAD, unit=" rad", dtype=dtype)
    rho_o = _checked_range("occluder_radius_rad", occluder_radius_rad, 0.0, 0.5 * math.pi,
                        low_inclusive=False, unit=" rad", dtype=dtype)
    d = _checked_range("separation_rad", separation_rad, 0.0, math.pi, unit=" rad",
                       dtype=dtype)
    a0, a1, a2 = _law_coefficients(law, limb_darkening, dtype)
    shape = check_broadcastable(sun_radius_rad=rho_s, occluder_radius_rad=rho_o,
                                separation_rad=d, limb_darkening=a0)
    n = math.prod(shape)

    def flat(x: torch.Tensor) -> torch.Tensor:
        # scalars stay of length 1 and broadcast inside the kernel
        return x.reshape(1) if x.numel() == 1 else x.expand(shape).reshape(-1)

    nodes, weights = legendre_unit(n_nodes)
    s = torch.as_tensor(1.0 - nodes * nodes, dtype=dtype)
    weight = torch.as_tensor(2.0 * nodes * weights, dtype=dtype)
    sun = torch.broadcast_tensors(rho_s, a0, a1, a2)
    shared_sun = sun[0].numel() == 1  # one Sun radius and one limb darkening for all
    geometry = (flat(rho_s), flat(rho_o), flat(d))
    if torch.is_grad_enabled() and any(x.requires_grad for x in (*geometry, a0, a1, a2)):
        coefficients = _radial_coefficients(torch.sin(sun[0]) ** 2, *sun[1:])
        coefficients = coefficients.reshape(1, -1) if shared_sun else \
            coefficients.expand(*shape, coefficients.shape[-1]).reshape(n, -1)
        inputs = (*geometry, coefficients)
        chunks = [_visible_fraction_flat(*(x if x.shape[0] == 1 else x[start : start + _CHUNK]
                                           for x in inputs), s, weight)
                  for start in range(0, max(n, 1), _CHUNK)]
        result = torch.cat(chunks) if len(chunks) > 1 else chunks[0]
    elif n == 0:
        return torch.empty(shape, dtype=dtype)
    else:
        with torch.no_grad():
            n_terms = _series_terms(torch.sin(rho_s.max()) ** 2)
            matrix = _series_matrix(n_terms)[: 2 if law == "linear" else 3]
            # the polynomial in w ends at its highest non-zero power (one less for the
            # linear law)
            degree = max(int(np.nonzero(np.abs(matrix).max(axis=(0, 1)))[0].max()), 1)
            matrix = torch.as_tensor(matrix[..., : degree + 1], dtype=dtype)
            if shared_sun:  # one column of coefficients, node-major (power, 1)
                radial = _radial_coefficients(torch.sin(sun[0].reshape(1)) ** 2,
                                              *(x.reshape(1) for x in sun[1 : len(matrix) + 1]),
                                              matrix=matrix).t()
            else:  # per configuration, in each chunk from its Sun radius
                radial = tuple(flat(x) for x in (a0, a1, a2)[: len(matrix)])
        # the separation and the occluder radius carry the configurations' length
        inputs = (geometry[0], geometry[1].expand(n), geometry[2].expand(n))
        result = torch.empty(n, dtype=dtype)
        workers = min(torch.get_num_threads(), -(-n // _TASK_ELEMENTS))
        chunk, rim_rows = ((_TASK_ELEMENTS, _TASK_ELEMENTS // n_nodes) if workers > 1
                           else (_SERIAL_CHUNK, _SERIAL_RIM_ROWS))
        workspaces = threading.local()  # one per thread for this call

        def task(start: int) -> None:
            workspace = getattr(workspaces, "buffers", None)
            if workspace is None:
                workspace = workspaces.buffers = _Workspace(
                    min(chunk, n), n_nodes, rim_rows, degree + 1, dtype)

            def piece(x: torch.Tensor) -> torch.Tensor:
                return x if x.shape[-1] == 1 else x[..., start : start + chunk]

            with torch.no_grad():
                _fraction_without_gradient(
                    *(piece(x) for x in inputs),
                    piece(radial) if shared_sun else (matrix, *(piece(x) for x in radial)),
                    s, weight, out=result[start : start + chunk], workspace=workspace)

        starts = range(0, n, chunk)
        if workers > 1:
            list(_thread_pool(workers).map(task, starts))
        else:
            for start in starts:
                task(start)
    return result.expand(n).reshape(shape) if result.numel() == 1 else result.reshape(shape)
