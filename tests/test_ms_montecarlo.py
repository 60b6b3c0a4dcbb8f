"""The backward Monte-Carlo reference of the ground sky radiance (issue 14).

The generator ``tests/data/ms_reference/generate_montecarlo.py`` is verified here against
references that do not use its ray machinery: a direct numerical quadrature of the
single-scattering definition (trapezoidal optical depths along the line of sight and
along each ray to the Sun), the closed-form single scattering of a homogeneous
plane-parallel layer, and sasktran2's single scattering; then the shipped table is the
reference of the skytorch multiple-scattering solver. Radiances are per unit TOA solar
irradiance normal to the beam [sr^-1]; Monte-Carlo agreement is judged in standard
errors of the estimate.
"""
from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
import xarray as xr

from skytorch.constants import PERCENT

DATA = Path(__file__).parent / "data" / "ms_reference"
TABLE = DATA / "montecarlo_sky.nc"
HAS_SOLVER = importlib.util.find_spec("skytorch.atmosphere.multiple_scattering") is not None


def _load_generator():
    spec = importlib.util.spec_from_file_location("generate_montecarlo",
                                                  DATA / "generate_montecarlo.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("generate_montecarlo", module)   # dataclasses look it up
    spec.loader.exec_module(module)
    return module


mc = _load_generator()


@pytest.fixture(scope="module")
def aerosol_550():
    """Rayleigh + aerosol 0.1 at 550 nm and a Sun table (coarser than the generator's)."""
    opt = mc.optics(0.1, 550.0)
    return opt, mc.SunTable(opt, n_sub=2, n_angle=129)


def _ray_optical_depth(opt, start, direction, n=1501):
    """Trapezoidal optical depth from points ``start`` (p, 3) along ``direction`` to the top.

    Infinite where the ray meets the ground. Independent of the generator's shell pieces.
    """
    radius, top = opt.planet_radius_m, opt.planet_radius_m + opt.top_m
    direction = np.broadcast_to(direction, start.shape)
    b = np.einsum("ij,ij->i", start, direction)
    c = np.sum(start * start, axis=1)
    length = -b + np.sqrt(b * b - c + top * top)
    disc = b * b - c + radius * radius
    ground = (disc > 0.0) & (-b - np.sqrt(np.maximum(disc, 0.0)) > 0.0)
    t = np.linspace(0.0, 1.0, n)
    pts = start[:, None, :] + (length[:, None] * t)[..., None] * direction[:, None, :]
    h = np.linalg.norm(pts, axis=2) - radius
    k = np.interp(h, opt.altitude_m, opt.extinction)
    tau = np.trapezoid(k, t, axis=1) * length
    return np.where(ground, np.inf, tau)


def _single_scattering_quadrature(opt, view_zenith_deg, azimuth_deg, sun_zenith_deg):
    r"""Direct quadrature of :math:`\int \beta_s P T_{los} T_\odot ds` along the sight line."""
    d0 = mc.view_vector(view_zenith_deg)
    sun = mc.sun_directions(view_zenith_deg, [azimuth_deg], [sun_zenith_deg])[0]
    obs = np.array([0.0, 0.0, opt.planet_radius_m + mc.OBSERVER_ALTITUDE_M])
    top = opt.planet_radius_m + opt.top_m
    b = obs @ d0
    s_top = -b + math.sqrt(b * b - obs @ obs + top * top)
    s = s_top * np.linspace(0.0, 1.0, 2001) ** 3
    pts = obs + s[:, None] * d0
    h = np.linalg.norm(pts, axis=1) - opt.planet_radius_m
    k = np.interp(h, opt.altitude_m, opt.extinction)
    tau_los = np.concatenate([[0.0], np.cumsum(0.5 * (k[1:] + k[:-1]) * np.diff(s))])
    ray = np.interp(h, opt.altitude_m, opt.rayleigh)
    aer = np.interp(h, opt.altitude_m, opt.aerosol)
    cos_theta = d0 @ sun
    phase = (ray * 3.0 / (16.0 * math.pi) * (1.0 + cos_theta ** 2)
             + aer * (1.0 - opt.asymmetry ** 2)
             / (4.0 * math.pi * (1.0 + opt.asymmetry ** 2 - 2.0 * opt.asymmetry * cos_theta)
                ** 1.5))
    integrand = phase * np.exp(-tau_los - _ray_optical_depth(opt, pts, sun))
    return float(np.trapezoid(integrand, s))


def _order_one(opt, table, view_zenith_deg, azimuths, sun_zeniths, n, seed):
    """Order-1 estimates and standard errors (azimuth, sun) from the generator."""
    az, sz = np.meshgrid(azimuths, sun_zeniths, indexing="ij")
    suns = mc.sun_directions(view_zenith_deg, az.ravel(), sz.ravel())
    d0 = mc.view_vector(view_zenith_deg)
    x, w = mc._first_events(opt, table, d0, suns, n, np.random.default_rng(seed))
    c = mc._nee(opt, table, x, np.broadcast_to(d0, x.shape), w, suns)
    mean, err = c.mean(axis=0), c.std(axis=0, ddof=1) / math.sqrt(n)
    return mean.reshape(az.shape), err.reshape(az.shape)


def test_sun_table_against_trapezoidal_rays(aerosol_550):
    """The Sun optical-depth table matches independent ray quadratures (|d tau| < 0.005)."""
    opt, table = aerosol_550
    rng = np.random.default_rng(7)
    h = 1.0e5 * rng.random(400) ** 3
    mu = np.sign(rng.random(400) - 0.5) * rng.random(400) ** 2
    start = np.stack([np.zeros(400), np.zeros(400), opt.planet_radius_m + h], axis=1)
    direction = np.stack([np.sqrt(1.0 - mu * mu), np.zeros(400), mu], axis=1)
    ref = _ray_optical_depth(opt, start, direction, n=20001)
    ours = table(h, mu)
    shadow = ~np.isfinite(ref)
    assert np.array_equal(~np.isfinite(ours), shadow)
    moderate = ~shadow & (ref < 5.0)
    assert moderate.sum() > 200
    assert np.abs(ours[moderate] - ref[moderate]).max() < 5e-3


@pytest.mark.parametrize("sun_zenith_deg", [60.0, 94.0])
def test_order_one_against_quadrature(aerosol_550, sun_zenith_deg):
    """Order 1 of the Monte-Carlo equals the direct single-scattering integral (3 sigma).

    Sun 94 deg puts the lower part of the sight lines in the Earth's shadow.
    """
    opt, table = aerosol_550
    azimuths = [0.0, 90.0, 180.0]
    mean, err = _order_one(opt, table, 60.0, azimuths, [sun_zenith_deg], 20000, 11)
    for a, azimuth in enumerate(azimuths):
        ref = _single_scattering_quadrature(opt, 60.0, azimuth, sun_zenith_deg)
        assert err[a, 0] < 0.03 * ref
        assert abs(mean[a, 0] - ref) < 3.0 * err[a, 0], (azimuth, mean[a, 0], ref, err[a, 0])


def test_thin_homogeneous_layer_closed_form():
    r"""Plane-parallel limit: single scattering of a homogeneous Rayleigh layer.

    Planet radius 1e11 m (curvature negligible over the 10 km layer), optical depth 0.05,
    observer at the bottom looking up at :math:`\mu_v`, Sun at :math:`\mu_0`:
    :math:`L_1 = P(\Theta)\,\mu_0 (e^{-\tau/\mu_0} - e^{-\tau/\mu_v}) / (\mu_0 - \mu_v)`.
    """
    tau, thickness = 0.05, 1.0e4
    levels = np.array([0.0, 2500.0, 5000.0, 7500.0, 10000.0])
    k = np.full(levels.shape, tau / thickness)
    opt = mc.Optics(levels, k, np.zeros_like(k), k, 0.0, 1.0e11, thickness)
    table = mc.SunTable(opt, n_sub=4, n_angle=129)
    view_zenith, sun_zenith = 30.0, 60.0
    mean, err = _order_one(opt, table, view_zenith, [0.0, 90.0, 180.0], [sun_zenith],
                           20000, 5)
    mu_v, mu_0 = math.cos(math.radians(view_zenith)), math.cos(math.radians(sun_zenith))
    for a, azimuth in enumerate([0.0, 90.0, 180.0]):
        cos_theta = (mu_v * mu_0 + math.sin(math.radians(view_zenith))
                     * math.sin(math.radians(sun_zenith)) * math.cos(math.radians(azimuth)))
        phase = 3.0 / (16.0 * math.pi) * (1.0 + cos_theta ** 2)
        # observer 1 m above the bottom: the layer below it (2e-5 of the path) is missed
        ref = phase * mu_0 * (math.exp(-tau / mu_0) - math.exp(-tau / mu_v)) / (mu_0 - mu_v)
        assert abs(mean[a, 0] / ref - 1.0) < max(3.0 * err[a, 0] / ref, 0.1 * PERCENT)


def _order_two_quadrature(opt, sun_table, sun_zenith_deg, n_los=32, n_mu=48, n_phi=48,
                          n_ray=400):
    r"""Deterministic double scattering at the zenith view (Rayleigh only).

    :math:`L_2 = \int ds_1 \beta(s_1) T(0, s_1) \int d\Omega\, P(\Theta_1)
    \int ds_2 \beta(s_2) T(s_1, s_2) P(\Theta_2) T_\odot(s_2)`: Gauss-Legendre in
    the line-of-sight coordinate and in the direction cosine, uniform azimuths,
    trapezoidal optical depths along each second leg; only the Sun's optical depth comes
    from the (separately tested) table.
    """
    radius, top = opt.planet_radius_m, opt.planet_radius_m + opt.top_m
    u, wu = np.polynomial.legendre.leggauss(n_los)
    u, wu = 0.5 * (u + 1.0), 0.5 * wu
    s1, w1 = opt.top_m * u ** 2, opt.top_m * 2.0 * u * wu
    mu, wmu = np.polynomial.legendre.leggauss(n_mu)
    phi = (np.arange(n_phi) + 0.5) * 2.0 * math.pi / n_phi
    m, f = np.meshgrid(mu, phi, indexing="ij")
    dirs = np.stack([np.sqrt(1 - m ** 2) * np.cos(f), np.sqrt(1 - m ** 2) * np.sin(f), m],
                    -1).reshape(-1, 3)
    wdir = np.repeat(wmu, n_phi) * 2.0 * math.pi / n_phi
    sun = mc.sun_directions(0.0, [0.0], [sun_zenith_deg])[0]
    fine = np.linspace(0.0, opt.top_m, 20001)
    k_fine = np.interp(fine + mc.OBSERVER_ALTITUDE_M, opt.altitude_m, opt.extinction)
    tau_fine = np.concatenate([[0.0], np.cumsum(0.5 * (k_fine[1:] + k_fine[:-1])
                                                * np.diff(fine))])
    v = np.linspace(0.0, 1.0, n_ray)
    total = 0.0
    for s, w in zip(s1, w1, strict=True):
        x1 = np.array([0.0, 0.0, radius + mc.OBSERVER_ALTITUDE_M + s])
        b = dirs @ x1
        disc = b * b - x1 @ x1 + radius * radius
        ground = (disc > 0.0) & (-b - np.sqrt(np.maximum(disc, 0.0)) > 0.0)
        length = np.where(ground, -b - np.sqrt(np.maximum(disc, 0.0)),
                          -b + np.sqrt(b * b - x1 @ x1 + top * top))
        s2 = length[:, None] * v ** 2
        pts = x1 + s2[..., None] * dirs[:, None, :]
        r = np.linalg.norm(pts, axis=2)
        h = r - radius
        k2 = np.interp(h, opt.altitude_m, opt.extinction)
        beta2 = np.interp(h, opt.altitude_m, opt.rayleigh)
        tau = np.concatenate([np.zeros((len(length), 1)), np.cumsum(
            0.5 * (k2[:, 1:] + k2[:, :-1]) * np.diff(s2, axis=1), axis=1)], axis=1)
        sun_t = np.exp(-sun_table(h.ravel(), ((pts @ sun) / r).ravel())).reshape(h.shape)
        inner = np.trapezoid(beta2 * np.exp(-tau) * sun_t, s2, axis=1)
        phase = (mc.rayleigh_phase(dirs[:, 2]) * mc.rayleigh_phase(dirs @ sun))
        beta1 = np.interp(s + mc.OBSERVER_ALTITUDE_M, opt.altitude_m, opt.rayleigh)
        los_t = math.exp(-np.interp(s, fine, tau_fine))
        total += w * beta1 * los_t * np.sum(wdir * phase * inner)
    return total


@pytest.mark.slow
@pytest.mark.parametrize("sun_zenith_deg", [60.0, 94.0])
def test_table_order_two_against_quadrature(table, sun_zenith_deg):
    """Shipped order 2 (Rayleigh, 550 nm, zenith) equals a deterministic quadrature (3 sigma).

    In twilight (Sun 94 deg) this is the check of the multiple-scattering part that
    sasktran2's successive orders cannot give (one solar zenith along the sight line).
    """
    opt = mc.optics(0.0, 550.0)
    ref = _order_two_quadrature(opt, mc.SunTable(opt), sun_zenith_deg)
    ours = table.sel(case="rayleigh", wavelength=550.0, view=0, sun_zenith=sun_zenith_deg)
    assert abs(float(ours.order_2) - ref) < 3.0 * float(ours.order_2_stderr), (
        float(ours.order_2), ref)


@pytest.fixture(scope="module")
def table():
    with xr.open_dataset(TABLE) as ds:
        return ds.load()


@pytest.fixture(scope="module")
def sasktran2():
    with xr.open_dataset(DATA / "sasktran2_sky.nc") as ds:
        return ds.load()


def _sasktran2_at_views(sasktran2, variable, case, sun_zenith_deg, wavelength):
    ref = sasktran2[variable].sel(case=case, sun_zenith=sun_zenith_deg, wavelength=wavelength)
    return np.array([float(ref.sel(view_zenith=vz, relative_azimuth=az))
                     for vz, az in mc.VIEWS])


def test_table_metadata(table):
    """The shipped table says how it was made and stays small."""
    for key in ("photons", "seed", "script", "date", "skytorch_commit"):
        assert key in table.attrs
    assert TABLE.stat().st_size < 200_000
    assert list(table.view_zenith.values) == [v[0] for v in mc.VIEWS]


@pytest.mark.parametrize("case", ["rayleigh", "rayleigh_aerosol"])
def test_table_order_one_against_sasktran2(table, sasktran2, case):
    """Shipped order 1 equals sasktran2's single scattering (Sun <= 80 deg), max(3 sigma, 1 %)."""
    for sun_zenith_deg in (30.0, 60.0, 80.0):
        for wavelength in mc.WAVELENGTH_NM:
            ours = table.sel(case=case, sun_zenith=sun_zenith_deg, wavelength=wavelength)
            ref = _sasktran2_at_views(sasktran2, "single_scattering", case, sun_zenith_deg,
                                      wavelength)
            tolerance = np.maximum(3.0 * ours.order_1_stderr.values, 1.0 * PERCENT * ref)
            assert np.all(np.abs(ours.order_1.values - ref) < tolerance), (
                sun_zenith_deg, wavelength, ours.order_1.values / ref - 1.0)


def test_table_day_precision(table):
    """Day sky (Sun <= 80 deg) to 0.5 % standard error at every view."""
    day = table.sel(sun_zenith=[30.0, 60.0, 80.0])
    assert float((day.total_stderr / day.total).max()) < 0.5 * PERCENT


def test_order_truncation_is_negligible():
    """Orders above MAX_ORDER are below 1e-4 of the total (most-scattering case).

    Rayleigh at 400 nm (vertical optical depth 0.51), zenith view, Sun 60 deg: the order
    spectrum decays geometrically; its measured ratio bounds the tail beyond the cap.
    """
    opt = mc.optics(0.0, 400.0)
    table = mc.SunTable(opt, n_sub=1, n_angle=65)
    suns = mc.sun_directions(0.0, [0.0], [60.0])
    res = mc.trace(opt, table, mc.view_vector(0.0), suns, 2000, np.random.default_rng(3))
    orders = res["order"][0] / res["n"]
    total = orders.sum()
    ratio = float(np.max(orders[3:9] / orders[2:8]))
    assert 0.2 < ratio < 0.6
    tail = orders[8] * ratio ** (mc.MAX_ORDER - 8) / (1.0 - ratio)
    assert tail < 1e-4 * total
    assert orders[mc.ROULETTE_ORDER:].sum() < 1e-3 * total


@pytest.fixture(scope="module")
def solver_tables():
    """Hold the tables per (case, resolution), built when first asked for."""
    return {}


#: the coarse tables of the solver test (8 x 32 x 16 x 6)
COARSE = {"n_r": 8, "n_mu": 32, "n_mu_s": 16, "n_phi": 6, "n_ray": 24, "n_sphere_mu": 6,
          "transmittance_r": 32, "transmittance_mu": 128, "mu_vertical_weight": 0.0,
          "r_ground_weight": 0.0, "sphere_phi_refinement": 1, "ray_quadrature": "trapezoid"}


def _solver_radiance(cache, case, orders=None, resolution=None):
    """Table radiance of all orders (``orders=None``) or of orders 1..N (default COARSE)."""
    from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering

    resolution = COARSE if resolution is None else resolution
    key = (case, tuple(sorted(resolution.items())))
    if key not in cache:
        wavelength = torch.tensor(mc.WAVELENGTH_NM, dtype=torch.float64)
        cache[key] = precompute_scattering(
            mc.skytorch_atmosphere(mc.CASES[case]), wavelength, ground_albedo=0.0,
            scattering_orders="converged", resolution=TableResolution(**resolution))
    tables = cache[key]
    vz = torch.deg2rad(torch.tensor([v[0] for v in mc.VIEWS], dtype=torch.float64))
    az = torch.deg2rad(torch.tensor([v[1] for v in mc.VIEWS], dtype=torch.float64))
    out = {}
    for sun_zenith_deg in SOLVER_SUN_ZENITHS:
        value = tables.radiance(torch.tensor(1.0, dtype=torch.float64), vz, az,
                                torch.tensor(math.radians(sun_zenith_deg),
                                             dtype=torch.float64), scattering_orders=orders)
        out[sun_zenith_deg] = value.detach().numpy().T  # (wavelength, view)
    return out


SOLVER_SUN_ZENITHS = (30.0, 60.0, 80.0, 90.0, 94.0, 98.0)


def _single_scattering(case):
    """Direct single scattering (256 samples per line of sight), (wavelength, view)."""
    from skytorch.atmosphere.scattering import constituent_radiance

    atmosphere = mc.skytorch_atmosphere(mc.CASES[case])
    wavelength = torch.tensor(mc.WAVELENGTH_NM, dtype=torch.float64)
    vz = torch.deg2rad(torch.tensor([v[0] for v in mc.VIEWS], dtype=torch.float64))
    az = torch.deg2rad(torch.tensor([v[1] for v in mc.VIEWS], dtype=torch.float64))
    one = torch.tensor(1.0, dtype=torch.float64)
    return {sun: constituent_radiance(atmosphere.constituents(wavelength), vz, az,
                                      torch.tensor(math.radians(sun), dtype=torch.float64),
                                      0.0 * one, one, n_samples=256).numpy().T
            for sun in SOLVER_SUN_ZENITHS}


def _worst(table, case, values):
    """Largest |relative error| per Sun zenith over the views the MC can decide."""
    worst = {}
    for sun_zenith_deg, value in values.items():
        ref = table.sel(case=case, sun_zenith=sun_zenith_deg)
        tolerance = 3.0 * PERCENT if sun_zenith_deg <= 80.0 else 10.0 * PERCENT
        relative = value / ref.total.values - 1.0
        decided = ref.total_stderr.values < tolerance / 3.0 * ref.total.values
        assert decided.any()
        worst[sun_zenith_deg] = (float(np.abs(relative[decided]).max()), tolerance)
    return worst


def _scene_sky_errors(table, solver_tables):
    """Return the errors of the scenes' sum (single scattering + reference orders >= 2)."""
    from skytorch.scene.presets import FIDELITY

    resolution = FIDELITY["reference"]["ms_tables"]
    single = _single_scattering("rayleigh")
    first = _solver_radiance(solver_tables, "rayleigh", orders=1, resolution=resolution)
    every = _solver_radiance(solver_tables, "rayleigh", resolution=resolution)
    return _worst(table, "rayleigh", {sun: single[sun] + every[sun] - first[sun]
                                      for sun in SOLVER_SUN_ZENITHS})


@pytest.mark.slow
@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_scene_day_sky_against_montecarlo_rayleigh(table, solver_tables):
    """What scenes add up by day: direct single scattering plus the tables' orders >= 2.

    Rayleigh, the "reference" preset's tables, Sun 30 / 60 / 80 deg: within 3 % (measured
    2.1 / 1.6 / 1.6 %, the tables' own total 2.2 / 1.8 / 2.0 %, with the geometric Sun-zenith
    look-up; 1.7 / 1.5 / 1.3 % and 1.8 / 1.7 / 1.9 % with the former blended one).
    """
    worst = _scene_sky_errors(table, solver_tables)
    day = {sun: value for sun, value in worst.items() if sun <= 80.0}
    assert all(error < tolerance for error, tolerance in day.values()), day


@pytest.mark.slow
@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_scene_twilight_sky_against_montecarlo_rayleigh(table, solver_tables):
    """The same sum in twilight (Sun 90-98 deg): within 10 %.

    Measured 1.6 / 8.4 / 4.0 % at Sun 90 / 94 / 98 deg with the geometric Sun-zenith
    look-up (6.4 / 10.3 / 4.3 % with the former blended one). The default preset's smaller
    tables: 4.7 / 3.8 / 6.0 % with 8 radii, 5.0 / 27.5 / 35.5 % with the 5 of before
    (tests/test_preset_radius_nodes_experiment.py, docs/scene.md).
    """
    worst = _scene_sky_errors(table, solver_tables)
    assert all(error < tolerance for error, tolerance in worst.values()), worst


#: the default tables (``TableResolution()``, 16 x 64 x 48 x 8 since 2026-12-05, the radius
#: nodes crowded towards the ground and the sphere quadrature's azimuths refined, then 24
#: radii and the exponential ray quadrature since 2026-12-07), spelled out
DEFAULT_TABLES = {"n_r": 24, "n_mu": 64, "n_mu_s": 48, "n_phi": 8, "n_ray": 96,
                  "n_sphere_mu": 12, "transmittance_r": 64, "transmittance_mu": 256,
                  "mu_vertical_weight": 0.5, "r_ground_weight": 0.5, "sphere_phi_refinement": 2,
                  "ray_quadrature": "exponential"}


@pytest.mark.slow
@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
@pytest.mark.parametrize("case", ["rayleigh", "rayleigh_aerosol"])
def test_sky_through_twilight_against_montecarlo(table, solver_tables, case):
    """Sun 30-98 deg: ray-marched order 1 + the default tables' orders >= 2.

    The issue's tolerances (3 % to Sun 80 deg, 10 % to 98 deg) at the views the MC decides.
    Measured, max over those views, 400 and 550 nm, Sun 30 / 60 / 80 / 90 / 94 / 98 deg, on
    the default tables of 24 radii with the exponential ray quadrature (2026-12-07): Rayleigh
    0.3 / 0.3 / 0.3 / 0.9 / 2.9 / 1.8 %, Rayleigh + aerosol 0.7 / 0.5 / 0.6 / 1.0 / 1.7 / 0.5 %
    (16 radii, trapezoid: 0.27 / 0.32 / 0.33 / 0.8 / 3.3 / 1.5 % and 0.99 / 0.81 / 1.1 /
    1.1 / 2.7 / 0.8 %; the default tables of 2026-12-05: 0.3 / 0.3 / 0.4 / 0.8 / 3.7 / 1.2 %
    and 1.3 / 1.4 / 2.2 / 2.3 / 3.5 / 2.4 %; docs/multiple_scattering_validation.md,
    "Twilight on the default tables"; with the former blended Sun-zenith look-up Sun 94 deg
    was 10.5 / 10.9 %).
    """
    from skytorch.atmosphere.multiple_scattering import TableResolution

    assert TableResolution(**DEFAULT_TABLES) == TableResolution()
    single = _single_scattering(case)
    first = _solver_radiance(solver_tables, case, orders=1, resolution=DEFAULT_TABLES)
    every = _solver_radiance(solver_tables, case, resolution=DEFAULT_TABLES)
    worst = _worst(table, case, {sun: single[sun] + every[sun] - first[sun]
                                 for sun in SOLVER_SUN_ZENITHS})
    assert all(error < tolerance for error, tolerance in worst.values()), worst


SOLVER_XFAIL = ("measured with coarse tables and the geometric Sun-zenith look-up "
                "(docs/multiple_scattering_validation.md), max over the decided views, 400 "
                "and 550 nm: Rayleigh day <= 2.6 %, Sun 90/94/98 deg 20.8/15.5/5.2 %; "
                "Rayleigh + aerosol day 6.8-10.8 % (near the Sun), Sun 90/94/98 deg "
                "10.7/12.0/1.8 %")


@pytest.mark.slow
@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
@pytest.mark.xfail(strict=True, reason=SOLVER_XFAIL)
@pytest.mark.parametrize("case", ["rayleigh", "rayleigh_aerosol"])
def test_solver_against_montecarlo(table, solver_tables, case):
    """Coarse-table solver within 3 % (Sun <= 80 deg) and 10 % (to 98 deg) of the MC.

    Only points where the Monte-Carlo standard error is below a third of the tolerance
    are judged (the others cannot decide the tolerance).
    """
    worst = _worst(table, case, _solver_radiance(solver_tables, case))
    assert all(error < tolerance for error, tolerance in worst.values()), worst
