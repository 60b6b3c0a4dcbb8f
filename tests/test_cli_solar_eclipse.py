"""``skytorch eclipse --solar``: local circumstances, obscuration map and the sky at maximum."""

import numpy as np
import xarray as xr

from skytorch.cli import main


def test_solar_mode_writes_circumstances_map_and_sky(tmp_path, capsys):
    out = tmp_path / "local.nc"
    status = main(["eclipse", "--solar", "2026-08-12", "--lat", "42.34", "--lon", "-3.70",
                   "--elevation", "850", "-o", str(out), "--map", str(tmp_path / "map.png"),
                   "--sky", str(tmp_path / "sky.png"), "--size", "32", "--fidelity", "fast"])
    assert status == 0
    text = capsys.readouterr().out
    assert "total here" in text and "solar_eclipse" in text
    local = xr.open_dataset(out)
    # the file holds what was printed: a total eclipse whose central phase spans C2..C3
    assert str(local.kind.values) == "total"
    span = (local.c3.values - local.c2.values) / np.timedelta64(1, "s")
    assert abs(float(local.central_duration) - span) < 1.0
    assert (tmp_path / "map.png").stat().st_size > 1000
    sky = xr.open_dataset(tmp_path / "sky.nc")
    assert np.datetime_as_string(local.maximum_time.values, unit="s").startswith(
        "2026-08-12T18:29")
    assert "solar_eclipse" in sky.attrs["effects_computed"]


def test_solar_mode_needs_a_site(capsys):
    assert main(["eclipse", "--solar", "2026-08-12", "--lat", "42.0"]) == 2
    assert "--lat and --lon" in capsys.readouterr().err


def test_demo_solar_eclipse_panel(tmp_path):
    from skytorch.commands.demo import PARTS, solar_eclipse_part

    assert "solar eclipse" in dict(PARTS)
    lines = solar_eclipse_part(tmp_path, True, {})
    assert "total, obscuration 1.0000" in lines[1]
    assert (tmp_path / "solar_eclipse.png").stat().st_size > 10_000
    sky = xr.open_dataset(tmp_path / "solar_eclipse_sky.nc")
    assert "solar_eclipse" in sky.attrs["effects_computed"]
