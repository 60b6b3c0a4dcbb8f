"""The eclipse higher-orders accuracy-vs-cost experiment runs end to end in --quick mode."""

from __future__ import annotations

import importlib.util
from pathlib import Path

from skytorch.dataset import open_dataset

SCRIPT = (Path(__file__).resolve().parents[1] / "experiments"
          / "eclipse_higher_orders_accuracy_cost.py")


def test_experiment_quick(tmp_path):
    spec = importlib.util.spec_from_file_location("eclipse_higher_orders_accuracy_cost", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main(["--quick", "--output-dir", str(tmp_path)]) == 0
    ds = open_dataset(tmp_path / "eclipse_higher_orders_accuracy_cost.nc")
    assert (tmp_path / "eclipse_higher_orders_accuracy_cost.png").stat().st_size > 0
    assert ds["ratio_to_montecarlo"].shape == (1, 1, 2, 1)
    # the quick quadrature at the Burgos zenith: orders >= 3 of the right size (0.4-2.5)
    assert bool(((ds["ratio_to_montecarlo"] > 0.4) & (ds["ratio_to_montecarlo"] < 2.5)).all())
