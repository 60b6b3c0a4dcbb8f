r"""Write the Monte-Carlo reference table of ground-level sky radiance (montecarlo_sky.nc).

A backward (adjoint) Monte-Carlo in spherical geometry whose only approximation is
statistical noise: straight rays, black ground, scalar radiance, a point Sun.

Optics are exactly those handed to sasktran2 by ``generate_sasktran2.py``: re-derived
here from the public skytorch API with the same calls (``Atmosphere.earth`` with
ozone 0 DU, water 0 cm, the Henyey-Greenstein aerosol of ``AEROSOL``;
``scattering_coefficients`` "rayleigh" and "aerosol", ``extinction_coefficient``; the
residual as a pure absorber) on the same altitude grid (0-10 km every 250 m, 10-100 km
every 1 km), linearly interpolated in altitude between levels.

Method, per view direction (all Sun positions scored on the same paths):

1. first scattering forced along the line of sight, its point drawn from a
   piecewise-constant density that mixes :math:`\beta_{sca}(s) T(0, s)` with the
   single-scattering integrand of every Sun position (defensive mixture); the weight is
   the exact integrand over the density, so the estimate is unbiased;
2. at every event a next-event estimate towards each Sun position:
   weight x (phase mixture of the species) x :math:`e^{-\tau_\odot}`, with
   :math:`\tau_\odot(r, \mu_\odot)` from a fine table of exact ray optical depths
   (zero where the ray to the Sun meets the planet);
3. a species is chosen by its share of the local scattering coefficient, a new direction
   drawn from its phase function, and the next event forced on the ray to the boundary
   (weight x :math:`1 - e^{-\tau_{ray}}` x the local single-scattering albedo), the
   distance found by inverting the cumulative optical depth, integrated exactly per shell
   segment (Gauss-Legendre on each piece between shell crossings; the extinction is
   linear in altitude inside a shell, the altitude a smooth function of the distance
   between crossings); the next order is scored at ``n_split`` = 8 events stratified in
   the optical depth of that ray (mean of their next-event estimates) and the history
   continues from one of them chosen at random, which keeps the estimate unbiased and
   samples the sunlit far end of a ray in twilight;
4. Russian roulette from order ``ROULETTE_ORDER`` on (survival 1/2, weight doubled);
   orders above ``MAX_ORDER`` are dropped (their size is reported).

Run: ``OMP_NUM_THREADS=1 .venv/bin/python tests/data/ms_reference/generate_montecarlo.py``
(``--quick`` for a smoke run that writes nothing unless ``--output`` is given).
"""
from __future__ import annotations

import argparse
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import xarray as xr

import skytorch as st

HERE = Path(__file__).resolve().parent
ALTITUDE_M = np.concatenate([np.arange(0.0, 10000.0, 250.0), np.arange(10000.0, 100001.0,
                                                                        1000.0)])
AEROSOL = {"aerosol_optical_depth": 0.1, "angstrom_alpha": 1.3, "aerosol_asymmetry": 0.7,
           "aerosol_single_scattering_albedo": 0.95}
CASES = {"rayleigh": 0.0, "rayleigh_aerosol": 0.1}
WAVELENGTH_NM = np.array([400.0, 550.0])
SUN_ZENITH_DEG = np.array([30.0, 60.0, 80.0, 90.0, 94.0, 98.0, 102.0, 106.0])
#: views: (view zenith [deg], relative azimuth [deg], 0 = towards the Sun)
VIEWS = [(0.0, 0.0)] + [(vz, az) for vz in (60.0, 85.0) for az in (0.0, 90.0, 180.0)]
OBSERVER_ALTITUDE_M = 1.0
ROULETTE_ORDER = 10
MAX_ORDER = 60
SEED = 20261202
#: Gauss-Legendre nodes and weights on [-1, 1] for each shell segment
GL_X, GL_W = np.polynomial.legendre.leggauss(3)


@dataclass(frozen=True)
class Optics:
    """Scattering and extinction coefficients on the altitude levels.

    Attributes
    ----------
    altitude_m : ndarray (level,)
        Levels [m]; coefficients are linear in altitude between them.
    rayleigh, aerosol, extinction : ndarray (level,)
        Rayleigh and aerosol scattering and total extinction coefficients [m^-1].
    asymmetry : float
        Henyey-Greenstein asymmetry parameter of the aerosol [1].
    planet_radius_m, top_m : float
        Planet radius and top of the atmosphere (altitude) [m].
    """

    altitude_m: np.ndarray
    rayleigh: np.ndarray
    aerosol: np.ndarray
    extinction: np.ndarray
    asymmetry: float
    planet_radius_m: float
    top_m: float


def skytorch_atmosphere(aod: float, ozone_du: float = 0.0) -> st.Atmosphere:
    """Return the atmosphere of the references: U.S. 1976, no water (no ozone by default)."""
    options = dict(AEROSOL, aerosol_optical_depth=aod)
    return st.Atmosphere.earth(ozone_du=ozone_du, precipitable_water_cm=0.0,
                               aerosol_phase_model="henyeygreenstein1941", **options)


def optics(aod: float, wavelength_nm: float, ozone_du: float = 0.0) -> Optics:
    """Optics of ``generate_sasktran2.manual_constituents`` at one wavelength.

    Parameters
    ----------
    aod : float
        Aerosol optical depth at 550 nm [1].
    wavelength_nm : float
        Wavelength [nm].
    ozone_du : float
        Ozone column [DU] (0 for ``montecarlo_sky.nc``); ozone is part of the pure absorber.

    Returns
    -------
    Optics
        Coefficients on ``ALTITUDE_M``.
    """
    atm = skytorch_atmosphere(aod, ozone_du)
    altitude = torch.tensor(ALTITUDE_M, dtype=torch.float64)
    wavelength = torch.tensor([wavelength_nm], dtype=torch.float64)
    scattering = atm.scattering_coefficients(altitude, wavelength)
    extinction = atm.extinction_coefficient(altitude, wavelength).numpy()[:, 0]
    rayleigh = scattering["rayleigh"].numpy()[:, 0]
    aerosol = scattering["aerosol"].numpy()[:, 0]
    ssa = float(AEROSOL["aerosol_single_scattering_albedo"])
    absorber = np.clip(extinction - rayleigh - aerosol / ssa, 0.0, None)
    return Optics(ALTITUDE_M.copy(), rayleigh, aerosol, rayleigh + aerosol / ssa + absorber,
                  float(AEROSOL["aerosol_asymmetry"]), float(atm.planet_radius_m),
                  float(atm.top_altitude_m))


def rayleigh_phase(cos_theta):
    """Rayleigh phase function 3/4 (1 + cos^2) / (4 pi) [sr^-1]."""
    return 3.0 / (16.0 * np.pi) * (1.0 + cos_theta ** 2)


def hg_phase(cos_theta, g):
    """Henyey-Greenstein phase function [sr^-1] of asymmetry ``g``."""
    return (1.0 - g * g) / (4.0 * np.pi * (1.0 + g * g - 2.0 * g * cos_theta) ** 1.5)


def coefficients(opt: Optics, h):
    """Rayleigh, aerosol scattering and extinction coefficients at altitudes ``h`` [m^-1]."""
    return (np.interp(h, opt.altitude_m, opt.rayleigh), np.interp(h, opt.altitude_m,
                                                                  opt.aerosol),
            np.interp(h, opt.altitude_m, opt.extinction))


def _segments(opt: Optics, h0, mu, distance=None):
    r"""Pieces of rays between shell crossings and their optical depths.

    The ray from altitude ``h0`` with direction cosine ``mu`` (to the local vertical) is
    written with :math:`x = s + r_0 \mu` (distance from the tangent point) so that
    :math:`r^2 = x^2 + b^2`. Shell ``j`` is crossed on the way down at
    :math:`x \in [-c_{j+1}, -c_j]` and on the way up at :math:`[c_j, c_{j+1}]`,
    :math:`c_j = \sqrt{r_j^2 - b^2}` (0 below the tangent point).

    Returns
    -------
    lo, hi : ndarray (ray, segment)
        Clipped piece bounds in x [m] (empty pieces have lo == hi).
    tau : ndarray (ray, segment)
        Optical depth of each piece [1].
    end : ndarray (ray,)
        Distance to the end of the ray (ground or top, or ``distance``) [m].
    ground : ndarray (ray,) of bool
        Whether the ray ends on the ground.
    """
    radius = opt.planet_radius_m
    z = opt.altitude_m
    r0 = radius + h0
    p = r0 * mu
    # r_j^2 - b^2 = (z_j - h0)(2R + z_j + h0) + p^2, free of cancellation
    c2 = (z[None, :] - h0[:, None]) * (2.0 * radius + z[None, :] + h0[:, None]) + p[:, None] ** 2
    c = np.sqrt(np.maximum(c2, 0.0))
    ground = (mu < 0.0) & (c2[:, 0] > 0.0)
    x_end = np.where(ground, -c[:, 0], c[:, -1])
    if distance is not None:
        x_end = np.minimum(x_end, p + distance)
    down_lo, down_hi = -c[:, :0:-1], -c[:, -2::-1]          # shells L-2 .. 0
    up_lo, up_hi = c[:, :-1], c[:, 1:]                        # shells 0 .. L-2
    lo = np.concatenate([down_lo, up_lo], axis=1)
    hi = np.concatenate([down_hi, up_hi], axis=1)
    lo = np.minimum(np.maximum(lo, p[:, None]), x_end[:, None])
    hi = np.minimum(np.maximum(hi, p[:, None]), x_end[:, None])
    tau = _piece_optical_depth(opt, lo, hi, p, r0, mu)
    return lo, hi, tau, x_end - p, ground


def _shell_index(n_levels: int) -> np.ndarray:
    return np.concatenate([np.arange(n_levels - 2, -1, -1), np.arange(n_levels - 1)])


def _piece_optical_depth(opt, lo, hi, p, r0, mu):
    """Gauss-Legendre optical depth of the non-empty pieces [lo, hi] in x (ray, segment)."""
    j_all = _shell_index(len(opt.altitude_m))
    if lo.shape[1] != len(j_all):
        raise ValueError("segment layout mismatch")
    rows, cols = np.nonzero(hi > lo)
    b2 = r0 * r0 * (1.0 - mu * mu)
    tau = np.zeros(lo.shape)
    tau[rows, cols] = _piece_optical_depth_1d(opt, lo[rows, cols], hi[rows, cols], b2[rows],
                                              j_all[cols])
    return tau


def optical_depth(opt: Optics, h0, mu, distance=None):
    """Optical depth along straight rays to the boundary or to ``distance`` [1].

    Parameters
    ----------
    opt : Optics
        Atmosphere.
    h0, mu : ndarray (ray,)
        Start altitude [m] and direction cosine to the local vertical [1].
    distance : ndarray (ray,), optional
        Path length [m]; default: to the ground or the top.

    Returns
    -------
    tau : ndarray (ray,)
        Optical depth [1].
    ground : ndarray (ray,) of bool
        Whether the full ray meets the ground.
    """
    _, _, tau, _, ground = _segments(opt, np.asarray(h0, float), np.asarray(mu, float),
                                     None if distance is None else np.asarray(distance,
                                                                              float))
    return tau.sum(axis=1), ground


def sample_distance(opt: Optics, h0, mu, u):
    r"""Draw distances of the next event, forced before the boundary.

    Parameters
    ----------
    opt : Optics
        Atmosphere.
    h0, mu : ndarray (ray,)
        Start altitude [m] and direction cosine [1].
    u : ndarray (ray, sample)
        Uniform random numbers in (0, 1); several samples per ray share its segments.

    Returns
    -------
    distance : ndarray (ray, sample)
        Distance [m] at which the optical depth is ``-log(1 - u (1 - exp(-tau_ray)))``.
    interaction : ndarray (ray,)
        :math:`1 - e^{-\tau_{ray}}`, the probability of an event before the boundary.
    """
    lo, hi, tau, _, _ = _segments(opt, h0, mu)
    cum = np.cumsum(tau, axis=1)
    interaction = -np.expm1(-cum[:, -1])
    target = -np.log1p(-u * interaction[:, None])
    m = u.shape[1]
    rows = np.repeat(np.arange(len(h0)), m)
    target = target.ravel()
    seg = np.minimum((cum[rows] < target[:, None]).sum(axis=1), tau.shape[1] - 1)
    before = np.where(seg > 0, cum[rows, np.maximum(seg - 1, 0)], 0.0)
    residual = target - before
    a, e = lo[rows, seg], hi[rows, seg]
    r0 = opt.planet_radius_m + h0[rows]
    p = r0 * mu[rows]
    b2 = r0 * r0 * (1.0 - mu[rows] ** 2)
    x = a + (e - a) * np.clip(residual / np.maximum(tau[rows, seg], 1e-300), 0.0, 1.0)
    j = _shell_index(len(opt.altitude_m))[seg]
    for _ in range(4):   # Newton on the integral from a to x
        part = _piece_optical_depth_1d(opt, a, x, b2, j)
        h = np.sqrt(x * x + b2) - opt.planet_radius_m
        k = _shell_k(opt, h, j)
        x = np.clip(x - (part - residual) / np.maximum(k, 1e-300), a, e)
    return (x - p).reshape(len(h0), m), interaction


def _shell_k(opt, h, j):
    z0, z1 = opt.altitude_m[j], opt.altitude_m[j + 1]
    k0, k1 = opt.extinction[j], opt.extinction[j + 1]
    return k0 + (k1 - k0) * (h - z0) / (z1 - z0)


def _piece_optical_depth_1d(opt, a, e, b2, j):
    mid, half = 0.5 * (a + e), 0.5 * (e - a)
    x = mid[:, None] + half[:, None] * GL_X
    h = np.sqrt(x * x + b2[:, None]) - opt.planet_radius_m
    k = _shell_k(opt, h, j[:, None])
    return half * (k @ GL_W)


class SunTable:
    """Optical depth to the top along the ray to the Sun, tau(h, mu_sun) [1].

    Two tables of exact ray optical depths, interpolated bilinearly:
    rising rays on (h, sqrt(mu)) and descending rays on (tangent altitude z_t,
    sqrt((h - z_t) / (top - z_t))), so that the grazing-ground cut-off (z_t = 0) is a
    grid line. Rays with z_t < 0 meet the planet (infinite optical depth).

    Parameters
    ----------
    opt : Optics
        Atmosphere.
    n_sub : int
        Sub-divisions of each altitude layer.
    n_angle : int
        Nodes of the angular coordinate.
    """

    def __init__(self, opt: Optics, n_sub: int = 2, n_angle: int = 257):
        self.opt = opt
        z = opt.altitude_m
        self.h = np.concatenate([np.linspace(z[i], z[i + 1], n_sub + 1)[:-1]
                                 for i in range(len(z) - 1)] + [z[-1:]])
        self.t = np.linspace(0.0, 1.0, n_angle)
        hh, tt = np.meshgrid(self.h, self.t, indexing="ij")
        tau_up, _ = optical_depth(opt, hh.ravel(), (tt ** 2).ravel())
        self.up = tau_up.reshape(hh.shape)
        top, radius = opt.top_m, opt.planet_radius_m
        start = hh + tt ** 2 * (top - hh)           # z_t = hh, start altitude
        # the node z_t = 0 is the ray grazing the ground: 1 mm above it, on the lit side
        r, b = radius + start, radius + np.maximum(hh, 1e-3)
        mu = -np.sqrt(np.clip((r - b) * (r + b), 0.0, None)) / r
        tau_down, _ = optical_depth(opt, start.ravel(), mu.ravel())
        self.down = tau_down.reshape(hh.shape)

    def _bilinear(self, table, h, t):
        i = np.clip(np.searchsorted(self.h, h) - 1, 0, len(self.h) - 2)
        fh = (h - self.h[i]) / (self.h[i + 1] - self.h[i])
        n = len(self.t) - 1
        k = np.clip((t * n).astype(int), 0, n - 1)
        ft = t * n - k
        return ((1 - fh) * ((1 - ft) * table[i, k] + ft * table[i, k + 1])
                + fh * ((1 - ft) * table[i + 1, k] + ft * table[i + 1, k + 1]))

    def __call__(self, h, mu):
        """Optical depth [1] from altitude ``h`` [m] along direction cosine ``mu``."""
        top, radius = self.opt.top_m, self.opt.planet_radius_m
        h = np.clip(h, 0.0, top)
        out = np.full(np.shape(h), np.inf)
        up = mu >= 0.0
        out[up] = self._bilinear(self.up, h[up], np.sqrt(mu[up]))
        dn = ~up
        r = radius + h[dn]
        m2 = mu[dn] ** 2
        drop = r * m2 / (1.0 + np.sqrt(1.0 - m2))        # r - b = h - z_t
        zt = h[dn] - drop
        lit = zt >= 0.0
        t = np.sqrt(np.clip(drop[lit] / (top - zt[lit]), 0.0, 1.0))
        vals = np.full(zt.shape, np.inf)
        vals[lit] = self._bilinear(self.down, zt[lit], t)
        out[dn] = vals
        return out


def _rotate(d, cos_theta, phi):
    """Turn unit vectors ``d`` (ray, 3) by arccos(cos_theta) at azimuth ``phi``."""
    a = np.where(np.abs(d[:, 2:3]) < 0.9, np.array([0.0, 0.0, 1.0]), np.array([1.0, 0, 0]))
    u = np.cross(d, a)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(d, u)
    sin_theta = np.sqrt(np.clip(1.0 - cos_theta ** 2, 0.0, 1.0))
    out = (cos_theta[:, None] * d + sin_theta[:, None] * (np.cos(phi)[:, None] * u
                                                         + np.sin(phi)[:, None] * v))
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def sample_rayleigh(u):
    """Scattering cosines drawn from the Rayleigh phase function (Cardano)."""
    q = 4.0 * u - 2.0
    a = np.cbrt(q + np.sqrt(q * q + 1.0))
    return a - 1.0 / a


def sample_hg(u, g):
    """Scattering cosines drawn from the Henyey-Greenstein phase function."""
    s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u)
    return np.clip((1.0 + g * g - s * s) / (2.0 * g), -1.0, 1.0)


def sun_directions(view_zenith_deg: float, relative_azimuth_deg, sun_zenith_deg):
    """Return unit vectors to the Sun (sun, 3) in the frame where the view azimuth is 0."""
    sz = np.deg2rad(np.asarray(sun_zenith_deg, float))
    az = -np.deg2rad(np.asarray(relative_azimuth_deg, float))
    return np.stack([np.sin(sz) * np.cos(az), np.sin(sz) * np.sin(az), np.cos(sz)], axis=-1)


def _nee(opt, table, x, d, w, suns, sun_weight=None):
    """Next-event estimates towards each Sun (ray, sun) [sr^-1 per unit weight].

    ``sun_weight``, when given, maps the points ``x`` (ray, 3) [m, from the planet's
    centre] to a factor (ray, sun) on the Sun's light there (the part of the disc a Moon
    leaves visible during a solar eclipse).
    """
    r = np.linalg.norm(x, axis=1)
    h = r - opt.planet_radius_m
    ray, aer, _ = coefficients(opt, h)
    sca = ray + aer
    cos_theta = d @ suns.T
    mu_s = (x @ suns.T) / r[:, None]
    tau = table(np.broadcast_to(h[:, None], mu_s.shape).ravel(), mu_s.ravel())
    phase = (ray[:, None] * rayleigh_phase(cos_theta)
             + aer[:, None] * hg_phase(cos_theta, opt.asymmetry)) / sca[:, None]
    estimate = w[:, None] * phase * np.exp(-tau).reshape(mu_s.shape)
    return estimate if sun_weight is None else estimate * sun_weight(x)


def _los_density(opt, table, d0, suns, n_sub=8, mixture=0.5, sun_weight=None):
    """Piecewise-constant density of the first event on the line of sight."""
    h0 = np.array([OBSERVER_ALTITUDE_M])
    mu0 = np.array([d0[2]])
    lo, hi, _, _, _ = _segments(opt, h0, mu0)
    p = (opt.planet_radius_m + h0[0]) * mu0[0]
    edges = np.unique(np.concatenate([lo[0], hi[0]]))
    frac = np.linspace(0.0, 1.0, n_sub + 1)[:-1]
    nodes = np.concatenate([(a + (e - a) * frac) for a, e in zip(edges[:-1], edges[1:], strict=True)]
                           + [edges[-1:]]) - p
    mids = 0.5 * (nodes[1:] + nodes[:-1])
    width = np.diff(nodes)
    tau, _ = optical_depth(opt, np.full(len(mids), h0[0]), np.full(len(mids), mu0[0]), mids)
    x = np.array([0.0, 0.0, opt.planet_radius_m + h0[0]]) + mids[:, None] * d0
    ray, aer, _ = coefficients(opt, np.linalg.norm(x, axis=1) - opt.planet_radius_m)
    f1 = (ray + aer) * np.exp(-tau)
    prob = f1 * width / np.sum(f1 * width)
    f2 = _nee(opt, table, x, np.broadcast_to(d0, x.shape), f1, suns, sun_weight)
    norm2 = np.sum(f2 * width[:, None], axis=0)
    lit = norm2 > 0.0
    if lit.any():
        prob2 = (f2[:, lit] * width[:, None] / norm2[lit]).mean(axis=1)
        prob = mixture * prob + (1.0 - mixture) * prob2
    return nodes, prob / prob.sum()


def _first_events(opt, table, d0, suns, n, rng, sun_weight=None):
    nodes, prob = _los_density(opt, table, d0, suns, sun_weight=sun_weight)
    cell = np.minimum(np.searchsorted(np.cumsum(prob), rng.random(n)), len(prob) - 1)
    s = nodes[cell] + rng.random(n) * (nodes[cell + 1] - nodes[cell])
    density = prob[cell] / (nodes[cell + 1] - nodes[cell])
    h0 = np.full(n, OBSERVER_ALTITUDE_M)
    tau, _ = optical_depth(opt, h0, np.full(n, d0[2]), s)
    x = np.array([0.0, 0.0, opt.planet_radius_m + OBSERVER_ALTITUDE_M]) + s[:, None] * d0
    ray, aer, _ = coefficients(opt, np.linalg.norm(x, axis=1) - opt.planet_radius_m)
    return x, (ray + aer) * np.exp(-tau) / density


def _scatter(opt, x, d, rng):
    h = np.linalg.norm(x, axis=1) - opt.planet_radius_m
    ray, aer, _ = coefficients(opt, h)
    n = len(h)
    is_ray = rng.random(n) * (ray + aer) < ray
    u = rng.random(n)
    cos_theta = np.where(is_ray, sample_rayleigh(u), sample_hg(u, opt.asymmetry)
                         if opt.asymmetry != 0.0 else 2.0 * u - 1.0)
    return _rotate(d, cos_theta, 2.0 * np.pi * rng.random(n))


def _next_events(opt, table, x, d, w, suns, n_split, rng, sun_weight=None):
    """Scatter, score the next order at ``n_split`` stratified events, continue from one."""
    n = len(w)
    d = _scatter(opt, x, d, rng)
    r = np.linalg.norm(x, axis=1)
    h, mu = r - opt.planet_radius_m, np.einsum("ij,ij->i", x, d) / r
    u = (np.arange(n_split)[None, :] + rng.random((n, n_split))) / n_split
    s, interaction = sample_distance(opt, h, mu, u)
    xs = (x[:, None, :] + s[..., None] * d[:, None, :]).reshape(-1, 3)
    ray, aer, ext = coefficients(opt, np.linalg.norm(xs, axis=1) - opt.planet_radius_m)
    ws = np.repeat(w * interaction, n_split) * (ray + aer) / ext
    c = _nee(opt, table, xs, np.repeat(d, n_split, axis=0), ws, suns, sun_weight)
    c = c.reshape(n, n_split, -1).mean(axis=1)
    pick = np.arange(n) * n_split + rng.integers(0, n_split, n)
    return xs[pick], d, ws[pick], c


def trace(opt: Optics, table: SunTable, d0, suns, n_photons: int, rng, batch: int = 2000,
          n_split: int = 8, sun_weight=None):
    """Backward Monte-Carlo histories from the observer along ``d0``.

    Parameters
    ----------
    opt : Optics
        Atmosphere.
    table : SunTable
        Optical depth to the Sun.
    d0 : ndarray (3,)
        Line of sight (unit vector; observer at the north pole of the planet).
    suns : ndarray (sun, 3)
        Unit vectors to the Sun positions scored.
    n_photons : int
        Histories.
    rng : numpy.random.Generator
        Random numbers.
    batch : int
        Histories traced together.
    n_split : int
        Stratified next events scored per scattering (one of them is continued).
    sun_weight : callable, optional
        Factor (ray, sun) on the Sun's light at points (ray, 3) [m, from the planet's
        centre]; see ``_nee``.

    Returns
    -------
    dict
        ``sum`` and ``sum2`` (sun, bin) over histories of the per-history radiance of
        bins order 1, 2, >= 3 and total [sr^-1]; ``order`` (sun, MAX_ORDER) sums per
        order; ``n`` histories.
    """
    k = len(suns)
    out = {"sum": np.zeros((k, 4)), "sum2": np.zeros((k, 4)),
           "order": np.zeros((k, MAX_ORDER)), "n": 0}
    done = 0
    while done < n_photons:
        n = min(batch, n_photons - done)
        tally = np.zeros((n, k, 3))
        x, w = _first_events(opt, table, d0, suns, n, rng, sun_weight)
        d = np.broadcast_to(d0, x.shape).copy()
        alive = np.arange(n)
        c = _nee(opt, table, x, d, w, suns, sun_weight)
        for order in range(1, MAX_ORDER + 1):
            tally[alive, :, min(order, 3) - 1] += c
            out["order"][:, order - 1] += c.sum(axis=0)
            if order == MAX_ORDER:
                break
            x, d, w, c = _next_events(opt, table, x, d, w, suns, n_split, rng, sun_weight)
            if order >= ROULETTE_ORDER:
                keep = rng.random(len(w)) < 0.5
                w, c = 2.0 * w[keep], 2.0 * c[keep]
                x, d, alive = x[keep], d[keep], alive[keep]
            if len(alive) == 0:
                break
        per = np.concatenate([tally, tally.sum(axis=2, keepdims=True)], axis=2)
        out["sum"] += per.sum(axis=0)
        out["sum2"] += (per ** 2).sum(axis=0)
        out["n"] += n
        done += n
    return out


def view_vector(view_zenith_deg: float) -> np.ndarray:
    """Line of sight at azimuth 0 of the given zenith angle (3,)."""
    vz = np.deg2rad(view_zenith_deg)
    return np.array([np.sin(vz), 0.0, np.cos(vz)])


def radiance(opt: Optics, table: SunTable, view_zenith_deg: float, azimuths_deg,
             sun_zenith_deg, n_photons: int, rng):
    """Mean radiance and standard error per (azimuth, sun zenith, bin) [sr^-1].

    Bins: order 1, order 2, orders >= 3, total.
    """
    az, sz = np.meshgrid(azimuths_deg, sun_zenith_deg, indexing="ij")
    suns = sun_directions(view_zenith_deg, az.ravel(), sz.ravel())
    res = trace(opt, table, view_vector(view_zenith_deg), suns, n_photons, rng)
    n = res["n"]
    mean = res["sum"] / n
    var = np.maximum(res["sum2"] / n - mean ** 2, 0.0) / (n - 1)
    shape = az.shape + (4,)
    return (mean.reshape(shape), np.sqrt(var).reshape(shape),
            (res["order"] / n).reshape(az.shape + (MAX_ORDER,)))


def _git_commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                              cwd=HERE, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def compute(case_names, wavelengths_nm, n_photons: int) -> xr.Dataset:
    """Monte-Carlo table for the given cases and wavelengths (every Sun zenith and view).

    Parameters
    ----------
    case_names : sequence of str
        Keys of ``CASES``.
    wavelengths_nm : sequence of float
        Wavelengths [nm].
    n_photons : int
        Histories per (case, wavelength, view zenith); each scores every Sun zenith and
        relative azimuth of that view zenith.

    Returns
    -------
    xarray.Dataset
        Radiances and standard errors [sr^-1] over (case, sun_zenith, wavelength, view).
    """
    start = time.perf_counter()
    view_zeniths = sorted({vz for vz, _ in VIEWS})
    shape = (len(case_names), len(SUN_ZENITH_DEG), len(wavelengths_nm), len(VIEWS), 4)
    mean, error = np.full(shape, np.nan), np.full(shape, np.nan)
    for i, case in enumerate(case_names):
        for j, wl in enumerate(wavelengths_nm):
            # one independent stream per (case, wavelength): parts can run separately
            rng = np.random.default_rng([SEED, list(CASES).index(case), int(wl)])
            opt = optics(CASES[case], wl)
            table = SunTable(opt)
            for vz in view_zeniths:
                idx = [v for v, (z, _) in enumerate(VIEWS) if z == vz]
                m, e, _ = radiance(opt, table, vz, [VIEWS[v][1] for v in idx],
                                        SUN_ZENITH_DEG, n_photons, rng)
                for a, v in enumerate(idx):
                    mean[i, :, j, v] = m[a]
                    error[i, :, j, v] = e[a]
                print(f"{case} {wl:.0f} nm view {vz:.0f}: "
                      f"{time.perf_counter() - start:.0f} s", flush=True)
    dims = ("case", "sun_zenith", "wavelength", "view")
    data = {}
    for b, name in enumerate(("order_1", "order_2", "order_3plus", "total")):
        data[name] = (dims, mean[..., b], {"units": "sr-1", "long_name":
                      f"{name} radiance per unit TOA solar irradiance normal to the beam"})
        data[f"{name}_stderr"] = (dims, error[..., b], {"units": "sr-1", "long_name":
                                  f"standard error of {name}"})
    ds = xr.Dataset(data, coords={
        "case": np.array(case_names, dtype="<U32"),
        "aerosol_optical_depth": ("case", [CASES[c] for c in case_names]),
        "sun_zenith": ("sun_zenith", SUN_ZENITH_DEG, {"units": "degree"}),
        "wavelength": ("wavelength", np.asarray(wavelengths_nm, float), {"units": "nm"}),
        "view": ("view", np.arange(len(VIEWS))),
        "view_zenith": ("view", [v[0] for v in VIEWS], {"units": "degree"}),
        "relative_azimuth": ("view", [v[1] for v in VIEWS], {"units": "degree",
                             "description": "0: looking toward the Sun's azimuth"})})
    ds.attrs.update(
        title="Backward Monte-Carlo reference sky radiance (spherical, scalar, black ground)",
        photons=n_photons, seed=SEED, script="tests/data/ms_reference/generate_montecarlo.py",
        date=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), skytorch_commit=_git_commit(),
        skytorch_version=st.__version__, observer_altitude_m=OBSERVER_ALTITUDE_M,
        roulette_order=ROULETTE_ORDER, max_order=MAX_ORDER, aerosol=repr(AEROSOL),
        cpu_time_s=round(time.process_time(), 1),
        photons_description="histories per (case, wavelength, view zenith); each scores "
        "every Sun zenith and relative azimuth of that view zenith")
    return ds


def main(argv=None) -> None:
    """Compute the table (or one part of it, or merge parts); ``--quick`` for a smoke run."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="few photons, no file")
    parser.add_argument("--photons", type=int, default=None,
                        help="histories per (case, wavelength, view zenith)")
    parser.add_argument("--case", choices=list(CASES), default=None, help="one case only")
    parser.add_argument("--wavelength", type=float, default=None, help="one wavelength [nm]")
    parser.add_argument("--merge", type=Path, nargs="+", default=None,
                        help="part files to merge into the output")
    parser.add_argument("--output", type=Path, default=None)
    args = parser.parse_args(argv)
    output = args.output or (None if args.quick else HERE / "montecarlo_sky.nc")
    if args.merge:
        parts = [xr.open_dataset(path).load() for path in args.merge]
        # object labels, so that combining does not cut "rayleigh_aerosol" to "rayleigh"
        parts = [part.assign_coords(case=part.case.values.astype(object)) for part in parts]
        ds = xr.combine_by_coords(parts, combine_attrs="drop_conflicts")
        ds.attrs["cpu_time_s"] = round(sum(float(p.attrs["cpu_time_s"]) for p in parts), 1)
        ds.attrs["date"] = max(p.attrs["date"] for p in parts)
        ds.attrs["skytorch_commit"] = ", ".join(sorted({p.attrs["skytorch_commit"]
                                                        for p in parts}))
        # under the roulette no history reaches order 51: the cap is bounded instead by
        # the order spectrum (tests/test_ms_montecarlo.py::test_order_truncation_...)
        ds = ds.drop_vars("orders_51_60", errors="ignore")
    else:
        n_photons = args.photons or (500 if args.quick else 120000)
        cases = [args.case] if args.case else list(CASES)
        wavelengths = [args.wavelength] if args.wavelength else list(WAVELENGTH_NM)
        ds = compute(cases, wavelengths, n_photons)
        print(f"cpu {ds.attrs['cpu_time_s']} s")
    if output is not None:
        ds.to_netcdf(output)
        print(f"wrote {output}")


if __name__ == "__main__":
    main()
