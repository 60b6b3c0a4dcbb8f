"""The light-curve retrieval of 2019-01-21 runs and fits its samples.

Reference: the published SSP-3 photometry of the 2019-01-21 eclipse (Georgia Journal of
Science 80(1) art. 32; ``tests/data/lunar_eclipse_2019_01_21_photometry.csv``). The quick
run fits the stratospheric AOD to the three V samples (coarse model, table 32).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import lunar_eclipse_light_curve_retrieval as experiment  # noqa: E402


def test_light_curve_retrieval_experiment_quick(tmp_path):
    """The fit's V residuals are smaller than the prior's (least squares in V).

    Measured (quick): prior V rms 0.26 mag, fitted 0.15 mag, stratospheric AOD
    0.013 ± 0.001 (the 2019 record: 0.009).
    """
    experiment.main(["--quick", "--output-dir", str(tmp_path)])
    stem = "lunar_eclipse_light_curve_retrieval"
    assert (tmp_path / f"{stem}.png").stat().st_size > 0
    with xr.open_dataset(tmp_path / f"{stem}.nc") as dataset:
        v = dataset.band.values == "V"
        fitted = dataset.residual.isel(fit=0).values[v]
        prior = dataset.prior_residual.values[v]
        depth = float(dataset.best_fit.isel(fit=0).sel(parameter="stratospheric_aod_550"))
    assert np.sqrt(np.mean(fitted ** 2)) < np.sqrt(np.mean(prior ** 2))
    assert 0.0 < depth < 0.1
