"""Benchmark of the eclipse geometry: occlusion of the Sun and lunar-eclipse circumstances.

Rows:

* :func:`skytorch.eclipse.sun_visible_fraction` on 1e7 random partial overlaps
  (Sun radius 4.65 mrad, occluder 0.1 to 3.1 Sun radii, separations across the whole
  overlap) in float64 and float32, without gradients, side by side with the previous
  implementation (the file as of commit ``PREVIOUS_COMMIT``, read with ``git show``): the
  two are called alternately in every repetition, with torch's default thread count and
  with one thread, and the medians and their ratio are reported; then other
  Gauss–Legendre node counts, and a backward pass on 1e6 evaluations. Target: 1e7
  evaluations <= 1 s. The load average before and after is printed with the table.
* :func:`skytorch.eclipse.lunar_eclipses` over 100 years (1950–2050), with the share spent
  in the ephemeris (:func:`skytorch.ephemeris.sun_moon_vectors`, skyfield + DE421) measured
  separately. Target: <= 5 s.

Run: ``python benchmarks/bench_eclipse_geometry.py [--append] [--threads 2]``. The machine
has two cores shared with other jobs: medians are noisy.
"""

from __future__ import annotations

import gc
import os
import statistics
import subprocess
import sys
import time
import types
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

SUN_RADIUS = 4.65e-3
N_OCCLUSION = 10_000_000
#: last commit with the previous sun_visible_fraction kernel (compared side by side)
PREVIOUS_COMMIT = "a5bc3be"
TARGET_OCCLUSION_S = 1.0
TARGET_ECLIPSES_S = 5.0


def _inputs(n: int, dtype: torch.dtype):
    generator = torch.Generator().manual_seed(0)
    ratio = 0.1 + 3.0 * torch.rand(n, generator=generator, dtype=torch.float64)
    rho_o = SUN_RADIUS * ratio
    d = (SUN_RADIUS + rho_o) * torch.rand(n, generator=generator, dtype=torch.float64)
    return rho_o.to(dtype), d.to(dtype)


def _previous_implementation():
    """``sun_visible_fraction`` of commit :data:`PREVIOUS_COMMIT`, or None without git."""
    root = Path(__file__).resolve().parents[1]
    try:
        source = subprocess.run(
            ["git", "-C", str(root), "show", f"{PREVIOUS_COMMIT}:skytorch/eclipse/occlusion.py"],
            capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    module = types.ModuleType("previous_occlusion")
    exec(compile(source, f"occlusion.py@{PREVIOUS_COMMIT}", "exec"), module.__dict__)
    return module.sun_visible_fraction


def _alternating_medians(functions: dict, repeat: int, warmup: int = 1) -> dict[str, float]:
    """Median wall time of each function.

    The functions called in turn in every repetition (so that a change of machine load affects all
    of them alike) [s].
    """
    for _ in range(warmup):
        for function in functions.values():
            function()
    samples = {name: [] for name in functions}
    for _ in range(repeat):
        for name, function in functions.items():
            gc.collect()
            start = time.perf_counter()
            function()
            samples[name].append(time.perf_counter() - start)
    return {name: statistics.median(values) for name, values in samples.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argument_parser(__doc__.splitlines()[0], repeat=3)
    parser.add_argument("--n", type=int, default=N_OCCLUSION, help="occlusion evaluations")
    args = parse_arguments(parser, argv)

    from skytorch.eclipse import circumstances as circumstances_module
    from skytorch.eclipse import lunar_eclipses, sun_visible_fraction

    load_before = os.getloadavg()
    rows = []
    scale = N_OCCLUSION / args.n
    previous = _previous_implementation()
    threads = torch.get_num_threads()
    for dtype, n_threads in ((torch.float64, threads), (torch.float32, threads),
                             (torch.float64, 1)):
        rho_o, d = _inputs(args.n, dtype)
        functions = {"new": lambda rho_o=rho_o, d=d: sun_visible_fraction(
            SUN_RADIUS, rho_o, d, 0.6)}
        if previous is not None:
            functions["previous"] = lambda rho_o=rho_o, d=d: previous(SUN_RADIUS, rho_o, d, 0.6)
        torch.set_num_threads(n_threads)
        try:
            with torch.no_grad():
                medians = _alternating_medians(functions, repeat=args.repeat)
        finally:
            torch.set_num_threads(threads)
        new = medians["new"] * scale
        old = medians.get("previous", float("nan")) * scale
        rows.append({"workload": f"sun_visible_fraction 1e7 ({str(dtype)[6:]}, 8 nodes, "
                                 f"{n_threads} thread{'s' if n_threads > 1 else ''})",
                     "previous s": old, "median s": new, "previous / new": old / new,
                     "target s": TARGET_OCCLUSION_S, "ratio to target": new / TARGET_OCCLUSION_S})
    for n_nodes in (7, 12):
        rho_o, d = _inputs(args.n, torch.float64)

        def occlusion(rho_o=rho_o, d=d, n_nodes=n_nodes):
            with torch.no_grad():
                sun_visible_fraction(SUN_RADIUS, rho_o, d, 0.6, n_nodes=n_nodes)

        seconds = median_seconds(occlusion, repeat=args.repeat, warmup=1) * scale
        rows.append({"workload": f"sun_visible_fraction 1e7 (float64, {n_nodes} nodes)",
                     "previous s": float("nan"), "median s": seconds,
                     "previous / new": float("nan"), "target s": TARGET_OCCLUSION_S,
                     "ratio to target": seconds / TARGET_OCCLUSION_S})

    # a Sun radius per configuration (as in the shadow and the lunar eclipse), 1e6 of them
    rho_o, d = _inputs(args.n // 10, torch.float64)
    rho_s = SUN_RADIUS * (0.97 + 0.06 * torch.rand(rho_o.shape, dtype=torch.float64,
                                                   generator=torch.Generator().manual_seed(2)))
    functions = {"new": lambda: sun_visible_fraction(rho_s, rho_o, d, 0.6)}
    if previous is not None:
        functions["previous"] = lambda: previous(rho_s, rho_o, d, 0.6)
    with torch.no_grad():
        medians = _alternating_medians(functions, repeat=args.repeat)
    new, old = (medians.get(k, float("nan")) * scale for k in ("new", "previous"))
    rows.append({"workload": "sun_visible_fraction 1e6 with a Sun radius per configuration "
                             "(float64, 8 nodes)",
                 "previous s": old, "median s": new, "previous / new": old / new,
                 "target s": float("nan"), "ratio to target": float("nan")})

    def with_gradient():
        separation = d.clone().requires_grad_(True)
        sun_visible_fraction(SUN_RADIUS, rho_o, separation).sum().backward()

    seconds = median_seconds(with_gradient, repeat=args.repeat, warmup=1) * scale * 10
    rows.append({"workload": "sun_visible_fraction 1e7 forward + backward (scaled from 1e6)",
                 "previous s": float("nan"), "median s": seconds, "previous / new": float("nan"),
                 "target s": float("nan"), "ratio to target": float("nan")})

    # lunar eclipses over a century; the ephemeris share measured by wrapping its call
    spent = {"ephemeris": 0.0}
    original = circumstances_module._Geometry.__init__

    def timed_init(self, *a, **k):
        start = time.perf_counter()
        original(self, *a, **k)
        spent["ephemeris"] += time.perf_counter() - start

    circumstances_module._Geometry.__init__ = timed_init
    try:
        count = {}

        def century():
            spent["ephemeris"] = 0.0
            count["n"] = lunar_eclipses("1950-01-01", "2050-01-01").sizes["eclipse"]

        seconds = median_seconds(century, repeat=args.repeat, warmup=1)
    finally:
        circumstances_module._Geometry.__init__ = original
    rows.append({"workload": f"lunar_eclipses 1950-2050 ({count['n']} eclipses)",
                 "previous s": float("nan"), "median s": seconds, "previous / new": float("nan"),
                 "target s": TARGET_ECLIPSES_S, "ratio to target": seconds / TARGET_ECLIPSES_S})
    rows.append({"workload": "  of which ephemeris (sun_moon_vectors at Chebyshev nodes)",
                 "previous s": float("nan"), "median s": spent["ephemeris"],
                 "previous / new": float("nan"), "target s": float("nan"),
                 "ratio to target": float("nan")})

    table = markdown_table(rows)
    load_after = os.getloadavg()
    text = (f"\n### Eclipse geometry (`benchmarks/bench_eclipse_geometry.py`)\n\n"
            f"Machine: {machine_description()}; load average (1 min) {load_before[0]:.1f} "
            f"before, {load_after[0]:.1f} after. `previous`: `sun_visible_fraction` as of "
            f"commit {PREVIOUS_COMMIT}, called alternately with the new one.\n\n{table}\n")
    report(text, args.append)
    return 0


if __name__ == "__main__":
    np.seterr(all="ignore")
    raise SystemExit(main())
