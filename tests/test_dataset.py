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
    to_zarr,
    variable,
    write_dataset,
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


# --- Zarr -------------------------------------------------------------------------------------

def _example_with_labels():
    ds = _example()
    labels = VariableSpec("1", "model", "Name of the model variant.")
    return ds.assign_coords(model=coordinate("model", np.array(["bodhaine1999", "peck"]), labels))


def test_zarr_round_trip_is_exact(tmp_path):
    pytest.importorskip("zarr")
    ds = _example_with_labels()
    path = to_zarr(ds, tmp_path / "sub" / "x.zarr")
    assert path.is_dir()
    back = open_dataset(path)
    # identical: values (float64 bit for bit, int32, ns datetimes, strings), dims, coords
    # and every variable and global attribute
    xr.testing.assert_identical(back, ds)
    assert back["tau"].dtype == np.float64 and back["flag"].dtype == np.int32
    assert back["time"].dtype == np.dtype("datetime64[ns]")
    np.testing.assert_array_equal(back["time"].values.astype("int64"),
                                  ds["time"].values.astype("int64"))  # .123456789 s kept
    assert back["model"].values.tolist() == ["bodhaine1999", "peck"]
    assert json.loads(back.attrs["parameters"]) == json.loads(ds.attrs["parameters"])
    # a plain xarray reader sees the same (no skytorch-specific decoding needed)
    with xr.open_zarr(path) as plain:
        np.testing.assert_array_equal(plain["tau"].values, ds["tau"].values)


def test_write_dataset_chooses_format_by_suffix(tmp_path):
    pytest.importorskip("zarr")
    ds = _example()
    nc = write_dataset(ds, tmp_path / "x.nc")
    store = write_dataset(ds, tmp_path / "x.ZARR")
    assert nc.is_file() and nc.read_bytes()[:4] == b"\x89HDF"  # netCDF-4 is HDF5
    assert store.is_dir() and (store / ".zmetadata").is_file()  # Zarr v2, consolidated
    xr.testing.assert_identical(open_dataset(store), ds)
    # netCDF reads a one-element attribute array back as a scalar; values are the same
    xr.testing.assert_equal(open_dataset(nc), ds)


def test_zarr_overwrite_and_interrupted_write(tmp_path, monkeypatch):
    pytest.importorskip("zarr")
    first, second = _example(), _example()
    path = to_zarr(first, tmp_path / "x.zarr")
    to_zarr(second, path)  # replaces the store
    np.testing.assert_array_equal(open_dataset(path)["tau"].values, second["tau"].values)
    assert [p.name for p in tmp_path.iterdir()] == ["x.zarr"]

    def fail(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(xr.Dataset, "to_zarr", fail)
    with pytest.raises(KeyboardInterrupt):
        to_zarr(first, path)
    np.testing.assert_array_equal(open_dataset(path)["tau"].values, second["tau"].values)
    assert [p.name for p in tmp_path.iterdir()] == ["x.zarr"]  # no temporary left


def test_zarr_missing_names_the_extra(tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "zarr", None)  # makes `import zarr` fail
    with pytest.raises(ImportError, match=r"skytorch\[zarr\]"):
        to_zarr(_example(), tmp_path / "x.zarr")
    with pytest.raises(ImportError, match=r"skytorch\[zarr\]"):
        write_dataset(_example(), tmp_path / "y.zarr")
    with pytest.raises(ImportError, match=r"skytorch\[zarr\]"):
        open_dataset(tmp_path / "y.zarr")
    assert list(tmp_path.iterdir()) == []
    write_dataset(_example(), tmp_path / "x.nc")  # netCDF needs nothing optional
