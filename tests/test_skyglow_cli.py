"""``skytorch skyglow`` command line."""

from __future__ import annotations

import pytest
from _skyglow_standin import single_torch_thread  # noqa: F401

from skytorch.cli import main
from skytorch.dataset import open_dataset

SMALL = ["--n-azimuth", "16", "--n-elevation", "4", "--n-distance", "6", "--components", "4",
         "--steps", "4", "--no-progress"]


def test_skyglow_command_synthetic_city(tmp_path, capsys):
    out, png, model = tmp_path / "sky.nc", tmp_path / "sky.png", tmp_path / "model.nc"
    status = main(["skyglow", "--synthetic", "--lat", "43.6", "--lon", "1.44", "-o", str(out),
                   "--png", str(png), "--save-model", str(model), *SMALL])
    assert status == 0
    ds = open_dataset(out)
    assert ds["radiance"].dims == ("elevation", "azimuth", "wavelength")
    assert ds.attrs["observer_lat_deg"] == pytest.approx(43.6)
    # the observer stands in the city centre: the sky is brighter than natural
    assert float(ds["total_brightness"].max()) < 22.0
    assert png.stat().st_size > 0 and "mag/arcsec^2" in capsys.readouterr().out
    # reuse the saved model on a light map file
    lights = tmp_path / "lights.nc"
    from skytorch.dataset import to_netcdf
    from skytorch.skyglow.citymap import synthetic_city

    to_netcdf(synthetic_city(20_000.0, 1_000.0), lights)
    again = tmp_path / "again.nc"
    assert main(["skyglow", "--lights", str(lights), "--model", str(model), "-o", str(again),
                 "--observer-x", "5000"]) == 0
    assert open_dataset(again)["luminance"].shape == (4, 16)
    # a built model's settings with --model were ignored (turbidity 5 drew turbidity 2)
    capsys.readouterr()
    assert main(["skyglow", "--lights", str(lights), "--model", str(model), "-o", str(again),
                 "--turbidity", "5"]) == 2
    assert "--turbidity: settings of a model to build" in capsys.readouterr().err
    assert main(["skyglow", "--synthetic", "--lat", "200", "-o", str(again), *SMALL]) == 2
    assert "--lat must be in [-90.0 degree, 90.0 degree]" in capsys.readouterr().err
    # the command's models have one observer-altitude node: another altitude drew the
    # ground's sky with a warning; --save-model with --model wrote nothing
    assert main(["skyglow", "--synthetic", "--observer-altitude", "800", "-o", str(again),
                 *SMALL]) == 2
    assert "--observer-altitude must be 0 m" in capsys.readouterr().err
    assert main(["skyglow", "--lights", str(lights), "--model", str(model), "-o", str(again),
                 "--observer-altitude", "800"]) == 2
    assert "observer altitudes [0, 0] m; got 800 m" in capsys.readouterr().err
    assert main(["skyglow", "--lights", str(lights), "--model", str(model), "-o", str(again),
                 "--save-model", str(tmp_path / "copy.nc")]) == 2
    assert "--save-model" in capsys.readouterr().err and not (tmp_path / "copy.nc").exists()


def test_skyglow_command_reports_bad_map(tmp_path, capsys):
    import numpy as np
    import xarray as xr

    bad = tmp_path / "bad.nc"
    xr.Dataset({"flux": (("y", "x"), np.array([[1.0, -5.0]]))},
               coords={"x": [0.0, 100.0], "y": [0.0]}).to_netcdf(bad)
    status = main(["skyglow", "--lights", str(bad), "-o", str(tmp_path / "o.nc"), *SMALL])
    assert status == 2
    assert "non-negative" in capsys.readouterr().err


def test_skyglow_command_float32_kernel_matches_float64(tmp_path):
    # the float32 kernel (PCA in float64) against the default float64 kernel, same grid
    outputs = {}
    for dtype in ("float64", "float32"):
        out, model = tmp_path / f"sky_{dtype}.nc", tmp_path / f"model_{dtype}.nc"
        assert main(["skyglow", "--synthetic", "-o", str(out), "--save-model", str(model),
                     "--kernel-dtype", dtype, *SMALL]) == 0
        assert open_dataset(model).attrs["parameters"].count(f'"compute_dtype": "{dtype}"') == 1
        outputs[dtype] = open_dataset(out)["luminance"].values
    relative = abs(outputs["float32"] - outputs["float64"]) / outputs["float64"]
    assert relative.max() < 1e-3  # 0.1 %, as the kernel test's float32 tolerance
