"""The skyglow multiple-scattering experiment runs end to end in --quick mode."""

from __future__ import annotations

import importlib.util
from pathlib import Path

from skytorch.dataset import open_dataset

SCRIPT = (Path(__file__).resolve().parents[1] / "experiments"
          / "skyglow_multiple_scattering.py")


def test_experiment_quick(tmp_path):
    spec = importlib.util.spec_from_file_location("skyglow_multiple_scattering", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main(["--quick", "--output-dir", str(tmp_path)]) == 0
    ds = open_dataset(tmp_path / "skyglow_multiple_scattering.nc")
    assert (tmp_path / "skyglow_multiple_scattering.png").stat().st_size > 0
    assert ds["factor"].shape == (2, 5, 3, 3)
    # all orders can only add light to the first
    assert float(ds["factor"].min()) >= 1.0
    assert ds["cost_error"].shape == (2, 2, 2)
