r"""``skytorch ephemeris``: Sun and Moon positions over a time range, written to netCDF.

Examples
--------
::

    skytorch ephemeris --start 2015-09-27T00:00 --end 2015-09-29T00:00 --step 10min \
        --lat 48.14 --lon 11.58 -o out/ephemeris.nc
    skytorch ephemeris --times 2024-03-20T03:06Z 2024-06-20T20:51Z -o seasons.nc
"""

from __future__ import annotations

import argparse
import logging
import re

import numpy as np

logger = logging.getLogger(__name__)

#: largest number of instants one call may produce (about 2 years at one-minute steps)
MAX_TIMES = 1_000_000

_STEP_UNITS = {
    "s": "s", "sec": "s", "second": "s", "seconds": "s",
    "min": "m", "minute": "m", "minutes": "m",
    "h": "h", "hour": "h", "hours": "h",
    "d": "D", "day": "D", "days": "D",
}
_STEP = re.compile(r"^\s*(\d+)\s*([a-z]+)\s*$")


def parse_step(text: str) -> np.timedelta64:
    """Parse a positive step such as ``"10min"``, ``"30s"``, ``"1h"`` or ``"2d"``."""
    match = _STEP.match(text.lower())
    if not match or match.group(2) not in _STEP_UNITS:
        raise ValueError(
            f"--step must be a positive integer with a unit (s, min, h, d), e.g. '10min'; "
            f"got {text!r}"
        )
    count = int(match.group(1))
    if count <= 0:
        raise ValueError(f"--step must be positive; got {text!r}")
    return np.timedelta64(count, _STEP_UNITS[match.group(2)]).astype("timedelta64[ns]")


def time_range(start: str, end: str, step: str) -> np.ndarray:
    """Instants from ``start`` to ``end`` inclusive, ``step`` apart (UTC datetime64[ns])."""
    from skytorch.ephemeris import parse_times

    first, last = parse_times([start, end])
    delta = parse_step(step)
    if last < first:
        raise ValueError(f"--end ({end}) is before --start ({start})")
    count = int((last - first) // delta) + 1
    if count > MAX_TIMES:
        raise ValueError(
            f"{count} instants requested; at most {MAX_TIMES} per call (use a larger --step)"
        )
    return first + delta * np.arange(count)


def requested_times(args: argparse.Namespace):
    """Return the instants of ``--times`` or of ``--start``/``--end``/``--step`` (one only)."""
    if args.times:
        if args.start or args.end:
            raise ValueError("give either --times or --start/--end, not both")
        return args.times
    if args.start and args.end:
        return time_range(args.start, args.end, args.step)
    raise ValueError("give --start and --end (with --step), or --times")


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``skytorch ephemeris``."""
    when = parser.add_argument_group("times (UTC, ISO 8601)")
    when.add_argument("--start", help="first instant, e.g. 2015-09-27T00:00")
    when.add_argument("--end", help="last instant (inclusive)")
    when.add_argument("--step", default="1h", help="spacing: 30s, 10min, 1h, 1d (default 1h)")
    when.add_argument("--times", nargs="+", metavar="TIME",
                      help="explicit instants instead of --start/--end/--step")
    where = parser.add_argument_group("observer (optional; adds altitude and azimuth)")
    where.add_argument("--lat", type=float, help="geodetic latitude [deg], -90..90")
    where.add_argument("--lon", type=float, help="east longitude [deg], -180 <= lon < 360")
    where.add_argument("--elevation", type=float, default=0.0,
                       help="height above the WGS84 ellipsoid [m] (default 0)")
    parser.add_argument("-o", "--output", required=True, help="netCDF file to write")


def run(args: argparse.Namespace) -> int:
    """Compute the Sun and Moon Dataset and write it; 0 on success."""
    from skytorch.dataset import to_netcdf
    from skytorch.ephemeris import sun_moon

    times = requested_times(args)
    dataset = sun_moon(times, lat_deg=args.lat, lon_deg=args.lon, elevation_m=args.elevation)
    path = to_netcdf(dataset, args.output)
    logger.info("wrote %d instants to %s", dataset.sizes["time"], path)
    print(f"wrote {path} ({dataset.sizes['time']} times)")
    return 0
