"""``skytorch demo``: the end-to-end demonstration job run by ``make demo``.

The job follows the night of the 2015-09-28 total lunar eclipse: Sun and Moon over the
night seen from a European site, written as netCDF with a PNG of the Moon's altitude.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

logger = logging.getLogger(__name__)

#: the demonstration site (Berlin) and night
SITE = {"lat_deg": 52.52, "lon_deg": 13.40, "elevation_m": 34.0}
NIGHT = ("2015-09-27T18:00", "2015-09-28T06:00")


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``skytorch demo``."""
    parser.add_argument("--output-dir", type=Path, default=Path("out"),
                        help="where netCDF and PNG files are written (default out/)")
    parser.add_argument("--quick", action="store_true", help="reduced resolution (tests)")


def _ephemeris_part(output_dir: Path, quick: bool) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from skytorch.dataset import to_netcdf
    from skytorch.ephemeris import parse_times, sun_moon

    start, end = parse_times(list(NIGHT))
    step = np.timedelta64(30 if quick else 5, "m")
    times = np.arange(start, end + step, step)
    ds = sun_moon(times, **SITE)
    path = to_netcdf(ds, output_dir / "eclipse_night_ephemeris.nc")
    figure, axes = plt.subplots(figsize=(7, 3.5))
    axes.plot(ds["time"].values, ds["moon_altitude"].values, label="Moon")
    axes.plot(ds["time"].values, ds["sun_altitude"].values, label="Sun")
    axes.axhline(0.0, color="grey", lw=0.5)
    axes.set_ylabel("altitude [degree]")
    axes.set_title("Berlin, night of the 2015-09-28 lunar eclipse")
    axes.legend()
    figure.autofmt_xdate()
    png = output_dir / "eclipse_night_ephemeris.png"
    figure.savefig(png, dpi=110, bbox_inches="tight")
    plt.close(figure)
    highest = int(np.argmax(ds["moon_altitude"].values))
    return [
        f"ephemeris: {ds.sizes['time']} times -> {path}, {png}",
        f"  Moon highest at {str(ds['time'].values[highest])[:16]} UTC, "
        f"altitude {float(ds['moon_altitude'][highest]):.1f} deg",
    ]


def run(args: argparse.Namespace) -> int:
    """Run the demonstration job and print a short summary."""
    output_dir = Path(args.output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    lines = ["skytorch demo: the 2015-09-28 total lunar eclipse"]
    lines += _ephemeris_part(output_dir, args.quick)
    print("\n".join(lines))
    return 0
