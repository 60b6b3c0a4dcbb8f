"""The straight-ray accuracy-vs-cost experiment runs and its errors fall with the nodes."""

from __future__ import annotations

import sys
from pathlib import Path

import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import straight_ray_accuracy_cost  # noqa: E402


def test_straight_ray_experiment_quick(tmp_path):
    straight_ray_accuracy_cost.main(["--quick", "--output-dir", str(tmp_path)])
    assert (tmp_path / "straight_ray_accuracy_cost.png").stat().st_size > 0
    with xr.open_dataset(tmp_path / "straight_ray_accuracy_cost.nc") as dataset:
        error = dataset["max_abs_error_mag"].values
        assert dataset["max_abs_error_mag"].attrs["units"] == "mag"
    # Gauss-Legendre converges: 2 nodes per piece are worse than 6, 6 within 1e-5 mag
    assert error[0] > 100 * error[4]
    assert error[4] < 1e-5
