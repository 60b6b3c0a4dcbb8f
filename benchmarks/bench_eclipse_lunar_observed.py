"""Benchmark of the lunar-eclipse issue targets: the observed set modelled, and the search.

Rows:

* the whole observed set modelled — every eclipse of ``observed_lunar_eclipses()`` with a
  V (or a magnitude below the full Moon) through ``lunar_light_curve(date,
  shadow=eclipse_shadow(date, terminator=...), n_times=48, table_n_v=192)``, as in
  ``experiments/lunar_eclipse_comparison.py`` (target <= 60 s), with one global limb
  atmosphere, the five latitude bands' azimuthal mean and the bands resolved in direction
  (13 position angles);
* ``skytorch.eclipse.lunar_eclipses`` 1950-2050 with contacts, and skyfield's
  ``eclipselib.lunar_eclipses`` over the same century (no contacts), side by side in one
  run (target: skytorch at least as fast).

Run: ``python benchmarks/bench_eclipse_lunar_observed.py [--append]``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._harness import (  # noqa: E402
    argument_parser,
    machine_description,
    markdown_table,
    median_seconds,
    parse_arguments,
    report,
)

TARGET_OBSERVED_SECONDS = 60.0


def main(argv: list[str] | None = None) -> int:
    parser = argument_parser(__doc__.splitlines()[0], repeat=3, threads=1)
    parser.add_argument("--search-only", action="store_true",
                        help="time only the two eclipse searches")
    args = parse_arguments(parser, argv)

    from skyfield import eclipselib
    from skyfield.api import load

    from skytorch.eclipse import (
        eclipse_shadow,
        lunar_eclipses,
        lunar_light_curve,
        observed_lunar_eclipses,
    )
    from skytorch.ephemeris import load_ephemeris

    observed = observed_lunar_eclipses()
    keep = (np.isfinite(observed.v_magnitude.values)
            | np.isfinite(observed.v_below_full_moon.values))
    dates = [np.datetime_as_string(d, "D") for d in observed.eclipse.values[keep]]

    def model_all(terminator):
        def run():
            for day in dates:
                lunar_light_curve(day, shadow=eclipse_shadow(day, terminator=terminator),
                                  n_times=48, table_n_v=192)
        return run

    ephemeris = load_ephemeris()
    timescale = load.timescale()
    t0, t1 = timescale.utc(1950, 1, 1), timescale.utc(2050, 1, 1)
    rows = [] if args.search_only else [
        {"case": f"observed set modelled ({len(dates)} eclipses), terminator={terminator}",
         "median [s]": median_seconds(model_all(terminator), repeat=1, warmup=0)}
        for terminator in ("global", "latitude_bands_mean", "latitude_bands")]
    rows += [
        {"case": "skytorch lunar_eclipses 1950-2050 (contacts)",
         "median [s]": median_seconds(lambda: lunar_eclipses("1950-01-01", "2050-01-01"),
                                      repeat=args.repeat, warmup=1)},
        {"case": "skyfield eclipselib.lunar_eclipses 1950-2050",
         "median [s]": median_seconds(
             lambda: eclipselib.lunar_eclipses(t0, t1, ephemeris),
             repeat=args.repeat, warmup=1)},
    ]
    ratio = rows[-2]["median [s]"] / rows[-1]["median [s]"]
    load_avg = " ".join(f"{x:.1f}" for x in os.getloadavg())
    observed_text = ("" if args.search_only else
                     f"Observed set: {rows[0]['median [s]']:.1f} s (target <= "
                     f"{TARGET_OBSERVED_SECONDS:.0f} s). ")
    summary = (f"Load average {load_avg}. {observed_text}Search: skytorch / skyfield "
               f"= {ratio:.2f} (target <= 1).")
    report(f"\n## Lunar eclipses: observed set and search ({machine_description()})\n\n"
           f"{summary}\n\n{markdown_table(rows)}\n", args.append)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
