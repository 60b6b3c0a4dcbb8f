"""The input contract of every public entry point, as one assertion for property tests.

Every call of a public function or method ends in exactly one of two ways:

* it returns a result whose numbers are all finite (tensors, arrays, Datasets, tuples and
  dicts of them are walked), or
* it raises ``ValueError`` or ``TypeError`` whose message names one of the parameters the
  caller passed (or one the entry point documents).

Anything else -- another exception type (``RuntimeError`` from torch, ``IndexError``,
``AttributeError``, ``KeyError``, ``NotImplementedError``), a NaN or inf in the result --
breaks the contract. Property tests (hypothesis) draw valid, hard and bad inputs and call
:func:`check_contract` on each; :func:`expect_rejected` is for inputs that must be refused.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping

import numpy as np
import torch
import xarray as xr

__all__ = ["ContractViolation", "all_finite", "arg", "call_and_check", "check_contract",
           "expect_rejected"]


class ContractViolation(AssertionError):
    """An entry point broke the input contract."""


def _numbers(value) -> Iterable[np.ndarray]:  # noqa: C901 (one branch per container type)
    if isinstance(value, torch.Tensor):
        if value.is_floating_point() or value.is_complex():
            yield value.detach().cpu().numpy()
    elif isinstance(value, np.ndarray):
        if np.issubdtype(value.dtype, np.floating) or np.issubdtype(value.dtype, np.complexfloating):
            yield value
    elif isinstance(value, float):
        yield np.asarray(value)
    elif isinstance(value, xr.Dataset):
        for variable in value.variables.values():
            yield from _numbers(np.asarray(variable.values))
    elif isinstance(value, xr.DataArray):
        yield from _numbers(np.asarray(value.values))
    elif isinstance(value, Mapping):
        for item in value.values():
            yield from _numbers(item)
    elif isinstance(value, (tuple, list)):
        for item in value:
            yield from _numbers(item)


def all_finite(value) -> bool:
    """Whether every floating number in ``value`` (walked recursively) is finite."""
    return all(bool(np.isfinite(array).all()) for array in _numbers(value))


def _names_a_parameter(message: str, names: Iterable[str]) -> bool:
    return any(name in message for name in names)


def check_contract(call: Callable[[], object], parameters: Iterable[str], *,
                   finite: bool = True):
    """Run ``call()`` and assert the contract; return the result, or the exception raised.

    Parameters
    ----------
    call : callable
        A zero-argument call of the entry point with the drawn inputs.
    parameters : iterable of str
        The parameter names a ``ValueError``/``TypeError`` may name.
    finite : bool
        Whether a returned result must be all finite (default True).
    """
    names = tuple(parameters)
    try:
        result = call()
    except (ValueError, TypeError) as error:
        if not _names_a_parameter(str(error), names):
            raise ContractViolation(
                f"{type(error).__name__} names none of {names}: {error}") from error
        return error
    except Exception as error:  # noqa: BLE001 - any other type is the violation itself
        raise ContractViolation(
            f"raised {type(error).__name__} instead of ValueError/TypeError: {error}"
        ) from error
    if finite and not all_finite(result):
        raise ContractViolation("returned a non-finite result")
    return result


def expect_rejected(call: Callable[[], object], parameters: Iterable[str]):
    """Assert that ``call()`` raises ValueError/TypeError naming one of ``parameters``."""
    outcome = check_contract(call, parameters, finite=False)
    if not isinstance(outcome, (ValueError, TypeError)):
        raise ContractViolation(f"accepted an invalid input (returned {type(outcome).__name__})")
    return outcome


def bad_values() -> list:
    """Values that no numeric parameter accepts: wrong types and non-finite numbers."""
    return ["3", None, object(), [1.0, "x"], math.nan, math.inf, -math.inf]


def arg(valid, bad=()):
    """Hypothesis strategy of ``(value, is_bad)`` pairs from lists of valid and bad values."""
    from hypothesis import strategies

    good = strategies.sampled_from(list(valid)).map(lambda v: (v, False))
    if not bad:
        return good
    return strategies.one_of(good, strategies.sampled_from(list(bad)).map(lambda v: (v, True)))


def _shape(value) -> tuple:
    try:
        return tuple(np.shape(value.detach().numpy() if isinstance(value, torch.Tensor)
                              else value))
    except (TypeError, ValueError):
        return ()


def call_and_check(function, arguments: dict, *, names=None, bad: bool = False,
                   misspelled: str | None = None, bounds=None, shape_arguments=(),
                   trailing: int = 0):
    """Call ``function(**values)`` for drawn ``arguments``: refused if bad, else accepted.

    Parameters
    ----------
    function : callable
        The entry point.
    arguments : dict
        ``name -> (value, is_bad)`` as drawn by :func:`arg`.
    names : iterable of str, optional
        Parameter names an error may name (default: the keys of ``arguments``).
    bad : bool
        The combination is bad although no single argument is.
    misspelled : str, optional
        Add this unknown keyword (the call must then be refused).
    bounds : (low, high), optional
        Every number of an accepted result must lie within.
    shape_arguments : iterable of str
        Arguments whose shapes (less ``trailing`` component dimensions) must broadcast; if
        they do not, the call must be refused.
    """
    values = {k: v for k, (v, _) in arguments.items()}
    bad = bad or any(flag for _, flag in arguments.values())
    names = tuple(names or arguments)
    if not bad and shape_arguments:
        shapes = [_shape(values[k]) for k in shape_arguments]
        if trailing:
            shapes = [s[:-trailing] if len(s) >= trailing else s for s in shapes]
        try:
            np.broadcast_shapes(*shapes)
        except ValueError:
            bad = True
    if misspelled is not None:
        values[misspelled] = 1.0
        names, bad = (*names, misspelled), True

    def outcome_call():
        return function(**values)

    if bad:
        return expect_rejected(outcome_call, names)
    result = check_contract(outcome_call, names)
    assert not isinstance(result, Exception), f"valid input rejected: {result}"
    if bounds is not None:
        low, high = bounds
        for values_out in (result if isinstance(result, tuple) else (result,)):
            values_out = torch.as_tensor(values_out)
            assert bool((values_out >= low).all()) and bool((values_out <= high).all()), (
                f"result outside [{low}, {high}]: {values_out}")
    return result
