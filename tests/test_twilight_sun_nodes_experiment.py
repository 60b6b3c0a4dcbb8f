"""The Sun-zenith-node accuracy-vs-cost experiment runs end to end in --quick mode."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from skytorch.constants import PERCENT
from skytorch.dataset import open_dataset

SCRIPT = (Path(__file__).resolve().parents[1] / "experiments"
          / "twilight_sun_nodes_accuracy_cost.py")


def test_experiment_quick(tmp_path):
    """Coarse tables with 16 and 32 Sun-zenith nodes, Rayleigh, against the Monte-Carlo.

    The day sky (Sun 30-80 deg) meets the issue's 3 % with either (measured 2.4 / 1.7 / 1.5
    and 1.9 / 1.5 / 1.5 %); in twilight these small tables are not converged in the Sun's
    nodes (Sun 94 deg: 5.4 % with 16, 9.8 % with 32; reported, not asserted).
    """
    spec = importlib.util.spec_from_file_location("twilight_sun_nodes_accuracy_cost", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main(["--quick", "--output-dir", str(tmp_path)]) == 0
    ds = open_dataset(tmp_path / "twilight_sun_nodes_accuracy_cost.nc")
    assert (tmp_path / "twilight_sun_nodes_accuracy_cost.png").stat().st_size > 0
    assert ds["error"].shape == (1, 2, 6, 2)
    day = ds["error"].sel(sun_zenith=[30.0, 60.0, 80.0], statistic="max over decided views")
    assert bool((ds["decided_views"].sel(sun_zenith=[30.0, 60.0, 80.0]) == 14).all())
    assert float(day.max()) < 3 * PERCENT
    assert np.isfinite(ds["error"].values).all()
    assert bool((ds["precompute_seconds"] > 0).all())
