r"""Column integrals of density profiles along straight rays, and the Chapman function.

The optical depth of a species whose extinction coefficient is
:math:`k(\lambda)\,\rho(h)` (a spectral coefficient times a dimensionless density
profile) is :math:`\tau(\lambda) = k(\lambda) \int \rho(h(s))\,ds`. The path integral
:math:`I = \int \rho\,ds` [m] does not depend on wavelength, so it is computed once per
species and ray, and the spectral dimension costs one multiplication.

Along a ray with impact parameter :math:`p`, parametrised by the signed distance
:math:`t` from the point of closest approach, :math:`r^2 = p^2 + t^2` depends on
:math:`|t|` only. The path is split into an ascending leg (:math:`t > 0`) and a
descending leg (:math:`t < 0`, mirrored), each monotonic in altitude.

Methods (``METHODS``):

``"gauss"`` (default)
    Composite Gauss–Legendre quadrature in :math:`|t|`, the legs being cut where the
    ray crosses the profile's breakpoint altitudes (multiples of the scale height,
    layer boundaries, the kinks of the ozone tent), so that every piece has a smooth
    integrand; ``n_steps`` nodes per piece.
``"trapezoid"``
    ``n_steps`` uniform steps along the path (the classic ray-marching scheme).
``"adaptive"``
    ``"gauss"`` with 4, 8, 16, ... nodes per piece until the largest relative change
    falls below ``rtol`` (or 128 nodes).

For an exponential profile the integral from an observer at radius :math:`r_0` to
infinity is :math:`\rho(h_0) H\,\mathrm{Ch}(r_0/H, z)` with the Chapman function
(ref. 1); :func:`chapman` gives Chapman's closed-form asymptotic expression and
:func:`chapman_horizontal` the exact closed form at :math:`z = 90°` (ref. 2).

References
----------
1. Chapman, S. 1931, "The absorption and dissociative or ionizing effect of
   monochromatic radiation in an atmosphere on a rotating earth, part II. Grazing
   incidence", Proc. Phys. Soc. 43, 483, doi:10.1088/0959-5309/43/5/302.
2. Huestis, D. L. 2001, "Accurate evaluation of the Chapman function for atmospheric
   attenuation", JQSRT 69, 709, doi:10.1016/S0022-4073(00)00107-2.
3. Kasten, F. & Young, A. T. 1989, "Revised optical air mass tables and approximation
   formula", Appl. Opt. 28, 4735, doi:10.1364/AO.28.004735.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere.optical_depth import column_integral
>>> from skytorch.atmosphere.profiles import exponential
>>> r = torch.tensor(6_371_000.0, dtype=torch.float64)
>>> column = column_integral(lambda h: exponential(h, 8000.0), r, torch.tensor(1.0,
...     dtype=torch.float64), 6_371_000.0, 6_471_000.0,
...     torch.tensor([2000.0, 4000.0, 8000.0, 16000.0, 32000.0, 64000.0], dtype=torch.float64))
>>> round(float(column), 2)   # 8000 (1 - exp(-12.5))
7999.97
"""

from __future__ import annotations

import math
from collections.abc import Callable

import torch

from skytorch._quadrature import unit_nodes
from skytorch._validate import (
    as_tensor,
    broadcast_shape,
    check_choice,
    check_int,
    check_range,
)
from skytorch.atmosphere.geometry import _ray_segment, _safe_divide, safe_sqrt

__all__ = [
    "DEFAULT_STEPS",
    "METHODS",
    "NODE_BLOCK_BYTES",
    "chapman",
    "chapman_horizontal",
    "check_rtol",
    "column_integral",
    "kasten_young_air_mass",
]

#: integration methods
METHODS = ("gauss", "trapezoid", "adaptive")
#: bytes of the nodes of one block of rays (one float tensor) in column integrals of many
#: rays: the density's temporaries then stay in a core's cache (1e6 rays x 72 nodes of the
#: US 1976 group: blocks of 2**19 bytes take 0.57 of the time of blocks 4x larger)
NODE_BLOCK_BYTES = 2 ** 19
#: default number of nodes per piece ("gauss") or steps ("trapezoid")
DEFAULT_STEPS = {"gauss": 6, "trapezoid": 500, "adaptive": 4}
_MAX_ADAPTIVE_NODES = 128

Density = Callable[[torch.Tensor], torch.Tensor]


def check_rtol(rtol) -> float:
    """Return the relative tolerance of ``"adaptive"`` as a float in (0, 1].

    ValueError naming ``rtol`` for NaN, inf, zero, negative or larger values; TypeError for
    non-numbers.
    """
    if isinstance(rtol, bool) or (isinstance(rtol, torch.Tensor) and rtol.numel() != 1):
        raise TypeError(f"rtol must be a number; got {rtol!r}")
    return float(check_range("rtol", as_tensor("rtol", rtol), 0.0, 1.0, low_inclusive=False))


def _altitude(c_lo, lo, u, planet_radius):
    """Altitude at distance ``u`` beyond ``|t| = lo`` where :math:`r^2 - R^2 = c_{lo}`.

    :math:`r^2 - R^2 = c_{lo} + u (2 lo + u)` and :math:`h = (r^2 - R^2)/(r + R)`: all
    terms are accurate (no difference of nearly equal squares), also in float32.
    """
    excess = torch.addcmul(c_lo, u, 2.0 * lo + u)
    # r^2 = R^2 + excess >= 0 always; h = excess / (r + R)
    return excess / (torch.sqrt(excess + planet_radius ** 2) + planet_radius)


def ray_legs(r, mu, planet_radius: float, top_radius: float) -> list[dict[str, torch.Tensor]]:
    """Return the ascending and descending legs of a ray inside the atmosphere.

    Each leg is monotonic in altitude and described in :math:`|t|` by its lower end
    ``lo`` [m], ``c_lo`` :math:`= r_{lo}^2 - R^2` [m^2] and ``length`` [m]; endpoint values
    of :math:`r^2 - R^2` are known exactly (observer :math:`h_0(2R + h_0)`, top
    :math:`h_t(2R + h_t)`, ground 0, closest approach :math:`p^2 - R^2`), and lengths are
    :math:`(c_{hi} - c_{lo})/(hi + lo)`, so nothing cancels near the zenith, the horizon
    or on boundaries.
    """
    segment = _ray_segment(r, mu, planet_radius, top_radius)
    hits, excess = segment["hits_ground"], segment["excess_sq"]
    inside = r <= top_radius
    t_top = safe_sqrt((top_radius - r) * (top_radius + r) + (r * mu) ** 2)
    t_ground = safe_sqrt((r * mu) ** 2 - (r - planet_radius) * (r + planet_radius))
    height = r - planet_radius
    c_obs = height * (r + planet_radius)
    c_top = (top_radius - planet_radius) * (top_radius + planet_radius)
    entering = (~inside) & (mu < 0) & (t_top > 0)
    zero = torch.zeros_like(r * mu)
    # ascending part (t >= 0): from the observer (mu >= 0) or closest approach to the top
    up_exists = (~hits) & (inside | entering)
    from_observer = inside & (mu >= 0)
    up_lo = torch.where(from_observer, r * mu, zero)
    up_c = torch.where(from_observer, c_obs + zero, excess)
    up_len = _safe_divide(c_top - up_c, t_top + up_lo)
    up_len = torch.where(up_exists, torch.clamp(up_len, min=0.0), zero)
    # empty legs start at the observer so that every sample stays above the ground
    up_lo = torch.where(up_exists, up_lo, zero)
    up_c = torch.where(up_exists, up_c, c_obs + zero)
    # descending part (t < 0), mirrored: from closest approach or the ground up to the start
    down_exists = (inside & (mu < 0)) | entering
    down_hi = torch.where(inside, -r * mu, t_top)
    down_c_hi = torch.where(inside, c_obs + zero, c_top + zero)
    down_lo = torch.where(hits, t_ground, zero)
    down_c = torch.where(hits, zero, excess)
    down_len = _safe_divide(down_c_hi - down_c, down_hi + down_lo)
    down_len = torch.where(down_exists, torch.clamp(down_len, min=0.0), zero)
    down_lo = torch.where(down_exists, down_lo, zero)
    down_c = torch.where(down_exists, down_c, c_obs + zero)
    return [{"lo": up_lo, "c_lo": up_c, "length": up_len, "excess": excess},
            {"lo": down_lo, "c_lo": down_c, "length": down_len, "excess": excess}]


def crossing_legs(r, mu, planet_radius: float, top_radius: float
                  ) -> list[dict[str, torch.Tensor]]:
    """Return the legs of :func:`ray_legs` that some ray crosses (a nonzero length)."""
    return [leg for leg in ray_legs(r, mu, planet_radius, top_radius)
            if bool((leg["length"] > 0).any())]


def _gauss_leg(density, leg, planet_radius, levels_m, n_nodes, truncate, support=False,
               block_bytes=None, piecewise=False):
    """Composite Gauss–Legendre integral over one leg, cut at ``levels_m``.

    With ``truncate`` the last level ends the integration (where the density of an
    exponential profile has dropped below a negligible fraction of the leg's maximum);
    with ``support`` the density vanishes outside [first level, last level] and only that
    range is integrated. With ``block_bytes`` (rays along one dim, parameters without batch
    dims) the nodes are evaluated on blocks of rays whose nodes take at most that many
    bytes, so that the temporaries of the density stay in a core's cache; the values are
    those of one evaluation. ``piecewise``: see :func:`column_integral`.
    """
    lo, c_lo, length = leg["lo"], leg["c_lo"], leg["length"]
    dtype = lo.dtype
    if callable(levels_m):
        base = c_lo / (torch.sqrt(torch.clamp(planet_radius ** 2 + c_lo, min=0.0))
                       + planet_radius)
        levels = levels_m(base)
    else:
        levels = levels_m.to(dtype)
    c_levels = levels * (2.0 * planet_radius + levels)  # (R + h)^2 - R^2
    tau_levels = safe_sqrt(c_levels - leg["excess"][..., None])
    u_levels = _safe_divide(c_levels - c_lo[..., None], tau_levels + lo[..., None])
    # a level at or behind the leg's start is not crossed: 0 with a zero gradient (a clamp
    # would pass the derivative of (c_level - c_lo) / (tau + lo), ~1e16 for a horizontal
    # ray from a level's own altitude, where the pieces' boundary terms no longer cancel)
    u_levels = torch.where(u_levels > 0, u_levels, torch.zeros_like(u_levels))
    u_levels = torch.minimum(u_levels, length[..., None])
    shape = broadcast_shape(u_levels.shape[:-1], lo.shape)
    u_levels = u_levels.expand(*shape, -1)
    if support:
        edges = u_levels
    else:
        if truncate:
            length = u_levels[..., -1]
            u_levels = u_levels[..., :-1]
        edges = torch.cat([torch.zeros(*shape, 1, dtype=dtype), u_levels,
                           length[..., None].expand(*shape, 1)], dim=-1)
    width = edges[..., 1:] - edges[..., :-1]
    nodes, weights = unit_nodes(n_nodes, dtype)
    per_ray = width.shape[-1] * n_nodes * width.element_size()
    block = None if block_bytes is None else max(1, block_bytes // per_ray)
    if block is None or len(shape) != 1 or shape[0] <= block:
        return _piece_integrals(density, c_lo, lo, edges, width, nodes, weights, planet_radius,
                                piecewise)
    c_lo, lo = c_lo.expand(shape), lo.expand(shape)
    parts = [_piece_integrals(density, c_lo[i:i + block], lo[i:i + block],
                              edges[i:i + block], width[i:i + block], nodes, weights,
                              planet_radius, piecewise)
             for i in range(0, shape[0], block)]
    if isinstance(parts[0], tuple):
        return tuple(torch.cat(columns) for columns in zip(*parts, strict=True))
    return torch.cat(parts)


def _piece_integrals(density, c_lo, lo, edges, width, nodes, weights, planet_radius,
                     piecewise=False):
    """Sum over the pieces (..., piece) of one leg of their Gauss–Legendre integrals."""
    u = torch.addcmul(edges[..., :-1, None], width[..., None], nodes)  # (..., pieces, nodes)
    n_pieces, n_nodes = u.shape[-2:]
    c_lo, lo = c_lo[..., None, None], lo[..., None, None]
    altitude = _altitude(c_lo, lo, u, planet_radius)
    if piecewise:
        middle = _altitude(c_lo, lo, torch.add(edges[..., :-1], width, alpha=0.5)[..., None],
                           planet_radius)
        values = density(altitude, middle)
    else:
        values = density(altitude.reshape(*altitude.shape[:-2], n_pieces * n_nodes))

    def reduce(value):
        value = value.reshape(*value.shape[:-1], n_pieces, n_nodes)
        return ((value @ weights) * width).sum(-1)

    if isinstance(values, (tuple, list)):
        return tuple(reduce(value) for value in values)
    return reduce(values)


def _add(total, part):
    """``total + part`` for tensors or, elementwise, for tuples of them."""
    if isinstance(part, tuple):
        if not isinstance(total, tuple):
            total = (total,) * len(part)
        return tuple(a + b for a, b in zip(total, part, strict=True))
    return total + part


def _trapezoid_leg(density, leg, planet_radius, n_steps):
    fraction = torch.linspace(0.0, 1.0, n_steps + 1, dtype=leg["lo"].dtype)
    u = leg["length"][..., None] * fraction
    values = density(_altitude(leg["c_lo"][..., None], leg["lo"][..., None], u,
                               planet_radius))
    step = leg["length"] / n_steps

    def reduce(value):
        return step * (value.sum(-1) - 0.5 * (value[..., 0] + value[..., -1]))

    if isinstance(values, (tuple, list)):
        return tuple(reduce(value) for value in values)
    return reduce(values)


def column_integral(density: Density, r, mu, planet_radius: float, top_radius: float,
                    levels_m: torch.Tensor, *, method: str = "gauss",
                    n_steps: int | None = None, rtol: float = 1e-9,
                    truncate: bool = False, support: bool = False,
                    block_bytes: int | None = None,
                    legs: list[dict[str, torch.Tensor]] | None = None,
                    piecewise: bool = False) -> torch.Tensor:
    r"""Path integral :math:`\int \rho(h(s))\,ds` of a density profile along a straight ray.

    Parameters
    ----------
    density : callable
        ``density(altitude_m)`` with ``altitude_m`` of shape ``(..., n_sample)`` returns the
        relative density, same shape (its parameters broadcast against ``...``), or a
        tuple of such densities (several profiles integrated on the same nodes; a tuple
        of columns is returned, and ``"adaptive"`` refines until all have converged).
    r : Tensor (...)
        Radius of the ray's origin [m] (``>= planet_radius``; may lie above the top).
    mu : Tensor (...)
        Cosine of the ray's zenith angle [1].
    planet_radius, top_radius : float
        Radii of the ground and of the top of the atmosphere [m].
    levels_m : Tensor (..., n_level) or callable
        Increasing breakpoint altitudes [m] where the integrand may change character, or
        a function of the lowest altitude of each leg (shape ``(...)``) returning them
        (e.g. that altitude plus multiples of a scale height).
    method : {"gauss", "trapezoid", "adaptive"}
        Quadrature (see the module description).
    n_steps : int, optional
        Nodes per piece ("gauss", start value for "adaptive") or steps ("trapezoid").
    rtol : float
        Relative tolerance of ``"adaptive"``.
    truncate : bool
        The last level ends the integration (the profile is negligible above it).
    support : bool
        The profile vanishes below the first and above the last level (ozone tent): only
        that range is integrated.
    block_bytes : int, optional
        ``"gauss"`` and ``"adaptive"`` with rays along one dim and a ``density`` whose
        parameters have no batch dims: evaluate the density on blocks of rays whose nodes
        take at most this many bytes per tensor (:data:`NODE_BLOCK_BYTES` keeps the
        temporaries in a core's cache; the values are those of one evaluation, bit for bit
        in float64).
    legs : list of dict, optional
        :func:`crossing_legs` of these rays, shared by profiles integrated along the same
        rays (computed here when not given).
    piecewise : bool
        ``"gauss"`` and ``"adaptive"`` call ``density(altitude_m, piece_altitude_m)`` with
        the nodes as (..., piece, node) and the altitude of each piece's middle
        (..., piece, 1), and take back densities of shape (..., piece * node) (a density
        whose character is looked up once per piece: the levels include its boundaries).

    Returns
    -------
    Tensor (...) or tuple of them
        Column integral [m] from the origin (or the atmosphere's entry point) to where the
        ray leaves the atmosphere or meets the ground (one per density of a tuple).
    """
    check_choice("method", method, METHODS)
    n_steps = check_int("n_steps", DEFAULT_STEPS[method] if n_steps is None else n_steps, 1)
    check_rtol(rtol)
    if block_bytes is not None:
        block_bytes = check_int("block_bytes", block_bytes, 1)
    if not (isinstance(r, torch.Tensor) and isinstance(mu, torch.Tensor)
            and r.is_floating_point() and mu.is_floating_point()):
        r = as_tensor("r", r)
        mu = as_tensor("mu", mu, dtype=r.dtype)
    try:
        broadcast_shape(r.shape, mu.shape)
    except ValueError:
        raise ValueError(f"shapes do not broadcast: r {tuple(r.shape)}, mu "
                         f"{tuple(mu.shape)}") from None
    if legs is None:
        legs = crossing_legs(r, mu, planet_radius, top_radius)
    zero = 0.0 * (r * mu)  # keeps the graph: empty paths have a zero (not missing) gradient
    if method == "trapezoid":
        # n_steps uniform steps along each leg
        total = zero
        for leg in legs:
            total = _add(total, _trapezoid_leg(density, leg, planet_radius, n_steps))
        return total if legs else _empty(density, r, zero)

    def integrate(n):
        total = zero
        for leg in legs:
            total = _add(total, _gauss_leg(density, leg, planet_radius, levels_m, n,
                                           truncate, support, block_bytes, piecewise))
        return total if legs else _empty(density, r, zero)

    if method == "gauss":
        return integrate(n_steps)
    return _adaptive(integrate, n_steps, rtol)


def _adaptive(integrate, n_steps: int, rtol: float):
    """``integrate(n)`` with n doubled from ``n_steps`` until converged to ``rtol``."""
    previous = integrate(n_steps)
    n = n_steps
    while n < _MAX_ADAPTIVE_NODES:
        n *= 2
        current = integrate(n)
        with torch.no_grad():
            converged = all(
                bool(((now - before).abs() / now.abs().clamp(min=torch.finfo(now.dtype).tiny)
                      <= rtol).all())
                for now, before in zip(*(_as_tuple(value) for value in (current, previous)),
                                       strict=True))
        previous = current
        if converged:
            break
    return previous


def _as_tuple(value):
    return value if isinstance(value, tuple) else (value,)


def _empty(density, r, zero):
    """Return the zero column(s) of paths that do not cross the atmosphere (one per density)."""
    probe = density(r.new_zeros(*zero.shape, 1))
    if isinstance(probe, (tuple, list)):
        return tuple(zero for _ in probe)
    return zero


def chapman_horizontal(x) -> torch.Tensor:
    r"""Exact Chapman function at zenith angle 90°, :math:`x e^x K_1(x)` (ref. 2).

    Parameters
    ----------
    x : Tensor (...)
        :math:`r / H` [1].

    Returns
    -------
    Tensor (...)
        :math:`\mathrm{Ch}(x, \pi/2)` [1].
    """
    x = check_range("x", x, 0.0, low_inclusive=False)
    return _chapman_horizontal(x)


def _chapman_horizontal(x: torch.Tensor) -> torch.Tensor:
    r""":func:`chapman_horizontal` of a checked tensor.

    Below x = 1e-30 the value is its limit 1 (:math:`x e^x K_1(x) = 1 + O(x^2 \ln x)`;
    :math:`K_1` itself overflows for subnormal x).
    """
    small = x < 1e-30
    safe = torch.where(small, torch.ones_like(x), x)
    return torch.where(small, torch.ones_like(x),
                       safe * torch.special.scaled_modified_bessel_k1(safe))


#: panel ends of the exact Chapman quadrature in u = h/H (e^-45 ~ 3e-20 truncation)
_CHAPMAN_LEVELS = (0.25, 0.5, 1.0, 2.0, 3.0, 4.5, 6.5, 9.0, 12.0, 16.0, 21.0, 27.0, 35.0, 45.0)
_CHAPMAN_NODES = 12


def _chapman_exact_upward(x, y):
    r"""Exact Ch(x, z) for z <= 90 deg from :math:`y = \sqrt{x/2}\cos z` (see chapman)."""
    nodes, weights = unit_nodes(_CHAPMAN_NODES, y.dtype)
    levels = torch.tensor((0.0, *_CHAPMAN_LEVELS), dtype=y.dtype)
    y_ = y[..., None]
    # v at each level u: u = v (v + 2y)  ->  v = u / (y + sqrt(y^2 + u)) (no cancellation)
    ends = levels / (y_ + torch.sqrt(y_ * y_ + levels))
    low, high = ends[..., :-1, None], ends[..., 1:, None]
    v = low + (high - low) * nodes
    x_ = x[..., None, None]
    u = v * (v + 2.0 * y_[..., None])
    w2 = (y_[..., None] + v) ** 2
    q = (1.0 + u / x_) / torch.sqrt(1.0 + u * u / (2.0 * x_ * w2))
    integrand = torch.exp(-u) * q * weights
    return torch.sqrt(2.0 * x) * ((high - low) * integrand).sum(dim=(-1, -2))


def chapman(x, zenith_rad, *, exact: bool = False) -> torch.Tensor:
    r"""Chapman grazing-incidence function, closed-form asymptotic or exact (refs. 1, 2).

    Parameters
    ----------
    x : Tensor (...)
        :math:`r/H` [1] (large: Earth ~800).
    zenith_rad : Tensor (...)
        Zenith angle of the ray at its origin [rad], 0..π.
    exact : bool
        ``False`` (default): Chapman's closed-form asymptotic function (relative error
        :math:`O(1/x)`, ≤ 2e-3 for the Earth). ``True``: the exact integral by quadrature
        (≤ 1e-10 relative in float64, 168 exponentials per value).

    Returns
    -------
    Tensor (...)
        :math:`\mathrm{Ch}(x, z)` [1]: the column from the origin to infinity in units of
        the vertical column, for an exponential atmosphere.

    Notes
    -----
    For :math:`z \le 90°`, with :math:`y = \sqrt{x/2}\,\cos z`, Chapman's leading-order
    form :math:`\mathrm{Ch} \approx \sqrt{\pi x/2}\; e^{y^2}\mathrm{erfc}(y)`, times a
    correction :math:`1 + (c - 1)\sin^2 z` with :math:`c = \mathrm{Ch}(x, 90°) /
    \sqrt{\pi x/2}` from the exact horizontal value, so that it is exact at 90°; the
    relative error elsewhere is :math:`O(1/x)`, at most 2e-3 for the Earth (tested against
    quadrature). For :math:`z > 90°`: :math:`\mathrm{Ch}(x, z) = 2 e^{x - x\sin z}
    \mathrm{Ch}(x \sin z, 90°) - \mathrm{Ch}(x, \pi - z)` (ref. 2).

    Exact form: with the altitude :math:`h` (in units of :math:`H`) as the path variable,

    .. math::

        \mathrm{Ch}(x, z) = \sqrt{x/2}\int_0^\infty
        \frac{e^{-h}\,(1 + h/x)}{\sqrt{y^2 + h + h^2/(2x)}}\,\mathrm{d}h
        = \sqrt{2x}\int_0^\infty e^{-u}\,
        \frac{1 + u/x}{\sqrt{1 + u^2/(2x\,(y + v)^2)}}\,\mathrm{d}v,
        \qquad u = v\,(v + 2y),

    (the first factor of the integrand alone gives Chapman's leading-order form); the
    substitution :math:`\sqrt{y^2 + h} = y + v` removes the :math:`h^{-1/2}` singularity
    of horizontal rays, and the smooth integrand is integrated by 12-node Gauss–Legendre
    on 14 panels between :math:`u` = 0, 0.25, 0.5, 1, 2, ..., 45.
    """
    if not isinstance(exact, bool):
        raise TypeError(f"exact must be True or False; got {exact!r}")
    # (a few ulps of slack: float32 pi rounds above math.pi)
    zenith = check_range("zenith_rad", zenith_rad, 0.0, math.pi + 1e-6, unit=" rad")
    zenith = torch.clamp(zenith, max=math.pi)
    x = check_range("x", x, 0.0, low_inclusive=False, dtype=zenith.dtype)
    try:
        shape = broadcast_shape(x.shape, zenith.shape)
    except ValueError:
        raise ValueError(f"shapes do not broadcast: x {tuple(x.shape)}, zenith_rad "
                         f"{tuple(zenith.shape)}") from None
    x, zenith = (x.expand(shape), zenith.expand(shape)) if exact else (x, zenith)
    below = zenith > 0.5 * math.pi
    z_up = torch.where(below, math.pi - zenith, zenith)
    y = torch.sqrt(0.5 * x) * torch.cos(z_up)
    if exact:
        upper = _chapman_exact_upward(x, y)
    else:
        asymptotic_90 = torch.sqrt(0.5 * math.pi * x)
        correction = _chapman_horizontal(x) / asymptotic_90
        # weight the horizontal correction by sin^2 z: exact at 0 and 90 deg
        weight = torch.sin(z_up) ** 2
        upper = asymptotic_90 * torch.special.erfcx(y) * (1.0 + (correction - 1.0) * weight)
    x_sin = x * torch.sin(zenith)
    lower = 2.0 * torch.exp(x - x_sin) * _chapman_horizontal(x_sin) - upper
    result = torch.where(below, lower, upper)
    with torch.no_grad():
        overflow = ~torch.isfinite(result)
        if bool(overflow.any()):
            # below the horizontal Ch grows like exp(x (1 - sin z)): beyond float range
            raise ValueError(
                "chapman(x, zenith_rad) overflows the floating-point range for zenith_rad > "
                "pi/2 where x (1 - sin z) > ~700 (the ray's lowest point lies that many "
                "scale heights below the origin); got x = "
                f"{float(torch.broadcast_to(x, result.shape)[overflow].reshape(-1)[0])}, "
                f"zenith_rad = "
                f"{float(torch.broadcast_to(zenith, result.shape)[overflow].reshape(-1)[0])}")
    return result


def kasten_young_air_mass(zenith_rad) -> torch.Tensor:
    r"""Relative optical air mass of Kasten & Young (ref. 3).

    :math:`m = 1/(\cos z + 0.50572 (96.07995° - z)^{-1.6364})`, :math:`z` in degrees in
    the second term; includes refraction (apparent zenith angle, in [0, π/2] [rad]: the
    fit ends at the horizon).
    """
    zenith = check_range("zenith_rad", zenith_rad, 0.0, 0.5 * math.pi + 1e-6, unit=" rad")
    zenith = torch.clamp(zenith, max=0.5 * math.pi)
    z_deg = torch.rad2deg(zenith)
    return 1.0 / (torch.cos(zenith) + 0.50572 * (96.07995 - z_deg) ** -1.6364)
