"""Benchmark of the Gaia DR3 stars at one instant: positions + magnitudes, and the Dataset.

Workload: every entry of the bundled Gaia DR3 catalogue (``gaia_stars()``, 482 176 stars)
at one instant from one site. Rows:

* skytorch positions + magnitudes — :func:`skytorch.stars.positions.star_vectors`,
  :func:`skytorch.stars.positions.time_operators` and
  :func:`skytorch.stars.observe_tensors` (refraction and extinction tables cached),
  float64 and float32;
* ``skytorch.stars.observe`` — the whole Dataset for the same stars and instant;
* skyfield — ``observer.at(t).observe(stars).apparent().altaz()`` vectorised over the
  stars (positions only).

Target (issue 17, item 6): positions + magnitudes <= 0.3 s. Run:
``python benchmarks/bench_stars_gaia.py [--append]``. CPU time of this process is the
robust measure on the shared two-core machine.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._harness import (  # noqa: E402
    argument_parser,
    machine_description,
    markdown_table,
    median_seconds,
    parse_arguments,
    report,
)
from benchmarks.bench_stars import median_cpu_seconds  # noqa: E402

LAT, LON, ELEVATION = 52.5, 13.4, 34.0
TIME = np.array(["2025-09-07T21:00"], dtype="datetime64[ns]")
TARGET_SECONDS = 0.3


def main(argv: list[str] | None = None) -> int:
    parser = argument_parser(__doc__.splitlines()[0], repeat=5, threads=1)
    args = parse_arguments(parser, argv)

    from skyfield.api import Star, wgs84

    from skytorch.atmosphere import Atmosphere
    from skytorch.ephemeris import load_ephemeris, skyfield_time
    from skytorch.stars import gaia_stars, observe, observe_tensors, photometry
    from skytorch.stars import observation as observe_module
    from skytorch.stars.positions import star_vectors, time_operators

    catalog = gaia_stars()
    n_star = catalog.sizes["star"]
    atmosphere = Atmosphere.earth()
    refraction = observe_module.refraction_table(atmosphere, ELEVATION)
    extinction = photometry.extinction_table(atmosphere, ELEVATION, refraction=True)
    columns = {name: catalog[name].values for name in
               ("ra", "dec", "pm_ra", "pm_dec", "parallax", "vmag", "bv")}

    def core(dtype):
        def run():
            stars = star_vectors(columns["ra"], columns["dec"], columns["pm_ra"],
                                 columns["pm_dec"], columns["parallax"], dtype=dtype)
            operators, velocity = time_operators(TIME, LAT, LON, ELEVATION)
            vmag = torch.as_tensor(columns["vmag"], dtype=dtype)
            bv = torch.as_tensor(columns["bv"], dtype=dtype)
            return observe_tensors(stars, vmag, bv, operators, velocity, refraction,
                                   extinction)
        return run

    rows = []
    for label, dtype in (("float64", torch.float64), ("float32", torch.float32)):
        rows.append({"method": f"skytorch positions + magnitudes ({label})",
                     "wall [s]": median_seconds(core(dtype), repeat=args.repeat, warmup=1),
                     "CPU [s]": median_cpu_seconds(core(dtype), repeat=args.repeat,
                                                   warmup=0)})
    full = lambda: observe(catalog, TIME, LAT, LON, ELEVATION, atmosphere=atmosphere)  # noqa: E731
    rows.append({"method": "skytorch.stars.observe (full Dataset, float64)",
                 "wall [s]": median_seconds(full, repeat=1, warmup=1),
                 "CPU [s]": median_cpu_seconds(full, repeat=1, warmup=0)})
    ephemeris = load_ephemeris()
    observer = ephemeris["earth"] + wgs84.latlon(LAT, LON, ELEVATION)
    star = Star(ra_hours=columns["ra"] / 15.0, dec_degrees=columns["dec"],
                ra_mas_per_year=columns["pm_ra"], dec_mas_per_year=columns["pm_dec"],
                parallax_mas=np.clip(columns["parallax"], 0.0, None))
    t = skyfield_time(TIME)[0]
    sky = lambda: observer.at(t).observe(star).apparent().altaz()  # noqa: E731
    rows.append({"method": "skyfield apparent alt/az (positions only)",
                 "wall [s]": median_seconds(sky, repeat=1, warmup=1),
                 "CPU [s]": median_cpu_seconds(sky, repeat=1, warmup=0)})
    sky_cpu = rows[-1]["CPU [s]"]
    for row in rows:
        row["ratio vs skyfield (CPU)"] = sky_cpu / row["CPU [s]"]
    best = rows[0]["CPU [s]"]
    load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    summary = (f"{n_star} Gaia DR3 stars at one instant, lat {LAT}, lon {LON}; load average "
               f"{load} on {os.cpu_count()} cores. Target: positions + magnitudes <= "
               f"{TARGET_SECONDS} s. Measured (float64): CPU {best:.3f} s "
               f"({'meets' if best <= TARGET_SECONDS else 'misses'} the target).")
    report(f"\n## Gaia stars at one instant ({machine_description()})\n\n{summary}\n\n"
           f"{markdown_table(rows)}\n", args.append)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
