"""sasktran2's twilight sky with several solar-zenith source columns against the Monte-Carlo.

Provenance: ``tests/data/ms_reference/sasktran2_twilight.nc`` was written by
``OMP_NUM_THREADS=1 .venv/bin/python tests/data/ms_reference/generate_sasktran2.py twilight``
(sasktran2 2026.10.1, scalar, spherical successive orders, skytorch's optics as Manual
constituents on the grid of ``sasktran2_sky.nc``; 1122 s on one thread). It holds the
successive-orders sky for ``num_sza`` = 1, 8 and 16 (the multiple-scattering source on
that many solar-zenith columns, spaced linearly in cos(solar zenith) over the range met
along the lines of sight), Sun zenith 90, 94, 98, 102 deg, 400 and 550 nm, cases
``rayleigh`` and ``rayleigh_aerosol`` (aerosol optical depth 0.1 at 550 nm), at the seven
views of the Monte-Carlo table ``montecarlo_sky.nc`` (``generate_montecarlo.py``).

The question these tests record: is the twilight excess of sasktran2's successive orders
over the Monte-Carlo (1.4-8x at the zenith, Sun 94-102 deg, with ``num_sza = 1``) the
single-solar-zenith approximation of the source? Measured answer: no. ``num_sza = 16``
agrees with 8 to 3.5 % up to Sun 94 deg and moves the zenith by < 1 %, yet stays above
the Monte-Carlo at every decisive view at Sun 94 deg (+11 % to 10.7x). The single
scattering agrees with the Monte-Carlo's order 1; the excess is already in sasktran2's
first multiple-scattering iteration (order 2), which matches the Monte-Carlo's order 2 by
day (slow live test below).

A view is *decisive* where the Monte-Carlo's relative standard error is below
``DECISIVE_STDERR``. All quantities are radiances per unit TOA solar irradiance [sr^-1].
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

DATA = Path(__file__).parent / "data" / "ms_reference"
TWILIGHT = DATA / "sasktran2_twilight.nc"
MONTECARLO = DATA / "montecarlo_sky.nc"
SKY = DATA / "sasktran2_sky.nc"

PERCENT = 0.01
#: Monte-Carlo relative standard error below which a view decides a comparison
DECISIVE_STDERR = 5 * PERCENT
#: sasktran2 single scattering vs Monte-Carlo order 1: the larger of 3 sigma and this
#: (the day-sky agreement of the two, <= 0.6 %, plus the twilight optical-depth table's
#: 4e-3 in tau; measured <= 1.3 % at Sun 90-94 deg, <= 3.9 % = 0.8 bound at 98 deg)
SINGLE_SCATTERING_FLOOR = 2 * PERCENT
#: num_sza = 16 against 8, Sun 90-94 deg, decisive views (measured <= 3.5 %)
NUM_SZA_CONVERGED = 5 * PERCENT
#: from Sun 98 deg num_sza = 16 still differs from 8 by more than this (measured 25 %, 16 %)
NUM_SZA_NOT_CONVERGED = 10 * PERCENT
#: zenith change from num_sza = 1 to 16 at Sun 90-94 deg (the solar zenith is constant
#: along the zenith line of sight; measured <= 0.8 %)
ZENITH_NUM_SZA_EFFECT = 2 * PERCENT
#: Sun 90 deg, 550 nm, num_sza = 16 against the Monte-Carlo: the day-sky level of
#: agreement of the three codes (2 %) plus the num_sza residual (measured 2.9 %)
SUN_90_GREEN = 4 * PERCENT
#: Sun 94 deg, num_sza = 16: excess over the Monte-Carlo in units of its sigma at every
#: decisive view, and at the zenith in relative terms (measured >= +11 % at sigma <= 1.9 %,
#: zenith +42 % to 5.0x)
EXCESS_SIGMAS = 5.0
ZENITH_EXCESS = 30 * PERCENT
#: other successive-orders settings at Sun 94 deg (measured <= 11.6 %: the legacy source)
SETTINGS_SPREAD = 15 * PERCENT
#: sasktran2's first multiple-scattering iteration against the Monte-Carlo's order 2:
#: by day the larger of 3 sigma and this (measured <= 1 %), at Sun 94 deg its excess
#: (measured 1.43x to 11.7x at the 14 Rayleigh views, MC sigma <= 2.9 %)
ORDER_TWO_DAY = 2 * PERCENT
ORDER_TWO_TWILIGHT_EXCESS = 30 * PERCENT


@pytest.fixture(scope="module")
def twilight() -> xr.Dataset:
    with xr.open_dataset(TWILIGHT) as ds:
        return ds.load()


@pytest.fixture(scope="module")
def montecarlo(twilight) -> xr.Dataset:
    with xr.open_dataset(MONTECARLO) as ds:
        return ds.sel(sun_zenith=twilight.sun_zenith.values,
                      wavelength=twilight.wavelength.values).load()


def _decisive(montecarlo) -> xr.DataArray:
    return montecarlo.total_stderr / montecarlo.total < DECISIVE_STDERR


def _generator():
    spec = importlib.util.spec_from_file_location("generate_sasktran2",
                                                  DATA / "generate_sasktran2.py")
    generator = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(generator)
    return generator


def test_table_is_on_the_montecarlo_views(twilight, montecarlo):
    """Same cases, views (view zenith, relative azimuth) and coordinates as the MC."""
    assert list(twilight.case.values) == list(montecarlo.case.values)
    np.testing.assert_array_equal(twilight.view_zenith.values, montecarlo.view_zenith.values)
    np.testing.assert_array_equal(twilight.relative_azimuth.values,
                                  montecarlo.relative_azimuth.values)
    assert list(twilight.num_sza.values) == [1, 8, 16]
    assert twilight.successive_orders.attrs["units"] == "sr-1"
    assert "sasktran2 2026.10.1" in twilight.attrs["source"]
    assert np.isfinite(twilight.successive_orders).all()


def test_num_sza_one_is_the_shipped_sky_table(twilight):
    """num_sza = 1 reproduces sasktran2_sky.nc (same code and settings, other views)."""
    with xr.open_dataset(SKY) as sky:
        sky = sky.sel(case=twilight.case.values, sun_zenith=twilight.sun_zenith.values,
                      wavelength=twilight.wavelength.values).load()
    for name in ("successive_orders", "single_scattering"):
        grid = sky[name]
        shipped = np.stack([grid.sel(view_zenith=vz, relative_azimuth=az).values
                            for vz, az in zip(twilight.view_zenith.values,
                                              twilight.relative_azimuth.values,
                                              strict=True)], axis=-1)
        ours = twilight[name]
        if "num_sza" in ours.dims:
            ours = ours.sel(num_sza=1)
        np.testing.assert_allclose(ours.values, shipped, rtol=1e-12, atol=0.0)


def test_single_scattering_matches_montecarlo_order_one(twilight, montecarlo):
    """Order 1 is common ground: within max(3 sigma, 2 %) wherever the MC decides it."""
    order_1 = montecarlo.order_1
    sigma = montecarlo.order_1_stderr / order_1
    decided = (order_1 > 0) & (sigma < DECISIVE_STDERR)
    assert int(decided.sum()) >= 70
    error = np.abs(twilight.single_scattering / order_1 - 1.0).where(decided)
    bound = np.maximum(3.0 * sigma, SINGLE_SCATTERING_FLOOR)
    assert bool((error <= bound).where(decided, True).all()), float((error / bound).max())
    # both put the same views wholly in the Earth's shadow
    np.testing.assert_array_equal(twilight.single_scattering.values == 0.0,
                                  order_1.values == 0.0)


def test_num_sza_is_converged_to_sun_94(twilight, montecarlo):
    """num_sza = 16 against 8: within 5 % at every decisive view, Sun 90 and 94 deg."""
    so = twilight.successive_orders.sel(sun_zenith=[90.0, 94.0])
    change = np.abs(so.sel(num_sza=16) / so.sel(num_sza=8) - 1.0)
    change = change.where(_decisive(montecarlo).sel(sun_zenith=[90.0, 94.0]))
    assert float(change.max()) < NUM_SZA_CONVERGED, float(change.max())


def test_num_sza_is_not_converged_from_sun_98(twilight, montecarlo):
    """Documented fact: at Sun 98 and 102 deg num_sza = 8 and 16 still differ by > 10 %."""
    so = twilight.successive_orders
    change = np.abs(so.sel(num_sza=16) / so.sel(num_sza=8) - 1.0).where(_decisive(montecarlo))
    for sun_zenith in (98.0, 102.0):
        worst = float(change.sel(sun_zenith=sun_zenith).max())
        assert worst > NUM_SZA_NOT_CONVERGED, (sun_zenith, worst)


def test_num_sza_hardly_moves_the_zenith(twilight):
    """Zenith, Sun 90-94 deg: num_sza = 16 differs from 1 by < 2 %."""
    zenith = twilight.successive_orders.sel(view=0, sun_zenith=[90.0, 94.0])
    change = np.abs(zenith.sel(num_sza=16) / zenith.sel(num_sza=1) - 1.0)
    assert float(change.max()) < ZENITH_NUM_SZA_EFFECT, float(change.max())


def test_num_sza_brings_sun_90_at_550_nm_to_the_montecarlo(twilight, montecarlo):
    """Sun at the horizon, 550 nm: num_sza = 16 is within 4 % of the MC (num_sza = 1: 5.7 %)."""
    so = twilight.successive_orders.sel(sun_zenith=90.0, wavelength=550.0)
    mc = montecarlo.total.sel(sun_zenith=90.0, wavelength=550.0)
    many = float(np.abs(so.sel(num_sza=16) / mc - 1.0).max())
    one = float(np.abs(so.sel(num_sza=1) / mc - 1.0).max())
    assert many < SUN_90_GREEN, many
    assert many < one


def test_larger_num_sza_does_not_reach_the_montecarlo_at_sun_94(twilight, montecarlo):
    """Documented disagreement: num_sza = 16 stays brighter than the MC at Sun 94 deg.

    Every decisive view (all 28, sigma <= 1.9 %) is more than 5 sigma above the MC, the
    zenith more than 30 % (+42 % to 5.0x); the day sky agrees within 2 %.
    """
    so = twilight.successive_orders.sel(num_sza=16, sun_zenith=94.0)
    mc = montecarlo.sel(sun_zenith=94.0)
    decided = _decisive(montecarlo).sel(sun_zenith=94.0)
    assert bool(decided.all())
    excess = (so - mc.total) / mc.total_stderr
    assert float(excess.min()) > EXCESS_SIGMAS, float(excess.min())
    zenith = so.sel(view=0) / mc.total.sel(view=0) - 1.0
    assert float(zenith.min()) > ZENITH_EXCESS, zenith.values


def test_other_successive_orders_settings_do_not_close_the_gap(twilight, montecarlo):
    """Sun 94 deg, Rayleigh: other settings move the sky < 15 %, the gap stays > 30 %.

    Rows: legacy interpolation, Lebedev incoming rule, 302 incoming / outgoing points,
    50 plain (Picard) iterations, the legacy successive-orders source.
    """
    rows = twilight.settings_sensitivity
    spread = np.abs(rows / rows.sel(setting="default") - 1.0)
    assert float(spread.max()) < SETTINGS_SPREAD, float(spread.max())
    mc = montecarlo.total.sel(case="rayleigh", sun_zenith=94.0)
    zenith = rows.sel(view=0) / mc.sel(view=0) - 1.0
    assert float(zenith.min()) > ZENITH_EXCESS, zenith.values


@pytest.mark.slow
def test_live_sasktran2_reproduces_a_num_sza_row(twilight):
    """sasktran2 run live (Rayleigh, Sun 102 deg, num_sza = 8, ~40 s) reproduces the file."""
    sk = pytest.importorskip("sasktran2")
    generator = _generator()
    wavelength = twilight.wavelength.values
    constituents = generator.manual_constituents(generator.skytorch_atmosphere(0.0),
                                                 wavelength)
    live = generator.run(constituents, 102.0, sk.MultipleScatterSource.SuccessiveOrders,
                         num_sza=8, wavelength_nm=wavelength,
                         views=generator.TWILIGHT_VIEWS)
    shipped = twilight.successive_orders.sel(num_sza=8, case="rayleigh", sun_zenith=102.0)
    np.testing.assert_allclose(live, shipped.values, rtol=1e-6)


@pytest.mark.slow
def test_live_sasktran2_order_two_against_montecarlo():
    """Where the twilight excess is: sasktran2's first multiple-scattering iteration.

    One Picard iteration of the successive orders minus the single scattering is
    sasktran2's order 2 (Rayleigh, num_sza = 1, ~10 s). By day (Sun 60 deg) it is the
    Monte-Carlo's order 2 within max(3 sigma, 2 %); at Sun 94 deg it is more than 30 %
    above it at every view (the MC's order 2 there agrees with a deterministic
    double-scattering quadrature, tests/test_ms_montecarlo.py).
    """
    sk = pytest.importorskip("sasktran2")
    generator = _generator()
    wavelength = np.array([400.0, 550.0])
    constituents = generator.manual_constituents(generator.skytorch_atmosphere(0.0),
                                                 wavelength)
    one_iteration = {"successive_orders_anderson_depth": 0,
                     "successive_orders_relative_tolerance": 0.0,
                     "successive_orders_absolute_tolerance": 0.0,
                     "num_successive_orders_iterations": 1}
    with xr.open_dataset(MONTECARLO) as ds:
        mc = ds.sel(case="rayleigh", wavelength=wavelength).load()
    ratios = {}
    for sun_zenith in (60.0, 94.0):
        common = dict(wavelength_nm=wavelength, views=generator.TWILIGHT_VIEWS)
        single = generator.run(constituents, sun_zenith, sk.MultipleScatterSource.NoSource,
                               **common)
        two = generator.run(constituents, sun_zenith,
                            sk.MultipleScatterSource.SuccessiveOrders,
                            config_options=one_iteration, **common)
        order_2 = mc.order_2.sel(sun_zenith=sun_zenith).values
        sigma = (mc.order_2_stderr.sel(sun_zenith=sun_zenith) / mc.order_2.sel(
            sun_zenith=sun_zenith)).values
        assert sigma.max() < DECISIVE_STDERR
        ratios[sun_zenith] = ((two - single) / order_2, sigma)
    ratio, sigma = ratios[60.0]
    assert (np.abs(ratio - 1.0) <= np.maximum(3.0 * sigma, ORDER_TWO_DAY)).all(), ratio
    ratio, _ = ratios[94.0]
    assert ratio.min() > 1.0 + ORDER_TWO_TWILIGHT_EXCESS, ratio
