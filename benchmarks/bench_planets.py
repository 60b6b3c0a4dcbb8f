"""Benchmark of the planets: skytorch.stars.planets vs skyfield, one day at 1-min steps.

Workload: the seven planets at 1 440 times. Rows:

* ``skytorch.stars.planets`` — the whole Dataset (apparent and astrometric places,
  heliocentric geometry at the emission time, phase, elongation, diameter, Mallama &
  Hilton 2018 magnitudes), geocentric and with an observer's altitude and azimuth;
* one instant (what a scene adds per frame);
* skyfield — ``earth.at(t).observe(planet)``, ``apparent().radec(epoch="date")`` and
  ``planetary_magnitude`` (Sun at the barycentre), the nearest it offers.

Run: ``python benchmarks/bench_planets.py [--append]``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._harness import (  # noqa: E402
    argument_parser,
    machine_description,
    markdown_table,
    median_seconds,
    parse_arguments,
    report,
)

LAT, LON = 52.5, 13.4
TIMES = np.datetime64("2021-01-01T00:00") + np.arange(1440) * np.timedelta64(1, "m")


def main(argv: list[str] | None = None) -> int:
    parser = argument_parser(__doc__.splitlines()[0], repeat=5)
    args = parse_arguments(parser, argv)

    from skyfield.magnitudelib import planetary_magnitude

    from skytorch.ephemeris import load_ephemeris, skyfield_time
    from skytorch.stars.planets import _TARGETS, PLANETS, planets

    ephemeris = load_ephemeris()

    def sky():
        t = skyfield_time(TIMES)
        earth = ephemeris["earth"].at(t)
        for name in PLANETS:
            astrometric = earth.observe(ephemeris[_TARGETS[name]])
            astrometric.apparent().radec(epoch="date")
            planetary_magnitude(astrometric)

    rows = [
        {"method": "skytorch planets, 1 440 times (geocentric)",
         "median [s]": median_seconds(lambda: planets(TIMES), repeat=args.repeat)},
        {"method": "skytorch planets, 1 440 times + observer alt/az",
         "median [s]": median_seconds(lambda: planets(TIMES, LAT, LON), repeat=args.repeat)},
        {"method": "skytorch planets, one instant",
         "median [s]": median_seconds(lambda: planets(TIMES[:1]), repeat=args.repeat)},
        {"method": "skyfield observe + apparent radec + planetary_magnitude, 1 440 times",
         "median [s]": median_seconds(sky, repeat=args.repeat)},
    ]
    reference = rows[-1]["median [s]"]
    for row in rows:
        row["ratio to skyfield"] = row["median [s]"] / reference
    load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    report(f"\n## Planets ({machine_description()})\n\nSeven planets, load average {load}. "
           "skyfield's row computes less (no heliocentric geometry at the emission time, "
           f"no elongation or diameter).\n\n{markdown_table(rows)}\n", args.append)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
