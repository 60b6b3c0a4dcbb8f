"""Input checks shared by every skytorch module.

Each helper raises ``ValueError`` (bad value) or ``TypeError`` (bad type) with a message
that names the parameter, shows the offending value and states the valid range, so that a
user sweeping thousands of cases learns at once which input was wrong. The checks read
values with ``torch.no_grad`` semantics (they never modify or detach the tensor they
return), so validation does not break autograd.

Examples
--------
>>> import torch
>>> from skytorch._validate import check_range
>>> check_range("turbidity", torch.tensor([1.0, 2.0]), low=1.0)
tensor([1., 2.])
>>> check_range("turbidity", 0.5, low=1.0)
Traceback (most recent call last):
...
ValueError: turbidity must be >= 1.0; got 0.5
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np
import torch

__all__ = [
    "as_tensor",
    "broadcast_shape",
    "check_choice",
    "check_finite",
    "check_positive",
    "check_range",
    "check_shape_last",
    "check_zenith",
    "check_broadcastable",
    "check_int",
]


def _describe(value: torch.Tensor, mask: torch.Tensor | None = None, unit: str = "") -> str:
    """Short human description of (the offending part of) a tensor, its unit after the number."""
    if value.ndim == 0:
        return f"{value.item()!r}{unit}"
    if mask is not None and bool(mask.any()):
        index = tuple(int(i) for i in torch.nonzero(mask)[0])
        bad = value[index].item()
        count = int(mask.sum())
        return (f"{bad!r}{unit} at index {index} ({count} offending "
                f"element{'s' * (count > 1)})")
    return f"tensor of shape {tuple(value.shape)}"


def _holds_bool(value) -> bool:
    """Whether a list or tuple (nested) holds a bool."""
    if isinstance(value, (list, tuple)):
        return any(isinstance(v, (bool, np.bool_)) or _holds_bool(v) for v in value)
    return False


def as_tensor(
    name: str,
    value,
    dtype: torch.dtype | None = None,
    device: torch.device | str | None = None,
) -> torch.Tensor:
    """Convert ``value`` to a floating tensor, keeping tensors (and their graph) as they are.

    Parameters
    ----------
    name : str
        Parameter name used in error messages.
    value : float, sequence, numpy array or torch.Tensor
        The input.
    dtype : torch.dtype, optional
        Floating dtype for non-tensor inputs (default float64). Tensors that are already
        floating keep their dtype unless ``dtype`` is given.
    device : torch.device or str, optional
        Device for non-tensor inputs.

    Returns
    -------
    torch.Tensor
        A floating-point tensor.

    Raises
    ------
    TypeError
        If ``value`` is not numeric (strings, None, complex numbers, objects).
    """
    if isinstance(value, torch.Tensor):
        if value.is_complex() or value.dtype == torch.bool:
            raise TypeError(f"{name} must be a real floating-point tensor; got dtype {value.dtype}")
        if dtype is not None and value.dtype != dtype:
            return value.to(dtype)
        if not value.is_floating_point():
            return value.to(torch.get_default_dtype() if dtype is None else dtype)
        return value
    if value is None or isinstance(value, (str, bytes)):
        raise TypeError(f"{name} must be a number or an array of numbers; got {value!r}")
    if isinstance(value, (bool, np.bool_)) or (isinstance(value, np.ndarray)
                                               and value.dtype == np.bool_) or _holds_bool(value):
        # True is not the number 1 here: a flag passed where a quantity is expected
        raise TypeError(f"{name} must be a number or an array of numbers; got a bool "
                        f"{value!r:.40}")
    if isinstance(value, np.ndarray) and not value.flags.writeable:
        # a read-only array (e.g. pandas ``.values``) cannot be shared with a tensor
        value = value.copy()
    try:
        tensor = torch.as_tensor(value, dtype=dtype or torch.float64, device=device)
    except (TypeError, ValueError, RuntimeError) as error:
        raise TypeError(
            f"{name} must be a number or an array of numbers; got {type(value).__name__}: "
            f"{value!r:.80}"
        ) from error
    return tensor


def check_finite(name: str, value, dtype: torch.dtype | None = None) -> torch.Tensor:
    """Return ``value`` as a tensor, raising ``ValueError`` if any element is NaN or inf."""
    tensor = as_tensor(name, value, dtype=dtype)
    with torch.no_grad():
        bad = ~torch.isfinite(tensor)
        if bool(bad.any()):
            raise ValueError(f"{name} must be finite; got {_describe(tensor, bad)}")
    return tensor


def check_range(
    name: str,
    value,
    low: float | None = None,
    high: float | None = None,
    *,
    low_inclusive: bool = True,
    high_inclusive: bool = True,
    unit: str = "",
    dtype: torch.dtype | None = None,
) -> torch.Tensor:
    """Return ``value`` as a finite tensor within ``[low, high]`` (bounds optional).

    Parameters
    ----------
    name : str
        Parameter name used in error messages.
    value : array_like or torch.Tensor
        The input.
    low, high : float, optional
        Bounds; ``None`` means unbounded on that side.
    low_inclusive, high_inclusive : bool
        Whether the bounds themselves are allowed.
    unit : str
        Unit appended to the numbers in the message, e.g. ``" m"``.
    dtype : torch.dtype, optional
        Passed to :func:`as_tensor`.

    Raises
    ------
    ValueError
        Naming the parameter, the first offending value and the valid range.
    """
    tensor = check_finite(name, value, dtype=dtype)
    with torch.no_grad():
        bad = torch.zeros_like(tensor, dtype=torch.bool)
        if low is not None:
            bad |= (tensor < low) if low_inclusive else (tensor <= low)
        if high is not None:
            bad |= (tensor > high) if high_inclusive else (tensor >= high)
        if bool(bad.any()):
            raise ValueError(
                f"{name} must be {_range_text(low, high, low_inclusive, high_inclusive, unit)}; "
                f"got {_describe(tensor, bad, unit)}"
            )
    return tensor


def _range_text(low, high, low_inclusive, high_inclusive, unit) -> str:
    if low is not None and high is not None:
        left = "[" if low_inclusive else "("
        right = "]" if high_inclusive else ")"
        return f"in {left}{low}{unit}, {high}{unit}{right}"
    if low is not None:
        return f"{'>=' if low_inclusive else '>'} {low}{unit}"
    if high is not None:
        return f"{'<=' if high_inclusive else '<'} {high}{unit}"
    return "finite"


def input_eps(value, dtype) -> float:
    """Machine epsilon of an input: the coarser of its own floating dtype and ``dtype``."""
    eps = torch.finfo(dtype).eps
    if torch.is_tensor(value) and value.is_floating_point():
        return max(eps, torch.finfo(value.dtype).eps)
    if isinstance(value, np.ndarray) and np.issubdtype(value.dtype, np.floating):
        return max(eps, float(np.finfo(value.dtype).eps))
    return eps


def check_angle(name: str, value, high: float, dtype) -> torch.Tensor:
    """Check an angle in [0, high] [rad]; return it as a ``dtype`` tensor.

    The bound is that of the input's own precision: float32(pi) is 9e-8 above pi, and is
    pi (the value is brought to the bound it rounds).
    """
    slack = 4.0 * input_eps(value, dtype)
    angle = check_range(name, value, 0.0, high * (1.0 + slack), dtype=dtype)
    return torch.clamp(angle, max=high)


def check_zenith(value, *, name: str = "zenith_rad",
                 dtype: torch.dtype | None = None) -> torch.Tensor:
    """Return a zenith angle [rad] as a finite tensor within [-pi, pi].

    Only the cosine of a zenith angle enters the ray geometry, so a negative angle is the
    same ray mirrored through the zenith (and finite differences across 0 stay valid);
    beyond pi the number is no longer a zenith angle.

    >>> check_zenith(4.0)
    Traceback (most recent call last):
    ...
    ValueError: zenith_rad must be in [-3.141592653589793, 3.141592653589793]; got 4.0
    """
    return check_range(name, value, -math.pi, math.pi, dtype=dtype)


def check_positive(name: str, value, *, allow_zero: bool = False, unit: str = "",
                   dtype: torch.dtype | None = None) -> torch.Tensor:
    """Return ``value`` as a finite tensor that is > 0 (or >= 0 with ``allow_zero``)."""
    return check_range(name, value, low=0.0, low_inclusive=allow_zero, unit=unit, dtype=dtype)


def refuse_gradient(what: str, *, why: str = "its results are arrays of an xarray.Dataset",
                    **values) -> None:
    """Raise ValueError naming the inputs that require a gradient ``what`` cannot carry.

    ``values``: name -> a tensor, an ``nn.Module`` (its parameters and buffers) or anything
    else (ignored); ``why`` says why there is no gradient. Used by the entry points that
    return Datasets (their arrays hold no gradient) and by those that return classes: a
    gradient asked for is refused rather than detached.
    """
    wanted = []
    for name, value in values.items():
        if torch.is_tensor(value) and value.requires_grad:
            wanted.append(name)
        elif isinstance(value, torch.nn.Module):
            wanted += [f"{name}.{key}" for key, tensor in (*value.named_parameters(),
                                                          *value.named_buffers())
                       if tensor.requires_grad]
    if wanted:
        verb = "requires" if len(wanted) == 1 else "require"
        raise ValueError(f"{', '.join(wanted)} {verb} a gradient, which {what} does not "
                         f"carry ({why}): pass detached values")


def check_flag(name: str, value) -> bool:
    """Check a boolean option; strings such as "no", numbers and None are a ``TypeError``."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False; got {value!r:.60}")
    return bool(value)


def check_choice(name: str, value: str, choices: Sequence[str]) -> str:
    """Return ``value`` if it is one of ``choices``; otherwise list the valid names.

    >>> check_choice("method", "gauss", ("trapezoid", "gauss"))
    'gauss'
    """
    if not isinstance(value, str):
        raise TypeError(f"{name} must be a string, one of {tuple(choices)}; got {value!r}")
    if value not in choices:
        raise ValueError(f"{name} must be one of {tuple(choices)}; got {value!r}")
    return value


def check_int(name: str, value, low: int | None = None, high: int | None = None) -> int:
    """Return ``value`` as a Python int within ``[low, high]``.

    Booleans and floats with a fractional part are rejected with ``TypeError``.
    """
    if isinstance(value, bool) or not (
        isinstance(value, int)
        or (hasattr(value, "__index__"))
        or (isinstance(value, float) and math.isfinite(value) and value.is_integer())
    ):
        raise TypeError(f"{name} must be an integer; got {value!r}")
    number = int(value)
    if (low is not None and number < low) or (high is not None and number > high):
        raise ValueError(
            f"{name} must be an integer {_range_text(low, high, True, True, '')}; got {number}"
        )
    return number


def check_shape_last(name: str, value: torch.Tensor, size: int) -> torch.Tensor:
    """Require the trailing dimension of ``value`` to have ``size`` elements (e.g. 3-vectors)."""
    if value.ndim == 0 or value.shape[-1] != size:
        raise ValueError(
            f"{name} must have shape (..., {size}); got shape {tuple(value.shape)}"
        )
    return value


def broadcast_shape(*shapes) -> torch.Size:
    """Broadcast shape of ``shapes`` (``ValueError`` listing them if they do not broadcast).

    Same result as ``torch.broadcast_shapes``, whose first call imports torch's symbolic
    shape machinery and sympy (0.4 s per process).
    """
    try:
        return torch.Size(np.broadcast_shapes(*(tuple(shape) for shape in shapes)))
    except ValueError as error:
        listing = ", ".join(str(tuple(shape)) for shape in shapes)
        raise ValueError(f"shapes do not broadcast: {listing}") from error


def check_broadcastable(**tensors: torch.Tensor) -> torch.Size:
    """Return the broadcast shape of the named tensors or raise naming all their shapes."""
    shapes = {key: tuple(torch.as_tensor(t).shape) for key, t in tensors.items()}
    try:
        return broadcast_shape(*shapes.values())
    except ValueError as error:
        listing = ", ".join(f"{key} {shape}" for key, shape in shapes.items())
        raise ValueError(f"shapes do not broadcast: {listing}") from error


def common_dtype(*values, default: torch.dtype = torch.float64) -> torch.dtype:
    """Floating dtype of the first floating tensor among ``values`` (``default`` if none).

    Outputs follow their inputs' dtype: a float32 ray direction gives float32 results.
    """
    dtypes: Iterable[torch.dtype] = (
        v.dtype for v in values if isinstance(v, torch.Tensor) and v.is_floating_point()
    )
    candidates = list(dtypes)
    if not candidates:
        return default
    result = candidates[0]
    for dtype in candidates[1:]:
        result = torch.promote_types(result, dtype)
    return result
