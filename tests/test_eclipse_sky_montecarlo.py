"""The sky at totality against a backward Monte-Carlo of every order (issue 16).

``tests/data/ms_reference/montecarlo_eclipse_sky.nc`` (written by
``generate_eclipse_montecarlo.py``: the random walk of ``montecarlo_sky.nc`` with the
Sun's visible fraction at every next event) is the reference: it finds the light
scattered into the umbra by sampling paths, not by the kernels' quadrature over
directions and distances. Radiances per unit TOA solar irradiance [sr^-1], judged in
standard errors of the estimate plus the stated quadrature error.
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
import xarray as xr

DATA = Path(__file__).parent / "data" / "ms_reference"
TABLE = DATA / "montecarlo_eclipse_sky.nc"
WAVELENGTHS = (400.0, 550.0)


def _load(name):
    spec = importlib.util.spec_from_file_location(name, DATA / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(name, module)   # dataclasses look it up
    spec.loader.exec_module(module)
    return sys.modules[name]


generator = _load("generate_eclipse_montecarlo")


@pytest.fixture(scope="module")
def reference():
    with xr.open_dataset(TABLE) as dataset:
        return dataset.sel(wavelength=list(WAVELENGTHS)).load()


@pytest.fixture(scope="module")
def model(reference):
    """Orders 1 and 2 of the eclipse-sky kernels (site, wavelength, view), defaults."""
    from skytorch.atmosphere.tables import TransmittanceTable
    from skytorch.scene.solar_eclipse_sky import (
        eclipsed_second_order,
        eclipsed_single_scattering,
    )

    atmosphere = generator.mc.skytorch_atmosphere(generator.mc.CASES[generator.CASE],
                                                  generator.OZONE_DU)
    wavelength = torch.tensor(WAVELENGTHS, dtype=torch.float64)
    table = TransmittanceTable.build(atmosphere, wavelength, cache=False, n_mu=128, n_r=32)
    height = generator.mc.OBSERVER_ALTITUDE_M
    first, second = [], []
    for site in reference.site.values:
        _, date, lat, lon = next(s for s in generator.SITES if s[0] == site)
        _, geometry = generator.site_geometry(date, lat, lon)
        views, _ = generator.view_directions(geometry)
        zenith = torch.tensor(np.radians(reference.view_zenith.values))
        azimuth = torch.tensor(np.arctan2(views[:, 1], views[:, 0]))
        first.append(eclipsed_single_scattering(atmosphere, wavelength, zenith, azimuth,
                                                geometry, height, n_samples=128,
                                                table=table).T.numpy())
        second.append(eclipsed_second_order(atmosphere, wavelength, zenith, azimuth,
                                            geometry, height, n_view=16, table=table
                                            ).T.numpy())
    return np.array(first), np.array(second)


def test_single_scattering_at_totality_against_montecarlo(reference, model):
    # order 1 ranges over 7 orders of magnitude (the zenith's ray leaves the umbra near
    # the top; the horizon sees the sunlit air outside it); the Monte-Carlo's first event
    # is forced on the line of sight, so its order 1 is a one-dimensional estimate
    mc, error = reference.order_1.values, reference.order_1_stderr.values
    first = model[0]
    lit = mc > 0
    assert np.all(first[~lit] < 1e-12)
    deviation = np.abs(first[lit] - mc[lit]) / (3.0 * error[lit] + 0.02 * mc[lit])
    assert deviation.max() < 1.0, deviation.max()


def test_second_order_at_totality_against_montecarlo(reference, model):
    # the default quadrature (16/4/16/16) is +4...+12 % from a converged one by day
    # (docs/solar_eclipse_sky.md); allowed: 15 % plus 3 standard errors
    mc, error = reference.order_2.values, reference.order_2_stderr.values
    deviation = np.abs(model[1] - mc) / (3.0 * error + 0.15 * mc)
    assert deviation.max() < 1.0, (model[1] / mc).round(3)


@pytest.mark.xfail(strict=True, reason="orders >= 3 are not in the eclipse-sky kernels: "
                   "at the zenith at totality they are 0.5-2.8 times order 2 "
                   "(Monte-Carlo, 700-400 nm)")
def test_orders_one_two_make_the_zenith_at_totality(reference, model):
    total = reference.total.isel(view=0).values
    assert np.all(np.abs(model[0][..., 0] + model[1][..., 0] - total) < 0.2 * total)
