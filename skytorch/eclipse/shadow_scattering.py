r"""Sunlight scattered once by the occluder's atmosphere into its shadow.

A point ``P`` in the shadow sees the atmosphere ring around the occluder. Besides the
refracted solar image (:mod:`skytorch.eclipse.shadow`), every volume element of the ring
that the Sun illuminates scatters light towards ``P``. This module adds that single-
scattered component to :class:`~skytorch.eclipse.shadow.Shadow` (``scattering=True``).

Geometry (spherical symmetry)
-----------------------------
Seen from ``P`` (distance ``L`` from the occluder's centre, direction ``c``), a line of
sight at angular radius ``theta`` from ``c`` and ring azimuth ``psi`` (0 towards the Sun)
is a straight line with impact parameter ``b = L sin(theta)``. Points on it are
``S(x) = b e + x v`` with ``v`` the unit vector from ``P`` along the line of sight, ``e``
the unit vector from the centre to the tangent point and ``x`` the distance from the
tangent point (``x > 0`` beyond it, on the Sun's side). For a point-like Sun in the
direction ``s`` (angular distance ``sigma`` from ``c``), the scattering angle is the
angle between ``s`` and ``v`` on P's sky,

.. math::

    \cos\Theta = \cos\theta\cos\sigma + \sin\theta\sin\sigma\cos\psi ,

and the sunlight that reaches ``S`` travels along direction ``-s``. By the rotational
symmetry of the atmosphere, the attenuation of both legs depends on the line of sight only
through ``b`` and on the Sun only through its angle with ``v`` measured in the plane
``(e, v)``,

.. math::

    \varepsilon = \operatorname{atan2}(s\cdot e,\ s\cdot v), \qquad
    s\cdot e = \frac{\cos\theta\cos\Theta - \cos\sigma}{\sin\theta} ,

(``epsilon = -theta`` on the shadow axis). The out-of-plane component of ``s`` is
dropped: it moves the Sun's ray through ``S`` by ``x^2 s_t^2 / 2b``, below 10 m for
the Earth seen from the Moon (``x < 600 km``, ``s_t < 0.02``); near the occluder, where
``theta`` is large, this is the main approximation (measured in the tests against a
brute-force volume integral with exact 3-D rays). The radiance of the line of sight per
unit solar irradiance is then

.. math::

    \frac{L_{sca}}{E_\odot} = \sum_{i\in\{R, a\}} P_i(\Theta)\,K_i(b, \varepsilon),\qquad
    K_i = \int_{-X}^{X} \beta_i(h(x))\,
        e^{-\tau_{view}(b, x) - \tau_\odot(b, \varepsilon, x)}\,dx ,

with ``X = sqrt(r_top^2 - b^2)``, ``beta_i`` the Rayleigh and aerosol scattering
coefficients, ``P_i`` their phase functions, ``tau_view`` the optical depth from ``S``
to ``P`` and ``tau_sun`` from ``S`` towards the Sun (zero transmittance where that ray
meets the ground or a closed cloud deck). Both optical depths are straight-ray path
integrals of the atmosphere
(:meth:`skytorch.atmosphere.Atmosphere.column_integrals`): the sunlight's ray through
``S`` has impact parameter ``b cos(eps) - x sin(eps)`` and the legs are split at ``S``.
Refraction of the two legs is neglected (the bending, at most ~1° for the Earth near
the ground, shifts where the light is scattered, not how much light the limb scatters;
its size is that of the in-plane angle ``epsilon`` itself at the Moon's distance, so the
result is an estimate of tens of per cent in the lowest, opaque layers; the optically
thin layers that dominate the scattered light bend by < 0.05°).

``K_i`` is tabulated once per atmosphere and wavelength set on ``b`` (Gauss–Legendre nodes
in ``s``, ``b = R + beta_min + (h_top - beta_min) s^2``) times ``epsilon`` (uniform in
``asinh(epsilon / epsilon_0)``, dense near 0, covering ``[-pi, pi]``); the path integral
uses Gauss–Legendre nodes in ``t`` with ``x = X sinh(a t) / sinh(a)`` (dense at the
tangent point). The illuminance at ``P`` relative to the unobstructed Sun is

.. math::

    \frac{E_{sca}}{E_\odot} = k^{-2}\int_{b}\int_0^{2\pi}
        \frac{L_{sca}}{E_\odot}\,\frac{b\,db\,d\psi}{L\sqrt{L^2 - b^2}} ,

(``k = D / |S_sun - P|``: the scattering ring is about ``L`` closer to the Sun than
``P``), a Gauss–Legendre sum over the table's ``b`` nodes and over ``psi`` in ``[0, pi]``
(mirror symmetry), with ``K_i`` interpolated linearly in ``asinh(epsilon/epsilon_0)``.
The solar disc is treated as a point at its centre for this component (its angular
radius is small against the ~1° widths of the phase functions and of ``K`` in
``epsilon``).

Closed forms (used in the tests)
--------------------------------
For a point on the axis far behind the occluder (``epsilon -> 0``, ``Theta = theta``)
the two legs of every scattering point add up to the whole chord, so
``K_i = tau_i(b) exp(-tau(b))`` with ``tau_i``, ``tau`` the scattering and total optical
depths of the chord. For an exponential species with ground coefficient ``beta_0`` and
scale height ``H << R``, ``tau(b) = beta_0 sqrt(2 pi b H) exp(-(b - R)/H)`` and
(optically thin)

.. math::

    \frac{E_{sca}}{E_\odot} \approx 2\pi\,\frac{R}{L^2}\,P(\theta_R)\,
        \beta_0 H\sqrt{2\pi R H} ,

while for a single scatterer without absorption, optically thick at the ground,
``int tau e^{-tau} db = H (1 - e^{-tau_0})`` gives ``E_sca / E_sun ~ 2 pi R H P / L^2``.

References
----------
1. García Muñoz, A., Pallé, E. 2011, "Lunar eclipse theory revisited: Scattered sunlight
   in both the quiescent and the volcanically perturbed atmosphere", JQSRT 112, 1609,
   doi:10.1016/j.jqsrt.2011.03.017.
2. Schneegans, S., Gilg, J., Ahlers, V., Zachmann, G., Gerndt, A. 2025, "Physically
   Based Real-Time Rendering of Eclipses", Computer Graphics Forum,
   doi:10.1111/cgf.70220.
3. Chandrasekhar, S. 1950, *Radiative Transfer*, Oxford (single scattering,
   Rayleigh phase function).

Examples
--------
>>> import torch
>>> from skytorch.eclipse.shadow import Shadow
>>> shadow = Shadow.earth(n_altitude=101, scattering=True)
>>> i = shadow.relative_illuminance(3.844e8, torch.tensor([0.0]), [680.0, 440.0])
>>> bool((i > 0).all())
True
"""

from __future__ import annotations

import logging
import math
import threading

import torch

from skytorch._validate import check_int, check_positive
from skytorch.eclipse.occlusion import _nodes as _unit_gauss

__all__ = [
    "DEFAULT_SCATTERING_RESOLUTION",
    "ScatteringProfile",
    "scattered_illuminance",
    "scattered_radiance",
    "scattering_kernel",
    "scattering_species",
    "species_phase",
]

logger = logging.getLogger(__name__)

#: default resolution factor of the scattered component (node counts below times it)
DEFAULT_SCATTERING_RESOLUTION = 1.0
#: base node counts: impact parameter, in-plane Sun angle, path, ring azimuth
_BASE_NODES = {"n_impact": 32, "n_path": 48, "n_azimuth": 12}
#: spacing of the epsilon grid at resolution 1 [rad]
_ANGLE_STEP_RAD = 0.002
#: epsilon nodes per lazily computed block
_BLOCK = 16
#: stretch of the path nodes x = X sinh(a t) / sinh(a)
_PATH_STRETCH = 3.0
#: points per chunk in the illuminance sum (bounds the temporaries)
_CHUNK = 2048
#: kernel values gathered at once for species with per-member or per-wavelength phase
#: functions (bounds the temporaries: 32 MiB in float64)
_GATHER_ELEMENTS = 1 << 22
#: rays per chunk in the kernel precomputation
_RAY_CHUNK = 65536


def _gauss(n: int, dtype=torch.float64):
    """Gauss–Legendre nodes and weights on [0, 1]."""
    x, w = _unit_gauss(n)
    return torch.as_tensor(x, dtype=dtype), torch.as_tensor(w, dtype=dtype)


def _members(value: torch.Tensor, batch_shape: tuple[int, ...], leading: int) -> torch.Tensor:
    """``(*lead, *B?)`` -> ``(*lead, n_batch)`` (expanding unbatched values)."""
    lead = value.shape[:leading]
    return value.expand(*lead, *batch_shape).reshape(*lead, -1)


def _optical_depth(constituents, columns: dict, batch: tuple[int, ...]) -> torch.Tensor:
    """Optical depth (*lead, n_batch, n_wl) of path columns (*lead, n_batch) of every species.

    :meth:`~skytorch.atmosphere.constituents.Constituents.optical_depth`, with the members moved to
    the constituents' leading batch dims and back.
    """
    lead = next(iter(columns.values())).shape[:-1]
    order = (len(lead), *range(len(lead)))
    aligned = {name: value.permute(order).reshape(*batch, *lead)
               for name, value in columns.items()}
    tau = constituents.optical_depth(aligned, extra=len(lead))
    tau = tau.expand(*batch, *lead, tau.shape[-1]).reshape(-1, *lead, tau.shape[-1])
    return tau.permute(*range(1, len(lead) + 1), 0, len(lead) + 1)


def scattering_species(constituents) -> tuple[str, ...]:
    """Names of the species that scatter light into the shadow (exactly absent ones left out).

    Parameters
    ----------
    constituents : Constituents
        :meth:`skytorch.atmosphere.Atmosphere.constituents` at the kernel's wavelengths.

    Returns
    -------
    tuple of str
        In the atmosphere's order (e.g. ``("rayleigh", "aerosol", "stratospheric_aerosol")``).
    """
    return tuple(sp.name for sp in constituents.scatterers() if not sp.vanishes)


def species_phase(species, cos_theta: torch.Tensor, batch: tuple[int, ...]) -> torch.Tensor:
    """Phase function of one species at scattering angles of every member [1/sr].

    Parameters
    ----------
    species : Species
        A scattering species of the constituents (its ``phase`` handle).
    cos_theta : Tensor (...)
        Cosine of the scattering angle [1].
    batch : tuple of int
        Batch shape ``B`` of the atmosphere.

    Returns
    -------
    Tensor (..., n_batch or 1, n_wavelength or 1)
        Size 1 along the members (wavelengths) where the phase function does not depend on
        them, in the dtype of ``cos_theta``.
    """
    lead = cos_theta.shape
    value = species.phase(cos_theta.reshape(*(1,) * len(batch), *lead), extra=len(lead))
    members = value.shape[:len(batch)]
    value = value.reshape(*members, *lead, value.shape[-1])
    if math.prod(members) > 1:
        value = value.expand(*batch, *lead, value.shape[-1])
    value = value.reshape(-1, *lead, value.shape[-1]).movedim(0, -2)
    return value.to(cos_theta.dtype)


def scattering_kernel(atmosphere, wavelength_nm, impact_radius_m, angle_rad, *,
                      n_path: int = _BASE_NODES["n_path"], blocking_radius_m=None
                      ) -> dict[str, torch.Tensor]:
    r"""Single-scattering path integrals ``K_i(b, epsilon)`` of lines of sight.

    Parameters
    ----------
    atmosphere : Atmosphere
        The occluder's atmosphere (batch shape ``B``; its members may differ in any
        parameter).
    wavelength_nm : Tensor (n_wavelength,)
        Wavelengths [nm].
    impact_radius_m : Tensor (n_impact,)
        Impact parameters ``b`` of the lines of sight, from the centre [m], between the
        planet radius and the top of the atmosphere.
    angle_rad : Tensor (n_angle,)
        In-plane angle ``epsilon`` between the direction towards the Sun and the line of
        sight (module docstring) [rad].
    n_path : int
        Gauss–Legendre nodes along the chord.
    blocking_radius_m : float, optional
        Sun rays passing below this radius are blocked [m] (default the planet radius;
        a closed cloud deck raises it).

    Returns
    -------
    dict of Tensor (n_impact, n_angle, n_batch, n_wavelength)
        One entry per scattering species of the atmosphere
        (:func:`scattering_species`: ``"rayleigh"``, ``"aerosol"``,
        ``"stratospheric_aerosol"`` where present):
        :math:`K_i = \int \beta_i\,e^{-\tau}\,dx` [1] (radiance per unit solar irradiance
        and unit phase function), float64.
    """
    n_path = check_int("n_path", n_path, low=4)
    wavelength = check_positive("wavelength_nm", wavelength_nm, unit=" nm",
                                dtype=torch.float64).reshape(-1)
    b = torch.as_tensor(impact_radius_m, dtype=torch.float64).reshape(-1)
    eps = torch.as_tensor(angle_rad, dtype=torch.float64).reshape(-1)
    planet, top = atmosphere.planet_radius_m, atmosphere.top_radius_m
    blocking = planet if blocking_radius_m is None else float(blocking_radius_m)
    batch = tuple(getattr(atmosphere, "batch_shape", ()))
    ones = (1,) * len(batch)
    t, wt = _gauss(n_path)
    t, wt = 2.0 * t - 1.0, 2.0 * wt
    a = _PATH_STRETCH
    half = torch.sqrt(torch.clamp(top * top - b * b, min=0.0))[:, None]  # (n_b, 1)
    x = half * torch.sinh(a * t) / math.sinh(a)  # (n_b, n_x)
    dx = half * a * torch.cosh(a * t) / math.sinh(a) * wt
    radius = torch.sqrt(b[:, None] ** 2 + x * x)
    altitude = torch.clamp(radius - planet, min=0.0)
    n_wl = wavelength.shape[0]
    # every species' optical depth from its path columns (nonlinear laws included)
    constituents = atmosphere.constituents(wavelength)
    # reference-level scattering coefficients per member and wavelength (n_batch, n_wl)
    # [1/m] (the species' own albedo, wavelength-dependent for Mie aerosol types)
    names = scattering_species(constituents)
    k = {s: constituents[s].scattering.expand(*batch, n_wl).reshape(-1, n_wl) for s in names}
    with torch.no_grad():
        # view leg from S towards P (direction -v): independent of epsilon
        mu_view = torch.clamp(-x / radius, -1.0, 1.0)
        view = atmosphere.column_integrals(torch.acos(mu_view).reshape(*x.shape, *ones),
                                           altitude.reshape(*x.shape, *ones))
        view = {s: _members(c, batch, 2) for s, c in view.items()}  # (n_b, n_x, n_batch)
        density = {s: _members(atmosphere.relative_density(s, altitude.reshape(*x.shape, *ones)),
                               batch, 2) for s in names}
        n_batch = max(math.prod(batch), 1)
        out = {s: torch.zeros(b.shape[0], eps.shape[0], n_batch, n_wl, dtype=torch.float64)
               for s in names}
        per_angle = max(1, _RAY_CHUNK // max(x.numel(), 1))
        for start in range(0, eps.shape[0], per_angle):
            e = eps[start:start + per_angle][None, :, None]  # (1, n_e, 1)
            xs, rs = x[:, None, :], radius[:, None, :]
            mu_sun = torch.clamp((b[:, None, None] * torch.sin(e) + xs * torch.cos(e)) / rs,
                                 -1.0, 1.0)  # (n_b, n_e, n_x)
            periapsis = rs * torch.sqrt(torch.clamp(1.0 - mu_sun * mu_sun, min=0.0))
            blocked = (mu_sun < 0.0) & (periapsis < blocking)
            shape = mu_sun.shape
            # sun legs only where the Sun is not hidden by the planet (its shadow)
            lit = torch.nonzero(~blocked.reshape(-1)).squeeze(-1)
            if lit.numel() == 0:  # (keep one ray: empty tensors through the quadrature)
                lit = torch.zeros(1, dtype=torch.long)
            columns = atmosphere.column_integrals(
                torch.acos(mu_sun.reshape(-1)[lit]).reshape(-1, *ones),
                altitude[:, None, :].expand(shape).reshape(-1)[lit].reshape(-1, *ones))
            sun = {}
            for name, value in columns.items():
                value = _members(value, batch, 1)  # (n_lit, nb)
                full = value.new_zeros((math.prod(shape), value.shape[-1]))
                sun[name] = full.index_copy(0, lit, value).reshape(*shape, -1)
            tau = _optical_depth(constituents, {s: view[s][:, None] + sun[s] for s in sun},
                                 batch)  # (n_b, n_e, n_x, nb, n_wl)
            transmittance = torch.where(blocked[..., None, None], 0.0, torch.exp(-tau))
            for s in names:
                beta = density[s][..., None] * k[s]  # (n_b, n_x, nb, n_wl)
                weight = (beta * dx[..., None, None])[:, None]  # (n_b, 1, n_x, nb, n_wl)
                out[s][:, start:start + per_angle] = (weight * transmittance).sum(2)
    return out


def _species_breakpoints(constituents, names) -> torch.Tensor:
    """Altitudes [m] where the density of a scattering layer changes character.

    The breakpoints of the species ``names`` whose profile is a layer above the ground
    (``Profile.aloft``: the stratospheric aerosol's Gaussian, its levels at multiples of
    the width), all members together; the molecular and tropospheric profiles, smooth
    and decreasing from the ground, are resolved by the base nodes.
    """
    levels = [constituents[name].profile.breakpoints_m for name in names
              if constituents[name].profile.aloft]
    levels = [x.detach().reshape(-1).to(torch.float64) for x in levels if x is not None]
    if not levels:
        return torch.zeros(0, dtype=torch.float64)
    return torch.unique(torch.cat(levels))


def impact_nodes(low_radius_m: float, top_radius_m: float, breakpoints_radius_m,
                 n_impact: int) -> tuple[torch.Tensor, torch.Tensor]:
    r"""Gauss–Legendre nodes of the impact parameter, in panels split at breakpoints.

    Nodes are placed in ``s`` with ``b = b_low + (r_top - b_low) s^2`` (dense near the
    ground, where the density falls fastest); the breakpoints strictly between
    ``b_low`` and ``r_top`` split ``s`` into panels, each with
    ``max(3, round(n_impact * panel length))`` nodes, so a thin layer (a stratospheric
    aerosol layer a few km wide) is resolved by its own panels. Breakpoints closer than
    ``1 / n_impact`` in ``s`` to the previous kept one (or to the top) are dropped, which
    bounds the panels at ``n_impact`` when many members' layers differ.

    Parameters
    ----------
    low_radius_m, top_radius_m : float
        Lowest and highest impact parameter [m].
    breakpoints_radius_m : Tensor (n,)
        Radii where the integrand changes character [m] (any order; outside values are
        ignored).
    n_impact : int
        Nodes of a single panel covering the whole range.

    Returns
    -------
    tuple of Tensor (n_nodes,)
        Impact parameters [m] and their weights [m] (the weights sum to
        ``r_top - b_low``).
    """
    span = top_radius_m - low_radius_m
    inner = torch.as_tensor(breakpoints_radius_m, dtype=torch.float64).reshape(-1)
    inner = inner[(inner > low_radius_m) & (inner < top_radius_m)]
    kept = [0.0]
    for edge in torch.sqrt((torch.sort(inner).values - low_radius_m) / span).tolist():
        # panels narrower than a base node spacing merge (many members' layers)
        if edge - kept[-1] >= 1.0 / n_impact and 1.0 - edge >= 1.0 / n_impact:
            kept.append(edge)
    edges = torch.tensor([*kept, 1.0], dtype=torch.float64)
    nodes, weights = [], []
    for start, end in zip(edges[:-1].tolist(), edges[1:].tolist(), strict=True):
        n = n_impact if edges.shape[0] == 2 else max(3, round(n_impact * (end - start)))
        x, w = _gauss(n)
        nodes.append(start + (end - start) * x)
        weights.append((end - start) * w)
    s, ws = torch.cat(nodes), torch.cat(weights)
    return low_radius_m + span * s * s, 2.0 * span * s * ws


def _lines_of_sight(impact_radius_m, low_radius_m: float, top_radius_m: float) -> torch.Tensor:
    """Check given impact parameters [m] (1-D, in the ring); return them as float64."""
    b = torch.as_tensor(impact_radius_m, dtype=torch.float64)
    if b.ndim != 1 or b.numel() == 0:
        raise ValueError(f"impact_radius_m must have shape (n_impact,); got shape "
                         f"{tuple(b.shape)}")
    outside = (b < low_radius_m) | (b > top_radius_m)
    if bool(outside.any()):
        raise ValueError(f"impact_radius_m must lie in [{low_radius_m:.6g}, "
                         f"{top_radius_m:.6g}] m (the occluder's surface and the top of "
                         f"the atmosphere); got {float(b[outside][0]):.6g} m")
    return b


class ScatteringProfile:
    """Tabulated single-scattering kernel of an atmosphere ring (see module docstring).

    The in-plane angle grid is uniform, ``epsilon_k = -pi + k delta`` (``delta`` about
    ``0.002 rad / resolution``: the Sun's ray through a scattering point at distance
    ``x`` from the tangent point moves by ``x delta``, ~2 km for the Earth, against
    scale heights of 8 km), and is computed lazily in blocks of nodes: only the angles
    that the evaluated points need are integrated (about 30 nodes for the Earth seen from
    the Moon, 400 for Mars seen from Phobos, all of them for a shadow table reaching down
    to the occluder).

    Parameters
    ----------
    atmosphere : Atmosphere
        The occluder's atmosphere.
    wavelength_nm : Tensor (n_wavelength,)
        Wavelengths [nm].
    lowest_altitude_m : float
        Lowest tangent altitude of the lines of sight (a closed cloud deck) [m].
    ray_weight : callable, optional
        Weight of a line of sight by its tangent altitude [m] (terrain, partial clouds).
    resolution : float
        Factor on the node counts.
    blocking_radius_m : float, optional
        Sun rays passing below this radius are blocked [m].
    impact_radius_m : Tensor (n_impact,), optional
        Lines of sight to tabulate instead of the quadrature nodes (an image of the
        ring, :func:`scattered_radiance`) [m], between the occluder's radius and the top
        of the atmosphere; those below ``lowest_altitude_m`` get weight 0.

    Attributes
    ----------
    impact_radius_m : Tensor (n_impact,)
        Gauss nodes of the impact parameter ``b`` [m].
    impact_weight_m : Tensor (n_impact,)
        Quadrature weights in ``b`` [m] (times the ray weight of terrain and clouds); for
        given lines of sight (``impact_radius_m``) the ray weight alone [1].
    is_quadrature : bool
        The impact nodes are a quadrature over the ring (``impact_radius_m`` not given).
    angle_step_rad : float
        Spacing ``delta`` of the ``epsilon`` grid [rad].
    species : tuple of str
        The scattering species (:func:`scattering_species`), in the kernel's order.
    constituents : Constituents
        The atmosphere's constituents at ``wavelength_nm`` (float64; their phase
        functions weight the kernel).
    kernel : Tensor (n_species, n_impact, n_angle, n_batch * n_wavelength)
        ``K`` of each species (zero in blocks not yet computed).
    n_batch, n_wavelength, n_azimuth, n_angle : int
    """

    def __init__(self, atmosphere, wavelength_nm, *, lowest_altitude_m: float = 0.0,
                 ray_weight=None, resolution: float = DEFAULT_SCATTERING_RESOLUTION,
                 blocking_radius_m=None, impact_radius_m=None):
        resolution = float(check_positive("scattering_resolution", resolution))
        nodes = {key: max(4, int(round(value * resolution)))
                 for key, value in _BASE_NODES.items()}
        self.nodes = nodes
        planet, top = atmosphere.planet_radius_m, atmosphere.top_radius_m
        low = planet + float(lowest_altitude_m)
        self.atmosphere = atmosphere
        self.wavelength_nm = check_positive("wavelength_nm", wavelength_nm, unit=" nm",
                                            dtype=torch.float64).reshape(-1)
        with torch.no_grad():
            self.constituents = atmosphere.constituents(self.wavelength_nm)
        self.species = scattering_species(self.constituents)
        if impact_radius_m is None:
            edges = _species_breakpoints(self.constituents, self.species)
            self.impact_radius_m, weight = impact_nodes(low, top, planet + edges,
                                                        nodes["n_impact"])
        else:  # given lines of sight (an image of the ring), not a quadrature; those
            # below the lowest altitude (a closed cloud deck) are blocked
            self.impact_radius_m = _lines_of_sight(impact_radius_m, planet, top)
            weight = (self.impact_radius_m >= low).to(torch.float64)
        if ray_weight is not None:
            weight = weight * ray_weight(self.impact_radius_m - planet)
        self.impact_weight_m = weight
        intervals = _BLOCK * math.ceil(2.0 * math.pi / (_ANGLE_STEP_RAD / resolution) / _BLOCK)
        self.n_angle = intervals + 1
        self.angle_step_rad = 2.0 * math.pi / intervals
        self.blocking_radius_m = blocking_radius_m
        self.batch_shape = tuple(getattr(atmosphere, "batch_shape", ()))
        self.n_batch = max(math.prod(self.batch_shape), 1)
        self.n_wavelength = int(self.wavelength_nm.shape[0])
        self.n_azimuth = nodes["n_azimuth"]
        self.planet_radius_m = planet
        n_b = self.impact_radius_m.shape[0]
        self.kernel = torch.zeros(len(self.species), n_b, self.n_angle,
                                  self.n_batch * self.n_wavelength, dtype=torch.float64)
        self._done = torch.zeros(intervals // _BLOCK, dtype=torch.bool)
        self._cache: dict = {}
        self._kernels: dict = {}
        self._lock = threading.Lock()
        self.is_quadrature = impact_radius_m is None

    def angles(self, index) -> torch.Tensor:
        """``epsilon`` of grid nodes ``index`` [rad]."""
        return -math.pi + self.angle_step_rad * torch.as_tensor(index, dtype=torch.float64)

    def ensure(self, index: torch.Tensor) -> None:
        """Compute the blocks holding nodes ``index`` and ``index + 1`` (if missing).

        Thread-safe: the blocks are computed under the profile's lock (a profile shared by
        the threads of a sweep computes each block once).
        """
        with self._lock, torch.no_grad():
            if index.numel() == 0:
                return
            first = int(index.min()) // _BLOCK
            last = min((int(index.max()) + 1) // _BLOCK, self._done.shape[0] - 1)
            blocks = torch.arange(first, last + 1)
            blocks = blocks[~self._done[blocks]]
            if blocks.numel() == 0:
                return
            nodes = (blocks[:, None] * _BLOCK + torch.arange(_BLOCK + 1)).reshape(-1)
            nodes = torch.unique(nodes)
            logger.info("single-scattering kernel: %d impact parameters x %d angles x %d "
                        "path nodes", self.impact_radius_m.shape[0], nodes.numel(),
                        self.nodes["n_path"])
            kernel = scattering_kernel(self.atmosphere, self.wavelength_nm,
                                       self.impact_radius_m, self.angles(nodes),
                                       n_path=self.nodes["n_path"],
                                       blocking_radius_m=self.blocking_radius_m)
            for species, name in enumerate(self.species):
                values = kernel[name].reshape(*kernel[name].shape[:2], -1)
                self.kernel[species][:, nodes] = values
            self._done[blocks] = True

    def kernel_matrix(self, dtype: torch.dtype) -> torch.Tensor:
        """Kernel of all species as one (n_species n_impact n_angle, n_batch n_wl) matrix."""
        with self._lock:
            key = (dtype, int(self._done.sum()))
            if key not in self._kernels:
                self._kernels = {key: self.kernel.reshape(-1, self.kernel.shape[-1]).to(dtype)}
            return self._kernels[key]

    def tables(self, dtype: torch.dtype) -> dict[str, torch.Tensor]:
        """Nodes and weights cast to ``dtype`` (cached)."""
        if dtype not in self._cache:
            psi, wpsi = _gauss(self.n_azimuth, dtype)
            self._cache[dtype] = {
                "b": self.impact_radius_m.to(dtype), "wb": self.impact_weight_m.to(dtype),
                "psi": math.pi * psi, "wpsi": 2.0 * math.pi * wpsi,
            }
        return self._cache[dtype]


def _kernel_at(profile, species_kernel, rows, fraction) -> torch.Tensor:
    """One species' kernel rows (...) interpolated in epsilon -> (..., n_batch, n_wl)."""
    w = fraction[..., None]
    value = species_kernel[rows] * (1.0 - w) + species_kernel[rows + 1] * w
    return value.reshape(*rows.shape, profile.n_batch, profile.n_wavelength)


def _ring_geometry(profile, big_l, sg, cos_psi, b):
    """Scattering angle, epsilon node and interpolation weight of ring lines of sight.

    ``big_l``, ``sg`` (p, 1, 1), ``b`` (n_b,), ``cos_psi`` (n_psi,) -> ``sin_t``,
    ``cos_t`` (p, n_b, 1) and ``cos_theta``, ``index``, ``fraction`` (p, n_b, n_psi);
    the kernel blocks of the nodes are computed.
    """
    sin_t = b[:, None] / big_l  # (p, n_b, 1)
    cos_t = torch.sqrt((1.0 - sin_t) * (1.0 + sin_t))
    cos_theta = torch.clamp(cos_t * torch.cos(sg) + sin_t * torch.sin(sg) * cos_psi,
                            -1.0, 1.0)  # (p, n_b, n_psi)
    s_e = (cos_t * cos_theta - torch.cos(sg)) / sin_t
    eps = torch.atan2(s_e, cos_theta)
    f = (eps + math.pi) / profile.angle_step_rad
    i = torch.clamp(torch.floor(f.detach()), 0, profile.n_angle - 2).long()
    profile.ensure(i)
    return sin_t, cos_t, cos_theta, i, f - i.to(f.dtype)


def _ring_sum(profile: ScatteringProfile, cos_theta, index, fraction, weight) -> torch.Tensor:
    """Sum over the ring nodes of ``weight P_s(Theta) K_s(b, epsilon)`` for every species.

    ``cos_theta``, ``index`` (lower ``epsilon`` node), ``fraction`` (linear interpolation
    weight) and ``weight`` are (p, n_impact, n_azimuth); returns (p, n_batch n_wavelength).
    Species whose phase function is the same for every member and wavelength (Rayleigh,
    an unbatched Henyey-Greenstein) share one sparse product; the others (a Mie asymmetry
    per wavelength, batched asymmetries) gather their kernel rows directly.
    """
    n_p, n_b = index.shape[:2]
    n_e = profile.n_angle
    block = n_b * n_e
    kernel = profile.kernel_matrix(cos_theta.dtype)  # (n_species block, n_batch n_wl)
    rows = (torch.arange(n_b) * n_e)[:, None] + index  # row inside a species' block
    total = cos_theta.new_zeros(n_p, kernel.shape[-1])
    shared_rows, shared_values = [], []
    for s, name in enumerate(profile.species):
        phase = species_phase(profile.constituents[name], cos_theta, profile.batch_shape)
        if phase.shape[-2:] == (1, 1):
            value = (weight * phase[..., 0, 0]).reshape(-1)
            lower = rows.reshape(-1) + s * block
            shared_rows += [lower, lower + 1]
            shared_values += [value * (1.0 - fraction).reshape(-1), value * fraction.reshape(-1)]
            continue
        factor = weight[..., None, None] * phase  # (p, n_b, n_psi, n_batch?, n_wl?)
        species_kernel = kernel[s * block:(s + 1) * block]
        step = max(1, _GATHER_ELEMENTS // max(rows[0].numel() * kernel.shape[-1], 1))
        parts = []
        for first in range(0, n_p, step):
            r = rows[first:first + step]
            value = _kernel_at(profile, species_kernel, r, fraction[first:first + step])
            parts.append((value * factor[first:first + step]).sum((1, 2)).reshape(r.shape[0], -1))
        total = total + torch.cat(parts)
    if shared_rows:
        point = torch.arange(n_p)[:, None, None].expand(index.shape).reshape(-1)
        indices = torch.stack([point.repeat(len(shared_rows)), torch.cat(shared_rows)])
        matrix = torch.sparse_coo_tensor(indices, torch.cat(shared_values),
                                         (n_p, kernel.shape[0]), check_invariants=False)
        total = total + torch.sparse.mm(matrix, kernel)
    return total


def scattered_illuminance(profile: ScatteringProfile, centre_distance_m, separation_rad,
                          deviation_scale) -> torch.Tensor:
    r"""Single-scattered illuminance relative to the unobstructed Sun.

    Parameters
    ----------
    profile : ScatteringProfile
        Tabulated kernel.
    centre_distance_m, separation_rad, deviation_scale : Tensor (...)
        ``L`` [m], ``sigma`` [rad] and ``k = D / |S - P|`` [1] (module docstring).

    Returns
    -------
    Tensor (..., n_batch, n_wavelength)
        :math:`E_{sca} / E_\odot` [1].
    """
    centre, sigma, scale = torch.broadcast_tensors(centre_distance_m, separation_rad,
                                                   deviation_scale)
    shape = centre.shape
    dtype = centre.dtype
    tables = profile.tables(dtype)
    b, wb = tables["b"], tables["wb"]
    psi, wpsi = tables["psi"], tables["wpsi"]
    cos_psi = torch.cos(psi)
    flat = [v.reshape(-1) for v in (centre, sigma, scale)]
    if not profile.is_quadrature:
        raise ValueError("this ScatteringProfile holds given lines of sight (impact_radius_m), "
                         "not a quadrature over the ring: use scattered_radiance")
    pieces = []
    for start in range(0, flat[0].shape[0], _CHUNK):
        big_l, sg, k = (v[start:start + _CHUNK, None, None] for v in flat)
        sin_t, cos_t, cos_theta, i, fraction = _ring_geometry(profile, big_l, sg, cos_psi, b)
        solid = sin_t / (big_l * cos_t) * wb[:, None]  # b db / (L sqrt(L^2 - b^2))
        weight = solid * wpsi / (k * k)  # (p, n_b, n_psi)
        pieces.append(_ring_sum(profile, cos_theta, i, fraction, weight))
    result = torch.cat(pieces) if pieces else centre.new_zeros(
        (0, profile.n_batch * profile.n_wavelength))
    return result.reshape(*shape, profile.n_batch, profile.n_wavelength)


def scattered_radiance(profile: ScatteringProfile, centre_distance_m, separation_rad,
                       deviation_scale, azimuth_rad) -> torch.Tensor:
    r"""Single-scattered radiance of the ring's lines of sight, per unit solar irradiance.

    The image of the scattering ring seen from points in the shadow: the lines of sight at
    the profile's impact parameters ``b`` and ring azimuths ``psi``,

    .. math::

        \frac{L_{sca}}{E_\odot} = k^{-2} w(b) \sum_i P_i(\Theta)\,K_i(b, \varepsilon)
        \quad [\mathrm{sr}^{-1}],

    (module docstring; ``w`` the ray weight of terrain and clouds). Its integral over the
    ring's solid angle is :func:`scattered_illuminance`.

    Parameters
    ----------
    profile : ScatteringProfile
        Kernel on the lines of sight (built with ``impact_radius_m``).
    centre_distance_m, separation_rad, deviation_scale : Tensor (...)
        ``L`` [m], ``sigma`` [rad] and ``k`` [1] (module docstring).
    azimuth_rad : Tensor (n_azimuth,)
        Ring azimuths ``psi`` (0 towards the Sun) [rad].

    Returns
    -------
    Tensor (..., n_impact, n_azimuth, n_batch, n_wavelength)
        Radiance over the unobstructed solar irradiance [1/sr].
    """
    centre, sigma, scale = torch.broadcast_tensors(centre_distance_m, separation_rad,
                                                   deviation_scale)
    dtype = centre.dtype
    psi = torch.as_tensor(azimuth_rad, dtype=dtype).reshape(-1)
    b = profile.impact_radius_m.to(dtype)
    if profile.is_quadrature:
        raise ValueError("scattered_radiance needs a ScatteringProfile built on lines of "
                         "sight (impact_radius_m=...); this one is a quadrature over the ring")
    ray_weight = profile.impact_weight_m.to(dtype)
    flat = [v.reshape(-1) for v in (centre, sigma, scale)]
    n_b, n_e = b.shape[0], profile.n_angle
    pieces = []
    for start in range(0, flat[0].shape[0], 1):
        big_l, sg, k = (v[start:start + 1, None, None] for v in flat)
        _, _, cos_theta, i, fraction = _ring_geometry(profile, big_l, sg, torch.cos(psi), b)
        kernel = profile.kernel_matrix(dtype)
        rows = (torch.arange(n_b) * n_e)[:, None] + i
        total = 0.0
        for s, name in enumerate(profile.species):
            phase = species_phase(profile.constituents[name], cos_theta, profile.batch_shape)
            species_kernel = kernel[s * n_b * n_e:(s + 1) * n_b * n_e]
            total = total + phase * _kernel_at(profile, species_kernel, rows, fraction)
        total = total * ray_weight[:, None, None, None]
        pieces.append(total / (k[..., None, None] ** 2))
    result = torch.cat(pieces) if pieces else centre.new_zeros(
        (0, n_b, psi.shape[0], profile.n_batch, profile.n_wavelength))
    return result.reshape(*centre.shape, *result.shape[1:])
