"""Ground-level sky radiance against sasktran2 (independent spherical RT code).

The reference table ``tests/data/ms_reference/sasktran2_sky.nc`` was written by
``tests/data/ms_reference/generate_sasktran2.py`` from skytorch's own optics (extinction,
single-scattering albedo, phase functions) handed to sasktran2 as user-defined
constituents, so these tests check the radiative transfer, not the optics. Tolerances
are in relative radiance (per unit TOA solar irradiance, [sr^-1]).

Only 400 and 550 nm are compared: at 700 nm skytorch's O2 band is a curve-of-growth band
law (slant optical depth 0.038 vertically) that has no local extinction coefficient, so
the Manual constituents miss it and single scattering differs by 8-14 % there (reported
in docs/multiple_scattering_validation.md).
"""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
import torch
import xarray as xr

import skytorch as st

DATA = Path(__file__).parent / "data" / "ms_reference"
TABLE = DATA / "sasktran2_sky.nc"
HAS_SOLVER = importlib.util.find_spec("skytorch.atmosphere.multiple_scattering") is not None


@pytest.fixture(scope="module")
def reference() -> xr.Dataset:
    with xr.open_dataset(TABLE) as ds:
        return ds.load()


def _atmosphere(aod: float) -> st.Atmosphere:
    return st.Atmosphere.earth(ozone_du=0.0, precipitable_water_cm=0.0,
                               aerosol_phase_model="henyeygreenstein1941",
                               aerosol_optical_depth=aod, angstrom_alpha=1.3,
                               aerosol_asymmetry=0.7, aerosol_single_scattering_albedo=0.95)


#: wavelengths outside skytorch's band-model absorption (see the module docstring) [nm]
WAVELENGTH_NM = [400.0, 550.0]


def _grid(ds):
    ds = ds.sel(wavelength=WAVELENGTH_NM)
    wavelength = torch.tensor(ds.wavelength.values, dtype=torch.float64)
    view_zenith = torch.deg2rad(torch.tensor(ds.view_zenith.values, dtype=torch.float64))
    azimuth = torch.deg2rad(torch.tensor(ds.relative_azimuth.values, dtype=torch.float64))
    return wavelength, view_zenith[:, None], azimuth[None, :]


@pytest.mark.parametrize("case", ["rayleigh", "rayleigh_aerosol"])
@pytest.mark.parametrize("sun_zenith_deg", [30.0, 60.0, 80.0])
def test_single_scattering_matches_sasktran2(reference, case, sun_zenith_deg):
    """The optics handed to sasktran2 are skytorch's: single scattering agrees to 2 %.

    This proves the inputs of the multiple-scattering comparison are matched (geometry,
    azimuth convention, cross sections, phase functions, absorption).
    """
    ref = reference.sel(case=case, sun_zenith=sun_zenith_deg, wavelength=WAVELENGTH_NM)
    wavelength, view_zenith, azimuth = _grid(reference)
    atm = _atmosphere(float(ref.aerosol_optical_depth))
    ours = atm.sky_radiance(wavelength, view_zenith, azimuth,
                            math.radians(sun_zenith_deg), 0.0, 1.0, scattering_orders=1)  # (vz, az, wl)
    theirs = torch.tensor(ref.single_scattering.transpose("view_zenith", "relative_azimuth",
                                                          "wavelength").values)
    relative = (ours / theirs - 1.0).abs()
    assert relative.max() < 0.02, f"max relative difference {relative.max():.4f}"


def test_sasktran2_sources_agree_for_the_day_sky(reference):
    """The reference is converged: successive orders vs discrete ordinates within 3 %."""
    day = reference.sel(sun_zenith=[30.0, 60.0])
    ratio = day.successive_orders / day.discrete_ordinates
    assert float(abs(ratio - 1.0).max()) < 0.03


def test_multiple_scattering_is_a_large_part_of_the_twilight_sky(reference):
    """In the reference, single scattering is a small part of the sky at Sun -8 deg."""
    zenith = reference.sel(sun_zenith=98.0, view_zenith=0.0, relative_azimuth=0.0)
    fraction = zenith.single_scattering / zenith.successive_orders
    assert float(fraction.max()) < 0.5


def _compare(reference, case, cases, resolution=None):
    """Max relative difference to sasktran2's successive orders per Sun zenith [1]."""
    from skytorch.atmosphere.multiple_scattering import precompute_scattering

    ref = reference.sel(case=case, wavelength=WAVELENGTH_NM)
    atm = _atmosphere(float(ref.aerosol_optical_depth))
    wavelength, view_zenith, azimuth = _grid(reference)
    tables = precompute_scattering(atm, wavelength, ground_albedo=0.0,
                                   scattering_orders="converged", resolution=resolution)
    out = {}
    for sun_zenith_deg in cases:
        ours = tables.radiance(torch.tensor(1.0, dtype=torch.float64), view_zenith, azimuth,
                               torch.tensor(math.radians(sun_zenith_deg),
                                            dtype=torch.float64))
        theirs = ref.successive_orders.sel(sun_zenith=sun_zenith_deg).transpose(
            "view_zenith", "relative_azimuth", "wavelength").values
        out[sun_zenith_deg] = float(np.abs(ours.detach().numpy() / theirs - 1.0).max())
    return out


@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_rayleigh_day_sky_against_sasktran2_coarse_tables(reference):
    """Rayleigh sky, Sun at 30 and 60 deg, coarse tables: within 3 % of sasktran2."""
    from skytorch.atmosphere.multiple_scattering import TableResolution

    coarse = TableResolution(n_r=8, n_mu=32, n_mu_s=16, n_phi=6, n_ray=24, n_sphere_mu=6,
                             transmittance_r=32, transmittance_mu=128, mu_vertical_weight=0.0,
                             r_ground_weight=0.0, sphere_phi_refinement=1, ray_quadrature="trapezoid")
    errors = _compare(reference, "rayleigh", (30.0, 60.0), coarse)
    assert max(errors.values()) < 0.03, errors


@pytest.mark.slow
@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
@pytest.mark.xfail(strict=True, reason="default tables alone (order 1 looked up too): "
                   "day sky 0.41 / 0.65 / 2.0 % (Rayleigh) and 1.7 / 2.2 / 3.2 % (Rayleigh + "
                   "aerosol) at Sun 30 / 60 / 80 deg (0.46 / 0.74 / 2.4 and 2.1 / 2.6 / 4.4 % "
                   "before the radius nodes were crowded towards the ground and the sphere "
                   "quadrature's azimuths refined, 2026-12-07; 9.1 % at Sun 30 deg at "
                   "38cba69), 31-32 % at the horizon "
                   "(Sun 90 deg); the twilight rows of this reference (num_sza = 1) are "
                   "1.4-8x brighter than the Monte-Carlo reference at Sun >= 94 deg "
                   "(docs/multiple_scattering_validation.md), so the solver cannot meet them")
@pytest.mark.parametrize("case", ["rayleigh", "rayleigh_aerosol"])
def test_multiple_scattering_against_sasktran2(reference, case):
    """Default tables: day sky (Sun 30-80 deg) within 3 %, Sun to -8 deg within 10 %."""
    errors = _compare(reference, case, (30.0, 60.0, 80.0, 90.0, 94.0, 98.0))
    day = {key: value for key, value in errors.items() if key <= 80.0}
    assert max(day.values()) < 0.03, errors
    assert max(errors.values()) < 0.10, errors


@pytest.mark.slow
@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_scene_sky_on_default_tables_against_sasktran2(reference):
    """The scenes' day sky (default tables) against sasktran2: the issue's 3 %.

    Ray-marched single scattering plus the default tables' orders >= 2 (the scenes' sum),
    Rayleigh and Rayleigh + aerosol 0.1, Sun at 30 and 60 deg, 400 and 550 nm, views
    with zenith 0-75 deg at every azimuth: within 3 % (measured 0.31 / 0.50 % Rayleigh,
    1.2 / 1.6 % aerosol, Sun 30 / 60 deg, on the default tables of 2026-12-07; 0.25 / 0.44
    and 1.2 / 1.7 % on those of 2026-12-05). At view zenith 85 deg the measured 1.5 / 2.0 %
    (aerosol, Sun 30 / 60 deg) are of the size of sasktran2's own two sources' difference
    there (up to 1.7 %); docs/multiple_scattering_validation.md.
    """
    from skytorch.atmosphere.multiple_scattering import precompute_scattering
    from skytorch.atmosphere.scattering import constituent_radiance

    wavelength, view_zenith, azimuth = _grid(reference)
    height = torch.tensor(1.0, dtype=torch.float64)
    below_85 = reference.view_zenith.values < 80.0
    for case in ("rayleigh", "rayleigh_aerosol"):
        ref = reference.sel(case=case, wavelength=WAVELENGTH_NM)
        atm = _atmosphere(float(ref.aerosol_optical_depth))
        tables = precompute_scattering(atm, wavelength, scattering_orders="converged")
        for sun_zenith_deg in (30.0, 60.0):
            sun = torch.tensor(math.radians(sun_zenith_deg), dtype=torch.float64)
            higher = (tables.radiance(height, view_zenith, azimuth, sun)
                      - tables.radiance(height, view_zenith, azimuth, sun, scattering_orders=1))
            ours = constituent_radiance(atm.constituents(wavelength), view_zenith, azimuth,
                                        sun, 0.0 * sun, height, n_samples=512) + higher
            theirs = ref.successive_orders.sel(sun_zenith=sun_zenith_deg).transpose(
                "view_zenith", "relative_azimuth", "wavelength").values
            error = np.abs(ours.numpy() / theirs - 1.0)[below_85]
            assert float(error.max()) < 0.03, (case, sun_zenith_deg, float(error.max()))


@pytest.mark.slow
def test_live_sasktran2_single_case(reference):
    """sasktran2 itself, run live on one small case, reproduces the shipped table."""
    sk = pytest.importorskip("sasktran2")
    spec = importlib.util.spec_from_file_location("generate_sasktran2",
                                                  DATA / "generate_sasktran2.py")
    generator = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(generator)
    constituents = generator.manual_constituents(generator.skytorch_atmosphere(0.1))
    live = generator.run(constituents, 60.0, sk.MultipleScatterSource.SuccessiveOrders)
    shipped = reference.successive_orders.sel(case="rayleigh_aerosol",
                                              sun_zenith=60.0).values
    np.testing.assert_allclose(live, shipped, rtol=1e-6)


@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_final_gather_day_sky_against_sasktran2(reference):
    """The final gather of the orders >= 2 on coarse tables against sasktran2 (spherical).

    Ray-marched single scattering plus ``higher_orders_gathered`` (defaults), 400 and
    550 nm, every view (zenith 0-85 deg, azimuth 0/90/180): Sun at 30 and 60 deg within
    the issue's 3 % for the Rayleigh and the Rayleigh + aerosol sky (measured 1.2 / 1.1 %
    and 1.9 / 1.7 %; the tables alone 2.0 / 1.9 % and 8.5 / 8.2 %); Sun at 80 deg within
    5 % (measured 1.7 % and 4.4 %, the latter at view zenith 85 deg, where sasktran2's two
    sources differ by up to 3 %; tables alone 3.6 / 12.5 %).
    """
    from skytorch.atmosphere.final_gather import higher_orders_gathered
    from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
    from skytorch.atmosphere.scattering import constituent_radiance

    coarse = TableResolution(n_r=8, n_mu=32, n_mu_s=16, n_phi=6, n_ray=24, n_sphere_mu=6,
                             transmittance_r=32, transmittance_mu=128, mu_vertical_weight=0.0,
                             r_ground_weight=0.0, sphere_phi_refinement=1, ray_quadrature="trapezoid")
    wavelength, view_zenith, azimuth = _grid(reference)
    height = torch.tensor(1.0, dtype=torch.float64)
    for case in ("rayleigh", "rayleigh_aerosol"):
        ref = reference.sel(case=case, wavelength=WAVELENGTH_NM)
        atm = _atmosphere(float(ref.aerosol_optical_depth))
        tables = precompute_scattering(atm, wavelength, scattering_orders="converged",
                                       resolution=coarse)
        for sun_zenith_deg, tolerance in ((30.0, 0.03), (60.0, 0.03), (80.0, 0.05)):
            sun = torch.tensor(math.radians(sun_zenith_deg), dtype=torch.float64)
            ours = (constituent_radiance(atm.constituents(wavelength), view_zenith, azimuth,
                                         sun, 0.0 * sun, height, n_samples=512)
                    + higher_orders_gathered(tables, atm, height, view_zenith, azimuth, sun))
            theirs = ref.successive_orders.sel(sun_zenith=sun_zenith_deg).transpose(
                "view_zenith", "relative_azimuth", "wavelength").values
            error = float(np.abs(ours.numpy() / theirs - 1.0).max())
            assert error < tolerance, (case, sun_zenith_deg, error)
