r"""Orders three and up of the sky at totality: the clear sky's field, dimmed by diffusion.

At totality the air around the observer is in the umbra; order 1 reaches it only from
the sunlit air 50–100 km away and order 2 (:func:`~skytorch.scene.solar_eclipse_sky.
eclipsed_second_order`) after one more scattering. The orders beyond carry the light
further into the umbra, step by step: a backward Monte-Carlo of every order puts them at
0.5–2.8 times order 2 at the zenith (``docs/solar_eclipse_sky.md``), where by day they
are 0.4–0.8 times it.

:func:`eclipsed_higher_orders` estimates them with a final gather whose incoming field is
the clear sky's, dimmed by how much of the Sun the light it carries has seen:

.. math::

    L_{\geq 3}(\hat v) = \int_0^{L} T(0 \to s) \sum_i \beta_i(h)
        \int_{4\pi} P_i(\hat\omega\cdot\hat v)\,L^{clear}_{2..N}(\mathbf p, \hat\omega)\,
        F(\mathbf p, \hat\omega)\,d\Omega\,ds,

with :math:`L^{clear}_{2..N}` the tables' orders 2 to N arriving at the sample
:math:`\mathbf p` of the line of sight, and the dimming

.. math::

    F(\mathbf p, \hat\omega) = \frac{\int w(\mathbf p, \mathbf q)\,G(\mathbf q)\,ds}
        {\int w(\mathbf p, \mathbf q)\,ds},\qquad
    G(\mathbf q) = \frac{\int_{4\pi}\int w_\odot(\mathbf q, \mathbf y)\,
        f_\odot(\mathbf y)\,ds\,d\Omega}{\int_{4\pi}\int w_\odot(\mathbf q, \mathbf y)
        \,ds\,d\Omega},

where :math:`\mathbf q = \mathbf p + s\hat\omega` runs along the incoming direction,
:math:`w = \beta_{sca}(\mathbf q)\,T_\odot(\mathbf q)\,T(\mathbf p\to\mathbf q)` weighs
each point by the clear sky's scattering of sunlight there and its transmittance to
:math:`\mathbf p`, :math:`w_\odot` is the same with each species' phase function for
the scattering of the solar beam towards :math:`\mathbf q` (the light of order 1
arriving at :math:`\mathbf q`), and :math:`f_\odot` the Sun's visible fraction
(:func:`~skytorch.scene.solar_eclipse_sky.visible_fraction_at`, tabulated against the
distance from the shadow's axis). :math:`G` is the eclipsed share of the order-1 field
at :math:`\mathbf q` and :math:`F` that of the light scattered from it towards
:math:`\mathbf p`.

Approximations (stated and measured, ``docs/solar_eclipse_sky.md``):

* the angular shape of each field is the clear sky's (the tables'); only its level is
  dimmed;
* every order >= 2 of the incoming field gets the dimming of order 2 (one step of
  diffusion into the umbra): the orders that carry the light further in are dimmed too
  much, so the result is low where they matter (the blue, a high Sun);
* the dimming of the scattering towards :math:`\mathbf p` is isotropic (the phase
  function enters :math:`G`, for the solar beam, only); paths are cut at
  ``path_length_m``.

Against the Monte-Carlo (Rayleigh + aerosol τ 0.1, 400 and 550 nm, 7 views, the
totalities of 2017-08-21 at Lowman and 2026-08-12 at Burgos), orders >= 3 are 0.64–0.94
of the reference at Lowman (Sun 44° from the zenith) and 0.99–1.28 at Burgos (82°) except
85° towards the Sun there at 550 nm (1.76); at the zenith 0.77–1.10. With orders 1 and 2
the sky is within 0.76–1.23 of the reference's total (1.54 at that view), where orders 1
and 2 alone are 0.10–0.83 of it.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere import Atmosphere
>>> from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
>>> from skytorch.scene.geometry import Geometry
>>> atm = Atmosphere.earth(turbidity=2.0)
>>> wl = torch.tensor([550.0], dtype=torch.float64)
>>> tables = precompute_scattering(atm, wl, scattering_orders=3,
...                                resolution=TableResolution.tiny())
>>> sun, moon = (0.0, 7.48e10, 1.296e11), (0.0, 1.87e8, 3.24e8)   # Sun 60 deg high
>>> g = Geometry(60.0, 90.0, 60.0, 90.0, 3.74e8, 1.496e11, math.pi, 0.0, 0.0, 0.0, 0.0,
...              sun_horizontal_m=sun, moon_horizontal_m=moon)
>>> zero = torch.tensor([0.0], dtype=torch.float64)
>>> higher = eclipsed_higher_orders(atm, wl, zero, zero, g, tables=tables, n_view=4,
...                                 n_mu=2, n_phi=4, n_neighbourhood_mu=2,
...                                 n_neighbourhood_phi=4, n_path=4)
>>> higher.shape, bool((higher > 0).all())
(torch.Size([1, 1]), True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import torch

from skytorch._quadrature import unit_nodes
from skytorch._validate import check_int, check_positive, check_range
from skytorch.atmosphere.geometry import (
    distance_to_ground,
    distance_to_top,
    ray_hits_ground,
    safe_sqrt,
)
from skytorch.atmosphere.multiple_scattering import MU_S_MIN, ScatteringTables
from skytorch.atmosphere.scattering import gather_on_line_of_sight
from skytorch.scene.solar_eclipse_sky import _eclipse_inputs, visible_fraction_at

__all__ = ["eclipsed_higher_orders"]

#: the tables' largest Sun zenith angle [rad] (the Sun 18 deg below the horizon)
_SUN_ZENITH_MAX = math.acos(MU_S_MIN)
#: the visible fraction is tabulated against the distance from the shadow's axis out to
#: this distance [m] (beyond the penumbra, some 3 500 km across at the Earth) ...
_AXIS_DISTANCE_MAX_M = 4.0e6
#: ... every this many metres (the umbra's edge is crossed in a few kilometres; the light
#: of the higher orders comes from tens of kilometres around)
_AXIS_DISTANCE_STEP_M = 1.0e3
#: points per chunk of the neighbourhood integral (memory: chunk x directions x samples)
_CHUNK = 256


@dataclass(frozen=True)
class _Dimming:
    """What the dimming of the clear field needs: air, shadow, Sun and quadrature."""

    constituents: object
    transmittance: object
    centre: torch.Tensor  # the planet's centre from the observer (3,) [m]
    sun: torch.Tensor  # unit vector to the Sun (3,)
    moon: torch.Tensor  # the Moon's centre from the observer (3,) [m]
    axis: torch.Tensor  # unit vector of the shadow's axis, Moon to Sun (3,)
    visible_table: torch.Tensor  # visible fraction every _AXIS_DISTANCE_STEP_M (n,)
    directions: torch.Tensor  # sphere of directions of the neighbourhood (d, 3)
    direction_weights: torch.Tensor  # (d,) [sr]
    n_path: int
    path_length_m: float
    across: tuple  # two unit vectors across the axis: (nearest the zenith, the other)
    share_table: torch.Tensor | None = None  # G (wavelength, height, across 0, across 1)
    half_width_m: float = 0.0

    def visible(self, points: torch.Tensor) -> torch.Tensor:
        """Visible fraction at points (..., 3) from the distance to the shadow's axis."""
        offset = points - self.moon
        along = offset @ self.axis
        distance = torch.linalg.vector_norm(offset - along[..., None] * self.axis, dim=-1)
        position = distance / _AXIS_DISTANCE_STEP_M
        last = self.visible_table.shape[0] - 1
        index = position.floor().clamp(max=last - 1).long()
        fraction = (position - index).clamp(0.0, 1.0)
        value = (self.visible_table[index] * (1 - fraction)
                 + self.visible_table[index + 1] * fraction)
        return torch.where(position >= last, torch.ones_like(value), value)

    def path_mean(self, start, direction, value, *, solar_phase: bool):
        r"""Weighted means of ``value`` along rays, and the weights' sums (..., wavelength).

        Rays from ``start`` (..., 3) along the unit ``direction`` (..., 3) to the ground,
        the top or ``path_length_m``, samples crowded towards the start; weights
        :math:`\beta_{sca} T_\odot T` (with each species' phase for the solar beam
        scattered back along the ray when ``solar_phase``).
        """
        planet = self.constituents.planet_radius_m
        top = self.constituents.top_radius_m
        from_centre = start - self.centre
        r = torch.linalg.vector_norm(from_centre, dim=-1)
        mu = ((from_centre * direction).sum(-1) / r).clamp(-1.0, 1.0)
        length = torch.where(ray_hits_ground(r, mu, planet), distance_to_ground(r, mu, planet),
                             distance_to_top(r, mu, top)).clamp(max=self.path_length_m)
        t = torch.arange(self.n_path + 1, dtype=r.dtype) / self.n_path
        s = length[..., None] * t ** 2
        points = start[..., None, :] + s[..., None] * direction[..., None, :]
        radius = torch.linalg.vector_norm(points - self.centre, dim=-1)
        height = (radius - planet).clamp(0.0, top - planet)
        cos_sun = ((points - self.centre) @ self.sun) / radius
        sun_zenith = torch.acos(cos_sun.clamp(-1.0, 1.0))
        lit = sun_zenith <= _SUN_ZENITH_MAX
        sun_depth = self.transmittance.lookup(
            torch.where(lit, sun_zenith, torch.zeros_like(sun_zenith)), height)
        sun_transmittance = torch.where(lit[..., None], torch.exp(-sun_depth),
                                        torch.zeros_like(sun_depth))
        extinction = sum(self.constituents.extinction_coefficients(height).values())
        coefficients = self.constituents.scattering_coefficients(height)
        if solar_phase:
            cosine = (direction @ self.sun)[..., None].expand(height.shape)
            scattering = sum(coefficients[species.name] * (4.0 * math.pi)
                             * species.phase(cosine)
                             for species in self.constituents.scatterers())
        else:
            scattering = sum(coefficients.values())
        step = torch.diff(s, dim=-1)
        depth = torch.cumsum(0.5 * (extinction[..., 1:, :] + extinction[..., :-1, :])
                             * step[..., None], dim=-2)
        depth = torch.cat([torch.zeros_like(depth[..., :1, :]), depth], dim=-2)
        trapezoid = torch.zeros_like(s)
        trapezoid[..., 1:] += 0.5 * step
        trapezoid[..., :-1] += 0.5 * step
        weight = scattering * sun_transmittance * torch.exp(-depth) * trapezoid[..., None]
        sampled = value(points)
        if sampled.dim() == weight.dim() - 1:
            sampled = sampled[..., None]
        return (weight * sampled).sum(-2), weight.sum(-2)

    def shadow_coordinates(self, points: torch.Tensor):
        """Offsets (..., 2) [m] across the shadow's axis and heights (...) [m] of points."""
        offset = points - self.moon
        across = torch.stack([offset @ self.across[0], offset @ self.across[1]], dim=-1)
        radius = torch.linalg.vector_norm(points - self.centre, dim=-1)
        height = (radius - self.constituents.planet_radius_m).clamp(
            0.0, self.constituents.top_altitude_m)
        return across, height

    def tabulate(self, n_across: int, n_height: int, half_width_m: float) -> _Dimming:
        r"""Return a copy whose :meth:`order_one_share` interpolates a table of :math:`G`.

        :math:`G` on ``n_across``\ :sup:`2` offsets across the shadow's axis within
        ±``half_width_m`` (:func:`_offset_nodes`: 3.8 times denser at the axis, where the
        umbra is, than at the edge) by ``n_height`` heights (uniform in the square root of the
        height, denser near the ground): each node the point of that offset and height
        nearest to the observer. Beyond the offsets :math:`G` is taken as the visible
        fraction (the penumbra varies over thousands of kilometres), and so at offsets whose
        line parallel to the axis never comes down to that height.
        """
        dtype = self.moon.dtype
        offsets = half_width_m * _offset_nodes(torch.linspace(-1.0, 1.0, n_across,
                                                              dtype=dtype))
        top = self.constituents.top_altitude_m
        heights = top * torch.linspace(0.0, 1.0, n_height, dtype=dtype) ** 2
        a, b, h = torch.meshgrid(offsets, offsets, heights, indexing="ij")
        start = self.moon + a[..., None] * self.across[0] + b[..., None] * self.across[1]
        q = start - self.centre
        along = q @ self.axis
        radius = self.constituents.planet_radius_m + h
        disc = along ** 2 - (q * q).sum(-1) + radius ** 2
        root = torch.sqrt(disc.clamp(min=0.0))
        candidates = torch.stack([-along - root, -along + root], dim=-1)  # (..., 2)
        points = start[..., None, :] + candidates[..., None] * self.axis
        nearest = torch.linalg.vector_norm(points, dim=-1).argmin(-1)
        points = torch.gather(points, -2, nearest[..., None, None].expand(
            *nearest.shape, 1, 3))[..., 0, :]
        reached = disc >= 0
        share = self.order_one_share(points)
        visible = self.visible(points)[..., None].expand_as(share)
        share = torch.where(reached[..., None], share, visible)
        # (wavelength, height, offset a, offset b) for grid_sample
        return replace(self, share_table=share.permute(3, 2, 0, 1).contiguous(),
                       half_width_m=float(half_width_m))

    def order_one_share(self, points: torch.Tensor) -> torch.Tensor:
        """:math:`G` at points (..., 3) -> (..., wl): from the table when tabulated."""
        if self.share_table is None:
            return self._order_one_share_direct(points)
        across, height = self.shadow_coordinates(points)
        top = self.constituents.top_altitude_m
        flat_across = _offset_coordinate(across / self.half_width_m).reshape(1, 1, 1, -1, 2)
        grid = torch.cat([flat_across.flip(-1), (2.0 * safe_sqrt(height / top) - 1.0
                                                 ).reshape(1, 1, 1, -1, 1)], dim=-1)
        sampled = torch.nn.functional.grid_sample(
            self.share_table[None], grid.to(self.share_table.dtype), mode="bilinear",
            padding_mode="border", align_corners=True)[0, :, 0, 0, :].T
        inside = (across.abs() <= self.half_width_m).all(-1).reshape(-1)
        visible = self.visible(points).reshape(-1, 1).expand_as(sampled)
        return torch.where(inside[:, None], sampled, visible).reshape(*points.shape[:-1], -1)

    def _order_one_share_direct(self, points: torch.Tensor) -> torch.Tensor:
        """:math:`G`: eclipsed share of the order-1 field at points (..., 3) -> (..., wl)."""
        flat = points.reshape(-1, 3)
        n_dir = self.directions.shape[0]
        weights = self.direction_weights[None, :, None]
        shares = []
        for first in range(0, flat.shape[0], _CHUNK):
            start = flat[first:first + _CHUNK, None, :].expand(-1, n_dir, 3)
            total, norm = self.path_mean(start, self.directions.expand_as(start),
                                         self.visible, solar_phase=True)
            norm = (norm * weights).sum(1)
            shares.append((total * weights).sum(1)
                          / torch.where(norm > 0, norm, torch.ones_like(norm)))
        return torch.cat(shares).reshape(*points.shape[:-1], -1)


def eclipsed_higher_orders(atmosphere, wavelength_nm, view_zenith_rad, view_azimuth_rad,
                           geometry, altitude_m: float = 0.0, *, tables, table=None,
                           scattering_orders="converged", n_view: int = 12, n_mu: int = 4,
                           n_phi: int = 12,
                           n_neighbourhood_mu: int = 4, n_neighbourhood_phi: int = 12,
                           n_path: int = 12, path_length_m: float = 800e3,
                           neighbourhood_grid=(31, 20, 250e3), n_nodes: int = 8
                           ) -> torch.Tensor:
    r"""Orders >= 3 of the sky during a solar eclipse per unit solar irradiance [1/sr].

    Parameters
    ----------
    atmosphere : Atmosphere
        The atmosphere (scalar parameters), the one of ``tables``.
    wavelength_nm : Tensor (wavelength,)
        [nm], those of ``tables``.
    view_zenith_rad, view_azimuth_rad : Tensor (...)
        Lines of sight [rad], azimuth from north through east (absolute).
    geometry : skytorch.scene.geometry.Geometry
        Sun and Moon at the observer.
    altitude_m : float
        Observer's height [m].
    tables : ScatteringTables
        The clear sky's orders (:func:`~skytorch.atmosphere.multiple_scattering.
        precompute_scattering`), with at least 2 orders; orders 2 to all computed are
        gathered.
    table : TransmittanceTable, optional
        The Sun's transmittance at ``wavelength_nm`` (built when not given).
    scattering_orders : int or "converged"
        N >= 3: the orders 3..N (the tables' orders 2..N - 1 gathered); "converged": every
        order of the tables gathered (orders 3..computed + 1).
    n_view, n_mu, n_phi : int
        Final gather: samples along the line of sight (>= 2), Gauss nodes per hemisphere
        and azimuths of the sphere at each sample (>= 1).
    n_neighbourhood_mu, n_neighbourhood_phi : int
        Sphere of directions of :math:`G` (>= 1 each).
    n_path : int
        Samples along each path of :math:`F` and :math:`G` (>= 2).
    path_length_m : float
        Longest path [m] (> 0).
    neighbourhood_grid : (int, int, float) or None
        :math:`G` tabulated on ``n_across`` x ``n_across`` offsets across the shadow's
        axis within ± ``half_width_m`` by ``n_height`` heights (>= 2 each; half width
        > 0 [m]) and interpolated; ``None`` computes it at every point (for checks: some
        thirty times slower per line of sight).
    n_nodes : int
        Quadrature nodes of the visible fraction.

    Returns
    -------
    Tensor (..., wavelength)
        :math:`L_{\geq 3}/E_\odot` [sr^-1]; add :func:`eclipsed_single_scattering` and
        :func:`eclipsed_second_order` for the sky.

    Notes
    -----
    Module docstring: the method, its approximations and its accuracy. Cost: about
    ``n_view * 2 n_mu * n_phi * (n_path + 1)`` neighbourhood integrals of
    ``2 n_neighbourhood_mu * n_neighbourhood_phi * (n_path + 1)`` samples each per line
    of sight (19 M samples at the defaults: 5–11 s per line with two wavelengths on 2
    cores): a few directions per scene, not every pixel.
    """
    from skytorch.atmosphere.tables import TransmittanceTable

    orders = _incoming_orders(tables, scattering_orders)
    n_view = check_int("n_view", n_view, 2)
    n_mu = check_int("n_mu", n_mu, 1)
    n_phi = check_int("n_phi", n_phi, 1)
    n_neighbourhood_mu = check_int("n_neighbourhood_mu", n_neighbourhood_mu, 1)
    n_neighbourhood_phi = check_int("n_neighbourhood_phi", n_neighbourhood_phi, 1)
    n_path = check_int("n_path", n_path, 2)
    path_length_m = float(check_positive("path_length_m", path_length_m, unit=" m"))
    constituents, view_zenith, view_azimuth, sun_zenith, sun_azimuth, _ = _eclipse_inputs(
        atmosphere, wavelength_nm, view_zenith_rad, view_azimuth_rad, geometry, n_nodes)
    if len(constituents.batch_shape):
        raise ValueError("eclipsed_higher_orders takes an atmosphere with scalar parameters; "
                         f"got batch shape {tuple(constituents.batch_shape)}")
    dtype = constituents.dtype
    wavelength = torch.as_tensor(wavelength_nm, dtype=torch.float64).reshape(-1)
    if (tables.wavelength_nm.shape != wavelength.shape
            or not torch.allclose(tables.wavelength_nm.to(torch.float64), wavelength)):
        raise ValueError(f"wavelength_nm {wavelength.tolist()} must be the tables' "
                         f"{tables.wavelength_nm.tolist()}")
    altitude = check_range("altitude_m", altitude_m, 0.0, tables.top_altitude_m, unit=" m",
                           dtype=dtype)
    if table is None:
        table = TransmittanceTable.build(atmosphere, wavelength, cache=False, n_mu=128,
                                         n_r=32)
    elif not isinstance(table, TransmittanceTable):
        raise TypeError("table must be a skytorch.atmosphere.tables.TransmittanceTable or "
                        f"None; got {type(table).__name__}")
    else:
        table.check_compatible(atmosphere, wavelength)
    dimming = _dimming(constituents, table, geometry, float(altitude), n_neighbourhood_mu,
                       n_neighbourhood_phi, n_path, path_length_m, n_nodes)
    if neighbourhood_grid is not None:
        dimming = dimming.tabulate(*_grid_setting(neighbourhood_grid))

    def incoming(zenith, azimuth, sun_zenith_local, sun_azimuth_local, height, to_observer):
        inside = sun_zenith_local <= _SUN_ZENITH_MAX
        sun_inside = torch.where(inside, sun_zenith_local, torch.zeros_like(sun_zenith_local))
        clear = (tables.radiance(height, zenith, azimuth, sun_inside, sun_azimuth_local,
                                 scattering_orders=orders)
                 - tables.radiance(height, zenith, azimuth, sun_inside, sun_azimuth_local,
                                   scattering_orders=1))
        clear = torch.where(inside[..., None], clear, torch.zeros_like(clear))
        local = _unit_vectors(zenith, azimuth)  # (d, 3)
        lead = (*height.shape[:-1], local.shape[0], 1, 3)
        origin = to_observer(torch.zeros(lead, dtype=height.dtype))[..., 0, :]
        direction = to_observer(local[:, None, :].expand(lead))[..., 0, :] - origin
        total, norm = dimming.path_mean(origin, direction, dimming.order_one_share,
                                        solar_phase=False)
        share = total / torch.where(norm > 0, norm, torch.ones_like(norm))
        return clear * share

    line = gather_on_line_of_sight(constituents, view_zenith, view_azimuth, sun_zenith,
                                   sun_azimuth, altitude, incoming, n_view=n_view,
                                   n_mu=n_mu, n_phi=n_phi)
    return line.radiance


def _unit_vectors(zenith: torch.Tensor, azimuth: torch.Tensor) -> torch.Tensor:
    """Return unit vectors (..., 3), north, east, up, of the directions (zenith, azimuth [rad])."""
    sin_zenith = torch.sin(zenith)
    return torch.stack([sin_zenith * torch.cos(azimuth), sin_zenith * torch.sin(azimuth),
                        torch.cos(zenith)], dim=-1)


def _incoming_orders(tables, scattering_orders) -> int | str:
    """Check the tables and return the last order of their field to gather (N - 1).

    ``"converged"`` for every order of the tables (with their remainder, if any).
    """
    if not isinstance(tables, ScatteringTables):
        raise TypeError(f"tables must be a ScatteringTables; got {type(tables).__name__}")
    if len(tables.batch_shape):
        raise ValueError("eclipsed_higher_orders takes tables of an atmosphere with scalar "
                         f"parameters; got batch shape {tuple(tables.batch_shape)}")
    if tables.orders_computed < 2:
        raise ValueError("tables must hold at least 2 orders (orders 2..N are dimmed and "
                         f"gathered); got {tables.orders_computed}")
    if scattering_orders == "converged":
        return "converged"
    return check_int("scattering_orders", scattering_orders, 3, tables.orders_computed + 1) - 1


def _grid_setting(neighbourhood_grid) -> tuple[int, int, float]:
    """Check ``neighbourhood_grid`` = (n_across, n_height, half_width_m)."""
    if not isinstance(neighbourhood_grid, (tuple, list)) or len(neighbourhood_grid) != 3:
        raise TypeError("neighbourhood_grid must be (n_across, n_height, half_width_m) or "
                        f"None; got {neighbourhood_grid!r}")
    return (check_int("neighbourhood_grid n_across", neighbourhood_grid[0], 2),
            check_int("neighbourhood_grid n_height", neighbourhood_grid[1], 2),
            float(check_positive("neighbourhood_grid half_width_m", neighbourhood_grid[2],
                                 unit=" m")))


#: stretch of the offsets of the dimming's table: sinh(k u) / sinh(k) for u uniform in
#: [-1, 1] is k / sinh(k) = 0.55 times the uniform spacing at the axis, k cosh(k) / sinh(k)
#: = 2.07 times at the edge
_OFFSET_STRETCH = 2.0


def _offset_nodes(u: torch.Tensor) -> torch.Tensor:
    """Offsets across the axis (in half widths) of the uniform coordinates ``u`` in [-1, 1]."""
    return torch.sinh(_OFFSET_STRETCH * u) / math.sinh(_OFFSET_STRETCH)


def _offset_coordinate(offset: torch.Tensor) -> torch.Tensor:
    """Inverse of :func:`_offset_nodes`."""
    return torch.asinh(offset * math.sinh(_OFFSET_STRETCH)) / _OFFSET_STRETCH


def _dimming(constituents, table, geometry, altitude: float, n_mu: int, n_phi: int,
             n_path: int, path_length_m: float, n_nodes: int) -> _Dimming:
    """Build the shadow's axis, its visible-fraction table and the neighbourhood sphere."""
    dtype = constituents.dtype
    sun = torch.tensor(geometry.sun_horizontal_m, dtype=dtype)
    moon = torch.tensor(geometry.moon_horizontal_m, dtype=dtype)
    axis = (sun - moon) / torch.linalg.vector_norm(sun - moon)
    foot = moon + axis * ((-moon) @ axis)  # the axis's point nearest to the observer
    up = torch.tensor([0.0, 0.0, 1.0], dtype=dtype)
    first = up - (up @ axis) * axis
    if float(torch.linalg.vector_norm(first)) < 1e-9:  # the Sun at the zenith
        first = torch.tensor([1.0, 0.0, 0.0], dtype=dtype)
    first = first / torch.linalg.vector_norm(first)
    across = torch.linalg.cross(axis, first)
    n_table = int(round(_AXIS_DISTANCE_MAX_M / _AXIS_DISTANCE_STEP_M)) + 1
    distance = torch.arange(n_table, dtype=dtype) * _AXIS_DISTANCE_STEP_M
    visible = visible_fraction_at(geometry, foot + distance[:, None] * first,
                                  n_nodes=n_nodes)
    x, w = unit_nodes(n_mu, dtype)
    mu, w = torch.cat([-x.flip(0), x]), torch.cat([w.flip(0), w])
    phi = (torch.arange(n_phi, dtype=dtype) + 0.5) * (2.0 * math.pi / n_phi)
    directions = _unit_vectors(torch.acos(mu)[:, None].expand(-1, n_phi).reshape(-1),
                            phi[None, :].expand(2 * n_mu, -1).reshape(-1))
    weights = w[:, None].expand(-1, n_phi).reshape(-1) * (2.0 * math.pi / n_phi)
    centre = torch.tensor([0.0, 0.0, -(constituents.planet_radius_m + altitude)], dtype=dtype)
    return _Dimming(constituents, table, centre, sun / torch.linalg.vector_norm(sun), moon,
                    axis, visible, directions, weights, n_path, path_length_m,
                    (first, across))
