"""Radiance leaving the top of the atmosphere against sasktran2 in spherical geometry.

The reference ``tests/data/ms_reference/sasktran2_top.nc`` (``generate_sasktran2.py top``)
holds sasktran2's spherical radiance seen from 100 km looking down at nadir 0, 30 and
60 deg, on the optics, Suns and grounds of DISORT's table ``disort_sky.nc`` (U.S. 1976
molecules, Henyey-Greenstein aerosol g = 0.7, single-scattering albedo 0.95, aerosol
optical depth 0-1 at 550 nm; black ground and a Lambertian ground of albedo 0.3).

Why a spherical reference here: a line of sight leaving 100 km at nadir 60 deg meets the
ground 1.6 deg of arc away, at a local zenith angle of 61.6 deg, so it crosses the
scattering layers more obliquely than DISORT's flat one (slant factor 2.10 instead of
2.00), and the ground and the air it sees have the Sun 1.6 deg higher or lower than the
observer. sasktran2's spherical radiance is 1.5-4.5 % above DISORT's there (black ground;
-3.4 … +5.1 % over the bright ground, with the sign of the Sun's azimuth), and skytorch's
spherical single scattering follows it (first test). At the nadir both geometries agree.
"""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
import torch
import xarray as xr

from tests.test_ms_disort import _atmosphere  # the same optics (generate_sasktran2.py)

DATA = Path(__file__).parent / "data" / "ms_reference"
HAS_SOLVER = importlib.util.find_spec("skytorch.atmosphere.multiple_scattering") is not None
PERCENT = 0.01
#: the coarse tables of the other reference comparisons (seconds to build)
COARSE_TABLES = dict(n_r=8, n_mu=32, n_mu_s=16, n_phi=6, n_ray=24, n_sphere_mu=6,
                     transmittance_r=32, transmittance_mu=128, mu_vertical_weight=0.0,
                     r_ground_weight=0.0, sphere_phi_refinement=1, ray_quadrature="trapezoid")


@pytest.fixture(scope="module")
def reference() -> xr.Dataset:
    with xr.open_dataset(DATA / "sasktran2_top.nc") as ds:
        return ds.load()


def _views(reference: xr.Dataset):
    """Return wavelength (λ,), view zenith (nadir, 1, 1) and azimuth (1, az, 1) tensors."""
    wavelength = torch.tensor(reference.wavelength.values, dtype=torch.float64)
    zenith = torch.deg2rad(180.0 - torch.tensor(reference.nadir.values, dtype=torch.float64))
    azimuth = torch.deg2rad(torch.tensor(reference.relative_azimuth.values,
                                         dtype=torch.float64))
    return wavelength, zenith[:, None, None], azimuth[None, :, None]


def _theirs(reference: xr.Dataset, name: str, aod, sun_zenith_deg: float) -> np.ndarray:
    """Return the reference values as (nadir, relative_azimuth, aod, wavelength)."""
    return reference[name].sel(aod=aod, sun_zenith=sun_zenith_deg).transpose(
        "nadir", "relative_azimuth", "aod", "wavelength").values


def test_single_scattering_leaving_the_top_matches_sasktran2(reference):
    """Ray-marched single scattering from 100 km, every aerosol optical depth: within 0.5 %.

    Measured 0.23 % at most (1024 samples; 0.07-0.2 % is the difference of sasktran2's
    250-m linear grid from the continuous aerosol profile). DISORT's flat geometry is
    3.8-4.7 % below both at nadir 60 deg (module docstring).
    """
    from skytorch.atmosphere.scattering import constituent_radiance

    aod = reference.aod.values
    atm = _atmosphere(torch.tensor(aod, dtype=torch.float64))
    wavelength, zenith, azimuth = _views(reference)
    height = torch.tensor(float(reference.attrs["observer_altitude_m"]), dtype=torch.float64)
    for sun_zenith_deg in reference.sun_zenith.values:
        sun = torch.tensor(math.radians(sun_zenith_deg), dtype=torch.float64)
        ours = constituent_radiance(atm.constituents(wavelength), zenith, azimuth, sun,
                                    0.0 * height, height, n_samples=1024).numpy()
        theirs = _theirs(reference, "single_scattering", aod, sun_zenith_deg)
        assert float(np.abs(ours / theirs - 1.0).max()) < 0.5 * PERCENT


def test_reference_sources_agree(reference):
    """sasktran2's successive orders and discrete ordinates within 2.5 % (its own spread).

    Measured 1.0-1.2 % up to optical depth 0.3 and 2.3 % at 1; the tolerances below stay
    above this spread.
    """
    spread = reference.discrete_ordinates / reference.successive_orders - 1.0
    assert float(abs(spread).max()) < 2.5 * PERCENT


def top_errors(reference: xr.Dataset, aod, resolution=None, ground_albedo=0.0):
    """Relative errors of the converged radiance leaving the top, (sun, nadir, az, aod, λ).

    Black ground: the ray-marched single scattering plus the tables' orders >= 2, as
    scenes add them up; over a Lambertian ground the tables' total (its order 1 with the
    Sun reflected once by the ground).
    """
    from skytorch.atmosphere.multiple_scattering import precompute_scattering
    from skytorch.atmosphere.scattering import constituent_radiance

    atm = _atmosphere(torch.tensor(aod, dtype=torch.float64))
    wavelength, zenith, azimuth = _views(reference)
    tables = precompute_scattering(atm, wavelength, ground_albedo=ground_albedo,
                                   scattering_orders="converged", resolution=resolution)
    height = torch.tensor(tables.top_altitude_m, dtype=torch.float64)
    name = "successive_orders_ground_albedo" if ground_albedo else "successive_orders"
    errors = []
    for sun_zenith_deg in reference.sun_zenith.values:
        sun = torch.tensor(math.radians(sun_zenith_deg), dtype=torch.float64)
        ours = tables.radiance(height, zenith, azimuth, sun)
        if not ground_albedo:
            ours = ours - tables.radiance(height, zenith, azimuth, sun, scattering_orders=1)
            ours = ours + constituent_radiance(atm.constituents(wavelength), zenith, azimuth,
                                               sun, 0.0 * height, height, n_samples=1024)
        errors.append(ours.detach().numpy() / _theirs(reference, name, aod, sun_zenith_deg)
                      - 1.0)
    return np.abs(np.stack(errors))


@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_top_of_molecular_and_thin_aerosol_atmospheres_coarse_tables(reference):
    """Coarse tables, molecules and τ 0.05, black ground: within 4 % of sasktran2.

    A regression bound of the coarse tables (measured 2.4 / 3.3 % with the Sun at 30 deg,
    1.9 / 2.4 % at 60 deg; at the nadir 0.4-0.75 %); the same sum is 3.6-4.5 % from DISORT,
    most of it the flat geometry. The default tables' numbers are in
    docs/multiple_scattering_validation.md.
    """
    from skytorch.atmosphere.multiple_scattering import TableResolution

    errors = top_errors(reference, [0.0, 0.05], TableResolution(**COARSE_TABLES))
    assert errors.max() < 4 * PERCENT
    assert errors[:, 0].max() < 1.5 * PERCENT               # nadir


@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_top_over_a_lambertian_ground_coarse_tables(reference):
    """Coarse tables over a ground of albedo 0.3, molecules and τ 0.05: within 3 %.

    The issue's day-sky tolerance against sasktran2, met at every view (measured 0.7 % for
    molecules, 1.95 % for τ 0.05), where DISORT's flat geometry differs by up to 6.4 %:
    the ground seen at nadir 60 deg has the Sun 1.6 deg higher or lower than the observer.
    """
    from skytorch.atmosphere.multiple_scattering import TableResolution

    errors = top_errors(reference, [0.0, 0.05], TableResolution(**COARSE_TABLES),
                        ground_albedo=float(reference.attrs["ground_albedo_run"]))
    assert errors.max() < 3 * PERCENT
