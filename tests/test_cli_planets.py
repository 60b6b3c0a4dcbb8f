"""The ``skytorch planets`` subcommand.

Reference: Venus at greatest eastern elongation, 46.1° from the Sun, on 2020-03-24
(USNO Astronomical Applications, "Astronomical Phenomena for the Year 2020").
"""

from __future__ import annotations

import numpy as np

from skytorch.cli import main
from skytorch.dataset import open_dataset


def test_planets_writes_venus_greatest_elongation(tmp_path):
    output = tmp_path / "venus.nc"
    status = main(["planets", "--start", "2020-03-20T00:00", "--end", "2020-03-28T00:00",
                   "--step", "6h", "--bodies", "venus", "--lat", "48.85", "--lon", "2.35",
                   "--atmosphere", "-o", str(output)])
    assert status == 0
    ds = open_dataset(output).sel(planet="venus")
    elongation = ds.elongation.values
    best = ds.time.values[int(np.argmax(elongation))]
    assert abs(best - np.datetime64("2020-03-24T12:00", "ns")) <= np.timedelta64(24, "h")
    assert abs(float(elongation.max()) - 46.1) < 0.1
    assert {"apparent_altitude", "apparent_magnitude", "above_horizon"} <= set(ds.data_vars)


def test_planets_command_errors(tmp_path, capsys):
    assert main(["planets", "-o", str(tmp_path / "x.nc")]) == 2
    assert "--start" in capsys.readouterr().err
    assert main(["planets", "--times", "2020-03-24T00:00", "--atmosphere",
                 "-o", str(tmp_path / "x.nc")]) == 2
    assert "observer" in capsys.readouterr().err
    assert not (tmp_path / "x.nc").exists()
