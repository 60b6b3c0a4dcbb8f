"""Multiple scattering by precomputed orders (skytorch.atmosphere.multiple_scattering).

The single-scattering order is compared with the ray-marched single-scattering kernel
(an independent algorithm, exact phase and columns along each ray); the higher orders
with conservation of energy; hard cases for finiteness; gradients by gradcheck.
"""

import dataclasses
import math

import numpy as np
import pytest
import torch

from skytorch.atmosphere import Atmosphere, multiple_scattering
from skytorch.atmosphere.multiple_scattering import (
    MU_S_MIN,
    ScatteringTables,
    TableResolution,
    precompute_scattering,
)

F64 = torch.float64
WAVELENGTH = torch.tensor([450.0, 650.0], dtype=F64)
#: a coarse table that still resolves the day sky (about 1.5 s to build 3 orders)
COARSE = TableResolution(n_r=8, n_mu=32, n_mu_s=16, n_phi=6, n_ray=32, n_sphere_mu=6, mu_vertical_weight=0.0,
                         r_ground_weight=0.0, sphere_phi_refinement=1, ray_quadrature="trapezoid")


@pytest.fixture(scope="module")
def day_tables():
    atm = Atmosphere.earth(turbidity=2.0)
    return atm, precompute_scattering(atm, WAVELENGTH, scattering_orders=3,
                                      resolution=COARSE)


@pytest.mark.parametrize("sun_deg", [0.0, 30.0, 60.0])
@pytest.mark.parametrize("view_deg, azimuth", [(0.0, 0.0), (60.0, 0.0), (60.0, 2.0)])
def test_single_order_matches_ray_marched_kernel(day_tables, sun_deg, view_deg, azimuth):
    atm, tables = day_tables
    sun, view = math.radians(sun_deg), math.radians(view_deg)
    order1 = tables.radiance(0.0, view, azimuth, sun, scattering_orders=1)
    marched = atm.sky_radiance(WAVELENGTH, torch.tensor(view, dtype=F64), azimuth,
                               torch.tensor(sun, dtype=F64), n_samples=256, scattering_orders=1)
    # the table's interpolation error on this coarse grid: a few per cent (measured
    # <= 2.6 % at 550 nm; docs/multiple_scattering.md)
    assert torch.allclose(order1, marched, rtol=0.04, atol=0.0), (order1, marched)


def test_orders_converge_monotonically(day_tables):
    _, tables = day_tables
    sizes = tables.order_contributions
    assert tables.orders_computed == 3 and sizes.shape == (3,)
    assert bool((sizes[1:] < sizes[:-1]).all()), sizes
    assert bool((sizes[1:] > 0).all())
    geometry = (0.0, torch.tensor([0.0, 1.0, 1.5]), 0.5, 1.2)
    previous = None
    for n in (1, 2, 3):
        value = tables.radiance(*geometry, scattering_orders=n)
        if previous is not None:
            assert bool((value > previous).all())
        previous = value


def test_multiple_scattering_adds_more_in_the_blue(day_tables):
    _, tables = day_tables
    ratio = (tables.radiance(0.0, 0.0, 0.0, 1.0)
             / tables.radiance(0.0, 0.0, 0.0, 1.0, scattering_orders=1))
    assert bool((ratio > 1.05).all()) and float(ratio[0]) > float(ratio[1]), ratio


def _global_energy_balance(tables) -> float:
    """Light leaving the top of the atmosphere over the whole planet / light intercepted.

    In spherical geometry the balance is global, not local: a Lambertian ground's light
    spreads over the larger sphere of the top ((R_top / R)^2 = 1.032 for 100 km), so the
    outgoing flux above the subsolar point is ~3 % below the incoming even when nothing
    is lost. Over the sphere, the flux F_out(mu_s) leaving the top [per unit solar
    irradiance] integrates to (2 pi R_top^2) * int F_out dmu_s = pi R_top^2, i.e.
    int_{-1}^{1} F_out dmu_s = 1/2 (F_out is 0 beyond the tables' twilight limit).
    """
    x, w = np.polynomial.legendre.leggauss(48)
    mu = torch.tensor(-0.5 * (x + 1.0))
    weight = torch.tensor(0.5 * w) * mu.abs()
    azimuth = (torch.arange(48, dtype=F64) + 0.5) * (2 * math.pi / 48)
    nodes, weights = [], []
    for low, high in ((MU_S_MIN, 0.0), (0.0, 1.0)):
        xs, ws = np.polynomial.legendre.leggauss(24)
        nodes.append(0.5 * (high - low) * xs + 0.5 * (high + low))
        weights.append(0.5 * (high - low) * ws)
    total = 0.0
    for mu_s, w_s in zip(np.concatenate(nodes), np.concatenate(weights), strict=True):
        radiance = tables.radiance(tables.top_altitude_m, torch.acos(mu)[:, None],
                                   azimuth[None, :], math.acos(mu_s))[..., 0]
        total += w_s * float((radiance * weight[:, None]).sum()) * 2 * math.pi / 48
    return total / 0.5


def _unscattered_limb_fraction(atm, wavelength) -> float:
    """Part of the light intercepted by the top sphere that crosses the limb unscattered.

    Rays with impact parameter p between the ground's radius R and the top's R_top miss
    the planet; their direct beam, exp(-tau) along the straight chord, leaves the top on
    the night side and is not sky radiance: sum of 2 p exp(-tau(p)) dp / R_top^2 (midpoint
    rule, 4000 chords; tau from the atmosphere's column integrals, no table involved; with
    tau = 0 it is the closed form 1 - (R / R_top)^2). 0.0251 for both atmospheres below at
    550 nm: the air above 35 km is transparent along the chords.
    """
    constituents = atm.constituents(wavelength, F64)
    ground, top = constituents.planet_radius_m, constituents.top_radius_m
    n = 4000
    p = ground + (top - ground) * (torch.arange(n, dtype=F64) + 0.5) / n
    columns = constituents.column_integrals(p, torch.zeros_like(p), extra=1)
    tau = 2.0 * constituents.optical_depth(columns, extra=1)[..., 0]
    return float((2.0 * p * torch.exp(-tau)).sum() * (top - ground) / n / top ** 2)


#: conservative atmospheres over a ground of albedo 1
RAYLEIGH_ONLY = {"aerosol_optical_depth": 0.0, "ozone_du": 0.0, "precipitable_water_cm": 0.0}
WITH_AEROSOL = {"turbidity": 2.0, "ozone_du": 0.0, "precipitable_water_cm": 0.0,
                "aerosol_single_scattering_albedo": 1.0}


def _balance_excess(parameters, resolution) -> float:
    """Sky light leaving the top / (intercepted - unscattered limb light) - 1, 550 nm."""
    atm = Atmosphere.earth(**parameters)
    wavelength = torch.tensor([550.0], dtype=F64)
    tables = precompute_scattering(atm, wavelength, ground_albedo=1.0,
                                   scattering_orders="converged", resolution=resolution)
    assert tables.converged
    return _global_energy_balance(tables) / (1.0 - _unscattered_limb_fraction(atm, wavelength)) - 1


BALANCE_COARSE = TableResolution(n_r=8, n_mu=32, n_mu_s=16, n_phi=6, n_ray=24, n_sphere_mu=6,
                                 transmittance_r=32, transmittance_mu=128, mu_vertical_weight=0.0,
                                 r_ground_weight=0.0, sphere_phi_refinement=1, ray_quadrature="trapezoid")


def test_lambertian_ground_under_a_transparent_atmosphere_returns_the_sunlight():
    """A white ground under a transparent atmosphere returns all the sunlight (closed form).

    Under an atmosphere of 10 Pa, a white Lambertian ground sends back all the sunlight
    that reaches it, so the light leaving the top is everything intercepted less what
    crosses the limb (3.07 %). Coarse tables: within 0.2 % (measured +0.08 % on
    the tiny, coarse and default tables alike; +2.4 % coarse and +1.1 % default when the
    Sun reflected once by the ground was interpolated from the table's nodes instead of
    computed at each look-up).
    """
    excess = _balance_excess(dict(RAYLEIGH_ONLY, surface_pressure_pa=10.0), BALANCE_COARSE)
    assert abs(excess) <= 0.002, excess


@pytest.mark.slow
def test_conservation_rayleigh_white_ground():
    """Conservative Rayleigh atmosphere over a ground of albedo 1 returns what it receives.

    What it receives: the intercepted light less the direct beam that crosses the limb
    unscattered (2.51 % at 550 nm), which is not sky radiance. The issue's 0.5 % on the
    default tables (measured +0.03 %; +0.07 % before the radii were crowded towards the
    ground and the sphere quadrature's azimuths refined; +0.20 % on the former 16 x 64 x 24 x 8 with 48
    samples per ray, +0.58 % on coarse 8 x 32 x 16 x 6 tables, +0.12 % at Bruneton 2017's
    sizes).
    """
    assert abs(_balance_excess(RAYLEIGH_ONLY, TableResolution())) <= 0.005


@pytest.mark.slow
def test_conservation_albedo_one():
    """A conservative forward-peaked aerosol over a white ground: the issue's 0.5 %.

    Turbidity 2, albedo 1, default tables: the light leaving the top exceeds the
    conserving value by +0.17 % (measured; +0.39 % before the radii were crowded towards
    the ground and the azimuths refined); +0.86 % on the former default (16 x 64 x 24 x
    8, 48 samples per ray), +0.72 % at Bruneton 2017's sizes, +2.7 % on coarse
    8 x 32 x 16 x 6 tables, +6.7 % on the tiny ones (docs/multiple_scattering.md).
    """
    assert abs(_balance_excess(WITH_AEROSOL, TableResolution())) <= 0.005


@pytest.mark.slow
def test_energy_excess_falls_as_the_tables_refine():
    """The aerosol balance's excess (coarse +2.7 %, tiny +6.7 %) falls with resolution."""
    excess = [_balance_excess(WITH_AEROSOL, res) for res in (TableResolution.tiny(),
                                                              BALANCE_COARSE)]
    assert 0.0 < excess[1] < 0.6 * excess[0], excess


@pytest.mark.parametrize("altitude, view, sun", [
    (0.0, math.pi / 2, math.pi / 2),          # Sun exactly at the horizon, tangent view
    (0.0, 0.0, math.radians(108.0)),          # Sun 18 deg below the horizon
    ("top", 2.5, 0.3),                        # observer at the top looking down
    ("top", 0.2, 0.3),                        # ... looking up (empty path)
    (5000.0, 1.75, 1.2),                      # view below the horizon from 5 km
])
def test_hard_geometries_finite(day_tables, altitude, view, sun):
    _, tables = day_tables
    altitude = tables.top_altitude_m if altitude == "top" else altitude
    value = tables.radiance(altitude, view, 0.3, sun)
    assert bool(torch.isfinite(value).all()) and bool((value >= 0).all())


def test_optically_thick_haze_and_albedo_extremes():
    atm = Atmosphere.earth(aerosol_optical_depth=5.0)
    for albedo in (0.0, 1.0):
        tables = precompute_scattering(atm, torch.tensor([550.0], dtype=F64),
                                       ground_albedo=albedo, scattering_orders=4,
                                       resolution=TableResolution.tiny())
        value = tables.radiance(0.0, torch.tensor([0.0, 1.0, 1.55]), 0.0, 0.5)
        assert bool(torch.isfinite(value).all()) and bool((value > 0).all())
    # a brighter ground brightens the sky seen from the ground
    dark = precompute_scattering(Atmosphere.earth(turbidity=2.0), WAVELENGTH,
                                 ground_albedo=0.0, scattering_orders=3,
                                 resolution=TableResolution.tiny())
    bright = precompute_scattering(Atmosphere.earth(turbidity=2.0), WAVELENGTH,
                                   ground_albedo=torch.tensor([0.3, 0.8], dtype=F64),
                                   scattering_orders=3, resolution=TableResolution.tiny())
    assert bool((bright.radiance(0.0, 0.0, 0.0, 0.5) > dark.radiance(0.0, 0.0, 0.0, 0.5)).all())


def test_growing_orders_of_coarse_rays_are_refused():
    """AOD 5 on 16 trapezoid samples per ray: the orders grow from the 5th; refused.

    Measured 1, 0.35, 0.158, 0.105, 0.149, 0.355 ... 1.5e25 (radiances of 1e23 and more,
    returned until 2026-12-07 with converged=False alone). The exponential quadrature on
    the same samples converges (its orders fall monotonically).
    """
    atm = Atmosphere.earth(aerosol_optical_depth=5.0)
    wavelength = torch.tensor([550.0], dtype=F64)
    with pytest.raises(ValueError, match="orders of scattering grow"):
        precompute_scattering(atm, wavelength, scattering_orders="converged",
                              resolution=TableResolution.tiny())
    tables = precompute_scattering(atm, wavelength, scattering_orders="converged",
                                   resolution=dataclasses.replace(
                                       TableResolution.tiny(), ray_quadrature="exponential"))
    assert tables.converged
    assert bool((torch.diff(tables.order_contributions) < 0).all())


def test_float32_tables_close_to_float64_over_a_lit_ground():
    """Views of the lit ground (the reflected sunlight computed at the look-up) in float32."""
    atm = Atmosphere.earth(turbidity=2.0)
    results = [precompute_scattering(atm, WAVELENGTH, ground_albedo=0.3, scattering_orders=3,
                                     dtype=dtype, resolution=TableResolution.tiny())
               .radiance(torch.tensor([0.0, 5000.0, 1.0e5]), torch.tensor([2.0, 1.75, 3.0]),
                         0.3, 1.0)
               for dtype in (torch.float32, torch.float64)]
    assert results[0].dtype == torch.float32 and bool(torch.isfinite(results[0]).all())
    assert torch.allclose(results[0].to(F64), results[1], rtol=1e-4, atol=0.0)


def test_float32_tables_at_one_radius_equal_the_per_point_lookup():
    """Float32 tables: one altitude for an image's points equals the per-point look-up.

    The table interpolated in r once (8 corners) against 16 corners per point, both in
    float32: within a few float32 ulp (measured 5.5e-7 relative; the float32 tables
    themselves are within 2e-4 of float64 over these views, next tests).
    """
    atm = Atmosphere.earth(turbidity=2.0)
    zenith = torch.linspace(0.0, 3.1, 64, dtype=F64)[:, None]
    azimuth = torch.linspace(-3.0, 3.0, 65, dtype=F64)
    tables = precompute_scattering(atm, WAVELENGTH, scattering_orders=3, dtype=torch.float32,
                                   resolution=TableResolution.tiny())
    once = tables.radiance(torch.tensor(1234.5), zenith, azimuth, 1.0)
    per_point = tables.radiance(torch.full((64, 65), 1234.5), zenith, azimuth, 1.0)
    assert once.dtype == torch.float32 and bool(torch.isfinite(once).all())
    assert torch.allclose(once, per_point, rtol=1e-5, atol=0.0)


@pytest.mark.parametrize(("weight", "refinement"), [(0.0, 1), (0.5, 1), (0.5, 2)])
def test_float32_tables_close_to_float64(weight, refinement):
    """Float32 tables, ref. 2's view nodes and nodes towards the vertical (views at 0 rad).

    Also with the sphere quadrature's azimuths refined and the radii crowded (the default
    tables' quadrature and mapping on tiny sizes).
    """
    atm = Atmosphere.earth(turbidity=2.0)
    resolution = dataclasses.replace(TableResolution.tiny(), mu_vertical_weight=weight,
                                     r_ground_weight=weight if refinement > 1 else 0.0,
                                     sphere_phi_refinement=refinement)
    results = [precompute_scattering(atm, WAVELENGTH, scattering_orders=3, dtype=dtype,
                                     resolution=resolution)
               .radiance(0.0, torch.tensor([0.0, 1.0, 1.5]), 0.4, 1.0)
               for dtype in (torch.float32, torch.float64)]
    assert results[0].dtype == torch.float32 and bool(torch.isfinite(results[0]).all())
    assert torch.allclose(results[0].to(F64), results[1], rtol=1e-4, atol=0.0)


def test_float32_horizon_and_bounds_are_those_of_float64():
    """A view at float32(pi/2), 4e-8 rad below the horizontal, is horizontal.

    At the ground it was a ray meeting the ground at once: the orders >= 2 vanished (the
    ray-marched order 1 treats it as horizontal: geometry.ray_hits_ground). float32(pi)
    and float32(108 deg) lie above the bounds in float64 by their round-off: accepted.
    """
    atm = Atmosphere.earth(turbidity=2.0)
    tables = {dtype: precompute_scattering(atm, WAVELENGTH, scattering_orders=3, dtype=dtype,
                                           resolution=TableResolution.tiny())
              for dtype in (torch.float32, torch.float64)}
    reference = tables[F64].radiance(0.0, math.pi / 2, 1.0, 1.0)
    assert bool((reference > 0).all())
    for table, view in ((tables[torch.float32], math.pi / 2),
                        (tables[torch.float32], torch.tensor(math.pi / 2)),
                        (tables[F64], torch.tensor(math.pi / 2))):
        value = table.radiance(0.0, view, 1.0, 1.0).to(F64)
        assert torch.allclose(value, reference, rtol=1e-4, atol=0.0), (value, reference)
    for bound, name in ((math.pi, "view_zenith_rad"), (math.radians(108.0), "sun_zenith_rad")):
        angle = torch.tensor(bound)                     # float32, above the float64 bound
        assert float(angle) > bound
        args = [tables[F64].top_altitude_m, 0.0, 0.0, 0.5]
        args[1 if name == "view_zenith_rad" else 3] = angle
        assert bool(torch.isfinite(tables[F64].radiance(*args)).all())
        args[1 if name == "view_zenith_rad" else 3] = bound * (1.0 + 1e-5)
        with pytest.raises(ValueError, match=name):
            tables[F64].radiance(*args)


@pytest.mark.parametrize("dtype", [torch.float32, F64])
def test_gradient_finite_for_a_view_grazing_the_ground_from_the_top(dtype):
    """From 100 km, the view tangent to the ground: a finite gradient (was NaN in float32).

    The ground distance's discriminant is 0 there; its square root had an infinite slope.
    """
    tables = precompute_scattering(Atmosphere.earth(turbidity=2.0), WAVELENGTH,
                                   scattering_orders=2, dtype=dtype,
                                   resolution=TableResolution.tiny())
    radius, top = tables.planet_radius_m, tables.planet_radius_m + tables.top_altitude_m
    grazing = math.acos(-math.sqrt(1.0 - (radius / top) ** 2))
    for view, sun in ((grazing, 1.0), (0.5, math.pi / 2)):
        view = torch.tensor(view, dtype=F64, requires_grad=True)
        sun = torch.tensor(sun, dtype=F64, requires_grad=True)
        value = tables.radiance(tables.top_altitude_m, view, 0.0, sun)
        gradients = torch.autograd.grad(value.sum(), (view, sun))
        assert all(bool(torch.isfinite(g)) for g in gradients), gradients


def test_batched_atmosphere_matches_single_members():
    turbidity = torch.tensor([2.0, 4.0], dtype=F64)
    batched = precompute_scattering(Atmosphere.earth(turbidity=turbidity), WAVELENGTH,
                                    scattering_orders=2, resolution=TableResolution.tiny())
    value = batched.radiance(0.0, 0.3, 0.2, 0.8)
    assert value.shape == (2, 2)
    for k in range(2):
        alone = precompute_scattering(Atmosphere.earth(turbidity=float(turbidity[k])),
                                      WAVELENGTH, scattering_orders=2,
                                      resolution=TableResolution.tiny())
        assert torch.allclose(value[k], alone.radiance(0.0, 0.3, 0.2, 0.8), rtol=1e-10)


@pytest.mark.parametrize("budget", [1, 500])
def test_ray_integrals_in_blocks_equal_whole_rays(monkeypatch, budget):
    """Blocks of a few samples (the path of large tables) give the whole rays' tables."""
    from skytorch.atmosphere import multiple_scattering

    atm = Atmosphere.earth(turbidity=2.0)
    geometry = (0.0, torch.tensor([0.0, 1.0, 1.5, 1.7]), 0.4, torch.tensor([0.5, 1.0, 1.5, 1.8]))
    options = {"ground_albedo": 0.3, "scattering_orders": 3, "resolution": TableResolution.tiny()}
    whole = precompute_scattering(atm, WAVELENGTH, **options).radiance(*geometry)
    monkeypatch.setattr(multiple_scattering, "_BUDGET", budget)
    blocks = precompute_scattering(atm, WAVELENGTH, **options).radiance(*geometry)
    assert torch.allclose(blocks, whole, rtol=1e-12, atol=0.0), (blocks, whole)


def test_ray_lookup_by_matrix_product_equals_the_gathered_rows(monkeypatch):
    """Dense matrix (small tables) or gathered rows (large ones): the same tables.

    The rays' (r, mu) interpolation both ways, over a reflecting ground and with gradients.
    """
    from skytorch.atmosphere import multiple_scattering

    turbidity = torch.tensor(2.0, dtype=torch.float64, requires_grad=True)
    geometry = (0.0, torch.tensor([0.0, 1.0, 1.5, 1.7]), 0.4, torch.tensor([0.5, 1.0, 1.5, 1.8]))
    options = {"ground_albedo": 0.3, "scattering_orders": 3, "resolution": TableResolution.tiny()}
    values = []
    for nodes in (0, 1 << 30):
        monkeypatch.setattr(multiple_scattering, "_DENSE_RAY_NODES", nodes)
        atm = Atmosphere.earth(turbidity=turbidity)
        value = precompute_scattering(atm, WAVELENGTH, **options).radiance(*geometry)
        values.append((value, torch.autograd.grad(value.sum(), turbidity)[0]))
    (gathered, d_gathered), (dense, d_dense) = values
    assert torch.allclose(dense, gathered, rtol=1e-12, atol=0.0), (dense, gathered)
    assert torch.allclose(d_dense, d_gathered, rtol=1e-10), (d_dense, d_gathered)


@pytest.mark.parametrize("nodes, budget", [(0, 1), (0, 1_000_000), (1 << 30, 300)])
def test_ray_lookups_in_reused_buffers_equal_the_recorded_path(monkeypatch, nodes, budget):
    """Without gradients the ray look-ups write into buffers reused by every call.

    With gradients recorded they allocate each result: the same tables, whether the rays'
    (r, mu) rows are gathered or multiplied by a matrix, in blocks of one or many samples
    (a partial last block), over a reflecting ground.
    """
    from skytorch.atmosphere import multiple_scattering

    monkeypatch.setattr(multiple_scattering, "_DENSE_RAY_NODES", nodes)
    monkeypatch.setattr(multiple_scattering, "_BUDGET", budget)
    geometry = (0.0, torch.tensor([0.0, 1.0, 1.5, 1.7]), 0.4, torch.tensor([0.5, 1.0, 1.5, 1.8]))
    options = {"ground_albedo": 0.3, "scattering_orders": 3, "resolution": TableResolution.tiny()}
    plain = precompute_scattering(Atmosphere.earth(turbidity=2.0), WAVELENGTH,
                                  **options).radiance(*geometry)
    turbidity = torch.tensor(2.0, dtype=torch.float64, requires_grad=True)
    recorded = precompute_scattering(Atmosphere.earth(turbidity=turbidity), WAVELENGTH,
                                     **options).radiance(*geometry)
    assert recorded.requires_grad
    assert torch.allclose(recorded.detach(), plain, rtol=1e-13, atol=0.0), (recorded, plain)


def test_lookups_in_blocks_equal_one_block(monkeypatch, day_tables):
    """Look-ups in blocks of a few points (the path of large images) equal one block."""
    from skytorch.atmosphere import multiple_scattering

    _, tables = day_tables
    geometry = (torch.tensor([0.0, 5.0e3])[:, None, None], torch.linspace(0.0, 3.1, 40)[:, None],
                torch.linspace(-3.0, 3.0, 7), torch.tensor(1.2))
    monkeypatch.setattr(multiple_scattering, "_LOOKUP_BUDGET", 1 << 40)
    whole = tables.radiance(*geometry)
    monkeypatch.setattr(multiple_scattering, "_LOOKUP_BUDGET", 7)
    assert torch.equal(tables.radiance(*geometry), whole)


def test_one_observer_radius_equals_the_per_point_lookup(day_tables):
    """One altitude for all points (the table interpolated in r once) equals the per-point one.

    8 corners per point against 16 (each point given the altitude), in value and in the
    gradient with respect to the altitude.
    """
    _, tables = day_tables
    # more points than the table has (mu, mu_s, phi) rows: the path of a fisheye image
    zenith = torch.linspace(0.0, 3.1, 64, dtype=F64)[:, None]
    azimuth = torch.linspace(-3.0, 3.0, 65, dtype=F64)
    sun = torch.tensor(1.2, dtype=F64)
    for altitude_m in (0.0, 1234.5, 7.0e3):
        one = torch.tensor(altitude_m, dtype=F64, requires_grad=True)
        each = torch.full((64, 65), altitude_m, dtype=F64, requires_grad=True)
        once, per_point = (tables.radiance(a, zenith, azimuth, sun) for a in (one, each))
        assert torch.allclose(once, per_point, rtol=1e-13, atol=0.0)
        (d_once,) = torch.autograd.grad(once.sum(), one)
        (d_each,) = torch.autograd.grad(per_point.sum(), each)
        assert torch.allclose(d_once, d_each.sum(), rtol=1e-10, atol=0.0), (d_once, d_each.sum())


@pytest.mark.parametrize(("weight", "refinement", "quadrature"),
                         [(0.0, 1, "trapezoid"), (0.5, 2, "trapezoid"), (0.0, 1, "exponential")])
def test_gradcheck_turbidity_ozone_albedo(weight, refinement, quadrature):
    res = TableResolution(n_r=3, n_mu=4, n_mu_s=3, n_phi=3, n_ray=4, n_sphere_mu=2,
                          transmittance_r=4, transmittance_mu=6, mu_vertical_weight=weight,
                          r_ground_weight=weight, sphere_phi_refinement=refinement,
                          ray_quadrature=quadrature)

    def f(turbidity, ozone, albedo):
        atm = Atmosphere.earth(turbidity=turbidity, ozone_du=ozone)
        tables = precompute_scattering(atm, torch.tensor([550.0], dtype=F64),
                                       ground_albedo=albedo, scattering_orders=3,
                                       resolution=res)
        # two views of the sky from the ground, one of the lit ground from 20 km
        return tables.radiance(torch.tensor([0.0, 0.0, 2.0e4], dtype=F64),
                               torch.tensor([0.2, 1.0, 2.5], dtype=F64), 0.5, 0.7)

    inputs = tuple(torch.tensor(v, dtype=F64, requires_grad=True) for v in (2.5, 300.0, 0.3))
    assert torch.autograd.gradcheck(f, inputs, eps=1e-6, atol=1e-10, rtol=1e-4)


def test_bad_input_names_parameter_and_range(day_tables):
    atm, tables = day_tables
    with pytest.raises(ValueError, match="sun_zenith_rad"):
        tables.radiance(0.0, 0.0, 0.0, math.radians(110.0))
    with pytest.raises(ValueError, match="altitude_m"):
        tables.radiance(-5.0, 0.0, 0.0, 0.5)
    with pytest.raises(ValueError, match="scattering_orders"):
        tables.radiance(0.0, 0.0, 0.0, 0.5, scattering_orders=9)
    with pytest.raises(ValueError, match="ground_albedo"):
        precompute_scattering(atm, WAVELENGTH, ground_albedo=1.5,
                              resolution=TableResolution.tiny())
    with pytest.raises(ValueError, match="scattering_orders"):
        precompute_scattering(atm, WAVELENGTH, scattering_orders="all")
    with pytest.raises(ValueError, match="n_mu"):
        TableResolution(n_mu=7)
    with pytest.raises(ValueError, match=r"mu_vertical_weight must be in \[0, 1\]; got 1.5"):
        TableResolution(mu_vertical_weight=1.5)
    with pytest.raises(TypeError, match="mu_vertical_weight"):
        TableResolution(mu_vertical_weight="half")
    with pytest.raises(ValueError, match=r"r_ground_weight must be in \[0, 1\); got 1.0"):
        TableResolution(r_ground_weight=1.0)
    with pytest.raises(TypeError, match="r_ground_weight"):
        TableResolution(r_ground_weight=None)
    with pytest.raises(ValueError, match="sphere_phi_refinement"):
        TableResolution(sphere_phi_refinement=0)
    with pytest.raises(TypeError, match="sphere_phi_refinement"):
        TableResolution(sphere_phi_refinement=1.5)
    with pytest.raises(ValueError, match="ray_quadrature must be one of"):
        TableResolution(ray_quadrature="simpson")
    whole = TableResolution(n_r=8.0, sphere_phi_refinement=2.0)
    assert (type(whole.n_r), type(whole.sphere_phi_refinement)) == (int, int)
    with pytest.raises(ValueError, match="forward_peak"):
        precompute_scattering(atm, WAVELENGTH, forward_peak="gaussian")
    assert isinstance(tables, ScatteringTables)


def test_bools_empty_wavelengths_and_zenith_ranges_are_refused(day_tables):
    """A flag is not a number, no wavelength is no grid, 7 rad is no zenith angle.

    The single-scattering path used to accept 7 rad, which the tables' refused.
    """
    atm, tables = day_tables
    with pytest.raises(TypeError, match="view_zenith_rad must be a number .* bool"):
        tables.radiance(0.0, True, 0.0, 0.5)
    with pytest.raises(TypeError, match="sun_zenith_rad must be a number .* bool"):
        tables.diffuse_irradiance(0.0, True)
    with pytest.raises(TypeError, match="sun_zenith_rad"):
        tables.diffuse_irradiance(0.0, "0.5")
    with pytest.raises(ValueError, match="altitude_m"):
        tables.diffuse_irradiance(-10.0, 0.5)
    with pytest.raises(TypeError, match="ground_albedo"):
        precompute_scattering(atm, WAVELENGTH, ground_albedo=True,
                              resolution=TableResolution.tiny())
    with pytest.raises(ValueError, match="at least one wavelength"):
        precompute_scattering(atm, torch.tensor([], dtype=F64),
                              resolution=TableResolution.tiny())
    for orders in (1, 3):
        with pytest.raises(ValueError, match="view_zenith_rad"):
            atm.sky_radiance(WAVELENGTH, 7.0, scattering_orders=orders,
                             tables=None if orders == 1 else tables)
    with pytest.raises(ValueError, match="sun_zenith_rad"):
        atm.sky_radiance(WAVELENGTH, 0.5, sun_zenith_rad=100.0, scattering_orders=1)


def test_sky_radiance_orders_knob(day_tables):
    """Over a black ground: the ray-marched order 1 plus the tables' orders 2..N."""
    atm, tables = day_tables
    view = torch.tensor([0.0, 1.0], dtype=F64)
    single = atm.sky_radiance(WAVELENGTH, view, 0.0, 0.8, scattering_orders=1)
    multiple = atm.sky_radiance(WAVELENGTH, view, 0.0, 0.8, scattering_orders=3,
                                tables=tables)
    higher = tables.radiance(0.0, view, 0.0, 0.8) - tables.radiance(0.0, view, 0.0, 0.8,
                                                                    scattering_orders=1)
    torch.testing.assert_close(multiple, single + higher, rtol=1e-12, atol=0.0)
    assert bool((multiple > single).all())
    # the default is the converged sky, which three orders are not: refused, not summed
    assert not tables.converged
    with pytest.raises(ValueError, match="pass scattering_orders=3"):
        atm.sky_radiance(WAVELENGTH, view, 0.0, 0.8, tables=tables)
    with pytest.raises(ValueError, match="tables: scattering_orders=1"):
        atm.sky_radiance(WAVELENGTH, view, 0.0, 0.8, scattering_orders=1, tables=tables)
    with pytest.raises(ValueError, match="n_samples: parameters of the ray-marched"):
        atm.sky_radiance(WAVELENGTH, view, 0.0, 0.8, ground_albedo=0.3, n_samples=64)
    with pytest.raises(ValueError, match="scattering_orders"):
        atm.sky_radiance(WAVELENGTH, view, scattering_orders=0)
    with pytest.raises(ValueError, match="wavelengths"):
        atm.sky_radiance(torch.tensor([500.0], dtype=F64), view, scattering_orders=2,
                         tables=tables)


def test_tables_refuse_another_atmosphere_albedo_or_lost_gradient(day_tables):
    """Tables answer only for the atmosphere, ground and gradients they were built with."""
    from skytorch.moon.sky import moonlit_sky_multiple_scattering

    atm, tables = day_tables
    hazy = Atmosphere.earth(aerosol_optical_depth=3.0)
    with pytest.raises(ValueError, match="another atmosphere: angstrom_beta"):
        hazy.sky_radiance(WAVELENGTH, 0.5, 0.0, 0.8, scattering_orders=3, tables=tables)
    with pytest.raises(ValueError, match="another atmosphere"):
        moonlit_sky_multiple_scattering(hazy, tables, 0.1, 0.5, 0.5, 0.0)
    for albedo in (0.3, np.array([0.3]), torch.tensor([0.0, 0.2], dtype=F64)):
        with pytest.raises(ValueError, match="is not the tables' 0"):
            atm.sky_radiance(WAVELENGTH, 0.5, 0.0, 0.8, scattering_orders=3, tables=tables,
                             ground_albedo=albedo)
    for albedo in (None, True, "white"):
        with pytest.raises(TypeError, match="ground_albedo"):
            atm.sky_radiance(WAVELENGTH, 0.5, 0.0, 0.8, scattering_orders=3, tables=tables,
                             ground_albedo=albedo)
    with pytest.raises(ValueError, match="ground_albedo must be finite"):
        atm.sky_radiance(WAVELENGTH, 0.5, 0.0, 0.8, scattering_orders=3, tables=tables,
                         ground_albedo=float("nan"))
    # a parameter that requires a gradient the tables do not carry: refused, not dropped
    turbidity = torch.tensor(2.0, dtype=F64, requires_grad=True)
    graded = Atmosphere.earth(turbidity=turbidity)
    with torch.no_grad():
        frozen = precompute_scattering(graded, WAVELENGTH, scattering_orders=2,
                                       resolution=TableResolution.tiny())
    with pytest.raises(ValueError, match="angstrom_beta require a gradient"):
        graded.sky_radiance(WAVELENGTH, 0.5, 0.0, 0.8, scattering_orders=2, tables=frozen)
    with torch.no_grad():  # no gradient asked: the same tables serve
        graded.sky_radiance(WAVELENGTH, 0.5, 0.0, 0.8, scattering_orders=2, tables=frozen)
    carried = precompute_scattering(graded, WAVELENGTH, scattering_orders=2,
                                    resolution=TableResolution.tiny())
    assert carried.gradient_parameters == {"angstrom_beta"}
    assert graded.sky_radiance(WAVELENGTH, 0.5, 0.0, 0.8, scattering_orders=2,
                               tables=carried).requires_grad


@pytest.mark.parametrize("g", [0.0, 0.7, 0.9])
def test_forward_peak_shapes_of_henyey_greenstein(g):
    """Scattering n times by a Henyey-Greenstein function of asymmetry g is one of g^n.

    The convolution over the sphere of two Henyey-Greenstein functions is the
    Henyey-Greenstein function of the product of their asymmetries (their Legendre
    moments are g^l), an independent closed form for the Legendre sums; truncated at 256
    terms, the sum misses 0.9^256 * 513 ≈ 1e-9 of the peak for g = 0.9, 2e-8 relative at
    the backward dip (tolerance 1e-6).
    """
    from skytorch.atmosphere.multiple_scattering import forward_peak_shapes

    terms = 256
    moments = torch.tensor(g, dtype=F64) ** torch.arange(terms + 1, dtype=F64)
    shapes = forward_peak_shapes(moments, [1, 2, 3])                     # (3, nodes)
    cosine = torch.cos(torch.linspace(0.0, math.pi, shapes.shape[-1], dtype=F64))
    for k, n in enumerate((1, 2, 3)):
        gn = g ** n
        closed = (1 - gn * gn) / (4 * math.pi * (1 + gn * gn - 2 * gn * cosine) ** 1.5)
        torch.testing.assert_close(shapes[k], closed, rtol=1e-6, atol=0.0)


def test_forward_peak_shape_of_rayleigh():
    """Moments (1, 0, 1/10): one scattering is 3/(16π)(1 + cos²Θ) [sr^-1]."""
    from skytorch.atmosphere.multiple_scattering import forward_peak_shapes

    moments = torch.zeros(257, dtype=F64)
    moments[0], moments[2] = 1.0, 0.1
    shape = forward_peak_shapes(moments, [1])[0]
    cosine = torch.cos(torch.linspace(0.0, math.pi, shape.shape[-1], dtype=F64))
    torch.testing.assert_close(shape, 3 / (16 * math.pi) * (1 + cosine ** 2), rtol=1e-12,
                               atol=0.0)


def test_forward_peak_factoring_leaves_a_molecular_sky():
    """Molecules alone: the factored and the plain look-up agree within 1.5 %.

    Rayleigh's shapes vary by a few % with the scattering angle, so factoring them out
    barely changes the interpolation; the sky (ground, view zenith 0-80 deg, three
    azimuths, Sun 20-100 deg) must not move by more than the coarse tables' own error
    against DISORT (1.3-2.3 %). Measured 0.7 % (Sun 100 deg, view 40 deg, anti-solar).
    """
    atm = Atmosphere.earth(aerosol_optical_depth=0.0, ozone_du=0.0,
                           precipitable_water_cm=0.0)
    plain, factored = (precompute_scattering(atm, WAVELENGTH, scattering_orders=4,
                                             resolution=COARSE, forward_peak=mode)
                       for mode in ("none", "factored"))
    view = torch.deg2rad(torch.tensor([0.0, 40.0, 80.0], dtype=F64))[:, None, None]
    azimuth = torch.tensor([0.0, 1.5, 3.1], dtype=F64)[None, :, None]
    sun = torch.deg2rad(torch.tensor([20.0, 50.0, 85.0, 95.0, 100.0], dtype=F64))
    ratio = factored.radiance(0.0, view, azimuth, sun) / plain.radiance(0.0, view, azimuth,
                                                                         sun)
    assert float((ratio - 1).abs().max()) < 0.015


@pytest.mark.parametrize("weight", [0.25, 0.5, 0.9])
def test_radius_nodes_towards_the_ground_invert_exactly(weight):
    """``r_ground_weight``: the look-up's coordinate of each radius node is its index.

    Closed forms both ways; they agree to 1e-12 at every node, the lowest node above the
    ground comes about (1 - w)^2 times as high (height ~ rho^2 / 2R; ref. 2's mapping
    of 16 radii under a 100 km top: 448 m), and the coordinate has a finite derivative on the
    ground.
    """
    from skytorch.atmosphere.multiple_scattering import _Shell

    shell, plain = _Shell(6.371e6, 6.471e6, 0.0, weight), _Shell(6.371e6, 6.471e6)
    nodes = torch.linspace(0.0, 1.0, 16, dtype=F64)
    radii = shell.r_of(nodes)
    assert float((shell.x_of_r(radii) - nodes).abs().max()) < 1e-12
    assert bool((radii[1:] > radii[:-1]).all())
    low, low_plain = float(radii[1]) - 6.371e6, float(plain.r_of(nodes)[1]) - 6.371e6
    assert 446.0 < low_plain < 450.0
    # heights near the ground go as the square of rho: the first spacing (1 - w + w/15)
    assert low / low_plain == pytest.approx((1 - weight + weight / 15) ** 2, rel=1e-3)
    r = torch.tensor(6.371e6 + 1.0, dtype=F64, requires_grad=True)
    (slope,) = torch.autograd.grad(shell.x_of_r(r), r)
    assert math.isfinite(float(slope))


@pytest.mark.parametrize("weight", [0.5, 1.0])
def test_view_nodes_towards_the_vertical_invert_exactly(weight):
    """``mu_vertical_weight``: the look-up's node coordinate of each table node is its index.

    The table places its view-zenith nodes by inverting the node coordinate (Newton's
    method) and looks up by the closed form; at every radius, on both sides of the horizon
    (the horizon itself excepted: the seam), the two agree to 1e-12, and the nodes near the vertical are denser than ref. 2's: from
    the top the first node after the nadir moves from 41 deg to 15.5 deg (w 1/2) and
    8.3 deg (w 1).
    """
    from skytorch.atmosphere.multiple_scattering import _Shell

    shell = _Shell(6.371e6, 6.471e6, weight)
    plain = _Shell(6.371e6, 6.471e6)
    nodes = torch.linspace(0.0, 1.0, 32, dtype=F64)
    for radius in (6.371e6 + 1.0, 6.372e6, 6.39e6, 6.471e6):
        r = torch.tensor(radius, dtype=F64)
        for ground in (True, False):
            mu = shell.mu_of(r, nodes, ground=ground)
            side, coordinate = shell.mu_coordinate(r, mu)
            # the last node is the horizon, the table's seam (read from the sky side)
            assert bool((side[:-1] == ground).all())
            assert float((coordinate - nodes)[:-1].abs().max()) < 1e-12
    top = torch.tensor(6.471e6, dtype=F64)
    first = math.degrees(math.acos(-float(shell.mu_of(top, nodes[1:2], ground=True))))
    before = math.degrees(math.acos(-float(plain.mu_of(top, nodes[1:2], ground=True))))
    assert before > 40.0 and first < (16.0 if weight == 0.5 else 9.0)


@pytest.mark.parametrize("turbidity, albedo", [(1.5, 0.0), (6.0, 0.3)])
def test_converged_sum_with_geometric_remainder_against_a_long_series(turbidity, albedo):
    """The ``"converged"`` sky with its extrapolated remainder against 40 orders summed.

    The reference is the same tables' series carried to 40 orders (its last order below
    1e-7 of the sum, a converged run of the same algorithm). Measured on these tables:
    at most 2.9e-4 (7 orders) and 5.2e-4 (15 orders) relative, against 1.5e-3 (9 orders)
    and 3.7e-3 (20 orders) for the sum stopped where the last order fell below 1e-4 of
    the whole table (until 2026-12-06): the twilight's nodes, small in that sum, converge
    more slowly (docs/multiple_scattering.md, "Converged orders").
    """
    atm = Atmosphere.earth(turbidity=turbidity, ozone_du=300.0)
    resolution = TableResolution(n_r=5, n_mu=16, n_mu_s=24, n_phi=5, n_ray=16, n_sphere_mu=4,
                                 transmittance_r=16, transmittance_mu=32,
                                 mu_vertical_weight=0.0,
                                 r_ground_weight=0.0, sphere_phi_refinement=1, ray_quadrature="trapezoid")
    converged = precompute_scattering(atm, WAVELENGTH, ground_albedo=albedo,
                                      scattering_orders="converged", resolution=resolution)
    series = precompute_scattering(atm, WAVELENGTH, ground_albedo=albedo,
                                   scattering_orders=40, resolution=resolution)
    assert converged.converged and converged.remainder_extrapolated
    assert converged.orders_computed < 20
    assert float(series.order_contributions[-1] / series.order_contributions.sum()) < 1e-7
    view = torch.linspace(0.0, 1.5, 11, dtype=F64)[:, None, None]
    azimuth = torch.tensor([0.0, 1.5, 3.1], dtype=F64)[None, :, None]
    sun = torch.deg2rad(torch.tensor([20.0, 60.0, 85.0, 92.0, 96.0, 100.0, 104.0, 108.0],
                                     dtype=F64))[None, None, :]
    ours = converged.radiance(0.0, view, azimuth, sun)
    reference = series.radiance(0.0, view, azimuth, sun)
    assert float(((ours - reference).abs() / reference).max()) < 1e-3
    # an integer number of orders sums exactly those orders (no remainder)
    n = converged.orders_computed
    exact = series.radiance(0.0, view, azimuth, sun, scattering_orders=n)
    assert torch.allclose(converged.radiance(0.0, view, azimuth, sun, scattering_orders=n),
                          exact, rtol=1e-12, atol=0.0)
    assert not torch.allclose(ours, exact, rtol=1e-6, atol=0.0)


def test_batched_converged_tables_equal_each_member_alone():
    """A batch stops where each member's last order is negligible, keeping the remainder.

    The stopping rule "last order below 1e-4 of the sum" was judged on the whole batch's sum
    and dropped the extrapolated remainder: turbidity 6 in a 3 x 2 batch was 0.25 / 0.35 %
    short of a 40-order series at Sun 100 / 108 deg where built alone it was within 3e-5.
    """
    turbidity = torch.tensor([1.5, 3.0, 6.0], dtype=F64)[:, None]
    ozone = torch.tensor([250.0, 400.0], dtype=F64)[None, :]
    batch = precompute_scattering(Atmosphere.earth(turbidity=turbidity, ozone_du=ozone),
                                  WAVELENGTH, scattering_orders="converged",
                                  resolution=TableResolution.tiny())
    alone = precompute_scattering(Atmosphere.earth(turbidity=6.0, ozone_du=250.0),
                                  WAVELENGTH, scattering_orders="converged",
                                  resolution=TableResolution.tiny())
    assert batch.converged and batch.remainder_extrapolated
    for degrees in (30.0, 96.0, 100.0, 108.0):
        sun = torch.tensor(math.radians(degrees), dtype=F64)
        member = batch.radiance(0.0, 0.0, 0.0, sun)[2, 0]
        assert torch.allclose(member, alone.radiance(0.0, 0.0, 0.0, sun), rtol=1e-10,
                              atol=0.0)


def test_lookups_under_no_grad_keep_the_gradient_of_later_lookups():
    """A preview under torch.no_grad() does not cache a table without its graph.

    dL/dturbidity was 0.0037 after such a preview and 0.0513 without it.
    """
    def gradient(preview):
        turbidity = torch.tensor(2.0, dtype=F64, requires_grad=True)
        tables = precompute_scattering(Atmosphere.earth(turbidity=turbidity), WAVELENGTH,
                                       scattering_orders=3, resolution=TableResolution.tiny())
        if preview:
            with torch.no_grad():
                tables.radiance(0.0, 0.5, 0.3, 0.8)
        return torch.autograd.grad(tables.radiance(0.0, 0.5, 0.3, 0.8).sum(), turbidity)[0]

    assert torch.allclose(gradient(True), gradient(False), rtol=1e-12)


def test_converged_remainder_gradient_and_float32():
    """The converged sky's remainder carries gradients and holds in float32.

    The gradient w.r.t. turbidity (autograd through the orders and the extrapolated
    remainder) against the central difference (h 1e-3) of the series carried to 40
    orders, an independent estimate of the limit's derivative: measured 3e-5 (Sun 40 deg)
    and 6e-4 (Sun 96 deg) relative. Tables in float32 stop at the same order and are
    within 5.7e-6 relative of float64.
    """
    wavelength = torch.tensor([450.0], dtype=F64)
    resolution = TableResolution(n_r=5, n_mu=16, n_mu_s=16, n_phi=5, n_ray=16, n_sphere_mu=4,
                                 transmittance_r=16, transmittance_mu=32,
                                 mu_vertical_weight=0.0,
                                 r_ground_weight=0.0, sphere_phi_refinement=1, ray_quadrature="trapezoid")
    view = torch.tensor([0.0, 1.0], dtype=F64)
    sun = torch.deg2rad(torch.tensor([40.0, 96.0], dtype=F64))

    def build(turbidity, scattering_orders, dtype=torch.float64):
        return precompute_scattering(Atmosphere.earth(turbidity=turbidity), wavelength,
                                     ground_albedo=0.3, scattering_orders=scattering_orders,
                                     resolution=resolution, dtype=dtype)

    turbidity = torch.tensor(3.0, dtype=F64, requires_grad=True)
    converged = build(turbidity, "converged")
    assert converged.remainder_extrapolated
    sky = converged.radiance(0.0, view, 0.5, sun)[..., 0]
    gradient = torch.stack([torch.autograd.grad(sky[i], turbidity, retain_graph=True)[0]
                            for i in range(2)])
    h = 1e-3
    difference = (build(torch.tensor(3.0 + h, dtype=F64), 40).radiance(0.0, view, 0.5, sun)
                  - build(torch.tensor(3.0 - h, dtype=F64), 40).radiance(0.0, view, 0.5, sun)
                  )[..., 0] / (2 * h)
    assert torch.allclose(gradient, difference, rtol=2e-3, atol=0.0), (gradient, difference)

    single = build(3.0, "converged", torch.float32)
    assert single.remainder_extrapolated
    assert single.orders_computed == converged.orders_computed
    ours = single.radiance(0.0, view, 0.5, sun).to(F64)
    assert torch.allclose(ours, sky.detach()[..., None], rtol=1e-4, atol=0.0)


def _fine_integral(step, depth_fn, source_fn, n=200_001):
    """Trapezoid of source x exp(-depth) on a fine grid over [0, sum(step)]."""
    s = torch.linspace(0.0, float(step.sum()), n, dtype=F64)
    return torch.trapezoid(source_fn(s) * torch.exp(-depth_fn(s)), s)


@pytest.mark.parametrize("extinction", [1e-7, 1e-3, 0.2, 5.0])
def test_exponential_path_weights_against_fine_quadrature(extinction):
    """Exact for a linear source in a uniform medium, from thin to thick segments.

    Reference: the trapezoid on 200 001 points (a converged run of another rule).
    Six segments of uneven length [km] with extinction ``extinction`` [km^-1]: optical
    depths per segment from 1e-7 (the Taylor branch) to 25.
    """
    knots = torch.tensor([0.0, 0.3, 1.0, 1.2, 2.5, 4.0, 5.0], dtype=F64)
    step = (knots[1:] - knots[:-1])[:, None]
    depth = (extinction * knots)[:, None]
    source = 2.0 + 0.7 * knots                                        # linear everywhere
    weights = multiple_scattering.exponential_path_weights(step, depth)
    ours = float((weights[:, 0] * source).sum())
    reference = float(_fine_integral(step, lambda s: extinction * s, lambda s: 2.0 + 0.7 * s))
    assert ours == pytest.approx(reference, rel=1e-8)
    trapezoid = float(torch.trapezoid(source * torch.exp(-depth[:, 0]), knots))
    if extinction >= 0.2:                       # where the trapezoid on T J is wrong
        assert abs(trapezoid / reference - 1) > 100 * abs(ours / reference - 1)


def test_exponential_path_weights_continuous_with_finite_gradients():
    """Both sides of the Taylor branch agree; gradients finite at zero optical depth."""
    step = torch.ones(1, 1, dtype=F64)
    for edge in (1e-3 * (1 - 1e-9), 1e-3 * (1 + 1e-9)):
        depth = torch.tensor([[0.0], [edge]], dtype=F64)
        w = multiple_scattering.exponential_path_weights(step, depth)
        exact = torch.tensor([-math.expm1(-edge) / edge], dtype=F64)  # E0 = w_lower + w_upper
        assert float(w.sum()) == pytest.approx(float(exact), rel=1e-13)

    def f(depth):
        return multiple_scattering.exponential_path_weights(
            step, torch.cat([torch.zeros_like(depth[:1]), depth]))

    for value in (0.0, 5e-4, 2e-3, 3.0):
        x = torch.tensor([[value]], dtype=F64, requires_grad=True)
        assert torch.autograd.gradcheck(f, (x,), eps=1e-7, atol=1e-9, rtol=1e-5)


def test_exponential_ray_quadrature_nearer_converged_rays():
    """Order 1 of tables on 24 samples per ray against the same tables on 384 (trapezoid).

    Through a haze of turbidity 8 the trapezoid on 24 samples overestimates the single
    scattering of the long rays near the horizon by up to 39 % (450 nm, view zenith 89°);
    the exponential quadrature (columns from sub-samples, transmittance exponential between
    samples) holds every view within 3.1 % (its rest: the source's curvature between samples).
    """
    atm = Atmosphere.earth(turbidity=8.0)
    base = dict(n_r=5, n_mu=16, n_mu_s=8, n_phi=5, n_sphere_mu=4, transmittance_r=16,
                transmittance_mu=32, mu_vertical_weight=0.0, r_ground_weight=0.0,
                sphere_phi_refinement=1)
    geometry = (torch.tensor(0.0, dtype=F64), torch.deg2rad(torch.tensor(
        [0.0, 45.0, 75.0, 85.0, 89.0], dtype=F64))[:, None], torch.tensor([0.0, 2.0], dtype=F64),
        torch.tensor(math.radians(60.0), dtype=F64))

    def order_one(quadrature, n_ray):
        tables = precompute_scattering(atm, WAVELENGTH, scattering_orders=1, resolution=(
            TableResolution(**base, n_ray=n_ray, ray_quadrature=quadrature)))
        return tables.radiance(*geometry)

    converged = order_one("trapezoid", 384)
    trapezoid = (order_one("trapezoid", 24) / converged - 1).abs().max()
    exponential = (order_one("exponential", 24) / converged - 1).abs().max()
    assert exponential < 0.04
    assert exponential < trapezoid / 5


def test_tables_refuse_pickling_by_name_and_deep_copy():
    """A raw AttributeError named a local closure; deepcopy gives equal look-ups."""
    import copy
    import pickle

    tables = precompute_scattering(Atmosphere.earth(), WAVELENGTH, scattering_orders=2,
                                   resolution=TableResolution.tiny())
    with pytest.raises(TypeError, match="cannot be pickled"):
        pickle.dumps(tables)
    twin = copy.deepcopy(tables)
    assert torch.equal(twin.radiance(0.0, 0.5, 0.0, 0.8), tables.radiance(0.0, 0.5, 0.0, 0.8))
