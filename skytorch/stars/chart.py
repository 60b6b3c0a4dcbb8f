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

from skytorch._validate import check_int

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
                  ax=None, title: str | None = None, observer_index: int | None = None):
    """Plot the stars of :func:`skytorch.stars.observe` at one time on an all-sky chart.

    Parameters
    ----------
    observation : xarray.Dataset
        Output of :func:`skytorch.stars.observe`.
    time_index : int
        Which time to draw, in [0, number of times).
    limit : float, optional
        Faintest magnitude drawn (after extinction) [mag]; default the Dataset's
        ``limiting_magnitude`` at that time (per star where the observation had a
        per-direction background).
    ax : matplotlib polar Axes, optional
        Drawn into a new figure when omitted.
    title : str, optional
        Default: the time and the observer.
    observer_index : int, optional
        Which observer to draw, for an observation of several (required then).

    Returns
    -------
    matplotlib.figure.Figure
        Zenith-equidistant projection (radius 90° − altitude), north up and east to the
        left as seen looking up; marker area from the magnitude after extinction, colour
        the apparent one (``color``), black background. An elevated observer's stars
        below 0° (down to the dip of the horizon) lie outside the 0° circle.
    """
    import matplotlib.pyplot as plt

    frame = _frame(observation, time_index, observer_index)
    per_star = limit is None and np.ndim(frame["limiting_magnitude"]) > 0
    limits = np.broadcast_to(frame["limiting_magnitude"].values if limit is None
                             else float(limit), (frame.sizes["star"],))
    keep = (frame["above_horizon"].values & (frame["magnitude"].values <= limits))
    altitude = frame["altitude"].values[keep]
    azimuth = np.deg2rad(frame["azimuth"].values[keep])
    magnitude = frame["magnitude"].values[keep]
    colours = np.clip(frame["color"].values[keep], 0.0, 1.0)
    # the marker scale: the faintest limit drawn
    if not per_star:
        size_limit = float(frame["limiting_magnitude"]) if limit is None else float(limit)
    else:
        size_limit = float(np.max(limits)) if limits.size else 6.5
    order = np.argsort(-magnitude)  # faint first, bright on top
    if ax is None:
        fig = plt.figure(figsize=(8, 8), facecolor="black")
        ax = fig.add_subplot(projection="polar")
    fig = ax.figure
    ax.set_facecolor("black")
    ax.set_theta_zero_location("N")
    ax.set_theta_direction(1)  # counter-clockwise: east to the left when north is up
    ax.scatter(azimuth[order], 90.0 - altitude[order],
               s=marker_sizes(magnitude[order], size_limit), c=colours[order], linewidths=0)
    ax.set_rlim(0.0, max(90.0, 90.0 - float(altitude.min())) if altitude.size else 90.0)
    ax.set_rticks([30.0, 60.0, 90.0])
    ax.set_yticklabels(["60°", "30°", "0°"], color="0.5", fontsize=7)
    ax.set_xticks(np.deg2rad([0.0, 90.0, 180.0, 270.0]))
    ax.set_xticklabels(["N", "E", "S", "W"], color="0.8")
    ax.grid(color="0.25", linewidth=0.5)
    if title is None:
        params = observation.attrs
        site = (f"lat {float(frame['lat'])}°, lon {float(frame['lon'])}°"
                if "lat" in frame.coords else
                f"lat {params.get('parameter_lat_deg', '?')}°, "
                f"lon {params.get('parameter_lon_deg', '?')}°")
        brighter = ("brighter than the limit of their direction" if per_star
                    else f"brighter than {size_limit:.1f} mag")
        title = (f"{np.datetime_as_string(frame['time'].values, unit='m')} UTC, {site} — "
                 f"{int(keep.sum())} stars {brighter}")
    ax.set_title(title, color="0.9", fontsize=9)
    return fig


def _frame(observation: xr.Dataset, time_index: int, observer_index: int | None):
    """One time (and one observer) of an observation, checked."""
    if not isinstance(observation, xr.Dataset) or "time" not in observation.dims:
        raise TypeError("observation must be the xarray.Dataset of skytorch.stars.observe; "
                        f"got {type(observation).__name__}")
    n_time = observation.sizes["time"]
    frame = observation.isel(time=check_int("time_index", time_index, 0, n_time - 1))
    if "observer" in observation.dims:
        n = observation.sizes["observer"]
        if observer_index is None:
            raise ValueError(f"observation holds {n} observers: pass observer_index in "
                             f"[0, {n - 1}]")
        frame = frame.isel(observer=check_int("observer_index", observer_index, 0, n - 1))
    elif observer_index is not None:
        raise ValueError("observer_index: the observation holds one observer")
    return frame
