"""Gauss–Legendre quadrature shared by every integrator of skytorch.

One definition of the nodes and weights (NumPy's :func:`numpy.polynomial.legendre.leggauss`,
Golub–Welsch), mapped to the unit interval or to batched bounds. The NumPy nodes are cached
per node count (a bounded cache keyed by the integer; the arrays are read-only so that no
caller can change them for the others).

Examples
--------
>>> import torch
>>> from skytorch._quadrature import gauss_legendre, unit_nodes
>>> x, w = unit_nodes(3, torch.float64)
>>> round(float(w.sum()), 12)
1.0
>>> x, w = gauss_legendre(4, torch.tensor(0.0), torch.tensor(2.0))
>>> round(float((w * x**3).sum()), 12)  # exact for polynomials up to degree 7
4.0
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import torch

__all__ = ["MAX_NODES", "gauss_legendre", "legendre_signed", "legendre_unit", "unit_nodes"]

#: the largest node count accepted (leggauss stays accurate far beyond; a guard against
#: a node count taken from a corrupted setting)
MAX_NODES = 4096


def _check_nodes(n) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise TypeError(f"the number of Gauss-Legendre nodes must be an integer; got {n!r}")
    if not 1 <= int(n) <= MAX_NODES:
        raise ValueError(f"the number of Gauss-Legendre nodes must be in [1, {MAX_NODES}]; "
                         f"got {n}")
    return int(n)


@lru_cache(maxsize=64)
def _signed(n: int) -> tuple[np.ndarray, np.ndarray]:
    x, w = np.polynomial.legendre.leggauss(n)
    x.setflags(write=False)
    w.setflags(write=False)
    return x, w


@lru_cache(maxsize=64)
def _unit(n: int) -> tuple[np.ndarray, np.ndarray]:
    x, w = _signed(n)
    x, w = 0.5 * (x + 1.0), 0.5 * w
    x.setflags(write=False)
    w.setflags(write=False)
    return x, w


def legendre_signed(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre nodes and weights on [-1, 1] as read-only NumPy arrays.

    Parameters
    ----------
    n : int
        Number of nodes, in [1, :data:`MAX_NODES`].

    Returns
    -------
    nodes, weights : numpy.ndarray
        Shapes ``(n,)``; the weights sum to 2.
    """
    return _signed(_check_nodes(n))


def legendre_unit(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre nodes and weights on [0, 1] as read-only NumPy arrays.

    Parameters
    ----------
    n : int
        Number of nodes, in [1, :data:`MAX_NODES`].

    Returns
    -------
    nodes, weights : numpy.ndarray
        Shapes ``(n,)``; the weights sum to 1.
    """
    return _unit(_check_nodes(n))


def unit_nodes(n: int, dtype: torch.dtype = torch.float64, ndim: int = 0
               ) -> tuple[torch.Tensor, torch.Tensor]:
    """Gauss–Legendre nodes and weights on [0, 1] as tensors.

    Parameters
    ----------
    n : int
        Number of nodes, in [1, :data:`MAX_NODES`].
    dtype : torch.dtype
        Floating dtype of the result.
    ndim : int
        Number of trailing singleton dims: the result has shape ``(n, 1, ..., 1)`` so that
        it leads ``ndim`` batch dims.

    Returns
    -------
    nodes, weights : Tensor
    """
    x, w = legendre_unit(n)
    shape = (x.shape[0],) + (1,) * int(ndim)
    # torch.tensor copies: the cached arrays are read-only
    return (torch.tensor(x, dtype=dtype).reshape(shape),
            torch.tensor(w, dtype=dtype).reshape(shape))


def gauss_legendre(n: int, low, high, dtype: torch.dtype = torch.float64
                   ) -> tuple[torch.Tensor, torch.Tensor]:
    """Gauss–Legendre nodes and weights on [low, high] with batched bounds.

    Parameters
    ----------
    n : int
        Number of nodes, in [1, :data:`MAX_NODES`].
    low, high : float or Tensor
        Bounds of the interval (broadcast together); differentiable.
    dtype : torch.dtype
        Dtype of the result.

    Returns
    -------
    nodes, weights : Tensor
        Shape ``(*broadcast(low, high).shape, n)``; ``sum(weights * f(nodes))``
        approximates the integral of ``f`` from ``low`` to ``high``.
    """
    x, w = unit_nodes(n, dtype)
    low = torch.as_tensor(low, dtype=dtype)[..., None]
    high = torch.as_tensor(high, dtype=dtype)[..., None]
    span = high - low
    return low + span * x, span * w
