"""The netCDF quantisation experiment runs in quick mode; errors stay within N digits."""

import subprocess
import sys
from pathlib import Path

import numpy as np

from skytorch.dataset import open_dataset

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "experiments" / "netcdf_quantisation_accuracy_cost.py"


def test_quantisation_experiment_quick(tmp_path):
    subprocess.run([sys.executable, str(SCRIPT), "--quick", "--output-dir", str(tmp_path)],
                   check=True, cwd=ROOT)
    ds = open_dataset(tmp_path / "netcdf_quantisation_accuracy_cost.nc")
    exact = ds.sel(setting=["uncompressed", "lossless"])
    assert float(exact["radiance_relative_error"].max()) == 0.0
    quantised = ds.where(np.isfinite(ds["significant_digits"]), drop=True)
    digits = quantised["significant_digits"].values
    # half a unit in the last kept digit
    assert np.all(quantised["radiance_relative_error"].values < 5.0 * 10.0 ** -digits)
    # fewer digits, smaller files; every quantised file below the lossless one
    order = np.argsort(digits)
    assert np.all(np.diff(quantised["size_mb"].values[order]) > 0)
    assert float(quantised["size_mb"].max()) < float(ds["size_mb"].sel(setting="lossless"))
    assert (tmp_path / "netcdf_quantisation_accuracy_cost.png").stat().st_size > 10_000
