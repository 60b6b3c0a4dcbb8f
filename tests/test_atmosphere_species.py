"""Constituents against published references: Bodhaine 1999, ozone column, Preetham."""

from __future__ import annotations

import math

import pytest
import torch

from skytorch.atmosphere import Atmosphere
from skytorch.constants import PERCENT


def bodhaine_eq30(wavelength_nm):
    """Rayleigh optical depth at 1013.25 hPa, 45 deg, sea level (Bodhaine 1999, eq. 30)."""
    lam = wavelength_nm / 1000.0
    return 0.0021520 * (1.0455996 - 341.29061 * lam ** -2 - 0.90230850 * lam ** 2) / (
        1.0 + 0.0027059889 * lam ** -2 - 85.968563 * lam ** 2)


def test_rayleigh_optical_depth_matches_bodhaine_eq30():
    wavelength = torch.linspace(400.0, 800.0, 41, dtype=torch.float64)
    atm = Atmosphere.earth(turbidity=1.0, ozone_du=0.0)
    tau = atm.optical_depth(wavelength, per_species=True)["rayleigh"]
    relative = (tau / bodhaine_eq30(wavelength) - 1.0).abs()
    assert float(relative.max()) <= 1 * PERCENT


@pytest.mark.parametrize(("wavelength", "reference"), [(400.0, 0.360), (550.0, 0.0971),
                                                       (700.0, 0.0364)])
def test_rayleigh_design_reference_values(wavelength, reference):
    atm = Atmosphere.earth(turbidity=1.0, ozone_du=0.0)
    tau = atm.optical_depth(torch.tensor([wavelength], dtype=torch.float64),
                            per_species=True)["rayleigh"]
    assert abs(float(tau[0]) / reference - 1.0) <= 1 * PERCENT


@pytest.mark.parametrize(("wavelength", "reference"), [(550.0, 0.028), (600.0, 0.040)])
def test_ozone_optical_depth_300_du(wavelength, reference):
    atm = Atmosphere.earth(turbidity=1.0, ozone_du=300.0)
    tau = atm.optical_depth(torch.tensor([wavelength], dtype=torch.float64),
                            per_species=True)["ozone"]
    assert abs(float(tau[0]) - reference) <= 0.002


def test_ozone_column_equals_dobson_units():
    # vertical ozone optical depth = column [DU] * 2.687e20 m^-2 * cross-section (the
    # 600 nm, 223 K row of data/ozone_cross_section_serdyuchenko2014.csv)
    atm = Atmosphere.earth(turbidity=1.0, ozone_du=300.0, ozone_temperature_k=223.0)
    tau = atm.optical_depth(torch.tensor([600.0], dtype=torch.float64), per_species=True)
    assert float(tau["ozone"][0]) == pytest.approx(300 * 2.687e20 * 5.1088e-25, rel=1e-9)


def test_preetham_turbidity_aerosol_optical_depth():
    # beta = 0.04608 T - 0.04586, alpha = 1.3 (Preetham 1999)
    atm = Atmosphere.earth(turbidity=3.0, ozone_du=0.0)
    tau = atm.optical_depth(torch.tensor([1000.0, 500.0], dtype=torch.float64),
                            per_species=True)["aerosol"]
    beta = 0.04608 * 3.0 - 0.04586
    assert float(tau[0]) == pytest.approx(beta, rel=1e-6)
    assert float(tau[1]) == pytest.approx(beta * 0.5 ** -1.3, rel=1e-6)


def test_refractivity_scales_with_density():
    atm = Atmosphere.earth(refractivity_profile="exponential")
    n1 = atm.refractivity(torch.tensor([0.0, 8000.0], dtype=torch.float64))
    assert float(n1[0]) == pytest.approx(2.77e-4, rel=1e-12)
    assert float(n1[1]) == pytest.approx(2.77e-4 / math.e, rel=1e-12)
    mars = Atmosphere.mars()
    assert float(mars.refractivity(0.0)) == pytest.approx(3.38e-6, rel=1e-12)


#: U.S. Standard Atmosphere 1976, tabulated densities at geometric altitudes 5, 10, 20 and
#: 50 km [kg m^-3] and at sea level (NOAA-S/T 76-1562, Table I)
US1976_TABLE_DENSITY = {5e3: 0.73643, 10e3: 0.41351, 20e3: 0.088910, 50e3: 1.0269e-3}
US1976_SEA_LEVEL_DENSITY = 1.2250


def test_default_refractivity_follows_the_us1976_table():
    """The default Earth refractivity is n - 1 = 2.77e-4 at the ground, scaled with density.

    The ground value is Schneegans 2025; it is scaled by the U.S. Standard Atmosphere 1976 density
    ratio (5-digit table values).
    """
    atm = Atmosphere.earth()
    assert atm.refractivity_profile == "us1976"
    altitude = torch.tensor([0.0, *US1976_TABLE_DENSITY], dtype=torch.float64)
    ratio = atm.refractivity(altitude) / 2.77e-4
    expected = torch.tensor([US1976_SEA_LEVEL_DENSITY, *US1976_TABLE_DENSITY.values()],
                            dtype=torch.float64) / US1976_SEA_LEVEL_DENSITY
    assert torch.allclose(ratio, expected, rtol=5e-5, atol=0)  # 5 significant digits


def test_reference_extinction_gives_vertical_optical_depths():
    """Reference coefficients times each profile's height integral are the vertical optical depths.

    Rayleigh vs Bodhaine et al. 1999 eq. 30 (0.0971 at 550 nm, 1 %), aerosol vs the
    Preetham/Angstrom closed form, and their refracted-path integrals add up to the total.
    """
    atm = Atmosphere.earth(turbidity=3.0, ozone_du=300.0)
    wavelength = torch.tensor([550.0], dtype=torch.float64)
    k = atm.reference_extinction(wavelength)
    assert set(k) == {"rayleigh", "aerosol", "ozone", "stratospheric_aerosol", "h2o", "o2",
                      "o2o2"}
    height = atm.profiles(torch.float64)["rayleigh"].column_height_m  # US 1976: 8.43 km
    assert float(k["rayleigh"][0] * height) == pytest.approx(0.0971, rel=1e-2)
    beta = 0.04608 * 3.0 - 0.04586
    assert float(k["aerosol"][0]) * 1200.0 == pytest.approx(beta * 0.55 ** -1.3, rel=1e-9)
    zenith = torch.tensor([0.3, 1.5], dtype=torch.float64)
    parts = atm.optical_depth(wavelength, zenith, refraction=True, per_species=True)
    total = atm.optical_depth(wavelength, zenith, refraction=True)
    assert torch.allclose(sum(parts.values()), total, rtol=1e-12)
    with pytest.raises(ValueError, match="wavelength_nm"):
        atm.reference_extinction(torch.tensor([-1.0]))
