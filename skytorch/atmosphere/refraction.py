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
    ``max_dh_m`` per step. It shares no formula with the Bouguer integrals and serves as
    the independent check.

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

import functools
import logging
import math

import numpy as np
import torch

from skytorch._validate import as_tensor, check_choice, check_int, check_range, common_dtype

__all__ = [
    "METHODS",
    "apparent_altitude",
    "bent_optical_depth",
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


class _Geometry:
    """Planet radius, top altitude and the refractive-index profile of an atmosphere.

    Only ``atm.planet_radius_m``, ``atm.top_altitude_m`` and ``atm.refractivity`` are
    used, so any object with these attributes works.
    """

    def __init__(self, atm, dtype: torch.dtype):
        self.atm = atm
        self.dtype = dtype
        self.radius = float(atm.planet_radius_m)
        self.top = float(atm.top_altitude_m)
        if not (self.radius > 0 and self.top > 0):
            raise ValueError(
                f"atmosphere needs planet_radius_m > 0 and top_altitude_m > 0; got "
                f"{self.radius!r} and {self.top!r}")
        zero = torch.zeros((), dtype=dtype)
        self.nu0, slope0 = self.refractivity_and_slope(zero)
        self.nu_top = self.refractivity(zero + self.top)
        # m at the ground: u'(R) = 1 + nu0 + R nu'(0) must stay > 0 (no ducting)
        ground_slope = float(1.0 + self.nu0.detach() + self.radius * slope0.detach())
        if not ground_slope > 0.0:
            raise ValueError(
                "the refractive-index profile traps horizontal rays (d(n r)/dr = "
                f"{ground_slope:.3g} <= 0 at the ground); Bouguer integrals need n r to grow "
                "with r")

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
        value = self.atm.refractivity(clamped).to(self.dtype)
        graph = value.requires_grad  # inputs or profile parameters need derivatives
        with torch.enable_grad():
            leaf = clamped if clamped.requires_grad else clamped.detach().requires_grad_(True)
            if value.shape != leaf.shape:  # a batched profile: one slope per element
                leaf = leaf.expand(value.shape)
            nu = self.atm.refractivity(leaf).to(self.dtype)
            if nu.requires_grad:
                (slope,) = torch.autograd.grad(nu, leaf, torch.ones_like(nu), create_graph=graph)
            else:  # constant profile
                slope = torch.zeros_like(nu)
        nu = value
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
        tol = 1e-9 * top if self.dtype == torch.float64 else 1e-5 * top
        with torch.no_grad():
            h = torch.clamp(beta, 0.0, top)
            for _ in range(60):
                nu, slope = self.refractivity_and_slope(h)
                f = h + nu * (radius + h) - beta
                fprime = 1.0 + nu + (radius + h) * slope
                step = f / fprime
                h = torch.clamp(h - step, 0.0, top)
                if bool((step.abs() <= tol).all()):
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

    def integrate(self, t_low, t_high, n_nodes, *, bending=True, extinction=None):
        """Quadrature over ``t`` in [t_low, t_high] of the bending and path integrands.

        Returns the bending [rad] (*S,) and, with ``extinction`` = (atm, wavelength_nm),
        the optical depth (*S, n_wl).
        """
        geometry = self.geometry
        ndim = max(self.h_p.dim(), torch.as_tensor(t_low).dim(), torch.as_tensor(t_high).dim())
        x, w = _gauss_nodes(n_nodes, geometry.dtype, ndim)
        span = t_high - t_low
        t = t_low + span * x
        weight = span * w
        altitude = self.h_p + self.length * t * t
        nu, slope = geometry.refractivity_and_slope(altitude)
        m = torch.clamp(self.slope_ratio(altitude, nu, slope), min=1e-6)
        u = (geometry.radius + altitude) * (1.0 + nu)
        jacobian = 2.0 * torch.sqrt(self.length) / torch.sqrt(m * (u + self.b))
        result = {}
        if bending:
            integrand = -slope * self.b / (1.0 + nu) * jacobian
            result["bending"] = (weight * integrand).sum(0)
        if extinction is not None:
            atm, wavelength_nm = extinction
            k = atm.extinction_coefficient(torch.clamp(altitude, 0.0, geometry.top),
                                           wavelength_nm).to(geometry.dtype)
            path = (weight * u * jacobian).unsqueeze(-1)
            result["optical_depth"] = (path * k).sum(0)
        return result


def _check_method(method: str) -> str:
    return check_choice("method", method, METHODS)


def _wavelengths(wavelength_nm, dtype):
    wavelength_nm = check_range("wavelength_nm", wavelength_nm, low=0.0, low_inclusive=False,
                                unit=" nm", dtype=dtype)
    return wavelength_nm.reshape(-1)


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
    elevation, height = torch.broadcast_tensors(elevation, height)
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
    _check_method(method)
    dtype = common_dtype(apparent_altitude_rad, altitude_m)
    if method == "rk4":
        return _trace_observer_rk4(atm, apparent_altitude_rad, altitude_m, dtype, step_m,
                                   max_dh_m)["deviation"]
    n_nodes = check_int("n_nodes", n_nodes, low=2)
    geometry, rays, elevation, _, t0 = _observer_rays(atm, apparent_altitude_rad, altitude_m,
                                                      dtype)
    down_hit = (elevation < 0.0) & rays.hits
    start = torch.where(down_hit, rays.t_ground, t0)
    bending = rays.integrate(start, torch.ones_like(start), n_nodes)["bending"]
    if bool(down_hit.any()):
        extra = rays.integrate(rays.t_ground, torch.maximum(-t0, rays.t_ground),
                               n_nodes)["bending"]
        bending = bending + torch.where(down_hit, extra, torch.zeros_like(extra))
    return torch.where(rays.misses, torch.zeros_like(bending), bending)


def apparent_altitude(
    atm,
    true_altitude_rad,
    altitude_m=0.0,
    *,
    tolerance_rad: float = 1e-3 * math.pi / 648000.0,
    max_iterations: int = 30,
    **options,
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
    **options
        Passed to :func:`refraction_angle` (``method``, ``n_nodes``, ...).

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
    dtype = common_dtype(true_altitude_rad, altitude_m)
    target = _check_elevation("true_altitude_rad", true_altitude_rad, dtype)
    height = as_tensor("altitude_m", altitude_m, dtype=dtype)
    target, height = torch.broadcast_tensors(target, height)
    limit = math.pi / 2
    delta = 1e-6 if dtype == torch.float64 else 1e-3
    floor = 8 * torch.finfo(dtype).eps

    def residual(e):
        return e - refraction_angle(atm, e, height, **options) - target

    with torch.no_grad():
        e = torch.clamp(target + 0.01 * (target < 0.5), -limit, limit)
        for _ in range(check_int("max_iterations", max_iterations, low=1)):
            lo = torch.clamp(e - delta, -limit, limit)
            hi = torch.clamp(e + delta, -limit, limit)
            derivative = (residual(hi) - residual(lo)) / (hi - lo)
            f = residual(e)
            e = torch.clamp(e - f / derivative, -limit, limit)
            if bool((f.abs() <= max(tolerance_rad, float(floor))).all()):
                break
    if torch.is_grad_enabled() and (target.requires_grad or height.requires_grad):
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
) -> torch.Tensor:
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
        See :func:`refraction_angle`.

    Returns
    -------
    Tensor (..., n_wavelength)
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
    _check_method(method)
    dtype = common_dtype(zenith_rad, altitude_m)
    zenith = check_range("zenith_rad", zenith_rad, 0.0, math.pi, unit=" rad", dtype=dtype)
    wavelength = _wavelengths(wavelength_nm, dtype)
    elevation = 0.5 * math.pi - zenith
    if method == "rk4":
        return _trace_observer_rk4(atm, elevation, altitude_m, dtype, step_m, max_dh_m,
                                   extinction=(atm, wavelength))["optical_depth"]
    n_nodes = check_int("n_nodes", n_nodes, low=2)
    geometry, rays, elevation, _, t0 = _observer_rays(atm, elevation, altitude_m, dtype)
    down_hit = (elevation < 0.0) & rays.hits
    # up to the top: [t0, 1]; rays hitting the ground: from the ground to the observer
    low = torch.where(down_hit, rays.t_ground, t0)
    high = torch.where(down_hit, torch.maximum(-t0, rays.t_ground), torch.ones_like(t0))
    tau = rays.integrate(low, high, n_nodes, bending=False,
                         extinction=(atm, wavelength))["optical_depth"]
    return torch.where(rays.misses.unsqueeze(-1), torch.zeros_like(tau), tau)


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
    _check_method(method)
    given = [name for name, value in (("impact_parameter_m", impact_parameter_m),
                                      ("impact_altitude_m", impact_altitude_m),
                                      ("periapsis_altitude_m", periapsis_altitude_m))
             if value is not None]
    if len(given) != 1:
        raise ValueError("give exactly one of impact_parameter_m, impact_altitude_m and "
                         f"periapsis_altitude_m; got {given or 'none'}")
    dtype = common_dtype(impact_parameter_m, impact_altitude_m, periapsis_altitude_m)
    radius = float(atm.planet_radius_m)
    if impact_parameter_m is not None:
        b_geo = check_range("impact_parameter_m", impact_parameter_m, low=0.0, unit=" m",
                            dtype=dtype)
        impact_altitude_m = b_geo - radius
    wavelength = None if wavelength_nm is None else _wavelengths(wavelength_nm, dtype)
    if method == "rk4":
        if periapsis_altitude_m is not None:
            raise ValueError("method='rk4' needs impact_parameter_m or impact_altitude_m")
        beta_geo = check_range("impact_altitude_m", impact_altitude_m, low=-radius,
                               unit=" m", dtype=dtype)
        return _trace_grazing_rk4(atm, beta_geo, wavelength, dtype, step_m, max_dh_m)
    n_nodes = check_int("n_nodes", n_nodes, low=2)
    geometry = _Geometry(atm, dtype)
    if periapsis_altitude_m is not None:
        h_p = check_range("periapsis_altitude_m", periapsis_altitude_m, low=-radius,
                          unit=" m", dtype=dtype)
    else:
        beta_geo = check_range("impact_altitude_m", impact_altitude_m, low=-radius,
                               unit=" m", dtype=dtype)
        # Bouguer invariant b = n_top * b_geo (the index is continued above the top)
        h_p = geometry.periapsis_altitude(beta_geo + geometry.nu_top * (radius + beta_geo))
    rays = _Rays(geometry, h_p)
    extinction = None if wavelength is None else (atm, wavelength)
    result = rays.integrate(rays.t_ground, torch.ones_like(h_p), n_nodes,
                            extinction=extinction)
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


def _rk4_trace(geometry, position, direction, extinction, step_m, max_dh_m, max_length,
               stop_at_ground=False):
    """Trace rays in the plane with RK4 until they leave the atmosphere upwards.

    With ``stop_at_ground`` a ray also stops once it is below the ground (optical depth
    from an observer to the ground).

    ``position`` (N, 2) [m] and ``direction`` (N, 2) unit vectors. Returns the final
    direction, the minimum radius along the path and the optical depth (N, n_wl) or None.
    """
    radius, top = geometry.radius, geometry.top
    dtype = position.dtype
    r_top = radius + top

    def index_and_gradient(p):
        r = torch.linalg.vector_norm(p, dim=-1)
        nu, slope = geometry.refractivity_and_slope(r - radius)
        return 1.0 + nu, slope.unsqueeze(-1) * p / r.unsqueeze(-1), r

    def extinction_at(r):
        atm, wavelength = extinction
        h = r - radius
        inside = ((h >= 0.0) & (h <= top)).unsqueeze(-1)
        k = atm.extinction_coefficient(torch.clamp(h, 0.0, top), wavelength).to(dtype)
        return torch.where(inside, k, torch.zeros_like(k))

    def derivative(p, v):
        n, grad, r = index_and_gradient(p)
        dp = v / n.unsqueeze(-1)
        dk = extinction_at(r) if extinction is not None else None
        return dp, grad, dk

    n0, _, r0 = index_and_gradient(position)
    v = direction * n0.unsqueeze(-1)  # optical direction n d
    p = position
    tau = None
    if extinction is not None:
        tau = torch.zeros(position.shape[:-1] + (extinction[1].numel(),), dtype=dtype)
    r_min = r0.clone()
    travelled = torch.zeros_like(r0)
    done = torch.zeros_like(r0, dtype=torch.bool)
    for _ in range(1_000_000):
        r = torch.linalg.vector_norm(p, dim=-1)
        n, _, _ = index_and_gradient(p)
        radial = (p * v).sum(-1) / (r * n)  # d r / d s = cos(local zenith angle)
        done = done | ((r >= r_top) & (radial >= 0.0)) | (travelled >= max_length)
        if stop_at_ground:
            done = done | (r < radius)
        if bool(done.all()):
            break
        ds = torch.minimum(torch.full_like(r, step_m),
                           max_dh_m / torch.clamp(radial.abs(), min=1e-12))
        ds = torch.where(done, torch.zeros_like(ds), ds)
        h2 = ds.unsqueeze(-1)
        k1p, k1v, k1k = derivative(p, v)
        k2p, k2v, k2k = derivative(p + 0.5 * h2 * k1p, v + 0.5 * h2 * k1v)
        k3p, k3v, k3k = derivative(p + 0.5 * h2 * k2p, v + 0.5 * h2 * k2v)
        k4p, k4v, k4k = derivative(p + h2 * k3p, v + h2 * k3v)
        p_new = p + h2 / 6.0 * (k1p + 2.0 * k2p + 2.0 * k3p + k4p)
        v_new = v + h2 / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        if tau is not None:
            tau = tau + h2 / 6.0 * (k1k + 2.0 * k2k + 2.0 * k3k + k4k)
        # minimum radius: a parabola through the radial speeds at both ends of the step
        r_new = torch.linalg.vector_norm(p_new, dim=-1)
        n_new, _, _ = index_and_gradient(p_new)
        radial_new = (p_new * v_new).sum(-1) / (r_new * n_new)
        curvature = (radial_new - radial) / torch.clamp(ds, min=1e-30)
        turning = (radial < 0.0) & (radial_new >= 0.0) & (curvature > 0.0) & ~done
        safe = torch.where(turning, curvature, torch.ones_like(curvature))
        vertex = r - radial * radial / (2.0 * safe)
        candidate = torch.where(turning, vertex, torch.minimum(r, r_new))
        r_min = torch.where(done, r_min, torch.minimum(r_min, candidate))
        p, v = p_new, v_new
        travelled = travelled + ds
    else:  # pragma: no cover - guarded by max_length
        raise RuntimeError("RK4 ray tracing did not terminate")
    direction_out = v / torch.linalg.vector_norm(v, dim=-1, keepdim=True)
    return direction_out, r_min, tau


def _clockwise_angle(d0, d1):
    """Angle by which ``d1`` is rotated clockwise from ``d0`` (bending towards the planet)."""
    cross = d0[..., 0] * d1[..., 1] - d0[..., 1] * d1[..., 0]
    dot = (d0 * d1).sum(-1)
    return torch.atan2(-cross, dot)


def _trace_observer_rk4(atm, elevation, altitude_m, dtype, step_m, max_dh_m, extinction=None):
    elevation = _check_elevation("apparent_altitude_rad", elevation, dtype)
    height = check_range("altitude_m", altitude_m, low=0.0, unit=" m", dtype=dtype)
    step_m = float(check_range("step_m", step_m, low=0.0, low_inclusive=False, unit=" m"))
    max_dh_m = float(check_range("max_dh_m", max_dh_m, low=0.0, low_inclusive=False,
                                 unit=" m"))
    elevation, height = torch.broadcast_tensors(elevation, height)
    shape = elevation.shape
    geometry = _Geometry(atm, dtype)
    e = elevation.reshape(-1)
    r0 = geometry.radius + height.reshape(-1)
    position = torch.stack([torch.zeros_like(r0), r0], dim=-1)
    direction = torch.stack([torch.cos(e), torch.sin(e)], dim=-1)
    r_top = geometry.radius + geometry.top
    max_length = 4.0 * math.sqrt(r_top**2 - geometry.radius**2) + 4.0 * geometry.top
    final, _, tau = _rk4_trace(geometry, position, direction, extinction, step_m, max_dh_m,
                               max_length, stop_at_ground=extinction is not None)
    if extinction is not None:
        return {"optical_depth": tau.reshape(shape + (tau.shape[-1],))}
    return {"deviation": _clockwise_angle(direction, final).reshape(shape)}


def _trace_grazing_rk4(atm, beta_geo, wavelength, dtype, step_m, max_dh_m):
    step_m = float(check_range("step_m", step_m, low=0.0, low_inclusive=False, unit=" m"))
    max_dh_m = float(check_range("max_dh_m", max_dh_m, low=0.0, low_inclusive=False,
                                 unit=" m"))
    geometry = _Geometry(atm, dtype)
    shape = beta_geo.shape
    radius = geometry.radius
    r_top = radius + geometry.top
    b = radius + beta_geo.reshape(-1)
    chord = torch.sqrt(torch.clamp((r_top - b) * (r_top + b), min=0.0))
    position = torch.stack([-chord, b], dim=-1)
    direction = torch.stack([torch.ones_like(b), torch.zeros_like(b)], dim=-1)
    extinction = None if wavelength is None else (atm, wavelength)
    max_length = 4.0 * math.sqrt(r_top**2 - radius**2) + 4.0 * geometry.top
    final, r_min, tau = _rk4_trace(geometry, position, direction, extinction, step_m,
                                   max_dh_m, max_length)
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
