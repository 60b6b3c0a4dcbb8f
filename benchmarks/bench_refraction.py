"""Benchmark of refracted rays: the deviation/contact table and grazing rays.

Rows, measured side by side in one run (``Atmosphere.earth()``: U.S. Standard Atmosphere
1976 refractivity, n - 1 = 2.77e-4 at the ground; and the 8 km exponential index):

* :func:`skytorch.atmosphere.refraction.deviation_table` 512 x 256 (Schneegans et al. 2025
  Fig. 6) with the Bouguer integrals at the table's default resolution (US 1976: 12
  panels of 16 Gauss–Legendre nodes; exponential: 32 nodes), float64 and float32, and
  the exponential index. Target: <= 10 s ("refracted rays, 10 km steps or better": the
  quadrature is more accurate than 10 km RK4 steps on every ray above the ground, see
  docs/accuracy.md).
* the same table with Schneegans' algorithm, RK4 ray marching at 10 km steps, on a
  64 x 32 sub-grid, scaled by the number of rays (full size would take minutes here).
* :func:`skytorch.atmosphere.refraction.trace_grazing_rays` for 4096 rays x 15
  wavelengths with optical depth (the eclipse-shadow precomputation).

Run: ``python benchmarks/bench_refraction.py [--append] [--threads 2] [--repeat 3]``. The
machine has two cores shared with other jobs: medians are noisy (the load average is
printed).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._harness import (  # noqa: E402
    argument_parser,
    machine_description,
    markdown_table,
    median_seconds,
    parse_arguments,
    report,
)

TARGET_TABLE_S = 10.0


def _cpu_seconds(function) -> float:
    """CPU time of one call, all threads [s] (less sensitive to other jobs than wall time)."""
    start = time.process_time()
    function()
    return time.process_time() - start
FULL = (512, 256)
RK4_SUBGRID = (64, 32)


def main(argv: list[str] | None = None) -> int:
    args = parse_arguments(argument_parser(__doc__.splitlines()[0], repeat=3), argv)

    from skytorch.atmosphere import Atmosphere
    from skytorch.atmosphere import refraction as rf

    atm = Atmosphere.earth()
    exponential = Atmosphere.earth(refractivity_profile="exponential")
    rows = []
    baseline = None
    for label, model, dtype in (("US 1976, 12 x 16 nodes", atm, torch.float64),
                                ("US 1976, 12 x 16 nodes", atm, torch.float32),
                                ("exponential, 32 nodes", exponential, torch.float64)):
        def build(model=model, dtype=dtype):
            return rf.deviation_table(model, *FULL, dtype=dtype, progress=False)

        seconds = median_seconds(build, repeat=args.repeat, warmup=0)
        baseline = baseline or seconds
        rows.append({"case": f"deviation table {FULL[0]}x{FULL[1]}, Bouguer, {label}, "
                             f"{str(dtype).replace('torch.', '')}",
                     "median [s]": seconds, "CPU [s]": _cpu_seconds(build),
                     "ratio": seconds / baseline, "target [s]": TARGET_TABLE_S,
                     "met": "yes" if seconds <= TARGET_TABLE_S else "no"})

    def marching():
        return rf.deviation_table(atm, *RK4_SUBGRID, method="rk4", step_m=10e3,
                                  progress=False)

    scale = (FULL[0] * FULL[1]) / (RK4_SUBGRID[0] * RK4_SUBGRID[1])
    sub = median_seconds(marching, repeat=1, warmup=0)
    scaled = sub * scale
    rows.append({"case": f"deviation table, RK4 10 km steps ({RK4_SUBGRID[0]}x{RK4_SUBGRID[1]} "
                         f"measured {sub:.2f} s, scaled to {FULL[0]}x{FULL[1]})",
                 "median [s]": scaled, "CPU [s]": _cpu_seconds(marching) * scale,
                 "ratio": scaled / baseline, "target [s]": TARGET_TABLE_S,
                 "met": "yes" if scaled <= TARGET_TABLE_S else "no"})
    wavelength = torch.linspace(360.0, 830.0, 15, dtype=torch.float64)
    impact = torch.linspace(1.8e3, 1e5, 4096, dtype=torch.float64)

    def grazing():
        with torch.no_grad():
            return rf.trace_grazing_rays(atm, impact_altitude_m=impact,
                                         wavelength_nm=wavelength)

    seconds = median_seconds(grazing, repeat=args.repeat, warmup=1)
    rows.append({"case": "trace_grazing_rays 4096 rays x 15 wavelengths, 64 nodes",
                 "median [s]": seconds, "CPU [s]": _cpu_seconds(grazing),
                 "ratio": seconds / baseline, "target [s]": "-", "met": "-"})

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    header = (f"## Refracted rays (`benchmarks/bench_refraction.py`)\n\n"
              f"Machine: {machine_description()}; load average {load:.1f} during the run "
              "(shared with other jobs: medians are noisy; the CPU column is the process "
              "time of one call summed over threads, less affected by the other jobs). "
              "Ratios are relative to the first row.\n")
    table = markdown_table(rows)
    report("\n\n" + header + "\n" + table + "\n", args.append)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
