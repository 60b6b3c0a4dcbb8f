"""The gas-resolution accuracy-versus-cost experiment runs (quick mode) and writes its outputs."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from skytorch.dataset import open_dataset

SCRIPT = (Path(__file__).resolve().parent.parent / "experiments"
          / "gas_resolution_accuracy_cost.py")


def test_gas_resolution_experiment_quick(tmp_path):
    spec = importlib.util.spec_from_file_location("gas_resolution_accuracy_cost", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.main(["--quick", "--output-dir", str(tmp_path)])
    dataset = open_dataset(tmp_path / "gas_resolution_accuracy_cost.nc")
    assert (tmp_path / "gas_resolution_accuracy_cost.png").stat().st_size > 0
    variant = dataset["variant"].values
    resolution = dataset["resolution"].values
    one_nm = (variant == "sampled") & (resolution == 1.0)
    no_gases = variant == "no gases"
    # 1 nm sampling of the gas bands is converged to 1e-4 mag in B, V and B-V; leaving
    # the gases out changes V by more than 0.01 mag on both paths (zenith 80 deg, limb)
    for name in ("error_b", "error_v", "error_bv"):
        assert one_nm.sum() == 2 and np.all(np.abs(dataset[name].values[one_nm]) <= 1e-4)
    assert np.all(np.abs(dataset["error_v"].values[no_gases]) > 0.01)
    for name in dataset.variables:
        assert "units" in dataset[name].attrs
