r"""Multiple scattering in spherical geometry by precomputed orders (Bruneton & Neyret 2008).

:func:`precompute_scattering` builds, for one :class:`~skytorch.atmosphere.Atmosphere`
(batched over its parameters) and a set of wavelengths, tables of the sky radiance of
each order of scattering over the observer's radius ``r``, the view zenith cosine ``mu``,
the Sun's zenith cosine ``mu_s`` and the view-Sun azimuth difference ``phi``; the
returned :class:`ScatteringTables` is the whole state (no module caches) and looks the
radiance up for any geometry (:meth:`ScatteringTables.radiance`).

Method (refs. 1, 2)
-------------------
* transmittance to the top of the atmosphere :math:`\tau(r,\mu)` on a table mapped as in
  ref. 2 (distance to the boundary), from the species' path columns
  (:meth:`~skytorch.atmosphere.constituents.Constituents.optical_depth`, every species
  with its law); the Sun's direct beam is zero where its ray meets the planet;
* order 1 (single scattering) per scattering species without its phase function
  (constant along a straight ray), multiplied at look-up by the exact phase
  :math:`P_s(\nu)`; view paths integrated by the trapezoid rule on ``n_ray`` samples
  with the cumulative per-species columns (``TableResolution.ray_quadrature``
  "exponential": the columns from sub-samples and the transmittance exponential between
  samples, :func:`exponential_path_weights`; the same weights for every order); plus
  the Sun reflected once by the Lambertian ground, on the table's nodes as the source of
  order 2 and computed anew at each look-up (the lit ground's kink at the terminator,
  interpolated across the nodes, was overestimated: +1.1 % of the light leaving the top
  of a white planet);
* order n >= 2: scattering density :math:`J_n = \sum_s \beta_s\,P_s \otimes L_{n-1}` by
  a product quadrature over the sphere (Gauss-Legendre in each hemisphere of ``mu``,
  periodic trapezoid in azimuth); each row of the discrete phase operator is
  renormalised to 1 so that scattering conserves energy on the discrete grid;
  :math:`L_n` is the integral of :math:`T\,J_n` along the ray plus, for rays that end on
  the ground, :math:`T\,\frac{\alpha}{\pi}E_{n-1}` with :math:`E_{n-1}` the downward
  irradiance of order n-1 at the ground;
* the forward peak factored out of the orders >= 2 (``forward_peak="factored"``): the
  light of order n from the Sun, and its source, are divided at the table's nodes by the
  angular shape of n scatterings by the column's mean phase function
  (:func:`forward_peak_shapes`, Legendre moments :math:`\chi_l^n`), interpolated, and
  multiplied by that shape at the looked-up view-Sun angle, which is constant along a
  straight ray; the light reflected by the ground is followed apart, unfactored. The
  multiply-scattered aureole of a forward-peaked aerosol then moves with the Sun instead
  of being smeared across the Sun-zenith and view nodes;
* ``scattering_orders="converged"`` adds orders until the last one is below
  ``rtol`` (1e-4) of the sum (at most ``max_orders``), or until the sum with its remainder
  extrapolated changes by less than ``rtol`` of each Sun-zenith node's sum: for large n,
  order n+1 is order n times the dominant eigenvalue q of the scattering operator (the
  successive orders tend to a geometric series, ref. 5), so the orders beyond n sum to
  :math:`L_n\,q/(1-q)`, with q the ratio of the last two orders per table node (summed
  over the azimuths). The tables then hold the remainder as a last level
  (:attr:`ScatteringTables.remainder_extrapolated`).

Approximations (tested in tests/test_multiple_scattering.py, quantified in
docs/multiple_scattering.md): multilinear interpolation in (r, mu, mu_s, phi) with the
horizon kept as a table seam; the Sun a point source; straight rays (no refraction);
scalar radiative transfer (no polarisation: up to ~8 % error in Rayleigh skies,
refs. 3, 4); species with a nonlinear optical-depth law enter the view paths by their
columns but contribute no local scattering.

Accuracy against DISORT in the plane-parallel limit (docs/multiple_scattering_validation.md,
"Exact rays and 24 radii"; default :class:`TableResolution`, Sun 30-60 deg, 400 and 550 nm,
views 0-60 deg; ray-marched order 1 + the tables' orders >= 2): the sky seen from the
ground is within 1.02 % for aerosol optical depth 0.05 (the sphere's shorter slant path),
0.82 % at 0.3 and 0.64 % at 1 (18 % and 44 % at 0.3 and 1 when the orders are interpolated
with their forward peak, ``forward_peak="none"``, on the tables of 2026-12-05). The
radiance leaving the top against sasktran2 in spherical geometry: within 0.7 % to τ 0.05,
1.7 % at 0.3 and 2.2 % at 1. A conservative atmosphere over a white ground returns what it
receives within 0.5 % (the issue's bound; docs/multiple_scattering.md, "Energy balance").

References
----------
1. Bruneton, E. & Neyret, F. 2008, "Precomputed Atmospheric Scattering", Computer
   Graphics Forum 27, 1079, doi:10.1111/j.1467-8659.2008.01245.x.
2. Bruneton, E. 2017, "A Qualitative and Quantitative Evaluation of 8 Clear Sky
   Models", IEEE TVCG 23, 2641, doi:10.1109/TVCG.2016.2622272 (and its
   precomputed_atmospheric_scattering implementation: table parametrisation).
3. Mishchenko, M. I., Lacis, A. A. & Travis, L. D. 1994, "Errors induced by the neglect
   of polarization in radiance calculations for Rayleigh-scattering atmospheres",
   JQSRT 51, 491, doi:10.1016/0022-4073(94)90149-X.
4. Kattawar, G. W., Plass, G. N. & Adams, C. N. 1971/1976 (scalar vs vector Rayleigh
   radiances), ApJ 170, 371, doi:10.1086/151223.
5. van de Hulst, H. C. 1980, "Multiple Light Scattering: Tables, Formulas, and
   Applications", vol. 1, Academic Press (successive orders of scattering).

Examples
--------
>>> import torch
>>> from skytorch.atmosphere import Atmosphere
>>> from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
>>> atm = Atmosphere.earth(turbidity=2.0)
>>> tables = precompute_scattering(atm, torch.tensor([450.0, 650.0]), scattering_orders=3,
...                                resolution=TableResolution.tiny())
>>> zenith = tables.radiance(0.0, 0.0, 0.0, 1.0)
>>> zenith.shape, bool((zenith > 0).all())
(torch.Size([2]), True)
>>> tables.orders_computed
3
"""

from __future__ import annotations

import copy
import functools
import math
from dataclasses import dataclass

import numpy as np
import torch

from skytorch._memory import Scratch
from skytorch._quadrature import legendre_signed, legendre_unit
from skytorch._validate import check_angle, check_int, check_range, input_eps
from skytorch.atmosphere.geometry import safe_sqrt
from skytorch.atmosphere.inputs import check_atmosphere, wavelength_tensor

__all__ = ["MU_S_MIN", "RAY_QUADRATURES", "ScatteringTables", "TableResolution",
           "exponential_path_weights", "forward_peak_shapes", "precompute_scattering"]

#: lowest cosine of the Sun's zenith angle in the tables: the Sun 18 deg below the horizon
#: largest Sun zenith angle of the tables [rad] (18 deg below the horizon)
MAX_SUN_ZENITH_RAD = math.radians(108.0)
MU_S_MIN = math.cos(MAX_SUN_ZENITH_RAD)
#: relative size of the last order at which ``"converged"`` stops
CONVERGENCE_RTOL = 1e-4
#: values per block of the tables' look-ups (points x channels)
_LOOKUP_BUDGET = 1 << 17
#: values per block of the ray integrals (samples x Sun directions x channels): the
#: element-wise work on blocks of this size stays in the caches
_BUDGET = 1_000_000
#: samples x Sun directions whose look-up plans (32 bytes each) the ray integrals keep
#: from one order to the next (2^21: 67 MB)
_GEOMETRY_BUDGET = 1 << 21
#: sub-samples per segment of the table's rays for their columns with ``ray_quadrature``
#: "exponential": the trapezoid on them. Against 64, turbidity 8, four orders, Sun 30-96 deg:
#: the radiance within 0.28 % on the default preset's 16-sample rays, 0.013 % on the
#: default tables' 96 (2 / 4 sub-samples: 4.4 / 1.1 % and 0.21 / 0.053 %)
_COLUMN_SUBSAMPLES = 8
#: the quadratures along the table's rays (:class:`TableResolution`)
RAY_QUADRATURES = ("trapezoid", "exponential")


@dataclass(frozen=True)
class TableResolution:
    r"""Sizes of the scattering tables and quadratures.

    Parameters
    ----------
    n_r : int
        Radii (uniform in the horizontal distance to the horizon, ref. 2, or crowded
        towards the ground by ``r_ground_weight``), >= 2.
    n_mu : int
        View zenith cosines, even, >= 4: half on rays meeting the ground, half on rays
        to the sky (the horizon is a seam of the table).
    n_mu_s : int
        Sun zenith cosines from cos 108 deg to 1 (mapping of ref. 2), >= 2.
    n_phi : int
        View-Sun azimuth differences, uniform on [0, pi], >= 3.
    n_ray : int
        Samples along each table ray, >= 2. Few samples overweight the observer's end of
        the rays (they cluster there): on :meth:`tiny` tables, 550 nm, Sun and view at
        28.6 deg, order 1 against the ray-marched single scattering (512 samples) is 40 /
        4.5 / 1.44 / 1.20 / 1.10 / 1.04 times it with 2 / 4 / 8 / 12 / 16 / 24 samples
        (trapezoid; exponential 31 / 4.2 / 1.41 / 1.19 / 1.10 / 1.04). Sizes that small
        serve gradient checks and tests; the build does not judge accuracy.
    n_sphere_mu : int
        Gauss-Legendre nodes per hemisphere of the sphere quadrature, >= 1.
    transmittance_r, transmittance_mu : int
        Size of the transmittance table, >= 2 each.
    mu_vertical_weight : float
        Share w in [0, 1] of the view-zenith nodes moved towards the vertical: the node
        coordinate is :math:`v = u + w(\sqrt{u} - u)(1 - u)` of ref. 2's distance
        coordinate u, which grows as the square of the angle from the vertical. 0 is ref.
        2's mapping; 1/2 (the default) spaces the nodes near the vertical uniformly in
        angle and keeps those at the horizon, thinning those between by up to 18 %. It
        takes the radiance leaving the top through a thick haze (τ 1) from 8 % to 0.5 %
        of sasktran2 at the nadir, and makes tables of 16 view nodes per half worse (the
        sky through τ 1: 20 % → 36 % of DISORT), so coarse tables should pass 0
        (docs/multiple_scattering_validation.md, "The view-zenith axis").
    r_ground_weight : float
        Share w in [0, 1) of the radius nodes moved towards the ground: the horizontal
        distance to the horizon is :math:`\rho / H = (1 - w)\,y + w\,y^2` of a uniform node
        coordinate y (0 is ref. 2's mapping). Near the ground the nodes are 1 - w times as
        far apart, at the top 1 + w times. At 1/2 on the default sizes it takes the sky
        through an aerosol of τ 1 (Sun 30 deg) from 1.7 % to 0.7 % of DISORT and the top
        from 4.4 % to 3.4 % of sasktran2 at no cost; tables of 8 radii get worse (the sky
        through τ 1: 0.7 % → 14.7 %), so coarse tables should pass 0
        (docs/multiple_scattering_validation.md, "Radius nodes towards the ground").
        The default is 1/2 since 2026-12-07, with ``sphere_phi_refinement`` 2.
    sphere_phi_refinement : int
        Azimuth intervals of the sphere quadrature per interval of the table's azimuths,
        >= 1: the source of each order >= 2 is the previous order scattered on a
        quadrature of ``2 (n_phi - 1) sphere_phi_refinement`` azimuths, the previous order
        interpolated linearly in azimuth between the table's nodes with its forward-peak
        shape factored out. With 1 (the table's own 14 azimuths, 25.7 deg apart, for
        ``n_phi`` 8) a Henyey-Greenstein peak of g 0.7 is aliased and the sky near the Sun
        through an aerosol of τ 1 came out 2.4-4.6 % too bright in its orders >= 2; 2
        removes that (4 changes it by < 0.1 %) at no measurable cost (default sizes, 3
        optical depths x 2 wavelengths: 126 / 131 / 127 s for 1 / 2 / 4;
        docs/multiple_scattering_validation.md, "Azimuths of the sphere quadrature").
    ray_quadrature : {"trapezoid", "exponential"}
        The integrals along the table's rays. ``"trapezoid"`` (ref. 2's): the columns and
        the product of source and transmittance by the trapezoid on the ``n_ray`` samples.
        ``"exponential"``: the columns from 8 sub-samples of each segment and the
        transmittance exponential between the samples (product integration,
        :func:`exponential_path_weights`), exact for a source linear between them however
        thick the segment (the default since 2026-12-07). With few samples through a thick
        haze the trapezoid overestimates the light of every order (docs/accuracy.md,
        "quadrature along the tables' rays").

    Notes
    -----
    The defaults (24 x 64 x 48 x 8, 96 samples per ray, view nodes moved half-way towards the
    vertical; 16 radii until 2026-12-07) were chosen by the error against DISORT, sasktran2 and
    the energy balance, one size at a time (docs/multiple_scattering_validation.md, "Default
    tables of 2026-12-05"): 96 samples per ray and 48 Sun-zenith nodes are what the converged
    sky through a thick haze and the conservation of energy need; they cost 3.6 times the former
    16 x 64 x 24 x 8 with 48 samples. Since 2026-12-07 the radius nodes are crowded towards the
    ground (``r_ground_weight`` 1/2) and the sphere quadrature has twice the table's azimuths
    (``sphere_phi_refinement`` 2): together they take the sky through an aerosol of τ 1 within
    1.15 % of DISORT (docs/multiple_scattering_validation.md, "Azimuths of the sphere
    quadrature"). Since the second revision of 2026-12-07 the tables have 24 radii and the
    exponential quadrature along their rays (``ray_quadrature``): on 16 radii the trapezoid's
    excess had offset the radius nodes' deficit (with 32 radii the trapezoid moves away from
    DISORT, 1.15 → 2.3 %); with the exact rays the sky converges as radii are added, within
    0.64 % of DISORT through τ 1 at 400 and 550 nm on 24 radii, for 1.5 times the build
    (docs/accuracy.md, "quadrature along the tables' rays"). Partial sizes take these defaults
    too; tables of 8 radii or fewer should pass ``r_ground_weight=0``.
    """

    n_r: int = 24
    n_mu: int = 64
    n_mu_s: int = 48
    n_phi: int = 8
    n_ray: int = 96
    n_sphere_mu: int = 12
    transmittance_r: int = 64
    transmittance_mu: int = 256
    mu_vertical_weight: float = 0.5
    r_ground_weight: float = 0.5
    sphere_phi_refinement: int = 2
    ray_quadrature: str = "exponential"

    def __post_init__(self):
        """Check every size (ValueError naming the field)."""
        if self.ray_quadrature not in RAY_QUADRATURES:
            raise ValueError(f"ray_quadrature must be one of {RAY_QUADRATURES}; got "
                             f"{self.ray_quadrature!r:.60}")
        for name, low in (("n_r", 2), ("n_mu", 4), ("n_mu_s", 2), ("n_phi", 3), ("n_ray", 2),
                          ("n_sphere_mu", 1), ("transmittance_r", 2),
                          ("transmittance_mu", 2), ("sphere_phi_refinement", 1)):
            # a whole float (8.0) is kept as the int it stands for: the sizes index tensors
            object.__setattr__(self, name, check_int(name, getattr(self, name), low))
        if self.n_mu % 2:
            raise ValueError(f"n_mu must be an even integer >= 4; got {self.n_mu}")
        for name, high, closed in (("mu_vertical_weight", 1.0, True),
                                   ("r_ground_weight", 1.0, False)):
            weight = getattr(self, name)
            interval = f"[0, {high:g}{']' if closed else ')'}"
            if isinstance(weight, bool) or not isinstance(weight, (int, float)):
                raise TypeError(f"{name} must be a float in {interval}; got "
                                f"{type(weight).__name__} {weight!r}")
            if not (0.0 <= weight <= high if closed else 0.0 <= weight < high):
                raise ValueError(f"{name} must be in {interval}; got {weight!r}")

    @classmethod
    def bruneton2017(cls) -> TableResolution:
        """Ref. 2's default sizes: R 32, mu 128, mu_s 32, nu 8; transmittance 256 x 64."""
        return cls(n_r=32, n_mu=128, n_mu_s=32, n_phi=8, n_ray=50, n_sphere_mu=16,
                   transmittance_r=64, transmittance_mu=256, mu_vertical_weight=0.0,
                   r_ground_weight=0.0, sphere_phi_refinement=1, ray_quadrature="trapezoid")

    @classmethod
    def tiny(cls) -> TableResolution:
        """Return a coarse table for tests and gradient checks (seconds to build)."""
        return cls(n_r=5, n_mu=16, n_mu_s=8, n_phi=5, n_ray=16, n_sphere_mu=4,
                   transmittance_r=16, transmittance_mu=32, mu_vertical_weight=0.0,
                   r_ground_weight=0.0, sphere_phi_refinement=1, ray_quadrature="trapezoid")


# ---------------------------------------------------------------- geometry and mappings
class _Shell:
    """Radii of the shell and the table mappings (ref. 2), as pure tensor functions."""

    def __init__(self, planet: float, top: float, vertical_weight: float = 0.0,
                 ground_weight: float = 0.0):
        self.R = planet
        self.Rt = top
        self.H = math.sqrt(top * top - planet * planet)
        self.vertical_weight = float(vertical_weight)
        self.ground_weight = float(ground_weight)

    def _node_coordinate(self, u):
        r"""View-zenith node coordinate :math:`v = u + w(\sqrt{u} - u)(1 - u)` of ref. 2's u."""
        if not self.vertical_weight:
            return u
        return u + self.vertical_weight * (safe_sqrt(u) - u) * (1.0 - u)

    def _distance_coordinate(self, v, iterations: int = 30):
        """Ref. 2's coordinate u of the node coordinate v (table nodes only).

        Newton's method in s = sqrt(u), where v = s^2 + w (s - s^2)(1 - s^2) increases on
        [0, 1]; 30 steps from s = sqrt(v) reach the round-off.
        """
        w = self.vertical_weight
        if not w:
            return v
        v = torch.clamp(v, 0.0, 1.0)
        s = torch.sqrt(v)
        for _ in range(iterations):
            value = s * s + w * (s - s * s) * (1.0 - s * s)
            slope = 2.0 * s + w * ((1.0 - 2.0 * s) * (1.0 - s * s) - 2.0 * s * (s - s * s))
            s = torch.clamp(s - (value - v) / slope, 0.0, 1.0)
        return s * s

    def rho(self, r):
        # (r - R)(r + R): no cancellation of r^2 - R^2 in float32; a zero (not infinite)
        # gradient on the ground, where the horizon distance is 0
        return safe_sqrt((r - self.R) * (r + self.R))

    def mu_horizon(self, r):
        return -self.rho(r) / r

    # the discriminants through safe_sqrt: a zero gradient where a ray grazes the ground
    # or the top (sqrt's is infinite at 0, and NaN through the clamp in float32)
    def distance_top(self, r, mu):
        return torch.clamp(-r * mu + safe_sqrt(
            r * r * mu * mu + (self.Rt - r) * (self.Rt + r)), min=0.0)

    def distance_ground(self, r, mu):
        return torch.clamp(-r * mu - safe_sqrt(
            r * r * mu * mu - (r - self.R) * (r + self.R)), min=0.0)

    # r <-> coordinate in [0, 1]: rho / H = (1 - w) x + w x^2
    def r_of(self, x):
        w = self.ground_weight
        return torch.sqrt((((1.0 - w) + w * x) * x * self.H) ** 2 + self.R ** 2)

    def x_of_r(self, r):
        w = self.ground_weight
        distance = self.rho(r) / self.H
        if not w:
            return distance
        # the root of w x^2 + (1 - w) x - distance in [0, 1], without cancellation
        return 2.0 * distance / ((1.0 - w) + torch.sqrt((1.0 - w) ** 2 + 4.0 * w * distance))

    # mu <-> (ground flag, node coordinate in [0, 1]); 1 at the horizon
    def mu_coordinate(self, r, mu):
        rho = self.rho(r)
        ground = mu < self.mu_horizon(r)
        d_g, d_t = self.distance_ground(r, mu), self.distance_top(r, mu)
        g_min, g_span = r - self.R, rho - (r - self.R)
        t_min, t_span = self.Rt - r, rho + self.H - (self.Rt - r)
        u_g = torch.where(g_span > 1e-9 * self.R, (d_g - g_min) / torch.clamp(g_span, min=1e-30),
                          (mu + 1.0) / torch.clamp(1.0 + self.mu_horizon(r), min=1e-30))
        u_t = (d_t - t_min) / t_span
        return ground, self._node_coordinate(torch.clamp(torch.where(ground, u_g, u_t),
                                                         0.0, 1.0))

    def mu_of(self, r, v, ground: bool):
        u = self._distance_coordinate(v)
        rho = self.rho(r)
        if ground:
            d = (r - self.R) + u * (rho - (r - self.R))
            safe = torch.clamp(d, min=1e-30)
            mu = -(rho * rho + d * d) / (2.0 * r * safe)
            flat = (rho - (r - self.R)) <= 1e-9 * self.R
            mu = torch.where(flat, -1.0 + u * (1.0 + self.mu_horizon(r)), mu)
        else:
            d = (self.Rt - r) + u * (rho + self.H - (self.Rt - r))
            mu = (self.H ** 2 - rho * rho - d * d) / (2.0 * r * torch.clamp(d, min=1e-30))
        return torch.clamp(mu, -1.0, 1.0)

    # mu_s <-> coordinate in [0, 1] (ref. 2, extended to cos 108 deg)
    def _a_big(self):
        d = float(self.distance_top(torch.tensor(self.R, dtype=torch.float64),
                                    torch.tensor(MU_S_MIN, dtype=torch.float64)))
        d_min, d_max = self.Rt - self.R, self.H
        return (d - d_min) / (d_max - d_min)

    def mu_s_coordinate(self, mu_s):
        d_min, d_max, big = self.Rt - self.R, self.H, self._a_big()
        d = -self.R * mu_s + torch.sqrt(self.R ** 2 * (mu_s * mu_s - 1.0) + self.Rt ** 2)
        a = (d - d_min) / (d_max - d_min)
        return torch.clamp(torch.clamp(1.0 - a / big, min=0.0) / (1.0 + a), 0.0, 1.0)

    def mu_s_of(self, x):
        d_min, d_max, big = self.Rt - self.R, self.H, self._a_big()
        a = big * (1.0 - x) / (1.0 + big * x)
        d = d_min + a * (d_max - d_min)
        return torch.clamp((self.H ** 2 - d * d) / (2.0 * self.R * d), -1.0, 1.0)


def _linear(c, n: int, offset=0):
    """Lower index and weight of a coordinate ``c`` in [0, n - 1] on ``n`` nodes."""
    c = torch.clamp(c, 0.0, n - 1.0)
    i = torch.clamp(torch.floor(c.detach()), 0, n - 2).to(torch.long)
    return i + offset, c - i


def _weights_as(corner, dtype):
    """Return an (index, weight) pair with its weight in ``dtype``."""
    return corner[0], corner[1].to(dtype)


def _mu_index(shell, r, mu, n_mu: int):
    """Lower index (into the full mu axis) and weight of ``mu`` at radius ``r``."""
    half = n_mu // 2
    ground, u = shell.mu_coordinate(r, mu)
    ig, wg = _linear(u * (half - 1), half)
    it, wt = _linear((1.0 - u) * (half - 1), half, half)
    return torch.where(ground, ig, it), torch.where(ground, wg, wt)


def _geometric(low, high, weight):
    """Interpolate between two nodes geometrically (linearly where a node is zero).

    The sky falls by orders of magnitude between two Sun-zenith nodes in twilight; there a
    linear interpolation overestimates by up to the ratio of the nodes, a geometric one is
    exact for an exponential fall. Where a node is zero (the planet's shadow) the
    interpolation is linear. (Until 2026-12-06 it was linear where the nodes differ by less
    than 1.5x and blended into the geometric one up to 4x: with 48 Sun-zenith nodes that
    left the orders >= 2 up to 6 % too bright between nodes at the Sun 4 deg below the
    horizon, docs/multiple_scattering_validation.md.)
    """
    if not (torch.is_grad_enabled() and any(
            isinstance(x, torch.Tensor) and x.requires_grad for x in (low, high, weight))):
        return _geometric_without_gradient(low, high, weight)
    positive = (low > 0) & (high > 0)
    tiny = torch.finfo(low.dtype).tiny
    # two logarithms, not the log of the ratio: high / tiny overflows where low is zero,
    # and the unused branch of the where would then give NaN gradients
    log_low = torch.log(torch.clamp(low, min=tiny))
    log_ratio = torch.log(torch.clamp(high, min=tiny)) - log_low
    linear = torch.addcmul(low, weight, high - low)
    geometric = torch.exp(torch.addcmul(log_low, weight, log_ratio))
    return torch.where(positive, geometric, linear)


def _geometric_without_gradient(low, high, weight, scratch=None):
    """:func:`_geometric` with its temporaries reused in place (no gradient recorded).

    The same operations in the same order as the differentiable path where both nodes are
    positive, so the same values, with fewer passes over the data: no clamp of the nodes
    (where one is zero its logarithm is -inf and the linear interpolation replaces the
    result) and the linear interpolation only where a node is not positive.

    With a :class:`~skytorch._memory.Scratch` ``scratch`` and both nodes positive
    everywhere, ``high`` is overwritten and the result is the scratch buffer ``"log_low"``
    (no new memory: the callers' loops reuse it, docs/benchmarks.md "Twilight sweep").
    """
    if scratch is not None and bool(low.min() > 0) and bool(high.min() > 0):
        log_low = torch.log(low, out=scratch("log_low", tuple(low.shape), low.dtype))
        log_ratio = high.log_().sub_(log_low)
        return log_low.addcmul_(weight, log_ratio).exp_()
    log_low = torch.log(low)
    log_ratio = torch.log(high).sub_(log_low)
    geometric = torch.addcmul(log_low, weight, log_ratio, out=log_low).exp_()
    # two reductions decide whether any node is not positive (NaN is not): cheaper than
    # the element-wise mask, which is formed only then
    if bool(low.min() > 0) and bool(high.min() > 0):
        return geometric
    positive = torch.minimum(low, high) > 0
    return torch.where(positive, geometric, torch.addcmul(low, weight, high - low))


def _gather4(table, b, corners):
    """Look ``table`` (b, n1, n2, n3, n4, λ') up at the corners.

    ``corners`` is four (index, weight) pairs of equal shapes; ``b`` the batch index.
    Multilinear in dims 1, 2 and 4 (r, mu, phi) and geometric in dim 3 (mu_s, see
    :func:`_geometric`). Returns (*shape, λ').

    Each of the 16 corners is one row gather of the λ' channels (:func:`torch.index_select`)
    accumulated with its weight; the weights of the (r, mu) corners are formed once. The
    points are looked up in blocks of :data:`_LOOKUP_BUDGET` values, whose temporaries
    stay in the caches. Where every point has one radius and they outnumber the table's
    (b, mu, mu_s, phi) rows (an image seen by one observer), the table is interpolated in
    r once and each point gathers 8 corners (0.77x the time of a 512² fisheye,
    docs/benchmarks.md).
    """
    (i1, w1), (i2, w2), (i3, w3), (i4, w4) = corners
    shape = torch.broadcast_shapes(*(x.shape for pair in corners for x in pair))
    if i1.numel() == 1 and table.shape[1] > 1 and math.prod(table.shape[:1] + table.shape[2:5]) \
            <= math.prod(shape):
        # every point at one radius (one observer): interpolate the table in r once, then
        # look up 8 corners instead of 16 (linear in r, so the same values up to round-off)
        ir = i1.reshape(())
        table = torch.lerp(table[:, ir], table[:, ir + 1],
                           w1.reshape(()).to(table.dtype))[:, None]
        i1, w1 = torch.zeros_like(i1), torch.zeros_like(w1)
    n1, n2, n3, n4 = table.shape[1:5]
    channels = table.shape[-1]
    flat = table.reshape(-1, channels)
    base = ((((b * n1 + i1) * n2 + i2) * n3 + i3) * n4 + i4).expand(shape).reshape(-1)
    w1, w2, w3, w4 = (w.expand(shape).reshape(-1, 1) for w in (w1, w2, w3, w4))
    step = max(1, _LOOKUP_BUDGET // max(1, channels))
    blocks = []
    for start in range(0, base.shape[0], step):
        block = slice(start, start + step)
        pair_weights = [((w1[block] if d1 else 1.0 - w1[block])
                         * (w2[block] if d2 else 1.0 - w2[block]),
                         d1 * n2 * n3 * n4 + d2 * n3 * n4) for d1 in range(min(n1, 2))
                        for d2 in (0, 1)]
        phi_weights = (1.0 - w4[block], w4[block])
        sides = []
        for d3 in (0, 1):
            side = None
            for pair, pair_offset in pair_weights:
                for d4 in (0, 1):
                    weight = pair * phi_weights[d4]
                    rows = torch.index_select(flat, 0,
                                              base[block] + (pair_offset + d3 * n4 + d4))
                    side = rows * weight if side is None else side.addcmul_(rows, weight)
            sides.append(side)
        blocks.append(_geometric(sides[0], sides[1], w3[block]))
    if not blocks:
        return flat.new_zeros(shape + (channels,))
    out = blocks[0] if len(blocks) == 1 else torch.cat(blocks)
    return out.reshape(shape + (channels,))


#: largest number of (r, mu) nodes for which :func:`_ray_plan` interpolates the rays'
#: samples by a dense matrix product: its cost grows with the nodes, the gather's does not
#: (both measured in docs/benchmarks.md, "The rays' (r, mu) interpolation")
_DENSE_RAY_NODES = 256


def _ray_plan(ray_corners, sun_corners, n1: int, n2: int, n3: int, n4: int):
    """Rows and weights of :func:`_gather_rays` on a table (1, n1, n2, n3, n4, λ').

    ``ray_corners`` is two (index, weight) pairs of shape (*g) on dims 1 and 2 (r, mu:
    fixed along a sample of a ray), ``sun_corners`` two pairs of shape (*g, m3, m4) on
    dims 3 and 4 (mu_s, phi: one per Sun direction of the table). The plan depends on
    the geometry only: every order of scattering and every parameter set reuses it.
    Up to :data:`_DENSE_RAY_NODES` (r, mu) nodes the (r, mu) interpolation is a matrix
    (samples, n1 n2) of four weights per row, applied by one matrix product; above, the
    four rows are gathered and accumulated.
    """
    (i1, w1), (i2, w2) = ray_corners
    n_g = i1.numel()
    corners = [(((i1 + d1) * n2 + (i2 + d2)).reshape(-1),
                ((w1 if d1 else 1.0 - w1) * (w2 if d2 else 1.0 - w2)).reshape(-1))
               for d1 in (0, 1) for d2 in (0, 1)]
    if n1 * n2 <= _DENSE_RAY_NODES:
        nodes = torch.zeros((n_g, n1 * n2), dtype=w1.dtype)
        for index, weight in corners:
            nodes.index_put_((torch.arange(n_g), index), weight, accumulate=True)
    else:
        nodes = [(index, weight.reshape(-1, 1)) for index, weight in corners]
    (i3, w3), (i4, w4) = sun_corners
    row = (torch.arange(n_g).reshape(tuple(i1.shape) + (1, 1)) * (n3 * n4)
           + (i3 * n4 + i4)).reshape(-1)
    # per mu_s side, the row of its lower phi corner (the upper is the next row)
    return nodes, (row, row + n4), w4.reshape(-1, 1), w3[None, ..., None]


def _gather_rays(table, plan, scratch=None):
    """Look ``table`` (1, n1, n2, n3, n4, λ') up at the samples of the table's rays.

    ``plan`` from :func:`_ray_plan`. The same interpolation as :func:`_gather4`
    (multilinear in r, mu, phi, geometric in mu_s), done in two stages: contiguous
    (mu_s, phi) blocks are interpolated in (r, mu) once per sample, then looked up in
    (mu_s, phi): the two phi corners of each mu_s side are adjacent rows, gathered as one
    pair. Returns (1, *g, m3, m4, λ').

    One parameter set at a time: the temporaries of a whole batch outgrow the caches (a
    10 × 10 batch took 4.6 s per set against 0.9 s alone). With a
    :class:`~skytorch._memory.Scratch` ``scratch`` (no gradient recorded) every
    temporary and the result are its buffers, valid until the next call with it: the
    same values without the first-write page faults of new memory at every call (the
    serial twilight sweep 84.6 → 70.5 s, docs/benchmarks.md).
    """
    if table.shape[0] != 1:
        raise ValueError(f"_gather_rays takes one parameter set; got {table.shape[0]}")
    scratch = Scratch(enabled=False) if scratch is None else scratch
    nodes, side_rows, w4, w3 = plan
    n1, n2, n3, n4, channels = table.shape[1:]
    # the (mu_s, phi, λ') block of each (r, mu) node is one row of this view
    blocks = table.reshape(n1 * n2, n3 * n4 * channels)
    if torch.is_tensor(nodes):
        ray = torch.matmul(nodes, blocks, out=scratch("ray", (nodes.shape[0], blocks.shape[1]),
                                                      blocks.dtype))
    else:
        ray = None
        for index, weight in nodes:
            rows = torch.index_select(blocks, 0, index, out=scratch(
                "ray" if ray is None else "rows", (index.shape[0], blocks.shape[1]),
                blocks.dtype))
            ray = rows.mul_(weight) if ray is None else ray.addcmul_(rows, weight)
    # each row with the next (a phi node and the one above): (g * n3 * n4 - 1, 2, λ')
    pairs = ray.reshape(-1, channels).unfold(0, 2, 1).transpose(1, 2)
    sides = []
    for name, index in zip(("low", "high"), side_rows, strict=True):
        rows = torch.index_select(pairs, 0, index, out=scratch(
            "pairs", (index.shape[0], 2, channels), pairs.dtype))
        side = torch.lerp(rows[:, 0], rows[:, 1], w4, out=scratch(
            name, (index.shape[0], channels), pairs.dtype))
        sides.append(side.reshape(w3.shape[:-1] + (channels,)))
    if scratch.enabled:
        return _geometric_without_gradient(sides[0], sides[1], w3, scratch)
    return _geometric(sides[0], sides[1], w3)


def _last_order_negligible(member_sizes) -> bool:
    """Whether the last order is below :data:`CONVERGENCE_RTOL` of the sum, for every member.

    ``member_sizes``: per order, the (b,) sizes of the parameter sets relative to order 1.
    """
    sizes = torch.stack(member_sizes)
    return bool((sizes[-1] <= CONVERGENCE_RTOL * sizes.sum(0)).all())


def _geometric_remainder(sky, ground, previous_sky, previous_ground):
    """Orders beyond the last, extrapolated as a geometric series, or None.

    ``sky``, ``ground`` (b, r, mu, ms, phi, λ) are the two parts of the last order,
    ``previous_*`` those of the one before. The ratio q of the two orders' sums over the
    azimuths, per table node (parameter set, r, mu, Sun zenith, wavelength; 0 where the
    order before is 0), gives the remainder :math:`L_n q / (1 - q)` of each part. None
    where a ratio is 1 or more (the series is not yet geometric there). (A first version,
    one ratio per Sun-zenith node summed over r and mu as well and the stop judged on the
    whole table's sum, left 2-3 % at the Sun 18 deg below the horizon.)
    """
    this = (sky.abs() + ground.abs()).sum(4, keepdim=True)
    before = (previous_sky.abs() + previous_ground.abs()).sum(4, keepdim=True)
    ratio = torch.where(before > 0, this / torch.where(before > 0, before, 1.0), 0.0)
    if bool((ratio.detach() >= 1.0).any()):
        return None
    factor = ratio / (1.0 - ratio)
    return sky * factor, ground * factor


def balanced_phase_operator(phase, weights, iterations: int = 200):
    r"""Discrete scattering operator that conserves energy both ways on a quadrature.

    With ``phase`` :math:`p_{ij} = P(\omega_i\cdot\omega_j)` (symmetric) and the solid-angle
    weights :math:`w_j` of the directions, returns :math:`K_{ij} = d_i\,p_{ij}\,w_j\,d_j`
    with the scale factors :math:`d` found by symmetric Sinkhorn iteration so that every row
    sums to 1 (the source of each direction is a weighted mean of the radiance: no gain
    for an isotropic field) and, by the symmetry of :math:`p`, every column satisfies
    :math:`\sum_i w_i K_{ij} = w_j` (the light scattered out of each direction is
    redistributed whole). Normalising rows alone loses the second property for a
    forward-peaked phase function on a coarse quadrature, and the scheme then gains or
    loses energy at every order.

    Parameters
    ----------
    phase : Tensor (..., n, n, λ)
        Phase function between the quadrature directions [sr^-1], symmetric in (n, n).
    weights : Tensor (n,)
        Quadrature weights [sr] (sum 4π).
    iterations : int
        Sinkhorn iterations (the scaling converges geometrically).

    Returns
    -------
    Tensor (..., n, n, λ)
    """
    a = phase * weights[:, None]
    d = torch.ones(a.shape[:-3] + (a.shape[-3], a.shape[-1]), dtype=a.dtype)
    for _ in range(iterations):
        d = torch.sqrt(d / torch.einsum("...ijl,...jl->...il", a, d))
    return d[..., :, None, :] * a * d[..., None, :, :]


#: Legendre terms of the forward-peak shapes, and their nodes (uniform in the scattering
#: angle, linear in its cosine between nodes)
_PEAK_TERMS = 256
_PEAK_NODES = 1025
#: lowest value of a peak shape relative to isotropy (the shapes divide the tables)
_PEAK_FLOOR = 1e-3


def _legendre(x, n_terms: int):
    """Legendre polynomials P_0..P_n at fixed nodes ``x`` (...) -> (n + 1, ...).

    By the recurrence in float64 (:func:`numpy.polynomial.legendre.legvander`), then in
    the dtype of ``x``; the nodes carry no gradient.
    """
    if x.requires_grad:
        raise ValueError("_legendre takes fixed nodes: x must not require gradients")
    values = np.polynomial.legendre.legvander(x.detach().to(torch.float64).numpy(), n_terms)
    return torch.from_numpy(np.ascontiguousarray(np.moveaxis(values, -1, 0))).to(x.dtype)


def _peak_nodes(dtype):
    """Cosines of the peak-shape nodes, from forward (1) to backward (-1) scattering."""
    return torch.cos(torch.linspace(0.0, math.pi, _PEAK_NODES, dtype=dtype))


def forward_peak_shapes(moments, orders):
    r"""Angular shape of light scattered ``n`` times by one phase function, on its nodes.

    With the Legendre moments :math:`\chi_l` of a phase function normalised to 1 over the
    sphere, the phase function convolved with itself ``n`` times over the sphere has the
    moments :math:`\chi_l^n`; its value at the scattering angle :math:`\Theta` is
    :math:`\sum_l \frac{2l+1}{4\pi}\chi_l^n P_l(\cos\Theta)` (for a Henyey-Greenstein
    function of asymmetry g, the Henyey-Greenstein function of asymmetry :math:`g^n`).

    Parameters
    ----------
    moments : Tensor (..., n_terms + 1)
        Legendre moments, :math:`\chi_0 = 1`.
    orders : sequence of int
        The numbers of scatterings ``n``.

    Returns
    -------
    Tensor (len(orders), ..., nodes) [sr^-1]
        On the cosines of :func:`_peak_nodes` (scattering angles uniform on [0, π]), at
        least :data:`_PEAK_FLOOR` / (4π).
    """
    return _peak_shapes(moments, orders,
                        _legendre(_peak_nodes(moments.dtype), moments.shape[-1] - 1))


def _peak_shapes(moments, orders, legendre):
    """:func:`forward_peak_shapes` with the Legendre polynomials (l, nodes) at the nodes."""
    n_terms = moments.shape[-1] - 1
    degree = torch.arange(n_terms + 1, dtype=moments.dtype)
    shapes = [torch.matmul(moments ** n * (2 * degree + 1) / (4 * math.pi), legendre)
              for n in orders]
    return torch.clamp(torch.stack(shapes), min=_PEAK_FLOOR / (4 * math.pi))


def _peak_corners(nu):
    """Lower node and weight of ``nu`` on :func:`_peak_nodes` (linear in the cosine)."""
    nodes = _peak_nodes(nu.dtype)
    angle = torch.acos(torch.clamp(nu.detach(), -1.0, 1.0))
    i = torch.clamp(torch.floor(angle * ((_PEAK_NODES - 1) / math.pi)), 0,
                    _PEAK_NODES - 2).to(torch.long)
    low, high = nodes[i], nodes[i + 1]
    return i, (nu - low) / (high - low)


def _peak_at(shape, nu):
    """Peak ``shape`` (b, nodes, λ) at the cosines ``nu`` (*g): (b, *g, λ)."""
    i, w = _peak_corners(nu)
    low = shape[:, i.reshape(-1)].reshape((shape.shape[0],) + tuple(nu.shape) + shape.shape[-1:])
    high = shape[:, (i + 1).reshape(-1)].reshape(low.shape)
    return torch.lerp(low, high, w[None, ..., None].to(shape.dtype))


# ---------------------------------------------------------------- the tables
def _depth_to_top(rows, shell, res, bi, r, mu):
    """Optical depth from (r, mu) to the top, looked up on the transmittance table.

    ``rows`` (b * transmittance_r * transmittance_mu, λ): the table's rows; ``bi`` the
    batch index broadcasting with ``r`` and ``mu`` (...). Bilinear in the table's
    coordinates (ref. 2's mapping); a ray that meets the ground is looked up as if the
    planet were transparent (callers mask it). Returns (..., λ) in the rows' dtype.
    """
    ir = _linear(shell.x_of_r(r) * (res.transmittance_r - 1), res.transmittance_r)
    _, u = shell.mu_coordinate(r, torch.clamp(mu, min=-1.0))
    im = _linear(u * (res.transmittance_mu - 1), res.transmittance_mu)
    base = (bi * res.transmittance_r + ir[0]) * res.transmittance_mu + im[0]
    w_r, w_m = ir[1].to(rows.dtype), im[1].to(rows.dtype)
    tau = 0.0
    for dr in (0, 1):
        for dm in (0, 1):
            w = (w_r if dr else 1 - w_r) * (w_m if dm else 1 - w_m)
            idx = base + dr * res.transmittance_mu + dm
            tau = tau + w[..., None] * rows[idx.reshape(-1)].reshape(idx.shape + rows.shape[-1:])
    return tau


class ScatteringTables:
    """Precomputed orders of scattering of one atmosphere at given wavelengths.

    Built by :func:`precompute_scattering`; holds tensors and the species' phase functions
    (its state is explicit: the look-up table of an order is joined from the tensors at its
    first look-up, per grad mode). It lives in the process that built it: the phase
    functions are closures of the atmosphere's species, so the tables cannot be pickled
    (TypeError; ``copy.deepcopy`` works); rebuild them where they are needed (a build's
    cost: docs/multiple_scattering.md "Cost").

    Attributes
    ----------
    wavelength_nm : Tensor (wavelength,)
    batch_shape : torch.Size
        The atmosphere's parameter batch shape (leading dims of the results).
    orders_computed : int
        Highest order of scattering in the tables.
    order_contributions : Tensor (orders_computed,)
        Per order, the sum of its radiance over the table relative to order 1 (the
        convergence report; monotone decreasing for a converging series).
    converged : bool
        Whether the last order is below :data:`CONVERGENCE_RTOL` of the sum, or the sum
        with its remainder extrapolated changed by less than that with the last order.
    remainder_extrapolated : bool
        Whether the tables hold, as a last level beyond ``orders_computed``, the orders
        beyond the last extrapolated as a geometric series (``"converged"`` tables; the
        look-ups with ``scattering_orders="converged"`` include it, those with an
        integer N sum the orders 1..N exactly).
    resolution : TableResolution
    ground_albedo : Tensor (*batch, wavelength)
    atmosphere_parameters : dict
        ``Atmosphere.parameters_dict()`` of the atmosphere they were built for
        (:meth:`check_built_for` compares it).
    gradient_parameters : frozenset of str
        The atmosphere's parameters whose gradients the tables carry (those that required
        a gradient while gradients were recorded at the build).
    """

    def __init__(self, *, shell, resolution, wavelength_nm, batch_shape, single, phases,
                 levels, contributions, converged, ground_albedo, peak_shape,
                 depth_rows, atmosphere_parameters, gradient_parameters,
                 remainder_extrapolated=False):
        self.atmosphere_parameters = atmosphere_parameters
        self.gradient_parameters = frozenset(gradient_parameters)
        self._shell = shell
        self.resolution = resolution
        self.wavelength_nm = wavelength_nm
        self.batch_shape = torch.Size(batch_shape)
        self._single = single            # (b, r, mu, mu_s, phi, n_species * λ)
        self._phases = phases            # callables phase(cos) -> (b, ..., λ)
        # per level (orders <= n), a function returning [ground's reflections | orders >= 2
        # scattered in the atmosphere divided by the peak shape] along the channels
        self._levels = levels
        self._peak_shape = peak_shape    # (b, nodes, λ): the shape of order 2
        # per order, [single | cumulative] along the channels (one look-up per pixel),
        # joined at the first look-up of that order
        self._lookup = {}
        self.order_contributions = contributions
        self.remainder_extrapolated = bool(remainder_extrapolated)
        self.orders_computed = len(levels) - int(self.remainder_extrapolated)
        self.converged = converged
        self.ground_albedo = ground_albedo
        # optical depth to the top (b * transmittance_r * transmittance_mu, λ), float64:
        # the Sun reflected once by the ground is computed at each look-up
        self._depth_rows = depth_rows

    def __deepcopy__(self, memo):
        """Copy every attribute (closures are shared, as deepcopy does for functions)."""
        new = object.__new__(type(self))
        memo[id(self)] = new
        new.__dict__.update(copy.deepcopy(self.__dict__, memo))
        return new

    def __reduce_ex__(self, protocol):
        """Refuse pickling with the reason (a raw AttributeError named a local closure)."""
        raise TypeError("ScatteringTables cannot be pickled: they hold the atmosphere's "
                        "phase functions (closures); rebuild them with precompute_scattering "
                        "in the process that uses them")

    def check_converged(self) -> None:
        """Raise ValueError unless the orders converged.

        :meth:`skytorch.atmosphere.Atmosphere.sky_radiance` asks it of tables given for
        its default ``scattering_orders="converged"``. The look-ups here, the final gather
        and the eclipse shadow's higher orders take ``"converged"`` as every order the
        tables hold (``converged`` says whether that is the limit).
        """
        if not self.converged:
            raise ValueError(f"scattering_orders='converged' but the tables hold "
                             f"{self.orders_computed} orders that have not converged: pass "
                             f"scattering_orders={self.orders_computed} for their sum, or "
                             "tables built with scattering_orders='converged'")

    def check_built_for(self, atmosphere, ground_albedo=None) -> None:
        """Raise ValueError unless the tables are those of ``atmosphere`` (and albedo).

        Parameters
        ----------
        atmosphere : skytorch.atmosphere.Atmosphere
            Its parameters must be those the tables were built with; the parameters that
            require a gradient (while gradients are recorded) must have required it at the
            build, or their gradient through the tables would be lost.
        ground_albedo : float or Tensor, optional
            The albedo a caller asks for: must equal the tables' (scalar or per
            wavelength, in [0, 1]); None skips the check.
        """
        given = atmosphere.parameters_dict()
        built = self.atmosphere_parameters
        differ = sorted(key for key in set(given) | set(built)
                        if given.get(key) != built.get(key))
        if differ:
            shown = ", ".join(f"{key} {given.get(key)!r:.40} (tables: {built.get(key)!r:.40})"
                              for key in differ[:4])
            raise ValueError(f"tables were built for another atmosphere: {shown}"
                             f"{' ...' if len(differ) > 4 else ''}")
        if torch.is_grad_enabled():
            lost = sorted(name for name, value in atmosphere.named_buffers()
                          if value.requires_grad and name not in self.gradient_parameters)
            if lost:
                raise ValueError(f"the atmosphere's {', '.join(lost)} require a gradient, "
                                 "which the tables do not carry (built without gradients "
                                 "for them): build the tables with gradients recorded, or "
                                 "pass parameters that do not require one")
        if ground_albedo is None:
            return
        n_lambda = self.wavelength_nm.shape[0]
        albedo = _check_albedo(ground_albedo, self.batch_shape, n_lambda,
                               self.ground_albedo.dtype)
        if not torch.equal(albedo.expand_as(self.ground_albedo).detach(),
                           self.ground_albedo.detach()):
            raise ValueError(f"ground_albedo {_brief(albedo)} is not the tables' "
                             f"{_brief(self.ground_albedo)}: build tables for it")
        if (torch.is_grad_enabled() and albedo.requires_grad
                and not self.ground_albedo.requires_grad):
            raise ValueError("ground_albedo requires a gradient, which the tables do not "
                             "carry (built without gradients for it)")

    @property
    def planet_radius_m(self) -> float:
        """Radius of the ground [m]."""
        return self._shell.R

    @property
    def top_altitude_m(self) -> float:
        """Altitude of the top of the atmosphere [m]."""
        return self._shell.Rt - self._shell.R

    def _lookup_table(self, n: int):
        """[single | orders <= ``n``] along the channels (b, r, mu, mu_s, phi, channels).

        Joined at its first use and kept per grad mode: a table joined under
        ``torch.no_grad()`` (a preview) holds no graph, and served later to a look-up that
        records one it would drop the gradients of tables built with them.
        """
        key = (n, torch.is_grad_enabled())
        if key not in self._lookup:
            self._lookup[key] = torch.cat([self._single, self._levels[n - 1]()], dim=-1)
        return self._lookup[key]

    def _order(self, scattering_orders):
        if scattering_orders is None or scattering_orders == "converged":
            return len(self._levels)
        n = check_int("scattering_orders", scattering_orders, 1, self.orders_computed)
        return n

    def radiance(self, altitude_m, view_zenith_rad, view_azimuth_rad, sun_zenith_rad,
                 sun_azimuth_rad=0.0, scattering_orders=None) -> torch.Tensor:
        r"""Sky radiance per unit extraterrestrial solar irradiance (..., wavelength) [sr^-1].

        Parameters
        ----------
        altitude_m : Tensor (...)
            Observer altitude [m], from the ground to the top of the atmosphere.
        view_zenith_rad, view_azimuth_rad : Tensor (...)
            Viewing direction [rad] (zenith in [0, pi], azimuth from north through east).
        sun_zenith_rad, sun_azimuth_rad : Tensor (...)
            Direction of the Sun [rad]; zenith in [0, 108 deg].
        scattering_orders : int or "converged", optional
            Sum the orders 1..N, or (default) every order computed with the remainder
            where :attr:`remainder_extrapolated`.

        Returns
        -------
        Tensor (*batch ⊔ ..., wavelength)
            All orders up to the requested one; ``...`` broadcasts with the tables'
            batch shape.
        """
        n = self._order(scattering_orders)
        dtype = self._single.dtype
        altitude = check_range("altitude_m", altitude_m, 0.0, self.top_altitude_m, unit=" m",
                               dtype=dtype)
        vz = check_angle("view_zenith_rad", view_zenith_rad, math.pi, dtype)
        va = check_range("view_azimuth_rad", view_azimuth_rad, dtype=dtype)
        sz = check_angle("sun_zenith_rad", sun_zenith_rad, MAX_SUN_ZENITH_RAD, dtype)
        sa = check_range("sun_azimuth_rad", sun_azimuth_rad, dtype=dtype)
        try:
            shape = torch.broadcast_shapes(self.batch_shape, altitude.shape, vz.shape,
                                           va.shape, sz.shape, sa.shape)
        except RuntimeError:
            raise ValueError(
                f"shapes do not broadcast: batch {tuple(self.batch_shape)}, altitude_m "
                f"{tuple(altitude.shape)}, view_zenith_rad {tuple(vz.shape)}, "
                f"sun_zenith_rad {tuple(sz.shape)}") from None
        b = self._batch_index(shape)
        r = self._shell.R + altitude  # not expanded: one radius is looked up once
        # a view below the horizontal by the round-off of its input (float32(pi/2) is
        # 4e-8 rad below) is horizontal: at the ground it would otherwise be a ray that
        # meets the ground at once (the rule of the ray-marched single scattering,
        # skytorch.atmosphere.geometry.ray_hits_ground: mu < -8 eps)
        mu = torch.cos(vz)
        tolerance = 8.0 * input_eps(view_zenith_rad, dtype)
        mu = torch.where((mu < 0.0) & (mu >= -tolerance), torch.zeros_like(mu), mu)
        mu, mu_s = mu.expand(shape), torch.cos(sz).expand(shape)
        dphi = torch.remainder(va - sa + math.pi, 2.0 * math.pi) - math.pi
        phi = torch.abs(dphi).expand(shape)
        nu = torch.clamp(mu * mu_s + torch.sin(vz) * torch.sin(sz) * torch.cos(dphi),
                         -1.0, 1.0).expand(shape)
        corners = self._corners(r, mu, mu_s, phi)
        both = _gather4(self._lookup_table(n), b, corners)
        n_lambda = self.wavelength_nm.shape[0]
        n_single = len(self._phases) * n_lambda
        single = both[..., :n_single].reshape(shape + (len(self._phases), n_lambda))
        total = both[..., n_single:n_single + n_lambda]
        if n > 1:
            i, w = _peak_corners(nu)
            rows = self._peak_shape[n - 1].reshape(-1, n_lambda)
            at = b * _PEAK_NODES + i
            low = torch.index_select(rows, 0, at.reshape(-1)).reshape(shape + (n_lambda,))
            high = torch.index_select(rows, 0, (at + 1).reshape(-1)).reshape(low.shape)
            total = total + both[..., n_single + n_lambda:] * torch.lerp(low, high, w[..., None])
        for k, phase in enumerate(self._phases):
            total = total + phase(nu) * single[..., k, :]
        albedo = self.ground_albedo
        if albedo.requires_grad or bool((albedo != 0).any()):
            total = total + self._reflected_sunlight(b, r.expand(shape), mu, mu_s,
                                                     nu).to(total.dtype)
        return total

    def _reflected_sunlight(self, b, r, mu, mu_s, nu):
        r"""Return the Sun reflected once by the Lambertian ground, at the looked-up geometry.

        On a ray from (r, mu) that meets the ground after a distance d, the ground point
        sees the Sun at :math:`\mu_{s,g} = (r\mu_s + d\nu)/R` and the ray arrives there
        with cosine :math:`\mu_g = (r\mu + d)/R`; the radiance is
        :math:`\frac{\alpha}{\pi}\max(\mu_{s,g}, 0)\,T_\odot(R, \mu_{s,g})\,
        e^{-[\tau(R,-\mu_g) - \tau(r,-\mu)]}`, both optical depths those of upward
        rays to the top (the view path reversed). Computed on the rays that meet the
        ground only, geometry in float64; (..., λ), zero on the other rays.
        """
        shell, res, rows = self._shell, self.resolution, self._depth_rows
        n_lambda = rows.shape[-1]
        shape = r.shape
        r, mu, mu_s, nu = (x.to(torch.float64).reshape(-1) for x in (r, mu, mu_s, nu))
        hits = torch.nonzero(mu < shell.mu_horizon(r)).squeeze(1)
        out = torch.zeros((r.shape[0], n_lambda), dtype=torch.float64)
        if hits.numel() == 0:
            return out.reshape(shape + (n_lambda,))
        b, r, mu, mu_s, nu = (x[hits] for x in (b.reshape(-1), r, mu, mu_s, nu))
        d = shell.distance_ground(r, mu)
        mu_g = torch.clamp((r * mu + d) / shell.R, -1.0, 0.0)
        mu_s_g = torch.clamp((r * mu_s + d * nu) / shell.R, -1.0, 1.0)
        ground = torch.full_like(r, shell.R)
        depth = (_depth_to_top(rows, shell, res, b, ground, -mu_g)
                 - _depth_to_top(rows, shell, res, b, r, -mu)
                 + _depth_to_top(rows, shell, res, b, ground, mu_s_g))
        albedo = self.ground_albedo.to(torch.float64).reshape(-1, n_lambda)[b]
        reflected = albedo * (torch.clamp(mu_s_g, min=0.0) / math.pi)[:, None] * torch.exp(
            -depth)
        return out.index_copy(0, hits, reflected).reshape(shape + (n_lambda,))

    def _batch_index(self, shape):
        """Flat batch index of every point of ``shape`` (batch dims broadcast as usual)."""
        count = max(1, math.prod(self.batch_shape))
        return torch.arange(count).reshape(self.batch_shape).expand(shape)

    def _corners(self, r, mu, mu_s, phi):
        res, shell = self.resolution, self._shell
        ir = _linear(shell.x_of_r(r) * (res.n_r - 1), res.n_r)
        im = _mu_index(shell, r, mu, res.n_mu)
        ims = _linear(shell.mu_s_coordinate(mu_s) * (res.n_mu_s - 1), res.n_mu_s)
        iph = _linear(phi / math.pi * (res.n_phi - 1), res.n_phi)
        return ir, im, ims, iph

    def diffuse_irradiance(self, altitude_m, sun_zenith_rad, *, n_mu: int = 48,
                           n_phi: int = 96, scattering_orders=None) -> torch.Tensor:
        """Horizontal diffuse downward irradiance per unit normal solar irradiance [1].

        The radiance integrated over the upper hemisphere (Gauss-Legendre in the zenith
        cosine with ``n_mu`` nodes, trapezoid in azimuth with ``n_phi``); shape
        (*batch ⊔ ..., wavelength) with ``...`` the broadcast shape of ``altitude_m`` and
        ``sun_zenith_rad``.
        """
        n_mu = check_int("n_mu", n_mu, 1)
        n_phi = check_int("n_phi", n_phi, 2)
        dtype = self._single.dtype
        altitude = check_range("altitude_m", altitude_m, 0.0, self.top_altitude_m, unit=" m",
                               dtype=dtype)
        sun = check_angle("sun_zenith_rad", sun_zenith_rad, MAX_SUN_ZENITH_RAD, dtype)
        x, w = legendre_unit(n_mu)
        mu = torch.tensor(x, dtype=dtype)
        weight = torch.tensor(w, dtype=dtype) * mu * (2.0 * math.pi / n_phi)
        az = torch.arange(n_phi, dtype=dtype) * (2.0 * math.pi / n_phi)
        # the quadrature dims lead: the tables' batch dims broadcast with the trailing ones
        rest = (1,) * max(altitude.ndim, sun.ndim, len(self.batch_shape))
        grid = (altitude[None, None], torch.acos(mu).reshape((n_mu, 1) + rest),
                az.reshape((1, n_phi) + rest), sun[None, None])
        radiance = self.radiance(*grid, scattering_orders=scattering_orders)
        return (radiance * weight.reshape((n_mu, 1) + rest + (1,))).sum((0, 1))


# ---------------------------------------------------------------- precompute
def _flat(tensor, batch_shape, core: int):
    """``tensor`` (*B or 1s, *core) as (b, *core) (b the product of the batch shape)."""
    core_shape = tuple(tensor.shape[tensor.ndim - core:])
    full = tensor.reshape((1,) * max(0, len(batch_shape) + core - tensor.ndim)
                          + tuple(tensor.shape))
    return full.expand(tuple(batch_shape) + core_shape).reshape((-1,) + core_shape)


def _cumulative_trapezoid(values, s):
    """Integral of ``values`` over ``s`` from the first sample to each (trapezoid, last axis)."""
    increment = 0.5 * (s[..., 1:] - s[..., :-1]) * (values[..., 1:] + values[..., :-1])
    return torch.cat([torch.zeros_like(increment[..., :1]), torch.cumsum(increment, -1)], -1)


def _segment_moments(depth):
    r"""Moments of the transmittance across a segment of optical depth ``depth``.

    :math:`E_0 = \int_0^1 e^{-\tau x}\,dx` and :math:`E_1 = \int_0^1 x\,e^{-\tau x}\,dx`,
    with their Taylor series below 1e-3 (the closed forms cancel there), finite with
    finite gradients at 0.
    """
    small = depth < 1e-3
    x = torch.where(small, torch.ones_like(depth), depth)
    loss = -torch.expm1(-x)
    e0 = torch.where(small, 1 - depth / 2 + depth ** 2 / 6 - depth ** 3 / 24, loss / x)
    e1 = torch.where(small, 0.5 - depth / 3 + depth ** 2 / 8 - depth ** 3 / 30,
                     (loss - x * torch.exp(-x)) / (x * x))
    return e0, e1


def exponential_path_weights(step, depth):
    r"""Weights of the samples of a ray for the integral of a source times the transmittance.

    Product integration: between two samples the source :math:`J` is linear and the
    transmittance :math:`T = T_k e^{-\Delta\tau_k x}` exponential in the fraction x of the
    segment, so that :math:`\int T J\,ds = \sum_k h_k T_k [(E_0 - E_1) J_k + E_1 J_{k+1}]`
    (:math:`h_k` the segment's length, :math:`E_{0,1}` the moments of
    :math:`e^{-\Delta\tau_k x}`). Exact for a source linear between the samples however
    thick the segment, where the trapezoid on :math:`T J` overestimates
    (:math:`(1 + e^{-\Delta\tau}) / 2` for :math:`\int_0^1 e^{-\Delta\tau x}dx`: +8 % at
    :math:`\Delta\tau = 1`).

    Parameters
    ----------
    step : Tensor (..., K - 1, 1)
        Lengths of the segments between the K samples [m] (broadcast with ``depth``).
    depth : Tensor (..., K, λ)
        Optical depth from the first sample to each, non-decreasing along K.

    Returns
    -------
    Tensor (..., K, λ)
        The weight of each sample [m], transmittance included.
    """
    increase = depth[..., 1:, :] - depth[..., :-1, :]
    e0, e1 = _segment_moments(increase)
    start = step * torch.exp(-depth[..., :-1, :])
    lower, upper = start * (e0 - e1), start * e1
    zero = torch.zeros_like(lower[..., :1, :])
    return torch.cat([lower, zero], -2) + torch.cat([zero, upper], -2)


def _geometry(tensor, n_batch: int):
    """Geometry ``tensor`` (*shape) with ``n_batch`` leading singleton dims."""
    return tensor.reshape((1,) * n_batch + tuple(tensor.shape))


def _brief(values: torch.Tensor) -> str:
    """Describe values for a message: the number when all are equal, else their range."""
    flat = values.detach().reshape(-1)
    low, high = float(flat.min()), float(flat.max())
    return f"{low:g}" if low == high else f"{low:g}-{high:g}"


def _check_albedo(ground_albedo, batch_shape, n_lambda, dtype):
    if isinstance(ground_albedo, bool) or ground_albedo is None:
        raise TypeError(f"ground_albedo must be a number or a tensor in [0, 1]; got "
                        f"{ground_albedo!r}")
    albedo = check_range("ground_albedo", ground_albedo, 0.0, 1.0, dtype=dtype)
    if albedo.ndim and albedo.shape[-1] not in (1, n_lambda):
        raise ValueError(f"ground_albedo must be a scalar or per wavelength (last dim "
                         f"{n_lambda}); got shape {tuple(albedo.shape)}")
    if albedo.ndim == 0:
        albedo = albedo.reshape(1)
    try:
        shape = torch.broadcast_shapes(tuple(batch_shape) + (n_lambda,), albedo.shape)
    except RuntimeError:
        raise ValueError(f"ground_albedo of shape {tuple(albedo.shape)} does not broadcast "
                         f"with the atmosphere's batch {tuple(batch_shape)} and "
                         f"{n_lambda} wavelengths") from None
    if tuple(shape[:-1]) != tuple(batch_shape):
        raise ValueError(f"ground_albedo of shape {tuple(albedo.shape)} adds batch dims to "
                         f"the atmosphere's {tuple(batch_shape)}")
    return albedo.expand(shape)


def precompute_scattering(atmosphere, wavelength_nm, *, ground_albedo=0.0,  # noqa: C901
                          scattering_orders=4, resolution: TableResolution | None = None,
                          dtype: torch.dtype = torch.float64, max_orders: int = 64,
                          forward_peak: str = "factored") -> ScatteringTables:
    r"""Precompute the orders of scattering of ``atmosphere`` (module docstring: method).

    Parameters
    ----------
    atmosphere : Atmosphere
        Any atmosphere (batched over its parameters: the tables carry its batch dims).
    wavelength_nm : Tensor (wavelength,)
        Wavelengths [nm].
    ground_albedo : float or Tensor (*batch, wavelength)
        Lambertian ground albedo in [0, 1], scalar or spectral.
    scattering_orders : int or "converged"
        Orders to compute (>= 1), or until the last is below :data:`CONVERGENCE_RTOL`
        of the sum or the sum with its remainder extrapolated as a geometric series
        changes by less than :data:`CONVERGENCE_RTOL` of each Sun-zenith node's sum (at
        most ``max_orders``; :attr:`ScatteringTables.converged` says whether it was
        reached, :attr:`ScatteringTables.remainder_extrapolated` whether the tables hold
        the remainder). Against the series carried to 40 orders the converged sky is
        within 8.4e-4 from the Sun at 20 deg to 18 deg below the horizon, where stopping
        at the last order below 1e-4 of the sum left 0.5-1.5 %
        (experiments/converged_orders_accuracy_cost.py).
    resolution : TableResolution, optional
        Table sizes (default :class:`TableResolution()`).
    dtype : torch.dtype
        float64 or float32: the dtype of the stored tables and of the look-ups. The
        geometry, the optical depths and the transmittances along the view rays are
        always computed in float64; the ray integrals (order 1 and, most of the cost, the
        orders >= 2) in ``dtype``: float32 builds the tables 1.4-1.9 times faster; its
        ray integrals of the orders >= 2 alone change the radiance by 5e-8 relative, the
        float32 look-ups by 2e-5 (up to 1.4e-4 for order 1 alone in deep twilight;
        docs/multiple_scattering.md).
    forward_peak : {"factored", "none"}
        How the orders >= 2 are interpolated between the table's nodes. ``"factored"``:
        divided at the nodes by the angular shape of light scattered n times by the
        column's mean phase function (:func:`forward_peak_shapes`), interpolated, and
        multiplied by that shape at the looked-up scattering angle, so that the
        multiply-scattered aureole follows the Sun instead of being smeared across the
        nodes (the same for the sources looked up along the table's rays); ``"none"``:
        interpolated as they are. Light reflected by the ground is followed apart and
        never factored. Against DISORT (aerosol optical depth 0.3, default tables) the
        sky's largest error goes from 18 % to 2.5 % (docs/multiple_scattering_validation.md).

    Returns
    -------
    ScatteringTables

    Notes
    -----
    Cost grows as ``n_r * n_mu * n_mu_s * n_phi * n_ray * wavelength`` per order (the
    ray integrals) plus the sphere quadrature; the default resolution takes about 8 s per
    order for 3 wavelengths (33 s for 4 orders, 2 threads), Bruneton 2017's sizes
    (``TableResolution.bruneton2017()``) 48-50 s for 4 orders of 15 wavelengths in float32 on
    2 cores
    (benchmarks/bench_multiple_scattering.py, docs/benchmarks.md).
    """
    check_atmosphere("atmosphere", atmosphere)
    if forward_peak not in ("factored", "none"):
        raise ValueError(f"forward_peak must be 'factored' or 'none'; got {forward_peak!r}")
    if dtype not in (torch.float32, torch.float64):
        raise ValueError(f"dtype must be torch.float32 or torch.float64; got {dtype}")
    if isinstance(scattering_orders, str):
        if scattering_orders != "converged":
            raise ValueError("scattering_orders must be an integer >= 1 or 'converged'; "
                             f"got {scattering_orders!r}")
        target = check_int("max_orders", max_orders, 1)
    else:
        target = check_int("scattering_orders", scattering_orders, 1, None)
    resolution = TableResolution() if resolution is None else resolution
    if not isinstance(resolution, TableResolution):
        raise TypeError(f"resolution must be a TableResolution; got "
                        f"{type(resolution).__name__}")
    res = resolution
    # the tables are built in float64 (the r^2 - R^2 geometry and long columns cancel in
    # float32) and stored in ``dtype``
    table_dtype, dtype = dtype, torch.float64
    # the ray integrals (order 1 along every ray of the table, and the orders >= 2 with
    # their sources looked up along them: most of the cost) in the stored dtype
    ray_dtype = table_dtype
    wavelength = wavelength_tensor(wavelength_nm, dtype)
    constituents = atmosphere.constituents(wavelength, dtype)
    shape_b = constituents.batch_shape
    nb = len(shape_b)
    b = max(1, math.prod(shape_b))
    n_lambda = wavelength.shape[0]
    albedo = _flat(_check_albedo(ground_albedo, shape_b, n_lambda, dtype), shape_b, 1)
    shell = _Shell(constituents.planet_radius_m, constituents.top_radius_m,
                   res.mu_vertical_weight, res.r_ground_weight)

    def tens(values):
        return torch.as_tensor(values, dtype=dtype)

    # --- transmittance table tau(r, mu) to the top (rays meeting the ground: shadow)
    xr = torch.linspace(0.0, 1.0, res.transmittance_r, dtype=dtype)
    r_t = shell.r_of(xr)[:, None]
    ut = torch.linspace(0.0, 1.0, res.transmittance_mu, dtype=dtype)[None, :]
    mu_t = shell.mu_of(r_t, ut, ground=False)
    cols = constituents.column_integrals(_geometry(r_t.expand_as(mu_t), nb),
                                         _geometry(mu_t, nb), extra=2)
    tau_table = _flat(constituents.optical_depth(cols, extra=2), shape_b, 3)  # (b, r, mu, λ)
    # its rows (b * r * mu, λ) in float64 and in the ray dtype
    tau_rows = {dt: tau_table.reshape(-1, n_lambda).to(dt) for dt in (dtype, ray_dtype)}

    def sun_transmittance(bi, r, mu, out_dtype=dtype):
        """exp(-tau) to the Sun (b, ...,) -> (..., λ) in ``out_dtype``; zero in the shadow.

        The geometry in float64 (``r`` near the ground cancels in float32).
        """
        tau = _depth_to_top(tau_rows[out_dtype], shell, res, bi, r, mu)
        lit = (mu >= shell.mu_horizon(r))[..., None]
        return torch.where(lit, torch.exp(-tau), torch.zeros_like(tau))

    # --- table nodes
    r_nodes = shell.r_of(torch.linspace(0.0, 1.0, res.n_r, dtype=dtype))           # (n_r)
    half = res.n_mu // 2
    u = torch.linspace(0.0, 1.0, half, dtype=dtype)
    mu_g = shell.mu_of(r_nodes[:, None], u[None, :], ground=True)                  # -1 -> h
    mu_sky = shell.mu_of(r_nodes[:, None], u.flip(0)[None, :], ground=False)       # h -> 1
    mu_nodes = torch.cat([mu_g, mu_sky], dim=1)                                    # (n_r, n_mu)
    ground_ray = torch.cat([torch.ones(half, dtype=torch.bool),
                            torch.zeros(half, dtype=torch.bool)])
    mu_s_nodes = shell.mu_s_of(torch.linspace(0.0, 1.0, res.n_mu_s, dtype=dtype))  # (n_mu_s)
    phi_nodes = torch.linspace(0.0, math.pi, res.n_phi, dtype=dtype)                # (n_phi)

    # --- view rays of the table: samples, transmittance, local scattering
    rr, mm = r_nodes[:, None], mu_nodes
    length = torch.where(ground_ray[None, :], shell.distance_ground(rr, mm),
                         shell.distance_top(rr, mm))                                # (n_r, n_mu)
    # samples clustered at the observer (rays to the sky: density falls away from it) and
    # at both ends of rays to the ground (smoothstep), as the single-scattering kernel
    t = torch.linspace(0.0, 1.0, res.n_ray, dtype=dtype)
    spacing = torch.where(ground_ray[:, None], 3 * t * t - 2 * t ** 3, t * t)       # (mu, K)
    s = length[..., None] * spacing                                                 # (r, mu, K)
    r_s = torch.sqrt(torch.clamp(rr[..., None] ** 2 + s * s + 2 * rr[..., None] * s
                                 * mm[..., None], min=shell.R ** 2))
    r_s = torch.clamp(r_s, max=shell.Rt)
    mu_view_s = torch.clamp((rr[..., None] * mm[..., None] + s) / r_s, -1.0, 1.0)
    height = r_s - shell.R
    densities = constituents.densities(_geometry(height, nb), extra=2)
    step = (s[..., 1:] - s[..., :-1])
    exponential = res.ray_quadrature == "exponential"
    if exponential:
        # the columns between the samples from sub-samples of each segment (the trapezoid
        # on the samples alone overestimates a density that falls along the ray)
        fraction = torch.arange(_COLUMN_SUBSAMPLES, dtype=dtype) / _COLUMN_SUBSAMPLES
        s_fine = torch.cat([(s[..., :-1, None] + step[..., None] * fraction).flatten(-2),
                            s[..., -1:]], -1)
        r_fine = torch.sqrt(torch.clamp(rr[..., None] ** 2 + s_fine * s_fine + 2 * rr[..., None]
                                        * s_fine * mm[..., None], min=shell.R ** 2))
        fine = constituents.densities(_geometry(torch.clamp(r_fine, max=shell.Rt) - shell.R,
                                                nb), extra=2)
        columns = {name: _cumulative_trapezoid(density, s_fine)[..., ::_COLUMN_SUBSAMPLES]
                   for name, density in fine.items()}
        del fine
    else:
        columns = {name: _cumulative_trapezoid(density, s) for name, density in densities.items()}
    depth_view = constituents.optical_depth(columns, extra=3)
    t_view = _flat(torch.exp(-depth_view), shape_b, 4)
    scatterers = [sp for sp in constituents.scatterers() if not sp.vanishes]
    beta_s = [_flat(densities[sp.name][..., None] * _geometry(sp.scattering, 0).reshape(
        tuple(sp.scattering.shape[:-1]) + (1, 1, 1, n_lambda)), shape_b, 4)
        for sp in scatterers]                                        # (b, r, mu, K, λ)
    zero = torch.zeros_like(step[..., :1])
    ds = 0.5 * (torch.cat([step, zero], -1) + torch.cat([zero, step], -1))  # trapezoid (r, mu, K)
    # weight of each sample in the integral of (source x transmittance) along the ray
    if exponential:
        path_weight = _flat(exponential_path_weights(
            _geometry(step, nb).unsqueeze(-1), depth_view), shape_b, 4)
    else:
        path_weight = t_view * ds[None, ..., None]                    # (b, r, mu, K, λ)
    del depth_view

    # per (r, mu, K) x (mu_s, phi): the Sun's cosine at the samples
    nu_nodes = torch.clamp(mm[..., None, None] * mu_s_nodes[:, None]
                           + torch.sqrt(1 - mm * mm)[..., None, None]
                           * torch.sqrt(1 - mu_s_nodes ** 2)[:, None]
                           * torch.cos(phi_nodes), -1.0, 1.0)        # (r, mu, mu_s, phi)

    def sample_sun(i, k=slice(None), rows=slice(None)):
        """mu_s at the samples ``k`` of the rays ``rows`` from r node ``i``.

        Shape (mu, K, mu_s, phi), or (mu, mu_s, phi) for an integer ``k``.
        """
        nu = nu_nodes[i][rows]
        if not isinstance(k, int):
            nu = nu[:, None]
        return torch.clamp((r_nodes[i] * mu_s_nodes[:, None] + s[i][rows, k][..., None, None]
                            * nu) / r_s[i][rows, k][..., None, None], -1.0, 1.0)

    def ray_chunks(channels):
        """Blocks of the table's ray samples whose temporaries stay within a budget.

        Per slice of the mu axis, the slices of the samples along the rays (all of them
        when a whole ray fits): ``[(rows, [k, ...]), ...]``. The ray integrals'
        element-wise work on ``channels`` values per (sample, mu_s, phi) then stays in
        the caches (on whole radii it ran 4-10 times slower per element). The budget is
        per parameter set, which the look-ups take one at a time (:func:`_gather_rays`).
        """
        per_sample = res.n_mu_s * res.n_phi * channels
        samples = max(1, _BUDGET // per_sample)
        if samples >= res.n_ray:
            step = samples // res.n_ray
            return [(slice(m, min(m + step, res.n_mu)), [slice(None)])
                    for m in range(0, res.n_mu, step)]
        ks = [slice(k, min(k + samples, res.n_ray)) for k in range(0, res.n_ray, samples)]
        return [(slice(m, m + 1), ks) for m in range(res.n_mu)]

    def along_rays(integrand, i, channels):
        """Sum of ``integrand(i, rows, k)`` over the blocks of :func:`ray_chunks`.

        The integrand returns its sum over the samples ``k`` of the rays ``rows``
        (b, rows, ...); the blocks are joined along the mu axis.
        """
        return torch.cat([sum(integrand(i, rows, k) for k in ks)
                          for rows, ks in ray_chunks(channels)], dim=1)

    # per block of ray samples, what the integrals of every order share: the look-up's
    # plan and the samples' weights (computed at the first order that needs them and
    # kept while they fit :data:`_GEOMETRY_BUDGET`; the rest are computed at each order)
    ray_geometry = {}
    kept = [0]
    ray_scratch = Scratch()

    def geometry_along_rays(i, rows, k):
        """Corners in the J table and weights of the samples ``k`` of the rays ``rows``.

        Returns the plan of :func:`_gather_rays` (:func:`_ray_plan`) and the weight
        (b, mu, K, 1, 1, 1, S, λ) of each sample and species (scattering coefficient x
        transmittance x trapezoid weight), in the ray dtype.
        """
        key = (i, rows.start, rows.stop, k.start, k.stop)
        if key in ray_geometry:
            return ray_geometry[key]
        geometry = sample_geometry(i, rows, k)
        size = geometry[0][2].numel()
        if kept[0] + size <= _GEOMETRY_BUDGET:
            ray_geometry[key] = geometry
            kept[0] += size
        return geometry

    def sample_geometry(i, rows, k):
        """:func:`geometry_along_rays` computed."""
        mus_s = sample_sun(i, k, rows)                              # (mu, K, ms, phi)
        mv = mu_view_s[i][rows, k]                                  # (mu, K)
        mv4 = mv[:, :, None, None]
        nu = nu_nodes[i][rows][:, None]
        denom = torch.sqrt(torch.clamp((1 - mv4 * mv4) * (1 - mus_s * mus_s), min=1e-30))
        phi_s = torch.acos(torch.clamp((nu - mv4 * mus_s) / denom, -1.0, 1.0))
        cr = _linear(shell.x_of_r(r_s[i][rows, k]) * (res.n_r - 1), res.n_r)
        pos = torch.clamp(torch.searchsorted(mu_q, mv.contiguous()) - 1, 0,
                          mu_q.shape[0] - 2)
        wmu = torch.clamp((mv - mu_q[pos]) / (mu_q[pos + 1] - mu_q[pos]), 0.0, 1.0)
        cms = _linear(shell.mu_s_coordinate(mus_s) * (res.n_mu_s - 1), res.n_mu_s)
        cph = _linear(phi_s / math.pi * (res.n_phi - 1), res.n_phi)
        # per sample and species: scattering coefficient x transmittance x trapezoid weight
        weight = path_weight[:, i, rows, k][:, :, :, None, :]
        if beta_s:
            weight = torch.stack([bs[:, i, rows, k] for bs in beta_s], -2) * weight
        else:
            weight = torch.zeros_like(weight)
        plan = _ray_plan((_weights_as(cr, ray_dtype), _weights_as((pos, wmu), ray_dtype)),
                         (_weights_as(cms, ray_dtype), _weights_as(cph, ray_dtype)),
                         res.n_r, 2 * res.n_sphere_mu, res.n_mu_s, res.n_phi)
        return plan, weight[:, :, :, None, None, None].to(ray_dtype)

    def scattered_along_rays(j_table, n_c, n_s, i, rows, k):
        """Integral of T J over the samples ``k`` of the rays ``rows`` from r node ``i``.

        ``j_table`` (b, r, q, ms, phi, c * S * λ) in the ray dtype; returns
        (b, mu, ms, phi, c, λ) in float64.
        """
        plan, weight = geometry_along_rays(i, rows, k)
        # no gradient recorded: the look-ups' temporaries are buffers reused by every call
        scratch = None if torch.is_grad_enabled() and (
            j_table.requires_grad or weight.requires_grad) else ray_scratch
        sets = []
        # one parameter set at a time: the looked-up J of a whole batch outgrows the caches
        for p in range(j_table.shape[0]):
            jv = _gather_rays(j_table[p:p + 1], plan, scratch)
            jv = jv.reshape(jv.shape[:-1] + (n_c, n_s, n_lambda))
            w = weight[p:p + 1] if weight.shape[0] > 1 else weight
            # the sum over the samples as one multiply-add per sample: a reduction over the
            # strided sample axis of the product took 8 times as long
            total = torch.mul(jv[:, :, 0], w[:, :, 0], out=None if scratch is None else scratch(
                "total", torch.broadcast_shapes(jv[:, :, 0].shape, w[:, :, 0].shape), jv.dtype))
            for sample in range(1, jv.shape[2]):
                total.addcmul_(jv[:, :, sample], w[:, :, sample])
            sets.append(total.sum(-2))
        return torch.cat(sets).to(dtype)                            # (b, mu, ms, phi, c, λ)

    def single_along_rays(i, rows, k):
        """Single scattering per species (no phase) over some samples of some rays.

        The samples ``k`` of the rays ``rows`` from r node ``i``: (b, mu, ms, phi, S, λ)
        in float64.
        """
        mus_s = sample_sun(i, k, rows)                              # (mu, K, ms, phi)
        t_sun = sun_transmittance(torch.arange(b)[:, None, None, None, None],
                                  r_s[i][rows, k][None, :, :, None, None], mus_s[None],
                                  ray_dtype)
        # (b, mu, K, ms, phi, λ) in the ray dtype
        path = t_sun * path_weight[:, i, rows, k].to(ray_dtype)[:, :, :, None, None, :]
        return torch.stack([(beta[:, i, rows, k].to(ray_dtype)[:, :, :, None, None, :] * path)
                            .sum(2).to(dtype) for beta in beta_s], dim=-2)

    # --- order 1: single scattering per species (no phase) and the Sun off the ground
    single_parts, ground1 = [], []
    for i in range(res.n_r):
        single_parts.append(
            along_rays(single_along_rays, i, len(beta_s) * n_lambda) if beta_s
            else torch.zeros((b, res.n_mu, res.n_mu_s, res.n_phi, 0, n_lambda), dtype=dtype))
        mus_g = sample_sun(i, -1)                                    # (mu, ms, phi)
        e0 = torch.clamp(mus_g, min=0.0)[..., None] * sun_transmittance(
            torch.arange(b)[:, None, None, None],
            torch.full((b,) + mus_g.shape, shell.R, dtype=dtype), mus_g.expand((b,) + mus_g.shape))
        g = (ground_ray[None, :, None, None, None] * t_view[:, i, :, -1][:, :, None, None, :]
             * albedo[:, None, None, None, :] / math.pi * e0)
        ground1.append(g)
    single = torch.stack(single_parts, dim=1)                        # (b, r, mu, ms, phi, S, λ)
    ground1 = torch.stack(ground1, dim=1)                            # (b, r, mu, ms, phi, λ)

    # --- sphere quadrature and the discrete phase operators
    xq, wq = legendre_signed(res.n_sphere_mu)
    mu_q = tens(np.concatenate([0.5 * (xq - 1.0), 0.5 * (xq + 1.0)]))
    w_q = tens(np.concatenate([0.5 * wq, 0.5 * wq]))
    # the sphere's azimuths: the table's azimuth nodes mirrored to the full circle, each
    # interval divided into ``sphere_phi_refinement`` (the previous order interpolated
    # between the table's azimuths with its peak shape factored out, as along the rays)
    refine = res.sphere_phi_refinement
    n_full = 2 * (res.n_phi - 1) * refine
    phi_full = torch.arange(n_full, dtype=dtype) * (math.pi / ((res.n_phi - 1) * refine))
    sin_q = torch.sqrt(1 - mu_q * mu_q)
    cos_theta = torch.clamp(
        mu_q[:, None, None, None] * mu_q[None, None, :, None]
        + sin_q[:, None, None, None] * sin_q[None, None, :, None]
        * torch.cos(phi_full[None, :, None, None] - phi_full[None, None, None, :]),
        -1.0, 1.0)                                                   # (q, m, q', m')
    n_out, n_in = 2 * res.n_sphere_mu * res.n_phi, 2 * res.n_sphere_mu * n_full
    w_in = (w_q[:, None] * (2 * math.pi / n_full)).expand(2 * res.n_sphere_mu, n_full)
    # output rows: the table's azimuths [0, pi] (every ``refine``-th of the circle's first half)
    rows = (torch.arange(2 * res.n_sphere_mu)[:, None] * n_full
            + refine * torch.arange(res.n_phi)[None, :]).reshape(-1)
    operators = []
    for sp in scatterers:
        p = sp.phase(_geometry(cos_theta, nb), extra=4)             # (*B?, q, m, q', m', λ?)
        p = p.reshape(tuple(p.shape[:-5]) + (n_in, n_in, p.shape[-1]))
        k = balanced_phase_operator(p, w_in.reshape(-1))[..., rows, :, :]
        lead = k.shape[:-3]
        k = k.reshape((-1,) + tuple(k.shape[-3:])) if lead else k[None]
        operators.append(k.permute(0, 3, 2, 1))                     # (b?, λ?, n_in, n_out)
    # interpolation of the table's mu axis onto the quadrature nodes at each r node
    iq, wq_ = _mu_index(shell, r_nodes[:, None].expand(-1, mu_q.shape[0]),
                        mu_q[None, :].expand(res.n_r, -1), res.n_mu)
    ar = torch.arange(res.n_r)[:, None]
    up = mu_q > 0
    sin_s = torch.sqrt(torch.clamp(1 - mu_s_nodes ** 2, min=0.0))
    # view-Sun cosines of the quadrature directions (q, ms, m) and of the J table (q, ms, phi)
    nu_q = torch.clamp(mu_q[:, None, None] * mu_s_nodes[None, :, None]
                       + sin_q[:, None, None] * sin_s[None, :, None]
                       * torch.cos(phi_full)[None, None, :], -1.0, 1.0)
    nu_j = nu_q[:, :, :(res.n_phi - 1) * refine + 1:refine]

    def phase_at(sp, cosine):
        """Phase of ``sp`` at the geometry ``cosine`` (*g): (b, *g, λ)."""
        p = sp.phase(_geometry(cosine, nb), extra=cosine.ndim)
        return _flat(p.expand(tuple(p.shape[:-1]) + (n_lambda,)), shape_b, cosine.ndim + 1)

    def phase_on_nodes():
        """Exact phases at the table's nu nodes: (b, r, mu, ms, phi, S, λ)."""
        return torch.stack([phase_at(sp, nu_nodes) for sp in scatterers], dim=-2)

    def column_phase_moments():
        """Legendre moments of the vertical column's mean phase function (b, λ, l).

        The species' phase functions weighted by their scattering optical depths from the
        ground to the top (the zenith ray of the lowest r node); isotropic (1, 0, ...)
        where nothing scatters or with ``forward_peak="none"``.
        """
        isotropic = torch.zeros((b, n_lambda, _PEAK_TERMS + 1), dtype=dtype)
        isotropic[..., 0] = 1.0
        if forward_peak == "none" or not scatterers:
            return isotropic
        xg, wg = (torch.tensor(v, dtype=dtype) for v in legendre_signed(2 * _PEAK_TERMS))
        legendre = _legendre(xg, _PEAK_TERMS) * wg                      # (l, G)
        total, depth = 0.0, 0.0
        for k, sp in enumerate(scatterers):
            weight = (beta_s[k][:, 0, -1] * ds[0, -1][None, :, None]).sum(1)  # (b, λ)
            chi = 2 * math.pi * torch.einsum("bgl,ng->bln", phase_at(sp, xg), legendre)
            total = total + weight[..., None] * chi / chi[..., :1]
            depth = depth + weight[..., None]
        return torch.where(depth > 0, total / torch.where(depth > 0, depth, 1.0), isotropic)

    shapes = {}
    # the Legendre polynomials at the peak-shape nodes, once for all orders
    peak_legendre = _legendre(_peak_nodes(dtype), _PEAK_TERMS)

    def peak(order, nu):
        """Shape of ``order`` scatterings at the cosines ``nu`` (*g): (b, *g, λ)."""
        if order not in shapes:
            shapes[order] = _peak_shapes(moments, [order], peak_legendre)[0].transpose(1, 2)
        return _peak_at(shapes[order], nu)

    moments = column_phase_moments()

    if scatterers:
        field = (single * phase_on_nodes()).sum(-2) + ground1
    else:
        field = ground1

    # the quadrature's azimuths between the table's nodes around the circle (periodic), each
    # node of the circle mirrored onto the table's half circle [0, pi]
    n_nodes_full = 2 * (res.n_phi - 1)
    node_low = torch.arange(n_full) // refine
    node_high = (node_low + 1) % n_nodes_full
    phi_low, phi_high = (torch.where(j < res.n_phi, j, n_nodes_full - j)
                         for j in (node_low, node_high))
    phi_weight = (torch.arange(n_full) % refine).to(dtype) / refine

    def on_quadrature(table):
        """``table`` (b, r, mu, ms, phi, ...) at the quadrature directions, phi mirrored.

        Linear in mu, then in azimuth between the table's nodes (two interpolations,
        one gather per corner).
        """
        extra = (None,) * (table.ndim - 5)
        lq = torch.lerp(table[:, ar, iq], table[:, ar, iq + 1],
                        wq_[(None, slice(None), slice(None), None, None) + extra].to(table.dtype))
        if refine == 1:
            return lq[:, :, :, :, phi_low]
        return torch.lerp(lq[:, :, :, :, phi_low], lq[:, :, :, :, phi_high],
                          phi_weight[(slice(None),) + extra].to(table.dtype))

    def single_at_quadrature():
        """Single scattering at the quadrature directions (b, r, q, ms, m, λ), exact phases.

        The phase-free single scattering is smooth in the view direction and is
        interpolated; the phase is evaluated at each quadrature direction's own
        scattering angle, so that the aureole is not smeared across the table's nodes.
        """
        out = torch.zeros_like(on_quadrature(ground1))
        if not scatterers:
            return out
        s_q = on_quadrature(single)                                  # (b, r, q, ms, m, S, λ)
        for k, sp in enumerate(scatterers):
            out = out + s_q[..., k, :] * phase_at(sp, nu_q)[:, None]
        return out

    def ground_irradiance_single(n_mu_fine=32, n_phi_fine=64):
        """Diffuse irradiance of order 1 at the ground (b, ms, λ), fine quadrature.

        The aureole of a forward-peaked phase function is not resolved by the sphere
        quadrature; its irradiance is integrated on a finer grid (the phase-free
        single scattering interpolated in mu and phi, the phase exact).
        """
        if not scatterers:
            return torch.zeros((b, res.n_mu_s, n_lambda), dtype=dtype)
        xf, wf = legendre_unit(n_mu_fine)
        mu_f = torch.tensor(xf, dtype=dtype)
        w_f = torch.tensor(wf, dtype=dtype) * mu_f * (2 * math.pi / n_phi_fine)
        phi_f = (torch.arange(n_phi_fine, dtype=dtype) + 0.5) * (2 * math.pi / n_phi_fine)
        r0 = r_nodes[:1].expand(n_mu_fine)
        im_f, wm_f = _mu_index(shell, r0, mu_f, res.n_mu)
        fold = math.pi - torch.abs(phi_f - math.pi)                  # |phi| in [0, pi]
        ip_f, wp_f = _linear(fold / math.pi * (res.n_phi - 1), res.n_phi)
        s0 = single[:, 0]                                            # (b, mu, ms, phi, S, λ)
        s_mu = (s0[:, im_f] * (1 - wm_f)[None, :, None, None, None, None]
                + s0[:, im_f + 1] * wm_f[None, :, None, None, None, None])  # (b, qf, ms, phi, S, λ)
        s_f = (s_mu[:, :, :, ip_f] * (1 - wp_f)[None, None, None, :, None, None]
               + s_mu[:, :, :, ip_f + 1] * wp_f[None, None, None, :, None, None])
        nu_f = torch.clamp(mu_f[:, None, None] * mu_s_nodes[None, :, None]
                           + torch.sqrt(1 - mu_f ** 2)[:, None, None] * sin_s[None, :, None]
                           * torch.cos(phi_f)[None, None, :], -1.0, 1.0)  # (qf, ms, mf)
        total = 0.0
        for k, sp in enumerate(scatterers):
            total = total + (s_f[..., k, :] * phase_at(sp, nu_f)
                             * w_f[None, :, None, None, None]).sum((1, 3))
        return total
    level_sum = field.detach().abs().sum()
    reference = level_sum if float(level_sum) > 0 else torch.tensor(1.0, dtype=dtype)
    # per level (orders <= n): the ground's reflections of diffuse light, and the light
    # scattered in the atmosphere by the orders 2..n (divided by the peak shape of order 2
    # at the nodes); the Sun reflected once by the ground (``ground1``, the source of
    # order 2) is not stored: the tables compute it at each look-up
    # (:meth:`ScatteringTables._reflected_sunlight`), since interpolating it across the
    # terminator, where it has a kink, overestimates it (+1.1 % of the light leaving the
    # top on the default tables)
    cumulative = [torch.zeros_like(ground1)]
    # the light reflected by the ground is followed apart (not peaked towards the Sun);
    # without the factor both parts are interpolated alike and travel together
    black_ground = not (bool((albedo != 0).any()) or albedo.requires_grad)
    with_ground = forward_peak == "factored" and not black_ground
    scattered_sum = [torch.zeros_like(ground1)]
    # per level, the stored shape: the orders' shapes weighted by their sizes (b, nodes, λ)
    level_weights = [torch.zeros((b, n_lambda), dtype=dtype)]
    level_shapes = [torch.zeros((b, _PEAK_NODES, n_lambda), dtype=dtype)]
    contributions = [torch.tensor(1.0, dtype=dtype)]
    # per parameter set: order 1's size and each order's relative to it (the stopping rule
    # of the last order below CONVERGENCE_RTOL of the sum holds for every member: the
    # whole batch's sum let a slowly converging member stop short of its remainder)
    member_reference = field.detach().abs().reshape(b, -1).sum(1)
    member_reference = torch.where(member_reference > 0, member_reference, 1.0)
    member_sizes = [torch.ones(b, dtype=dtype)]
    converged = False
    sky = ground = None                      # the last order's two parts
    # the orders beyond the last extrapolated as a geometric series ("converged" only)
    remainder = previous_remainder = previous_sky = previous_ground = None
    while len(cumulative) < target:
        order = len(cumulative) + 1
        # radiance of the last order at the quadrature directions, phi mirrored, and its
        # irradiance at the ground (r node 0), as [light from the Sun scattered in the
        # atmosphere only | light reflected by the ground on its way]; the first is
        # interpolated in mu with the peak shape of its order factored out
        # (a black ground without gradient reflects nothing: its part is zero, not computed)
        if order == 2:
            parts = [single_at_quadrature(), None if black_ground else on_quadrature(ground1)]
        else:
            parts = [on_quadrature(sky / peak(order - 1, nu_nodes))
                     * peak(order - 1, nu_q)[:, None],
                     None if black_ground else on_quadrature(ground)]
        if with_ground:
            lq = torch.stack(parts)
        else:
            lq = (parts[0] if parts[1] is None else parts[0] + parts[1])[None]
        if order == 2:
            e_prev = ground_irradiance_single()                      # (b, ms, λ)
        else:
            e_prev = (lq[:, :, 0][:, :, up] * (w_q[up] * mu_q[up])[None, None, :, None, None,
                                                                 None]
                      ).sum((0, 2, 4)) * (2 * math.pi / n_full)
        n_c = lq.shape[0]
        lin = lq.permute(0, 1, 6, 2, 4, 3, 5).reshape(
            n_c, b, n_lambda, res.n_r * res.n_mu_s, n_in)
        # per species the phase-weighted mean radiance (smooth in r); its scattering
        # coefficient is applied at each sample's own altitude (exact vertical profile)
        parts = [torch.matmul(lin, op).reshape(n_c, b, n_lambda, res.n_r, res.n_mu_s, n_out)
                 for op in operators]
        n_s = max(1, len(parts))
        if not parts:
            parts = [torch.zeros((n_c, b, n_lambda, res.n_r, res.n_mu_s, n_out), dtype=dtype)]
        j_table = torch.stack(parts, 2).reshape(
            n_c, b, n_s, n_lambda, res.n_r, res.n_mu_s, 2 * res.n_sphere_mu, res.n_phi
        ).permute(1, 4, 6, 5, 7, 0, 2, 3)              # (b, r, q, ms, phi, c, S, λ)
        # the Sun's source with the peak shape of this order factored out (restored per
        # ray: the view-Sun angle is constant along a straight ray)
        divisor = torch.ones((1,) * 5 + (n_c, 1, 1), dtype=dtype)
        peak_j = peak(order, nu_j)
        divisor = divisor * torch.stack([peak_j] + [torch.ones_like(peak_j)] * (n_c - 1),
                                        -2)[:, None, :, :, :, :, None]
        # contiguous: each block of the ray integrals views its (r, mu) rows
        j_table = (j_table / divisor).flatten(-3).to(ray_dtype).contiguous()
        nxt_sky, nxt_ground = [], []
        for i in range(res.n_r):
            ray = along_rays(functools.partial(scattered_along_rays, j_table, n_c, n_s), i,
                             n_c * n_s * n_lambda)
            nxt_sky.append(ray[..., 0, :] * peak(order, nu_nodes[i]))
            mus_g = sample_sun(i, -1)                               # (mu, ms, phi)
            eg = _linear(shell.mu_s_coordinate(mus_g) * (res.n_mu_s - 1), res.n_mu_s)
            e_at = _geometric(e_prev[:, eg[0]], e_prev[:, eg[0] + 1], eg[1][None, ..., None])
            reflected = (ground_ray[None, :, None, None, None]
                         * t_view[:, i, :, -1][:, :, None, None, :]
                         * albedo[:, None, None, None, :] / math.pi * e_at)
            nxt_ground.append(reflected + ray[..., 1, :] if with_ground else reflected)
        sky, ground = torch.stack(nxt_sky, dim=1), torch.stack(nxt_ground, dim=1)
        cumulative.append(cumulative[-1] + ground)
        scattered_sum.append(scattered_sum[-1] + sky)
        peak(order, nu_q[:1, :1, :1])
        weight = sky.abs().sum((1, 2, 3, 4))                                # (b, λ)
        level_shapes.append(level_shapes[-1] + weight[:, None] * shapes[order])
        level_weights.append(level_weights[-1] + weight)
        size = (sky + ground).detach().abs().sum() / reference
        contributions.append(size.to(dtype))
        if order >= 4 and float(contributions[-1]) > float(contributions[-2]) > float(
                contributions[-3]):
            # an order of scattering holds less light than the one before it in a
            # physical atmosphere: two growing orders are the tables' error, not light
            shown = ", ".join(f"{float(c):.3g}" for c in contributions)
            raise ValueError(
                f"the orders of scattering grow ({shown} of order 1): the tables' rays "
                f"sample this atmosphere too coarsely (n_ray {res.n_ray}, ray_quadrature "
                f"{res.ray_quadrature!r}); use ray_quadrature='exponential' or more n_ray")
        member_sizes.append((sky + ground).detach().abs().reshape(b, -1).sum(1).to(dtype)
                            / member_reference)
        if _last_order_negligible(member_sizes):
            converged = True
            if isinstance(scattering_orders, str):
                remainder = None
                break
        if isinstance(scattering_orders, str) and order >= 3:
            previous_remainder, remainder = remainder, _geometric_remainder(
                sky, ground, previous_sky, previous_ground)
            if remainder is not None and previous_remainder is not None:
                # change of the extrapolated sum from the last order to this one
                change = (sky + ground + remainder[0] + remainder[1] - previous_remainder[0]
                          - previous_remainder[1]).detach().abs().sum((1, 2, 4))
                level = (cumulative[-1] + scattered_sum[-1]).detach().abs().sum((1, 2, 4))
                if bool((change <= CONVERGENCE_RTOL * level).all()):
                    converged = True
                    break
        previous_sky, previous_ground = sky, ground
    if remainder is not None and converged:
        # the remainder as one more level, with the peak shape of the last order
        cumulative.append(cumulative[-1] + remainder[1])
        scattered_sum.append(scattered_sum[-1] + remainder[0])
        weight = remainder[0].abs().sum((1, 2, 3, 4))
        level_shapes.append(level_shapes[-1] + weight[:, None] * shapes[order])
        level_weights.append(level_weights[-1] + weight)
    if not isinstance(scattering_orders, str):
        converged = converged or _last_order_negligible(member_sizes)

    n_s = len(scatterers)
    single_flat = single.reshape(single.shape[:5] + (n_s * n_lambda,))
    # the looked-up sums of the orders >= 2 with their peak shapes factored out
    peak(2, nu_q[:1, :1, :1])
    level_shapes = [torch.where(weight[:, None] > 0, shape / torch.where(
        weight > 0, weight, 1.0)[:, None], shapes[2])
        for shape, weight in zip(level_shapes, level_weights, strict=True)]

    stored = atmosphere.constituents(wavelength.to(table_dtype), table_dtype)
    stored_phase = {sp.name: sp for sp in stored.scatterers()}

    def level_table(ground_part, scattered, shape):
        """[ground's reflections | scattered / its peak shape] of one level (tables' dtype)."""
        return torch.cat([ground_part, scattered / _peak_at(shape, nu_nodes)], -1).to(
            table_dtype)

    def make_phase(sp):
        def phase(nu):
            # the parameters' batch dims broadcast with the geometry (as everywhere)
            p = sp.phase(nu, 0)
            return p.expand(tuple(p.shape[:-1]) + (n_lambda,))
        return phase

    return ScatteringTables(shell=shell, resolution=res,
                            wavelength_nm=wavelength.to(table_dtype),
                            batch_shape=shape_b, single=single_flat.to(table_dtype),
                            phases=[make_phase(stored_phase[sp.name]) for sp in scatterers],
                            levels=[functools.partial(level_table, c, f, q) for c, f, q in zip(
                                cumulative, scattered_sum, level_shapes, strict=True)],
                            peak_shape=[q.to(table_dtype) for q in level_shapes],
                            contributions=torch.stack(contributions),
                            converged=converged,
                            remainder_extrapolated=remainder is not None,
                            ground_albedo=albedo.reshape(tuple(shape_b) + (n_lambda,)),
                            atmosphere_parameters=atmosphere.parameters_dict(),
                            gradient_parameters=[
                                name for name, value in atmosphere.named_buffers()
                                if value.requires_grad and torch.is_grad_enabled()],
                            depth_rows=tau_rows[dtype])
