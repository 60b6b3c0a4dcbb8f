"""The fidelity-ladder experiment runs in quick mode and its errors are ordered."""

import subprocess
import sys
from pathlib import Path

from skytorch.dataset import open_dataset

ROOT = Path(__file__).resolve().parents[1]
#: the reference preset's tables against direct single scattering (docs/scene.md)
REFERENCE_SKY_MAX_ERROR = 0.01


def test_scene_accuracy_cost_quick(tmp_path):
    subprocess.run([sys.executable, str(ROOT / "experiments" / "scene_accuracy_cost.py"),
                    "--quick", "--output-dir", str(tmp_path)], check=True, cwd=ROOT)
    ds = open_dataset(tmp_path / "scene_accuracy_cost.nc")
    sky = ds["sky_max_relative_error"].sel(preset=["fast", "reference"]).values
    assert sky[1] < sky[0]
    assert sky[1] < REFERENCE_SKY_MAX_ERROR
    night = ds["night_l1_relative_error"]
    assert float(night.sel(night_preset="default")) == 0.0
    assert float(night.sel(night_preset="fast")) > 0.0
    assert (tmp_path / "scene_accuracy_cost.png").stat().st_size > 10_000
