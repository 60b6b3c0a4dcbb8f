"""The eclipse-sky second-order accuracy-vs-cost experiment runs and converges."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import eclipse_sky_second_order_accuracy_cost as experiment  # noqa: E402


def test_eclipse_sky_second_order_experiment_quick(tmp_path):
    experiment.main(["--quick", "--output-dir", str(tmp_path)])
    stem = "eclipse_sky_second_order_accuracy_cost"
    assert (tmp_path / f"{stem}.png").stat().st_size > 0
    with xr.open_dataset(tmp_path / f"{stem}.nc") as dataset:
        error = np.abs(dataset["relative_error"])
        grid = dataset["grid_error"].sel(statistic="median").values
        along_sight = np.abs(dataset["n_view_relative_error"]).max("line_of_sight")
        along_rays = np.abs(dataset["n_samples_relative_error"]).max("line_of_sight")
        assert dataset["second_order"].attrs["units"] == "sr-1"
    # 2 direction cosines per hemisphere and 8 azimuths miss most of the light from the
    # sunlit ring around the umbra; the default quadrature is within 15 % of the finest
    assert float(error.isel(quadrature=0).max()) > 0.5
    assert float(error.sel(quadrature="16/4/16/16").max()) < 0.15
    # each dimension converges: the error shrinks as it is refined
    assert float(along_sight.sel(n_view=16)) < float(along_sight.sel(n_view=8))
    assert float(along_rays.sel(n_samples=16)) < float(along_rays.sel(n_samples=6))
    # the finer grid and the log look-up both shrink the look-up error
    assert grid[1, 1] < grid[0, 1] and grid[1, 1] < grid[1, 0]
