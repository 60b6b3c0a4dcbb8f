r"""Orders of scattering of the skyglow of one ground source, by backward Monte Carlo.

The single-scattering kernel (:func:`skytorch.skyglow.kernel.kernel_radiance`) leaves out
the light scattered more than once. This module measures every order for the kernel's
geometry — a source of unit flux at ground distance ``r`` and altitude ``h_c``, an
observer at altitude ``h_o`` looking in azimuth ``θ`` (from the source) and elevation
``φ`` — with no approximation but statistical noise, in the spherical atmosphere of the
same :class:`~skytorch.skyglow.kernel.Medium` (scattering and extinction tables, phase
functions) and with the same emission function:

* paths start at the observer along the line of sight and go backwards; free paths are
  drawn by delta tracking (Woodcock et al. 1965) against the largest extinction
  coefficient of the medium, so the heterogeneous spherical atmosphere needs no ray
  marching and no optical-depth table;
* at every real collision the source is sampled explicitly (next-event estimation), the
  kernel's integrand divided by the collision density:
  :math:`w\,\sum_s β_s p_s(\cos Θ)/β_{ext}\; I(ψ)\, e^{-τ(S,P)} / (|P-S|^2 + a^2)`, so that
  the first collisions give the kernel itself and the later ones the orders 2, 3, …
  (:math:`τ(S,P)` from the medium's optical-depth table, as in the kernel);
* the weight is multiplied by the single-scattering albedo and the path turns by an angle
  drawn from the phase function of a species chosen in proportion to its scattering
  coefficient; the ground is black (as in the kernel) and paths end there or when they
  leave the top of the atmosphere.

The radiance per order, with its standard error, gives the multiple-scattering factor
``Σ_k L_k / L_1`` by which the single-scattering kernel underestimates the skyglow
(Dobashi et al. 2023 §5.3 rendered theirs with a path tracer). Measurements are in
``docs/skyglow.md``.

References
----------
1. Dobashi, Y., Ishikawa, N. & Iwasaki, K. 2023, "Efficient Visualization of Light
   Pollution for the Night Sky", ACM Trans. Graph. 42, 219, doi:10.1145/3618337.
2. Woodcock, E. R., Murphy, T., Hemmings, P. J. & Longworth, T. C. 1965, "Techniques used
   in the GEM code for Monte Carlo neutronics calculations in reactors and other systems
   of complex geometry", Argonne National Laboratory report ANL-7050, 557.
3. Duff, T., Burgess, J., Christensen, P. et al. 2017, "Building an Orthonormal Basis,
   Revisited", J. Computer Graphics Techniques 6(1), 1.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import torch

from skytorch._validate import (
    as_tensor,
    check_broadcastable,
    check_choice,
    check_int,
    check_positive,
    check_range,
)
from skytorch.skyglow.kernel import Medium, emission_intensity, kernel_radiance

__all__ = ["CONVERGED_ORDERS", "ESTIMATORS", "FACTOR_AZIMUTHS_DEG", "FACTOR_DISTANCES",
           "FACTOR_ELEVATIONS_DEG", "ScatteringOrders", "higher_order_radiance",
           "skyglow_scattering_orders"]

#: how the orders are scored: along each new direction by the kernel, or at each collision
ESTIMATORS = ("line", "collision")

#: nodes of the inverse cumulative distributions of the phase functions (uniform in angle,
#: 0.0225° apart: finer than the forward peak of the aerosols)
_PHASE_NODES = 8001


@dataclass(frozen=True)
class ScatteringOrders:
    """Radiance per order of scattering of lines of sight, with the Monte-Carlo errors.

    Attributes
    ----------
    radiance : Tensor (..., wavelength, order)
        Mean radiance scattered ``k`` times (k = 1, 2, …) towards the observer per unit
        source flux [m^-2 sr^-1].
    standard_error : Tensor (..., wavelength, order)
        Standard error of each mean [m^-2 sr^-1].
    second_order_from_above : Tensor (..., wavelength)
        The part of the second order whose light reaches the first scattering point from
        above that point's horizon [m^-2 sr^-1]: the part that the single-scattering kernel,
        seen from the scattering points, also gives (a check of the paths).
    second_order_from_above_error : Tensor (..., wavelength)
        Its standard error [m^-2 sr^-1].
    truncated_weight : Tensor (..., wavelength)
        Mean weight of the paths still travelling after the last order followed: an upper
        bound on the share of the light of the orders not counted [1].
    n_paths : int
        Paths per line of sight and wavelength.
    """

    radiance: torch.Tensor
    standard_error: torch.Tensor
    second_order_from_above: torch.Tensor
    second_order_from_above_error: torch.Tensor
    truncated_weight: torch.Tensor
    n_paths: int

    @property
    def total(self) -> torch.Tensor:
        """Sum of all orders (..., wavelength) [m^-2 sr^-1]."""
        return self.radiance.sum(-1)

    @property
    def factor(self) -> torch.Tensor:
        """Multiple-scattering factor, all orders over the first (..., wavelength) [1]."""
        return self.total / self.radiance[..., 0]

    @property
    def factor_error(self) -> torch.Tensor:
        """Standard error of :attr:`factor` (..., wavelength) [1], from the orders' errors.

        The orders of one path are correlated; their errors are added linearly, which
        bounds the error of the sum from above.
        """
        first, error = self.radiance[..., 0], self.standard_error
        higher = self.total - first
        return (error[..., 1:].sum(-1) + higher / first * error[..., 0]) / first


def _phase(medium: Medium, species: str, cos_theta: torch.Tensor,
           wavelength_index: torch.Tensor | int) -> torch.Tensor:
    """Phase function [sr^-1] of one species at each point's wavelength (index)."""
    phase = medium.phase_functions[species](cos_theta)
    if phase.shape != cos_theta.shape:  # (..., wavelength) or (..., 1)
        if phase.shape[-1] == 1:
            phase = phase[..., 0]
        elif isinstance(wavelength_index, int):
            phase = phase[..., wavelength_index]
        else:
            phase = phase.gather(-1, wavelength_index[..., None])[..., 0]
    return phase.to(cos_theta.dtype)


def _phase_samplers(medium: Medium, dtype):
    """Scattering-angle nodes (nodes,) and cumulative distributions (species, wl, nodes)."""
    theta = torch.linspace(0.0, math.pi, _PHASE_NODES, dtype=torch.float64)
    rows = []
    for species in medium.species:
        per_wavelength = []
        for index in range(medium.wavelength_nm.numel()):
            phase = _phase(medium, species, torch.cos(theta), index)
            density = 2.0 * math.pi * phase * torch.sin(theta)
            cumulative = torch.cat([torch.zeros(1, dtype=torch.float64), torch.cumsum(
                0.5 * (density[1:] + density[:-1]) * (theta[1] - theta[0]), 0)])
            per_wavelength.append(cumulative / cumulative[-1])
        rows.append(torch.stack(per_wavelength))
    return theta.to(dtype), torch.stack(rows).to(dtype)


def _sample_angle(theta: torch.Tensor, cumulative: torch.Tensor, uniform: torch.Tensor):
    """Angles [rad] distributed as ``cumulative`` on ``theta`` (linear inverse)."""
    index = torch.searchsorted(cumulative, uniform).clamp(1, theta.numel() - 1)
    low, high = cumulative[index - 1], cumulative[index]
    step = (high - low).clamp_min(torch.finfo(high.dtype).tiny)
    fraction = ((uniform - low) / step).clamp(0.0, 1.0)
    return theta[index - 1] + fraction * (theta[index] - theta[index - 1])


def _rotate(direction: torch.Tensor, cos_theta: torch.Tensor, phi: torch.Tensor):
    """Turn ``direction`` (n, 3) by the angle acos(cos_theta), in azimuth ``phi`` around it.

    The frame around each direction is that of Duff et al. 2017 (no branch but the sign).
    """
    sin_theta = torch.sqrt((1.0 - cos_theta * cos_theta).clamp_min(0.0))
    x, y, z = direction.unbind(-1)
    sign = torch.where(z >= 0, torch.ones_like(z), -torch.ones_like(z))
    a = -1.0 / (sign + z)
    b = x * y * a
    first = torch.stack([1.0 + sign * x * x * a, sign * b, -sign * x], -1)
    second = torch.stack([b, sign + y * y * a, -y], -1)
    return (cos_theta[:, None] * direction + (sin_theta * torch.cos(phi))[:, None] * first
            + (sin_theta * torch.sin(phi))[:, None] * second)


class _Tables:
    """The medium's altitude tables at one dtype, read at (wavelength index, altitude)."""

    def __init__(self, medium: Medium, dtype):
        self.step = medium.altitude_step_m
        self.n_altitude = medium.extinction_table.shape[0]
        #: (wavelength, altitude) and (species, wavelength, altitude), flattened per species
        self.extinction = medium.extinction_table.T.to(dtype).contiguous()
        self.scattering = medium.scattering_table.permute(0, 2, 1).to(dtype).contiguous()
        self.majorant = self.extinction.max(-1).values  # (wavelength,)

    def _read(self, table: torch.Tensor, wavelength: torch.Tensor, altitude: torch.Tensor):
        position = (altitude / self.step).clamp(0.0, self.n_altitude - 1)
        index = position.floor().long().clamp(max=self.n_altitude - 2)
        fraction = position - index
        flat = table.reshape(-1)
        base = wavelength * self.n_altitude + index
        return flat[base] * (1.0 - fraction) + flat[base + 1] * fraction

    def extinction_at(self, wavelength, altitude):
        """Extinction coefficient (n,) [1/m]."""
        return self._read(self.extinction, wavelength, altitude)

    def scattering_at(self, wavelength, altitude):
        """Scattering coefficient of each species (species, n) [1/m]."""
        return torch.stack([self._read(table, wavelength, altitude)
                            for table in self.scattering])


def _geometry(medium, azimuth_rad, elevation_rad, distance_m, source_altitude_m,
              observer_altitude_m):
    """Check and broadcast the geometry inputs; return them flattened, and their shape."""
    names = ("azimuth_rad", "elevation_rad", "distance_m", "source_altitude_m",
             "observer_altitude_m")
    values = [as_tensor(name, value, dtype=torch.float64) for name, value in zip(
        names, (azimuth_rad, elevation_rad, distance_m, source_altitude_m,
                observer_altitude_m), strict=True)]
    check_range("azimuth_rad", values[0], unit=" rad")
    check_range("elevation_rad", values[1], -math.pi / 2, math.pi / 2, unit=" rad")
    check_range("distance_m", values[2], 0.0, unit=" m")
    top = medium.top_altitude_m
    check_range("source_altitude_m", values[3], 0.0, top, unit=" m")
    check_range("observer_altitude_m", values[4], 0.0, top, unit=" m")
    shape = check_broadcastable(**dict(zip(names, values, strict=True)))
    return [v.expand(shape).reshape(-1) for v in values], shape


def skyglow_scattering_orders(medium: Medium, azimuth_rad, elevation_rad, distance_m,
                              source_altitude_m=0.0, observer_altitude_m=0.0, *,
                              emission: str = "garstang1986",
                              emission_parameters: Mapping[str, float] | None = None,
                              source_radius_m: float = 10.0, n_paths: int = 100_000,
                              max_orders: int = 30, estimator: str = "line",
                              kernel_steps: int = 8, seed: int = 0,
                              chunk_paths: int = 1_000_000,
                              dtype: torch.dtype = torch.float64) -> ScatteringOrders:
    """Radiance of lines of sight per order of scattering, by backward Monte Carlo.

    Parameters
    ----------
    medium : Medium
        The atmosphere's tables and phase functions (as for the kernel); every wavelength
        of the medium is computed.
    azimuth_rad, elevation_rad : array_like (...)
        Lines of sight: azimuth from the direction of the source (any angle) and elevation
        above the observer's horizon, in [−π/2, π/2] [rad].
    distance_m : array_like (...)
        Ground distance of the source from the observer [m], ≥ 0.
    source_altitude_m, observer_altitude_m : array_like (...)
        Altitudes of the source and the observer [m], within the atmosphere.
    emission, emission_parameters
        Upward emission function of the source
        (:func:`~skytorch.skyglow.kernel.emission_intensity`).
    source_radius_m : float
        Radius ``a`` of the source in ``1/(s^2 + a^2)`` [m], as in the kernel.
    n_paths : int
        Paths per line of sight and wavelength.
    max_orders : int
        Orders followed; :attr:`ScatteringOrders.truncated_weight` bounds the rest.
    estimator : {"line", "collision"}
        ``"line"`` (default): the order k + 1 is scored at the k-th collision as the
        single-scattering kernel along the path's new direction (the first order is the
        kernel itself); ``"collision"``: every order is scored at its own collision by
        next-event estimation, which needs no kernel and is noisier (a point near the
        source gives a rare, large score).
    kernel_steps : int
        ``n_steps`` of the kernel for ``estimator="line"``.
    seed : int
        Seed of the call's own random generator (the result is reproducible).
    chunk_paths : int
        Paths traced at once, at least the ``n_paths`` of one line of sight and wavelength
        (about 200 bytes per path).
    dtype : torch.dtype
        Arithmetic of the paths (float64 default; float32 is faster and enough for
        factors at the percent level).

    Returns
    -------
    ScatteringOrders
        Arrays over the broadcast shape of the geometry inputs, the medium's wavelengths
        and the orders (float64 whatever ``dtype``: the tallies are accumulated in it). The
        orders end at the last one any path scored (so their number depends on the run);
        a line of sight that sees no lit air (e.g. down to the ground next to the
        observer) has a first order of 0 and a factor of NaN.

    Raises
    ------
    ValueError
        For a geometry or option outside its range, or geometry inputs that do not
        broadcast.
    TypeError
        When ``medium`` is not a :class:`~skytorch.skyglow.kernel.Medium` or ``dtype`` not
        a floating dtype.

    Examples
    --------
    >>> from skytorch.atmosphere import Atmosphere
    >>> medium = Medium(Atmosphere.earth(turbidity=2.0), [550.0])
    >>> orders = skyglow_scattering_orders(medium, 0.0, math.pi / 2, 10e3, n_paths=2000)
    >>> tuple(orders.factor.shape), bool(orders.factor > 1.0)
    ((1,), True)
    """
    if not isinstance(medium, Medium):
        raise TypeError(f"medium must be a skytorch.skyglow.kernel.Medium; got "
                        f"{type(medium).__name__}: {medium!r:.60}")
    if dtype not in (torch.float64, torch.float32):
        raise TypeError(f"dtype must be torch.float64 or torch.float32; got {dtype!r:.40}")
    flat, shape = _geometry(medium, azimuth_rad, elevation_rad, distance_m,
                            source_altitude_m, observer_altitude_m)
    a = float(check_positive("source_radius_m", source_radius_m, unit=" m"))
    n_paths = check_int("n_paths", n_paths, 2)
    max_orders = check_int("max_orders", max_orders, 1, 1000)
    chunk_paths = check_int("chunk_paths", chunk_paths, 1)
    kernel_steps = check_int("kernel_steps", kernel_steps, 1, 4096)
    check_choice("estimator", estimator, ESTIMATORS)
    emission_intensity(torch.ones(1), emission, emission_parameters)  # checks the names
    n_wl = medium.wavelength_nm.numel()
    n_cases = flat[0].numel() * n_wl
    generator = torch.Generator().manual_seed(int(seed))
    tables = _Tables(medium, dtype)
    samplers = _phase_samplers(medium, dtype)
    tallies = torch.zeros(5, n_cases, max(max_orders, 2), dtype=torch.float64)
    options = {"emission": emission, "emission_parameters": emission_parameters,
               "source_radius_m": a, "kernel_steps": kernel_steps}
    geometry = [v.to(dtype) for v in flat]
    per_chunk = max(1, chunk_paths // n_paths)
    for first in range(0, n_cases, per_chunk):
        cases = torch.arange(first, min(first + per_chunk, n_cases))
        paths = _Paths(medium, tables, samplers, geometry, cases, n_wl, n_paths, options,
                       generator)
        _trace(paths, estimator, max_orders, tallies[:, first:first + cases.numel()], first)
    n = float(n_paths)
    sums, squares, above, above_squares, alive = tallies
    mean = sums / n
    error = torch.sqrt((squares / n - mean * mean).clamp_min(0.0) / n)
    above_mean = above[:, 1] / n
    above_error = torch.sqrt((above_squares[:, 1] / n - above_mean ** 2).clamp_min(0.0) / n)
    orders = int((sums != 0).any(0).nonzero().max()) + 1 if bool((sums != 0).any()) else 1
    return ScatteringOrders(
        radiance=mean[:, :orders].reshape(*shape, n_wl, orders),
        standard_error=error[:, :orders].reshape(*shape, n_wl, orders),
        second_order_from_above=above_mean.reshape(*shape, n_wl),
        second_order_from_above_error=above_error.reshape(*shape, n_wl),
        truncated_weight=(alive[:, 0] / n).reshape(*shape, n_wl), n_paths=n_paths)


#: share of the paths that turn towards the source at a scattering (``estimator="line"``)
GUIDED_FRACTION = 0.5
#: half-angle of the cone around the source direction that the guided paths sample [rad]
_CONE_HALF_ANGLE = 0.5 * math.pi


class _SourceCone:
    r"""Directions around the source direction, dense near it.

    The angle γ from the axis has the density :math:`\propto γ/(γ^2 + γ_0^2)` on
    [0, γ_max] (uniform in :math:`\ln(γ^2 + γ_0^2)`), the azimuth is uniform: per solid
    angle :math:`f = γ / (2π \sin γ\, Z (γ^2 + γ_0^2))` with
    :math:`Z = \tfrac12 \ln(1 + γ_{max}^2/γ_0^2)`; ``width`` is γ₀, the source radius
    over its distance. The kernel along a line passing the source at angle γ grows as 1/γ,
    so sampling it this way bounds the scores.
    """

    def __init__(self, width: torch.Tensor):
        self.width2 = (width * width).clamp_min(1e-24)
        self.log_range = torch.log1p(_CONE_HALF_ANGLE ** 2 / self.width2)

    def sample(self, axis: torch.Tensor, paths) -> torch.Tensor:
        """Directions (n, 3) around each axis."""
        u = paths._uniform(axis.shape[0])
        gamma = torch.sqrt(self.width2 * torch.expm1(u * self.log_range))
        phi = 2.0 * math.pi * paths._uniform(axis.shape[0])
        return _rotate(axis, torch.cos(gamma), phi)

    def density(self, axis: torch.Tensor, direction: torch.Tensor) -> torch.Tensor:
        """Density per solid angle [sr^-1] of the directions (n, 3)."""
        cosine = (axis * direction).sum(-1).clamp(-1.0, 1.0)
        sine = torch.sqrt((1.0 - cosine * cosine).clamp_min(0.0))
        gamma = torch.atan2(sine, cosine)
        ratio = torch.where(gamma > 1e-6, gamma / sine.clamp_min(torch.finfo(sine.dtype).tiny),
                            torch.ones_like(gamma))
        value = ratio / (math.pi * self.log_range * (gamma * gamma + self.width2))
        return torch.where(gamma <= _CONE_HALF_ANGLE, value, torch.zeros_like(value))


class _Paths:
    """The paths of a chunk of cases (line of sight × wavelength), all at once.

    Frame of each path's case: observer above the origin, planet centre at (0, 0, −R),
    source in azimuth 0 (as in the kernel).
    """

    def __init__(self, medium, tables, samplers, geometry, cases, n_wl, n_paths, options,
                 generator):
        azimuth, elevation, distance, h_c, h_o = geometry
        self.medium, self.tables, self.samplers = medium, tables, samplers
        self.options, self.generator, self.n_wl = options, generator, n_wl
        dtype = self.dtype = azimuth.dtype
        big_r = self.big_r = medium.planet_radius_m
        self.case = cases.repeat_interleave(n_paths)
        line, self.wavelength = self.case // n_wl, self.case % n_wl
        self.h_c = h_c[line]
        n = self.case.numel()
        zero = torch.zeros(n, dtype=dtype)
        self.centre = torch.tensor([0.0, 0.0, -big_r], dtype=dtype)
        alpha = distance[line] / big_r
        self.source_up = torch.stack([torch.sin(alpha), zero, torch.cos(alpha)], -1)
        self.source = torch.stack([(big_r + self.h_c) * torch.sin(alpha), zero,
                                   self.h_c * torch.cos(alpha)
                                   - 2.0 * big_r * torch.sin(0.5 * alpha) ** 2], -1)
        self.point = torch.stack([zero, zero, h_o[line]], -1)
        cos_elevation = torch.cos(elevation[line])
        self.direction = torch.stack([cos_elevation * torch.cos(azimuth[line]),
                                      cos_elevation * torch.sin(azimuth[line]),
                                      torch.sin(elevation[line])], -1)
        self.weight = torch.ones(n, dtype=dtype)
        self.majorant = tables.majorant[self.wavelength]

    def altitude(self, rows):
        """Altitude [m] of the paths' current points."""
        return torch.linalg.vector_norm(self.point[rows] - self.centre, dim=-1) - self.big_r

    def _uniform(self, n):
        return torch.rand(n, generator=self.generator, dtype=self.dtype)

    def track(self) -> torch.Tensor:
        """Move the live paths to their next real collision (delta tracking).

        Paths that reach the ground or leave the atmosphere get weight 0. Returns the
        indices of the paths that collided.
        """
        live = torch.nonzero(self.weight > 0).squeeze(-1)
        collided = []
        while live.numel():
            step = -torch.log1p(-self._uniform(live.numel())) / self.majorant[live]
            self.point[live] += step[:, None] * self.direction[live]
            height = self.altitude(live)
            gone = (height < 0.0) | (height > self.medium.top_altitude_m)
            self.weight[live[gone]] = 0.0
            inside, height = live[~gone], height[~gone]
            accept = (self._uniform(inside.numel()) * self.majorant[inside]
                      < self.tables.extinction_at(self.wavelength[inside], height))
            collided.append(inside[accept])
            live = inside[~accept]
        return torch.cat(collided) if collided else live

    def collision_score(self, rows) -> torch.Tensor:
        r"""Source light scattered at the points towards the previous point, per collision.

        :math:`\sum_s β_s p_s(\cos Θ)/β_{ext}\; I(ψ) e^{-τ(S,P)} / (|P-S|^2 + a^2)`.
        """
        medium, options = self.medium, self.options
        p, w = self.point[rows], self.wavelength[rows]
        to_point = p - self.source[rows]
        length2 = (to_point * to_point).sum(-1)
        e = to_point * torch.rsqrt(length2)[:, None]
        cos_psi = (e * self.source_up[rows]).sum(-1)
        intensity = emission_intensity(cos_psi, options["emission"],
                                       options["emission_parameters"])
        height = self.altitude(rows)
        mu = (e * (p - self.centre)).sum(-1) / (height + self.big_r)
        tau = (medium.optical_depth_from_altitude(self.h_c[rows], cos_psi)
               - medium.optical_depth_from_altitude(height, mu)).gather(
            -1, w[:, None])[:, 0].clamp_min(0.0)
        cos_scatter = -(e * self.direction[rows]).sum(-1)
        beta = self.tables.scattering_at(w, height)
        phased = sum(beta[i] * _phase(medium, species, cos_scatter, w)
                     for i, species in enumerate(medium.species))
        a = options["source_radius_m"]
        return (phased / self.tables.extinction_at(w, height) * intensity * torch.exp(-tau)
                / (length2 + a * a))

    def line_score(self, rows) -> torch.Tensor:
        """Source light scattered once towards the points along their new directions.

        The single-scattering kernel seen from each point (its altitude, ground distance
        and azimuth from the source, the direction's elevation): the expectation of
        :meth:`collision_score` over the next collision, without its variance.
        """
        up = self.point[rows] - self.centre
        height = torch.linalg.vector_norm(up, dim=-1)
        up = up / height[:, None]
        height = (height - self.big_r).clamp(0.0, self.medium.top_altitude_m)
        source_up = self.source_up[rows]
        cosine = (up * source_up).sum(-1)
        towards = source_up - cosine[:, None] * up
        sine = torch.linalg.vector_norm(towards, dim=-1)
        # right above the source any azimuth will do: the kernel does not depend on it
        towards = towards / sine.clamp_min(torch.finfo(sine.dtype).tiny)[:, None]
        across = torch.linalg.cross(up, towards, dim=-1)
        d = self.direction[rows]
        elevation = torch.asin((d * up).sum(-1).clamp(-1.0, 1.0))
        azimuth = torch.atan2((d * across).sum(-1), (d * towards).sum(-1))
        distance = self.big_r * torch.atan2(sine, cosine)
        options = self.options
        radiance = kernel_radiance(self.medium, azimuth, elevation, distance, self.h_c[rows],
                                   height, emission=options["emission"],
                                   emission_parameters=options["emission_parameters"],
                                   n_steps=options["kernel_steps"],
                                   source_radius_m=options["source_radius_m"])
        return radiance.gather(-1, self.wavelength[rows][:, None])[:, 0]

    def scatter(self, rows, guided: bool = False) -> None:
        """Survive with the albedo and turn.

        The new direction follows the phase function of a species drawn in proportion to
        its scattering coefficient; with ``guided``, half of the paths instead turn
        towards the source (:meth:`_towards_source`) and every weight takes the ratio of
        the phase function to the mixture's density (one-sample multiple importance
        sampling, balance heuristic), which keeps the estimate unbiased.
        """
        height = self.altitude(rows)
        w = self.wavelength[rows]
        beta = self.tables.scattering_at(w, height)
        total = beta.sum(0)
        self.weight[rows] *= total / self.tables.extinction_at(w, height)
        pick = self._uniform(rows.numel()) * total
        species = (torch.cumsum(beta, 0) < pick[None]).sum(0).clamp(max=beta.shape[0] - 1)
        uniform = self._uniform(rows.numel())
        angle = torch.empty(rows.numel(), dtype=self.dtype)
        theta, cumulative = self.samplers
        for s in range(cumulative.shape[0]):
            for index in range(self.n_wl):
                chosen = (species == s) & (w == index)
                angle[chosen] = _sample_angle(theta, cumulative[s, index], uniform[chosen])
        phi = 2.0 * math.pi * self._uniform(rows.numel())
        old = self.direction[rows]
        new = _rotate(old, torch.cos(angle), phi)
        if guided:
            axis, cone = self._source_cone(rows)
            towards = self._uniform(rows.numel()) < GUIDED_FRACTION
            new = torch.where(towards[:, None], cone.sample(axis, self), new)
            cos_scatter = (old * new).sum(-1)
            phase = sum(beta[i] / total * _phase(self.medium, name, cos_scatter, w)
                        for i, name in enumerate(self.medium.species))
            mixture = ((1.0 - GUIDED_FRACTION) * phase
                       + GUIDED_FRACTION * cone.density(axis, new))
            self.weight[rows] *= phase / mixture
        self.direction[rows] = new

    def _source_cone(self, rows):
        """Return the unit vectors from the points to the source and the cone around them."""
        towards = self.source[rows] - self.point[rows]
        distance = torch.linalg.vector_norm(towards, dim=-1)
        axis = towards / distance[:, None]
        width = self.options["source_radius_m"] / distance
        return axis, _SourceCone(width)

    def upward(self, rows) -> torch.Tensor:
        """Whether the paths' directions climb at their current points."""
        return (self.direction[rows] * (self.point[rows] - self.centre)).sum(-1) > 0.0


def _trace(paths: _Paths, estimator: str, max_orders: int, tallies: torch.Tensor,
           first_case: int) -> None:
    """Follow the paths order by order, adding their scores to ``tallies``.

    ``tallies`` (5, case, order): sums and sums of squares of the scores, the same for the
    second order's part from above, and (order 0 only) the weight left after the last
    order. With ``estimator="line"`` the order k + 1 is scored at the k-th collision along
    the new direction (the first order by the kernel from the observer); with
    ``"collision"`` every order is scored at its own collision.
    """
    slots = paths.case - first_case
    from_above = torch.zeros(slots.numel(), dtype=torch.bool)

    def add(order, rows, score):
        score = score.to(torch.float64)
        tallies[0, :, order].index_add_(0, slots[rows], score)
        tallies[1, :, order].index_add_(0, slots[rows], score * score)
        if order == 1:
            part = torch.where(from_above[rows], score, torch.zeros_like(score))
            tallies[2, :, order].index_add_(0, slots[rows], part)
            tallies[3, :, order].index_add_(0, slots[rows], part * part)

    everyone = torch.arange(slots.numel())
    if estimator == "line":
        add(0, everyone, paths.line_score(everyone))
    for order in range(max_orders if estimator == "collision" else max_orders - 1):
        rows = paths.track()
        if not rows.numel():
            break
        if estimator == "collision":
            add(order, rows, paths.weight[rows] * paths.collision_score(rows))
        paths.scatter(rows, guided=estimator == "line")
        if order == 0:
            from_above[rows] = paths.upward(rows)
        if estimator == "line":
            add(order + 1, rows, paths.weight[rows] * paths.line_score(rows))
    tallies[4, :, 0].index_add_(0, slots, paths.weight.to(torch.float64))


#: elevations [deg], azimuths from the source [deg] and number of distances (geometric,
#: over the model's range) at which :func:`higher_order_radiance` runs the Monte Carlo
FACTOR_ELEVATIONS_DEG = (1.0, 4.0, 10.0, 20.0, 35.0, 55.0, 89.0)
FACTOR_AZIMUTHS_DEG = (0.0, 30.0, 60.0, 90.0, 120.0, 150.0, 180.0)
FACTOR_DISTANCES = 10
#: orders followed for ``scattering_orders="converged"`` (the light left after them is
#: below 1e-6 of the paths' weight in every case measured, docs/skyglow.md)
CONVERGED_ORDERS = 30


def _linear_weights(nodes: torch.Tensor, values: torch.Tensor):
    """Left node index and fraction of ``values`` on increasing ``nodes`` (held outside)."""
    index = (torch.searchsorted(nodes, values.contiguous()) - 1).clamp(0, nodes.numel() - 2)
    fraction = ((values - nodes[index]) / (nodes[index + 1] - nodes[index])).clamp(0.0, 1.0)
    return index, fraction


def _interpolate_axis(table: torch.Tensor, dim: int, nodes, values) -> torch.Tensor:
    """Linear interpolation of ``table`` along ``dim`` from ``nodes`` to ``values``."""
    index, fraction = _linear_weights(nodes, values)
    shape = [1] * table.dim()
    shape[dim] = -1
    left = table.index_select(dim, index)
    right = table.index_select(dim, index + 1)
    return left + fraction.reshape(shape) * (right - left)


def higher_order_radiance(medium: Medium, distance_m, azimuth_rad, elevation_rad,
                          source_altitude_m: float = 0.0, observer_altitude_m: float = 0.0, *,
                          scattering_orders: int | str = "converged", n_paths: int = 1000,
                          seed: int = 0, emission: str = "garstang1986",
                          emission_parameters: Mapping[str, float] | None = None,
                          source_radius_m: float = 10.0):
    """Radiance of the orders 2 … N of a unit ground source on a grid of lines of sight.

    The Monte Carlo (:func:`skyglow_scattering_orders`, line estimator) runs on a coarse
    grid — :data:`FACTOR_DISTANCES` distances spaced geometrically over the requested ones,
    the elevations :data:`FACTOR_ELEVATIONS_DEG` and azimuths :data:`FACTOR_AZIMUTHS_DEG` —
    and the logarithm of the radiance of the higher orders is interpolated linearly in log
    distance, azimuth and elevation to the requested grid (held constant beyond the coarse
    nodes). Added to the single-scattering kernel it gives every order. The light scattered
    more than once is a smooth function of the geometry, unlike the first order, which
    vanishes along long low lines of sight away from the source; so it is this radiance,
    not the factor on the kernel, that is interpolated.

    Parameters
    ----------
    medium : Medium
        The atmosphere's tables; every wavelength of the medium.
    distance_m, azimuth_rad, elevation_rad : Tensor (n,)
        The grid's distances [m] (> 0), azimuths from the source in [0, π] and elevations
        in [0, π/2] [rad], each increasing.
    source_altitude_m, observer_altitude_m : float
        Altitudes of the sources and the observer [m].
    scattering_orders : int ≥ 2 or "converged"
        Highest order (:data:`CONVERGED_ORDERS` for "converged").
    n_paths : int
        Paths per coarse line of sight and wavelength.
    seed, emission, emission_parameters, source_radius_m
        As for :func:`skyglow_scattering_orders`.

    Returns
    -------
    radiance : Tensor (distance, azimuth, elevation, wavelength)
        Orders 2 … N per unit source flux [m^-2 sr^-1].
    summary : dict
        The coarse nodes; there the factor (all orders over the first), its standard error,
        the higher orders' radiance and their standard error; paths and orders.
    """
    if scattering_orders == "converged":
        max_orders = CONVERGED_ORDERS
    else:
        max_orders = check_int("scattering_orders", scattering_orders, 2, 1000)
    distance = as_tensor("distance_m", distance_m, dtype=torch.float64).reshape(-1)
    azimuth = as_tensor("azimuth_rad", azimuth_rad, dtype=torch.float64).reshape(-1)
    elevation = as_tensor("elevation_rad", elevation_rad, dtype=torch.float64).reshape(-1)
    check_positive("distance_m", distance, unit=" m")
    # grids built as k · 2π/n may end one ulp beyond π (or π/2): a rounding, held at it
    check_range("azimuth_rad", azimuth, -1e-9, math.pi + 1e-9, unit=" rad")
    check_range("elevation_rad", elevation, -1e-9, math.pi / 2 + 1e-9, unit=" rad")
    azimuth = azimuth.clamp(0.0, math.pi)
    elevation = elevation.clamp(0.0, math.pi / 2)
    low, high = float(distance.min()), float(distance.max())
    distance_nodes = torch.logspace(math.log10(low), math.log10(max(high, low * 1.001)),
                                    FACTOR_DISTANCES, dtype=torch.float64)
    azimuth_nodes = torch.deg2rad(torch.tensor(FACTOR_AZIMUTHS_DEG, dtype=torch.float64))
    elevation_nodes = torch.deg2rad(torch.tensor(FACTOR_ELEVATIONS_DEG,
                                                 dtype=torch.float64))
    orders = skyglow_scattering_orders(
        medium, azimuth_nodes[None, :, None], elevation_nodes[None, None, :],
        distance_nodes[:, None, None], source_altitude_m, observer_altitude_m,
        emission=emission, emission_parameters=emission_parameters,
        source_radius_m=source_radius_m, n_paths=n_paths, max_orders=max_orders, seed=seed)
    higher = orders.radiance[..., 1:].sum(-1)  # (distance, azimuth, elevation, wavelength)
    higher_error = orders.standard_error[..., 1:].sum(-1)
    if not bool((higher > 0).all()):
        raise ValueError(f"no path scattered twice on some coarse line of sight with "
                         f"n_paths={n_paths}; raise n_paths")
    log_radiance = _interpolate_axis(torch.log(higher), 0, torch.log(distance_nodes),
                                     torch.log(distance))
    log_radiance = _interpolate_axis(log_radiance, 1, azimuth_nodes, azimuth)
    radiance = torch.exp(_interpolate_axis(log_radiance, 2, elevation_nodes, elevation))
    summary = {"distance_m": distance_nodes, "azimuth_rad": azimuth_nodes,
               "elevation_rad": elevation_nodes, "factor": orders.factor,
               "factor_error": orders.factor_error, "higher_orders": higher,
               "higher_orders_error": higher_error, "n_paths": n_paths,
               "orders": max_orders, "truncated_weight": orders.truncated_weight}
    return radiance, summary
