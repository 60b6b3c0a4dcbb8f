r"""Refracted rays: astronomical refraction, bent optical depth, grazing rays, deviation table.

References used (independent of the code under test):

* Bennett 1982 refraction formula, scaled from its conditions (1010 hPa, 10 °C) to the
  model's sea-level refractivity;
* Kasten & Young 1989 relative air mass;
* the small-refractivity asymptote of the bending of a grazing ray through an exponential
  atmosphere, :math:`\delta \approx \nu(h_p)\sqrt{2\pi r_p/H}`;
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
    """Earth: 8 km exponential molecules and refractivity, n - 1 = 2.77e-4, Rayleigh only."""
    from skytorch.atmosphere import Atmosphere

    return Atmosphere.earth(turbidity=1.0, ozone_du=0.0, refractivity_profile="exponential")


@pytest.fixture(scope="module")
def default_air():
    """Earth as built by default: US 1976 refractivity, 8 km exponential molecules."""
    from skytorch.atmosphere import Atmosphere

    return Atmosphere.earth(turbidity=1.0, ozone_du=0.0)


@pytest.fixture(scope="module")
def standard_air():
    """Earth with the U.S. Standard Atmosphere 1976 molecules, Rayleigh only."""
    from skytorch.atmosphere import Atmosphere

    return Atmosphere.earth(turbidity=1.0, ozone_du=0.0, molecule_profile="us1976")


def test_any_object_with_the_attributes_works(air):
    """The functions use only four attributes of the atmosphere.

    planet_radius_m, top_altitude_m, refractivity and extinction_coefficient: a plain object gives
    the Atmosphere's results (whose path columns are split at its species' breakpoints: the plain
    object is given them as its quadrature levels).
    """
    plain = ExponentialAir(beta550=None)
    plain.extinction_coefficient = air.extinction_coefficient
    elevation = _deg([20.0, 0.0, -0.3])
    assert torch.allclose(rf.refraction_angle(plain, elevation), rf.refraction_angle(air, elevation),
                          rtol=1e-12, atol=0)
    plain.refractivity_breakpoints_m = sorted(
        {level for profile in air.profiles().values() if profile.breakpoints_m is not None
         for level in profile.breakpoints_m.reshape(-1).tolist()})
    impact = torch.tensor([2e3, 20e3], dtype=torch.float64)
    a = rf.trace_grazing_rays(plain, impact_altitude_m=impact, wavelength_nm=[550.0])
    b = rf.trace_grazing_rays(air, impact_altitude_m=impact, wavelength_nm=[550.0])
    assert torch.allclose(a["optical_depth"], b["optical_depth"], rtol=1e-12)


def _deg(values, dtype=torch.float64):
    return torch.tensor(values, dtype=dtype) * DEGREE


# --- independent algorithms agree ---------------------------------------------------------


@pytest.mark.parametrize("profile", ["air", "default_air"])
def test_bouguer_matches_rk4_observer(profile, request):
    """RK4 ray tracing (steps ending at the US 1976 layer bases) against the Bouguer integrals.

    For the exponential and the default (US 1976) refractivity.
    """
    air = request.getfixturevalue(profile)
    elevation = _deg([60.0, 20.0, 5.0, 1.0, 0.0])
    bouguer = rf.refraction_angle(air, elevation)
    rk4 = rf.refraction_angle(air, elevation, method="rk4", step_m=5e3, max_dh_m=500.0)
    assert torch.allclose(bouguer, rk4, rtol=0, atol=0.01 * ARCSECOND)


@pytest.mark.parametrize("profile", ["air", "default_air"])
def test_bouguer_matches_rk4_grazing(profile, request):
    air = request.getfixturevalue(profile)
    impact = torch.tensor([1_800.0, 5e3, 20e3, 60e3], dtype=torch.float64)
    bouguer = rf.trace_grazing_rays(air, impact_altitude_m=impact, wavelength_nm=[450.0, 650.0])
    rk4 = rf.trace_grazing_rays(air, impact_altitude_m=impact, wavelength_nm=[450.0, 650.0],
                                method="rk4", step_m=10e3)
    assert torch.allclose(bouguer["deviation_rad"], rk4["deviation_rad"], rtol=0,
                          atol=0.01 * ARCSECOND)
    assert torch.allclose(bouguer["contact_radius_m"], rk4["contact_radius_m"], rtol=0, atol=0.5)
    assert torch.allclose(bouguer["optical_depth"], rk4["optical_depth"], rtol=5e-5)
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
    """Bennett 1982 [arcmin -> rad].

    ``improved`` adds his -0.06' sin(14.7 R + 13 deg) term (accuracy 0.015' instead of 0.07'; Meeus
    1998, ch. 16).
    """
    h = torch.as_tensor(elevation_deg, dtype=torch.float64)
    minutes = 1.0 / torch.tan((h + 7.31 / (h + 4.4)) * DEGREE)
    if improved:
        minutes = minutes - 0.06 * torch.sin((14.7 * minutes + 13.0) * DEGREE)
    return minutes * ARCMINUTE


@pytest.mark.parametrize("profile", ["air", "default_air"])
def test_refraction_vs_bennett(profile, request):
    """Bennett's improved formula is accurate to 0.015' in absolute terms.

    i.e. to better than 2 % only up to ~60 degrees; above, its absolute accuracy is the test (and
    the Laplace expansion below checks the relative accuracy). The plain formula carries a
    systematic +0.06' sin(14.7 R + 13 deg) error (0.06' at 10-20 degrees), hence the improved one.
    """
    air = request.getfixturevalue(profile)
    elevation = torch.tensor([10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 80.0], dtype=torch.float64)
    model = rf.refraction_angle(air, elevation * DEGREE)
    scale = _bennett_scale(NU_EARTH)
    improved = _bennett(elevation, improved=True) * scale
    low = elevation <= 60.0
    assert torch.allclose(model[low], improved[low], rtol=2 * PERCENT, atol=0)
    high = elevation >= 60.0
    assert torch.allclose(model[high], improved[high], rtol=0, atol=0.015 * ARCMINUTE)


def test_refraction_vs_laplace_expansion(air):
    """Laplace's refraction R = A tan z - B tan^3 z for an exponential atmosphere.

    A = nu0 (1 - H/R), B = nu0 (H/R - nu0/2) (Laplace; Smart 1977, ch. III), valid for z <= 30
    degrees.
    """
    zenith = torch.tensor([1.0, 10.0, 20.0, 30.0], dtype=torch.float64)
    model = rf.refraction_angle(air, (90.0 - zenith) * DEGREE)
    ratio = SCALE_HEIGHT_M / EARTH_RADIUS_M
    tan_z = torch.tan(zenith * DEGREE)
    laplace = NU_EARTH * (1 - ratio) * tan_z - NU_EARTH * (ratio - NU_EARTH / 2) * tan_z**3
    assert torch.allclose(model, laplace, rtol=1e-5, atol=0)


def test_horizon_refraction_vs_bennett():
    """At Bennett's conditions the apparent horizon is refracted by 33'-36'.

    At 1010 hPa, 10 degC, with the U.S. Standard Atmosphere 1976 profile (Bennett: 34.5').
    """
    from skytorch.atmosphere import Atmosphere

    bennett_air = Atmosphere.earth(turbidity=1.0, ozone_du=0.0, molecule_profile="us1976",
                                   surface_pressure_pa=101_000.0, surface_temperature_k=283.15)
    horizon = float(rf.refraction_angle(bennett_air, torch.tensor(0.0, dtype=torch.float64)))
    assert 33 * ARCMINUTE <= horizon <= 36 * ARCMINUTE
    # the exponential 8 km profile (isothermal) bends more: documented, not hidden
    default = float(rf.refraction_angle(ExponentialAir(), torch.tensor(0.0, dtype=torch.float64)))
    assert 37 * ARCMINUTE < default < 38 * ARCMINUTE


def test_us1976_quadrature_panels(standard_air):
    """The U.S. 1976 profile has kinks in dn/dr.

    The quadrature is split there and converges at once (the independent checks of this profile are
    the Bennett horizon and Kasten-Young air-mass tests).
    """
    elevation = _deg([45.0, 10.0, 2.0, 0.0])
    coarse = rf.refraction_angle(standard_air, elevation, n_nodes=16)
    fine = rf.refraction_angle(standard_air, elevation, n_nodes=128)
    assert torch.allclose(coarse, fine, rtol=0, atol=0.001 * ARCSECOND)


def _kasten_young(zenith_deg):
    z = torch.as_tensor(zenith_deg, dtype=torch.float64)
    return 1.0 / (torch.cos(z * DEGREE) + 0.50572 * (96.07995 - z) ** -1.6364)


@pytest.mark.parametrize("profile", ["air", "standard_air"])
def test_air_mass_along_refracted_rays_vs_kasten_young(profile, request):
    """Rayleigh air mass along refracted rays at the apparent zenith angle.

    As pvlib applies Kasten & Young 1989.
    """
    atm = request.getfixturevalue(profile)
    zenith = torch.tensor([0.0, 60.0, 80.0, 85.0, 90.0], dtype=torch.float64)
    tau = rf.bent_optical_depth(atm, [550.0], zenith * DEGREE, per_species=True)["rayleigh"][..., 0]
    air_mass = tau / tau[0]
    reference = _kasten_young(zenith) / _kasten_young(0.0)
    assert torch.allclose(air_mass[:4], reference[:4], rtol=1 * PERCENT)
    assert abs(float(air_mass[4] / reference[4]) - 1.0) < 5 * PERCENT
    # the Atmosphere's own air mass with refraction=True goes through the same path
    model = atm.air_mass(zenith * DEGREE, refraction=True)
    assert torch.allclose(model, air_mass, rtol=1e-6)


def test_refracted_species_match_straight_rays_at_the_zenith():
    """Every species has the straight-ray optical depth at the zenith.

    Every species of the constituents, the gas bands with their curve of growth included, has at the
    zenith (where the ray does not bend) the optical depth of the straight-ray integrator (its
    adaptive quadrature: an independent rule, converged).
    """
    from skytorch.atmosphere import Atmosphere

    atm = Atmosphere.earth(turbidity=2.0)
    wavelength = torch.tensor([550.0, 687.0, 762.0, 940.0], dtype=torch.float64)
    bent = rf.bent_optical_depth(atm, wavelength, 0.0, per_species=True)
    straight = atm.optical_depth(wavelength, 0.0, per_species=True, method="adaptive")
    assert bent.keys() == straight.keys()
    assert {"h2o", "o2", "o2o2"} <= bent.keys()
    for name, value in straight.items():
        assert torch.allclose(bent[name], value, rtol=1e-9, atol=1e-15), name
    total = rf.bent_optical_depth(atm, wavelength, 0.0)
    assert torch.allclose(total, sum(bent.values()), rtol=1e-14, atol=0)


def test_band_law_takes_the_whole_limb_column():
    """A ray grazing the limb without refractivity has the curve-of-growth chord depth.

    A straight chord (no refractivity) has the optical depth of the column of both halves of the
    chord through the curve of growth -- the straight-ray columns from the tangent point outwards,
    doubled, as the independent reference -- which in the bands is smaller than twice the optical
    depth of one half (saturation).
    """
    from skytorch.atmosphere import Atmosphere

    atm = Atmosphere.earth(reference_refractivity=0.0)
    wavelength = torch.tensor([550.0, 687.0, 762.0, 940.0], dtype=torch.float64)
    periapsis = torch.tensor([3e3, 10e3, 25e3], dtype=torch.float64)
    rays = rf.trace_grazing_rays(atm, wavelength_nm=wavelength, periapsis_altitude_m=periapsis)
    assert torch.equal(rays["deviation_rad"], torch.zeros_like(periapsis))
    constituents = atm.constituents(wavelength)
    radius = atm.planet_radius_m + periapsis
    half = constituents.column_integrals(radius, torch.zeros_like(radius), method="adaptive")
    whole = constituents.optical_depth({name: 2.0 * value for name, value in half.items()})
    assert torch.allclose(rays["optical_depth"], whole, rtol=1e-6, atol=0)
    halves = 2.0 * constituents.optical_depth(half)
    # in the water band at 940 nm the sum of the halves overstates by > 10 % at 3 km
    assert float(halves[0, 3]) > 1.1 * float(whole[0, 3])


def test_grazing_deviation_at_ground_is_twice_horizon_refraction(air):
    rays = rf.trace_grazing_rays(air, periapsis_altitude_m=torch.tensor(0.0, dtype=torch.float64))
    horizon = rf.refraction_angle(air, torch.tensor(0.0, dtype=torch.float64), method="rk4")
    assert abs(float(rays["deviation_rad"] - 2 * horizon)) < 0.01 * ARCSECOND
    # RK4 through the limb, 50 m above the ground (10 km steps stay above it)
    low = rf.trace_grazing_rays(air, periapsis_altitude_m=torch.tensor(50.0, dtype=torch.float64))
    rk4 = rf.trace_grazing_rays(air, impact_altitude_m=low["impact_altitude_m"], method="rk4")
    assert abs(float(low["deviation_rad"] - rk4["deviation_rad"])) < 0.01 * ARCSECOND
    assert abs(float(low["contact_altitude_m"] - rk4["contact_altitude_m"])) < 0.5
    # the classical ~70' (about 1.2 degrees) that bends sunlight into the umbra
    assert 65 * ARCMINUTE < float(rays["deviation_rad"]) < 80 * ARCMINUTE


@pytest.mark.parametrize("periapsis_m", [0.0, 10e3, 30e3])
def test_mars_grazing_deviation_small_refractivity_asymptote(periapsis_m):
    from skytorch.atmosphere import Atmosphere

    mars = Atmosphere.mars()
    assert mars.planet_radius_m == MARS_RADIUS_M and mars.top_altitude_m == MARS_TOP_M
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
    rk4 = apparent - rf.refraction_angle(air, apparent, method="rk4", step_m=10e3,
                                         max_dh_m=1e3)
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
    # finite gradients in this dtype, also for an observer high up
    leaf = elevation.clone().requires_grad_(True)
    height = torch.tensor(10e3, dtype=dtype, requires_grad=True)
    (d_e, d_h) = torch.autograd.grad(rf.refraction_angle(air, leaf, height).sum(),
                                     (leaf, height))
    assert torch.isfinite(d_e).all() and torch.isfinite(d_h).all()
    # below the horizon from a mountain: the ray dips to a periapsis and comes back
    high = rf.refraction_angle(air, _deg([-1.0], dtype), 3000.0)
    rk4 = rf.refraction_angle(air, _deg([-1.0]), 3000.0, method="rk4", step_m=10e3,
                              max_dh_m=1e3)
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
    leaf = impact.clone().requires_grad_(True)
    out = rf.trace_grazing_rays(air, impact_altitude_m=leaf, wavelength_nm=[440.0, 680.0])
    (grad,) = torch.autograd.grad(out["deviation_rad"].sum() + out["optical_depth"].sum(), leaf)
    assert grad.dtype == dtype and torch.isfinite(grad).all()


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
    # exactly tangent to the ground (periapsis 0) and exactly at the top
    periapsis = torch.tensor([0.0, EARTH_TOP_M], dtype=torch.float64, requires_grad=True)
    rays = rf.trace_grazing_rays(air, periapsis_altitude_m=periapsis, wavelength_nm=[500.0])
    (grad,) = torch.autograd.grad(rays["deviation_rad"].sum() + rays["optical_depth"].sum(),
                                  periapsis)
    assert torch.isfinite(grad).all() and float(grad[0]) < 0.0


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


# --- deviation / contact table -------------------------------------------------------------------


@pytest.fixture(scope="module")
def small_table(air):
    return rf.deviation_table(air, 24, 16, n_nodes=48, progress=False)


def test_deviation_table_dataset(small_table):
    ds = small_table
    assert ds.deviation.dims == ("x_r", "x_mu")
    for name in ("deviation", "contact_radius", "contact_altitude", "altitude",
                 "view_zenith_angle", "x_r", "x_mu"):
        assert {"units", "long_name", "description"} <= set(ds[name].attrs)
    assert ds.deviation.attrs["units"] == "degree"
    # Schneegans et al. 2025: "maximum computed deviation of about 0.6 deg for an observer at
    # sea level ... stored at x_mu = 1 and x_r = 0"
    assert float(ds.deviation[0].max()) == pytest.approx(float(ds.deviation[0, -1]))
    assert abs(float(ds.deviation[0, -1]) - 0.6) < 0.05
    assert float(abs(ds.deviation[:, 0]).max()) * DEGREE < 1e-4 * ARCSECOND  # zenith column
    assert float(ds.view_zenith_angle[0, -1]) == pytest.approx(90.0)
    # rays tangent to the ground bend into it; up-going rays touch nothing below their origin
    assert float(ds.contact_altitude[3, -1]) < 0.0
    assert torch.allclose(torch.as_tensor(ds.contact_altitude[:, 0].values),
                          torch.as_tensor(ds.altitude.values), atol=1e-6)


def test_deviation_table_rk4_agrees_for_rays_above_ground(air, small_table):
    """Schneegans' RK4 ray marching at 10 km steps, on rays that stay above the ground."""
    rk4 = rf.deviation_table(air, 24, 16, method="rk4", step_m=10e3, progress=False)
    above = small_table.contact_altitude > 100.0
    difference = abs(rk4.deviation - small_table.deviation).where(above)
    assert float(difference.max()) * DEGREE < 0.01 * ARCSECOND
    contact = abs(rk4.contact_altitude - small_table.contact_altitude).where(above)
    assert float(contact.max()) < 1.0


def test_lookup(air, small_table):
    table = rf.DeviationTable(small_table)
    # at the grid nodes the look-up returns the tabulated values (parametrisation round trip)
    altitude = torch.as_tensor(small_table.altitude.values)[:, None].expand(24, 16)
    zenith = torch.deg2rad(torch.as_tensor(small_table.view_zenith_angle.values))
    out = table(altitude, torch.clamp(zenith, max=math.pi))
    assert torch.allclose(out["deviation_rad"],
                          torch.deg2rad(torch.as_tensor(small_table.deviation.values)),
                          rtol=1e-6, atol=1e-3 * ARCSECOND)
    # between the nodes, against the direct integral at random rays: the bilinear error of
    # Schneegans' parametrisation is largest at the horizon and near the zenith column
    generator = torch.Generator().manual_seed(7)
    h = torch.rand(400, generator=generator, dtype=torch.float64) ** 2 * EARTH_TOP_M
    z = torch.rand(400, generator=generator, dtype=torch.float64) * 89.0 * DEGREE
    direct = rf.refraction_angle(air, math.pi / 2 - z, h)
    finer = rf.deviation_table(air, 48, 48, n_nodes=32, progress=False)
    error = (rf.lookup_deviation(finer, h, z)["deviation_rad"] - direct).abs()
    assert float(error.max()) < 0.5 * ARCMINUTE
    assert float(error.median()) < 0.1 * ARCSECOND
    # below the geometric horizon: flagged as hitting the ground
    assert bool(table(torch.tensor(0.0), torch.tensor(math.radians(91.0)))["hits_ground"])


def test_accuracy_cost_experiment_quick(tmp_path):
    import importlib.util
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "experiments" / "refraction_accuracy_cost.py"
    spec = importlib.util.spec_from_file_location("refraction_accuracy_cost", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main(["--quick", "--output-dir", str(tmp_path)]) == 0
    from skytorch.dataset import open_dataset

    ds = open_dataset(tmp_path / "refraction_accuracy_cost.nc")
    assert (tmp_path / "refraction_accuracy_cost.png").exists()
    # more nodes, smaller error (float64); RK4 at 10 km (landing on the US 1976 layer
    # bases) is within 0.01" (measured 0.0035")
    errors = ds.bouguer_error.sel(dtype="float64").values
    assert errors[-1] < errors[0]
    assert float(ds.rk4_error.max()) < 0.01


def test_batched_atmosphere_matches_members():
    """A (2, 1) sweep of surface pressure gives the refraction of each member atmosphere."""
    from skytorch.atmosphere import Atmosphere

    pressure = torch.tensor([[90_000.0], [101_325.0]], dtype=torch.float64)
    batched = Atmosphere.earth(turbidity=1.0, ozone_du=0.0, surface_pressure_pa=pressure)
    elevation = _deg([0.0, 5.0, 30.0])
    result = rf.refraction_angle(batched, elevation)
    assert result.shape == (2, 3)
    for i in range(2):
        member = Atmosphere.earth(turbidity=1.0, ozone_du=0.0,
                                  surface_pressure_pa=float(pressure[i, 0]))
        assert torch.allclose(result[i], rf.refraction_angle(member, elevation), rtol=1e-12)
    rays = rf.trace_grazing_rays(batched, impact_altitude_m=torch.tensor([3e3, 2e4]),
                                 wavelength_nm=[550.0])
    assert rays["deviation_rad"].shape == (2, 2) and rays["optical_depth"].shape == (2, 2, 1)


def test_apparent_altitude_gradient(air):
    true = torch.tensor([0.001, 0.2, 1.0], dtype=torch.float64, requires_grad=True)
    assert gradcheck(lambda t: rf.apparent_altitude(air, t), (true,), atol=1e-6, rtol=1e-4)


def test_rays_hitting_the_ground_bouguer_vs_rk4(air):
    """Below the horizon from 20 km.

    Rays that hit the ground and, continued through the planet of constant index, come out again
    (RK4 lands on the ground and crosses the planet on a straight chord).
    """
    elevation = _deg([-4.5, -6.0, -10.0])
    bouguer = rf.refraction_angle(air, elevation, 20e3)
    rk4 = rf.refraction_angle(air, elevation, 20e3, method="rk4", step_m=10e3)
    assert torch.allclose(bouguer, rk4, rtol=0, atol=0.01 * ARCSECOND)
    # optical depth to the ground point
    zenith = math.pi / 2 - elevation
    tau = rf.bent_optical_depth(air, [550.0], zenith, 20e3)
    tau_rk4 = rf.bent_optical_depth(air, [550.0], zenith, 20e3, method="rk4", step_m=10e3)
    assert torch.allclose(tau, tau_rk4, rtol=1e-5)


def _edlen_refractivity(wavelength_nm):
    """Edlén 1966 dispersion of standard air (an independent formula from Peck-Reeder)."""
    sigma2 = (1e3 / torch.as_tensor(wavelength_nm, dtype=torch.float64)) ** 2
    return (8342.54 + 2406147.0 / (130.0 - sigma2) + 15998.0 / (38.9 - sigma2)) * 1e-8


def test_dispersion_of_refraction(default_air):
    """Wavelength-dependent refraction: 589.3 nm is the grey model.

    At 45 degrees, where R is proportional to n - 1 (Laplace), R(400) - R(700) = R (n400 -
    n700)/(n589 - 1) with Edlén's dispersion (measured 1.43"); RK4 agrees at the horizon (400-700
    nm: 53.9").
    """
    elevation = _deg([0.0, 5.0, 45.0])
    grey = rf.refraction_angle(default_air, elevation)
    assert torch.equal(rf.refraction_angle(default_air, elevation, wavelength_nm=589.3), grey)
    wavelength = torch.tensor([[400.0], [700.0]], dtype=torch.float64)
    batched = rf.refraction_angle(default_air, elevation, wavelength_nm=wavelength)
    assert batched.shape == (2, 3)
    for i, w in enumerate(wavelength[:, 0].tolist()):
        single = rf.refraction_angle(default_air, elevation, wavelength_nm=w)
        assert torch.allclose(batched[i], single, rtol=1e-12, atol=0)
    dispersion = batched[0] - batched[1]
    edlen = (_edlen_refractivity(400.0) - _edlen_refractivity(700.0)) / _edlen_refractivity(
        589.3)
    assert float(dispersion[2]) == pytest.approx(float(grey[2] * edlen), rel=2 * PERCENT)
    assert bool((dispersion[:-1] > dispersion[1:]).all())  # largest at the horizon
    rk4 = rf.refraction_angle(default_air, elevation[:1], wavelength_nm=400.0, method="rk4")
    assert abs(float(rk4[0] - batched[0, 0])) < 0.01 * ARCSECOND
    with pytest.raises(ValueError, match="one wavelength"):
        rf.refraction_angle(default_air, elevation, wavelength_nm=wavelength, method="rk4")


@pytest.mark.parametrize("method", ["bouguer", "rk4"])
def test_apparent_altitude_at_the_zenith_is_the_zenith(default_air, method):
    """No refraction at the zenith: e(π/2) = π/2, alone, from a height, with a gradient.

    Newton's step landed on the bracket's end (π/2) and counted as leaving it: the root
    was replaced by the bisection midpoint, 45°.
    """
    zenith = torch.tensor(math.pi / 2, dtype=torch.float64)
    for height in (0.0, 1000.0):
        e = default_air.apparent_altitude(zenith, torch.tensor(height, dtype=torch.float64),
                                     method=method)
        assert abs(float(e) - math.pi / 2) < 1e-12
    true = zenith.clone().requires_grad_(True)
    e = default_air.apparent_altitude(true, method=method)
    (slope,) = torch.autograd.grad(e, true)
    assert abs(float(e.detach()) - math.pi / 2) < 1e-12 and 0.999 < float(slope) < 1.0
