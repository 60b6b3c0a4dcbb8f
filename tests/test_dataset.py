"""CF metadata and the lossless netCDF round trip."""

import json

import numpy as np
import pytest
import torch
import xarray as xr

import skytorch
from skytorch.dataset import (
    VariableSpec,
    build_dataset,
    coordinate,
    open_dataset,
    time_coordinate,
    to_netcdf,
    variable,
)

WAVELENGTH = VariableSpec("nm", "wavelength", "Vacuum wavelength.")
TAU = VariableSpec("1", "optical depth", "Slant optical depth.",
                   "atmosphere_optical_thickness_due_to_ambient_aerosol_particles")


def _example():
    times = np.array(["2015-09-28T02:47:00", "2016-12-31T23:59:59.123456789"], dtype="datetime64[ns]")
    tau = torch.rand(2, 3, dtype=torch.float64)
    return build_dataset(
        {"tau": variable(("time", "wavelength"), tau, TAU),
         "flag": variable("time", np.array([1, 0], dtype=np.int32),
                          VariableSpec("1", "flag", "An integer flag."))},
        {"time": time_coordinate(times),
         "wavelength": coordinate("wavelength", [440.0, 550.0, 680.0], WAVELENGTH)},
        title="round trip", references=["Bodhaine et al. 1999, doi:10.1175/..."],
        parameters={"turbidity": 2.0, "refraction": True, "ozone_du": torch.tensor([300.0]),
                    "method": "gauss", "nested": {"a": 1}},
    )


def test_global_attributes():
    ds = _example()
    assert ds.attrs["Conventions"] == "CF-1.10"
    assert ds.attrs["source"] == f"skytorch {skytorch.__version__}"
    for key in ("title", "history", "references"):
        assert ds.attrs[key]
    params = json.loads(ds.attrs["parameters"])
    assert params["turbidity"] == 2.0 and params["ozone_du"] == [300.0]
    assert ds.attrs["parameter_refraction"] == "True"
    for name in ds.variables:
        if name == "time":
            assert ds[name].attrs["standard_name"] == "time"
            continue
        assert {"units", "long_name", "description"} <= set(ds[name].attrs)


def test_netcdf_round_trip_is_exact(tmp_path):
    ds = _example()
    path = to_netcdf(ds, tmp_path / "sub" / "x.nc")
    back = open_dataset(path)
    assert back["tau"].dtype == np.float64
    np.testing.assert_array_equal(back["tau"].values, ds["tau"].values)
    np.testing.assert_array_equal(back["time"].values, ds["time"].values)
    np.testing.assert_array_equal(back["flag"].values, ds["flag"].values)
    for key in ("Conventions", "title", "parameters", "references"):
        assert back.attrs[key] == ds.attrs[key]
    assert back["tau"].attrs == ds["tau"].attrs


def test_dimension_without_coordinate_rejected():
    with pytest.raises(ValueError, match="without a coordinate"):
        build_dataset({"tau": variable(("x",), [1.0, 2.0], TAU)}, {}, title="t")


def test_interrupted_write_keeps_existing_file(tmp_path, monkeypatch):
    path = to_netcdf(_example(), tmp_path / "x.nc")
    before = path.read_bytes()

    def fail(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(xr.Dataset, "to_netcdf", fail)
    with pytest.raises(KeyboardInterrupt):
        to_netcdf(_example(), path)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["x.nc"]


def test_shape_mismatch_and_missing_metadata():
    with pytest.raises(ValueError, match="do not match"):
        variable(("a", "b"), [1.0, 2.0], TAU)
    with pytest.raises(ValueError, match="lacks"):
        variable(("a",), [1.0], {"units": "1"})
