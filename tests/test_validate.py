"""Input validation: clear errors naming parameter, value and range; autograd intact."""

import math

import numpy as np
import pytest
import torch

from skytorch._validate import (
    as_tensor,
    check_broadcastable,
    check_choice,
    check_finite,
    check_int,
    check_positive,
    check_range,
    common_dtype,
)


def test_range_message_names_parameter_value_and_range():
    with pytest.raises(ValueError, match=r"turbidity must be >= 1.0; got 0.5"):
        check_range("turbidity", 0.5, low=1.0)
    with pytest.raises(ValueError, match=r"lat_deg must be in \[-90.0, 90.0\]; got 91.0 at index \(1,\)"):
        check_range("lat_deg", [10.0, 91.0], -90.0, 90.0)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_rejected(bad):
    with pytest.raises(ValueError, match="ozone_du must be finite"):
        check_finite("ozone_du", torch.tensor([1.0, bad]))


def test_types_rejected():
    for bad in ("3", None, b"x", object()):
        with pytest.raises(TypeError, match="altitude_m"):
            as_tensor("altitude_m", bad)
    with pytest.raises(TypeError):
        as_tensor("x", torch.tensor([1 + 1j]))


def test_exclusive_bounds_and_positive():
    with pytest.raises(ValueError, match=r"> 0.0"):
        check_positive("scale_height_m", 0.0)
    assert float(check_positive("scale_height_m", 0.0, allow_zero=True)) == 0.0
    with pytest.raises(ValueError, match=r"in \(0.0, 1.0\)"):
        check_range("u", 1.0, 0.0, 1.0, low_inclusive=False, high_inclusive=False)


def test_validation_keeps_autograd():
    x = torch.tensor([2.0, 3.0], requires_grad=True)
    y = check_range("x", x, low=0.0)
    assert y is x
    (y**2).sum().backward()
    assert torch.equal(x.grad, torch.tensor([4.0, 6.0]))


def test_dtype_follows_input():
    assert check_finite("x", torch.tensor([1.0], dtype=torch.float32)).dtype == torch.float32
    assert check_finite("x", [1.0]).dtype == torch.float64
    assert check_finite("x", torch.tensor([1])).is_floating_point()
    assert common_dtype(torch.zeros(1, dtype=torch.float32), 3.0) == torch.float32
    assert common_dtype(1.0) == torch.float64


def test_choice_int_and_shapes():
    assert check_choice("method", "gauss", ("gauss", "trapezoid")) == "gauss"
    with pytest.raises(ValueError, match=r"method must be one of \('gauss', 'trapezoid'\); got 'simpson'"):
        check_choice("method", "simpson", ("gauss", "trapezoid"))
    with pytest.raises(TypeError):
        check_choice("method", 3, ("gauss",))
    assert check_int("n_steps", 4.0, low=1) == 4
    with pytest.raises(TypeError):
        check_int("n_steps", 2.5)
    with pytest.raises(TypeError):
        check_int("n_steps", True)
    with pytest.raises(ValueError, match=r"n_steps must be an integer >= 1; got 0"):
        check_int("n_steps", 0, low=1)
    assert check_broadcastable(a=torch.zeros(5, 1), b=torch.zeros(1, 4)) == torch.Size([5, 4])
    with pytest.raises(ValueError, match=r"a \(3,\), b \(4,\)"):
        check_broadcastable(a=torch.zeros(3), b=torch.zeros(4))


def test_as_tensor_accepts_read_only_arrays_without_warning():
    """A read-only NumPy array (pandas ``.values``) converts without a torch warning."""
    import warnings

    values = np.arange(4.0)
    values.setflags(write=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tensor = as_tensor("x", values)
    assert tensor.tolist() == [0.0, 1.0, 2.0, 3.0]
