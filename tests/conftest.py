"""Shared test configuration: tolerance units and dtype parametrisation."""

from __future__ import annotations

import matplotlib
import pytest
import torch
from hypothesis import settings

from skytorch.constants import ARCMINUTE, ARCSECOND, DEGREE, MAG, PERCENT  # noqa: F401

matplotlib.use("Agg")

# property tests draw the same examples on every machine and run: the suite is deterministic
settings.register_profile("deterministic", derandomize=True, database=None)
settings.load_profile("deterministic")

#: tolerance units for readable assertions: ``assert err < 2 * ARCSECOND``
__all__ = ["ARCMINUTE", "ARCSECOND", "DEGREE", "MAG", "PERCENT"]


@pytest.fixture(params=[torch.float64, torch.float32], ids=["float64", "float32"])
def dtype(request):
    """Run a hard-case test in both float64 and float32."""
    return request.param
