"""The presets' table-knob accuracy-vs-cost experiment runs end to end in --quick mode."""

from __future__ import annotations

import numpy as np

from experiments import preset_tables_accuracy_cost as experiment
from skytorch.constants import PERCENT
from skytorch.dataset import open_dataset


def test_experiment_quick(tmp_path):
    """The default preset's tables of before and since 2026-12-07, molecules alone.

    Against the Monte-Carlo (Sun 30-98 deg) the present tables are within 6 % at every
    Sun (measured 2.2 / 1.8 / 1.8 / 2.2 / 4.5 / 5.6 %; before 4.9 / 4.4 / 4.4 / 4.8 / 4.2 /
    6.3 %); against the quick run's converged solver (16 radii, 48 view and 32 Sun-zenith
    nodes) their orders >= 2 are nearer at every Sun from 98 to 108 deg (measured 6.9 /
    12.3 / 13.8 / 25.9 / 27.7 / 42.2 % against 26.4 / 40.4 / 54.1 / 80.3 / 137 / 252 %).
    """
    assert experiment.main(["--quick", "--output-dir", str(tmp_path)]) == 0
    ds = open_dataset(tmp_path / "preset_tables_accuracy_cost.nc")
    assert (tmp_path / "preset_tables_accuracy_cost.png").stat().st_size > 0
    assert ds["error_montecarlo"].shape == (1, 2, 6, 2)
    assert ds["error_converged"].shape == (1, 2, 7, 2)
    worst = ds["error_montecarlo"].sel(case="rayleigh", statistic="max over decided views")
    assert float(worst.isel(tables=1).max()) < 6 * PERCENT
    deep = ds["error_converged"].sel(case="rayleigh", statistic_converged="max over views",
                                     sun_zenith_twilight=slice(98.0, 108.0))
    assert bool((deep.isel(tables=1) < deep.isel(tables=0)).all())
    assert np.isfinite(ds["error_montecarlo"].values).all()
    assert bool((ds["build_seconds"] > 0).all())
