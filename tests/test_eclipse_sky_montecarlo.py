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
    from skytorch.scene.solar_eclipse_sky import (
        eclipsed_second_order,
        eclipsed_single_scattering,
    )

    atmosphere, wavelength, table = generator.model_inputs(WAVELENGTHS)
    height = generator.mc.OBSERVER_ALTITUDE_M
    first, second = [], []
    for site in reference.site.values:
        geometry, zenith, azimuth = generator.site_lines(site)
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




@pytest.fixture(scope="module")
def higher(reference):
    """Orders >= 3 (site, wavelength, view): the dimmed clear-sky gather.

    Coarse clear-sky tables (8 x 32 x 16 x 6, every order), the quadratures at their
    defaults.
    """
    from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
    from skytorch.scene.eclipse_higher_orders import eclipsed_higher_orders

    atmosphere, wavelength, table = generator.model_inputs(WAVELENGTHS)
    tables = precompute_scattering(atmosphere, wavelength, scattering_orders="converged",
                                   resolution=TableResolution(n_r=8, n_mu=32, n_mu_s=16,
                                                              n_phi=6, n_ray=48, mu_vertical_weight=0.0,
                                                              r_ground_weight=0.0, sphere_phi_refinement=1, ray_quadrature="trapezoid"))
    out = []
    for site in reference.site.values:
        geometry, zenith, azimuth = generator.site_lines(site)
        out.append(eclipsed_higher_orders(atmosphere, wavelength, zenith, azimuth, geometry,
                                          generator.mc.OBSERVER_ALTITUDE_M, tables=tables,
                                          table=table).T.numpy())
    return np.array(out)


def test_higher_orders_at_totality_against_montecarlo(reference, higher):
    # one step of diffusion into the umbra for every order >= 2 of the incoming field, an
    # isotropic dimming of the light scattered towards the line of sight (module docstring
    # of eclipse_higher_orders): at the zenith 0.77-1.10 of the reference, elsewhere
    # 0.64-1.76, the largest towards the low Sun at Burgos (docs/solar_eclipse_sky.md);
    # allowed 0.7-1.3 at the zenith and 0.5-2.0 elsewhere, 3 standard errors added
    mc, error = reference.order_3plus.values, reference.order_3plus_stderr.values
    low = np.full(mc.shape[-1], 0.5)
    high = np.full(mc.shape[-1], 2.0)
    low[0], high[0] = 0.7, 1.3
    assert np.all(higher > low * mc - 3.0 * error), (higher / mc).round(3)
    assert np.all(higher < high * mc + 3.0 * error), (higher / mc).round(3)


def test_every_order_makes_the_zenith_at_totality(reference, model, higher):
    """Orders 1, 2 and >= 3 against the Monte-Carlo's total at the zenith: within 20 %.

    Orders 1 and 2 alone are 0.26 (400 nm) to 0.66 (700 nm) of it at Lowman.
    """
    total = reference.total.isel(view=0).values
    both = model[0][..., 0] + model[1][..., 0]
    assert np.all(both < 0.8 * total)
    assert np.all(np.abs(both + higher[..., 0] - total) < 0.2 * total), (
        (both + higher[..., 0]) / total).round(3)
