"""Water vapour, O2 bands and O2-O2 absorption (skytorch.atmosphere.gases).

References used here, each independent of the code under test:

* pvlib 0.16.1's SPECTRL2 (Bird & Riordan 1986): its water vapour transmittance, the ratio
  of its direct normal irradiance with and without precipitable water;
* absorber amounts along straight vertical, slant and limb paths by a fine numpy trapezoid
  in the path length (not skytorch's Gauss-Legendre column integrals), with the
  isothermal exponential atmosphere's pressure p/p_s = exp(-h/H);
* the closed-form vertical column of the squared exponential O2 density, n0^2 H/2.
"""

from __future__ import annotations

import math

import numpy as np
import pvlib
import pytest
import torch
from pvlib.spectrum import spectrl2

from skytorch.atmosphere import Atmosphere, gases

R_EARTH = 6_371_000.0
H_AIR = 8000.0
H_WATER = gases.WATER_VAPOUR_SCALE_HEIGHT_M
M = gases.PRESSURE_EXPONENT


def _earth(**options):
    """Return the isothermal exponential atmosphere (pressure known in closed form)."""
    settings = {"ozone_du": 0.0, "aerosol_optical_depth": 0.0, "molecule_profile": "exponential",
                "rayleigh_scale_height_m": H_AIR}
    settings.update(options)
    return Atmosphere.earth(**settings)


def test_water_curve_of_growth_matches_pvlib_spectrl2():
    """Bird & Riordan eq. 2-8 at u = W M.

    Pvlib's water transmittance (DNI with W over DNI without), at every SPECTRL2 wavelength in
    300-1100 nm, to 1e-9 in optical depth.
    """
    zenith = np.array([0.0, 60.0, 80.0])
    air_mass = pvlib.atmosphere.get_relative_airmass(zenith, model="kasten1966")

    def dni(water):
        out = spectrl2(apparent_zenith=zenith, aoi=zenith, surface_tilt=0.0, ground_albedo=0.2,
                       surface_pressure=101325.0, relative_airmass=air_mass,
                       precipitable_water=water, ozone=0.3, aerosol_turbidity_500nm=0.1,
                       dayofyear=np.full(zenith.shape, 172))
        return out["wavelength"], out["dni"].T

    wavelength, wet = dni(2.5)
    _, dry = dni(0.0)
    keep = (wavelength >= 300.0) & (wavelength <= 1100.0)
    reference = -np.log(wet[:, keep] / dry[:, keep])
    path = torch.tensor(2.5 * air_mass, dtype=torch.float64)[:, None]
    tau = gases.water_vapour_optical_depth(torch.tensor(wavelength[keep]), path).numpy()
    assert reference.max() > 2.0  # the 940 nm band core at 80 deg: saturated
    np.testing.assert_allclose(tau, reference, rtol=0.0, atol=1e-9)


def _limb_path_amount(density, tangent_m, half_length_m=1.2e6, n=2_000_001):
    """Trapezoid integral of ``density(h)`` along the straight line grazing at ``tangent_m``."""
    s = np.linspace(-half_length_m, half_length_m, n)
    radius = R_EARTH + tangent_m
    h = np.sqrt(radius ** 2 + s ** 2) - R_EARTH
    return np.trapezoid(density(h), s)


def _vertical_amount(density, n=400_001):
    h = np.linspace(0.0, 100e3, n)
    return np.trapezoid(density(h), h)


def _water_density(h):
    return np.exp(-h / H_WATER) * np.exp(-h / H_AIR) ** M  # relative density (p/p_s)^m


def _air_density(h):
    return np.exp(-h / H_AIR) * np.exp(-h / H_AIR) ** M


def _from_space(tangent_m, atm):
    """Origin radius and direction cosine of a ray entering at the top.

    Grazing at ``tangent_m`` (impact parameter R + h_t).
    """
    r = atm.top_radius_m + 1000.0
    impact = R_EARTH + tangent_m
    mu = -math.sqrt(1.0 - (impact / r) ** 2)
    return torch.tensor(r, dtype=torch.float64), torch.tensor(mu, dtype=torch.float64)


@pytest.mark.parametrize("tangent_km", [5.0, 10.0, 15.0])
def test_curve_of_growth_along_a_limb_path(tangent_km):
    """Two-way limb path grazing at 5-15 km.

    The band optical depths of h2o and o2 are the curve of growth of the pressure-scaled amount
    integrated independently (trapezoid), and the o2o2 optical depth is linear in the trapezoid
    integral of n_O2^2.
    """
    water = 2.0
    atm = _earth(precipitable_water_cm=water)
    wavelength = torch.tensor([690.0, 720.0, 762.5, 937.0, 1065.0], dtype=torch.float64)
    c = atm.constituents(wavelength)
    r, mu = _from_space(tangent_km * 1e3, atm)
    tau = c.optical_depth(c.column_integrals(r, mu), per_species=True)
    tangent = tangent_km * 1e3
    u_water = water * _limb_path_amount(_water_density, tangent) / _vertical_amount(
        _water_density)
    u_air = _limb_path_amount(_air_density, tangent) / _vertical_amount(_air_density)
    expected_h2o = gases.water_vapour_optical_depth(wavelength, u_water)
    expected_o2 = gases.mixed_gas_optical_depth(wavelength, u_air)
    # the limb path is long: 20-50 standard vertical columns of air at 10 km
    assert 5.0 < u_air < 200.0
    torch.testing.assert_close(tau["h2o"], expected_h2o, rtol=2e-4, atol=1e-12)
    torch.testing.assert_close(tau["o2"], expected_o2, rtol=2e-4, atol=1e-12)
    n0 = (gases.O2_VOLUME_MIXING_RATIO * atm.molecular_column_m2().item() / H_AIR
          / 2.686780111e25)  # [amagat]
    squared = n0 ** 2 * _limb_path_amount(lambda h: np.exp(-2.0 * h / H_AIR), tangent)
    torch.testing.assert_close(tau["o2o2"], gases.o2o2_optical_depth(wavelength, squared),
                               rtol=2e-4, atol=1e-12)


def test_vertical_o2o2_column_closed_form():
    """Vertical o2o2 optical depth from the ground.

    K (0.2095 n0 / L)^2 H/2 (closed form of the squared exponential), with n0 = p N_A / (M g H).
    """
    atm = _earth()
    wavelength = torch.tensor([477.0, 577.0, 630.0, 1065.0], dtype=torch.float64)
    tau = atm.optical_depth(wavelength, per_species=True)["o2o2"]
    n0 = 101325.0 * 6.02214076e23 / (atm.molar_mass_kg_mol.item() * 9.80616 * H_AIR)
    expected = gases.o2o2_coefficient(wavelength) * (
        0.2095 * n0 / 2.686780111e25) ** 2 * H_AIR / 2.0
    torch.testing.assert_close(tau, expected, rtol=1e-6, atol=0.0)
    # the O4 bands are of order 1e-2 in vertical optical depth
    assert 0.004 < float(tau[0]) < 0.02 and 0.005 < float(tau[1]) < 0.03


def test_zenith_water_path_is_the_precipitable_water():
    """Overhead from sea level the scaled water amount is W (Bird & Riordan's u = W M, M = 1).

    For both profile shapes.
    """
    wavelength = torch.tensor([720.0, 820.0, 937.0], dtype=torch.float64)
    for profile in ("exponential", "us1976"):
        atm = _earth(precipitable_water_cm=3.0, molecule_profile=profile)
        tau = atm.optical_depth(wavelength, per_species=True)["h2o"]
        torch.testing.assert_close(tau, gases.water_vapour_optical_depth(wavelength, 3.0),
                                   rtol=1e-5, atol=0.0)


def test_gradcheck_precipitable_water():
    """D T / d W in float64 against finite differences on slant and near-horizontal paths.

    Including W = 0 (the curve of growth is smooth there).
    """
    wavelength = torch.tensor([720.0, 937.0], dtype=torch.float64)
    zenith = torch.tensor([0.3, 1.45], dtype=torch.float64)

    def transmittance(water):
        return _earth(precipitable_water_cm=water).transmittance(wavelength, zenith)

    for value in (0.01, 1.4, 4.0):
        water = torch.tensor(value, dtype=torch.float64, requires_grad=True)
        assert torch.autograd.gradcheck(transmittance, (water,), eps=1e-6, atol=1e-8)
    # at W = 0 (the lower end of the range) against a one-sided difference
    water = torch.tensor(0.0, dtype=torch.float64, requires_grad=True)
    (grad,) = torch.autograd.grad(transmittance(water).sum(), water)
    def forward(step):
        return float((transmittance(torch.tensor(step, dtype=torch.float64)).sum()
                      - transmittance(torch.tensor(0.0, dtype=torch.float64)).sum()) / step)

    richardson = 2.0 * forward(1e-8) - forward(2e-8)  # first-order error removed
    assert float(grad) < 0.0
    assert float(grad) == pytest.approx(richardson, rel=1e-5)
    water = torch.tensor([0.7, 2.0], dtype=torch.float64, requires_grad=True)
    tau = _earth(precipitable_water_cm=water[:, None]).optical_depth(wavelength, zenith)
    (tau.sum()).backward()
    assert torch.all(water.grad > 0)


def test_float32_matches_float64():
    atm = Atmosphere.earth(precipitable_water_cm=2.0)
    wavelength = torch.tensor([690.0, 762.5, 937.0], dtype=torch.float64)
    zenith = torch.tensor([0.0, 1.4], dtype=torch.float64)
    t64 = atm.transmittance(wavelength, zenith)
    t32 = atm.transmittance(wavelength.float(), zenith.float())
    assert t32.dtype == torch.float32
    torch.testing.assert_close(t32.double(), t64, rtol=1e-5, atol=1e-7)


def test_mars_has_no_oxygen_and_dry_earth_no_water():
    wavelength = torch.tensor([762.5, 937.0], dtype=torch.float64)
    mars = Atmosphere.mars().optical_depth(wavelength, per_species=True)
    assert float(mars["o2"].abs().max()) == 0.0 and float(mars["o2o2"].abs().max()) == 0.0
    dry = _earth(precipitable_water_cm=0.0).optical_depth(wavelength, per_species=True)
    assert float(dry["h2o"].abs().max()) == 0.0 and float(dry["o2"][0]) > 0.3


@pytest.mark.parametrize("bad", [-0.1, 10.5, float("nan")])
def test_bad_precipitable_water_raises(bad):
    with pytest.raises(ValueError, match="precipitable_water_cm"):
        Atmosphere.earth(precipitable_water_cm=bad)


@pytest.mark.parametrize("wavelength", [241.0, 1100.5, 1500.0])
def test_out_of_range_wavelength_raises(wavelength):
    with pytest.raises(ValueError, match=r"wavelength_nm must be in \[242.0, 1100.0\] nm"):
        gases.bird_coefficients(torch.tensor([wavelength]))
    with pytest.raises(ValueError, match="wavelength_nm"):
        Atmosphere.earth().optical_depth(torch.tensor([wavelength]))


def test_bad_amounts_raise():
    with pytest.raises(ValueError, match="amount"):
        gases.water_vapour_optical_depth(torch.tensor([937.0]), -1.0)
    with pytest.raises(ValueError, match="o2_squared_path"):
        gases.o2o2_optical_depth(torch.tensor([577.0]), -1.0)
    with pytest.raises(TypeError, match="amount"):
        gases.mixed_gas_optical_depth(torch.tensor([762.5]), "one")


def test_coefficients_zero_below_the_table_and_the_cia_data():
    """242-300 nm: no band coefficients (SPECTRL2's table starts at 300 nm with zeros).

    The O2-O2 table has no data below 336 nm.
    """
    a_w, a_u = gases.bird_coefficients(torch.tensor([242.0, 280.0, 300.0]))
    assert float(a_w.abs().max()) == 0.0 and float(a_u.abs().max()) == 0.0
    assert float(gases.o2o2_coefficient(torch.tensor([250.0, 335.0])).abs().max()) == 0.0


def _us1976_sounding(water):
    """US 1976 sampled every 500 m (pressure, temperature).

    Optionally with an h2o_vmr that makes the water density exp(-h / 2 km) (vmr times the air
    density p/kT).
    """
    import xarray as xr

    from skytorch.atmosphere.profiles import us1976, us1976_pressure_ratio, us1976_temperature

    altitude = np.arange(0.0, 100e3 + 250.0, 500.0)
    h = torch.tensor(altitude, dtype=torch.float64)
    variables = {
        "pressure": ("altitude", 101325.0 * us1976_pressure_ratio(h).numpy(), {"units": "Pa"}),
        "temperature": ("altitude", us1976_temperature(h).numpy(), {"units": "K"}),
    }
    if water:
        vmr = 0.01 * np.exp(-altitude / H_WATER) / us1976(h).numpy()
        variables["h2o_vmr"] = ("altitude", vmr, {"units": "1"})
    return xr.Dataset(variables, coords={"altitude": ("altitude", altitude, {"units": "m"})})


@pytest.mark.parametrize("water_in_sounding", [False, True])
def test_sounding_gives_the_us1976_gas_optical_depths(water_in_sounding):
    """A sounding sampled from US 1976 gives the built-in US 1976 gas optical depths.

    With or without an h2o_vmr that reproduces the 2 km water profile; slant and near the horizon,
    within 1 % (the sounding is interpolated log-linearly between 500 m levels).
    """
    wavelength = torch.tensor([690.0, 762.5, 937.0, 1065.0], dtype=torch.float64)
    zenith = torch.tensor([0.0, 1.2, 1.5], dtype=torch.float64)
    built_in = Atmosphere.earth(precipitable_water_cm=2.0).optical_depth(
        wavelength, zenith, per_species=True)
    sounding = Atmosphere.earth(precipitable_water_cm=2.0,
                                profile=_us1976_sounding(water_in_sounding))
    assert sounding.molecule_profile == "sounding"
    tau = sounding.optical_depth(wavelength, zenith, per_species=True)
    for name in gases.GAS_SPECIES:
        torch.testing.assert_close(tau[name], built_in[name], rtol=1e-2, atol=1e-6)
