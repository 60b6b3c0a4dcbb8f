"""The stopping-rule experiment of the converged orders runs end to end in --quick mode."""

from __future__ import annotations

import numpy as np

from experiments import converged_orders_accuracy_cost as experiment
from skytorch.dataset import open_dataset


def test_experiment_quick(tmp_path):
    """Turbidity 1.5 over a black ground on the fast preset's tables, 2 wavelengths.

    The reference series is converged (last order below 1e-7 of its sum); the present
    rule is within 1e-3 of it at every Sun zenith and nearer to it than the former rule
    at the deepest twilight (Sun 108 deg).
    """
    assert experiment.main(["--quick", "--output-dir", str(tmp_path)]) == 0
    ds = open_dataset(tmp_path / "converged_orders_accuracy_cost.nc")
    assert (tmp_path / "converged_orders_accuracy_cost.png").stat().st_size > 0
    assert ds["rule_error"].shape == (1, 2, 15)
    assert float(ds["series_last_order"].max()) < 1e-7
    former, present = ds["rule_error"].isel(case=0, rule=0), ds["rule_error"].isel(case=0, rule=1)
    assert float(present.max()) < 1e-3
    assert float(present.sel(sun_zenith=108.0)) < float(former.sel(sun_zenith=108.0))
    fixed = ds["fixed_orders_error"].isel(case=0).max("sun_zenith").values
    assert bool((np.diff(fixed) < 0).all())  # more orders, nearer the series
    assert bool((ds["build_seconds"] > 0).all())
