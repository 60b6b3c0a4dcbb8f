"""Validation of skytorch.eclipse.occlusion.sun_visible_fraction.

References (independent of the contour-integral method under test):

* ring integration: the solar disc cut into rings about its centre; on each ring the arc
  inside the occluder comes from the spherical law of cosines, and the radial integral
  is done by adaptive quadrature (scipy.integrate.quad) — a polar integration whose
  azimuthal part is exact;
* a dense 2-D polar grid with a point-in-cap test (brute force);
* closed forms: the spherical lens area (Gauss–Bonnet) for a uniform disc, and concentric
  discs for a limb-darkened one.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy import integrate

from skytorch.eclipse import sun_visible_fraction
from skytorch.eclipse.occlusion import limb_darkening_profile

SUN_RADIUS = 4.65e-3  # angular radius of the Sun seen from Earth [rad]
EXACT = 1e-6  # required absolute accuracy of the visible fraction
FLOAT32_EXACT = 2e-6  # float32: a few units of its 1.2e-7 resolution, amplified by d f/d d


def ring_reference(rho_s, rho_o, d, u=0.6, u2=0.0, law="linear"):
    """Visible fraction by radial integration of exact ring arcs (numpy/scipy)."""

    def radiance(theta):
        r = math.sin(theta) / math.sin(rho_s)
        mu = math.sqrt(max(0.0, 1.0 - r * r))
        if law == "linear":
            return 1.0 - u * (1.0 - mu)
        return 1.0 - u * (1.0 - mu) - u2 * (1.0 - mu) ** 2

    def hav(x):
        return math.sin(0.5 * x) ** 2

    def half_arc(theta):
        # haversine law of the triangle (Sun centre, occluder centre, point on the ring)
        denominator = math.sin(theta) * math.sin(d)
        numerator = hav(rho_o) - hav(theta - d)
        if denominator == 0.0:
            return math.pi if numerator > 0 else 0.0
        return 2.0 * math.asin(math.sqrt(min(1.0, max(0.0, numerator / denominator))))

    # theta = rho_s sin(xi) removes the square root of the limb-darkening law at the limb
    def integrand(xi, arc):
        theta = rho_s * math.sin(xi)
        return radiance(theta) * math.sin(theta) * 2.0 * arc(theta) * rho_s * math.cos(xi)

    kinks = sorted(math.asin(x / rho_s) for x in (abs(d - rho_o), d + rho_o) if 0 < x < rho_s)
    options = dict(limit=400, epsabs=1e-14, epsrel=1e-12)
    blocked = integrate.quad(integrand, 0, math.pi / 2, args=(half_arc,),
                             points=kinks or None, **options)[0]
    total = integrate.quad(integrand, 0, math.pi / 2, args=(lambda _: math.pi,), **options)[0]
    return 1.0 - blocked / total


def polar_grid_reference(rho_s, rho_o, d, u, n_theta=3000, n_psi=6000):
    """Brute-force 2-D polar grid over the solar disc with a point-in-cap test."""
    xi = (np.arange(n_theta) + 0.5) / n_theta * np.pi / 2
    theta = rho_s * np.sin(xi)
    d_theta = rho_s * np.cos(xi) * np.pi / 2 / n_theta
    r = np.sin(theta) / np.sin(rho_s)
    radiance = 1.0 - u * (1.0 - np.sqrt(np.clip(1.0 - r * r, 0.0, None)))
    psi = (np.arange(n_psi) + 0.5) / n_psi * 2 * np.pi
    cos_distance = (np.cos(theta)[:, None] * np.cos(d)
                    + np.sin(theta)[:, None] * np.sin(d) * np.cos(psi)[None, :])
    covered = (cos_distance > np.cos(rho_o)).mean(axis=1)
    weight = radiance * np.sin(theta) * d_theta
    return 1.0 - float((weight * covered).sum() / weight.sum())


def spherical_lens_area(rho_s, rho_o, d):
    """Solid angle of the intersection of two spherical caps (Gauss–Bonnet)."""
    alpha = math.acos((math.cos(rho_o) - math.cos(d) * math.cos(rho_s))
                      / (math.sin(d) * math.sin(rho_s)))
    beta = math.acos((math.cos(rho_s) - math.cos(d) * math.cos(rho_o))
                     / (math.sin(d) * math.sin(rho_o)))
    # angle at an intersection point between the great circles to the two centres; the
    # lens' interior angle there is pi - chi
    chi = math.acos((math.cos(d) - math.cos(rho_s) * math.cos(rho_o))
                    / (math.sin(rho_s) * math.sin(rho_o)))
    # area = 2 pi - (geodesic curvature of the rims) - (exterior angles at the corners)
    return 2 * (math.pi - chi) - 2 * alpha * math.cos(rho_s) - 2 * beta * math.cos(rho_o)


configurations = st.tuples(
    st.floats(-4.0, -0.7),  # log10 sun radius (up to 0.2 rad)
    st.floats(-3.0, 3.0),  # log10 occluder / sun radius
    st.floats(0.0, 1.05),  # separation / (sum of radii)
    st.floats(0.0, 1.0),  # u
)


def _unpack(configuration):
    log_sun, log_ratio, overlap, u = configuration
    rho_s = 10.0**log_sun
    rho_o = min(rho_s * 10.0**log_ratio, 0.5 * math.pi)
    return rho_s, rho_o, overlap * (rho_s + rho_o), u


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(configurations)
def test_linear_law_matches_ring_integration(configuration):
    rho_s, rho_o, d, u = _unpack(configuration)
    value = sun_visible_fraction(rho_s, rho_o, d, u).item()
    assert abs(value - ring_reference(rho_s, rho_o, d, u)) < EXACT


@settings(max_examples=60, deadline=None)
@given(configurations, st.floats(-0.5, 0.5))
def test_quadratic_law_matches_ring_integration(configuration, u2_fraction):
    rho_s, rho_o, d, u1 = _unpack(configuration)
    # keep the law physical: u1 + u2 <= 1 and u1 + 2 u2 >= 0
    u2 = float(np.clip(u2_fraction, -0.5 * u1, 1.0 - u1))
    value = sun_visible_fraction(rho_s, rho_o, d, (u1, u2), law="quadratic").item()
    assert abs(value - ring_reference(rho_s, rho_o, d, u1, u2, "quadratic")) < EXACT


@pytest.mark.parametrize(
    ("ratio", "overlap"),
    [(0.3, 0.5), (1.1, 0.48), (0.05, 0.9), (0.9, 0.1), (3.0, 0.9)],
)
def test_brute_force_polar_grid(ratio, overlap):
    rho_o = ratio * SUN_RADIUS
    d = overlap * (SUN_RADIUS + rho_o)
    value = sun_visible_fraction(SUN_RADIUS, rho_o, d, 0.6).item()
    assert abs(value - polar_grid_reference(SUN_RADIUS, rho_o, d, 0.6)) < 1e-5


@pytest.mark.parametrize(
    ("rho_s", "rho_o", "d"),
    [(0.01, 0.02, 0.02), (0.2, 0.5, 0.55), (0.1, 1.5, 1.55), (0.2, 0.05, 0.2), (0.15, 0.15, 0.1)],
)
def test_uniform_disc_is_spherical_lens_area(rho_s, rho_o, d):
    sun_solid_angle = 2 * math.pi * (1 - math.cos(rho_s))
    expected = 1 - spherical_lens_area(rho_s, rho_o, d) / sun_solid_angle
    assert abs(sun_visible_fraction(rho_s, rho_o, d, 0.0).item() - expected) < EXACT


@pytest.mark.parametrize("ratio", [0.01, 0.3, 0.7, 0.999])
@pytest.mark.parametrize("u", [0.0, 0.6, 1.0])
def test_concentric_occluder_closed_form(ratio, u):
    # flat limit (rho_s = 1e-5 rad): blocked flux of a central disc of radius r (Sun radii)
    rho_s = 1e-5
    blocked = (1 - u) * ratio**2 + 2 * u / 3 * (1 - (1 - ratio**2) ** 1.5)
    expected = 1 - blocked / (1 - u / 3)
    assert abs(sun_visible_fraction(rho_s, ratio * rho_s, 0.0, u).item() - expected) < EXACT


def test_limb_darkening_profile():
    mu = torch.tensor([0.0, 0.5, 1.0], dtype=torch.float64)
    assert torch.allclose(limb_darkening_profile(mu, 0.6), 1 - 0.6 * (1 - mu))
    quadratic = limb_darkening_profile(mu, (0.4, 0.2), law="quadratic")
    assert torch.allclose(quadratic, 1 - 0.4 * (1 - mu) - 0.2 * (1 - mu) ** 2)


def test_broadcasting_and_dtype():
    d = torch.linspace(0, 2 * SUN_RADIUS, 5, dtype=torch.float32)
    rho_o = torch.tensor([[0.5], [1.0], [2.0]], dtype=torch.float32) * SUN_RADIUS
    value = sun_visible_fraction(SUN_RADIUS, rho_o, d)
    assert value.shape == (3, 5) and value.dtype == torch.float32
    assert sun_visible_fraction(SUN_RADIUS, SUN_RADIUS, 0.001).dtype == torch.float64


def test_many_chunks_agree_with_single_evaluations(monkeypatch):
    from skytorch.eclipse import occlusion

    monkeypatch.setattr(occlusion, "_CHUNK", 4_096)
    monkeypatch.setattr(occlusion, "_SERIAL_CHUNK", 4_096)
    monkeypatch.setattr(occlusion, "_NODE_CHUNK", 1_000)  # rim sub-chunks, uneven split
    monkeypatch.setattr(occlusion, "_SERIAL_RIM_ROWS", 1_000)
    generator = torch.Generator().manual_seed(3)
    rho_o = SUN_RADIUS * (0.1 + 3 * torch.rand(40_000, generator=generator, dtype=torch.float64))
    d = (SUN_RADIUS + rho_o) * torch.rand(40_000, generator=generator, dtype=torch.float64)
    batch = sun_visible_fraction(SUN_RADIUS, rho_o, d)
    picks = [0, 4_095, 4_096, 39_999]
    single = torch.stack([sun_visible_fraction(SUN_RADIUS, rho_o[i], d[i]) for i in picks])
    assert torch.allclose(batch[picks], single, atol=1e-15)


def test_threaded_chunks_equal_one_thread(monkeypatch):
    # without gradients, chunks of configurations are spread over a thread pool (tasks and
    # rim sub-chunks of a different size than on one thread); every configuration is
    # computed by the same element-wise operations, so the results are identical
    from skytorch.eclipse import occlusion

    monkeypatch.setattr(occlusion, "_TASK_ELEMENTS", 2_048)
    generator = torch.Generator().manual_seed(5)
    rho_s = SUN_RADIUS * (0.5 + torch.rand(20_000, generator=generator, dtype=torch.float64))
    rho_o = rho_s * (0.1 + 3 * torch.rand(20_000, generator=generator, dtype=torch.float64))
    d = (rho_s + rho_o) * torch.rand(20_000, generator=generator, dtype=torch.float64)
    threads = torch.get_num_threads()
    try:
        torch.set_num_threads(1)
        serial = sun_visible_fraction(rho_s, rho_o, d, 0.6)
        torch.set_num_threads(3)
        threaded = sun_visible_fraction(rho_s, rho_o, d, 0.6)
    finally:
        torch.set_num_threads(threads)
    assert torch.equal(serial, threaded)
    # and both equal the path with gradients (the previous kernel, autograd-capable)
    with_gradient = sun_visible_fraction(rho_s, rho_o, d.clone().requires_grad_(True), 0.6)
    assert torch.allclose(serial, with_gradient.detach(), rtol=0.0, atol=1e-13)


@pytest.mark.parametrize("law", ["linear", "quadratic"])
def test_per_configuration_sun_and_law(law):
    # a Sun radius and limb-darkening coefficients per configuration: the kernel without
    # gradients builds the radial coefficients per chunk; it must agree with the path with
    # gradients, with single evaluations, and with the independent ring integration
    rng = np.random.default_rng(11)
    n = 3_000
    rho_s = 10.0 ** rng.uniform(-4.0, math.log10(0.2), n)
    rho_o = np.minimum(rho_s * 10.0 ** rng.uniform(-2.0, 2.0, n), 0.5 * math.pi)
    d = rng.uniform(0.0, 1.05, n) * (rho_s + rho_o)
    u1 = rng.uniform(0.0, 1.0, n)
    u2 = np.clip(rng.uniform(-0.5, 0.5, n), -0.5 * u1, 1.0 - u1)
    limb = np.stack([u1, u2], axis=-1) if law == "quadratic" else u1
    inputs = [torch.as_tensor(x) for x in (rho_s, rho_o, d, limb)]
    fast = sun_visible_fraction(*inputs, law=law)
    with_gradient = sun_visible_fraction(*inputs[:2], inputs[2].clone().requires_grad_(True),
                                         inputs[3], law=law).detach()
    assert torch.allclose(fast, with_gradient, rtol=0.0, atol=1e-13)
    for i in (0, 1, 2_999):
        single = sun_visible_fraction(*(x[i] for x in inputs), law=law)
        # (a lone configuration may use fewer terms of the 1/cos series: 1e-9 relative)
        assert float(single) == pytest.approx(float(fast[i]), abs=1e-12)
        reference = ring_reference(rho_s[i], rho_o[i], d[i], u1[i], u2[i], law)
        assert abs(float(fast[i]) - reference) < EXACT
    # float32 follows float64 to the float32 floor of near-contact configurations
    fast32 = sun_visible_fraction(*(x.float() for x in inputs), law=law)
    assert float((fast32.double() - fast).abs().max()) < 2e-5


def test_gradients_over_rim_sub_chunks_agree_with_single_evaluations(monkeypatch):
    from skytorch.eclipse import occlusion

    monkeypatch.setattr(occlusion, "_NODE_CHUNK", 1_000)
    generator = torch.Generator().manual_seed(4)
    rho_o = SUN_RADIUS * (0.1 + 3 * torch.rand(3_000, generator=generator, dtype=torch.float64))
    d = ((SUN_RADIUS + rho_o) * torch.rand(3_000, generator=generator, dtype=torch.float64))
    d.requires_grad_(True)
    sun_visible_fraction(SUN_RADIUS, rho_o, d).sum().backward()
    for i in (0, 999, 1_000, 2_999):
        single = d.detach()[i].clone().requires_grad_(True)
        sun_visible_fraction(SUN_RADIUS, rho_o[i], single).backward()
        assert d.grad[i].item() == pytest.approx(single.grad.item(), rel=1e-12)


@pytest.mark.parametrize(
    ("name", "value", "message"),
    [("sun_radius_rad", -1e-3, "sun_radius_rad"), ("sun_radius_rad", 0.3, "sun_radius_rad"),
     ("occluder_radius_rad", 2.0, "occluder_radius_rad"),
     ("separation_rad", float("nan"), "separation_rad"), ("limb_darkening", 1.5, "limb_darkening")],
)
def test_invalid_input_names_parameter(name, value, message):
    arguments = dict(sun_radius_rad=SUN_RADIUS, occluder_radius_rad=SUN_RADIUS,
                     separation_rad=SUN_RADIUS, limb_darkening=0.6)
    arguments[name] = value
    with pytest.raises(ValueError, match=message):
        sun_visible_fraction(**arguments)


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -1e-3, 4.0])
def test_invalid_value_in_a_large_input_names_parameter(bad):
    # large inputs are range-checked in one pass; the error must still name the parameter
    d = torch.full((1000,), SUN_RADIUS, dtype=torch.float64)
    d[637] = bad
    with pytest.raises(ValueError, match="separation_rad"):
        sun_visible_fraction(SUN_RADIUS, SUN_RADIUS, d)


def test_shapes_that_do_not_broadcast_name_the_parameters():
    with pytest.raises(ValueError, match="occluder_radius_rad .3,.*separation_rad .4,"):
        sun_visible_fraction(SUN_RADIUS, torch.full((3,), SUN_RADIUS), torch.zeros(4))


def test_invalid_law_and_quadratic_coefficients():
    with pytest.raises(ValueError, match="law"):
        sun_visible_fraction(SUN_RADIUS, SUN_RADIUS, 0.0, law="cubic")
    with pytest.raises(ValueError, match="pair"):
        sun_visible_fraction(SUN_RADIUS, SUN_RADIUS, 0.0, 0.5, law="quadratic")
    with pytest.raises(ValueError, match="u1 \\+ u2"):
        sun_visible_fraction(SUN_RADIUS, SUN_RADIUS, 0.0, (0.8, 0.5), law="quadratic")


# --- hard cases: float64 and float32, values and gradients -----------------------------------

HARD_CASES = {
    # name: (occluder / sun radius, separation / sun radius, exact value or None)
    "behind centre, larger occluder": (2.0, 0.0, 0.0),
    "behind centre, equal radii": (1.0, 0.0, 0.0),
    "behind centre, annular": (0.5, 0.0, None),
    "tangent outside": (1.0, 2.0, 1.0),
    "tangent inside, occluder on the disc": (0.5, 0.5, None),
    "tangent inside, Sun in the occluder": (2.0, 1.0, 0.0),
    "fully visible": (1.0, 5.0, 1.0),
    "far beyond the penumbra": (3.0, 300.0, 1.0),
    "Phobos-like antumbra": (0.6, 0.2, None),
    "antumbra on the axis": (0.6, 0.0, None),
    "tiny occluder on the axis": (1e-3, 0.0, None),
    "tiny occluder": (1e-3, 0.5, None),
    "huge occluder (Earth from low orbit)": (1.4 / SUN_RADIUS, 1.4 / SUN_RADIUS + 0.3, None),
}


@pytest.mark.parametrize("case", list(HARD_CASES))
def test_hard_cases_values_and_gradients(case, dtype):
    ratio, offset, exact = HARD_CASES[case]
    inputs = torch.tensor([SUN_RADIUS, ratio * SUN_RADIUS, offset * SUN_RADIUS], dtype=dtype,
                          requires_grad=True)
    u = torch.tensor(0.6, dtype=dtype, requires_grad=True)
    value = sun_visible_fraction(inputs[0], inputs[1], inputs[2], u)
    value.backward()
    assert value.dtype == dtype
    assert torch.isfinite(value) and torch.isfinite(inputs.grad).all()
    assert torch.isfinite(u.grad)
    rho_s, rho_o, d = (float(x) for x in inputs.detach())  # the values the dtype can hold
    reference = ring_reference(rho_s, rho_o, d) if exact is None else exact
    tolerance = EXACT if dtype == torch.float64 else FLOAT32_EXACT
    assert abs(value.item() - reference) < tolerance
    if exact is not None:  # flat there: tangency (f ~ eps^1.5) or no overlap at all
        assert torch.all(inputs.grad == 0)


@pytest.mark.parametrize(
    ("ratio", "offset"), [(0.3, 0.5), (2.0, 2.5), (0.99, 0.02), (60.0, 60.5), (0.5, 0.05)])
@pytest.mark.parametrize("law", ["linear", "quadratic"])
def test_gradcheck_away_from_kinks(ratio, offset, law):
    inputs = torch.tensor([SUN_RADIUS, ratio * SUN_RADIUS, offset * SUN_RADIUS],
                          dtype=torch.float64, requires_grad=True)
    coefficients = torch.tensor(0.6 if law == "linear" else [0.5, 0.2], dtype=torch.float64,
                                requires_grad=True)

    def function(x, c):
        return sun_visible_fraction(x[0], x[1], x[2], c, law=law, n_nodes=16)

    assert torch.autograd.gradcheck(function, (inputs, coefficients), eps=1e-9, atol=1e-6)


def test_gradient_matches_finite_difference_of_reference():
    # derivative with respect to separation vs a central difference of the ring reference
    rho_o, d, step = 0.4 * SUN_RADIUS, 0.9 * SUN_RADIUS, 1e-3 * SUN_RADIUS
    separation = torch.tensor(d, dtype=torch.float64, requires_grad=True)
    sun_visible_fraction(SUN_RADIUS, rho_o, separation).backward()
    expected = (ring_reference(SUN_RADIUS, rho_o, d + step)
                - ring_reference(SUN_RADIUS, rho_o, d - step)) / (2 * step)
    assert separation.grad.item() == pytest.approx(expected, rel=1e-5)


def test_accuracy_cost_experiment_quick(tmp_path):
    import runpy
    from pathlib import Path

    from skytorch.dataset import open_dataset

    script = Path(__file__).resolve().parents[1] / "experiments" / "eclipse_geometry_accuracy_cost.py"
    module = runpy.run_path(str(script))
    assert module["main"](["--quick", "--output-dir", str(tmp_path)]) == 0
    dataset = open_dataset(tmp_path / "eclipse_geometry_accuracy_cost.nc")
    assert (tmp_path / "eclipse_geometry_accuracy_cost.png").stat().st_size > 0
    # float64 error falls with the node count and is below 1e-6 at the default
    errors = dataset.max_error.sel(dtype="float64").values
    assert errors[-1] < 1e-6 and errors[0] > errors[-1]


@pytest.mark.parametrize("ratio", [0.05, 0.6, 0.95])
def test_gradient_on_the_axis_matches_concentric_closed_form(ratio, dtype):
    # occluder centred on the disc (antumbra on the axis), every input requiring a gradient:
    # d f / d rho_o from the derivative of the concentric closed form (flat limit), and
    # d f / d d = 0 by symmetry
    rho_s, u = 1e-5, 0.6
    inputs = torch.tensor([rho_s, ratio * rho_s, 0.0], dtype=dtype, requires_grad=True)
    sun_visible_fraction(inputs[0], inputs[1], inputs[2], u).backward()
    blocked_slope = 2 * (1 - u) * ratio + 2 * u * ratio * math.sqrt(1 - ratio**2)
    expected = -blocked_slope / (1 - u / 3) / rho_s
    tolerance = 1e-6 if dtype == torch.float64 else 1e-4
    assert torch.isfinite(inputs.grad).all()
    assert inputs.grad[1].item() == pytest.approx(expected, rel=tolerance)
    assert inputs.grad[2].item() == 0.0
