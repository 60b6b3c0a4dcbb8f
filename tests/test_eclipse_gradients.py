"""Values and gradients of sun_visible_fraction at hard cases against an independent reference.

The reference (:func:`reference` below) is written in mpmath (22 digits, tanh-sinh
quadrature) from formulas that share nothing with the contour integral under test:

* the value by rings about the Sun's centre, ``B = int I(theta) sin(theta) 2 psi(theta)
  d theta`` with ``psi`` the half-arc of the ring inside the occluder (spherical law of
  cosines), written in ``mu`` (``sin theta = sin rho_s sqrt(1 - mu^2)``) so that the
  square root of the radiance at the limb disappears; ``f = 1 - B / F``;
* the derivatives with respect to the separation and the occluder radius by Reynolds'
  transport theorem (only the occluder's rim moves): ``dB/dd = -2 sin rho_o
  int_0^phi_max I cos(phi) d phi``, ``dB/d rho_o = 2 sin rho_o int_0^phi_max I d phi``
  (``phi``: azimuth on the rim about the occluder's centre, 0 towards the Sun's centre);
* with respect to the Sun's radius: the limb moves (``I = a0`` there, over the arc
  ``2 alpha sin rho_s`` inside the occluder) and the radiance changes inside,
  ``dI/d rho_s = (a1 + 2 a2 mu) (1 - mu^2) cot(rho_s) / mu`` at fixed ``theta``;
* with respect to the linear limb-darkening coefficient directly (``B`` and ``F`` are
  linear in it).
 Cases: inner tangency with the occluder on the disc (both
sides, offsets 1e-19 to 1e-6 rad in float64, 1e-8 to 1e-4 rad in float32), inner tangency
with the Sun inside the occluder, outer tangency, containment (both ways) and the antumbra
axis.

Tolerances, in physical units: the visible fraction within 1e-7 (float64; the 8-node rim
quadrature's error is 2.4e-8 here) or 3e-7 (float32: a few units of its resolution);
each derivative within ``GRADIENT_TOLERANCE / rho_s`` [1/rad], i.e. the error of the
fraction's change across one solar radius (the natural scale of the derivatives, which are
of order 1 / rho_s = 215 per rad), 3e-6 in float64 (the quadrature, measured 1.2e-6 at
worst) and 1e-5 in float32 (at outer tangency a float32 offset of 1e-8 rad is only known
to ulp(rho_o + rho_s) = 2e-10 rad, and f' grows as the square root of the offset).
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest
import torch

from skytorch.eclipse import sun_visible_fraction

SUN_RADIUS = 4.65e-3  # [rad]
VALUE_TOLERANCE = {torch.float64: 1e-7, torch.float32: 3e-7}
GRADIENT_TOLERANCE = {torch.float64: 3e-6, torch.float32: 1e-5}
OFFSETS = {torch.float64: (1e-19, 1e-16, 1e-13, 1e-10, 1e-8, 1e-6),
           torch.float32: (1e-8, 1e-6, 1e-4)}
DTYPES = (torch.float64, torch.float32)
#: working precision of the reference [decimal digits] (18 already gives the same doubles)
_DIGITS = 22


# --- independent reference -----------------------------------------------------------------


def _law(law, limb_darkening):
    if law == "linear":
        u = mp.mpf(limb_darkening)
        return 1 - u, u, mp.mpf(0)
    u1, u2 = (mp.mpf(x) for x in limb_darkening)
    return 1 - u1 - u2, u1 + 2 * u2, -u2


def _hav(x):
    return mp.sin(x / 2) ** 2


def _angle(numerator, denominator):
    """Angle in [0, pi] whose haversine is numerator / denominator (clipped)."""
    if denominator <= 0:
        return mp.pi if numerator > 0 else mp.mpf(0)
    h = min(max(numerator / denominator, mp.mpf(0)), mp.mpf(1))
    return 2 * mp.asin(mp.sqrt(h))


def reference(rho_s, rho_o, d, limb_darkening=0.6, law="linear"):  # noqa: C901 (mpmath quadrature, one branch per overlap case)
    """Visible fraction and its gradient.

    Returns ``(f, {"d": df/dd, "rho_o": df/drho_o, "rho_s": df/drho_s, "u": df/du})``
    (``"u"`` only for the linear law); inputs are Python floats (their exact binary
    values are used).
    """
    with mp.workdps(_DIGITS):
        rho_s, rho_o, d = (mp.mpf(x) for x in (rho_s, rho_o, d))
        a0, a1, a2 = _law(law, limb_darkening)
        s = mp.sin(rho_s)
        cot_s = mp.cos(rho_s) / s

        def radiance(mu):
            return a0 + a1 * mu + a2 * mu * mu

        def theta_of_mu(mu):
            return mp.asin(s * mp.sqrt(1 - mu * mu))

        def half_arc(theta):
            # half-angle about the Sun's centre of the ring of radius theta in the occluder
            if theta <= abs(d - rho_o):
                return mp.pi if rho_o > d else mp.mpf(0)
            if theta >= d + rho_o:
                return mp.mpf(0)
            return _angle(_hav(rho_o) - _hav(theta - d), mp.sin(theta) * mp.sin(d))

        kinks = [mp.sqrt(1 - (mp.sin(x) / s) ** 2) for x in (abs(d - rho_o), d + rho_o)
                 if 0 < x < rho_s]
        points = sorted({mp.mpf(0), *kinks, mp.mpf(1)})

        def integrate(function):
            return mp.quad(function, points)

        def element(mu):  # sin(theta) d theta / d mu
            return s * s * mu / mp.cos(theta_of_mu(mu))

        blocked = integrate(lambda mu: radiance(mu) * element(mu) * 2 * half_arc(theta_of_mu(mu)))
        total = 2 * mp.pi * integrate(lambda mu: radiance(mu) * element(mu))
        fraction = 1 - blocked / total

        # rim of the occluder: phi_max where it crosses the limb
        if d <= rho_s - rho_o:
            phi_max = mp.pi
        elif d <= rho_o - rho_s or d >= rho_o + rho_s:
            phi_max = mp.mpf(0)
        else:
            phi_max = _angle(_hav(rho_s) - _hav(d - rho_o), mp.sin(d) * mp.sin(rho_o))

        def radiance_on_rim(phi):
            hav_theta = _hav(d - rho_o) + mp.sin(d) * mp.sin(rho_o) * _hav(phi)
            sin2_theta = 4 * hav_theta * (1 - hav_theta)
            return radiance(mp.sqrt(max(1 - sin2_theta / (s * s), mp.mpf(0))))

        if phi_max > 0:
            rim_points = [0, phi_max / 2, phi_max]
            blocked_d = -2 * mp.sin(rho_o) * mp.quad(
                lambda phi: radiance_on_rim(phi) * mp.cos(phi), rim_points)
            blocked_o = 2 * mp.sin(rho_o) * mp.quad(radiance_on_rim, rim_points)
        else:
            blocked_d = blocked_o = mp.mpf(0)
        # limb of the Sun: alpha, half-arc inside the occluder
        alpha = half_arc(rho_s)

        def radiance_slope(mu):  # dI / d rho_s at fixed theta, times mu
            return (a1 + 2 * a2 * mu) * (1 - mu * mu) * cot_s

        inner = integrate(lambda mu: radiance_slope(mu) * element(mu) / mu
                          * 2 * half_arc(theta_of_mu(mu)))
        blocked_s = a0 * 2 * alpha * s + inner
        total_s = a0 * 2 * mp.pi * s + 2 * mp.pi * integrate(
            lambda mu: radiance_slope(mu) * element(mu) / mu)

        def fraction_slope(blocked_x, total_x):
            return -(blocked_x * total - blocked * total_x) / total**2

        gradient = {"d": fraction_slope(blocked_d, 0), "rho_o": fraction_slope(blocked_o, 0),
                    "rho_s": fraction_slope(blocked_s, total_s)}
        if law == "linear":
            blocked_u = integrate(lambda mu: (mu - 1) * element(mu) * 2 * half_arc(theta_of_mu(mu)))
            total_u = 2 * mp.pi * integrate(lambda mu: (mu - 1) * element(mu))
            gradient["u"] = fraction_slope(blocked_u, total_u)
        return float(fraction), {key: float(value) for key, value in gradient.items()}


# --- tests -----------------------------------------------------------------------------------


def _evaluate(rho_s, rho_o, d, dtype, limb_darkening=0.6, law="linear"):
    inputs = torch.tensor([rho_s, rho_o, d], dtype=torch.float64).to(dtype)
    inputs.requires_grad_(True)
    u = torch.tensor(limb_darkening, dtype=dtype, requires_grad=True)
    value = sun_visible_fraction(inputs[0], inputs[1], inputs[2], u, law=law)
    value.backward()
    held = [float(x) for x in inputs.detach()]  # the inputs as the dtype holds them
    gradient = {"rho_s": inputs.grad[0].item(), "rho_o": inputs.grad[1].item(),
                "d": inputs.grad[2].item()}
    if law == "linear":
        gradient["u"] = u.grad.item()
    return value.item(), gradient, held


def _check(rho_s, rho_o, d, dtype, limb_darkening=0.6, law="linear"):
    value, gradient, held = _evaluate(rho_s, rho_o, d, dtype, limb_darkening, law)
    expected_value, expected_gradient = reference(*held, limb_darkening, law)
    assert abs(value - expected_value) < VALUE_TOLERANCE[dtype], (value, expected_value)
    tolerance = GRADIENT_TOLERANCE[dtype] / held[0]
    for key, expected in expected_gradient.items():
        scale = tolerance if key != "u" else GRADIENT_TOLERANCE[dtype]  # d f / d u is in [1]
        assert abs(gradient[key] - expected) < scale, (key, gradient[key], expected)
    return value, gradient, expected_gradient


def _cases(offsets_of_dtype):
    return [(dtype, sign * offset) for dtype in DTYPES for offset in offsets_of_dtype[dtype]
            for sign in (-1.0, 1.0)]


@pytest.mark.parametrize("ratio", [0.1, 0.5])
@pytest.mark.parametrize(("dtype", "offset"), _cases(OFFSETS))
def test_inner_tangency_occluder_on_the_disc(ratio, dtype, offset):
    # d = rho_s - rho_o + offset: partial overlap for offset > 0, containment below
    rho_o = ratio * SUN_RADIUS
    _check(SUN_RADIUS, rho_o, SUN_RADIUS - rho_o + offset, dtype)


@pytest.mark.parametrize(("dtype", "offset"), _cases(OFFSETS))
def test_inner_tangency_sun_inside_the_occluder(dtype, offset):
    # d = rho_o - rho_s + offset: the Sun hidden for offset < 0, a sliver above
    rho_o = 2.0 * SUN_RADIUS
    _check(SUN_RADIUS, rho_o, rho_o - SUN_RADIUS + offset, dtype)


@pytest.mark.parametrize(("dtype", "offset"), _cases(OFFSETS))
def test_outer_tangency(dtype, offset):
    rho_o = 0.5 * SUN_RADIUS
    _check(SUN_RADIUS, rho_o, SUN_RADIUS + rho_o + offset, dtype)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize(("ratio", "separation"), [
    (0.5, 0.2),  # occluder inside the disc
    (0.05, 0.9),  # small occluder near the limb
    (3.0, 1.0),  # Sun inside the occluder
    (0.6, 0.0),  # antumbra on the axis
    (0.999, 0.0),  # annular, nearly total, on the axis
    (1.0, 0.3),  # equal radii
])
def test_containment_and_axis(ratio, separation, dtype):
    _, gradient, _ = _check(SUN_RADIUS, ratio * SUN_RADIUS, separation * SUN_RADIUS, dtype)
    if separation == 0.0:
        assert gradient["d"] == 0.0  # symmetry


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("offset", [-1e-10, 1e-13, 1e-10, 1e-6])
def test_inner_tangency_quadratic_law(dtype, offset):
    if dtype == torch.float32 and abs(offset) < 1e-8:
        offset = 1e-8 if offset > 0 else -1e-8
    rho_o = 0.4 * SUN_RADIUS
    _check(SUN_RADIUS, rho_o, SUN_RADIUS - rho_o + offset, dtype, (0.5, 0.2), "quadratic")


def test_gradient_is_continuous_across_inner_tangency():
    # the derivative w.r.t. the separation is continuous across inner tangency (the
    # missing rim arc shrinks as the square root of the offset); before the fix it read
    # 1.5e9 at +5e-19 rad and 4.4e4 at +1e-16 rad
    rho_o = 0.5 * SUN_RADIUS
    base = SUN_RADIUS - rho_o
    slopes = [_evaluate(SUN_RADIUS, rho_o, base + offset, torch.float64)[1]["d"]
              for offset in (-1e-16, 5e-19, 1e-16, 1e-13)]
    assert max(slopes) - min(slopes) < 1e-3  # [1/rad], against a slope of 34.2 per rad


@pytest.mark.parametrize("dtype", DTYPES)
def test_fast_path_matches_gradient_path_near_tangency(dtype):
    # the kernel without gradients gives the same values next to every tangency
    rho_o = torch.tensor([0.5, 2.0, 0.5], dtype=torch.float64) * SUN_RADIUS
    base = torch.stack([SUN_RADIUS - rho_o[0], rho_o[1] - SUN_RADIUS, SUN_RADIUS + rho_o[2]])
    offsets = torch.tensor(OFFSETS[dtype], dtype=torch.float64)
    d = (base[:, None] + torch.cat([-offsets, offsets])[None, :]).to(dtype)
    rho_o = rho_o[:, None].to(dtype).expand_as(d)
    with torch.no_grad():
        fast = sun_visible_fraction(SUN_RADIUS, rho_o, d)
    slow = sun_visible_fraction(SUN_RADIUS, rho_o, d.clone().requires_grad_(True)).detach()
    resolution = 1e-15 if dtype == torch.float64 else 2e-7
    assert (fast - slow).abs().max().item() < resolution


# --- the shadow: gradients with respect to the atmosphere ---------------------------------------

MOON_DISTANCE = 3.844e8  # [m]
#: points from the umbra's centre to the penumbra [m] and two wavelengths [nm]
SHADOW_OFFSETS = (0.0, 3.0e6, 6.0e6)
SHADOW_WAVELENGTHS = (450.0, 650.0)


def _shadow_illuminance(grad=False, **parameters):
    from skytorch.atmosphere import Atmosphere
    from skytorch.eclipse import Shadow

    tensors = {key: torch.tensor(value, dtype=torch.float64, requires_grad=grad)
               for key, value in parameters.items()}
    shadow = Shadow.earth(Atmosphere.earth(**tensors), n_altitude=65)
    offsets = torch.tensor(SHADOW_OFFSETS, dtype=torch.float64)
    return tensors, shadow.relative_illuminance(MOON_DISTANCE, offsets, SHADOW_WAVELENGTHS)


@pytest.mark.parametrize(("name", "value", "step"), [("turbidity", 2.0, 1e-4),
                                                     ("ozone_du", 300.0, 1e-2)])
def test_shadow_gradient_wrt_the_atmosphere_matches_finite_differences(name, value, step):
    # d(I / I_sun)/d(parameter) in the umbra and the penumbra against a central difference
    # (truncation error ~ step^2 times the third derivative: far below the tolerance)
    tensors, illuminance = _shadow_illuminance(grad=True, **{name: value})
    with torch.no_grad():
        _, plus = _shadow_illuminance(**{name: value + step})
        _, minus = _shadow_illuminance(**{name: value - step})
    expected = (plus - minus) / (2 * step)
    for index in np.ndindex(*illuminance.shape):
        (slope,) = torch.autograd.grad(illuminance[index], tensors[name], retain_graph=True)
        # relative 1e-6, or 1e-12 per unit of the parameter where the slope is tiny
        assert abs(slope.item() - expected[index].item()) <= (
            1e-6 * abs(expected[index].item()) + 1e-12), (index, slope, expected[index])
    # the differentiable path (no low-rank factorisation) gives the cached path's values
    with torch.no_grad():
        _, cached = _shadow_illuminance(**{name: value})
    assert torch.allclose(illuminance.detach(), cached, rtol=1e-10, atol=1e-16)
