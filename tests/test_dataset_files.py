"""netCDF files others can read: permissions, lossless compression, exact round trip, CF."""

from __future__ import annotations

import contextlib
import os
import stat

import numpy as np
import pytest
import xarray as xr

import skytorch as st
from skytorch.dataset import (
    VariableSpec,
    build_dataset,
    coordinate,
    open_dataset,
    time_coordinate,
    to_netcdf,
    to_zarr,
    variable,
)

RADIANCE = VariableSpec("W m-2 sr-1 nm-1", "spectral radiance", "Sky spectral radiance.")
WAVELENGTH = VariableSpec("nm", "wavelength", "Vacuum wavelength.")
AXIS = VariableSpec("1", "image coordinate", "Position in the all-sky image, -1 to 1.")


@contextlib.contextmanager
def umask(mask: int):
    previous = os.umask(mask)
    try:
        yield
    finally:
        os.umask(previous)


def mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


def render_like(size: int = 256, n_wavelength: int = 8) -> xr.Dataset:
    """Make a float64 all-sky render: a smooth sky over the disc, exact zeros outside it."""
    axis = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    x, y = np.meshgrid(axis, axis[::-1])
    r = np.hypot(x, y)
    wavelength = np.linspace(400.0, 700.0, n_wavelength)
    zenith = r[..., None] * np.pi / 2
    sky = 1e-3 * (wavelength / 550.0) ** -4 * (1.0 + 2.0 * zenith**2) * np.exp(
        -0.3 / np.maximum(np.cos(zenith), 0.05))
    sky = np.where(r[..., None] <= 1.0, sky, 0.0)
    return build_dataset(
        {"radiance": variable(("y", "x", "wavelength"), sky, RADIANCE),
         "luminance": variable(("y", "x"), 683.0 * sky.sum(-1),
                               VariableSpec("cd m-2", "luminance", "Photopic luminance."))},
        {"y": coordinate("y", axis[::-1], AXIS), "x": coordinate("x", axis, AXIS),
         "wavelength": coordinate("wavelength", wavelength, WAVELENGTH)},
        title="render-like all-sky image", parameters={"size": size},
        references=["Preetham, Shirley & Smits 1999, doi:10.1145/311535.311545"])


def mixed() -> xr.Dataset:
    """Every dtype a skytorch Dataset holds, with values that test bit exactness."""
    rng = np.random.default_rng(12)
    times = np.array(["2015-09-28T02:47:00", "2016-12-31T23:59:59.123456789",
                      "1999-08-11T11:03:00"], dtype="datetime64[ns]")
    observers = np.array(["Berlin (Tempelhof)", "Ulm", "Zürich – Üetliberg"], dtype=object)
    ds = build_dataset(
        {"f64": variable(("time", "k"), rng.standard_normal((3, 5)) * 1e-300, RADIANCE),
         "f32": variable(("time", "k"), rng.standard_normal((3, 5)).astype(np.float32),
                         RADIANCE),
         "extremes": variable("k", np.array([np.finfo(float).tiny, -0.0, 5e-324,
                                             np.finfo(float).max, np.nan]), RADIANCE),
         "count": variable("time", np.array([1, -2, 2**40]), VariableSpec("1", "count")),
         "effects_computed": variable("observer", np.array(["moon,stars", "moon", ""],
                                                          dtype=object),
                                      VariableSpec("1", "effects computed"))},
        {"time": time_coordinate(times), "k": coordinate("k", np.arange(5), AXIS),
         "observer": coordinate("observer", observers, VariableSpec("1", "observer name"))},
        title="mixed types", parameters={"label": "ä ö ü", "turbidity": 2.5},
        references=["none: a test Dataset"],
        effects_skipped="sky: below 1e-3 of the image; skyglow: no city")
    ds.attrs["observers"] = "Berlin; Ulm"
    return ds


@pytest.mark.parametrize(("mask", "expected"), [(0o022, 0o644), (0o077, 0o600),
                                                (0o002, 0o664)])
def test_new_file_mode_follows_umask(tmp_path, mask, expected):
    with umask(mask):
        path = to_netcdf(mixed(), tmp_path / "x.nc")
        with open(tmp_path / "plain", "w"):  # what open() gives, the reference
            pass
    assert mode(tmp_path / "plain") == expected
    assert mode(path) == expected
    assert [p.name for p in sorted(tmp_path.iterdir())] == ["plain", "x.nc"]  # no temporary


def test_overwrite_keeps_the_file_mode(tmp_path):
    path = to_netcdf(mixed(), tmp_path / "x.nc")
    os.chmod(path, 0o640)
    with umask(0o077):
        to_netcdf(render_like(16), path)
    assert mode(path) == 0o640  # as open(path, "w") keeps the mode of the file it truncates
    assert "radiance" in open_dataset(path)


def test_zarr_store_mode_follows_umask(tmp_path):
    pytest.importorskip("zarr")
    with umask(0o022):
        store = to_zarr(mixed(), tmp_path / "x.zarr")
    assert mode(store) == 0o755
    assert all(mode(p) == 0o644 for p in store.rglob("*") if p.is_file())


def test_round_trip_is_exact_with_and_without_compression(tmp_path):
    ds = mixed()
    for compress in (True, False):
        back = open_dataset(to_netcdf(ds, tmp_path / f"{compress}.nc", compress=compress))
        xr.testing.assert_identical(back, ds)
        for name in ("f64", "f32", "extremes", "count"):
            assert back[name].dtype == ds[name].dtype
            # bit for bit (NaN, -0.0 and subnormals included)
            assert back[name].values.tobytes() == ds[name].values.tobytes()
        assert back["time"].dtype == np.dtype("datetime64[ns]")
        assert back["time"].values.view("int64").tolist() == ds["time"].values.view(
            "int64").tolist()
        assert back["observer"].values.tolist() == ds["observer"].values.tolist()
        assert back["effects_computed"].values.tolist() == ["moon,stars", "moon", ""]
        assert back.attrs == ds.attrs
        assert back["f64"].encoding["zlib"] is False  # 120 bytes: not worth a chunk index


def test_rewriting_a_read_dataset_uses_the_new_options(tmp_path):
    first = to_netcdf(render_like(32), tmp_path / "a.nc", compress=False)
    again = to_netcdf(open_dataset(first), tmp_path / "b.nc")  # encodings of a.nc ignored
    assert open_dataset(again)["radiance"].encoding["zlib"] is True
    xr.testing.assert_identical(open_dataset(again), open_dataset(first))


def test_compression_shrinks_a_render(tmp_path):
    ds = render_like(256)
    raw = to_netcdf(ds, tmp_path / "raw.nc", compress=False).stat().st_size
    packed = to_netcdf(ds, tmp_path / "packed.nc").stat().st_size
    best = to_netcdf(ds, tmp_path / "best.nc", compression_level=9).stat().st_size
    # uncompressed: the array bytes plus HDF5 overhead
    assert raw >= ds["radiance"].nbytes + ds["luminance"].nbytes
    ratio = raw / packed
    print(f"256x256x8 float64 render-like: {raw} B raw, {packed} B zlib-4 "
          f"({ratio:.2f}x), {best} B zlib-9 ({raw / best:.2f}x)")
    assert ratio > 1.5  # lossless; the zeros outside the disc and the exponents compress
    assert best <= packed
    xr.testing.assert_identical(open_dataset(tmp_path / "packed.nc"), ds)


def test_bad_options_are_refused(tmp_path):
    ds = render_like(8)
    for level in (0, 10, -1):
        with pytest.raises(ValueError, match="compression_level"):
            to_netcdf(ds, tmp_path / "x.nc", compression_level=level)
    for level in (4.0, "4", None, True):
        with pytest.raises(TypeError, match="compression_level"):
            to_netcdf(ds, tmp_path / "x.nc", compression_level=level)
    for compress in ("yes", 1, None):
        with pytest.raises(TypeError, match="compress"):
            to_netcdf(ds, tmp_path / "x.nc", compress=compress)
    with pytest.raises(TypeError, match="dataset"):
        to_netcdf(ds["radiance"], tmp_path / "x.nc")
    with pytest.raises(TypeError, match="path"):
        to_netcdf(ds, 3)
    (tmp_path / "folder").mkdir()
    with pytest.raises(ValueError, match="is a directory"):
        to_netcdf(ds, tmp_path / "folder")
    (tmp_path / "folder").rmdir()
    with pytest.raises(TypeError, match="unexpected keyword"):
        to_netcdf(ds, tmp_path / "x.nc", compresion_level=3)
    assert list(tmp_path.iterdir()) == []


# --- CF check ------------------------------------------------------------------------------
#
# cfchecker needs the UDUNITS-2 C library and downloads the CF tables, so the suite uses
# cf_xarray (pure Python, a test dependency): its UDUNITS unit registry (pint) must parse
# every units attribute, and its CF decoder must find the time axis and the standard names.

def _cf_datasets():
    return {
        "render-like": render_like(32),
        "mixed": mixed(),
        "ephemeris": st.ephemeris.sun_moon(["2024-06-20T20:51Z", "2024-06-21T00:00Z"],
                                           lat_deg=52.5, lon_deg=13.4),
        "sweep": st.sweep(lambda turbidity, wavelength_nm: turbidity * wavelength_nm,
                          progress=False, turbidity=[1.0, 2.0], wavelength_nm=[440.0, 550.0]),
    }


@pytest.mark.parametrize("name", ["render-like", "mixed", "ephemeris", "sweep"])
def test_files_pass_cf_checks(tmp_path, name):
    cf_xarray = pytest.importorskip("cf_xarray")
    pytest.importorskip("pint")
    import netCDF4
    from cf_xarray.units import units as udunits

    if "DU" not in udunits:  # UDUNITS-2 defines it (udunits2-common.xml); cf_xarray lacks it
        udunits.define("dobson = 446.2e-6 * mole / meter ** 2 = DU")
    ds = _cf_datasets()[name]
    path = to_netcdf(ds, tmp_path / f"{name}.nc")
    with netCDF4.Dataset(path) as raw:  # the file as any netCDF reader sees it
        assert raw.Conventions == "CF-1.10"
        for attribute in ("title", "source", "history", "references"):
            assert getattr(raw, attribute)
        for var in raw.variables.values():
            if var.dtype is str:
                continue
            assert "units" in var.ncattrs(), var.name
            units = var.units
            if " since " in units:  # a time coordinate: a UDUNITS time unit and an epoch
                step, epoch = units.split(" since ")
                assert step in ("seconds", "milliseconds", "microseconds", "nanoseconds")
                np.datetime64(epoch)
                if name != "mixed":  # whole seconds: a unit UDUNITS (and cfunits) knows
                    assert step == "seconds"
                continue
            udunits.parse_units(units)
    back = open_dataset(path)
    assert cf_xarray.__version__
    cf = back.cf
    if "time" in back.dims:
        assert cf.axes["T"] == ["time"]
        assert cf.standard_names["time"] == ["time"]
    for var_name, var in back.variables.items():
        standard_name = var.attrs.get("standard_name")
        if standard_name:
            assert var_name in cf.standard_names[standard_name]
