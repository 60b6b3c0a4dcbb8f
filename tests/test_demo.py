"""The demonstration job runs end to end and writes real files.

References: the 2015-09-28 eclipse in the Five Millennium Canon of Lunar Eclipses
(Espenak & Meeus 2009, NASA/TP-2009-214172): total, umbral magnitude 1.2765, gamma
-0.3296, totality 72 min; the eclipsed full Moon is up all night from Berlin.
"""

import numpy as np

from skytorch.cli import main
from skytorch.dataset import open_dataset

CANON_UMBRAL_MAGNITUDE = 1.2765
CANON_GAMMA = -0.3296
CANON_TOTALITY_MIN = 72.0


def test_demo_quick_writes_netcdf_and_png(tmp_path, capsys):
    assert main(["demo", "--quick", "--output-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "2015-09-28" in out
    assert "SKIPPED" not in out  # every part exists in this version
    ds = open_dataset(tmp_path / "eclipse_night_ephemeris.nc")
    assert float(ds["moon_altitude"].max()) > 30.0
    for name in ("eclipse_night_ephemeris", "eclipse_light_curve", "eclipse_shadow_profile",
                 "allsky_three_phases", "sweep_moon_colour"):
        assert (tmp_path / f"{name}.png").stat().st_size > 10_000, name
    assert (tmp_path / "eclipse_moon_strip.png").stat().st_size > 2_000
    circ = open_dataset(tmp_path / "eclipse_circumstances.nc").isel(eclipse=0)
    assert str(circ["kind"].values) == "total"
    assert abs(float(circ["umbral_magnitude"]) - CANON_UMBRAL_MAGNITUDE) < 0.005
    assert abs(float(circ["gamma"]) - CANON_GAMMA) < 0.002
    assert abs(float(circ["total_duration"]) - CANON_TOTALITY_MIN) < 1.0
    typical = open_dataset(tmp_path / "eclipse_light_curve_typical.nc")
    volcanic = open_dataset(tmp_path / "eclipse_light_curve_calbuco.nc")
    # more aerosol in the limb: a darker eclipse (Keen 1983)
    assert float(volcanic["v_magnitude"].max()) > float(typical["v_magnitude"].max())
    totality = open_dataset(tmp_path / "allsky_2_totality.nc")
    assert {"moon", "eclipse", "skyglow"} <= set(totality.attrs["effects_computed"].split(","))
    # the close-up at partial ingress resolves the umbra's edge: part of the disc is more
    # than 5 mag arcsec^-2 fainter than the sunlit part
    assert (tmp_path / "moon_camera_three_phases.png").stat().st_size > 10_000
    closeup = open_dataset(tmp_path / "moon_camera_1_partial.nc")
    disc = closeup["component_v_mag_arcsec2"].sel(component="moon").values
    disc = disc[disc < np.nanmedian(disc) - 3.0]
    assert disc.max() - disc.min() > 5.0
    sweep = open_dataset(tmp_path / "sweep_moon_colour.nc")
    assert set(sweep["b_minus_v"].dims) == {"turbidity", "ozone_du"}
    assert np.isfinite(sweep["b_minus_v"].values).all()


def test_demo_reports_a_part_that_cannot_be_imported(tmp_path, capsys, monkeypatch):
    from skytorch.commands import demo

    def missing(output_dir, quick, state):
        from skytorch.nonexistent_module import something  # noqa: F401

    def present(output_dir, quick, state):
        return ["present part ran"]

    monkeypatch.setattr(demo, "PARTS", (("optional part", missing), ("present", present)))
    assert main(["demo", "--quick", "--output-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "optional part: SKIPPED (No module named 'skytorch.nonexistent_module')" in out
    assert "present part ran" in out
