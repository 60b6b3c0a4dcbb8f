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
  run (target: skytorch at least as fast);
* ``--gradients``: the 2019-01-21 light curve (the retrieval's model: the date's shadow
  with the limb cloud profile, 48 times, table 64) forward, and forward + backward with
  respect to the stratospheric and tropospheric AOD and the ozone column, alternating
  (target: with gradients <= 2x forward); and the three-parameter retrieval from the
  2019-01-21 photometric light curve (six samples, ``retrieve_atmosphere`` defaults;
  target <= 30 s).

Run: ``python benchmarks/bench_eclipse_lunar_observed.py [--append] [--search-only |
--gradients]``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._harness import (  # noqa: E402
    alternating_medians,
    argument_parser,
    machine_description,
    markdown_table,
    median_seconds,
    parse_arguments,
    report,
)

TARGET_OBSERVED_SECONDS = 60.0
TARGET_GRADIENT_RATIO = 2.0
TARGET_RETRIEVAL_SECONDS = 30.0
PHOTOMETRY_2019 = (Path(__file__).resolve().parents[1] / "tests" / "data"
                   / "lunar_eclipse_2019_01_21_photometry.csv")


def gradient_rows(repeat: int) -> tuple[list[dict[str, object]], str]:
    """Light curve forward and with gradients (alternating), and the 3-parameter retrieval."""
    import torch
    import xarray as xr

    from experiments.lunar_eclipse_comparison import _read_photometry
    from skytorch.eclipse import (
        eclipse_atmosphere,
        eclipse_shadow,
        lunar_light_curve,
        retrieve_atmosphere,
    )

    date = "2019-01-21"
    start = {"stratospheric_aod_550": 0.01, "tropospheric_aod": 0.12, "ozone_du": 300.0}

    def curve(parameters):
        shadow = eclipse_shadow(date, atmosphere=eclipse_atmosphere(date, **parameters))
        return lunar_light_curve(date, shadow=shadow, n_times=48, table_n_v=64)

    def forward():
        curve(start)

    def with_gradients():
        leaves = {k: torch.tensor(v, dtype=torch.float64, requires_grad=True)
                  for k, v in start.items()}
        result = curve(leaves)
        (result["v_magnitude"].sum() + result["b_magnitude"].sum()).backward()
        if any(leaf.grad is None or not torch.isfinite(leaf.grad) for leaf in leaves.values()):
            raise RuntimeError("the light curve carried no finite gradient to a parameter")

    medians = alternating_medians({"forward": forward, "gradients": with_gradients}, repeat)
    times, bands, magnitude = _read_photometry(PHOTOMETRY_2019)
    observed = xr.Dataset({"time": ("sample", times), "band": ("sample", bands),
                           "magnitude": ("sample", magnitude),
                           "uncertainty": ("sample", np.full(times.size, 0.1))})
    retrieval = median_seconds(lambda: retrieve_atmosphere(
        observed, date, parameters=tuple(start), max_iter=30), repeat=1, warmup=0)
    ratio = medians["gradients"] / medians["forward"]
    rows = [
        {"case": "2019-01-21 light curve, forward (48 times, table 64)",
         "median [s]": medians["forward"]},
        {"case": "same, forward + backward (3 parameters)", "median [s]": medians["gradients"]},
        {"case": "3-parameter retrieval from the 2019-01-21 light curve (6 samples)",
         "median [s]": retrieval},
    ]
    summary = (f"Gradients / forward = {ratio:.2f} (target <= {TARGET_GRADIENT_RATIO:.0f}); "
               f"retrieval {retrieval:.1f} s (target <= {TARGET_RETRIEVAL_SECONDS:.0f} s).")
    return rows, summary


def main(argv: list[str] | None = None) -> int:
    parser = argument_parser(__doc__.splitlines()[0], repeat=3, threads=1)
    parser.add_argument("--search-only", action="store_true",
                        help="time only the two eclipse searches")
    parser.add_argument("--gradients", action="store_true",
                        help="time only the light curve with gradients and the retrieval")
    args = parse_arguments(parser, argv)
    if args.gradients:
        rows, summary = gradient_rows(args.repeat)
        load_avg = " ".join(f"{x:.1f}" for x in os.getloadavg())
        report(f"\n## Lunar eclipses: gradients and retrieval ({machine_description()})\n\n"
               f"Load average {load_avg}. {summary}\n\n{markdown_table(rows)}\n", args.append)
        return 0

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
