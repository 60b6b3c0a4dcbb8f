"""The radius-node accuracy-vs-cost experiment runs end to end in --quick mode."""

from __future__ import annotations

from pathlib import Path

from experiments._common import load_script
from skytorch.dataset import open_dataset

SCRIPT = Path(__file__).resolve().parents[1] / "experiments" / "radius_nodes_accuracy_cost.py"


def test_experiment_quick(tmp_path):
    """Coarse tables (8 radii), 550 nm, τ 1: crowding their few radii is no gain.

    Measured (ray-marched order 1 + the tables' orders >= 2, largest error over the views,
    Sun 30 / 60 deg): the sky from the ground 0.72 / 4.5 % of DISORT with ref. 2's mapping
    and 14.7 / 11.0 % with ``r_ground_weight`` 1/2; the top 24.8 / 18.8 % and 22.3 / 19.1 %
    of sasktran2. Eight radii have too few nodes left above the haze when crowded, so
    coarse tables keep ref. 2's mapping (the default tables' gain is in the full run,
    docs/multiple_scattering_validation.md, "Radius nodes towards the ground").
    """
    module = load_script(SCRIPT, "radius_nodes_accuracy_cost")
    assert module.main(["--quick", "--output-dir", str(tmp_path)]) == 0
    ds = open_dataset(tmp_path / "radius_nodes_accuracy_cost.nc")
    assert (tmp_path / "radius_nodes_accuracy_cost.png").stat().st_size > 0
    assert ds["error"].shape == (2, 2, 2, 1, 2)
    assert list(ds["r_ground_weight"].values) == [0.0, 0.5]
    sky = ds["error"].sel(where="sky from the ground (DISORT)", statistic="max over views")
    plain, crowded = sky.isel(case=0), sky.isel(case=1)
    assert float(plain.max()) < 0.06
    assert bool((crowded > plain).all())
    assert float(ds["error"].sel(where="top (sasktran2, spherical)").max()) < 0.3
