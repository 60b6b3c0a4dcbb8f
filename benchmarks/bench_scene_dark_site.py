"""Benchmark of the dark-site render (issue target: 512² with the natural sky ≤ 1 s).

Workload: a 512 × 512 fisheye at Paranal, 2026-09-11 04:45 UTC (Sun and Moon down),
``natural_model="leinert1998"`` (zodiacal light, airglow, integrated starlight, each
extinguished and scattered once into the line of sight), 70 sfu, catalogue stars drawn,
float64. Rows: the first render in a fresh process (building the scene's resources,
including the scattered-light tables), the warm render (median of ``--repeat`` renders of
the same scene) and, of the first render, the time of the two scattered-light tables.

Run: ``python benchmarks/bench_scene_dark_site.py [--append] [--threads 2]``.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._harness import (  # noqa: E402
    argument_parser,
    parse_arguments,
    report_section,
)

TARGET_S = 1.0
PARANAL = {"lat_deg": -24.63, "lon_deg": -70.40, "elevation_m": 2635.0}


def main(argv: list[str] | None = None) -> int:
    parser = argument_parser(__doc__.splitlines()[0], repeat=5, threads=2)
    args = parse_arguments(parser, argv)
    from skytorch.scene import Scene
    from skytorch.scene.resources import SceneResources

    load_before = os.getloadavg()
    timed = {"scattered_airglow_table": 0.0, "scattered_sky_response": 0.0}
    originals = {name: getattr(SceneResources, name) for name in timed}

    def timing(name):
        def wrapper(self, *arguments, **keywords):
            clock = time.perf_counter()
            try:
                return originals[name](self, *arguments, **keywords)
            finally:
                timed[name] += time.perf_counter() - clock
        return wrapper

    for name in timed:
        setattr(SceneResources, name, timing(name))
    try:
        scene = Scene(time="2026-09-11T04:45:00", size=512, natural_model="leinert1998",
                      solar_flux_sfu=70.0, **PARANAL)
        clock = time.perf_counter()
        scene.render()
        first = time.perf_counter() - clock
        tables = dict(timed)
        warm = []
        for _ in range(args.repeat):
            clock = time.perf_counter()
            scene.render()
            warm.append(time.perf_counter() - clock)
    finally:
        for name, function in originals.items():
            setattr(SceneResources, name, function)
    median = statistics.median(warm)
    rows = [
        {"case": "first render (resources built)", "wall [s]": f"{first:.3f}",
         "target [s]": "", "met": ""},
        {"case": "  of which the scattered airglow table", "wall [s]":
         f"{tables['scattered_airglow_table']:.3f}", "target [s]": "", "met": ""},
        {"case": "  of which the zodiacal light and starlight response", "wall [s]":
         f"{tables['scattered_sky_response']:.3f}", "target [s]": "", "met": ""},
        {"case": f"warm render (median of {args.repeat})", "wall [s]": f"{median:.3f}",
         "target [s]": f"{TARGET_S:.0f}", "met": "yes" if median <= TARGET_S else "no"},
    ]
    report_section("Dark-site render", "bench_scene_dark_site.py", load_before,
                   "512² fisheye, Paranal 2026-09-11 04:45 UTC, natural_model=\"leinert1998\", "
                   "70 sfu, stars drawn, float64.", rows, args.append)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
