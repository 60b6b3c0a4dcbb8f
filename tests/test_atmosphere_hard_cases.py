"""Hard cases of ray geometry and optical depth, float64 and float32, values and gradients."""

from __future__ import annotations

import math

import mpmath
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.geometry import distance_to_ground, distance_to_top, ray_hits_ground

R = 6_371_000.0
TOP = R + 100_000.0
mpmath.mp.dps = 40

#: relative accuracy of distances: a few ulps of the dtype (float32: about 1e-6)
ULPS = {torch.float64: 1e-13, torch.float32: 4e-6}


def exact_distances(r, mu):
    """Distances to the top and the ground with 40 significant digits (mpmath)."""
    r, mu = mpmath.mpf(r), mpmath.mpf(mu)
    top_disc = r * r * (mu * mu - 1) + mpmath.mpf(TOP) ** 2
    to_top = -r * mu + mpmath.sqrt(max(top_disc, 0))
    ground_disc = r * r * (mu * mu - 1) + mpmath.mpf(R) ** 2
    to_ground = -r * mu - mpmath.sqrt(ground_disc) if ground_disc >= 0 else None
    return float(to_top), (None if to_ground is None else float(to_ground))


CASES = {
    # name: (altitude [m], mu)
    "zenith": (0.0, 1.0),
    "nadir_from_10km": (10_000.0, -1.0),
    "horizontal_at_ground": (0.0, 0.0),
    "horizontal_at_1m": (1.0, 0.0),
    "slightly_up_at_ground": (0.0, 1e-4),
    "on_top_boundary_up": (100_000.0, 0.3),
    "on_top_boundary_horizontal": (100_000.0, 0.0),
    "down_from_30km": (30_000.0, -0.2),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_distance_to_top_precision(case, dtype):
    altitude, mu = CASES[case]
    r = torch.tensor(R + altitude, dtype=dtype)
    mu_t = torch.tensor(mu, dtype=dtype)
    exact, _ = exact_distances(float(r), float(mu_t))
    value = float(distance_to_top(r, mu_t, TOP))
    assert abs(value - exact) <= ULPS[dtype] * max(exact, 1.0) + 1e-9


@pytest.mark.parametrize("altitude", [10.0, 1000.0, 30_000.0])
def test_distance_to_ground_precision(altitude, dtype):
    r = torch.tensor(R + altitude, dtype=dtype)
    mu = torch.tensor(-0.7, dtype=dtype)
    _, exact = exact_distances(float(r), float(mu))
    assert bool(ray_hits_ground(r, mu, R))
    value = float(distance_to_ground(r, mu, R))
    assert abs(value / exact - 1.0) <= ULPS[dtype]


def test_tangent_to_ground_counts_as_hit():
    r = torch.tensor(R + 5000.0, dtype=torch.float64)
    mu_tangent = -torch.sqrt(1.0 - (R / r) ** 2)
    hit = ray_hits_ground(r, mu_tangent - 1e-12, R)
    miss = ray_hits_ground(r, mu_tangent + 1e-12, R)
    assert bool(hit) and not bool(miss)
    # the tangent distance is sqrt(r^2 - R^2) either way
    assert float(distance_to_ground(r, mu_tangent - 1e-12, R)) == pytest.approx(
        math.sqrt(float(r) ** 2 - R ** 2), rel=1e-5)


def reference_column(altitude, mu, scale_height=8000.0):
    """Independent column integral (mpmath tanh-sinh quadrature on the path)."""
    r0 = mpmath.mpf(R + altitude)
    mu = mpmath.mpf(mu)
    to_top, to_ground = exact_distances(float(r0), float(mu))
    length = to_ground if (to_ground is not None and mu < 0) else to_top

    def density(s):
        r = mpmath.sqrt(r0 * r0 + s * s + 2 * r0 * mu * s)
        return mpmath.exp(-(r - R) / scale_height)

    breaks = [0] + [b for b in (1e3, 1e4, 5e4, 2e5, float(max(0, -r0 * mu))) if b < length]
    return float(mpmath.quad(density, sorted(set(breaks)) + [length]))


@pytest.fixture(scope="module")
def rayleigh_only():
    # the closed forms are those of the isothermal exponential
    return Atmosphere.earth(turbidity=1.0, ozone_du=0.0, molecule_profile="exponential")


#: accuracy of optical depths in each dtype (float32 rounding of altitudes, ~1e-7 * R/H)
COLUMN_TOLERANCE = {torch.float64: 1e-6, torch.float32: 3e-5}


@pytest.mark.parametrize("case", ["zenith", "horizontal_at_ground", "horizontal_at_1m",
                                  "slightly_up_at_ground", "down_from_30km",
                                  "nadir_from_10km", "on_top_boundary_up"])
def test_column_hard_cases(rayleigh_only, case, dtype):
    altitude, mu = CASES[case]
    zenith = torch.tensor(math.acos(mu), dtype=dtype)
    column = rayleigh_only.column_integrals(zenith, torch.tensor(altitude, dtype=dtype))
    value = column["rayleigh"]
    assert value.dtype == dtype
    # float32(pi/2) is a horizontal ray by convention (see the next test)
    exact = reference_column(altitude, 0.0 if mu == 0.0 else math.cos(float(zenith)))
    # (the ray leaving the top upwards has a zero column: absolute floor 1e-20 m)
    assert abs(float(value) - exact) <= COLUMN_TOLERANCE[dtype] * exact + 1e-20


def test_horizontal_float32_pi_over_2_is_horizontal(rayleigh_only):
    # float32(pi/2) is 4e-8 rad below the horizon: treated as horizontal, not as a ground hit
    tau32 = rayleigh_only.optical_depth(torch.tensor([550.0], dtype=torch.float32),
                                        torch.tensor(math.pi / 2, dtype=torch.float32))
    tau64 = rayleigh_only.optical_depth(torch.tensor([550.0], dtype=torch.float64),
                                        torch.tensor(math.pi / 2, dtype=torch.float64))
    assert abs(float(tau32) / float(tau64) - 1.0) <= 1e-4


def test_ray_hitting_ground_ends_there(rayleigh_only, dtype):
    # from 10 km straight down: column = H e^{-h/H} (e^{h/H} - 1) exactly (vertical path)
    column = rayleigh_only.column_integrals(torch.tensor(math.pi, dtype=dtype),
                                            torch.tensor(10_000.0, dtype=dtype))["rayleigh"]
    exact = 8000.0 * (1.0 - math.exp(-10_000.0 / 8000.0))
    assert abs(float(column) / exact - 1.0) <= COLUMN_TOLERANCE[dtype]


def test_looking_down_from_ground_is_zero(rayleigh_only, dtype):
    tau = rayleigh_only.optical_depth(torch.tensor([550.0], dtype=dtype),
                                      torch.tensor(2.0, dtype=dtype))
    assert float(tau) == 0.0


def test_start_above_atmosphere_equals_start_at_entry(rayleigh_only, dtype):
    # a ray from 300 km altitude, 105 deg zenith (impact parameter 30 km above the
    # ground): same column as from its entry point
    r0, mu0 = R + 300e3, math.cos(math.radians(105.0))
    # entry: the nearer intersection with the top sphere
    disc = (r0 * mu0) ** 2 - (r0 - TOP) * (r0 + TOP)
    entry = -r0 * mu0 - math.sqrt(disc)
    r1 = math.sqrt(r0 * r0 + entry * entry + 2 * r0 * mu0 * entry)
    mu1 = (r0 * mu0 + entry) / r1
    outside = rayleigh_only.column_integrals(torch.tensor(math.acos(mu0), dtype=dtype),
                                             torch.tensor(300e3, dtype=dtype))["rayleigh"]
    reference = reference_column(r1 - R, mu1)
    assert abs(float(outside) / reference - 1.0) <= COLUMN_TOLERANCE[dtype]


def test_outside_looking_away_is_zero(rayleigh_only, dtype):
    tau = rayleigh_only.optical_depth(torch.tensor([550.0], dtype=dtype),
                                      torch.tensor(0.3, dtype=dtype),
                                      torch.tensor(500e3, dtype=dtype))
    assert float(tau) == 0.0


def test_grazing_the_top_from_outside(rayleigh_only, dtype):
    # impact parameter just above the top radius: the ray misses the atmosphere
    r0 = R + 1000e3
    mu = -math.sqrt(1.0 - ((TOP + 10.0) / r0) ** 2)
    tau = rayleigh_only.optical_depth(torch.tensor([550.0], dtype=dtype),
                                      torch.tensor(math.acos(mu), dtype=dtype),
                                      torch.tensor(1000e3, dtype=dtype))
    assert float(tau) == 0.0
    # just inside: tiny but positive and finite
    mu_in = -math.sqrt(1.0 - ((TOP - 1000.0) / r0) ** 2)
    tau_in = rayleigh_only.optical_depth(torch.tensor([550.0], dtype=dtype),
                                         torch.tensor(math.acos(mu_in), dtype=dtype),
                                         torch.tensor(1000e3, dtype=dtype))
    assert 0.0 < float(tau_in) < 1e-4


def test_observer_inside_planet_raises(rayleigh_only):
    with pytest.raises(ValueError, match="altitude_m"):
        rayleigh_only.optical_depth(torch.tensor([550.0]), 0.0, -1.0)


def test_huge_optical_depth_transmittance_is_exact_zero(dtype):
    atm = Atmosphere.earth(aerosol_optical_depth=100.0, angstrom_alpha=0.0, ozone_du=0.0)
    wavelength = torch.tensor([550.0], dtype=dtype)
    zenith = torch.tensor(math.pi / 2, dtype=dtype)
    tau = atm.optical_depth(wavelength, zenith, per_species=True)
    assert float(tau["aerosol"]) > 1e3
    transmittance = atm.transmittance(wavelength, zenith)
    assert float(transmittance) == 0.0
    # log-transmittance = -tau stays accurate: it scales exactly with the aerosol amount
    small = Atmosphere.earth(aerosol_optical_depth=1.0, angstrom_alpha=0.0, ozone_du=0.0)
    ratio = tau["aerosol"] / small.optical_depth(wavelength, zenith, per_species=True)["aerosol"]
    assert abs(float(ratio) - 100.0) <= 100.0 * COLUMN_TOLERANCE[dtype]


@pytest.mark.parametrize("turbidity", [1.0, 10.0])
@pytest.mark.parametrize("ozone", [0.0, 300.0])
def test_parameter_limits_finite(turbidity, ozone, dtype):
    atm = Atmosphere.earth(turbidity=turbidity, ozone_du=ozone)
    wavelength = torch.linspace(360.0, 830.0, 15, dtype=dtype)
    zenith = torch.tensor([0.0, 1.0, math.pi / 2, 1.6], dtype=dtype)
    tau = atm.optical_depth(wavelength, zenith, torch.tensor(1000.0, dtype=dtype))
    assert bool(torch.isfinite(tau).all()) and bool((tau >= 0).all())
    if ozone == 0.0:
        parts = atm.optical_depth(wavelength, zenith, per_species=True)
        assert float(parts["ozone"].abs().max()) == 0.0


def test_tiny_aerosol_scale_height_converges():
    atm = Atmosphere.earth(turbidity=3.0, aerosol_scale_height_m=10.0)
    zenith = torch.tensor([0.0, 1.2, math.pi / 2], dtype=torch.float64)
    columns = atm.column_integrals(zenith, 0.0)["aerosol"]
    reference = atm.column_integrals(zenith, 0.0, method="adaptive", n_steps=32)["aerosol"]
    assert torch.allclose(columns, reference, rtol=1e-5)
    assert float(columns[0]) == pytest.approx(10.0, rel=1e-6)


@pytest.mark.parametrize("zenith", [0.0, 1.0, 1.5, math.pi / 2 - 1e-3, 1.7, 2.8])
def test_gradcheck_optical_depth(zenith):
    atm = Atmosphere.earth(turbidity=2.0, ozone_du=300.0)
    wavelength = torch.tensor([450.0, 650.0], dtype=torch.float64)

    def function(z, h):
        return atm.optical_depth(wavelength, z, h)

    z = torch.tensor(zenith, dtype=torch.float64, requires_grad=True)
    h = torch.tensor(2000.0, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(function, (z, h), eps=1e-4, atol=1e-7, rtol=1e-3)


def test_gradcheck_parameters():
    wavelength = torch.tensor([500.0], dtype=torch.float64)

    def function(turbidity, ozone):
        return Atmosphere.earth(turbidity=turbidity, ozone_du=ozone).optical_depth(
            wavelength, torch.tensor(1.3, dtype=torch.float64))

    turbidity = torch.tensor(2.5, dtype=torch.float64, requires_grad=True)
    ozone = torch.tensor(300.0, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(function, (turbidity, ozone), eps=1e-6, atol=1e-8)


@pytest.mark.parametrize("case", sorted(CASES))
def test_gradients_finite_on_hard_cases(case, dtype):
    altitude, mu = CASES[case]
    atm = Atmosphere.earth(turbidity=2.0, ozone_du=300.0)
    zenith = torch.tensor(math.acos(mu), dtype=dtype, requires_grad=True)
    height = torch.tensor(altitude, dtype=dtype, requires_grad=True)
    tau = atm.optical_depth(torch.tensor([550.0], dtype=dtype), zenith, height)
    tau.sum().backward()
    assert bool(torch.isfinite(zenith.grad)) and bool(torch.isfinite(height.grad))


# ---------------------------------------------------------------- property tests
ATMOSPHERE = Atmosphere.earth(turbidity=3.0, ozone_du=300.0)
WAVELENGTH = torch.tensor([400.0, 550.0, 700.0], dtype=torch.float64)


@settings(max_examples=60, deadline=None)
@given(altitude=st.floats(0.0, 300e3), zenith=st.floats(0.0, math.pi))
def test_property_finite_and_bounded(altitude, zenith):
    for dtype in (torch.float64, torch.float32):
        transmittance = ATMOSPHERE.transmittance(WAVELENGTH.to(dtype),
                                                 torch.tensor(zenith, dtype=dtype),
                                                 torch.tensor(altitude, dtype=dtype))
        assert bool(torch.isfinite(transmittance).all())
        assert bool(((transmittance >= 0) & (transmittance <= 1)).all())


@settings(max_examples=60, deadline=None)
@given(altitude=st.floats(1.0, 99e3), zenith_fraction=st.floats(0.0, 1.0),
       forward_fraction=st.floats(0.0, 0.99))
def test_property_monotone_in_path_length(altitude, zenith_fraction, forward_fraction):
    # an observer further along the same ray sees a shorter path to the exit, so less
    # optical depth; the rays are built to miss the ground (no filtering of inputs)
    r1 = R + altitude
    max_zenith = math.pi - math.asin((R + 1.0) / r1)
    zenith = zenith_fraction * max_zenith
    mu1 = math.cos(zenith)
    to_exit = -r1 * mu1 + math.sqrt(r1 * r1 * mu1 * mu1 - r1 * r1 + TOP * TOP)
    step = forward_fraction * to_exit
    r0 = math.sqrt(r1 * r1 + step * step + 2.0 * r1 * step * mu1)
    mu0 = max(-1.0, min(1.0, (r1 * mu1 + step) / r0))
    tau1 = ATMOSPHERE.optical_depth(WAVELENGTH, torch.tensor(zenith, dtype=torch.float64),
                                    torch.tensor(altitude, dtype=torch.float64))
    tau0 = ATMOSPHERE.optical_depth(WAVELENGTH, torch.tensor(math.acos(mu0), dtype=torch.float64),
                                    torch.tensor(r0 - R, dtype=torch.float64))
    assert bool((tau1 >= tau0 * (1.0 - 1e-9)).all())


@pytest.mark.parametrize("altitude", [1000.0, 2000.0, 8000.0])
def test_horizontal_ray_from_a_profile_level_has_the_altitude_derivative(altitude):
    """A horizontal ray from a breakpoint altitude of the U.S. 1976 air: dτ/dh = central FD.

    The level at the observer's own altitude passed the clamp's derivative of its crossing
    distance (~1e16 m/m): Rayleigh +18 %, O2-O2 330 times the slope at 2000 m.
    """
    from skytorch.atmosphere import Atmosphere

    atm = Atmosphere.earth()
    wavelength = torch.tensor([550.0], dtype=torch.float64)
    zenith = torch.tensor(math.pi / 2, dtype=torch.float64)
    height = torch.tensor(altitude, dtype=torch.float64, requires_grad=True)
    columns = atm.optical_depth(wavelength, zenith, height, per_species=True)
    step = 0.01
    for name in ("rayleigh", "o2o2", "aerosol"):
        (slope,) = torch.autograd.grad(columns[name][0], height, retain_graph=True)

        def tau(h, name=name):
            return float(atm.optical_depth(wavelength, zenith, torch.tensor(
                h, dtype=torch.float64), per_species=True)[name][0])

        central = (tau(altitude + step) - tau(altitude - step)) / (2 * step)
        assert abs(float(slope) - central) <= 1e-6 * abs(central), (name, float(slope), central)


def test_rk4_column_of_a_ray_outside_the_air_keeps_a_zero_gradient():
    """A horizontal ray from the top: τ = 0 with a gradient of 0 (a constant before)."""
    from skytorch.atmosphere.refraction import bent_optical_depth

    atm = Atmosphere.earth()
    wavelength = torch.tensor([550.0], dtype=torch.float64)
    for method in ("bouguer", "rk4"):
        height = torch.tensor(100e3, dtype=torch.float64, requires_grad=True)
        zenith = torch.tensor(math.pi / 2, dtype=torch.float64, requires_grad=True)
        tau = bent_optical_depth(atm, wavelength, zenith, height, method=method)
        assert float(tau.detach().abs().max()) == 0.0
        gradients = torch.autograd.grad(tau.sum(), (zenith, height))
        assert all(float(g) == 0.0 for g in gradients), method


def test_float32_refraction_and_bent_columns_match_float64():
    """float32 in, float32 out, float64 inside: the horizon and the zenith to 1e-6.

    In float32 the Bouguer integrals lost 3.1e-4 of the horizon refraction (0.61″) and
    2.0e-4 of the zenith's bent column; float32(π/2) stays a horizontal direction.
    """
    atm = Atmosphere.earth()
    wavelength = torch.tensor([550.0])
    for elevation in (0.0, 1e-3, 0.5, math.pi / 2):
        wide = atm.refraction(torch.tensor(elevation, dtype=torch.float64))
        narrow = atm.refraction(torch.tensor(elevation, dtype=torch.float32))
        assert narrow.dtype == torch.float32
        assert abs(float(narrow) - float(wide)) <= 1e-6 * float(wide) + 1e-12
        zenith = math.pi / 2 - elevation
        wide = atm.optical_depth(wavelength.double(), torch.tensor(zenith, dtype=torch.float64),
                                 refraction=True)
        narrow = atm.optical_depth(wavelength, torch.tensor(zenith, dtype=torch.float32),
                                   refraction=True)
        assert narrow.dtype == torch.float32
        assert abs(float(narrow) / float(wide) - 1.0) < 1e-6, (elevation, narrow, wide)
