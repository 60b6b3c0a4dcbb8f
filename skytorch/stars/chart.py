"""All-sky chart of an observation: zenith-centred, north up, east to the left.

Examples
--------
>>> from skytorch.stars import bright_stars, observe
>>> from skytorch.stars.chart import all_sky_chart
>>> fig = all_sky_chart(observe(bright_stars(3.0), "2025-09-07T20:00", 52.5, 13.4))
>>> import matplotlib.pyplot as plt; plt.close(fig)
"""

from __future__ import annotations

import numpy as np
import xarray as xr

__all__ = ["all_sky_chart", "marker_sizes"]


def marker_sizes(magnitude, limit: float = 6.5, brightest: float = -1.5,
                 largest_pt2: float = 60.0, smallest_pt2: float = 0.4) -> np.ndarray:
    """Marker areas [pt²] growing with brightness: logarithmic in flux between the limits.

    The area is interpolated linearly in magnitude from ``smallest_pt2`` at ``limit`` to
    ``largest_pt2`` at ``brightest`` (the eye judges star size roughly by log-flux).
    """
    m = np.clip(np.asarray(magnitude, dtype=float), brightest, limit)
    fraction = (limit - m) / (limit - brightest)
    return smallest_pt2 + fraction**1.5 * (largest_pt2 - smallest_pt2)


def all_sky_chart(observation: xr.Dataset, time_index: int = 0, *, limit: float | None = None,
                  ax=None, title: str | None = None):
    """Plot the stars of :func:`skytorch.stars.observe` at one time on an all-sky chart.

    Parameters
    ----------
    observation : xarray.Dataset
        Output of :func:`skytorch.stars.observe`.
    time_index : int
        Which time to draw.
    limit : float, optional
        Faintest magnitude drawn (after extinction) [mag]; default the Dataset's
        ``limiting_magnitude`` at that time.
    ax : matplotlib polar Axes, optional
        Drawn into a new figure when omitted.
    title : str, optional
        Default: the time and the observer.

    Returns
    -------
    matplotlib.figure.Figure
        Zenith-equidistant projection (radius 90° − altitude), north up and east to the
        left as seen looking up; marker area from the magnitude after extinction, colour
        the apparent one (``color``), black background.
    """
    import matplotlib.pyplot as plt

    frame = observation.isel(time=time_index)
    if limit is None:
        limit = float(frame["limiting_magnitude"])
    keep = (frame["above_horizon"].values & (frame["magnitude"].values <= limit))
    altitude = frame["altitude"].values[keep]
    azimuth = np.deg2rad(frame["azimuth"].values[keep])
    magnitude = frame["magnitude"].values[keep]
    colours = np.clip(frame["color"].values[keep], 0.0, 1.0)
    order = np.argsort(-magnitude)  # faint first, bright on top
    if ax is None:
        fig = plt.figure(figsize=(8, 8), facecolor="black")
        ax = fig.add_subplot(projection="polar")
    fig = ax.figure
    ax.set_facecolor("black")
    ax.set_theta_zero_location("N")
    ax.set_theta_direction(1)  # counter-clockwise: east to the left when north is up
    ax.scatter(azimuth[order], 90.0 - altitude[order], s=marker_sizes(magnitude[order], limit),
               c=colours[order], linewidths=0)
    ax.set_rlim(0.0, 90.0)
    ax.set_rticks([30.0, 60.0, 90.0])
    ax.set_yticklabels(["60°", "30°", "0°"], color="0.5", fontsize=7)
    ax.set_xticks(np.deg2rad([0.0, 90.0, 180.0, 270.0]))
    ax.set_xticklabels(["N", "E", "S", "W"], color="0.8")
    ax.grid(color="0.25", linewidth=0.5)
    if title is None:
        params = observation.attrs
        title = (f"{np.datetime_as_string(frame['time'].values, unit='m')} UTC, "
                 f"lat {params.get('parameter_lat_deg', '?')}°, "
                 f"lon {params.get('parameter_lon_deg', '?')}° — {int(keep.sum())} stars "
                 f"brighter than {limit:.1f} mag")
    ax.set_title(title, color="0.9", fontsize=9)
    return fig
