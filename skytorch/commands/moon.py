r"""``skytorch moon``: phase, illumination, bright limb, libration, brightness and disc images.

Examples
--------
::

    skytorch moon --time 2025-09-07T20:00 --lat 52.5 --lon 13.4 -o moon.nc --png moon.png
    skytorch moon --start 2025-09-01 --end 2025-09-30 --step 1d --lat 52.5 --lon 13.4 \
        -o september.nc --pixels 32
"""

from __future__ import annotations

import argparse
import logging

import numpy as np

from skytorch.commands.stars import add_time_and_observer, times_from

logger = logging.getLogger(__name__)

#: most disc images drawn side by side in the PNG (evenly spaced over the times)
MAX_PANELS = 8


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``skytorch moon``."""
    add_time_and_observer(parser, step="1d")
    parser.add_argument("--pixels", type=int, default=64,
                        help="pixels across the lunar disc image (default 64)")
    parser.add_argument("-o", "--output", required=True, help="netCDF file to write")
    parser.add_argument("--png", help="disc images with phase and libration (PNG)")


def moon_dataset(times, lat_deg: float, lon_deg: float, elevation_m: float = 0.0,
                 n_pixels: int = 64):
    """Geometry, brightness and disc images of the Moon over ``time`` in one Dataset.

    Returns
    -------
    xarray.Dataset
        :func:`skytorch.moon.moon_geometry` (topocentric phase, illuminated fraction,
        magnitude, apparent diameter and parallactic angle; geocentric bright limb, total
        and optical libration, axis position angle) merged with
        :func:`skytorch.moon.datasets.moon_disc_images` (``radiance`` over time, y, x,
        wavelength).
    """
    from skytorch._validate import check_int
    from skytorch.moon.datasets import moon_disc_images, moon_geometry

    geometry = moon_geometry(times, lat_deg, lon_deg, elevation_m)
    images = moon_disc_images(geometry, n_pixels=check_int("n_pixels", n_pixels, 4, 4096))
    merged = geometry.merge(images, combine_attrs="override")
    merged.attrs["title"] = "The Moon: geometry, brightness and disc images"
    merged.attrs["references"] = geometry.attrs["references"]
    return merged


def summary(ds) -> str:
    """One line per time (at most 10): phase, illumination, magnitude, libration."""
    lines = []
    for index in range(min(ds.sizes["time"], 10)):
        frame = ds.isel(time=index)
        lines.append(
            f"{np.datetime_as_string(frame['time'].values, unit='m')} UTC  "
            f"phase {float(frame.phase_angle):6.2f}°  k {float(frame.illuminated_fraction):.4f}"
            f"  χ {float(frame.bright_limb_angle):6.2f}°  V {float(frame.magnitude):6.2f}  "
            f"libration l {float(frame.libration_longitude):+.3f}° "
            f"b {float(frame.libration_latitude):+.3f}°")
    if ds.sizes["time"] > 10:
        lines.append(f"... {ds.sizes['time'] - 10} more times")
    return "\n".join(lines)


def figure(ds):
    """Disc images (sRGB) of up to :data:`MAX_PANELS` times, labelled.

    Each panel is exposed to its brightest pixel (the magnitude in the label gives the
    brightness), so thin crescents and the earthlit new Moon stay visible.
    """
    import torch

    from skytorch.plot import eclipse_strip
    from skytorch.spectrum import spectrum_to_xyz, xyz_to_srgb

    n_time = ds.sizes["time"]
    picks = np.unique(np.linspace(0, n_time - 1, min(n_time, MAX_PANELS)).round().astype(int))
    radiance = torch.tensor(np.array(ds["radiance"].values[picks]))
    xyz = spectrum_to_xyz(radiance, torch.tensor(np.array(ds["wavelength"].values)))
    peak = xyz[..., 1].flatten(1).amax(dim=1).clamp_min(torch.finfo(xyz.dtype).tiny)
    rgb = xyz_to_srgb(xyz / peak[:, None, None, None], gamma=True, clip=True).numpy()
    labels = []
    for index in picks:
        frame = ds.isel(time=int(index))
        labels.append(f"{np.datetime_as_string(frame['time'].values, unit='m')}\n"
                      f"k {float(frame.illuminated_fraction):.3f}, "
                      f"V {float(frame.magnitude):.2f}\n"
                      f"l {float(frame.libration_longitude):+.2f}°, "
                      f"b {float(frame.libration_latitude):+.2f}°")
    fig = eclipse_strip(rgb, labels)
    fig.set_size_inches(1.9 * len(picks), 2.6)
    fig.suptitle("The Moon (north up, east left; each panel exposed to its brightest "
                 "pixel)", fontsize=8)
    return fig


def run(args: argparse.Namespace) -> int:
    """Compute the Moon Dataset, write netCDF (and the PNG); 0 on success."""
    from skytorch.dataset import to_netcdf

    ds = moon_dataset(times_from(args), args.lat, args.lon, args.elevation, args.pixels)
    path = to_netcdf(ds, args.output)
    logger.info("wrote %s (%d times)", path, ds.sizes["time"])
    if args.png:
        from skytorch.plot import savefig

        savefig(figure(ds), args.png, dpi=130)
    print(f"{path}: {ds.sizes['time']} times\n{summary(ds)}")
    return 0
