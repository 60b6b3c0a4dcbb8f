"""``skytorch`` subcommands report bad input by name with exit status 2, no traceback."""

from __future__ import annotations

import pytest

from skytorch.cli import main


@pytest.mark.parametrize(("text", "name"), [
    ('time = "2015-06-21T19:45"\n[observer]\nlat_deg = 95.0\nlon_deg = 2.35\n', "lat_deg"),
    ('[observer]\nlat_deg = 48.0\nlon_deg = 2.0\nelevation_m = -100.0\n', "elevation_m"),
    ('[atmosphere]\nturbidity = 0.5\n', "turbidity"),
    ('natural_mag_arcsec2 = "dark"\n', "natural_mag_arcsec2"),
    ('[view]\nkind = "directions"\nazimuth_deg = [0.0]\n', "directions"),
    ('[view]\nkind = "fisheye"\nsise = 8\n', "sise"),
    ('brightness = 3\n', "brightness"),
    ('time = "2100-01-01"\n', "time"),
    ('time = \n', "TOML"),
])
def test_render_refuses_bad_scenes_by_name(tmp_path, capsys, text, name):
    path = tmp_path / "scene.toml"
    path.write_text(text)
    assert main(["render", str(path), "-o", str(tmp_path / "sky.nc")]) == 2
    error = capsys.readouterr().err
    assert error.startswith("skytorch render: error:")
    assert name.lower() in error.lower()
    assert not (tmp_path / "sky.nc").exists()


def test_render_of_a_missing_or_unreadable_file_is_an_error(tmp_path, capsys):
    assert main(["render", str(tmp_path / "none.toml"), "-o", str(tmp_path / "a.nc")]) == 2
    assert "none.toml" in capsys.readouterr().err
    assert main(["render", str(tmp_path), "-o", str(tmp_path / "a.nc")]) == 2  # a folder
    assert "skytorch render: error:" in capsys.readouterr().err


def test_ephemeris_command_refuses_bad_observers(tmp_path, capsys):
    status = main(["ephemeris", "--start", "2015-01-01", "--end", "2015-01-02",
                   "--lat", "95", "--lon", "0", "-o", str(tmp_path / "e.nc")])
    assert status == 2
    assert "lat_deg" in capsys.readouterr().err


@pytest.mark.parametrize(("arguments", "name"), [
    (["planets", "--times", "2020-03-24T00:00", "--turbidity", "5"], "--turbidity"),
    (["planets", "--times", "2020-03-24T00:00", "--elevation", "300"], "elevation_m"),
    (["stars", "--time", "2020-03-24T00:00", "--lat", "50", "--lon", "10",
      "--no-atmosphere", "--ozone", "250"], "--ozone"),
    (["stars", "--time", "2020-03-24T00:00", "--step", "5min", "--lat", "50", "--lon", "10"],
     "--step"),
])
def test_settings_that_would_go_unused_are_errors(tmp_path, capsys, arguments, name):
    """Atmosphere settings without an atmosphere, a height without an observer."""
    assert main([*arguments, "-o", str(tmp_path / "x.nc")]) == 2
    assert name in capsys.readouterr().err
    assert not (tmp_path / "x.nc").exists()
