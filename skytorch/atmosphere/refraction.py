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

The code is split by concept: :mod:`~skytorch.atmosphere.ray_geometry` (the index profile,
its slope and kinks, the periapsis of a ray, the checks and per-ray views of a batched
atmosphere), :mod:`~skytorch.atmosphere.bouguer` (the Bouguer integrals),
:mod:`~skytorch.atmosphere.ray_tracer` (the RK4 tracer) and
:mod:`~skytorch.atmosphere.deviation_tables` (the deviation / contact-radius table); this
module holds the public functions, which check their inputs and choose the algorithm, and
re-exports the table functions.

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
>>> from skytorch.atmosphere.ray_geometry import ExponentialAir as Air
>>> r = refraction_angle(Air(), torch.tensor(0.0, dtype=torch.float64))
>>> round(float(r) * 180 / torch.pi * 60)  # arcminutes at the apparent horizon
37
"""

from __future__ import annotations

import math

import torch

from skytorch._validate import check_choice, check_int, check_range, common_dtype
from skytorch.atmosphere.bouguer import (
    DEFAULT_NODES,
    TABLE_NODES,
    TABLE_PANEL_NODES,
    _grazing_observer_bending,
    _observer_bending,
    _observer_optical_depth,
    _trace_grazing_bouguer,
)
from skytorch.atmosphere.deviation_tables import (
    TABLE_PARAMETRISATIONS,
    DeviationTable,
    deviation_table,
    lookup_deviation,
)
from skytorch.atmosphere.inputs import wavelength_tensor
from skytorch.atmosphere.optical_depth import check_rtol
from skytorch.atmosphere.ray_geometry import (
    METHODS,
    _check_atmosphere,
    _check_elevation,
    _check_method,
    _columns_optical_depth,
    _constituents,
    _Dispersive,
    _extinction_of,
    _integrated_species,
    _needs_grad,
    _profile_densities_of,
    _ray_shape,
    _species_levels,
    _wavelengths,
)
from skytorch.atmosphere.ray_tracer import (
    DEFAULT_MAX_DH_M,
    DEFAULT_STEP_M,
    _trace_grazing_rk4,
    _trace_observer_rk4,
)

__all__ = [
    "DEFAULT_MAX_DH_M",
    "DEFAULT_NODES",
    "DEFAULT_STEP_M",
    "GROUND_MODES",
    "METHODS",
    "TABLE_NODES",
    "TABLE_PANEL_NODES",
    "TABLE_PARAMETRISATIONS",
    "DeviationTable",
    "apparent_altitude",
    "bent_optical_depth",
    "deviation_table",
    "horizon_dip",
    "lookup_deviation",
    "refraction_angle",
    "trace_grazing_rays",
]


#: what the observer functions do with a ray that hits the ground (below the apparent
#: horizon): ``"allow"`` continues it through a planet of constant index (refraction) or
#: stops the optical depth at the ground point; ``"raise"`` raises ValueError
GROUND_MODES = ("allow", "raise")


def _dip_terms(atm, height, dtype):
    r"""Geometric and apparent dip of the horizon [rad] for observer altitudes ``height``.

    Closed forms of spherical symmetry (no quadrature): :math:`\cos d_g = R/(R+h)` and,
    with Bouguer's invariant of the ray grazing the ground, :math:`\cos d_a = n(0)R /
    (n(h)(R+h))`; both written as :math:`d = 2\arcsin\sqrt{(1-\cos d)/2}` without
    cancellation.
    """
    radius = float(atm.planet_radius_m)
    top = float(atm.top_altitude_m)
    zero = torch.zeros((), dtype=dtype)
    nu0 = atm.refractivity(zero).to(dtype)
    nu_h = atm.refractivity(torch.clamp(height, 0.0, top)).to(dtype)
    geometric = 2.0 * torch.asin(torch.sqrt(0.5 * height / (radius + height)))
    # 1 - cos d_a = (h (1 + nu_h) - R (nu0 - nu_h)) / ((1 + nu_h) (R + h))
    excess = height * (1.0 + nu_h) - radius * (nu0 - nu_h)
    if bool((excess < 0.0).any()):
        bad = float(torch.broadcast_to(height, excess.shape)[excess < 0.0].reshape(-1)[0])
        raise ValueError(
            f"altitude_m={bad!r} m: the refractive index falls faster with altitude than "
            "1/r between the ground and the observer (n(0) R > n(h) (R + h), a duct), so no "
            "ray from the observer grazes the ground; valid: profiles with "
            "n(h) (R + h) >= n(0) R")
    ratio = excess / ((1.0 + nu_h) * (radius + height))
    apparent = 2.0 * torch.asin(torch.sqrt(torch.clamp(0.5 * ratio, min=0.0)))
    return geometric, apparent


def _first_flagged(mask, *tensors) -> tuple[float, ...]:
    """Values of ``tensors`` (broadcast to ``mask``) at the first flagged element."""
    first = int(mask.reshape(-1).nonzero()[0, 0])
    return tuple(float(torch.broadcast_to(x.detach(), mask.shape).reshape(-1)[first])
                 for x in tensors)


def _check_above_ground(atm, elevation, height, dtype, ground, name, value):
    """Raise for rays below the apparent horizon when ``ground == "raise"``.

    ``elevation``: apparent altitude of the rays at the observers [rad]; ``name`` and
    ``value``: the user's parameter (shown in the message).
    """
    if check_choice("ground", ground, GROUND_MODES) == "allow":
        return
    _, dip = _dip_terms(atm, height.detach(), dtype)
    below = elevation.detach() < -dip
    if bool(below.any()):
        v, h, d = _first_flagged(below, value, height, dip)
        raise ValueError(
            f"{name}={v!r} rad at altitude_m={h!r} m is below the apparent "
            f"horizon ({int(below.sum())} ray(s)): the ray hits the ground; valid apparent "
            f"altitudes are >= -{math.degrees(d):.6g} deg, the apparent dip of the "
            "horizon (horizon_dip); ground='allow' continues such rays through the planet")


def horizon_dip(atm, altitude_m, *, n_nodes: int = DEFAULT_NODES) -> dict[str, torch.Tensor]:
    r"""Dip of the horizon for an elevated observer: geometric and apparent (refracted).

    Parameters
    ----------
    atm : Atmosphere or compatible
        Needs ``planet_radius_m``, ``top_altitude_m`` and ``refractivity(altitude_m)``.
    altitude_m : float or Tensor (...)
        Observer altitude above the (smooth, spherical) ground, ≥ 0 [m].
    n_nodes : int
        Gauss–Legendre nodes of the refraction of the grazing ray (see
        :func:`refraction_angle`).

    Returns
    -------
    dict of Tensor (...)
        ``geometric_dip_rad``: depression of the geometric horizon,
        :math:`\arccos(R/(R+h))` [rad]; ``apparent_dip_rad``: depression below the
        astronomical horizon of the apparent horizon, the ray that grazes the ground
        [rad]; ``refraction_rad``: refraction of that grazing ray from the observer to
        space [rad]; ``true_altitude_rad``: true altitude of a source seen on the apparent
        horizon, −(apparent dip + refraction) [rad] — sources below it are hidden by the
        ground. dtype of ``altitude_m``.

    Notes
    -----
    Bouguer's invariant :math:`b = n(r)\,r\cos e` is constant along a ray, so the ray
    that leaves the observer at apparent altitude :math:`-d_a` and touches the ground
    horizontally satisfies

    .. math:: \cos d_a = \frac{n(0)\,R}{n(h)\,(R+h)},

    exact for a spherically symmetric index. For small dips,
    :math:`d_a^2 \approx 2h/R - 2(\nu(0) - \nu(h)) = d_g^2\,(1 - \bar k)` with
    :math:`\bar k = R(\nu(0)-\nu(h))/h` the mean terrestrial refraction coefficient of
    the layer below the observer (ray curvature over Earth curvature, ≈ 0.13–0.17 for
    the standard lapse rate; refs. 1, 2): the refracted dip is smaller than the
    geometric one and the apparent horizon lies farther away. The observer functions
    accept apparent altitudes down to :math:`-d_a` with ``ground="raise"``.

    References
    ----------
    1. Young, A. T. 2004, "Sunset science. IV. Low-altitude refraction", Astron. J. 127,
       3622, doi:10.1086/420806.
    2. Bomford, G. 1980, *Geodesy*, 4th ed., Clarendon Press, Oxford (terrestrial
       refraction coefficient from pressure, temperature and lapse rate).

    Examples
    --------
    >>> import math, torch
    >>> from skytorch.atmosphere.ray_geometry import ExponentialAir as Air
    >>> dip = horizon_dip(Air(), torch.tensor(3000.0, dtype=torch.float64))
    >>> round(math.degrees(float(dip["geometric_dip_rad"])), 3)
    1.758
    >>> round(math.degrees(float(dip["apparent_dip_rad"])), 3)
    1.588
    """
    _check_atmosphere(atm)
    dtype = common_dtype(altitude_m)
    height = check_range("altitude_m", altitude_m, low=0.0, unit=" m", dtype=dtype)
    geometric, apparent = _dip_terms(atm, height, dtype)
    _, n_nodes = _check_method("bouguer", n_nodes)
    bend = _grazing_observer_bending(atm, height, dtype, n_nodes)
    geometric, apparent, bend = torch.broadcast_tensors(geometric, apparent, bend)
    return {"geometric_dip_rad": geometric, "apparent_dip_rad": apparent,
            "refraction_rad": bend, "true_altitude_rad": -(apparent + bend)}


#: angles whose float32 roundings stand for them (float32 π/2 is 4.4e-8 above π/2)
_EXACT_ANGLES = (-math.pi / 2, math.pi / 2, math.pi)


def _float64(*values, angles=()):
    """Return the float32 tensors among ``values`` in float64 (others unchanged), a tuple.

    The values at the indices ``angles`` [rad] equal to the float32 rounding of ±π/2 or π
    become those angles (in float32 a zenith angle of float32(π/2) is horizontal within
    rounding; in float64 it would be 4.4e-8 rad below the horizon).
    """
    result = []
    for index, value in enumerate(values):
        if isinstance(value, torch.Tensor) and value.dtype == torch.float32:
            wide = value.to(torch.float64)
            if index in angles:
                for angle in _EXACT_ANGLES:
                    rounded = float(torch.tensor(angle, dtype=torch.float32))
                    wide = torch.where(value == rounded, angle, wide)
            value = wide
        result.append(value)
    return tuple(result)


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
    ground: str = "allow",
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
    ground : {"allow", "raise"}
        Rays that hit the ground (apparent altitude below −``apparent_dip_rad`` of
        :func:`horizon_dip`, e.g. −1.62° at 3 km): ``"allow"`` continues them through a
        planet of constant index (a smooth continuation, not an observable), ``"raise"``
        raises ValueError. Elevated observers see down to the apparent dip.

    Returns
    -------
    Tensor (...)
        Refraction [rad], the total bending of the ray from the observer to the top of
        the atmosphere; dtype of the inputs (float32 inputs are traced in float64 and the
        result rounded: in float32 the integrals lose 3e-4 at the horizon).

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
    >>> from skytorch.atmosphere.ray_geometry import ExponentialAir as Air
    >>> e = torch.deg2rad(torch.tensor([45.0], dtype=torch.float64))
    >>> float(refraction_angle(Air(), e) * 206264.8).__round__()  # arcseconds
    57
    """
    method, n_nodes = _check_method(method, n_nodes, n_steps)
    _check_atmosphere(atm)
    dtype = common_dtype(apparent_altitude_rad, altitude_m)
    if dtype == torch.float32:
        # the Bouguer integrals lose 3e-4 of the horizon refraction in float32: the ray in
        # float64, the result in the inputs' float32
        return refraction_angle(
            atm, *_float64(apparent_altitude_rad, altitude_m, angles=(0,)), method=method,
            n_nodes=n_nodes,
            step_m=step_m, max_dh_m=max_dh_m, n_steps=n_steps,
            wavelength_nm=_float64(wavelength_nm)[0], ground=ground).to(torch.float32)
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
    _check_above_ground(atm, apparent_altitude_rad, altitude_m, dtype, ground,
                        "apparent_altitude_rad", apparent_altitude_rad)
    if method == "rk4":
        return _trace_observer_rk4(atm, apparent_altitude_rad, altitude_m, dtype, step_m,
                                   max_dh_m)["deviation_rad"]
    return _observer_bending(atm, apparent_altitude_rad, altitude_m, dtype, n_nodes)[0]



def _check_visible(atm, target, height, dtype, options):
    """Raise when a true altitude lies below the one seen on the apparent horizon."""
    with torch.no_grad():
        _, dip = _dip_terms(atm, height, dtype)
        lowest = -dip - refraction_angle(atm, -dip, height, **options)
        hidden = target < lowest
    if bool(hidden.any()):
        t, h, low = _first_flagged(hidden, target, height, lowest)
        raise ValueError(
            f"true_altitude_rad={t!r} rad at altitude_m={h!r} m is "
            f"hidden by the ground ({int(hidden.sum())} source(s)): valid true altitudes are "
            f">= {math.degrees(low):.6g} deg, the true altitude seen on the apparent "
            "horizon (horizon_dip)")


def _visible_branch(atm, target, height, dtype, options, raise_hidden):
    """Lower bound and mask of the apparent altitudes of visible sources.

    Above the ground, :math:`e - R(e)` has its minimum at the apparent horizon
    :math:`-d_a`: a true altitude just above the lowest visible one (:func:`horizon_dip`)
    is reached by two apparent altitudes, one above the horizon (the visible source) and
    one below it on the continued refraction (a ray into the ground). Returns
    ``(-d_a, visible)``; ``visible`` is false everywhere when the index ducts (no ray
    grazes the ground, ``ground="allow"`` only).
    """
    try:
        _, dip = _dip_terms(atm, height, dtype)
    except ValueError:
        if raise_hidden:
            raise
        return torch.zeros_like(target), torch.zeros_like(target, dtype=torch.bool)
    low = torch.broadcast_to(-dip, target.shape)
    lowest = low - refraction_angle(atm, low, height, **options)
    return low.clone(), target >= lowest


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
    ground: str = "allow",
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
    ground : {"allow", "raise"}
        ``"raise"``: a true altitude below the ``true_altitude_rad`` of
        :func:`horizon_dip` (the source is hidden by the ground) raises ValueError;
        ``"allow"``: the inverse of the continued refraction (see
        :func:`refraction_angle`).

    Returns
    -------
    Tensor (...)
        Apparent altitude [rad]. The last Newton step carries the gradient, so
        derivatives are exact.

    Examples
    --------
    >>> import torch
    >>> from skytorch.atmosphere.ray_geometry import ExponentialAir as Air
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
    raise_hidden = check_choice("ground", ground, GROUND_MODES) == "raise"
    if raise_hidden:
        _check_visible(atm, target, height, dtype, options)
    target, height = torch.broadcast_tensors(target, height)
    limit = math.pi / 2
    delta = 1e-6 if dtype == torch.float64 else 1e-3
    floor = 8 * torch.finfo(dtype).eps

    def residual(e):
        return e - refraction_angle(atm, e, height, **options) - target

    with torch.no_grad():
        low, visible = _visible_branch(atm, target, height, dtype, options, raise_hidden)
        e = torch.clamp(target + 0.01 * (target < 0.5), -limit, limit)
        e = torch.where(visible, torch.maximum(e, low), e)
        high = torch.full_like(e, limit)
        for _ in range(iterations):
            lo = torch.clamp(e - delta, -limit, limit)
            hi = torch.clamp(e + delta, -limit, limit)
            derivative = (residual(hi) - residual(lo)) / (hi - lo)
            f = residual(e)
            step = torch.clamp(e - f / derivative, -limit, limit)
            # a visible source: the root above the apparent horizon, kept in its bracket
            # [low, high] (bisection where Newton's step leaves it)
            low = torch.where(visible & (f < 0), e, low)
            high = torch.where(visible & (f > 0), e, high)
            outside = visible & ((step <= low) | (step >= high) | ~torch.isfinite(step))
            # a root already found stays (at the zenith Newton's step is the bracket's end)
            converged = f.abs() <= max(tolerance, float(floor))
            e = torch.where(converged, e, torch.where(outside, 0.5 * (low + high), step))
            if bool(converged.all()):
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
    ground: str = "allow",
) -> torch.Tensor | dict[str, torch.Tensor]:
    r"""Optical depth from an observer to space along the refracted ray.

    Parameters
    ----------
    atm : Atmosphere or compatible
        An :class:`~skytorch.atmosphere.Atmosphere` (its ``constituents`` and
        ``profiles``: the path column of every species is integrated and turned into
        optical depths by :meth:`~skytorch.atmosphere.constituents.Constituents.optical_depth`,
        nonlinear band laws included), or any object with
        ``extinction_coefficient(altitude_m, wavelength_nm)`` [1/m] (integrated along
        the path).
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
        Return the optical depth of every species of the atmosphere's constituents by
        name (``rayleigh``, ``aerosol``, ``ozone``, ...); needs an
        :class:`~skytorch.atmosphere.Atmosphere`.
    rtol : float
        Tolerance of the straight-ray ``"adaptive"`` integrator: checked (in (0, 1]) and
        otherwise unused here (the Gauss–Legendre rule has a fixed number of nodes).
    ground : {"allow", "raise"}
        Rays below the apparent horizon (zenith angle beyond π/2 + the
        ``apparent_dip_rad`` of :func:`horizon_dip`): ``"allow"`` gives the optical depth
        to the ground point, ``"raise"`` raises ValueError. Rays between the
        astronomical and the apparent horizon of an elevated observer descend to their
        periapsis and climb to space: their optical depth (and air mass) is that whole
        path.

    Returns
    -------
    Tensor (..., n_wavelength) or dict of Tensor
        Optical depth [1] along the bent path to the top of the atmosphere; for rays that
        hit the ground (below the apparent horizon) the optical depth to the ground
        point. Float32 inputs are traced in float64 and the result rounded to float32
        (a float32 π/2 zenith angle stays horizontal).

    Notes
    -----
    :math:`\tau = \int k(h)\,\mathrm{d}s` with :math:`\mathrm{d}s = u\,|\mathrm{d}r| /
    \sqrt{u^2-b^2}`, integrated over :math:`t` like :func:`refraction_angle`; for an
    Atmosphere the columns :math:`\int\rho_s\,\mathrm{d}s` of its species are integrated
    that way and :math:`\tau = \sum_s \tau_s(\text{column}_s)`. The
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
    if per_species and not hasattr(atm, "constituents"):
        raise TypeError("per_species=True needs an Atmosphere (its constituents); got "
                        f"{type(atm).__name__}")
    _check_atmosphere(atm, *(("profiles",) if hasattr(atm, "constituents")
                             else ("extinction_coefficient",)))
    dtype = common_dtype(zenith_rad, altitude_m)
    if dtype == torch.float32:
        # float32 bent columns were 2e-4 off at the zenith: the ray in float64, the result
        # in the inputs' float32
        tau = bent_optical_depth(
            atm, _float64(wavelength_nm)[0], *_float64(zenith_rad, altitude_m, angles=(0,)),
            method=method,
            n_nodes=n_nodes, step_m=step_m, max_dh_m=max_dh_m, n_steps=n_steps,
            per_species=per_species, rtol=rtol, ground=ground)
        if isinstance(tau, dict):
            return {name: value.to(torch.float32) for name, value in tau.items()}
        return tau.to(torch.float32)
    limit = math.pi * (1.0 + 4.0 * torch.finfo(dtype).eps)
    zenith = check_range("zenith_rad", zenith_rad, 0.0, limit, unit=" rad", dtype=dtype)
    height = check_range("altitude_m", altitude_m, low=0.0, unit=" m", dtype=dtype)
    _ray_shape(atm, zenith_rad=zenith, altitude_m=height)
    wavelength = _wavelengths(wavelength_nm, dtype)
    if hasattr(atm, "constituents"):  # an Atmosphere: its spectral range
        wavelength = wavelength_tensor(wavelength, dtype)
    elevation = torch.clamp(0.5 * math.pi - zenith, -0.5 * math.pi, 0.5 * math.pi)
    _check_above_ground(atm, elevation, height, dtype, ground, "zenith_rad", zenith)
    constituents = _constituents(atm, wavelength, dtype)
    if constituents is None:
        coefficient_of = _extinction_of(wavelength)
    else:  # path columns of the species
        names = _integrated_species(constituents)
        coefficient_of = _profile_densities_of(names, dtype)
    levels = () if constituents is None else _species_levels(constituents)
    if method == "rk4":
        tau = _trace_observer_rk4(atm, elevation, height, dtype, step_m, max_dh_m,
                                  coefficient=coefficient_of)["optical_depth"]
    else:
        tau = _observer_optical_depth(atm, elevation, height, dtype, n_nodes, coefficient_of,
                                      levels)
    if constituents is None:
        return tau
    return _columns_optical_depth(constituents, names, tau, per_species)



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
        optical depth, ``constituents`` and ``profiles`` (an
        :class:`~skytorch.atmosphere.Atmosphere`: path columns of its species, see
        :func:`bent_optical_depth`) or ``extinction_coefficient``.
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
    >>> from skytorch.atmosphere.ray_geometry import ExponentialAir as Air
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
    optical = (() if wavelength_nm is None else ("profiles",) if hasattr(atm, "constituents")
               else ("extinction_coefficient",))
    _check_atmosphere(atm, *optical)
    dtype = common_dtype(impact_parameter_m, impact_altitude_m, periapsis_altitude_m)
    radius = float(atm.planet_radius_m)
    if impact_parameter_m is not None:
        b_geo = check_range("impact_parameter_m", impact_parameter_m, low=0.0, unit=" m",
                            dtype=dtype)
        impact_altitude_m = b_geo - radius
    wavelength = None if wavelength_nm is None else _wavelengths(wavelength_nm, dtype)
    if wavelength is not None and hasattr(atm, "constituents"):  # an Atmosphere
        wavelength = wavelength_tensor(wavelength, dtype)
    constituents = None if wavelength is None else _constituents(atm, wavelength, dtype)
    if constituents is not None:  # path columns of the species
        names = _integrated_species(constituents)
        coefficient_of = _profile_densities_of(names, dtype)
    else:
        coefficient_of = None if wavelength is None else _extinction_of(wavelength)
    if method == "rk4":
        if periapsis_altitude_m is not None:
            raise ValueError("method='rk4' needs impact_parameter_m or impact_altitude_m")
        beta_geo = check_range("impact_altitude_m", impact_altitude_m, low=-radius,
                               unit=" m", dtype=dtype)
        output = _trace_grazing_rk4(atm, beta_geo, coefficient_of, dtype, step_m, max_dh_m)
    else:
        levels = () if constituents is None else _species_levels(constituents)
        output = _trace_grazing_bouguer(atm, coefficient_of, dtype, n_nodes,
                                        impact_altitude_m=impact_altitude_m,
                                        periapsis_altitude_m=periapsis_altitude_m,
                                        levels=levels)
    if constituents is not None:
        output["optical_depth"] = _columns_optical_depth(constituents, names,
                                                         output["optical_depth"], False)
    return output
