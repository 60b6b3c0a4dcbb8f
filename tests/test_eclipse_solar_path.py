"""The Moon's shadow on Earth: path limits against NASA's table, obscuration maps."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from skytorch.eclipse.solar_local import solar_eclipse_local
from skytorch.eclipse.solar_path import obscuration_map, solar_eclipse_path

DATA = {"1980-02-16": Path(__file__).parent / "data" / "solar_path_1980_02_16.csv",
        "2024-04-08": Path(__file__).parent / "data" / "solar_path_2024_04_08.csv"}
EARTH_KM = 6371.0


def _degrees(text):
    degrees, minutes = text.split()
    sign = -1.0 if degrees.startswith("-") else 1.0
    return sign * (abs(float(degrees)) + float(minutes) / 60.0)


@pytest.fixture(scope="module", params=sorted(DATA))
def eclipse(request):
    return request.param


@pytest.fixture(scope="module")
def table(eclipse):
    frame = pd.read_csv(DATA[eclipse], comment="#", dtype=str)
    for column in ("north_lat", "north_lon", "south_lat", "south_lon", "central_lat",
                   "central_lon"):
        frame[column] = frame[column].map(_degrees)
    for column in ("ratio", "sun_alt", "width_km", "duration_s"):
        frame[column] = frame[column].astype(float)
    return frame


@pytest.fixture(scope="module")
def path(eclipse):
    return solar_eclipse_path(eclipse, step_s=5.0)


def _local_xy(lat, lon, lat0, lon0):
    """Equirectangular plane [km] around (lat0, lon0) (adequate over ~100 km)."""
    x = np.radians(lon - lon0) * np.cos(np.radians(lat0)) * EARTH_KM
    return x, np.radians(lat - lat0) * EARTH_KM


def _distance_to_line(lat, lon, line_lat, line_lon):
    """Distance [km] from a point to a polyline (segments in a local plane)."""
    keep = ~np.isnan(line_lat)
    x, y = _local_xy(line_lat[keep], line_lon[keep], lat, lon)
    ax, ay, bx, by = x[:-1], y[:-1], x[1:], y[1:]
    ex, ey = bx - ax, by - ay
    t = np.clip(-(ax * ex + ay * ey) / (ex**2 + ey**2), 0.0, 1.0)
    return float(np.min(np.hypot(ax + t * ex, ay + t * ey)))


@pytest.mark.parametrize("line", ["north", "south", "central"])
def test_limits_and_central_line_against_nasa_table(table, path, line):
    # distance of every published point from our line (the lines, not the instants: the
    # published times carry the table's own Delta T and UT1)
    for _, row in table.iterrows():
        distance = _distance_to_line(row[f"{line}_lat"], row[f"{line}_lon"],
                                     path[f"{line}_latitude"].values,
                                     path[f"{line}_longitude"].values)
        assert distance <= 2.0, (row.time, line, distance)


def test_instants_width_ratio_altitude(table, path):
    at = path.sel(time=table.time.values.astype("datetime64[ns]"))
    # the published instants lie within 3 s of ours along the central line (the table's
    # Delta T and UT1 against skyfield's): the time of our nearest point to each row
    seconds = (path.time.values - path.time.values[0]) / np.timedelta64(1, "s")
    offsets = []
    for _, row in table.iterrows():
        x, y = _local_xy(path.central_latitude.values, path.central_longitude.values,
                         row.central_lat, row.central_lon)
        i = int(np.argmin(np.hypot(x, y)))
        ex, ey = x[i + 1] - x[i - 1], y[i + 1] - y[i - 1]
        fraction = -(x[i - 1] * ex + y[i - 1] * ey) / (ex**2 + ey**2)
        nearest = seconds[i - 1] + fraction * (seconds[i + 1] - seconds[i - 1])
        published = (np.datetime64(row.time) - path.time.values[0]) / np.timedelta64(1, "s")
        offsets.append(published - nearest)
    assert np.max(np.abs(offsets)) < 3.0 and np.std(offsets) < 0.3
    np.testing.assert_allclose(at.path_width.values / 1e3, table.width_km, atol=1.0)
    np.testing.assert_allclose(at.moon_sun_ratio.values, table.ratio, atol=6e-4)
    np.testing.assert_allclose(at.sun_altitude.values, table.sun_alt, atol=0.6)


def test_central_durations_against_nasa_table(eclipse, table):
    ds = solar_eclipse_local(eclipse, table.central_lat.to_numpy(copy=True),
                             table.central_lon.to_numpy(copy=True))
    assert (ds.kind.values == "total").all()
    np.testing.assert_allclose(ds.central_duration.values, table.duration_s, atol=1.0)


def test_observer_at_the_path_limit(eclipse, table):
    # 2 km inside and outside the published northern limit, along the line to the centre
    row = table.iloc[5 if eclipse.startswith("1980") else 50]
    x, y = _local_xy(row.central_lat, row.central_lon, row.north_lat, row.north_lon)
    unit = np.array([x, y]) / np.hypot(x, y)
    offsets = np.array([2.0, -2.0])
    lat = row.north_lat + np.degrees(offsets * unit[1] / EARTH_KM)
    lon = row.north_lon + np.degrees(offsets * unit[0] / EARTH_KM
                                     / np.cos(np.radians(row.north_lat)))
    ds = solar_eclipse_local(eclipse, lat, lon)
    assert ds.kind.values.tolist() == ["total", "partial"]
    assert 0.0 < float(ds.central_duration[0]) < 90.0  # ~sqrt(2 km) of the half-width
    assert float(ds.magnitude[1]) > 0.99


def test_path_width_at_greatest_eclipse_2024():
    ds = solar_eclipse_path("2024-04-08", step_s=60.0)
    at = ds.sel(time=np.datetime64("2024-04-08T18:17"), method="nearest")
    assert float(at.path_width) / 1e3 == pytest.approx(197.5, abs=1.5)  # canon: 197.5 km
    assert (ds.moon_sun_ratio > 1).all()


def test_path_width_near_the_ends_2017():
    """No width where a limit has left Earth; the same width at an instant for any step.

    The rows at the path's ends gave 1 061-1 466 km (distances to the far end of the other
    limit line) against the canon's 115 km at greatest eclipse, and at 16:50 UTC the width
    grew with the step (70.0 km at 60 s, 80.7 km at 600 s: chords of the limit lines).
    """
    instant = np.datetime64("2017-08-21T16:50")
    widths = []
    for step in (60.0, 600.0):
        ds = solar_eclipse_path("2017-08-21", step_s=step)
        missing = ds.north_latitude.isnull() | ds.south_latitude.isnull()
        assert bool(missing.any()) and bool(ds.path_width.where(missing).isnull().all())
        assert float(ds.path_width.max()) / 1e3 < 120.0
        widths.append(float(ds.path_width.sel(time=instant, method="nearest")))
    assert widths[0] == pytest.approx(widths[1], rel=1e-9)


def test_hybrid_path_changes_kind():
    ds = solar_eclipse_path("2023-04-20", step_s=120.0)
    ratio = ds.moon_sun_ratio.values
    assert ratio[0] < 1 and ratio[-1] < 1 and ratio.max() > 1


def test_non_central_eclipse_has_no_path():
    with pytest.raises(ValueError, match="not central"):
        solar_eclipse_path("2015-09-13")


def test_map_agrees_with_local_circumstances():
    local = solar_eclipse_local("2024-04-08", [40.7128, 41.4993], [-74.006, -81.6944])
    for i, (lat, lon) in enumerate([(40.7128, -74.006), (41.4993, -81.6944)]):
        ds = obscuration_map(local.maximum_time.values[i], [lat, 0.0], [lon, 10.0])
        assert float(ds.obscuration[0, 0]) == pytest.approx(float(local.obscuration[i]),
                                                             abs=1e-6)
        assert float(ds.obscuration[1, 1]) == 0.0  # Gulf of Guinea: outside the penumbra
        assert float(ds.magnitude[1, 1]) < 0


def test_map_defaults_and_checks():
    ds = obscuration_map("2026-08-12T17:46", np.arange(30.0, 70.0, 1.0),
                         np.arange(-30.0, 20.0, 1.0))
    assert ds.obscuration.dims == ("latitude", "longitude")
    assert ds.obscuration.shape == (40, 50)
    assert float(ds.obscuration.max()) > 0.99  # the umbra is on the map (Iceland-Spain)
    assert float(ds.obscuration.min()) >= 0.0
    with pytest.raises(ValueError, match="lat_deg"):
        obscuration_map("2026-08-12T17:46", [95.0], [0.0])
    with pytest.raises(ValueError, match="one-dimensional"):
        obscuration_map("2026-08-12T17:46", [[1.0]], [0.0])
