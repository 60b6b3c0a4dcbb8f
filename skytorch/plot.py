"""Matplotlib figures shared by the modules: all-sky images, profiles, light curves, strips.

Every function draws on a given ``axes`` (or makes a figure when none is given) and
returns the axes, so figures can be composed; :func:`savefig` writes PNG files with
the project's settings. Matplotlib is imported only when a function is called, with the
non-interactive ``Agg`` backend unless another one is already active.

Examples
--------
>>> import numpy as np
>>> from skytorch import plot
>>> axes = plot.profile(np.linspace(0, 1, 5), {"a": np.arange(5.0)}, xlabel="x")
>>> axes.get_xlabel()
'x'
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _axes(axes, figsize=(6, 4)):
    if axes is not None:
        return axes
    _, axes = _pyplot().subplots(figsize=figsize)
    return axes


def savefig(figure, path, dpi: int = 110) -> Path:
    """Save a figure as PNG (parent folders created) and close it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=dpi, bbox_inches="tight")
    _pyplot().close(figure)
    return path


def fisheye_xy(altitude_deg, azimuth_deg):
    """Image coordinates (x, y) of directions in the all-sky view (north up, east left)."""
    radius = (90.0 - np.asarray(altitude_deg, dtype=float)) / 90.0
    azimuth = np.radians(np.asarray(azimuth_deg, dtype=float))
    return -radius * np.sin(azimuth), radius * np.cos(azimuth)


def all_sky(dataset, axes=None, *, title: str | None = None, exposure=None,
            night: bool = False, compass: bool = True, markers: dict | None = None):
    """Plot an all-sky (fisheye) or panorama image of a rendered scene (tone-mapped).

    Parameters
    ----------
    dataset : xarray.Dataset
        Output of :meth:`skytorch.Scene.render` with ``xyz`` and ``solid_angle``.
    axes : matplotlib Axes, optional
    title : str, optional
    exposure : float, optional
        Exposure [cd^-1 m^2] (default automatic, :func:`skytorch.scene.tonemap.tonemap`).
    night : bool
        Night-vision rendering.
    compass : bool
        Label N, E, S, W on a fisheye.
    markers : dict, optional
        ``{label: (altitude_deg, azimuth_deg)}`` circled and labelled on a fisheye
        (sources smaller than a screen pixel stay findable).
    """
    import torch

    from skytorch.scene.tonemap import tonemap

    axes = _axes(axes, (5, 5))
    xyz = torch.as_tensor(dataset["xyz"].values)
    valid = torch.as_tensor(dataset["solid_angle"].values > 0)
    rgb, _ = tonemap(xyz, valid, exposure=exposure, night=night)
    image = rgb.numpy()
    if dataset["xyz"].dims[0] == "elevation":
        axes.imshow(image[::-1], extent=(0, 360, 0, 90), aspect="auto")
        axes.set_xlabel("azimuth [degree]")
        axes.set_ylabel("elevation [degree]")
    else:
        axes.imshow(image, extent=(-1, 1, -1, 1), interpolation="nearest")
        axes.set_axis_off()
        if compass:
            for text, (x, y) in {"N": (0, 1.06), "S": (0, -1.1), "E": (-1.1, 0),
                                 "W": (1.06, 0)}.items():
                axes.text(x, y, text, color="0.3", ha="center", va="center", fontsize=8)
        for label, (altitude, azimuth) in (markers or {}).items():
            x, y = fisheye_xy(altitude, azimuth)
            axes.scatter([x], [y], s=120, facecolors="none", edgecolors="orange", lw=0.8)
            axes.annotate(label, (x, y), xytext=(6, 6), textcoords="offset points",
                          color="orange", fontsize=7)
    if title:
        axes.set_title(title, fontsize=9)
    return axes


def profile(x, curves: dict, axes=None, *, xlabel: str = "", ylabel: str = "",
            log: bool = False, title: str | None = None, styles: dict | None = None):
    """Curves ``{label: y}`` against ``x`` (optionally on a log y axis)."""
    axes = _axes(axes)
    styles = styles or {}
    for label, y in curves.items():
        draw = axes.semilogy if log else axes.plot
        draw(np.asarray(x), np.asarray(y), label=label, **styles.get(label, {}))
    axes.set_xlabel(xlabel)
    axes.set_ylabel(ylabel)
    axes.grid(alpha=0.3)
    if len(curves) > 1:
        axes.legend(fontsize=8)
    if title:
        axes.set_title(title, fontsize=10)
    return axes


def obscuration_map(dataset, axes=None, *, observer=None, title: str | None = None):
    """Plot the Sun's obscuration over latitude and longitude, on the day side only.

    Parameters
    ----------
    dataset : xarray.Dataset
        From :func:`skytorch.eclipse.obscuration_map` (``obscuration``, ``sun_altitude``
        over ``latitude``, ``longitude``).
    axes : matplotlib Axes, optional
    observer : (float, float), optional
        (latitude, longitude) [degree] marked with a cross.
    title : str, optional
    """
    axes = _axes(axes, figsize=(9, 4.5))
    shown = dataset.obscuration.where(dataset.sun_altitude > 0)
    image = axes.pcolormesh(dataset.longitude, dataset.latitude, shown, shading="auto",
                            vmin=0.0, vmax=1.0, cmap="magma_r")
    if observer is not None:
        axes.plot(observer[1], observer[0], "c+", markersize=12)
    axes.set_xlabel("longitude [degree east]")
    axes.set_ylabel("latitude [degree north]")
    if title:
        axes.set_title(title)
    axes.figure.colorbar(image, ax=axes, label="obscuration")
    return axes


def light_curve(times, magnitudes: dict, axes=None, *, ylabel: str = "V [mag]",
                title: str | None = None, events: dict | None = None):
    """Magnitudes ``{label: values}`` over times (inverted y axis), with event markers."""
    axes = _axes(axes, (7, 4))
    times = np.asarray(times)
    hours = (times - times[0]) / np.timedelta64(1, "h")
    for label, values in magnitudes.items():
        axes.plot(hours, np.asarray(values), label=label)
    for name, when in (events or {}).items():
        position = (np.datetime64(when) - times[0]) / np.timedelta64(1, "h")
        axes.axvline(position, color="0.6", lw=0.7, ls=":")
        axes.text(position, 1.0, name, transform=axes.get_xaxis_transform(), fontsize=7,
                  ha="center", va="bottom", color="0.4")
    axes.invert_yaxis()
    axes.set_xlabel(f"hours since {np.datetime_as_string(times[0], unit='m')} UTC")
    axes.set_ylabel(ylabel)
    axes.grid(alpha=0.3)
    axes.legend(fontsize=8)
    if title:
        axes.set_title(title, fontsize=10, pad=14)
    return axes


def eclipse_strip(images, labels, figure=None):
    """Plot a row of disc images ``(n, y, x, 3)`` in [0, 1] with labels; return the figure."""
    plt = _pyplot()
    images = np.asarray(images)
    n = images.shape[0]
    if figure is None:
        figure = plt.figure(figsize=(1.3 * max(n, 1), 1.6))
    for index in range(n):
        axes = figure.add_subplot(1, n, index + 1)
        axes.imshow(np.clip(images[index], 0.0, 1.0), origin="lower")
        axes.set_axis_off()
        axes.set_title(labels[index], fontsize=7)
    return figure
