"""Benchmark of scene renders against the targets of the scenes issue.

Rows (512 × 512 fisheye, RGB, default fidelity, float64; medians after one warm-up run
that fills the caches — transmittance and skyglow tables, star catalogue):

* night — Berlin at the greatest phase of the 2015-09-28 eclipse with a synthetic city
  of one million inhabitants 12 km away: Moon (eclipsed), stars, skyglow, refraction;
  target ≤ 2 s;
* day — Paris, 2015-06-21 12:00 UTC: single-scattering sky (look-up table over view
  zenith and relative azimuth) and the Sun; target ≤ 3 s;
* planner — side by side, interleaved, each run at an instant no plan has seen (the
  per-(time, site) geometry cache cold; tables per atmosphere warm): the night render
  given its plan, the night render without a plan (planning inside), and ``plan()``
  alone; target: planning ≤ 5 % of a render, judged on CPU time (one thread, so equal
  to wall time on an idle machine; less disturbed by other processes).

Run: ``python benchmarks/bench_scene.py [--size N] [--repeat R] [--append]``
(``--append`` adds the table to ``docs/benchmarks.md``). Timings on a shared 2-core
machine are noisy.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import skytorch as st  # noqa: E402
from benchmarks._harness import (  # noqa: E402
    argument_parser,
    machine_description,
    markdown_table,
    median_cpu_seconds,
    median_seconds,
    parse_arguments,
    report,
)

TARGET_NIGHT_S = 2.0
TARGET_DAY_S = 3.0
TARGET_PLANNER_FRACTION = 0.05


def scenes(size: int, fidelity: str = "default"):
    from skytorch.commands.demo import CITY, SITE
    from skytorch.skyglow.citymap import synthetic_city

    city = synthetic_city(extent_m=60_000.0, cell_m=500.0, **CITY)
    night = st.Scene(time="2015-09-28T02:47", **SITE, size=size, light_map=city,
                     fidelity=fidelity, outputs=("xyz", "srgb"))
    day = st.Scene(time="2015-06-21T12:00", lat_deg=48.85, lon_deg=2.35, size=size,
                   fidelity=fidelity, outputs=("xyz", "srgb"))
    return night, day


def planner_overhead(scene, repeat: int):
    """Medians of wall and CPU time [s].

    Render given a plan, render without one, plan() alone — each at instants no plan has seen (one
    second apart, so the work is the same and the per-(time, site) geometry cache is cold),
    interleaved run by run.
    """
    import statistics
    import time

    import numpy as np

    base = np.datetime64(str(scene.time))
    runs = {"given": [], "cold": [], "plan": []}
    for k in range(repeat):
        scenes = [scene.replace(time=str(base + np.timedelta64(3 * k + j + 1, "s")))
                  for j in range(3)]
        plan = scenes[0].plan()
        for name, work in (("given", lambda s=scenes[0], p=plan: s.render(p)),
                           ("cold", scenes[1].render), ("plan", scenes[2].plan)):
            wall, cpu = time.perf_counter(), time.process_time()
            work()
            runs[name].append((time.perf_counter() - wall, time.process_time() - cpu))
    walls = [statistics.median(w for w, _ in runs[n]) for n in ("given", "cold", "plan")]
    cpus = [statistics.median(c for _, c in runs[n]) for n in ("given", "cold", "plan")]
    return (*walls, *cpus)


def main(argv=None) -> int:
    parser = argument_parser(__doc__.splitlines()[0], repeat=5, thread_option=False)
    parser.add_argument("--size", type=int, default=512)
    args = parse_arguments(parser, argv)
    night, day = scenes(args.size)
    night_plan = night.plan()
    rows = []
    t_night = median_seconds(lambda: night.render(night_plan), repeat=args.repeat)
    cpu_night = median_cpu_seconds(lambda: night.render(night_plan), args.repeat)
    rows.append({"case": f"night {args.size}² ({night_plan.attrs()['effects_computed']})",
                 "median [s]": f"{t_night:.3f}", "CPU [s]": f"{cpu_night:.3f}",
                 "target": f"≤ {TARGET_NIGHT_S} s",
                 "met": "yes" if t_night <= TARGET_NIGHT_S else "no"})
    day_plan = day.plan()
    t_day = median_seconds(lambda: day.render(day_plan), repeat=args.repeat)
    cpu_day = median_cpu_seconds(lambda: day.render(day_plan), args.repeat)
    rows.append({"case": f"day {args.size}² ({day_plan.attrs()['effects_computed']})",
                 "median [s]": f"{t_day:.3f}", "CPU [s]": f"{cpu_day:.3f}",
                 "target": f"≤ {TARGET_DAY_S} s",
                 "met": "yes" if t_day <= TARGET_DAY_S else "no"})
    t_given, t_cold, t_plan, c_given, c_cold, c_plan = planner_overhead(night, args.repeat)
    rows.append({"case": "night render given its plan (a new instant each run)",
                 "median [s]": f"{t_given:.3f}", "CPU [s]": f"{c_given:.3f}",
                 "target": "(reference)", "met": ""})
    rows.append({"case": "night render without a plan (a new instant: plans inside)",
                 "median [s]": f"{t_cold:.3f}", "CPU [s]": f"{c_cold:.3f}",
                 "target": f"≤ {1 + TARGET_PLANNER_FRACTION:.2f} × the render given a plan",
                 "met": f"{t_cold / t_given - 1.0:+.1%} (CPU {c_cold / c_given - 1.0:+.1%}); "
                        + ("yes" if c_cold / c_given - 1.0 <= TARGET_PLANNER_FRACTION
                           else "no")})
    rows.append({"case": "plan() alone for a new instant (ephemeris, bounds, decisions)",
                 "median [s]": f"{t_plan:.4f}", "CPU [s]": f"{c_plan:.4f}",
                 "target": f"≤ {TARGET_PLANNER_FRACTION:.0%} of a render",
                 "met": f"{t_plan / t_given:.1%} of the render given a plan (CPU "
                        f"{c_plan / c_given:.1%}); "
                        + ("yes" if c_plan / c_given <= TARGET_PLANNER_FRACTION else "no")})
    import os

    load = os.getloadavg()[0]
    table = (f"\n### Scenes ({machine_description()}; load average {load:.1f})\n\n"
             "`python benchmarks/bench_scene.py` — 512 × 512 fisheye, RGB, default "
             "fidelity, float64, tables warm (the planner rows at instants no plan has "
             "seen); shared 2-core machine, noisy: the planner's targets are judged on CPU "
             "time (one thread).\n\n"
             + markdown_table(rows) + "\n")
    report(table, args.append)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
