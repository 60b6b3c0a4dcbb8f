r"""``skytorch stars``: apparent star positions and magnitudes, netCDF and an all-sky chart.

Examples
--------
::

    skytorch stars --time 2025-09-07T20:00 --lat 52.5 --lon 13.4 -o stars.nc --png chart.png
    skytorch stars --start 2025-09-07T18:00 --end 2025-09-08T04:00 --step 10min \
        --lat 28.76 --lon -17.89 --elevation 2400 --turbidity 1.5 -o lapalma.nc
"""

from __future__ import annotations

import argparse
import logging

logger = logging.getLogger(__name__)


def add_time_and_observer(parser: argparse.ArgumentParser, step: str = "10min") -> None:
    """``--time`` or ``--start/--end/--step`` (UTC) and ``--lat/--lon/--elevation``."""
    when = parser.add_argument_group("times (UTC, ISO 8601)")
    when.add_argument("--time", nargs="+", metavar="TIME", help="one or more instants")
    when.add_argument("--start", help="first instant of a range")
    when.add_argument("--end", help="last instant of a range (inclusive)")
    when.add_argument("--step", help=f"spacing of a range (default {step})")
    parser.set_defaults(default_step=step)
    where = parser.add_argument_group("observer")
    where.add_argument("--lat", type=float, required=True, help="geodetic latitude [deg]")
    where.add_argument("--lon", type=float, required=True, help="east longitude [deg]")
    where.add_argument("--elevation", type=float, default=0.0,
                       help="height above the ellipsoid [m] (default 0)")


def times_from(args: argparse.Namespace):
    """Return the instants given by :func:`add_time_and_observer`'s arguments."""
    from skytorch.commands.ephemeris import time_range

    if args.time:
        given = [f"--{name}" for name in ("start", "end", "step")
                 if getattr(args, name) is not None]
        if given:
            raise ValueError(f"{', '.join(given)}: a range, which --time replaces (give one "
                             "or the other)")
        return args.time
    if args.start and args.end:
        return time_range(args.start, args.end,
                          args.default_step if args.step is None else args.step)
    raise ValueError("give --time, or --start and --end")


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``skytorch stars``."""
    add_time_and_observer(parser)
    sky = parser.add_argument_group("catalogue and sky")
    sky.add_argument("--limit-magnitude", type=float, default=6.5,
                     help="faintest catalogue V magnitude (default 6.5)")
    sky.add_argument("--bsc5", help="read this Yale Bright Star Catalogue file instead of "
                                    "the bundled Hipparcos 2")
    sky.add_argument("--turbidity", type=float,
                     help="Preetham turbidity of the atmosphere (default 2)")
    sky.add_argument("--ozone", type=float, help="ozone column [DU] (default 300)")
    sky.add_argument("--no-atmosphere", action="store_true",
                     help="no refraction or extinction (magnitudes above the atmosphere)")
    sky.add_argument("--no-refraction", action="store_true", help="geometric altitudes")
    sky.add_argument("--sky-brightness", type=float, default=22.0,
                     help="sky background [V mag/arcsec^2] for the limiting magnitude")
    sky.add_argument("--visibility", choices=("schaefer1990", "muller2012"),
                     default="schaefer1990", help="visibility model (default schaefer1990)")
    parser.add_argument("-o", "--output", required=True, help="netCDF file to write")
    parser.add_argument("--png", help="all-sky chart of the first time (PNG)")


def run(args: argparse.Namespace) -> int:
    """Compute the observation, write netCDF (and the chart); 0 on success."""
    from skytorch.dataset import to_netcdf
    from skytorch.stars import bright_stars, observe, read_bsc5

    times = times_from(args)
    catalog = (read_bsc5(args.bsc5, args.limit_magnitude) if args.bsc5
               else bright_stars(args.limit_magnitude))
    if args.no_atmosphere:
        given = [f"--{name}" for name in ("turbidity", "ozone") if getattr(args, name) is not None]
        if given:
            raise ValueError(f"{', '.join(given)}: settings of the atmosphere, which "
                             "--no-atmosphere leaves out")
        atmosphere = False
    else:
        from skytorch.atmosphere import Atmosphere

        atmosphere = Atmosphere.earth(
            turbidity=2.0 if args.turbidity is None else args.turbidity,
            ozone_du=300.0 if args.ozone is None else args.ozone)
    ds = observe(catalog, times, args.lat, args.lon, args.elevation, atmosphere=atmosphere,
                 refraction=not args.no_refraction,
                 sky_brightness_mag_arcsec2=args.sky_brightness, visibility=args.visibility)
    path = to_netcdf(ds, args.output)
    logger.info("wrote %s (%d times, %d stars)", path, ds.sizes["time"], ds.sizes["star"])
    if args.png:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from skytorch.stars.chart import all_sky_chart

        fig = all_sky_chart(ds)
        fig.savefig(args.png, dpi=120, facecolor="black", bbox_inches="tight")
        plt.close(fig)
    print(f"{path}: {ds.sizes['star']} stars, {ds.sizes['time']} times; visible now: "
          f"{int(ds['n_visible'][0])} (limit {float(ds['limiting_magnitude'][0]):.2f} mag)")
    return 0
