"""The TOML scene format and ``skytorch render``."""

import re

import numpy as np
import pytest

import skytorch as st
from skytorch._data import data_path
from skytorch.cli import main
from skytorch.dataset import open_dataset


def test_example_scene_reads_every_table():
    scene = st.Scene.from_toml(data_path("scene_example.toml"))
    assert (scene.lat_deg, scene.lon_deg, scene.elevation_m) == (52.52, 13.40, 34.0)
    assert scene.view == "fisheye" and scene.size == 256
    assert scene.light_map is not None and float(scene.light_map["flux"].sum()) > 0.0
    assert scene.tolerance == 0.01 and scene.fidelity == "default"
    assert scene.turbidity == 2.0 and scene.ozone_du == 300.0 and scene.ground_albedo == 0.0
    assert str(scene.time).startswith("2015-09-28T02:47")


def test_unknown_keys_are_rejected(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('time = "2015-09-28T02:47"\nbrightness = 3\n')
    with pytest.raises(ValueError, match="brightness"):
        st.Scene.from_toml(path)


def test_render_command_writes_netcdf_and_png(tmp_path, capsys):
    path = tmp_path / "scene.toml"
    path.write_text('time = "2015-06-21T19:45"\n[observer]\nlat_deg = 48.85\n'
                    'lon_deg = 2.35\n[view]\nkind = "panorama"\nsize = 8\n')
    out, png = tmp_path / "sky.nc", tmp_path / "sky.png"
    assert main(["render", str(path), "-o", str(out), "--png", str(png),
                 "--fidelity", "fast", "--night"]) == 0
    ds = open_dataset(out)
    assert ds.attrs["effects_computed"] == "sky,sun"
    assert "stars:" in ds.attrs["effects_skipped"]
    assert np.isfinite(ds["radiance"].values).all()
    assert png.stat().st_size > 200
    assert "computed: sky,sun" in capsys.readouterr().out


def test_camera_view_and_several_observers_from_toml(tmp_path, capsys):
    path = tmp_path / "moon.toml"
    path.write_text('time = "2015-09-28T02:47"\nnatural_model = "constant"\n'
                    '[observer]\nlat_deg = [52.52, 48.85]\nlon_deg = [13.40, 2.35]\n'
                    '[view]\nkind = "camera"\nsize = 8\nfov_deg = 1.5\ntarget = "moon"\n'
                    '[planner]\nexclude = ["stars"]\n')
    scene = st.Scene.from_toml(path)
    assert scene.n_observers == 2 and scene.camera == {"fov_deg": 1.5, "target": "moon"}
    out, png = tmp_path / "moon.nc", tmp_path / "moon.png"
    assert main(["render", str(path), "-o", str(out), "--png", str(png),
                 "--fidelity", "fast"]) == 0
    ds = open_dataset(out)
    assert ds.sizes["observer"] == 2 and ds.sizes["camera_x"] == 8
    assert (tmp_path / "moon_0.png").stat().st_size > 100
    assert (tmp_path / "moon_1.png").stat().st_size > 100
    assert "observer 1: computed: moon" in capsys.readouterr().out


def test_scene_file_refuses_keys_it_would_ignore_or_override():
    """A table's key at the top level overrode the table; directions without their view.

    ``turbidity = 2.0`` at the top level and ``[atmosphere] turbidity = 6.0`` rendered
    turbidity 2; ``[view]`` directions drew a 256² fisheye.
    """
    base = {"time": "2024-06-21T12:00:00", "observer": {"lat_deg": 48.85, "lon_deg": 2.35}}
    with pytest.raises(ValueError, match=r"unknown top-level keys \['turbidity'\]"):
        st.Scene.from_dict({**base, "turbidity": 2.0, "atmosphere": {"turbidity": 6.0}})
    with pytest.raises(ValueError, match="directions describes view='directions'"):
        st.Scene.from_dict({**base, "view": {"altitude_deg": [10.0], "azimuth_deg": [0.0]}})
    with pytest.raises(ValueError, match="camera describes view='camera'"):
        st.Scene(view="fisheye", camera={"fov_deg": 3.0, "target": "sun"})


def test_camera_on_a_target_far_below_the_horizon_points_at_it():
    """It was aimed at the horizon's refraction (−0.45°) for any target below −1°."""
    scene = st.Scene(time="2024-01-15T23:30", lat_deg=48.85, lon_deg=2.35, view="camera",
                     size=8, camera={"fov_deg": 3.0, "target": "moon"}, fidelity="fast")
    geometry = scene.resources().geometry(scene)
    altitude, azimuth = scene.camera_centre()
    assert geometry.moon_altitude_deg < -10.0
    assert altitude == pytest.approx(geometry.moon_altitude_deg, abs=1e-9)
    assert azimuth == pytest.approx(geometry.moon_azimuth_deg, abs=1e-9)


def test_scene_refuses_settings_it_would_not_use():
    """solar_flux_sfu without leinert1998, skyglow settings without a light map, no output.

    Each rendered bit for bit the default before.
    """
    base = {"time": "2024-06-21T12:00:00", "lat_deg": 48.85, "lon_deg": 2.35}
    with pytest.raises(ValueError, match="solar_flux_sfu=250.0: used by natural_model"):
        st.Scene(**base, solar_flux_sfu=250.0)
    with pytest.raises(ValueError, match=r"lamp='hps', observer_xy=\(1000.0, 0.0\)"):
        st.Scene(**base, lamp="hps", observer_xy=(1000.0, 0.0))
    with pytest.raises(ValueError, match="outputs must name at least one"):
        st.Scene(**base, outputs=[])
    assert st.Scene(**base, natural_model="leinert1998", solar_flux_sfu=250.0)


def test_render_command_checks_its_output_options_before_rendering(tmp_path, capsys):
    """A bad --exposure, --png without 'xyz' and a directory -o failed after the render.

    The netCDF was left behind with exit status 2.
    """
    path = tmp_path / "scene.toml"
    path.write_text('time = "2015-06-21T19:45"\noutputs = ["spectral", "srgb"]\n'
                    '[observer]\nlat_deg = 48.85\nlon_deg = 2.35\n[view]\nkind = "panorama"\n'
                    'size = 8\n')
    out, png = tmp_path / "sky.nc", tmp_path / "sky.png"
    for options, message in (
            (["--png", str(png)], "--png tone-maps the 'xyz' output"),
            (["--png", str(png), "--exposure", "-1"], "--exposure must be"),
            (["--exposure", "2"], "--exposure sets the PNG's exposure")):
        capsys.readouterr()
        assert main(["render", str(path), "-o", str(out), *options]) == 2
        assert message in capsys.readouterr().err
        assert not out.exists()
    assert main(["render", str(path), "-o", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err


def test_scene_file_must_name_its_time_and_place(tmp_path):
    """A file without time or [observer] rendered the 2015-09-28 eclipse over Berlin."""
    for text, message in (('[observer]\nlat_deg = 48.85\nlon_deg = 2.35\n', "must give time"),
                          ('time = "2024-06-21T12:00"\n', "[observer] lat_deg, [observer] lon_deg"),
                          ('time = "2024-06-21T12:00"\n[observer]\nlat_deg = 48.85\n',
                           "[observer] lon_deg")):
        path = tmp_path / "scene.toml"
        path.write_text(text)
        with pytest.raises(ValueError, match=re.escape(message)):
            st.Scene.from_toml(path)
