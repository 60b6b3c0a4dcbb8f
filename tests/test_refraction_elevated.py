"""Refraction, dip of the horizon and extinction for elevated observers (skyfield #1069).

References, none of them the Bouguer quadrature of the package:

* the geometric dip acos(R / (R + h)) (1.758 deg at 3 km) in an atmosphere without
  refraction;
* the refracted dip d_g sqrt(1 - k) with the terrestrial refraction coefficient of the
  layer below the observer from pressure, temperature and lapse rate,
  k = 503 P / T^2 (0.0343 + dT/dz) (P in hPa, T in K, dT/dz in K/m; Bomford 1980,
  *Geodesy*, 4th ed.; Young 2004, AJ 127, 3622), averaged over the layer with the
  U.S. 1976 troposphere written out here (T = 288.15 - 0.0065 z, P = 1013.25 (T /
  288.15)^5.25588);
* a ray traced by direct integration of the ray equation d(n d)/ds = grad n in
  Cartesian coordinates with scipy's DOP853 (adaptive, rtol 1e-11) through the same
  refractivity profile, optical depth as a further state variable.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from scipy.integrate import solve_ivp

import skytorch as st
from skytorch.atmosphere import refraction as rf

ARCSEC = math.pi / 648000.0


@pytest.fixture(scope="module")
def atm():
    return st.Atmosphere.earth()


class _Vacuum:
    """An atmosphere of index 1 (no refraction)."""

    planet_radius_m, top_altitude_m, top_radius_m = 6.371e6, 1e5, 6.471e6

    def refractivity(self, altitude_m, wavelength_nm=None):
        return torch.zeros_like(torch.as_tensor(altitude_m, dtype=torch.float64))


def _index(atm):
    """n(h) - 1 and its slope [1/m] at one altitude, from the atmosphere's profile."""
    top = float(atm.top_altitude_m)

    def nu_and_slope(h):
        h = min(max(h, 0.0), top)
        leaf = torch.tensor(h, dtype=torch.float64, requires_grad=True)
        nu = atm.refractivity(leaf)
        (slope,) = torch.autograd.grad(nu, leaf)
        inside = 0.0 < h < top
        return float(nu.detach()), float(slope) if inside else 0.0

    return nu_and_slope


def _trace_ode(atm, elevation_rad, altitude_m, wavelength_nm=None):
    """Ray from the observer at apparent elevation to the top (or the ground).

    Returns (true altitude of the outgoing ray [rad], lowest altitude [m], optical depth,
    whether it hit the ground).
    """
    radius, top = float(atm.planet_radius_m), float(atm.top_altitude_m)
    nu_and_slope = _index(atm)

    def extinction(h):
        if wavelength_nm is None:
            return 0.0
        k = atm.extinction_coefficient(torch.tensor([min(max(h, 0.0), top)],
                                                    dtype=torch.float64),
                                       torch.tensor([wavelength_nm], dtype=torch.float64))
        return float(k.reshape(-1)[0])

    def rhs(_, state):
        x, y, px, py, _tau = state
        r = math.hypot(x, y)
        nu, slope = nu_and_slope(r - radius)
        n = 1.0 + nu
        return [px / n, py / n, slope * x / r, slope * y / r, extinction(r - radius)]

    def leaves(_, state):
        return math.hypot(state[0], state[1]) - (radius + top)

    def lands(_, state):
        return math.hypot(state[0], state[1]) - radius

    leaves.terminal, leaves.direction = True, 1.0
    lands.terminal, lands.direction = True, -1.0
    n0 = 1.0 + nu_and_slope(altitude_m)[0]
    start = [0.0, radius + altitude_m, n0 * math.cos(elevation_rad),
             n0 * math.sin(elevation_rad), 0.0]
    solution = solve_ivp(rhs, (0.0, 5e6), start, method="DOP853", rtol=1e-11, atol=1e-9,
                         events=(leaves, lands), dense_output=True)
    assert solution.status == 1, solution.message
    end = solution.y[:, -1]
    true_altitude = math.atan2(end[3], end[2])
    s = np.linspace(0.0, solution.t[-1], 20001)
    path = solution.sol(s)
    lowest = float(np.hypot(path[0], path[1]).min() - radius)
    # a shallow dip below the ground can fall between two steps of the event search
    hit = solution.t_events[1].size > 0 or lowest < 0.0
    return true_altitude, lowest, float(end[4]), hit


def _bomford_mean_k(altitude_m, n=2001):
    """Mean terrestrial refraction coefficient over [0, h] (U.S. 1976 troposphere)."""
    z = np.linspace(0.0, altitude_m, n)
    temperature = 288.15 - 0.0065 * z
    pressure_hpa = 1013.25 * (temperature / 288.15) ** 5.25588
    k = 503.0 * pressure_hpa / temperature ** 2 * (0.0343 - 0.0065)
    return float(np.trapezoid(k, z) / altitude_m)


def _deg(values):
    return torch.deg2rad(torch.tensor(values, dtype=torch.float64))


def test_geometric_dip_without_refraction():
    height = torch.tensor([0.0, 3000.0, 10_000.0, 1e5, 4e5], dtype=torch.float64)
    dip = rf.horizon_dip(_Vacuum(), height)
    expected = np.arccos(6.371e6 / (6.371e6 + height.numpy()))
    assert np.allclose(dip["geometric_dip_rad"].numpy(), expected, rtol=0, atol=1e-12)
    # no refraction: the apparent horizon is the geometric one, and unrefracted
    assert np.allclose(dip["apparent_dip_rad"].numpy(), expected, rtol=0, atol=1e-12)
    assert float(dip["refraction_rad"].abs().max()) == 0.0
    assert math.degrees(float(dip["geometric_dip_rad"][1])) == pytest.approx(1.758, abs=5e-4)


@pytest.mark.parametrize("height", [3000.0, 10_000.0])
def test_apparent_dip_against_terrestrial_refraction_coefficient(atm, height):
    dip = rf.horizon_dip(atm, torch.tensor(height, dtype=torch.float64))
    k = _bomford_mean_k(height)
    # 0.17 at sea level; the mean over the layer falls with height (0.15 to 3 km, 0.12 to 10 km)
    assert 0.10 < k < 0.18
    closed = math.acos(6.371e6 / (6.371e6 + height)) * math.sqrt(1.0 - k)
    # sqrt(1 - k) is the small-angle form: 0.2 % of the dip (0.2' at 3 km, 0.4' at 10 km)
    assert float(dip["apparent_dip_rad"]) == pytest.approx(closed, rel=2e-3)
    assert float(dip["apparent_dip_rad"]) < float(dip["geometric_dip_rad"])


def test_grazing_ray_touches_the_ground(atm):
    """The ODE ray launched at minus the apparent dip grazes the ground (within 1 m)."""
    height = 3000.0
    dip = rf.horizon_dip(atm, torch.tensor(height, dtype=torch.float64))
    d = float(dip["apparent_dip_rad"])
    true, lowest, _, hit = _trace_ode(atm, -d + 0.2 * ARCSEC, height)
    assert not hit and abs(lowest) < 1.0
    assert abs(true - float(dip["true_altitude_rad"])) < 1.0 * ARCSEC
    _, _, _, hit = _trace_ode(atm, -d - 2.0 * ARCSEC, height)
    assert hit


@pytest.mark.parametrize(("height", "elevation_deg"), [
    (3000.0, -1.0), (3000.0, -0.5), (3000.0, -1.6), (10_000.0, -2.5), (10_000.0, 1.0)])
def test_refraction_below_the_horizon_against_ode(atm, height, elevation_deg):
    e = math.radians(elevation_deg)
    true, _, _, hit = _trace_ode(atm, e, height)
    assert not hit
    bend = rf.refraction_angle(atm, torch.tensor(e, dtype=torch.float64), height,
                               ground="raise")
    assert abs(float(bend) - (e - true)) < 1.0 * ARCSEC


def test_apparent_altitude_below_the_horizon_against_ode(atm):
    height, e = 3000.0, math.radians(-1.2)
    true, _, _, _ = _trace_ode(atm, e, height)
    apparent = rf.apparent_altitude(atm, torch.tensor(true, dtype=torch.float64), height,
                                    ground="raise")
    assert abs(float(apparent) - e) < 1.0 * ARCSEC


@pytest.mark.parametrize("height", [1000.0, 3000.0, 10_000.0])
def test_apparent_altitude_just_above_the_lowest_visible_against_ode(atm, height):
    """A source just above the lowest visible true altitude is seen above the horizon.

    Two apparent altitudes give such a true altitude: the visible ray and, below the
    apparent horizon, a continued ray into the ground (the inversion returned it: at 3 km
    true -2.45 deg gave -1.89 deg, 0.27 deg below the horizon, instead of -1.605 deg).
    """
    dip = rf.horizon_dip(atm, torch.tensor(height, dtype=torch.float64))
    true = float(dip["true_altitude_rad"]) + math.radians(0.02)
    for ground in ("raise", "allow"):
        apparent = float(rf.apparent_altitude(atm, torch.tensor(true, dtype=torch.float64),
                                              height, ground=ground))
        assert apparent > -float(dip["apparent_dip_rad"])
        traced, _, _, hit = _trace_ode(atm, apparent, height)
        assert not hit
        assert abs(traced - true) < 1.0 * ARCSEC


def test_optical_depth_below_the_horizon_against_ode(atm):
    """Extinction of a ray from 3 km that dips below the horizon and climbs to space."""
    height, e = 3000.0, math.radians(-1.0)
    _, _, tau_ode, _ = _trace_ode(atm, e, height, wavelength_nm=500.0)
    tau = rf.bent_optical_depth(atm, [500.0], torch.tensor(0.5 * math.pi - e,
                                                            dtype=torch.float64),
                                height, ground="raise")
    assert float(tau.reshape(-1)[0]) == pytest.approx(tau_ode, rel=1e-6)


def test_rays_into_the_ground_raise(atm):
    height = torch.tensor(3000.0, dtype=torch.float64)
    d = float(rf.horizon_dip(atm, height)["apparent_dip_rad"])
    below = torch.tensor([-0.5 * d, -d - 1e-6], dtype=torch.float64)
    with pytest.raises(ValueError, match="apparent_altitude_rad.*below the apparent horizon"):
        rf.refraction_angle(atm, below, height, ground="raise")
    with pytest.raises(ValueError, match="zenith_rad"):
        rf.bent_optical_depth(atm, [550.0], 0.5 * math.pi - below, height, ground="raise")
    lowest = float(rf.horizon_dip(atm, height)["true_altitude_rad"])
    with pytest.raises(ValueError, match="true_altitude_rad.*hidden by the ground"):
        rf.apparent_altitude(atm, torch.tensor(lowest - 1e-5, dtype=torch.float64), height,
                             ground="raise")
    with pytest.raises(ValueError, match="ground"):
        rf.refraction_angle(atm, below, height, ground="clip")
    # a ground observer: any ray below the horizon hits the ground
    with pytest.raises(ValueError, match="hits the ground"):
        rf.refraction_angle(atm, torch.tensor(-1e-4, dtype=torch.float64), 0.0,
                            ground="raise")
    # the default keeps continuing them (finite, the earlier behaviour)
    assert torch.isfinite(rf.refraction_angle(atm, below, height)).all()
    # down to the dip itself is fine, and through the Atmosphere method
    edge = torch.tensor(-d * (1 - 1e-9), dtype=torch.float64)
    assert torch.isfinite(atm.refraction(edge, altitude_m=3000.0, ground="raise"))


def test_horizon_dip_gradients_and_float32(atm):
    """Derivatives w.r.t. the observer altitude against finite differences; float32 values.

    Steps of 1 m: the periapsis of the grazing ray is solved to 1e-4 m, which makes
    centimetre differences noisy at the 1e-3 level.
    """
    height = torch.tensor([3000.0, 10_000.0], dtype=torch.float64, requires_grad=True)
    for key in ("geometric_dip_rad", "apparent_dip_rad", "true_altitude_rad"):
        assert torch.autograd.gradcheck(lambda h, key=key: rf.horizon_dip(atm, h)[key],
                                        (height,), eps=1.0, atol=1e-11, rtol=1e-4)
    single = rf.horizon_dip(atm, torch.tensor([3000.0, 10_000.0]))
    double = rf.horizon_dip(atm, height.detach())
    for key, value in single.items():
        assert value.dtype == torch.float32
        # float32 within 0.01 arcsec of float64 (the issue asks for 1 arcsec; measured
        # < 0.001" for the dips and for the refraction of the grazing rays from 3 and
        # 10 km, whose periapsis is the ground itself rather than solved from the dip)
        error = (value.double() - double[key]).abs()
        assert float(error.max()) < 0.01 * ARCSEC, (key, float(error.max()) / ARCSEC)


def test_grazing_ray_refraction_against_the_observer_ray_at_the_apparent_dip(atm):
    """Check the grazing ray against the observer ray sent down at the apparent dip.

    horizon_dip builds the ray with its periapsis on the ground; refraction_angle solves
    the periapsis from the dip (exact enough in float64).
    """
    height = torch.tensor([1.0, 100.0, 3000.0, 10_000.0, 30_000.0], dtype=torch.float64)
    dip = rf.horizon_dip(atm, height)
    observer_ray = rf.refraction_angle(atm, -dip["apparent_dip_rad"], height)
    assert float((dip["refraction_rad"] - observer_ray).abs().max()) < 1e-3 * ARCSEC
