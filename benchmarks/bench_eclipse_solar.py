"""Benchmark of the solar-eclipse functions: global circumstances, local circumstances, map.

Rows:

* :func:`skytorch.eclipse.solar.solar_eclipses` over 100 years (1950-2050), with the share
  spent in the ephemeris (:func:`skytorch.ephemeris.sun_moon_vectors`, skyfield + DE421)
  measured separately. Target: <= 2 s.
* :func:`skytorch.eclipse.solar_local.solar_eclipse_local` for 10 000 observers spread
  over North America (2024-04-08). Target: <= 1 s.
* :func:`skytorch.eclipse.solar_path.obscuration_map` on the default 1440 x 720 grid at
  one instant (2024-04-08T18:18). Target: <= 1 s.
* :func:`skytorch.eclipse.solar_path.solar_eclipse_path` for 2024-04-08 every 60 s (no
  target).

Run: ``python benchmarks/bench_eclipse_solar.py [--append] [--threads 1]``. The machine
has two cores shared with other jobs: medians are noisy.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np
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

TARGETS = {"global": 2.0, "local": 1.0, "map": 1.0}


def _ephemeris_share(function) -> float:
    """Seconds spent in sun_moon_vectors during one call of ``function``."""
    import skytorch.ephemeris as ephemeris

    original = ephemeris.sun_moon_vectors
    spent = [0.0]

    def timed(times):
        start = time.perf_counter()
        try:
            return original(times)
        finally:
            spent[0] += time.perf_counter() - start

    ephemeris.sun_moon_vectors = timed
    try:
        function()
    finally:
        ephemeris.sun_moon_vectors = original
    return spent[0]


def main(argv: list[str] | None = None) -> int:
    parser = argument_parser(__doc__.splitlines()[0], repeat=3)
    args = parse_arguments(parser, argv)

    from skytorch.eclipse.solar import solar_eclipses
    from skytorch.eclipse.solar_local import solar_eclipse_local
    from skytorch.eclipse.solar_path import obscuration_map, solar_eclipse_path

    load_before = os.getloadavg()
    generator = np.random.default_rng(0)
    lat = torch.as_tensor(generator.uniform(15.0, 60.0, 10_000))
    lon = torch.as_tensor(generator.uniform(-130.0, -60.0, 10_000))
    count = {}

    def global_run():
        count["n"] = solar_eclipses("1950-01-01", "2050-01-01").sizes["eclipse"]

    rows = []
    seconds = median_seconds(global_run, repeat=args.repeat)
    ephemeris = _ephemeris_share(global_run)
    rows.append({"workload": f"solar_eclipses 1950-2050 ({count['n']} eclipses)",
                 "median s": seconds, "target s": TARGETS["global"],
                 "ratio to target": seconds / TARGETS["global"]})
    rows.append({"workload": "  of which ephemeris (sun_moon_vectors at Chebyshev nodes)",
                 "median s": ephemeris, "target s": float("nan"),
                 "ratio to target": float("nan")})
    seconds = median_seconds(lambda: solar_eclipse_local("2024-04-08", lat, lon),
                             repeat=args.repeat)
    rows.append({"workload": "solar_eclipse_local 2024-04-08, 10 000 observers",
                 "median s": seconds, "target s": TARGETS["local"],
                 "ratio to target": seconds / TARGETS["local"]})
    seconds = median_seconds(lambda: obscuration_map("2024-04-08T18:18"), repeat=args.repeat)
    rows.append({"workload": "obscuration_map 1440 x 720 (2024-04-08T18:18)",
                 "median s": seconds, "target s": TARGETS["map"],
                 "ratio to target": seconds / TARGETS["map"]})
    seconds = median_seconds(lambda: solar_eclipse_path("2024-04-08", step_s=60.0),
                             repeat=args.repeat)
    rows.append({"workload": "solar_eclipse_path 2024-04-08, 60 s steps", "median s": seconds,
                 "target s": float("nan"), "ratio to target": float("nan")})
    load_after = os.getloadavg()
    text = (
        "\n## Solar eclipses (`benchmarks/bench_eclipse_solar.py`)\n\n"
        f"{machine_description()}; median of {args.repeat} runs after one warm-up; load "
        f"average (1/5/15 min) {'/'.join(f'{v:.2f}' for v in load_before)} before, "
        f"{'/'.join(f'{v:.2f}' for v in load_after)} after.\n\n"
        + markdown_table(rows) + "\n"
    )
    report(text, args.append)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
