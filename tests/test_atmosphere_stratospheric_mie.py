"""Mie table of the stratospheric sulfate aerosol.

Miepython against van de Hulst's anomalous diffraction, convergence of the lognormal size integral,
the shipped table against its generator, and the interpolation's range check.
"""

import importlib.util
import math
from pathlib import Path

import miepython  # in the test extra; the generator imports it too
import numpy as np
import pytest
import torch

from skytorch.atmosphere.aerosol import SULFATE_RANGE_NM, sulfate_mie_properties

GENERATOR = Path(__file__).resolve().parents[1] / "data" / "make_aerosol_tables.py"


def _generator():
    spec = importlib.util.spec_from_file_location("make_aerosol_tables", GENERATOR)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_single_sphere_matches_anomalous_diffraction_at_large_size():
    """Q_ext of one sphere (x = 200, m = 1.43) vs van de Hulst 1957 anomalous diffraction.

    Q = 2 - (4/p) sin p + (4/p^2)(1 - cos p), p = 2x(m-1): within 2 %.
    """
    x, m = 200.0, 1.43
    qext = float(miepython.efficiencies_mx(complex(m, -1e-8), x)[0])
    p = 2.0 * x * (m - 1.0)
    adt = 2.0 - 4.0 / p * math.sin(p) + 4.0 / p ** 2 * (1.0 - math.cos(p))
    assert abs(qext / adt - 1.0) < 0.02


def test_lognormal_integral_converged():
    """Doubling the nodes of the size integral changes the extinction by < 1e-3."""
    gen = _generator()
    wavelength = np.array([230.0, 550.0, 1000.0, 1690.0])
    coarse = gen.size_averages(wavelength)
    fine = gen.size_averages(wavelength, n_nodes=2 * gen.N_NODES)
    assert np.all(np.abs(coarse[0] / fine[0] - 1.0) < 1e-3)
    assert np.all(np.abs(coarse[2] - fine[2]) < 1e-3)


def test_shipped_table_matches_generator():
    """The shipped CSV at three wavelengths equals a fresh run of the generator (1e-6)."""
    gen = _generator()
    wavelength = np.array([300.0, 550.0, 1500.0])
    c_ext, c_sca, g = gen.size_averages(wavelength)
    ratio, albedo, asym = sulfate_mie_properties(torch.tensor(wavelength, dtype=torch.float64))
    np.testing.assert_allclose(ratio.numpy(), c_ext / c_ext[1], rtol=1e-6)
    np.testing.assert_allclose(albedo.numpy(), c_sca / c_ext, rtol=1e-8)
    np.testing.assert_allclose(asym.numpy(), g, rtol=1e-6)


def test_small_particle_limit_of_the_spectrum():
    """Sub-micron droplets: extinction falls with wavelength.

    Angstrom exponent between 1 and 4, the Rayleigh limit; nearly conservative scattering (1 -
    albedo < 1e-5 for k = 1e-8) and forward-peaked, 0 < g < 1, with g decreasing towards the
    infrared.
    """
    ratio, albedo, g = sulfate_mie_properties(torch.tensor([550.0, 1000.0],
                                                           dtype=torch.float64))
    alpha = -math.log(float(ratio[1] / ratio[0])) / math.log(1000.0 / 550.0)
    assert 1.0 < alpha < 4.0
    assert torch.all(1.0 - albedo < 1e-5)
    assert torch.all((g > 0.0) & (g < 1.0)) and float(g[1]) < float(g[0])


@pytest.mark.parametrize("bad", [229.0, 1691.0, float("nan")])
def test_out_of_range_wavelength_refused(bad):
    with pytest.raises(ValueError, match="wavelength_nm"):
        sulfate_mie_properties(torch.tensor([bad]))
    assert SULFATE_RANGE_NM == (230.0, 1690.0)
