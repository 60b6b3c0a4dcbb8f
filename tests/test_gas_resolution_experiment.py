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
    # 1 nm sampling of the gas bands is converged to 1e-4 mag in B, V and B-V, and to
    # 5e-4 mag in R, I, V-R and V-I, where the O2 A band and the water bands lie (well
    # below the 0.003 mag of the best solar-analogue colours); leaving the gases out
    # changes V by more than 0.01 mag and R and I by more than 0.05 mag on both paths
    # (zenith 80 deg, limb)
    assert one_nm.sum() == 2
    for name in ("error_b", "error_v", "error_bv"):
        assert np.all(np.abs(dataset[name].values[one_nm]) <= 1e-4)
    for name in ("error_r", "error_i", "error_vr", "error_vi"):
        assert np.all(np.abs(dataset[name].values[one_nm]) <= 5e-4)
    assert np.all(np.abs(dataset["error_v"].values[no_gases]) > 0.01)
    for name in ("error_r", "error_i"):
        assert np.all(np.abs(dataset[name].values[no_gases]) > 0.05)
    # the sampling error in I shrinks from 10 nm to 1 nm on every path
    ten_nm = (variant == "sampled") & (resolution == 10.0)
    assert np.all(np.abs(dataset["error_i"].values[one_nm])
                  < np.abs(dataset["error_i"].values[ten_nm]))
    for name in dataset.variables:
        assert "units" in dataset[name].attrs
