"""The stars accuracy-vs-cost experiment runs in quick mode and writes its outputs."""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

from skytorch.dataset import open_dataset

SCRIPT = Path(__file__).resolve().parents[1] / "experiments" / "stars_accuracy_cost.py"


def test_stars_experiment_quick(tmp_path, monkeypatch):
    monkeypatch.setattr(sys, "argv", [str(SCRIPT), "--quick", "--output-dir", str(tmp_path)])
    namespace = runpy.run_path(str(SCRIPT), run_name="not_main")
    assert namespace["main"](["--quick", "--output-dir", str(tmp_path)]) == 0
    ds = open_dataset(tmp_path / "stars_accuracy_cost.nc")
    assert (tmp_path / "stars_accuracy_cost.png").stat().st_size > 10_000
    errors = dict(zip(ds.variant.values.tolist(), ds.position_max_error.values, strict=True))
    assert errors["full, float64"] < 1.0  # arcsec against skyfield
    assert errors["no aberration"] > 5.0  # annual aberration is up to 20.5″
