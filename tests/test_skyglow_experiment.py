"""The skyglow accuracy-vs-cost experiment runs end to end in --quick mode."""

from __future__ import annotations

import importlib.util
from pathlib import Path

from _skyglow_standin import single_torch_thread  # noqa: F401

from skytorch.dataset import open_dataset

SCRIPT = Path(__file__).resolve().parents[1] / "experiments" / "skyglow_accuracy_cost.py"


def test_experiment_quick(tmp_path):
    spec = importlib.util.spec_from_file_location("skyglow_accuracy_cost", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main(["--quick", "--output-dir", str(tmp_path)]) == 0
    ds = open_dataset(tmp_path / "skyglow_accuracy_cost.nc")
    assert (tmp_path / "skyglow_accuracy_cost.png").stat().st_size > 0
    # more components never make the same-grid error worse in this small case
    error = ds["mean_relative_error"].values[:, 0]
    assert error[-1] <= error[0]
    q = ds["quadrature_max_error"].values
    assert q.shape == (2, 3) and q[0, -1] < q[0, 0] and q[1, -1] < q[1, 0]
