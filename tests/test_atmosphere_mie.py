"""Mie theory behind the aerosol tables, against independent references.

The published test cases of Du (2004), van de Hulst's anomalous diffraction, OPAC's own Mie results
for its aerosol components, convergence of the size integrals, and every shipped type table against
a fresh run of its generator.
"""

import importlib.util
import math
from pathlib import Path

import miepython  # in the test extra; the generator imports it too
import numpy as np
import pytest
import torch

from skytorch.atmosphere.aerosol import aerosol_type_properties

GENERATOR = Path(__file__).resolve().parents[1] / "data" / "make_aerosol_tables.py"


@pytest.fixture(scope="module")
def gen():
    spec = importlib.util.spec_from_file_location("make_aerosol_tables", GENERATOR)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def opac(gen):
    return gen.opac_inputs()


#: Du, H. 2004, "Mie-scattering calculation", Appl. Opt. 43, 1951,
#: doi:10.1364/AO.43.001951, Table 1 (Wiscombe's test spheres; the values as listed in the
#: scattnlay test suite, github.com/ovidiopr/scattnlay): x, m = n + i k, Q_ext, Q_sca.
#: Left out: x = 10000, m = 10 + 10i (|m| x = 1.4e5, far beyond the |m| x < 3300 of the
#: aerosol tables), where miepython 3.3.0 gives Q_ext 2.005914 against 2.005968 (-2.7e-5).
DU_2004_TABLE_1 = [
    (0.099, 0.75, 0.0, 7.417859e-06, 7.417859e-06),
    (0.101, 0.75, 0.0, 8.033538e-06, 8.033538e-06),
    (10.0, 0.75, 0.0, 2.232265, 2.232265),
    (1000.0, 0.75, 0.0, 1.997908, 1.997908),
    (100.0, 1.33, 1e-5, 2.101321, 2.096594),
    (10000.0, 1.33, 1e-5, 2.004089, 1.723857),
    (0.055, 1.5, 1.0, 0.101491, 1.131687e-05),
    (0.056, 1.5, 1.0, 0.103347, 1.216311e-05),
    (100.0, 1.5, 1.0, 2.097502, 1.283697),
    (10000.0, 1.5, 1.0, 2.004368, 1.236574),
    (1.0, 10.0, 10.0, 2.532993, 2.049405),
    (100.0, 10.0, 10.0, 2.071124, 1.836785),
]


@pytest.mark.parametrize(("x", "n", "k", "q_ext", "q_sca"), DU_2004_TABLE_1)
def test_single_sphere_matches_du_2004_table_1(x, n, k, q_ext, q_sca):
    """Q_ext and Q_sca of single spheres within 5e-6 relative.

    The table has 7 digits; miepython's sign convention has absorption as a negative imaginary part.
    """
    result = miepython.efficiencies_mx(complex(n, -k), x)
    assert float(result[0]) == pytest.approx(q_ext, rel=5e-6)
    assert float(result[1]) == pytest.approx(q_sca, rel=5e-6)


@pytest.mark.parametrize(("m", "x"), [(1.01, 1000.0), (1.01, 5000.0), (1.05, 5000.0)])
def test_anomalous_diffraction_for_index_near_one(m, x):
    """Van de Hulst (1957) anomalous diffraction, Q = 2 - (4/p) sin p + (4/p^2)(1 - cos p).

    P = 2x(m - 1), the limit m -> 1, x -> infinity: within 1 % (its edge-term error at these x is
    0.4-0.8 %).
    """
    q_ext = float(miepython.efficiencies_mx(complex(m, 0.0), x)[0])
    p = 2.0 * x * (m - 1.0)
    adt = 2.0 - 4.0 / p * math.sin(p) + 4.0 / p ** 2 * (1.0 - math.cos(p))
    assert abs(q_ext / adt - 1.0) < 0.01


#: wavelengths of the OPAC comparison [nm] (three per component keeps the test fast)
OPAC_CHECK_NM = (300.0, 550.0, 1000.0)


@pytest.mark.parametrize("component", ["inso", "waso", "soot", "ssam", "sscm", "minm",
                                       "miam", "micm", "mitr", "suso"])
def test_components_match_opac_mie(gen, opac, component):
    """Size-averaged extinction, albedo and asymmetry of each OPAC component.

    Same refractive index and truncated lognormal, against OPAC's own Mie code (Hess et al. 1998,
    the values in its data files): extinction within 0.5 %, albedo within 2e-3, g within 0.015 (OPAC
    writes g with 3 decimals; measured worst over 250-2000 nm: 0.26 %, 8e-4, 0.0094).
    """
    data = opac[component]
    rows = np.isin(data["wavelength_nm"], OPAC_CHECK_NM)
    c_ext, c_sca, g = gen.component_averages(component, data["wavelength_nm"][rows],
                                             inputs=opac)
    # OPAC: extinction [km^-1] of 1 particle per cm^3 = C_ext [um^2] * 1e-8 cm^2 cm^-3
    np.testing.assert_allclose(c_ext * 1e-3, data["extinction_per_km"][rows], rtol=5e-3)
    np.testing.assert_allclose(c_sca / c_ext, data["single_scattering_albedo"][rows],
                               atol=2e-3)
    np.testing.assert_allclose(g, data["asymmetry"][rows], atol=0.015)


def test_continental_polluted_matches_opac_type_output(gen):
    """The OPAC 3.1 output for the continental polluted type at 80 % relative humidity.

    550 nm (inso 0.6, waso 15700, soot 34300 cm^-3; forge.ipsl.jussieu.fr/ether, file
    ``trunk/hftp/iasi/aerosol/opac_calc/copo``): extinction 0.1746 km^-1 within 0.5 %, albedo 0.8925
    within 1e-3, g 0.6977 within 3e-3 (measured: 1e-4 and 3e-4).
    """
    ext, sca, g = gen.type_averages("continental_polluted", np.array([550.0]))
    assert float(ext[0]) * 1e-3 == pytest.approx(0.1746, rel=5e-3)
    assert float(sca[0] / ext[0]) == pytest.approx(0.8925, abs=1e-3)
    assert float(g[0]) == pytest.approx(0.6977, abs=3e-3)


@pytest.mark.parametrize(("name", "wavelength"), [
    ("continental_average", (300.0,)),
    ("urban", (1000.0,)),
    ("desert", (550.0,)),
])
def test_lognormal_integrals_converged(gen, name, wavelength):
    """Doubling the nodes of every size integral changes the extinction at each wavelength.

    The albedo and g by < 1e-4 (relative, absolute, absolute); all wavelengths and the ln r span:
    experiments/aerosol_mie_accuracy_cost.py.
    """
    coarse = gen.type_averages(name, np.array(wavelength))
    fine = gen.type_averages(name, np.array(wavelength), node_scale=2.0)
    assert np.all(np.abs(coarse[0] / fine[0] - 1.0) < 1e-4)
    assert np.all(np.abs(coarse[1] / coarse[0] - fine[1] / fine[0]) < 1e-4)
    assert np.all(np.abs(coarse[2] - fine[2]) < 1e-4)


def test_sea_salt_integral_limited_by_the_ripple_structure(gen):
    """Nearly non-absorbing sea salt (k ~ 1e-7 to 1e-8).

    The ripple and resonance structure of Q_ext(x) is not resolved by any affordable node count, and
    doubling the nodes of maritime clean changes its extinction at 1000 nm by 1e-4 to 1e-3 (measured
    2.1e-4 at 600 -> 1200 nodes of the accumulation mode), its albedo by < 1e-5: bounded here at
    1e-3 and 1e-5; the measured values are in docs/accuracy.md.
    """
    coarse = gen.type_averages("maritime_clean", np.array([1000.0]))
    fine = gen.type_averages("maritime_clean", np.array([1000.0]), node_scale=2.0)
    assert abs(float(coarse[0][0] / fine[0][0]) - 1.0) < 1e-3
    assert abs(float(coarse[1][0] / coarse[0][0] - fine[1][0] / fine[0][0])) < 1e-5
    assert abs(float(coarse[2][0] - fine[2][0])) < 1e-3


@pytest.mark.parametrize("name", ["continental_clean", "continental_average",
                                  "continental_polluted", "urban", "desert",
                                  "maritime_clean", "maritime_polluted",
                                  "maritime_tropical", "arctic", "antarctic"])
def test_shipped_type_table_matches_generator(gen, name):
    """Each shipped type table equals a fresh run of the generator at two of its wavelengths.

    At 870 and 1600 nm, where the size parameters are small and the run fast: albedo and g within
    1e-6 (8 decimals written), the extinction ratio between the two wavelengths within 1e-6
    relative.
    """
    wavelength = np.array([870.0, 1600.0])
    ext, sca, g = gen.type_averages(name, wavelength)
    shipped = aerosol_type_properties(name, torch.tensor(wavelength, dtype=torch.float64))
    ratio = shipped[0].numpy()
    assert ratio[1] / ratio[0] == pytest.approx(ext[1] / ext[0], rel=1e-6)
    np.testing.assert_allclose(shipped[1].numpy(), sca / ext, atol=1e-6)
    np.testing.assert_allclose(shipped[2].numpy(), g, atol=1e-6)


def test_opac_inputs_cover_the_table_wavelengths(gen, opac):
    """Every component has OPAC's wavelengths, a positive k and a mode radius in bounds.

    OPAC's 18 wavelengths 250-2000 nm, a positive absorption index and a mode radius inside its size
    bounds.
    """
    for name in gen.OPAC_COMPONENTS:
        data = opac[name]
        r_min, r_max, sigma, r_mod = data["size"]
        assert data["wavelength_nm"][0] == 250.0 and data["wavelength_nm"][-1] == 2000.0
        assert data["wavelength_nm"].size == 18
        assert np.all(data["n_imag"] > 0.0) and np.all(data["n_real"] > 1.0)
        assert r_min < r_mod < r_max and sigma > 1.0
