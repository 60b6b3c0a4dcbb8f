"""The ``skytorch ephemeris`` subcommand."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from skytorch.cli import main
from skytorch.commands.ephemeris import parse_step, time_range
from skytorch.dataset import open_dataset


def test_ephemeris_writes_netcdf_over_the_2015_eclipse(tmp_path):
    """Two days at 10-minute steps around the total lunar eclipse of 2015-09-28."""
    output = tmp_path / "eclipse.nc"
    status = main(["ephemeris", "--start", "2015-09-27T00:00", "--end", "2015-09-29T00:00",
                   "--step", "10min", "--lat", "-1.4", "--lon", "-48.5", "-o", str(output)])
    assert status == 0
    ds = open_dataset(output)
    assert ds.sizes["time"] == 2 * 144 + 1
    assert ds.time.values[0] == np.datetime64("2015-09-27T00:00", "ns")
    assert {"sun_altitude", "moon_azimuth", "moon_distance"} <= set(ds.data_vars)
    # NASA canon: greatest eclipse 02:47:09 UT, Moon near the zenith of Belem, Brazil
    at = ds.sel(time=np.datetime64("2015-09-28T02:50", "ns"))
    assert float(at.moon_altitude) > 80.0
    # USNO: full Moon 2015-09-28 02:50 UT, i.e. ecliptic longitudes 180 deg apart
    # (0.5 deg/h relative motion: 0.01 deg is about a minute)
    epsilon = np.radians(23.4375)  # obliquity of date, 2015

    def longitude(ra_deg, dec_deg):
        ra, dec = np.radians(ra_deg), np.radians(dec_deg)
        return np.degrees(np.arctan2(np.sin(ra) * np.cos(epsilon) + np.tan(dec) * np.sin(epsilon),
                                     np.cos(ra)))

    elongation = longitude(float(at.moon_ra), float(at.moon_dec)) - longitude(
        float(at.sun_ra), float(at.sun_dec))
    assert abs(elongation % 360.0 - 180.0) < 0.02


def test_ephemeris_explicit_times(tmp_path):
    output = tmp_path / "seasons.nc"
    assert main(["ephemeris", "--times", "2024-03-20T03:06Z", "2024-06-20T20:51Z",
                 "-o", str(output)]) == 0
    ds = open_dataset(output)
    assert ds.sizes["time"] == 2 and "sun_altitude" not in ds
    assert abs(float(ds.sun_dec[1]) - 23.44) < 0.01


@pytest.mark.parametrize(
    "arguments",
    [
        ["--start", "2015-09-27", "--end", "2015-09-26"],  # end before start
        ["--start", "2015-09-27", "--end", "2015-09-28", "--step", "ten minutes"],
        ["--start", "2015-09-27", "--end", "2015-09-28", "--step", "0min"],
        ["--start", "1800-01-01", "--end", "1800-01-02"],  # outside DE421
        ["--times", "2015-09-27", "--lat", "95", "--lon", "0"],
        ["--start", "2015-09-27"],  # no end
    ],
)
def test_ephemeris_bad_arguments_exit_with_status_2(tmp_path, capsys, arguments):
    output = tmp_path / "bad.nc"
    assert main(["ephemeris", *arguments, "-o", str(output)]) == 2
    assert "error" in capsys.readouterr().err
    assert not output.exists()


def test_step_and_range_helpers():
    assert parse_step("90s") == np.timedelta64(90, "s")
    assert parse_step("2 h") == np.timedelta64(7200, "s")
    assert parse_step("1d") == np.timedelta64(86400, "s")
    times = time_range("2020-01-01T00:00", "2020-01-01T01:00", "25min")
    assert times.tolist() == np.array(["2020-01-01T00:00", "2020-01-01T00:25",
                                       "2020-01-01T00:50"], dtype="datetime64[ns]").tolist()
    with pytest.raises(ValueError, match="at most"):
        time_range("1900-01-01", "2050-01-01", "1min")


def test_python_m_skytorch_ephemeris_help():
    result = subprocess.run([sys.executable, "-m", "skytorch", "ephemeris", "--help"],
                            capture_output=True, text=True, timeout=120, check=False)
    assert result.returncode == 0, result.stderr
    assert "--start" in result.stdout and "--lat" in result.stdout
