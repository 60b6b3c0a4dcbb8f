r"""Phase functions and single-scattering sky radiance.

Phase functions are normalised over the sphere, :math:`\int P\,d\Omega = 1` [1/sr].

References
----------
1. Chandrasekhar, S. 1950, *Radiative Transfer*, Oxford (Rayleigh phase function).
2. Henyey, L. G. & Greenstein, J. L. 1941, "Diffuse radiation in the Galaxy",
   ApJ 93, 70, doi:10.1086/144246.
3. Cornette, W. M. & Shanks, J. G. 1992, "Physically reasonable analytic expression for
   the single-scattering phase function", Appl. Opt. 31, 3152,
   doi:10.1364/AO.31.003152.
4. Bruneton, E. & Neyret, F. 2008, "Precomputed Atmospheric Scattering", Computer
   Graphics Forum 27, 1079, doi:10.1111/j.1467-8659.2008.01245.x.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere.scattering import rayleigh_phase
>>> round(float(rayleigh_phase(torch.tensor(1.0))) * 4 * 3.141592653589793, 3)
1.5
"""

from __future__ import annotations

import math
from typing import NamedTuple

import torch

from skytorch._quadrature import unit_nodes
from skytorch._validate import (
    broadcast_shape,
    check_choice,
    check_finite,
    check_int,
    check_range,
    check_zenith,
    common_dtype,
)
from skytorch.atmosphere.constituents import insert_dims
from skytorch.atmosphere.geometry import _distance_to_ground, _distance_to_top, _ray_hits_ground
from skytorch.atmosphere.inputs import altitude_tensor, check_atmosphere, wavelength_tensor

__all__ = [
    "PHASE_FUNCTIONS",
    "SECOND_ORDER_SPACING_POWER",
    "GatheredLineOfSight",
    "gather_on_line_of_sight",
    "constituent_radiance",
    "single_scattering_radiance",
    "cornette_shanks",
    "cumulative_columns",
    "henyey_greenstein",
    "phase_function",
    "rayleigh_phase",
    "second_order_radiance",
]

#: aerosol phase-function models
PHASE_FUNCTIONS = ("cornetteshanks1992", "henyeygreenstein1941")


#: slack on |cos theta| <= 1 for cosines formed from rounded unit vectors
_COS_SLACK = 1e-5


def _cosine(cos_theta) -> torch.Tensor:
    """cos(theta) checked to lie in [-1, 1] (a rounding slack, then clamped)."""
    cos_theta = check_range("cos_theta", cos_theta, -1.0 - _COS_SLACK, 1.0 + _COS_SLACK)
    return torch.clamp(cos_theta, -1.0, 1.0)


def _asymmetry(g, cos_theta) -> torch.Tensor:
    """Asymmetry parameter in (-1, 1), broadcastable with ``cos_theta``."""
    g = check_range("g", g, -1.0, 1.0, low_inclusive=False, high_inclusive=False,
                    dtype=cos_theta.dtype)
    try:
        broadcast_shape(g.shape, cos_theta.shape)
    except ValueError:
        raise ValueError(f"shapes do not broadcast: cos_theta {tuple(cos_theta.shape)}, "
                         f"g {tuple(g.shape)}") from None
    return g


def rayleigh_phase(cos_theta) -> torch.Tensor:
    r"""Rayleigh phase function :math:`\frac{3}{16\pi}(1 + \cos^2\theta)` [1/sr] (ref. 1).

    Parameters
    ----------
    cos_theta : Tensor (...)
        Cosine of the scattering angle [1].
    """
    cos_theta = _cosine(cos_theta)
    return 3.0 / (16.0 * math.pi) * (1.0 + cos_theta * cos_theta)


def henyey_greenstein(cos_theta, g) -> torch.Tensor:
    r"""Henyey–Greenstein phase function [1/sr] (ref. 2).

    :math:`P = \frac{1}{4\pi}\frac{1 - g^2}{(1 + g^2 - 2 g \cos\theta)^{3/2}}`.

    Parameters
    ----------
    cos_theta : Tensor (...)
        Cosine of the scattering angle [1].
    g : float or Tensor (...)
        Asymmetry parameter, -1 < g < 1 [1].
    """
    cos_theta = _cosine(cos_theta)
    g = _asymmetry(g, cos_theta)
    return (1.0 - g * g) / (4.0 * math.pi * (1.0 + g * g - 2.0 * g * cos_theta) ** 1.5)


def cornette_shanks(cos_theta, g) -> torch.Tensor:
    r"""Cornette–Shanks phase function [1/sr] (ref. 3, as used in ref. 4).

    :math:`P = \frac{3}{8\pi}\frac{(1 - g^2)(1 + \cos^2\theta)}
    {(2 + g^2)(1 + g^2 - 2 g\cos\theta)^{3/2}}`.
    """
    cos_theta = _cosine(cos_theta)
    g = _asymmetry(g, cos_theta)
    return (3.0 / (8.0 * math.pi) * (1.0 - g * g) * (1.0 + cos_theta * cos_theta)
            / ((2.0 + g * g) * (1.0 + g * g - 2.0 * g * cos_theta) ** 1.5))


def phase_function(cos_theta, g, model: str = "cornetteshanks1992") -> torch.Tensor:
    """Aerosol phase function by model keyword (``PHASE_FUNCTIONS``) [1/sr]."""
    check_choice("model", model, PHASE_FUNCTIONS)
    if model == "cornetteshanks1992":
        return cornette_shanks(cos_theta, g)
    return henyey_greenstein(cos_theta, g)


def _direction(zenith, azimuth):
    """Return unit vectors (..., 3) in the observer's (north, east, up) frame."""
    zenith, azimuth = torch.broadcast_tensors(zenith, azimuth)
    sin_z = torch.sin(zenith)
    return torch.stack([sin_z * torch.cos(azimuth), sin_z * torch.sin(azimuth),
                        torch.cos(zenith)], dim=-1)


def single_scattering_radiance(atmosphere, wavelength_nm, view_zenith_rad,
                               view_azimuth_rad=0.0, sun_zenith_rad=0.0,
                               sun_azimuth_rad=0.0, altitude_m=0.0, *, n_samples: int = 128,
                               table=None, sun_steps: int | None = None) -> torch.Tensor:
    r"""Single-scattering sky radiance per unit extraterrestrial solar irradiance [1/sr].

    Parameters
    ----------
    atmosphere : Atmosphere
        The atmosphere (its parameters broadcast with the angles); TypeError for any
        other object.
    wavelength_nm : Tensor (wavelength,)
        Wavelengths [nm].
    view_zenith_rad, view_azimuth_rad : Tensor (...)
        Viewing direction at the observer [rad] (azimuth from north through east; the
        zenith angle in [-pi, pi], a negative one the ray mirrored through the zenith).
    sun_zenith_rad, sun_azimuth_rad : Tensor (...)
        Direction of the Sun [rad]; zenith angles beyond 90° (twilight) are allowed.
    altitude_m : Tensor (...)
        Observer altitude [m], between the ground and the top of the atmosphere.
    n_samples : int
        Samples along the view ray (quadratically spaced from the observer), >= 2.
    table : TransmittanceTable, optional
        Look up the Sun's transmittance instead of integrating it (faster). It must have
        been built for ``atmosphere`` and ``wavelength_nm`` (ValueError naming ``table``
        otherwise, see :meth:`TransmittanceTable.check_compatible`).
    sun_steps : int, optional
        Gauss–Legendre nodes per piece for the Sun's transmittance.

    Returns
    -------
    Tensor (..., wavelength)
        :math:`L/E_\odot` [sr^-1]; ``...`` broadcasts the angles, the altitude and the
        parameters' batch shape (ValueError naming the shapes otherwise).

    Notes
    -----
    .. math::

        \frac{L}{E_\odot} = \int_0^{L} \sum_{i} \beta_i(h(s))\,P_i(\cos\theta)\,
        T(0 \to s)\,T_\odot(s)\,ds,\qquad \cos\theta = \hat v\cdot\hat s,

    over Rayleigh and aerosol scattering (ref. 4, eq. 1 without multiple scattering),
    with the view ray ending at the top of the atmosphere or the ground,
    :math:`T(0 \to s)` integrated along the view ray (trapezoid on the samples) and
    :math:`T_\odot(s) = 0` where the ray to the Sun meets the planet (its shadow).
    """
    check_atmosphere("atmosphere", atmosphere)
    n_samples = check_int("n_samples", n_samples, 2)
    if sun_steps is not None:
        sun_steps = check_int("sun_steps", sun_steps, 1)
    dtype = common_dtype(wavelength_nm, view_zenith_rad, view_azimuth_rad, sun_zenith_rad,
                         sun_azimuth_rad, altitude_m)
    wavelength = wavelength_tensor(wavelength_nm, dtype)
    # zenith angles in [-pi, pi] (a negative one is the ray mirrored through the zenith)
    view_zenith = check_zenith(view_zenith_rad, name="view_zenith_rad", dtype=dtype)
    view_azimuth = check_finite("view_azimuth_rad", view_azimuth_rad, dtype=dtype)
    sun_zenith = check_zenith(sun_zenith_rad, name="sun_zenith_rad", dtype=dtype)
    sun_azimuth = check_finite("sun_azimuth_rad", sun_azimuth_rad, dtype=dtype)
    altitude = altitude_tensor(altitude_m, dtype)
    if bool((altitude > atmosphere.top_altitude_m).any()):
        raise ValueError("altitude_m must be inside the atmosphere (<= "
                         f"{atmosphere.top_altitude_m} m) for sky radiance; got "
                         f"{float(altitude.max())} m")
    atmosphere.check_geometry(view_zenith_rad=view_zenith, view_azimuth_rad=view_azimuth,
                              sun_zenith_rad=sun_zenith, sun_azimuth_rad=sun_azimuth,
                              altitude_m=altitude)
    if table is not None:
        from skytorch.atmosphere.tables import TransmittanceTable

        if not isinstance(table, TransmittanceTable):
            raise TypeError("table must be a skytorch.atmosphere.tables.TransmittanceTable; "
                            f"got {type(table).__name__}")
        table.check_compatible(atmosphere, wavelength)
    return constituent_radiance(atmosphere.constituents(wavelength), view_zenith,
                                view_azimuth, sun_zenith, sun_azimuth, altitude,
                                n_samples=n_samples, table=table, sun_steps=sun_steps)


def cumulative_columns(densities, step):
    """Trapezoid columns (..., n) [m] of each density from the first sample to each sample.

    ``densities`` maps species to (..., n) samples, ``step`` (..., n - 1) the distances
    between consecutive samples [m].
    """
    columns = {}
    for name, density in densities.items():
        increments = 0.5 * step * (density[..., 1:] + density[..., :-1])
        columns[name] = torch.cat([torch.zeros_like(increments[..., :1]),
                                   torch.cumsum(increments, dim=-1)], dim=-1)
    return columns


def constituent_radiance(constituents, view_zenith, view_azimuth, sun_zenith, sun_azimuth,
                         altitude, *, n_samples: int = 128, table=None,
                         sun_steps: int | None = None, source_weight=None) -> torch.Tensor:
    r"""Single-scattering radiance :math:`L/E_\odot` (..., wavelength) [sr^-1] of constituents.

    Of :class:`~skytorch.atmosphere.constituents.Constituents` (checked inputs).

    The kernel behind :func:`single_scattering_radiance`: every species that scatters
    contributes its scattering coefficient and phase function; the view-path optical
    depth comes from cumulative per-species path columns along the samples and the Sun's
    from straight-ray columns (or ``table``), both through
    :meth:`~skytorch.atmosphere.constituents.Constituents.optical_depth`.

    ``source_weight``, when given, is a callable taking the sample points (..., n, 3) [m]
    from the observer in its (north, east, up) frame and returning a weight (..., n) on
    the source term there (the Sun's visible fraction during a solar eclipse:
    :func:`skytorch.scene.solar_eclipse_sky.eclipsed_single_scattering`).
    """
    dtype = constituents.dtype
    planet = constituents.planet_radius_m
    top = constituents.top_radius_m
    view = _direction(view_zenith, view_azimuth)
    sun = _direction(sun_zenith, sun_azimuth)
    cos_theta = torch.clamp((view * sun).sum(-1), -1.0, 1.0)
    r0 = planet + altitude
    mu_v = view[..., 2]
    hits = _ray_hits_ground(r0, mu_v, planet)
    length = torch.where(hits, _distance_to_ground(r0, mu_v, planet),
                         _distance_to_top(r0, mu_v, top))
    fraction = torch.linspace(0.0, 1.0, n_samples, dtype=dtype) ** 2
    s = length[..., None] * fraction  # (..., n)
    # sample positions relative to the planet centre: observer at (0, 0, r0)
    r0_ = r0[..., None]
    r_sq = r0_ * r0_ + s * s + 2.0 * r0_ * s * mu_v[..., None]
    r = torch.sqrt(r_sq)
    # (rounding can put the last sample a hair outside the shell)
    height = torch.clamp(((r_sq - planet ** 2) / (r + planet)), 0.0,
                         constituents.top_altitude_m)
    # cosine of the Sun's zenith angle at each sample: (p . sun) / r
    p_dot_sun = r0_ * sun[..., 2:3] + s * cos_theta[..., None]
    mu_sun = torch.clamp(p_dot_sun / r, -1.0, 1.0)
    # the samples are one geometry dim after the parameters' batch dims: passed as
    # ``extra=1`` (explicit, so that the atmosphere can be shared by threads)
    densities = constituents.densities(height)  # (..., n): the samples are the sample dim
    # transmittance towards the Sun from each sample (zero in the planet's shadow)
    if table is not None:
        tau_sun = table.lookup(torch.acos(mu_sun), height)
    else:
        columns = constituents.column_integrals(planet + height, mu_sun, n_steps=sun_steps,
                                                extra=1)
        tau_sun = constituents.optical_depth(columns, extra=1)
    # view path: cumulative trapezoid columns of every species along the samples
    step = s[..., 1:] - s[..., :-1]
    tau_view = constituents.optical_depth(cumulative_columns(densities, step), extra=1)
    shadow = _ray_hits_ground(r, mu_sun, planet)[..., None]
    sun_transmittance = torch.where(shadow, torch.zeros_like(tau_sun), torch.exp(-tau_sun))
    source = None
    for species in constituents.scatterers():
        if species.vanishes:
            continue
        # (..., n, wavelength): density times the reference scattering coefficient times
        # the phase function at the (per view ray) scattering angle
        term = (densities[species.name][..., None]
                * insert_dims(species.scattering, 1, 1)
                * species.phase(cos_theta)[..., None, :])
        source = term if source is None else source + term
    if source is None:
        source = torch.zeros_like(tau_view)
    if source_weight is not None:
        points = s[..., None] * view[..., None, :]  # (..., n, 3) from the observer
        source = source * source_weight(points)[..., None]
    step = step[..., None]
    integrand = source * torch.exp(-tau_view) * sun_transmittance
    return (0.5 * step * (integrand[..., 1:, :] + integrand[..., :-1, :])).sum(-2)


#: the samples along a line of sight of :func:`second_order_radiance` crowd towards the
#: observer as the cube of a uniform parameter (the aerosols' 1.2 km scale height)
SECOND_ORDER_SPACING_POWER = 3


def _rotation_to(up: torch.Tensor) -> torch.Tensor:
    r"""Rotations (..., 3, 3) taking the observer's frame to the local frames of points.

    ``up`` (..., 3) is the local vertical of each point in the observer's (north, east,
    up) frame; the rotation turns it into (0, 0, 1) about the axis :math:`\hat z \times
    \hat u` (Rodrigues), so that local north stays in the plane of the observer's north
    and the vertical. ``x_local = M @ x``.
    """
    n, e, u = up.unbind(-1)
    # rotating u to z: axis (e, -n, 0) / sin, angle acos(u); with c = u the matrix is
    # I + [k]x sin + [k]x^2 (1 - c), written out (k = (e, -n, 0)/s, s^2 = n^2 + e^2)
    factor = 1.0 / (1.0 + u)  # (1 - c)/s^2
    rows = [torch.stack([1.0 - n * n * factor, -n * e * factor, -n], -1),
            torch.stack([-n * e * factor, 1.0 - e * e * factor, -e], -1),
            torch.stack([n, e, u], -1)]
    return torch.stack(rows, -2)


def _line_of_sight_spacing(n_view: int, r0, mu, length, ends_on_ground) -> torch.Tensor:
    """Distances (..., n_view) [m] of the samples along lines of sight.

    The samples crowd as the cube of a uniform parameter
    (:data:`SECOND_ORDER_SPACING_POWER`) towards the lowest point of the line, where the
    air and the aerosol are densest: the observer for lines going up, the point of closest
    approach to the ground for lines that pass it (the limb seen from above; the samples
    on either side in proportion to its length), and for lines that end on the ground
    both ends (the two halves mirrored).
    """
    u = torch.linspace(0.0, 1.0, n_view, dtype=length.dtype)
    power = SECOND_ORDER_SPACING_POWER
    half = 0.5 * (2.0 * torch.minimum(u, 1.0 - u)) ** power
    both_ends = torch.where(u <= 0.5, half, 1.0 - half)
    # fraction of the line at its lowest point (0 for lines going up)
    lowest = torch.clamp(-r0 * mu / length, 0.0, 1.0)[..., None]
    tiny = torch.finfo(length.dtype).tiny
    before = lowest * (1.0 - torch.clamp(1.0 - u / lowest.clamp(min=tiny), min=0.0) ** power)
    after = (1.0 - lowest) * torch.clamp((u - lowest) / (1.0 - lowest).clamp(min=tiny),
                                         min=0.0) ** power
    around_lowest = torch.where(u < lowest, before, lowest + after)
    fraction = torch.where(ends_on_ground[..., None], both_ends, around_lowest)
    return length[..., None] * fraction


class GatheredLineOfSight(NamedTuple):
    """Result of :func:`gather_on_line_of_sight`.

    Attributes
    ----------
    radiance : Tensor (..., wavelength)
        The scattered source integrated along the line of sight [sr^-1 per unit source].
    transmittance : Tensor (..., wavelength)
        Transmittance from the observer to the end of the line of sight [1].
    ends_on_ground : Tensor (...)
        Whether the line of sight ends on the ground.
    end_sun_zenith : Tensor (...)
        The Sun's zenith angle at the end of the line of sight [rad].
    """

    radiance: torch.Tensor
    transmittance: torch.Tensor
    ends_on_ground: torch.Tensor
    end_sun_zenith: torch.Tensor


def gather_on_line_of_sight(constituents, view_zenith, view_azimuth, sun_zenith,
                            sun_azimuth, altitude, incoming, *, n_view: int, n_mu: int,
                            n_phi: int) -> GatheredLineOfSight:
    r"""Scatter a radiance field into a line of sight and integrate it along the line.

    .. math::

        L = \int_0^{L} T(0 \to s) \sum_i \beta_i(h)
            \int_{4\pi} P_i(\hat\omega\cdot\hat v)\,L_{in}(\mathbf p(s), \hat\omega)
            \,d\Omega\,ds

    by the trapezoid rule on ``n_view`` samples spaced as the cube of a uniform parameter
    (:data:`SECOND_ORDER_SPACING_POWER`) towards the lowest point of the line (the
    observer, the point of closest approach, or both ends of a line to the ground) and a
    product quadrature over the sphere at every sample (Gauss-Legendre with ``n_mu`` nodes
    per hemisphere of the local zenith cosine, ``n_phi`` uniform azimuths).

    ``incoming(zenith, azimuth, sun_zenith, sun_azimuth, height, to_observer)`` returns the
    radiance :math:`L_{in}` (..., k, d, wavelength) arriving at the ``k`` samples from the
    ``d`` directions, given in the local frame of each sample (its vertical, its north in
    the plane of the observer's north and that vertical): ``zenith``, ``azimuth`` (d,),
    the Sun's local ``sun_zenith``, ``sun_azimuth`` and ``height`` (..., k, 1) [rad, m];
    ``to_observer`` maps points (..., k, d, n, 3) of the local frames to the observer's
    (north, east, up) frame [m].
    """
    dtype = constituents.dtype
    planet, top = constituents.planet_radius_m, constituents.top_radius_m
    view = _direction(view_zenith, view_azimuth)
    sun = _direction(sun_zenith, sun_azimuth)
    view, sun = torch.broadcast_tensors(view, sun)
    altitude = altitude.expand(view.shape[:-1])
    r0 = planet + altitude
    mu_v = view[..., 2]
    hits = _ray_hits_ground(r0, mu_v, planet)
    length = torch.where(hits, _distance_to_ground(r0, mu_v, planet),
                         _distance_to_top(r0, mu_v, top))
    s = _line_of_sight_spacing(n_view, r0, mu_v, length, hits)  # (..., k)
    points = s[..., None] * view[..., None, :]  # (..., k, 3) from the observer
    centre = points + torch.stack([torch.zeros_like(r0), torch.zeros_like(r0), r0],
                                  -1)[..., None, :]
    radius = torch.linalg.vector_norm(centre, dim=-1)
    height = torch.clamp(radius - planet, 0.0, constituents.top_altitude_m)
    rotation = _rotation_to(centre / radius[..., None])  # (..., k, 3, 3)
    local_sun = (rotation @ sun[..., None, :, None])[..., 0]
    local_view = (rotation @ view[..., None, :, None])[..., 0]
    # the sphere of directions at each sample, in its local frame
    # double Gauss: each hemisphere on its own, nodes crowding towards the horizon, where
    # the radiance of long near-horizontal paths peaks
    x, w = unit_nodes(n_mu, dtype)
    mu, w = torch.cat([-x.flip(0), x]), torch.cat([w.flip(0), w])
    phi = (torch.arange(n_phi, dtype=dtype) + 0.5) * (2.0 * math.pi / n_phi)
    dir_zenith = torch.acos(mu)[:, None].expand(2 * n_mu, n_phi).reshape(-1)
    dir_azimuth = phi[None, :].expand(2 * n_mu, n_phi).reshape(-1)
    dir_weight = w[:, None].expand(2 * n_mu, n_phi).reshape(-1) * (2.0 * math.pi / n_phi)
    directions = _direction(dir_zenith, dir_azimuth)  # (d, 3)
    sun_zenith_local = torch.acos(torch.clamp(local_sun[..., 2], -1.0, 1.0))
    sun_azimuth_local = torch.atan2(local_sun[..., 1], local_sun[..., 0])

    def to_observer(local_points):  # (..., k, d, n, 3) local -> the observer's frame
        back = torch.einsum("...ji,...dnj->...dni", rotation, local_points)
        return back + points[..., None, None, :]

    field = incoming(dir_zenith, dir_azimuth, sun_zenith_local[..., None],
                     sun_azimuth_local[..., None], height[..., None],
                     to_observer)  # (..., k, d, wavelength)
    cosine = torch.clamp(local_view @ directions.T, -1.0, 1.0)  # (..., k, d)
    densities = constituents.densities(height)
    source = None
    for species in constituents.scatterers():
        if species.vanishes:
            continue
        inscattered = ((species.phase(cosine) * field) * dir_weight[:, None]).sum(-2)
        term = densities[species.name][..., None] * species.scattering * inscattered
        source = term if source is None else source + term
    step = s[..., 1:] - s[..., :-1]
    columns = cumulative_columns(densities, step)
    transmittance = torch.exp(-constituents.optical_depth(columns, extra=1))
    if source is None:
        source = torch.zeros_like(transmittance)
    integrand = source * transmittance
    radiance = (0.5 * step[..., None] * (integrand[..., 1:, :] + integrand[..., :-1, :])).sum(-2)
    return GatheredLineOfSight(radiance, transmittance[..., -1, :], hits,
                               sun_zenith_local[..., -1])


def second_order_radiance(constituents, view_zenith, view_azimuth, sun_zenith, sun_azimuth,
                          altitude, *, n_view: int = 24, n_mu: int = 4, n_phi: int = 16,
                          n_samples: int = 16, table=None, source_weight=None
                          ) -> torch.Tensor:
    r"""Second order of scattering :math:`L_2/E_\odot` (..., wavelength) [sr^-1].

    Of :class:`~skytorch.atmosphere.constituents.Constituents` with scalar parameters,
    black ground, straight rays, by direct quadrature:

    .. math::

        L_2 = \int_0^{L} T(0 \to s) \sum_i \beta_i(h)
              \int_{4\pi} P_i(\hat\omega\cdot\hat v)\,L_1(\mathbf p(s), \hat\omega)
              \,d\Omega\,ds,

    with :math:`L_1(\mathbf p, \hat\omega)` the single-scattered radiance reaching the
    point :math:`\mathbf p` of the line of sight from the direction :math:`\hat\omega`
    (:func:`constituent_radiance` with an observer at :math:`\mathbf p`, in the local
    frame of that point: its vertical, the Sun's zenith angle there and the ground and top
    of the atmosphere as seen from it).

    Parameters
    ----------
    constituents : Constituents
        Scalar parameters (no batch dims).
    view_zenith, view_azimuth, sun_zenith, sun_azimuth, altitude : Tensor (...)
        As :func:`constituent_radiance` (azimuths in the observer's frame).
    n_view : int
        Samples along the line of sight (crowding as the cube of a uniform parameter,
        :data:`SECOND_ORDER_SPACING_POWER`, towards the observer, or the line's lowest
        point when it passes one, or both ends of a line to the ground; trapezoid rule),
        >= 2.
    n_mu, n_phi : int
        Gauss–Legendre nodes in the direction cosine per hemisphere (double Gauss) and
        uniform azimuths of the sphere of directions at each sample, >= 1.
    n_samples : int
        Samples along each of those rays (:func:`constituent_radiance`), >= 2.
    table : TransmittanceTable, optional
        The Sun's transmittance (integrated when not given).
    source_weight : callable, optional
        ``source_weight(points)`` with points (..., n, 3) [m] from the observer in its
        frame: a weight on the Sun's source term at every first scattering (the Sun's
        visible fraction during a solar eclipse).

    Returns
    -------
    Tensor (..., wavelength)
        The second order alone; add :func:`constituent_radiance` for orders 1–2.

    Notes
    -----
    Cost: ``n_view · 2 n_mu · n_phi · n_samples`` points per line of sight. Checked against
    a backward Monte-Carlo's second order (``tests/test_ms_montecarlo.py``).
    """
    n_view = check_int("n_view", n_view, 2)
    n_mu = check_int("n_mu", n_mu, 1)
    n_phi = check_int("n_phi", n_phi, 1)
    n_samples = check_int("n_samples", n_samples, 2)
    if len(constituents.batch_shape):
        raise ValueError("second_order_radiance takes an atmosphere with scalar parameters; "
                         f"got batch shape {tuple(constituents.batch_shape)}")

    def first_order(zenith, azimuth, sun_zenith_local, sun_azimuth_local, height, to_observer):
        weight = None
        if source_weight is not None:
            def weight(local_points):  # (..., k, d, n, 3) in the samples' local frames
                return source_weight(to_observer(local_points))
        return constituent_radiance(constituents, zenith, azimuth, sun_zenith_local,
                                    sun_azimuth_local, height, n_samples=n_samples,
                                    table=table, source_weight=weight)

    return gather_on_line_of_sight(constituents, view_zenith, view_azimuth, sun_zenith,
                                   sun_azimuth, altitude, first_order, n_view=n_view,
                                   n_mu=n_mu, n_phi=n_phi).radiance
