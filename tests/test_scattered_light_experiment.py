"""The scattered-airglow accuracy-vs-cost experiment runs and writes its files."""

from __future__ import annotations

import sys
from pathlib import Path

import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import scattered_light_accuracy_cost  # noqa: E402


def test_scattered_light_experiment_quick(tmp_path):
    scattered_light_accuracy_cost.main(["--quick", "--output-dir", str(tmp_path)])
    assert (tmp_path / "scattered_light_accuracy_cost.png").stat().st_size > 0
    with xr.open_dataset(tmp_path / "scattered_light_accuracy_cost.nc") as dataset:
        error = dict(zip(dataset.variant.values.tolist(), dataset.max_rel_error.values,
                         strict=True))
    # quick run: against the default nodes; the coarsest path and azimuth rules are
    # further from it than the next ones
    assert error["n_steps=8"] > error["n_steps=16"] > 0.0
    assert error["n_azimuth=2"] > 0.0
