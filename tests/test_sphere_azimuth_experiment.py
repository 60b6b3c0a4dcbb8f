"""The sphere-azimuth accuracy-vs-cost experiment runs end to end in --quick mode."""

from __future__ import annotations

from pathlib import Path

from experiments._common import load_script
from skytorch.dataset import open_dataset

SCRIPT = (Path(__file__).resolve().parents[1] / "experiments"
          / "sphere_azimuth_accuracy_cost.py")


def test_experiment_quick(tmp_path):
    """Coarse tables (6 azimuth nodes, 8 radii), 550 nm, τ 1, refinement 1 and 2.

    Measured (ray-marched order 1 + the tables' orders >= 2, largest error over the views,
    Sun 30 / 60 deg): the sky from the ground 0.71 / 4.5 % of DISORT with the table's own
    azimuths and 1.7 / 4.4 % with twice as many; the top 24.8 / 18.8 % and 24.8 / 19.6 %
    of sasktran2. The coarse tables' errors are their radii and view nodes', which the
    quadrature's azimuths do not move; the gain is on the default tables (full run,
    docs/multiple_scattering_validation.md, "Azimuths of the sphere quadrature").
    """
    module = load_script(SCRIPT, "sphere_azimuth_accuracy_cost")
    assert module.main(["--quick", "--output-dir", str(tmp_path)]) == 0
    ds = open_dataset(tmp_path / "sphere_azimuth_accuracy_cost.nc")
    assert (tmp_path / "sphere_azimuth_accuracy_cost.png").stat().st_size > 0
    assert ds["error"].shape == (2, 2, 2, 1, 2)
    assert list(ds["sphere_phi_refinement"].values) == [1, 2]
    sky = ds["error"].sel(where="sky from the ground (DISORT)", statistic="max over views")
    assert float(sky.max()) < 0.06
    assert float(ds["error"].sel(where="top (sasktran2, spherical)").max()) < 0.3
