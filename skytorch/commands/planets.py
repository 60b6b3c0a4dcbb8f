r"""``skytorch planets``: places, phases and V magnitudes of the planets, written to netCDF.

Examples
--------
::

    skytorch planets --start 2020-04-03T17:00 --end 2020-04-03T23:00 --step 10min \
        --lat 48.85 --lon 2.35 --atmosphere -o out/planets.nc
    skytorch planets --times 2026-08-12T18:29:18 --bodies venus jupiter -o totality.nc
"""

from __future__ import annotations

import argparse
import logging

from skytorch.commands.ephemeris import configure as configure_times
from skytorch.commands.ephemeris import requested_times

logger = logging.getLogger(__name__)


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``skytorch planets``."""
    from skytorch.stars.planets import PLANETS

    configure_times(parser)
    parser.add_argument("--bodies", nargs="+", choices=PLANETS, default=list(PLANETS),
                        help="planets (default all seven)")
    parser.add_argument("--atmosphere", action="store_true",
                        help="refract and extinguish through Atmosphere.earth() (needs "
                             "--lat and --lon)")
    parser.add_argument("--turbidity", type=float,
                        help="aerosol turbidity of that atmosphere (default 2; needs "
                             "--atmosphere)")


def run(args: argparse.Namespace) -> int:
    """Compute the planets' Dataset and write it; 0 on success."""
    from skytorch.atmosphere import Atmosphere
    from skytorch.dataset import to_netcdf
    from skytorch.stars.planets import planets

    times = requested_times(args)
    if args.turbidity is not None and not args.atmosphere:
        raise ValueError(f"--turbidity {args.turbidity:g} sets the atmosphere, which needs "
                         "--atmosphere")
    atmosphere = (Atmosphere.earth(turbidity=2.0 if args.turbidity is None else args.turbidity)
                  if args.atmosphere else None)
    dataset = planets(times, lat_deg=args.lat, lon_deg=args.lon, elevation_m=args.elevation,
                      bodies=tuple(args.bodies), atmosphere=atmosphere)
    path = to_netcdf(dataset, args.output)
    logger.info("wrote %d instants x %d planets to %s", dataset.sizes["time"],
                dataset.sizes["planet"], path)
    print(f"wrote {path} ({dataset.sizes['time']} times, {dataset.sizes['planet']} planets)")
    return 0
