"""The eclipse-shadow multiple-scattering experiment runs end to end in --quick mode."""

from __future__ import annotations

import importlib.util
from pathlib import Path

from skytorch.dataset import open_dataset

SCRIPT = (Path(__file__).resolve().parents[1] / "experiments"
          / "shadow_multiple_scattering.py")


def test_experiment_quick(tmp_path):
    spec = importlib.util.spec_from_file_location("shadow_multiple_scattering", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main(["--quick", "--output-dir", str(tmp_path)]) == 0
    ds = open_dataset(tmp_path / "shadow_multiple_scattering.nc")
    assert (tmp_path / "shadow_multiple_scattering.png").stat().st_size > 0
    assert ds["higher_orders"].shape == (2, 4, 3)
    # scattering adds light everywhere in the umbra
    assert float(ds["higher_orders"].min()) > 0.0
    assert float(ds["single_scattering"].min()) > 0.0
