"""Tests of skytorch.spectrum against published colorimetric and photometric references."""

from __future__ import annotations

import math

import pytest
import torch
from scipy.integrate import quad

from skytorch import spectrum
from skytorch.constants import (
    BOLTZMANN_J_K,
    MAG,
    PERCENT,
    PLANCK_J_S,
    SPEED_OF_LIGHT_M_S,
)
from skytorch.dataset import open_dataset

#: tolerance on CIE 1931 chromaticity coordinates
CHROMATICITY = 1.0
#: second radiation constant c2 = hc/k [m K] (CODATA 2018, exact)
C2_M_K = PLANCK_J_S * SPEED_OF_LIGHT_M_S / BOLTZMANN_J_K
#: Stefan–Boltzmann constant [W m^-2 K^-4] (CODATA 2018)
STEFAN_BOLTZMANN = 5.670374419e-8


def chromaticity(xyz: torch.Tensor) -> torch.Tensor:
    return xyz[..., :2] / xyz.sum(-1, keepdim=True)


def planck_si(wavelength_m: float, temperature_k: float) -> float:
    """Planck's law written independently, [W m^-2 sr^-1 m^-1]."""
    x = C2_M_K / (wavelength_m * temperature_k)
    return 2 * PLANCK_J_S * SPEED_OF_LIGHT_M_S**2 / wavelength_m**5 / math.expm1(x)


# --- grids and tables ---------------------------------------------------------------------------

def test_wavelength_presets():
    assert spectrum.wavelength_grid("rgb").tolist() == [680.0, 550.0, 440.0]
    bands = spectrum.wavelength_grid("bands15")
    width = (830.0 - 360.0) / 15
    assert bands.shape == (15,)
    assert torch.allclose(bands, 360.0 + width * (torch.arange(15, dtype=torch.float64) + 0.5))
    cie5 = spectrum.wavelength_grid("cie5", dtype=torch.float32)
    assert cie5.dtype == torch.float32 and cie5.shape == (95,)
    assert float(cie5[0]) == 360.0 and float(cie5[-1]) == 830.0


def test_photopic_peak_is_one_at_555_nm():
    wavelength = spectrum.wavelength_grid("cie1")
    v = spectrum.photopic_luminous_efficiency(wavelength)
    assert float(v[wavelength == 555.0]) == 1.0
    assert float(wavelength[torch.argmax(v)]) == 555.0
    # y-bar of the CIE 1931 observer is V(lambda) of 1924 by definition
    ybar = spectrum.cie_xyz_cmf(wavelength)[:, 1]
    assert torch.allclose(ybar, v, atol=1e-9)
    # zero outside the tabulated range
    assert float(spectrum.photopic_luminous_efficiency(900.0)) == 0.0


def test_passbands_match_bessell_1990_table_points():
    # Bessell 1990 Table 2: V peaks at 530 nm, B at 420 nm; V(550) = 0.898, B(450) = 0.853
    assert float(spectrum.v_band_response(530.0)) == 1.0
    assert float(spectrum.b_band_response(420.0)) == 1.0
    assert float(spectrum.v_band_response(550.0)) == pytest.approx(0.898)
    assert float(spectrum.b_band_response(450.0)) == pytest.approx(0.853)
    assert float(spectrum.v_band_response(400.0)) == 0.0
    assert float(spectrum.b_band_response(650.0)) == 0.0


def test_cousins_r_and_i_passbands_match_bessell_1990_table_points():
    # Bessell 1990 Table 2: R_C peaks at 600 nm, R(700) = 0.61, R(800) = 0.14, zero at
    # 550 and 900 nm; I_C is 1 at 800-810 nm, I(750) = 0.91, I(900) = 0.15, zero at 920 nm
    assert float(spectrum.r_band_response(600.0)) == 1.0
    assert float(spectrum.r_band_response(700.0)) == pytest.approx(0.61)
    assert float(spectrum.r_band_response(800.0)) == pytest.approx(0.14)
    assert float(spectrum.i_band_response(805.0)) == 1.0
    assert float(spectrum.i_band_response(750.0)) == pytest.approx(0.91)
    assert float(spectrum.i_band_response(900.0)) == pytest.approx(0.15)
    for response, outside in ((spectrum.r_band_response, (540.0, 905.0)),
                              (spectrum.i_band_response, (690.0, 925.0))):
        assert float(response(outside[0])) == 0.0 and float(response(outside[1])) == 0.0


def test_band_grids_cover_their_passbands():
    # B and V on the CIE grid; R and I on whole nanometres over their own tables
    assert torch.equal(spectrum.band_grid("V"), spectrum.wavelength_grid("cie1"))
    for band, (low, high) in (("R", (550.0, 900.0)), ("I", (700.0, 920.0))):
        grid = spectrum.band_grid(band, dtype=torch.float32)
        assert grid.dtype == torch.float32
        assert (float(grid[0]), float(grid[-1])) == (low, high)
        assert torch.all(grid[1:] - grid[:-1] == 1.0)


def test_solar_table_plus_infrared_tail_gives_total_solar_irradiance():
    # Total solar irradiance 1361 W m^-2 (Kopp & Lean 2011, doi:10.1029/2010GL045777).
    # The table covers 280-4000 nm; beyond 4000 nm the Sun radiates like a 5772 K black
    # body (IAU 2015 nominal T_eff), whose fraction there is integrated independently.
    fine = torch.arange(280.0, 4000.0 + 0.25, 0.5, dtype=torch.float64)
    table_integral = float(torch.trapezoid(spectrum.solar_irradiance(fine), fine))
    total = quad(planck_si, 1e-8, 1e-3, args=(5772.0,), limit=500)[0]
    tail = quad(planck_si, 4e-6, 1e-3, args=(5772.0,), limit=500)[0]
    estimate = table_integral + 1361.0 * tail / total
    assert estimate == pytest.approx(1361.0, rel=1 * PERCENT)


def test_solar_band_average_is_mean_of_fine_table():
    # the band mean from the cumulative integral equals a brute-force average
    centre = spectrum.wavelength_grid("bands15")[5]
    width = (830.0 - 360.0) / 15
    fine = torch.linspace(float(centre) - width / 2, float(centre) + width / 2, 20001,
                          dtype=torch.float64)
    brute = torch.trapezoid(spectrum.solar_irradiance(fine), fine) / width
    assert float(spectrum.solar_irradiance(centre, bandwidth_nm=width)) == pytest.approx(
        float(brute), rel=1e-6)


# --- colorimetry ----------------------------------------------------------------------------------

@pytest.mark.parametrize("preset", ["cie1", "cie5", "bands15", "rgb"])
def test_equal_energy_white_point(preset):
    # CIE illuminant E has chromaticity (1/3, 1/3) by construction of the observer
    wavelength = spectrum.wavelength_grid(preset)
    xyz = spectrum.spectrum_to_xyz(torch.ones_like(wavelength), wavelength)
    assert torch.allclose(chromaticity(xyz), torch.full((2,), 1 / 3, dtype=torch.float64),
                          atol=1e-3 * CHROMATICITY)


def test_planckian_locus_6504_k():
    # Planckian locus at 6504 K: (x, y) = (0.3135, 0.3237) (Wyszecki & Stiles 1982,
    # Color Science 2nd ed., Table 1(3.11) interpolated)
    xy = chromaticity(spectrum.temperature_to_xyz(6504.0))
    assert torch.allclose(xy, torch.tensor([0.3135, 0.3237], dtype=torch.float64),
                          atol=2e-3 * CHROMATICITY)


def test_illuminant_a_chromaticity():
    # CIE standard illuminant A: Planckian radiator at 2848 K with c2 = 1.435e-2 m K,
    # chromaticity (0.44757, 0.40745) (CIE 015:2004, Table T.3)
    temperature = 2848.0 * C2_M_K / 1.435e-2
    xy = chromaticity(spectrum.temperature_to_xyz(temperature))
    assert torch.allclose(xy, torch.tensor([0.44757, 0.40745], dtype=torch.float64),
                          atol=2e-4 * CHROMATICITY)


def test_srgb_of_d65_white_is_one():
    # D65 white point (x, y) = (0.3127, 0.3290), Y = 1 (IEC 61966-2-1)
    x, y = 0.3127, 0.3290
    xyz = torch.tensor([x / y, 1.0, (1 - x - y) / y], dtype=torch.float64)
    assert torch.allclose(spectrum.xyz_to_srgb(xyz), torch.ones(3, dtype=torch.float64),
                          atol=1e-3)
    assert torch.allclose(spectrum.xyz_to_linear_srgb(xyz), torch.ones(3, dtype=torch.float64),
                          atol=1e-3)


def test_srgb_transfer_function_closed_form():
    # IEC 61966-2-1: linear 0.5 -> 1.055 * 0.5**(1/2.4) - 0.055; 0.002 -> 12.92 * 0.002
    for linear, encoded in ((0.5, 1.055 * 0.5 ** (1 / 2.4) - 0.055), (0.002, 12.92 * 0.002)):
        y = torch.tensor(linear, dtype=torch.float64)
        # XYZ of a neutral grey with linear sRGB = (c, c, c)
        xyz = torch.linalg.solve(torch.tensor(spectrum.XYZ_TO_LINEAR_SRGB, dtype=torch.float64),
                                 y.repeat(3))
        assert torch.allclose(spectrum.xyz_to_srgb(xyz), torch.full((3,), encoded,
                                                                    dtype=torch.float64))
    # negative (out-of-gamut) components stay finite and odd-symmetric, clip bounds them
    xyz = torch.tensor([0.2, 0.5, 0.05], dtype=torch.float64)
    rgb = spectrum.xyz_to_srgb(xyz)
    assert torch.isfinite(rgb).all() and (rgb < 0).any()
    assert float(spectrum.xyz_to_srgb(xyz, clip=True).min()) == 0.0


@pytest.mark.parametrize("preset, tolerance", [("bands15", 5e-4), ("rgb", 3e-3)])
def test_coarse_grid_colour_of_5800_k_black_body(preset, tolerance):
    # converged reference: the same black body on the 1-nm CIE grid
    fine = spectrum.wavelength_grid("cie1")
    reference = chromaticity(spectrum.spectrum_to_xyz(spectrum.blackbody_radiance(fine, 5800.0),
                                                      fine))
    coarse = spectrum.wavelength_grid(preset)
    xy = chromaticity(spectrum.spectrum_to_xyz(spectrum.blackbody_radiance(coarse, 5800.0),
                                               coarse))
    assert torch.allclose(xy, reference, atol=tolerance * CHROMATICITY)


def test_solar_reference_reconstruction_of_a_rayleigh_sky():
    # a sunlit Rayleigh sky, solar spectrum x lambda^-4: bands15 relative to the Sun
    # matches the 1-nm integral far better than a plain piecewise-linear reconstruction
    def sky(wavelength):
        return spectrum.solar_irradiance(wavelength) * (wavelength / 550.0) ** -4

    fine = spectrum.wavelength_grid("cie1")
    reference = chromaticity(spectrum.spectrum_to_xyz(sky(fine), fine))
    bands = spectrum.wavelength_grid("bands15")
    solar = chromaticity(spectrum.spectrum_to_xyz(sky(bands), bands, reference="solar"))
    plain = chromaticity(spectrum.spectrum_to_xyz(sky(bands), bands))
    assert torch.allclose(solar, reference, atol=5e-4 * CHROMATICITY)
    assert (plain - reference).abs().max() > 3 * (solar - reference).abs().max()


def test_wavelength_order_does_not_matter():
    wavelength = spectrum.wavelength_grid("rgb")
    values = torch.tensor([[0.3, 0.5, 0.9], [1.0, 2.0, 3.0]], dtype=torch.float64)
    permutation = torch.tensor([2, 0, 1])
    assert torch.allclose(spectrum.spectrum_to_xyz(values, wavelength),
                          spectrum.spectrum_to_xyz(values[:, permutation],
                                                   wavelength[permutation]))


def test_luminous_factor():
    wavelength = spectrum.wavelength_grid("cie1")
    radiance = torch.zeros_like(wavelength)
    radiance[wavelength == 555.0] = 1.0  # 1 W m^-2 sr^-1 in the 1-nm bin at 555 nm
    luminance = spectrum.spectrum_to_xyz(radiance, wavelength, luminous=True)[1]
    assert float(luminance) == pytest.approx(683.002, rel=1e-9)


def test_temperature_to_srgb_colours():
    rgb = spectrum.temperature_to_srgb(torch.tensor([3000.0, 20000.0], dtype=torch.float64))
    assert torch.allclose(rgb.amax(-1), torch.ones(2, dtype=torch.float64))
    assert rgb[0, 0] > rgb[0, 2]  # cool star: red > blue
    assert rgb[1, 2] > rgb[1, 0]  # hot star: blue > red


# --- photometry ---------------------------------------------------------------------------------

def test_solar_colour_and_magnitude():
    wavelength = spectrum.wavelength_grid("cie1")
    sun = spectrum.solar_irradiance(wavelength)
    v = spectrum.spectrum_to_magnitude(sun, wavelength, "V")
    b = spectrum.spectrum_to_magnitude(sun, wavelength, "B")
    # Ramirez et al. 2012, ApJ 752, 5, doi:10.1088/0004-637X/752/1/5: (B-V)_sun = 0.653
    assert float(b - v) == pytest.approx(0.653, abs=0.03 * MAG)
    # Willmer 2018, ApJS 236, 47, doi:10.3847/1538-4365/aabfdf: V_sun = -26.76 (Vega)
    assert float(v) == pytest.approx(-26.76, abs=0.05 * MAG)


def test_solar_cousins_colours():
    # Ramirez et al. 2012, ApJ 752, 5, doi:10.1088/0004-637X/752/1/5 (line-depth-ratio
    # solution): (V-R)_C = 0.356 +- 0.003 and (V-I)_C = 0.701 +- 0.003, so
    # (R-I)_C = 0.345. The ASTM G173 Sun with Bessell 1990 passbands and Bessell et al.
    # 1998 zero points gives V-R = 0.378 and R-I = 0.360, both redder, so that
    # V-I = 0.739 is 0.038 mag redder than Ramirez (beyond 0.03; stated in the Notes of
    # spectrum_to_magnitude, not asserted at that tolerance).
    wavelength = torch.arange(350.0, 1001.0, 1.0, dtype=torch.float64)
    sun = spectrum.solar_irradiance(wavelength)
    v, r, i = (spectrum.spectrum_to_magnitude(sun, wavelength, band) for band in "VRI")
    assert float(v - r) == pytest.approx(0.356, abs=0.03 * MAG)
    assert float(r - i) == pytest.approx(0.701 - 0.356, abs=0.03 * MAG)


@pytest.mark.parametrize("band", ["R", "I"])
def test_red_band_magnitude_against_quadrature(band):
    # a 4000 K black body, integrated with scipy's adaptive quadrature against the
    # passband table (linear interpolation written with numpy): the energy-weighted mean
    # over the whole passband, including its part beyond 830 nm
    import numpy as np

    table = np.loadtxt(f"data/bessell1990_{band.lower()}.csv", delimiter=",", comments="#",
                       skiprows=5)

    def response(x):
        return float(np.interp(x, table[:, 0], table[:, 1]))

    low, high = table[0, 0], table[-1, 0]
    points = list(table[:, 0])
    numerator = quad(lambda x: planck_si(x * 1e-9, 4000.0) * 1e-9 * response(x), low, high,
                     points=points, limit=200)[0]
    denominator = quad(response, low, high, points=points, limit=200)[0]
    zero = spectrum.ZERO_POINT_FLUX_W_M2_NM["bessell1998"][band]
    expected = -2.5 * math.log10(numerator / denominator / zero)
    wavelength = torch.arange(500.0, 1000.5, 0.5, dtype=torch.float64)
    flux = spectrum.blackbody_radiance(wavelength, 4000.0)
    magnitude = spectrum.spectrum_to_magnitude(flux, wavelength, band)
    assert float(magnitude) == pytest.approx(expected, abs=1e-4 * MAG)


def test_magnitude_zero_point_definition():
    # a flat f_lambda equal to Bessell et al. 1998's zero point has magnitude 0
    wavelength = spectrum.wavelength_grid("cie5")
    for band, flux in (("V", 3.631e-11), ("B", 6.32e-11), ("R", 2.177e-11),
                       ("I", 1.126e-11)):
        m = spectrum.spectrum_to_magnitude(torch.full_like(wavelength, flux), wavelength, band)
        assert abs(float(m)) < 1e-9 * MAG
    # ten times fainter -> +2.5 mag, with an explicit zero point
    m = spectrum.spectrum_to_magnitude(torch.full_like(wavelength, 1e-12), wavelength,
                                       zero_point=1e-11)
    assert float(m) == pytest.approx(2.5, abs=1e-9)


def test_bv_to_temperature():
    # Ballesteros 2012 eq. 14 in closed form; the Sun's B-V = 0.65 gives ~5772 K (IAU)
    bv = 0.65
    expected = 4600.0 * (1 / (0.92 * bv + 1.7) + 1 / (0.92 * bv + 0.62))
    assert float(spectrum.bv_to_temperature(bv)) == pytest.approx(expected, rel=1e-12)
    assert float(spectrum.bv_to_temperature(bv)) == pytest.approx(5772.0, abs=150.0)
    temperatures = spectrum.bv_to_temperature(torch.tensor([-0.3, 0.0, 1.0, 2.0]))
    assert (temperatures[1:] < temperatures[:-1]).all()


# --- black bodies ---------------------------------------------------------------------------------

def test_planck_wien_and_rayleigh_jeans_limits():
    c1 = 2 * PLANCK_J_S * SPEED_OF_LIGHT_M_S**2
    # Wien (x = hc/(lambda k T) >> 1): B / B_Wien = 1 / (1 - exp(-x))
    wavelength_nm, temperature = 300.0, 3000.0
    x = C2_M_K / (wavelength_nm * 1e-9 * temperature)
    wien = c1 / (wavelength_nm * 1e-9) ** 5 * math.exp(-x) * 1e-9
    ratio = float(spectrum.blackbody_radiance(wavelength_nm, temperature)) / wien
    assert ratio == pytest.approx(1 / (1 - math.exp(-x)), rel=1e-12)
    # Rayleigh-Jeans (x << 1): B = 2 c k T / lambda^4 (1 - x/2 + ...)
    wavelength_nm, temperature = 1e7, 1e4
    lam = wavelength_nm * 1e-9
    x = C2_M_K / (lam * temperature)
    rayleigh_jeans = 2 * SPEED_OF_LIGHT_M_S * BOLTZMANN_J_K * temperature / lam**4 * 1e-9
    assert float(spectrum.blackbody_radiance(wavelength_nm, temperature)) == pytest.approx(
        rayleigh_jeans * (1 - x / 2 + x**2 / 12), rel=1e-6)


def test_stefan_boltzmann():
    # pi * integral of B_lambda = sigma T^4
    temperature = 5772.0
    wavelength = torch.logspace(1, 7, 200001, dtype=torch.float64)  # 10 nm .. 1 cm
    radiance = spectrum.blackbody_radiance(wavelength, temperature)
    exitance = math.pi * float(torch.trapezoid(radiance, wavelength))
    assert exitance == pytest.approx(STEFAN_BOLTZMANN * temperature**4, rel=1e-5)


def test_blackbody_hard_cases(dtype):
    wavelength = torch.tensor([10.0, 550.0, 1e6], dtype=dtype)
    temperature = torch.tensor([10.0, 5772.0, 1e5], dtype=dtype, requires_grad=True)
    radiance = spectrum.blackbody_radiance(wavelength, temperature)
    assert radiance.dtype == dtype
    assert torch.isfinite(radiance).all()
    values = radiance.detach()
    assert float(values[0]) == 0.0  # exp(-x) underflows to exactly 0
    reference = planck_si(550e-9, 5772.0) * 1e-9
    tolerance = 1e-12 if dtype == torch.float64 else 1e-5
    assert float(values[1]) == pytest.approx(reference, rel=tolerance)
    radiance.sum().backward()
    assert torch.isfinite(temperature.grad).all()


def test_gradients():
    wavelength = spectrum.wavelength_grid("bands15")
    spectrum_values = torch.rand(2, 15, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda s: spectrum.spectrum_to_xyz(s, wavelength),
                                    (spectrum_values,))
    assert torch.autograd.gradcheck(
        lambda s: spectrum.spectrum_to_magnitude(s + 0.1, wavelength, "V"), (spectrum_values,))
    xyz = torch.tensor([[0.95, 1.0, 1.09], [1e-4, 1e-4, 1e-4], [0.2, 0.5, 0.05]],
                       dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(spectrum.xyz_to_srgb, (xyz,))
    temperature = torch.tensor([3000.0, 6000.0], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(
        lambda t: spectrum.blackbody_radiance(torch.tensor(500.0, dtype=torch.float64), t),
        (temperature,))
    bv = torch.tensor([0.0, 0.65], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(spectrum.bv_to_temperature, (bv,))


def test_float32_colour(dtype):
    wavelength = spectrum.wavelength_grid("bands15", dtype=dtype)
    radiance = spectrum.blackbody_radiance(wavelength, torch.tensor(5800.0, dtype=dtype))
    xyz = spectrum.spectrum_to_xyz(radiance, wavelength)
    rgb = spectrum.spectrum_to_srgb(radiance / xyz[1], wavelength)
    assert xyz.dtype == dtype and rgb.dtype == dtype
    reference = spectrum.spectrum_to_xyz(radiance.double(), wavelength.double())
    assert torch.allclose(xyz.double(), reference, rtol=1e-5)


# --- bad input ------------------------------------------------------------------------------------

def test_bad_input():
    wavelength = spectrum.wavelength_grid("rgb")
    with pytest.raises(ValueError, match="preset"):
        spectrum.wavelength_grid("xyz")
    with pytest.raises(ValueError, match="wavelength_nm"):
        spectrum.cie_xyz_cmf(torch.tensor([-5.0, 550.0]))
    with pytest.raises(ValueError, match="wavelength_nm"):
        spectrum.blackbody_radiance(float("nan"), 5000.0)
    with pytest.raises(ValueError, match="temperature_k"):
        spectrum.blackbody_radiance(500.0, 0.0)
    with pytest.raises(ValueError, match="spectral_radiance"):
        spectrum.spectrum_to_xyz(torch.tensor([1.0, float("nan"), 1.0]), wavelength)
    with pytest.raises(ValueError, match="trailing dimension"):
        spectrum.spectrum_to_xyz(torch.ones(4), wavelength)
    with pytest.raises(ValueError, match="repeat"):
        spectrum.spectrum_to_xyz(torch.ones(2), torch.tensor([500.0, 500.0]))
    with pytest.raises(ValueError, match="reference"):
        spectrum.spectrum_to_xyz(torch.ones(3), wavelength, reference="moon")
    with pytest.raises(ValueError, match="wavelength_nm"):
        spectrum.solar_irradiance(5000.0)
    with pytest.raises(ValueError, match="band"):
        spectrum.spectrum_to_magnitude(torch.ones(3), wavelength, band="U")
    with pytest.raises(ValueError, match="band"):
        spectrum.band_grid("K")
    with pytest.raises(ValueError, match="spectral_flux"):
        spectrum.spectrum_to_magnitude(-torch.ones(3), wavelength)
    with pytest.raises(ValueError, match="bv"):
        spectrum.bv_to_temperature(-0.7)
    with pytest.raises(ValueError, match="xyz"):
        spectrum.xyz_to_srgb(torch.ones(4))
    with pytest.raises(TypeError):
        spectrum.spectrum_to_xyz("bright", wavelength)


def test_accuracy_cost_experiment_quick(tmp_path):
    from experiments.spectrum_accuracy_cost import main

    netcdf_path, png_path = main(["--quick", "--output-dir", str(tmp_path)])
    assert png_path.is_file()
    ds = open_dataset(netcdf_path)
    blackbodies = ["blackbody_3000K", "blackbody_5800K", "blackbody_10000K"]
    error = ds["chromaticity_error"].sel(dtype="float64", spectrum_kind=blackbodies)
    # converged trend: the 5-nm grid is far better than three wavelengths for black bodies
    assert float(error.sel(grid="cie5", reference="none").max()) < 1e-4
    assert float(error.sel(grid="rgb", reference="none").max()) > 1e-3
