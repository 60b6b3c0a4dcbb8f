"""``skytorch stars``: netCDF output, all-sky chart, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from skytorch.cli import main
from skytorch.dataset import open_dataset

DATA = Path(__file__).parent / "data"


def test_stars_command_writes_netcdf_and_chart(tmp_path, capsys):
    output, png = tmp_path / "stars.nc", tmp_path / "chart.png"
    status = main(["stars", "--time", "2025-09-07T20:00", "--lat", "52.5", "--lon", "13.4",
                   "--limit-magnitude", "4.0", "-o", str(output), "--png", str(png)])
    assert status == 0
    assert png.stat().st_size > 10_000
    ds = open_dataset(output)
    assert ds.sizes["time"] == 1 and 400 < ds.sizes["star"] < 600
    assert ds.altitude.attrs["units"] == "degree"
    assert np.isfinite(ds.magnitude.values).all()
    assert "visible now" in capsys.readouterr().out


def test_stars_command_time_range_bsc5_without_atmosphere(tmp_path):
    output = tmp_path / "bsc.nc"
    status = main(["stars", "--start", "2025-01-01T00:00", "--end", "2025-01-01T01:00",
                   "--step", "30min", "--lat", "-30", "--lon", "-70", "--bsc5",
                   str(DATA / "bsc5_sample.dat"), "--no-atmosphere", "-o", str(output)])
    assert status == 0
    ds = open_dataset(output)
    assert ds.sizes["time"] == 3 and ds.sizes["star"] == 4  # the V = 7.1 record is cut
    assert np.allclose(ds.magnitude.values, ds.vmag.values[None, :])


def test_stars_command_errors(tmp_path, capsys):
    status = main(["stars", "--lat", "0", "--lon", "0", "-o", str(tmp_path / "x.nc")])
    assert status == 2
    assert "--time" in capsys.readouterr().err
    status = main(["stars", "--time", "2025-01-01", "--lat", "120", "--lon", "0",
                   "-o", str(tmp_path / "x.nc"), "--no-atmosphere"])
    assert status == 2
