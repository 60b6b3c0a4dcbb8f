"""Angles wrapped to one turn.

``torch.remainder(x, p)`` of a tiny negative ``x`` rounds to ``p`` itself (the sum ``p + x``
is ``p`` in floating point): a "[0, 2π)" azimuth of exactly 2π, or a table column one past
the last. :func:`wrap_to_turn` maps that case to 0.
"""

from __future__ import annotations

import torch

__all__ = ["wrap_to_turn"]


def wrap_to_turn(angle: torch.Tensor, turn: float) -> torch.Tensor:
    """Return ``angle`` modulo ``turn`` in [0, turn) (``turn``: 2π [rad] or 360 [degree]).

    Examples
    --------
    >>> import math
    >>> float(wrap_to_turn(torch.tensor(-1e-20, dtype=torch.float64), 2 * math.pi))
    0.0
    """
    wrapped = torch.remainder(angle, turn)
    return torch.where(wrapped >= turn, wrapped - turn, wrapped)
