"""Property test of the input contract of build_dataset, to_netcdf and open_dataset."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
import xarray as xr
from _contract import check_contract, expect_rejected
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st_

from skytorch.dataset import (
    VariableSpec,
    build_dataset,
    coordinate,
    open_dataset,
    to_netcdf,
    variable,
)

SPEC = VariableSpec("1", "value", "A test value.")
values = st_.one_of(
    st_.lists(st_.floats(allow_nan=True, allow_infinity=False, width=64), min_size=1,
              max_size=5),
    st_.just(torch.tensor([1, 2, 3])),  # integers stay integers in a Dataset
    st_.just(np.array([1.5, -0.0], dtype=np.float32)),
    st_.just([[1.0, 2.0]]),
)
levels = st_.sampled_from([1, 4, 9, 0, 10, -3, 4.0, "4", None, True])
compress = st_.sampled_from([True, False, "yes", None, 1])


@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=values, level=levels, packed=compress)
def test_to_netcdf_contract(tmp_path, data, level, packed):
    array = np.asarray(data)
    dims = tuple(f"d{i}" for i in range(array.ndim))
    ds = build_dataset(
        {"v": variable(dims, array, SPEC)},
        {d: coordinate(d, np.arange(n), SPEC) for d, n in zip(dims, array.shape, strict=True)},
        title="contract")
    path = tmp_path / "x.nc"
    outcome = check_contract(
        lambda: to_netcdf(ds, path, compress=packed, compression_level=level),
        ("compress", "compression_level"), finite=False)
    if isinstance(outcome, (ValueError, TypeError)):
        return
    back = open_dataset(outcome)
    xr.testing.assert_identical(back, ds)  # NaN where NaN, bit for bit otherwise
    assert back["v"].values.tobytes() == ds["v"].values.tobytes()


def test_bad_arguments_are_refused(tmp_path):
    ds = build_dataset({"v": variable("d", [1.0], SPEC)}, {"d": coordinate("d", [0.0], SPEC)},
                       title="t")
    for call, names in [
        (lambda: to_netcdf(None, tmp_path / "x.nc"), ("dataset",)),
        (lambda: to_netcdf(ds["v"], tmp_path / "x.nc"), ("dataset",)),
        (lambda: to_netcdf(ds, None), ("path",)),
        (lambda: to_netcdf(ds, 3.0), ("path",)),
        (lambda: to_netcdf(ds, tmp_path / "x.nc", compression_level=math.nan),
         ("compression_level",)),
        (lambda: open_dataset(None), ("path",)),
        (lambda: build_dataset({"v": variable("d", [1.0], SPEC)}, {}, title="t"),
         ("coordinate",)),
        (lambda: variable(("a", "b"), [1.0], SPEC), ("dimensions",)),
        (lambda: variable("a", [1.0], {"units": "1"}), ("long_name",)),
    ]:
        expect_rejected(call, names)
    with pytest.raises(TypeError, match="unexpected keyword"):
        to_netcdf(ds, tmp_path / "x.nc", compresion=True)
