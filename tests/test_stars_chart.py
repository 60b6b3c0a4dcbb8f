"""The all-sky chart of an observation: every form of observe's Dataset draws."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import xarray as xr  # noqa: E402

from skytorch.stars import bright_stars, observe  # noqa: E402
from skytorch.stars.chart import all_sky_chart  # noqa: E402

TIME = ["2025-09-07T21:00"]


@pytest.fixture(scope="module")
def catalog():
    return bright_stars(4.0)


def _drawn(figure) -> int:
    points = figure.axes[0].collections[0].get_offsets()
    plt.close(figure)
    return len(points)


def test_chart_draws_the_stars_above_the_horizon_and_the_limit(catalog):
    ds = observe(catalog, TIME, 52.5, 13.4)
    frame = ds.isel(time=0)
    expected = int((frame.above_horizon & (frame.magnitude <= frame.limiting_magnitude)).sum())
    assert _drawn(all_sky_chart(ds)) == expected > 100


def test_chart_of_a_per_direction_background(catalog):
    """Each star against the limit of its own direction (a bright east hides its stars)."""
    altitude, azimuth = np.linspace(-2.0, 90.0, 47), np.arange(0.0, 360.0, 5.0)
    sky = np.where(azimuth[None, :] < 180.0, 16.0, 22.0) + 0.0 * altitude[:, None]
    background = xr.Dataset({"sky_brightness": (("altitude", "azimuth"), sky,
                                                {"units": "mag arcsec-2"})},
                            coords={"altitude": altitude, "azimuth": azimuth})
    ds = observe(catalog, TIME, 52.5, 13.4, background=background)
    frame = ds.isel(time=0)
    expected = int((frame.above_horizon & (frame.magnitude <= frame.limiting_magnitude)).sum())
    figure = all_sky_chart(ds)
    assert "limit of their direction" in figure.axes[0].get_title()
    assert _drawn(figure) == expected


def test_chart_of_several_observers_and_bad_indices(catalog):
    several = observe(catalog, TIME, [52.5, -33.9], [13.4, 18.4])
    with pytest.raises(ValueError, match="pass observer_index"):
        all_sky_chart(several)
    with pytest.raises(ValueError, match="observer_index"):
        all_sky_chart(several, observer_index=2)
    frame = several.isel(time=0, observer=1)
    expected = int((frame.above_horizon & (frame.magnitude <= frame.limiting_magnitude)).sum())
    assert _drawn(all_sky_chart(several, observer_index=1)) == expected
    with pytest.raises(ValueError, match="time_index"):
        all_sky_chart(observe(catalog, TIME, 52.5, 13.4), time_index=1)


def test_chart_of_an_elevated_observer_shows_the_stars_below_zero(catalog):
    """From 10 km stars are seen below 0 deg (the dip is 3.2 deg): the chart shows them."""
    ds = observe(catalog, TIME, 52.5, 13.4, 10_000.0)
    drawn = ds.above_horizon & (ds.magnitude <= ds.limiting_magnitude)
    low = float(ds.altitude.where(drawn).min())
    assert low < 0.0
    figure = all_sky_chart(ds)
    assert figure.axes[0].get_ylim()[1] == pytest.approx(90.0 - low)
    plt.close(figure)
