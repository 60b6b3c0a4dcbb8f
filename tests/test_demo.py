"""The demonstration job runs end to end and writes real files."""

from skytorch.cli import main
from skytorch.dataset import open_dataset


def test_demo_quick_writes_netcdf_and_png(tmp_path, capsys):
    assert main(["demo", "--quick", "--output-dir", str(tmp_path)]) == 0
    ds = open_dataset(tmp_path / "eclipse_night_ephemeris.nc")
    # the eclipsed full Moon is up all night from Berlin: highest near local midnight
    assert float(ds["moon_altitude"].max()) > 30.0
    assert (tmp_path / "eclipse_night_ephemeris.png").stat().st_size > 10_000
    assert "2015-09-28" in capsys.readouterr().out
