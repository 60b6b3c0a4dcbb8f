"""Benchmark of star positions + magnitudes: skytorch vs skyfield, one night at 1-min steps.

Workload: the Hipparcos 2 stars brighter than V = 6.5 (about 8 900) at 1 440 times (one
night at one-minute steps) from one site. Rows:

* skytorch positions + magnitudes — :func:`skytorch.stars.positions.time_operators`
  (precession–nutation, Earth rotation, aberration, parallax for every time) and
  :func:`skytorch.stars.observe_tensors` (one GEMM per 32 times, aberration, ray-traced
  refraction and V-band extinction through cached tables), float64 and float32;
* the same with the tables built inside the timed call (first call for an atmosphere);
* ``skytorch.stars.observe`` — the whole Dataset (adds limiting magnitude, visibility,
  relative brightness, scintillation index, colours and the xarray assembly);
* skyfield — ``observer.at(t).observe(stars).apparent().altaz()`` vectorised over the
  stars, looped over a subset of the times and scaled to 1 440 (it has no magnitudes).

Run: ``python benchmarks/bench_stars.py [--append] [--skyfield-times 12]``. The machine has
two cores shared with other jobs: medians are noisy.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._harness import (  # noqa: E402
    argument_parser,
    machine_description,
    markdown_table,
    median_cpu_seconds,
    median_seconds,
    parse_arguments,
    report,
)

LAT, LON, ELEVATION = 52.5, 13.4, 34.0
TARGET_SECONDS = 1.0
TARGET_RATIO = 20.0


def main(argv: list[str] | None = None) -> int:
    parser = argument_parser(__doc__.splitlines()[0], repeat=3, threads=1)
    parser.add_argument("--skyfield-times", type=int, default=12,
                        help="times measured with skyfield (scaled to all)")
    # --threads defaults to 1: on a shared, oversubscribed machine OpenMP threads spin
    # while waiting
    args = parse_arguments(parser, argv)

    from skyfield.api import Star, wgs84

    from skytorch.atmosphere import Atmosphere
    from skytorch.ephemeris import load_ephemeris, skyfield_time
    from skytorch.stars import bright_stars, observe, observe_tensors, photometry
    from skytorch.stars import observation as observe_module
    from skytorch.stars.positions import star_vectors, time_operators

    catalog = bright_stars(6.5)
    n_star = catalog.sizes["star"]
    times = np.datetime64("2025-09-07T18:00", "ns") + np.arange(1440) * np.timedelta64(60, "s")
    atmosphere = Atmosphere.earth()
    refraction = observe_module.refraction_table(atmosphere, ELEVATION)
    extinction = photometry.extinction_table(atmosphere, ELEVATION, refraction=True)

    def skytorch_core(dtype, cold=False):
        def run():
            refr, ext = refraction, extinction
            if cold:
                observe_module._REFRACTION_TABLES.clear()
                photometry._TABLES.clear()
                refr = observe_module.refraction_table(atmosphere, ELEVATION)
                ext = photometry.extinction_table(atmosphere, ELEVATION, refraction=True)
            stars = star_vectors(catalog.ra.values, catalog.dec.values, catalog.pm_ra.values,
                                 catalog.pm_dec.values, catalog.parallax.values, dtype=dtype)
            operators, velocity = time_operators(times, LAT, LON, ELEVATION)
            vmag = torch.as_tensor(catalog.vmag.values, dtype=dtype)
            bv = torch.as_tensor(catalog.bv.values, dtype=dtype)
            return observe_tensors(stars, vmag, bv, operators, velocity, refr, ext)
        return run

    ephemeris = load_ephemeris()
    observer = ephemeris["earth"] + wgs84.latlon(LAT, LON, ELEVATION)
    star = Star(ra_hours=catalog.ra.values / 15.0, dec_degrees=catalog.dec.values,
                ra_mas_per_year=catalog.pm_ra.values, dec_mas_per_year=catalog.pm_dec.values,
                parallax_mas=np.clip(catalog.parallax.values, 0.0, None))
    subset = times[:: len(times) // args.skyfield_times][: args.skyfield_times]
    t_subset = skyfield_time(subset)

    def skyfield_run():
        for i in range(len(subset)):
            observer.at(t_subset[i]).observe(star).apparent().altaz()

    rows = []
    seconds, cpu = {}, {}
    for label, dtype in (("float64", torch.float64), ("float32", torch.float32)):
        seconds[label] = median_seconds(skytorch_core(dtype), repeat=args.repeat, warmup=1)
        cpu[label] = median_cpu_seconds(skytorch_core(dtype), repeat=args.repeat, warmup=0)
        rows.append({"method": f"skytorch positions + magnitudes ({label}, tables cached)",
                     "wall [s]": seconds[label], "CPU [s]": cpu[label]})
    cold = skytorch_core(torch.float64, cold=True)
    rows.append({"method": "skytorch positions + magnitudes (float64, tables rebuilt)",
                 "wall [s]": median_seconds(cold, repeat=1, warmup=0),
                 "CPU [s]": median_cpu_seconds(cold, repeat=1, warmup=0)})
    for label, options in (("float64", {}), ("float32", {"dtype": torch.float32}),
                           ("float64, reddening=False", {"reddening": False})):
        def full(options=options):
            return observe(catalog, times, LAT, LON, ELEVATION, atmosphere=atmosphere,
                           **options)
        rows.append({"method": f"skytorch.stars.observe (full Dataset, {label})",
                     "wall [s]": median_seconds(full, repeat=args.repeat, warmup=1),
                     "CPU [s]": median_cpu_seconds(full, repeat=args.repeat, warmup=0)})
    scale = len(times) / len(subset)
    sky = median_seconds(skyfield_run, repeat=1, warmup=1) * scale
    sky_cpu = median_cpu_seconds(skyfield_run, repeat=1, warmup=0) * scale
    rows.append({"method": f"skyfield apparent alt/az ({len(subset)} times, scaled x"
                           f"{scale:.0f})", "wall [s]": sky, "CPU [s]": sky_cpu})
    for row in rows:
        row["ratio vs skyfield (CPU)"] = sky_cpu / row["CPU [s]"]
    table = markdown_table(rows)
    best, best_cpu = seconds["float64"], cpu["float64"]
    load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    summary = (
        f"{n_star} stars x {len(times)} times at lat {LAT}, lon {LON}; load average during "
        f"the run {load} on {os.cpu_count()} cores (CPU time is the robust measure here). "
        f"Target: positions + magnitudes <= {TARGET_SECONDS:.0f} s and >= "
        f"{TARGET_RATIO:.0f}x skyfield. Measured (float64, cached tables): wall "
        f"{best:.2f} s, CPU {best_cpu:.2f} s "
        f"({'meets' if best_cpu <= TARGET_SECONDS else 'misses'} the time target in CPU "
        f"time), {sky_cpu / best_cpu:.0f}x skyfield in CPU time "
        f"({'meets' if sky_cpu / best_cpu >= TARGET_RATIO else 'misses'} the ratio target)."
    )
    text = (f"\n## Stars: positions and magnitudes ({machine_description()})\n\n{summary}\n\n"
            f"{table}\n")
    report(text, args.append)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
