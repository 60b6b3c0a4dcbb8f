"""Buffers reused by the chunks of a loop (:class:`Scratch`).

Examples
--------
>>> import torch
>>> scratch = Scratch()
>>> scratch("x", (2, 3), torch.float32).shape
torch.Size([2, 3])
"""

from __future__ import annotations

import math

import torch


class Scratch:
    """Named buffers reused by every chunk of one loop (one object per call, not shared).

    A loop over chunks that allocates its temporaries afresh gets memory that the C
    allocator may have returned to the system after the previous chunk, and pays the
    first-write page faults again, chunk after chunk. Passing ``out=scratch(name, shape,
    dtype)`` to the torch operations of the loop writes into the same memory every time.

    Parameters
    ----------
    enabled : bool
        ``False`` makes every request return ``None``, so that ``out=None`` allocates as
        usual: the path for tensors that record gradients (``out=`` does not).

    Examples
    --------
    >>> import torch
    >>> scratch = Scratch()
    >>> a = scratch("x", (2, 3), torch.float64)
    >>> b = scratch("x", (1, 3), torch.float64)
    >>> a.data_ptr() == b.data_ptr()
    True
    >>> Scratch(enabled=False)("x", (2, 3), torch.float64) is None
    True
    """

    def __init__(self, enabled: bool = True):
        self.enabled = bool(enabled)
        self._buffers: dict[str, torch.Tensor] = {}

    def __call__(self, name: str, shape: tuple[int, ...], dtype: torch.dtype
                 ) -> torch.Tensor | None:
        """Return the buffer ``name`` viewed as ``shape`` (``None`` when not enabled)."""
        if not self.enabled:
            return None
        numel = math.prod(shape)
        buffer = self._buffers.get(name)
        if buffer is None or buffer.numel() < numel or buffer.dtype != dtype:
            buffer = torch.empty(numel, dtype=dtype)
            self._buffers[name] = buffer
        return buffer[:numel].view(shape)
