"""Refracted rays: astronomical refraction, bent optical depth, grazing rays, deviation table.

References used (independent of the code under test):

* Bennett 1982 refraction formula, scaled from its conditions (1010 hPa, 10 °C) to the
  model's sea-level refractivity;
* Kasten & Young 1989 relative air mass;
* the small-refractivity asymptote of the bending of a grazing ray through an exponential
  atmosphere, :math:`\\delta \\approx \\nu(h_p)\\sqrt{2\\pi r_p/H}`;
* RK4 ray tracing of the eikonal equation (an algorithm sharing no formula with the
  Bouguer integrals), converged at small steps.
"""

from __future__ import annotations

import math

import pytest
import torch
from torch.autograd import gradcheck

from skytorch.atmosphere import refraction as rf
from skytorch.constants import ARCMINUTE, ARCSECOND, DEGREE, PERCENT

EARTH_RADIUS_M = 6_371_000.0
EARTH_TOP_M = 100_000.0
SCALE_HEIGHT_M = 8_000.0
NU_EARTH = 2.77e-4
MARS_RADIUS_M = 3_389_500.0
MARS_TOP_M = 80_000.0
MARS_SCALE_HEIGHT_M = 11_100.0
NU_MARS = 3.38e-6


class ExponentialAir:
    """Minimal atmosphere: exponential refractivity and Rayleigh-like extinction."""

    def __init__(self, radius=EARTH_RADIUS_M, top=EARTH_TOP_M, nu0=NU_EARTH,
                 scale_height=SCALE_HEIGHT_M, beta550=1.21e-5):
        self.planet_radius_m = radius
        self.top_altitude_m = top
        self.top_radius_m = radius + top
        self.nu0, self.scale_height, self.beta550 = nu0, scale_height, beta550

    def refractivity(self, altitude_m, wavelength_nm=None):
        return self.nu0 * torch.exp(-altitude_m / self.scale_height)

    def extinction_coefficient(self, altitude_m, wavelength_nm):
        wavelength = torch.as_tensor(wavelength_nm, dtype=altitude_m.dtype)
        return (self.beta550 * torch.exp(-altitude_m / self.scale_height)[..., None]
                * (550.0 / wavelength) ** 4)


@pytest.fixture(scope="module")
def air():
    return ExponentialAir()


def _deg(values, dtype=torch.float64):
    return torch.tensor(values, dtype=dtype) * DEGREE


# --- independent algorithms agree ---------------------------------------------------------


def test_bouguer_matches_rk4_observer(air):
    elevation = _deg([60.0, 20.0, 5.0, 1.0, 0.0])
    bouguer = rf.refraction_angle(air, elevation)
    rk4 = rf.refraction_angle(air, elevation, method="rk4", step_m=2e3, max_dh_m=200.0)
    assert torch.allclose(bouguer, rk4, rtol=0, atol=0.01 * ARCSECOND)


def test_bouguer_matches_rk4_grazing(air):
    impact = torch.tensor([1_800.0, 5e3, 20e3, 60e3], dtype=torch.float64)
    bouguer = rf.trace_grazing_rays(air, impact_altitude_m=impact, wavelength_nm=[450.0, 650.0])
    rk4 = rf.trace_grazing_rays(air, impact_altitude_m=impact, wavelength_nm=[450.0, 650.0],
                                method="rk4", step_m=2e3)
    assert torch.allclose(bouguer["deviation_rad"], rk4["deviation_rad"], rtol=0,
                          atol=0.01 * ARCSECOND)
    assert torch.allclose(bouguer["contact_radius_m"], rk4["contact_radius_m"], rtol=0, atol=0.5)
    assert torch.allclose(bouguer["optical_depth"], rk4["optical_depth"], rtol=1e-5)
    assert not bool(bouguer["hits_ground"].any())


def test_quadrature_converges(air):
    elevation = _deg([30.0, 2.0, 0.0, -0.4])
    reference = rf.refraction_angle(air, elevation, 500.0, n_nodes=256)
    coarse = rf.refraction_angle(air, elevation, 500.0, n_nodes=16)
    assert torch.allclose(coarse, reference, rtol=0, atol=0.001 * ARCSECOND)


# --- published references ---------------------------------------------------------------------


def _bennett_scale(nu_sea_level):
    """Ratio of the model's refractivity to that of Bennett's conditions (1010 hPa, 10 °C).

    Edlén 1966 gives n - 1 = 2.7784e-4 for dry air at 15 °C, 1013.25 hPa, 550 nm; by the
    ideal gas law this becomes 2.818e-4 at 1010 hPa, 10 °C.
    """
    sigma2 = (1.0 / 0.55) ** 2
    edlen = (8342.54 + 2406147.0 / (130.0 - sigma2) + 15998.0 / (38.9 - sigma2)) * 1e-8
    bennett_nu = edlen * (1010.0 / 1013.25) * (288.15 / 283.15)
    return nu_sea_level / bennett_nu


def _bennett(elevation_deg, improved=False):
    """Bennett 1982 [arcmin -> rad]; ``improved`` adds his -0.06' sin(14.7 R + 13 deg) term
    (accuracy 0.015' instead of 0.07'; Meeus 1998, ch. 16)."""
    h = torch.as_tensor(elevation_deg, dtype=torch.float64)
    minutes = 1.0 / torch.tan((h + 7.31 / (h + 4.4)) * DEGREE)
    if improved:
        minutes = minutes - 0.06 * torch.sin((14.7 * minutes + 13.0) * DEGREE)
    return minutes * ARCMINUTE


def test_refraction_vs_bennett(air):
    """Bennett's improved formula is accurate to 0.015' in absolute terms, i.e. to better than
    2 % only up to ~60 degrees; above, its absolute accuracy is the test (and the Laplace
    expansion below checks the relative accuracy). The plain formula carries a systematic
    +0.06' sin(14.7 R + 13 deg) error (0.06' at 10-20 degrees), hence the improved one."""
    elevation = torch.tensor([10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 80.0], dtype=torch.float64)
    model = rf.refraction_angle(air, elevation * DEGREE)
    scale = _bennett_scale(NU_EARTH)
    improved = _bennett(elevation, improved=True) * scale
    low = elevation <= 60.0
    assert torch.allclose(model[low], improved[low], rtol=2 * PERCENT, atol=0)
    high = elevation >= 60.0
    assert torch.allclose(model[high], improved[high], rtol=0, atol=0.015 * ARCMINUTE)


def test_refraction_vs_laplace_expansion(air):
    """R = A tan z - B tan^3 z with A = nu0 (1 - H/R), B = nu0 (H/R - nu0/2) for an
    exponential atmosphere (Laplace; Smart 1977, ch. III), valid for z <= 30 degrees."""
    zenith = torch.tensor([1.0, 10.0, 20.0, 30.0], dtype=torch.float64)
    model = rf.refraction_angle(air, (90.0 - zenith) * DEGREE)
    ratio = SCALE_HEIGHT_M / EARTH_RADIUS_M
    tan_z = torch.tan(zenith * DEGREE)
    laplace = NU_EARTH * (1 - ratio) * tan_z - NU_EARTH * (ratio - NU_EARTH / 2) * tan_z**3
    assert torch.allclose(model, laplace, rtol=1e-5, atol=0)


def _kasten_young(zenith_deg):
    z = torch.as_tensor(zenith_deg, dtype=torch.float64)
    return 1.0 / (torch.cos(z * DEGREE) + 0.50572 * (96.07995 - z) ** -1.6364)


def test_air_mass_along_refracted_rays_vs_kasten_young(air):
    zenith = torch.tensor([0.0, 60.0, 80.0, 85.0, 90.0], dtype=torch.float64)
    tau = rf.bent_optical_depth(air, [550.0], zenith * DEGREE)[..., 0]
    air_mass = tau / tau[0]
    reference = _kasten_young(zenith)
    assert torch.allclose(air_mass[:4], reference[:4], rtol=1 * PERCENT)
    assert abs(float(air_mass[4] / reference[4]) - 1.0) < 5 * PERCENT


def test_grazing_deviation_at_ground_is_twice_horizon_refraction(air):
    rays = rf.trace_grazing_rays(air, periapsis_altitude_m=torch.tensor(0.0, dtype=torch.float64))
    rk4 = rf.trace_grazing_rays(air, impact_altitude_m=rays["impact_altitude_m"] + 0.05,
                                method="rk4", step_m=2e3)
    horizon = rf.refraction_angle(air, torch.tensor(0.0, dtype=torch.float64), method="rk4",
                                  step_m=2e3)
    assert abs(float(rays["deviation_rad"] - 2 * horizon)) < 0.5 * ARCSECOND
    assert abs(float(rays["deviation_rad"] - rk4["deviation_rad"])) < 0.5 * ARCSECOND
    # the classical ~70' (about 1.2 degrees) that bends sunlight into the umbra
    assert 65 * ARCMINUTE < float(rays["deviation_rad"]) < 80 * ARCMINUTE


@pytest.mark.parametrize("periapsis_m", [0.0, 10e3, 30e3])
def test_mars_grazing_deviation_small_refractivity_asymptote(periapsis_m):
    mars = ExponentialAir(MARS_RADIUS_M, MARS_TOP_M, NU_MARS, MARS_SCALE_HEIGHT_M)
    rays = rf.trace_grazing_rays(mars, periapsis_altitude_m=torch.tensor(periapsis_m,
                                                                         dtype=torch.float64))
    r_p = MARS_RADIUS_M + periapsis_m
    nu_p = NU_MARS * math.exp(-periapsis_m / MARS_SCALE_HEIGHT_M)
    asymptote = nu_p * math.sqrt(2 * math.pi * r_p / MARS_SCALE_HEIGHT_M)
    assert abs(float(rays["deviation_rad"]) / asymptote - 1.0) < 0.5 * PERCENT


def test_apparent_altitude_inverts_refraction(air):
    true = _deg([-0.5, 0.0, 0.3, 5.0, 45.0, 89.0])
    apparent = rf.apparent_altitude(air, true)
    recovered = apparent - rf.refraction_angle(air, apparent)
    assert torch.allclose(recovered, true, rtol=0, atol=0.01 * ARCSECOND)
    # independent: the RK4 tracer at the solution gives the same true altitude
    rk4 = apparent - rf.refraction_angle(air, apparent, method="rk4", step_m=2e3,
                                         max_dh_m=200.0)
    assert torch.allclose(rk4[1:], true[1:], rtol=0, atol=0.05 * ARCSECOND)


# --- hard cases -----------------------------------------------------------------------------------


def test_hard_cases_refraction_dtype(air, dtype):
    elevation = _deg([90.0, 0.0, -0.5, -5.0, -90.0], dtype)
    for height in (0.0, 10e3, EARTH_TOP_M, 300e3):
        result = rf.refraction_angle(air, elevation, torch.tensor(height, dtype=dtype))
        reference = rf.refraction_angle(air, _deg([90.0, 0.0, -0.5, -5.0, -90.0]), height)
        assert result.dtype == dtype
        assert torch.isfinite(result).all()
        assert torch.allclose(result.double(), reference, rtol=0, atol=0.05 * ARCSECOND)
    assert abs(float(rf.refraction_angle(air, elevation[0]))) < 1e-9 * ARCSECOND
    # below the horizon from a mountain: the ray dips to a periapsis and comes back
    high = rf.refraction_angle(air, _deg([-1.0], dtype), 3000.0)
    rk4 = rf.refraction_angle(air, _deg([-1.0]), 3000.0, method="rk4", step_m=2e3,
                              max_dh_m=200.0)
    assert abs(float(high.double() - rk4)) < 0.05 * ARCSECOND


def test_hard_cases_grazing_dtype(air, dtype):
    top = EARTH_TOP_M
    impact = torch.tensor([-5e3, 0.0, 1764.0, 1765.0, 50e3, top - 1.0, top, top + 1.0],
                          dtype=dtype)
    rays = rf.trace_grazing_rays(air, impact_altitude_m=impact, wavelength_nm=[440.0, 680.0])
    reference = rf.trace_grazing_rays(air, impact_altitude_m=impact.double(),
                                      wavelength_nm=[440.0, 680.0])
    for key in ("deviation_rad", "contact_altitude_m", "optical_depth"):
        assert rays[key].dtype == dtype
        assert torch.isfinite(rays[key]).all()
    assert torch.equal(rays["hits_ground"], reference["hits_ground"])
    assert rays["hits_ground"][:3].all() and not rays["hits_ground"][3:].any()
    assert torch.allclose(rays["deviation_rad"].double(), reference["deviation_rad"], rtol=0,
                          atol=0.05 * ARCSECOND)
    assert torch.allclose(rays["optical_depth"].double(), reference["optical_depth"],
                          rtol=1e-4)
    assert float(rays["deviation_rad"][-2]) == 0.0 and float(rays["deviation_rad"][-1]) == 0.0
    assert torch.all(rays["optical_depth"][-2:] == 0.0)


def test_gradients_refraction(air):
    elevation = torch.tensor([1e-3, -1e-3, 0.5, -0.02, 1.5], dtype=torch.float64,
                             requires_grad=True)
    assert gradcheck(lambda e: rf.refraction_angle(air, e, 10.0), (elevation,))
    height = torch.tensor([1.0, 10.0, 1e4], dtype=torch.float64, requires_grad=True)
    assert gradcheck(lambda h: rf.refraction_angle(air, torch.tensor(-0.01, dtype=torch.float64),
                                                   h), (height,))
    # exactly at the horizon (a kink for a ground observer) and at the zenith: finite
    edge = torch.tensor([0.0, math.pi / 2, -math.pi / 2], dtype=torch.float64,
                        requires_grad=True)
    (grad,) = torch.autograd.grad(rf.refraction_angle(air, edge).sum(), edge)
    assert torch.isfinite(grad).all()


def test_gradients_grazing(air):
    impact = torch.tensor([-100.0, 1765.0, 1800.0, 5e4, EARTH_TOP_M - 1.0],
                          dtype=torch.float64, requires_grad=True)

    def run(b):
        rays = rf.trace_grazing_rays(air, impact_altitude_m=b, wavelength_nm=[500.0])
        return rays["deviation_rad"], rays["optical_depth"], rays["contact_altitude_m"]

    assert gradcheck(run, (impact,))
    edge = torch.tensor([0.0, EARTH_TOP_M, EARTH_TOP_M + 1.0], dtype=torch.float64,
                        requires_grad=True)
    rays = rf.trace_grazing_rays(air, impact_altitude_m=edge, wavelength_nm=[500.0])
    (grad,) = torch.autograd.grad(rays["deviation_rad"].sum() + rays["optical_depth"].sum(),
                                  edge)
    assert torch.isfinite(grad).all()


def test_invalid_inputs(air):
    with pytest.raises(ValueError, match="method"):
        rf.refraction_angle(air, 0.1, method="euler")
    with pytest.raises(ValueError, match="altitude_m"):
        rf.refraction_angle(air, 0.1, -5.0)
    with pytest.raises(ValueError, match="apparent_altitude_rad"):
        rf.refraction_angle(air, float("nan"))
    with pytest.raises(ValueError, match="exactly one"):
        rf.trace_grazing_rays(air, impact_parameter_m=6.4e6, impact_altitude_m=1e3)
    with pytest.raises(ValueError, match="wavelength_nm"):
        rf.trace_grazing_rays(air, impact_altitude_m=1e3, wavelength_nm=[-1.0])
