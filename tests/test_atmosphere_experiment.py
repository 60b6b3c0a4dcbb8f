"""The accuracy-versus-cost experiment runs (quick mode) and writes its outputs."""

from __future__ import annotations

import importlib.util
from pathlib import Path

from skytorch.dataset import open_dataset

SCRIPT = Path(__file__).resolve().parent.parent / "experiments" / "atmosphere_accuracy_cost.py"


def test_accuracy_cost_experiment_quick(tmp_path):
    spec = importlib.util.spec_from_file_location("atmosphere_accuracy_cost", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.main(["--quick", "--output-dir", str(tmp_path)])
    dataset = open_dataset(tmp_path / "atmosphere_accuracy_cost.nc")
    assert (tmp_path / "atmosphere_accuracy_cost.png").stat().st_size > 0
    # the default quadrature (gauss, 6 nodes, float64) meets 1e-6 against the reference
    mask = ((dataset["od_method"] == "gauss") & (dataset["od_steps"] == 6)
            & (dataset["od_dtype"] == "float64")).values
    assert mask.any() and float(dataset["od_error"].values[mask].max()) <= 1e-6
    for name in dataset.variables:
        assert "units" in dataset[name].attrs


PROFILE_SCRIPT = SCRIPT.parent / "atmosphere_profile_accuracy_cost.py"


def test_profile_accuracy_cost_experiment_quick(tmp_path):
    spec = importlib.util.spec_from_file_location("atmosphere_profile_accuracy_cost",
                                                  PROFILE_SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.main(["--quick", "--output-dir", str(tmp_path)])
    dataset = open_dataset(tmp_path / "atmosphere_profile_accuracy_cost.nc")
    assert (tmp_path / "atmosphere_profile_accuracy_cost.png").stat().st_size > 0
    # a US 1976 sounding at 1 km gives the built-in optical depths to < 0.1 %, and the
    # default 6 Gauss nodes per piece converge to 1e-9 (against adaptive, rtol 1e-12)
    assert float(dataset["sounding_tau_error"].sel(sounding_step=1.0).max()) < 1e-3
    assert float(dataset["quadrature_tau_error"].sel(gauss_nodes=6).max()) < 1e-9
    for name in dataset.variables:
        assert "units" in dataset[name].attrs
