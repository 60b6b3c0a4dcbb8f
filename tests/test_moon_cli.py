"""``skytorch moon``: netCDF and PNG output against skyfield and the disc integral."""

from __future__ import annotations

import argparse

import numpy as np
import pytest
import torch

from skytorch.commands import moon as moon_command
from skytorch.constants import DEGREE, MOON_RADIUS_M, PERCENT
from skytorch.dataset import open_dataset

TIMES = ["2025-09-07T20:00", "2025-09-14T20:00", "2025-09-27T04:00"]
SITE = (52.5, 13.4, 34.0)
#: topocentric phase angle against skyfield's positions (same DE421, light time) [deg]
PHASE_TOLERANCE_DEG = 0.01
#: 64-pixel disc sum against the Gauss quadrature of the same reflectance law
IMAGE_FLUX_TOLERANCE = 2 * PERCENT


def _parse(argv):
    parser = argparse.ArgumentParser()
    moon_command.configure(parser)
    return parser.parse_args(argv)


@pytest.fixture(scope="module")
def moon_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("moon")
    output, png = folder / "moon.nc", folder / "moon.png"
    args = _parse(["--time", *TIMES, "--lat", str(SITE[0]), "--lon", str(SITE[1]),
                   "--elevation", str(SITE[2]), "-o", str(output), "--png", str(png)])
    assert moon_command.run(args) == 0
    return open_dataset(output), png


def test_moon_command_writes_dataset_and_png(moon_run, capsys):
    ds, png = moon_run
    assert png.stat().st_size > 10_000
    for name in ("phase_angle", "illuminated_fraction", "bright_limb_angle",
                 "libration_longitude", "libration_latitude", "optical_libration_longitude",
                 "magnitude", "apparent_diameter", "parallactic_angle"):
        assert ds[name].dims == ("time",) and np.isfinite(ds[name].values).all()
    assert ds.radiance.dims == ("time", "y", "x", "wavelength")
    assert ds.phase_angle.attrs["units"] == "degree" and ds.radiance.attrs["units"]
    # the Moon's libration stays within its published bounds (|l| < 8.2°, |b| < 7°)
    assert np.abs(ds.libration_longitude.values).max() < 8.2
    assert np.abs(ds.libration_latitude.values).max() < 7.0


def test_moon_command_phase_against_skyfield(moon_run):
    """Topocentric phase angle and illuminated fraction from skyfield's own positions."""
    from skyfield.api import wgs84

    from skytorch.ephemeris import load_ephemeris, skyfield_time

    ds, _ = moon_run
    eph = load_ephemeris()
    t = skyfield_time(np.array(TIMES, dtype="datetime64[ns]"))
    observer = eph["earth"] + wgs84.latlon(*SITE[:2], elevation_m=SITE[2])
    moon = observer.at(t).observe(eph["moon"]).apparent()
    sun_from_moon = eph["moon"].at(t - moon.light_time).observe(eph["sun"]).position.au
    to_observer = -moon.position.au
    cos_i = np.sum(sun_from_moon * to_observer, axis=0) / (
        np.linalg.norm(sun_from_moon, axis=0) * np.linalg.norm(to_observer, axis=0))
    phase = np.degrees(np.arccos(cos_i))
    assert np.abs(ds.phase_angle.values - phase).max() < PHASE_TOLERANCE_DEG
    k = (1.0 + np.cos(np.radians(phase))) / 2.0
    assert np.abs(ds.illuminated_fraction.values - k).max() < PHASE_TOLERANCE_DEG * DEGREE


def test_moon_command_disc_image_flux(moon_run):
    """The image summed over pixels gives the irradiance of the disc-integrated law."""
    from skytorch.moon import lunar_irradiance

    ds, _ = moon_run
    n = ds.sizes["x"]
    pixel_area = (2.0 / n) ** 2  # lunar radii²
    wl = torch.tensor(ds.wavelength.values, dtype=torch.float64)
    for index in range(ds.sizes["time"]):
        frame = ds.isel(time=index)
        distance = float(frame.distance)
        image_flux = (frame.radiance.values.sum(axis=(0, 1)) * pixel_area
                      * (MOON_RADIUS_M / distance) ** 2)
        expected = lunar_irradiance(torch.tensor(float(frame.phase_angle) * DEGREE,
                                                 dtype=torch.float64), wl,
                                    distance_m=distance,
                                    sun_distance_m=float(frame.sun_distance)).numpy()
        if float(frame.phase_angle) < 170.0:
            assert np.abs(image_flux / expected - 1.0).max() < IMAGE_FLUX_TOLERANCE


def test_moon_command_errors(tmp_path):
    with pytest.raises(ValueError, match="--time"):
        moon_command.run(_parse(["--lat", "0", "--lon", "0", "-o", str(tmp_path / "x.nc")]))
    with pytest.raises(ValueError, match="lat"):
        moon_command.run(_parse(["--time", "2025-01-01", "--lat", "95", "--lon", "0",
                                 "-o", str(tmp_path / "x.nc")]))


def test_moon_command_in_cli_registry(tmp_path):
    from skytorch import cli

    assert "moon" in cli.SUBCOMMANDS
    status = cli.main(["moon", "--time", TIMES[0], "--lat", "0", "--lon", "0",
                       "-o", str(tmp_path / "m.nc"), "--pixels", "16"])
    assert status == 0
