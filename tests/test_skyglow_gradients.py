"""Gradients of the skyglow render and kernel at hard cases, against finite differences.

The render is linear in the fluxes, so its gradient is checked exactly (gradcheck in
float64); with respect to the observer position away from polar nodes, and at a lit cell
(where the distance is not differentiable: the returned gradient must be finite). The
kernel is checked at the horizon (φ = 0, where the table lookups sit on their edges),
at the zenith and for a source at the observer (r = 0), with one-sided differences where
the argument is at the end of its range.
"""

from __future__ import annotations

import math

import torch
from _skyglow_standin import cached_model, medium, single_torch_thread  # noqa: F401
from torch.autograd import gradcheck

from skytorch.skyglow.kernel import kernel_radiance

X = torch.arange(4, dtype=torch.float64) * 1000.0 - 1500.0
Y = torch.arange(3, dtype=torch.float64) * 1000.0 - 1000.0
FLUX = torch.rand(3, 4, dtype=torch.float64, generator=torch.Generator().manual_seed(0)) * 1e5


def _luminance(flux, observer_xy=(0.0, 0.0)):
    model = cached_model()
    return model.render(flux, observer_xy=observer_xy, x_m=X, y_m=Y,
                        as_dataset=False)["luminance"]


def test_render_gradient_with_respect_to_flux():
    flux = FLUX.clone().requires_grad_(True)
    # every 4th elevation and 8th azimuth: 16 outputs against 12 fluxes
    assert gradcheck(lambda f: _luminance(f)[::4, ::8], (flux,), eps=1.0, atol=1e-15,
                     rtol=1e-6)


def test_render_gradient_with_respect_to_the_observer_position():
    """At (130, 270) m — between polar nodes — against central differences (eps 1 mm)."""
    xy = torch.tensor([130.0, 270.0], dtype=torch.float64, requires_grad=True)
    assert gradcheck(lambda p: _luminance(FLUX, p).sum(), (xy,), eps=1e-3, atol=1e-12,
                     rtol=1e-4)


def test_render_gradient_finite_with_the_observer_on_a_lit_cell():
    """Differentiate at r = 0 to the cell at (500, 0) m.

    sqrt and atan2 have no derivative there; the gradient is finite (the other cells'
    contributions) and equal to the one obtained with that cell switched off plus a zero
    subgradient for it.
    """
    xy = torch.tensor([500.0, 0.0], dtype=torch.float64, requires_grad=True)
    (gradient,) = torch.autograd.grad(_luminance(FLUX, xy).sum(), xy)
    assert bool(torch.isfinite(gradient).all())
    dark = FLUX.clone()
    dark[1, 2] = 0.0  # the cell at x = 500 m, y = 0 m
    xy_dark = torch.tensor([500.0, 0.0], dtype=torch.float64, requires_grad=True)
    (gradient_dark,) = torch.autograd.grad(_luminance(dark, xy_dark).sum(), xy_dark)
    torch.testing.assert_close(gradient, gradient_dark, rtol=1e-9, atol=1e-20)


MEDIUM = medium((550.0,))


def _kernel(elevation, distance, azimuth=0.3):
    return kernel_radiance(MEDIUM, azimuth, elevation, distance, 0.0, 0.0, n_steps=8)


def _value(elevation: float, distance: float) -> float:
    return float(_kernel(torch.tensor(elevation, dtype=torch.float64),
                         torch.tensor(distance, dtype=torch.float64)))


def test_kernel_gradient_on_the_horizontal_ray():
    """Differentiate at φ = 0: second-order forward differences (h = 1e-10 rad).

    For sources 10 m and 5 km away; before the table-edge fix the 5 km gradient was
    36 % low.
    """
    for distance in (10.0, 5000.0):
        elevation = torch.tensor(0.0, dtype=torch.float64, requires_grad=True)
        (gradient,) = torch.autograd.grad(_kernel(elevation, distance).sum(), elevation)
        h = 1e-10
        reference = (-3 * _value(0.0, distance) + 4 * _value(h, distance)
                     - _value(2 * h, distance)) / (2 * h)
        assert abs(float(gradient) - reference) < 1e-5 * abs(reference), distance


def test_kernel_gradient_matches_central_differences():
    """Low, middle and near-zenith rays, sources at 10 m, 1 km and 15 km."""
    elevation = torch.tensor([1e-3, 0.7, math.pi / 2 - 1e-3], dtype=torch.float64,
                             requires_grad=True)
    distance = torch.tensor([10.0, 1e3, 1.5e4], dtype=torch.float64, requires_grad=True)
    assert gradcheck(lambda e, r: _kernel(e, r), (elevation, distance), eps=1e-7,
                     atol=1e-16, rtol=1e-4)


def test_kernel_gradient_for_a_source_at_the_observer():
    """Differentiate at r = 0 (the end of the range) at the zenith and on the horizon.

    The gradients are finite (they were NaN), and half a metre away they match central
    differences.

    On the horizon the kernel itself jumps at r = 0 (0 there, 1.6e-8 m^-2 sr^-1 for
    r → 0+: the horizontal ray lies in the source's horizon plane, where Garstang's
    emission is discontinuous), so only finiteness is asserted at r = 0.
    """
    for elevation0 in (0.0, math.pi / 2):
        elevation = torch.tensor(elevation0, dtype=torch.float64, requires_grad=True)
        distance = torch.tensor(0.0, dtype=torch.float64, requires_grad=True)
        g_el, g_r = torch.autograd.grad(_kernel(elevation, distance).sum(),
                                        (elevation, distance))
        assert bool(torch.isfinite(g_el)) and bool(torch.isfinite(g_r))
    distance = torch.tensor([0.5], dtype=torch.float64, requires_grad=True)
    assert gradcheck(lambda r: _kernel(math.pi / 2 - 1e-3, r), (distance,), eps=1e-4,
                     atol=1e-18, rtol=1e-4)


def test_dataset_render_refuses_a_gradient_it_cannot_carry():
    """A Dataset holds arrays: a flux or position that requires a gradient is refused.

    It was detached; as_dataset=False keeps the graph (tests above).
    """
    import pytest

    model = cached_model()
    flux = FLUX.clone().requires_grad_(True)
    with pytest.raises(ValueError, match="flux requires a gradient"):
        model.render(flux, x_m=X, y_m=Y)
    xy = torch.tensor([130.0, 270.0], dtype=torch.float64, requires_grad=True)
    with pytest.raises(ValueError, match="observer_xy requires a gradient"):
        model.render(FLUX, observer_xy=xy, x_m=X, y_m=Y)
