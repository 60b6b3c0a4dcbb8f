"""Straight-ray optical depth against closed forms and independent quadrature."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from scipy import integrate, special
from torch.autograd import gradcheck

from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.optical_depth import chapman, chapman_horizontal, kasten_young_air_mass
from skytorch.atmosphere.profiles import us1976
from skytorch.constants import DEGREE, PERCENT

R = 6_371_000.0
TOP = 100_000.0
H = 8_000.0
#: accuracy of the default quadrature against the closed form (issue 3)
DEFAULT_RELATIVE_TOLERANCE = 1e-6


def exact_exponential_column(altitude, zenith, scale_height=H, top=TOP):
    """Independent reference: scipy's adaptive Gauss-Kronrod on the path integral."""
    r0 = R + altitude
    mu = math.cos(zenith)
    rt = R + top
    disc = (r0 * mu) ** 2 + (rt - r0) * (rt + r0)
    length = -r0 * mu + math.sqrt(disc)
    disc_ground = (r0 * mu) ** 2 - (r0 - R) * (r0 + R)
    if mu < 0 and disc_ground >= 0:  # the ray meets the ground
        length = -r0 * mu - math.sqrt(disc_ground)

    def density(s):
        r = math.sqrt(r0 * r0 + s * s + 2.0 * r0 * mu * s)
        return math.exp(-(r - R) / scale_height)

    # split where the integrand varies fastest (near the observer and the tangent point)
    points = sorted({min(length, x) for x in (1e3, 1e4, 5e4, 2e5, max(0.0, -r0 * mu))})
    value, _ = integrate.quad(density, 0.0, length, points=points, epsabs=0.0,
                              epsrel=1e-13, limit=500)
    return value


@pytest.fixture(scope="module")
def rayleigh_only():
    # the closed forms are those of the isothermal exponential
    return Atmosphere.earth(turbidity=1.0, ozone_du=0.0, molecule_profile="exponential")


def test_zenith_column_closed_form(rayleigh_only):
    column = rayleigh_only.column_integrals(0.0, 0.0)["rayleigh"]
    exact = H * (1.0 - math.exp(-TOP / H))
    assert abs(float(column) / exact - 1.0) <= DEFAULT_RELATIVE_TOLERANCE


def test_horizontal_column_bessel_closed_form(rayleigh_only):
    # Ch(x, 90 deg) = x e^x K1(x) (exact); the part above the top is removed with the
    # asymptotic Chapman function at the top (it is 6e-7 of the total, so its 1e-3 error
    # is negligible).
    x = R / H
    to_infinity = H * x * special.kve(1, x)
    rt = R + TOP
    zenith_top = math.asin(R / rt)
    above = H * math.exp(-TOP / H) * float(chapman(torch.tensor(rt / H, dtype=torch.float64),
                                                   torch.tensor(zenith_top, dtype=torch.float64)))
    exact = to_infinity - above
    column = rayleigh_only.column_integrals(torch.tensor(math.pi / 2, dtype=torch.float64),
                                            0.0)["rayleigh"]
    assert abs(float(column) / exact - 1.0) <= DEFAULT_RELATIVE_TOLERANCE


@pytest.mark.parametrize("altitude", [0.0, 3000.0, 40_000.0])
@pytest.mark.parametrize("zenith_deg", [30.0, 60.0, 80.0, 85.0, 89.0, 90.0, 91.0, 95.0])
def test_column_matches_independent_quadrature(rayleigh_only, altitude, zenith_deg):
    if altitude == 0.0 and zenith_deg > 90.0:
        pytest.skip("ray hits the ground at once")
    zenith = zenith_deg * DEGREE
    column = rayleigh_only.column_integrals(torch.tensor(zenith, dtype=torch.float64),
                                            altitude)["rayleigh"]
    exact = exact_exponential_column(altitude, zenith)
    assert abs(float(column) / exact - 1.0) <= DEFAULT_RELATIVE_TOLERANCE


@pytest.mark.parametrize("zenith_deg", [0.0, 45.0, 75.0, 88.0, 90.0, 92.0])
def test_chapman_closed_form_against_quadrature(zenith_deg):
    # Chapman's asymptotic closed form: relative error O(1/x) ~ 1e-3 for x = R/H
    x = R / H
    zenith = zenith_deg * DEGREE
    reference = exact_exponential_column(0.0 if zenith_deg <= 90 else 5000.0, zenith,
                                         top=2e6) / H
    if zenith_deg > 90:
        reference *= math.exp(5000.0 / H)
        x = (R + 5000.0) / H
    value = float(chapman(torch.tensor(x, dtype=torch.float64),
                          torch.tensor(zenith, dtype=torch.float64)))
    assert abs(value / reference - 1.0) <= 2e-3


def test_chapman_horizontal_exact():
    import mpmath

    x = torch.tensor([10.0, 100.0, 800.0], dtype=torch.float64)
    reference = [float(v * mpmath.exp(v) * mpmath.besselk(1, v)) for v in x.tolist()]
    assert np.allclose(chapman_horizontal(x).numpy(), reference, rtol=1e-12)


@pytest.mark.parametrize("zenith_deg", [0.0, 30.0, 60.0, 70.0, 75.0, 80.0])
def test_air_mass_kasten_young_to_80_degrees(rayleigh_only, zenith_deg):
    zenith = torch.tensor(zenith_deg * DEGREE, dtype=torch.float64)
    air_mass = rayleigh_only.air_mass(zenith)
    reference = kasten_young_air_mass(zenith)
    assert abs(float(air_mass / reference) - 1.0) <= 1 * PERCENT


def test_air_mass_kasten_young_at_85_degrees(rayleigh_only):
    zenith = torch.tensor(85.0 * DEGREE, dtype=torch.float64)
    ratio = float(rayleigh_only.air_mass(zenith) / kasten_young_air_mass(zenith))
    assert abs(ratio - 1.0) <= 3 * PERCENT


def _v_band_optical_depth(atm):
    wavelength = torch.arange(470.0, 701.0, 5.0, dtype=torch.float64)
    tau = atm.optical_depth(wavelength)
    try:
        from skytorch.spectrum import solar_irradiance, v_band_response
    except ImportError:  # spectrum module absent: effective V wavelength
        return atm.optical_depth(torch.tensor([550.0], dtype=torch.float64))[..., 0]
    weight = v_band_response(wavelength) * solar_irradiance(wavelength)
    # band-averaged transmittance -> effective optical depth
    transmittance = (torch.exp(-tau) * weight).sum(-1) / weight.sum(-1)
    return -torch.log(transmittance)


@pytest.mark.parametrize("turbidity", [1.5, 2.0, 3.0])
def test_v_band_extinction_coefficient(turbidity):
    atm = Atmosphere.earth(turbidity=turbidity, ozone_du=300.0)
    k = 1.086 * float(_v_band_optical_depth(atm))
    assert 0.15 <= k <= 0.40


def test_methods_agree(rayleigh_only):
    atm = Atmosphere.earth(turbidity=3.0, ozone_du=300.0)
    zenith = torch.tensor([0.0, 1.0, 1.5, 1.55, 1.6], dtype=torch.float64)
    altitude = torch.tensor(2000.0, dtype=torch.float64)
    wavelength = torch.tensor([450.0, 600.0], dtype=torch.float64)
    reference = atm.optical_depth(wavelength, zenith, altitude, method="adaptive", n_steps=16)
    gauss = atm.optical_depth(wavelength, zenith, altitude)
    trapezoid = atm.optical_depth(wavelength, zenith, altitude, method="trapezoid",
                                  n_steps=20_000)
    assert torch.allclose(gauss, reference, rtol=1e-6, atol=0.0)
    assert torch.allclose(trapezoid, reference, rtol=1e-4, atol=0.0)


def test_batched_parameter_sweep_matches_single_calls():
    turbidity = torch.tensor([1.0, 2.0, 3.0, 5.0, 10.0], dtype=torch.float64)[:, None]
    ozone = torch.tensor([0.0, 200.0, 300.0, 400.0], dtype=torch.float64)[None, :]
    wavelength = torch.tensor([440.0, 550.0, 680.0], dtype=torch.float64)
    swept = Atmosphere.earth(turbidity=turbidity, ozone_du=ozone).optical_depth(
        wavelength, torch.tensor(1.2, dtype=torch.float64))
    assert swept.shape == (5, 4, 3)
    single = Atmosphere.earth(turbidity=3.0, ozone_du=400.0).optical_depth(
        wavelength, torch.tensor(1.2, dtype=torch.float64))
    assert torch.allclose(swept[2, 3], single, rtol=1e-12)


def test_batched_geometry_and_parameters_broadcast():
    atm = Atmosphere.earth(turbidity=torch.tensor([2.0, 4.0], dtype=torch.float64)[:, None])
    zenith = torch.linspace(0.0, 1.5, 7, dtype=torch.float64)
    tau = atm.optical_depth(torch.tensor([550.0], dtype=torch.float64), zenith)
    assert tau.shape == (2, 7, 1)
    assert bool((tau[1] > tau[0]).all())


def test_per_species_sum_to_total():
    atm = Atmosphere.earth(turbidity=2.5, ozone_du=350.0)
    wavelength = torch.tensor([500.0, 600.0], dtype=torch.float64)
    parts = atm.optical_depth(wavelength, 1.0, per_species=True)
    total = atm.optical_depth(wavelength, 1.0)
    assert torch.allclose(sum(parts.values()), total, rtol=1e-14)


def test_pressure_scaling_of_rayleigh_depth():
    wavelength = torch.tensor([550.0], dtype=torch.float64)
    sea = Atmosphere.earth(turbidity=1.0, ozone_du=0.0)
    high = Atmosphere.earth(turbidity=1.0, ozone_du=0.0, surface_pressure_pa=70_000.0)
    ratio = (high.optical_depth(wavelength, per_species=True)["rayleigh"]
             / sea.optical_depth(wavelength, per_species=True)["rayleigh"])
    assert float(ratio) == pytest.approx(70_000.0 / 101_325.0, rel=1e-6)


@pytest.mark.parametrize(("geopotential_m", "pressure_pa", "temperature_k"),
                         [(11_000.0, 22_632.06, 216.65), (20_000.0, 5_474.889, 216.65),
                          (32_000.0, 868.0187, 228.65), (47_000.0, 110.9063, 270.65)])
def test_us1976_density_against_standard_pressures(geopotential_m, pressure_pa,
                                                   temperature_k):
    # U.S. Standard Atmosphere 1976, Table 4: pressure and temperature at layer bases
    r0 = 6_356_766.0
    geometric = r0 * geopotential_m / (r0 - geopotential_m)
    expected = (pressure_pa / 101_325.0) * (288.15 / temperature_k)
    value = float(us1976(torch.tensor(geometric, dtype=torch.float64)))
    assert value == pytest.approx(expected, rel=1e-4)


def test_us1976_profile_rayleigh_depth_matches_bodhaine():
    # the column is hydrostatic whatever the profile shape
    wavelength = torch.tensor([550.0], dtype=torch.float64)
    atm = Atmosphere.earth(turbidity=1.0, ozone_du=0.0, molecule_profile="us1976")
    tau = float(atm.optical_depth(wavelength)[0])
    assert tau == pytest.approx(0.0971, rel=1 * PERCENT)
    slant = atm.air_mass(torch.tensor(80 * DEGREE, dtype=torch.float64))
    assert abs(float(slant / kasten_young_air_mass(torch.tensor(80 * DEGREE))) - 1) <= PERCENT


def test_refraction_delegation_and_refracted_air_mass():
    from skytorch.atmosphere import refraction

    atm = Atmosphere.earth(turbidity=1.0, ozone_du=0.0)
    altitude = torch.tensor([5.0, 30.0], dtype=torch.float64) * DEGREE
    assert torch.equal(atm.refraction(altitude), refraction.refraction_angle(atm, altitude))
    # relative air mass along refracted rays vs Kasten & Young 1989: <= 1 % at 85 deg
    zenith = torch.tensor(85.0 * DEGREE, dtype=torch.float64)
    bent = atm.air_mass(zenith, refraction=True)
    assert abs(float(bent / kasten_young_air_mass(zenith)) - 1.0) <= 1 * PERCENT


def _mpmath_chapman(x, zenith):
    """Ch(x, z) = integral of exp(x - r(t)) dt along the straight ray, by mpmath."""
    import mpmath

    mpmath.mp.dps = 30
    x, mu = mpmath.mpf(x), mpmath.cos(mpmath.mpf(zenith))
    points = [0, -x * mu] if mu < 0 else [0]
    points += [points[-1] + 60, mpmath.inf]
    return float(mpmath.quad(lambda t: mpmath.exp(x - mpmath.sqrt(x * x + 2 * x * t * mu + t * t)),
                             points))


@pytest.mark.parametrize("x", [50.0, 305.0, 800.0])
def test_exact_chapman_against_mpmath(x):
    zenith_deg = [0.0, 45.0, 80.0, 89.0, 89.9, 90.0, 90.1, 93.0, 100.0]
    zenith = torch.tensor(zenith_deg, dtype=torch.float64) * DEGREE
    value = chapman(torch.tensor(x, dtype=torch.float64), zenith, exact=True)
    reference = torch.tensor([_mpmath_chapman(x, float(z)) for z in zenith],
                             dtype=torch.float64)
    assert float((value / reference - 1.0).abs().max()) <= 1e-10
    # the asymptotic form is O(1/x): measurably worse, which the exact form removes
    asymptotic = chapman(torch.tensor(x, dtype=torch.float64), zenith)
    assert float((asymptotic / reference - 1.0).abs().max()) > 1e-5


def test_exact_chapman_float32_and_gradient():
    zenith = torch.tensor([0.3, 1.2, 1.5707, 1.7], dtype=torch.float64, requires_grad=True)
    x = torch.tensor(800.0, dtype=torch.float64)
    assert gradcheck(lambda z: chapman(x, z, exact=True), (zenith,))
    single = chapman(x.float(), zenith.detach().float(), exact=True)
    assert single.dtype == torch.float32
    double = chapman(x, zenith.detach(), exact=True)
    assert float((single.double() / double - 1.0).abs().max()) <= 1e-5


def test_many_straight_rays_are_integrated_in_chunks_without_changing_them():
    """More than 2 RAY_CHUNK rays go through in chunks: same values, shapes, gradients."""
    from skytorch.atmosphere import Atmosphere
    from skytorch.atmosphere.model import RAY_CHUNK

    atm = Atmosphere.earth(turbidity=2.5, ozone_du=300.0)
    rows = 2 * RAY_CHUNK // 7 + 150  # rows x 7 altitudes > 2 RAY_CHUNK rays
    generator = torch.Generator().manual_seed(1)
    zenith = torch.rand(rows, 1, generator=generator, dtype=torch.float64) * 1.6
    altitude = torch.linspace(0.0, 5000.0, 7, dtype=torch.float64)
    wavelength = torch.tensor([340.0, 550.0, 762.0, 940.0], dtype=torch.float64)
    chunked = atm.optical_depth(wavelength, zenith, altitude, per_species=True)
    whole = atm._optical_depth(wavelength, zenith, altitude, per_species=True)
    for key, value in whole.items():
        assert chunked[key].shape == value.shape == (rows, 7, 4)
        assert torch.equal(chunked[key], value), key
    leaf = zenith.clone().requires_grad_(True)
    atm.optical_depth(wavelength, leaf, altitude).sum().backward()
    assert torch.isfinite(leaf.grad).all() and bool((leaf.grad.abs() > 0).any())
