"""Benchmark of the Earth's shadow with atmosphere and of one lunar-eclipse light curve.

Rows (medians, measured side by side in one run):

* ``ShadowTable.compute`` for the Earth, 256 x 256 (u, v) x 15 wavelengths, refraction +
  extinction (ring profile traced once, included), in float64 and float32; and the
  64 x 64 table for scale. Target: <= 10 s (Schneegans et al. 2025 report about two
  minutes on a GPU for their complete precomputation).
* ``Shadow.relative_illuminance`` on 65 536 points (no table), float64.
* ``lunar_eclipse`` for 2015-09-28: 200 times, 15 wavelengths, 12 x 24 disc points (0.01 mag
  converged, tests/test_eclipse_lunar.py), with a prepared shadow model (its ring profile
  cached; the per-eclipse (u, v) table is built inside). Target: <= 2 s.
* ``--sweep``: a 10 x 10 turbidity x ozone sweep of the 2015-09-28 light curve (200 times,
  15 wavelengths), as one batched ``lunar_light_curve`` call and through
  ``skytorch.sweep(backend="broadcast")`` (both include tracing the rays of all 100
  atmospheres), and ``backend="serial"`` on a 2 x 2 corner scaled to 100 points. Target
  (issue 7): <= 60 s.

* ``--scattering``: the same table, direct evaluation and light curve without and with the
  single-scattered light (``Shadow.earth(scattering=True)``, kernel precomputation
  included), side by side; plus the table restricted to 0.9–1.1 lunar distances (what a
  lunar eclipse needs). Target for the full table: <= 10 s.

Run: ``python benchmarks/bench_eclipse_shadow.py [--append] [--threads 2] [--quick]
[--scattering]``.
The development machine has two cores shared with other jobs: medians are noisy.
"""

from __future__ import annotations

import sys
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
TARGET_CURVE_S = 2.0
TARGET_SWEEP_S = 60.0


def main(argv: list[str] | None = None) -> int:
    parser = argument_parser(__doc__.splitlines()[0], repeat=3)
    parser.add_argument("--quick", action="store_true", help="64 x 64 table only")
    parser.add_argument("--sweep", action="store_true",
                        help="only the 10 x 10 turbidity x ozone light-curve sweep")
    parser.add_argument("--scattering", action="store_true",
                        help="only the rows without and with single-scattered light")
    args = parse_arguments(parser, argv)
    if args.sweep:
        return _sweep(args)
    if args.scattering:
        return _scattering(args)

    from skytorch.eclipse.lunar import lunar_eclipse
    from skytorch.eclipse.shadow import Shadow
    from skytorch.eclipse.shadow_table import ShadowTable
    from skytorch.spectrum import wavelength_grid

    wavelength = wavelength_grid("bands15")
    rows = []
    sizes = [(64, torch.float64)] if args.quick else [(64, torch.float64),
                                                      (256, torch.float64),
                                                      (256, torch.float32)]
    for n, dtype in sizes:
        def build(n=n, dtype=dtype):
            shadow = Shadow.earth()  # fresh: includes tracing the ring profile
            ShadowTable.compute(shadow, wavelength, n_u=n, n_v=n, dtype=dtype, progress=False)

        seconds = median_seconds(build, repeat=1 if n == 256 else args.repeat, warmup=0)
        rows.append({"workload": f"Earth shadow table {n}x{n}x15 ({str(dtype)[6:]})",
                     "median s": seconds, "target s": TARGET_TABLE_S,
                     "ratio to target": seconds / TARGET_TABLE_S})

    shadow = Shadow.earth()
    shadow.ring_profile(wavelength)
    distance = torch.linspace(3.0e8, 5.0e8, 256, dtype=torch.float64)[:, None]
    offset = torch.linspace(0.0, 1.2e7, 256, dtype=torch.float64)[None, :]
    if not args.quick:
        seconds = median_seconds(
            lambda: shadow.relative_illuminance(distance, offset, wavelength), repeat=1,
            warmup=0)
        rows.append({"workload": "relative_illuminance 65536 points x 15 (direct)",
                     "median s": seconds, "target s": TARGET_TABLE_S,
                     "ratio to target": seconds / TARGET_TABLE_S})

    def curve():
        lunar_eclipse("2015-09-28", n_times=200, n_images=0, shadow=shadow)

    seconds = median_seconds(curve, repeat=args.repeat, warmup=1)
    rows.append({"workload": "lunar_eclipse 2015-09-28, 200 times, 288 disc points x 15",
                 "median s": seconds, "target s": TARGET_CURVE_S,
                 "ratio to target": seconds / TARGET_CURVE_S})

    text = (f"\n## Eclipse shadow (`benchmarks/bench_eclipse_shadow.py`)\n\n"
            f"Machine: {machine_description()}\n\n{markdown_table(rows)}\n")
    return _report(text, args.append)


def _scattering(args) -> int:
    """Rows without and with the single-scattered light, measured side by side."""
    from skytorch.constants import MEAN_EARTH_MOON_DISTANCE_M
    from skytorch.eclipse.lunar import lunar_eclipse
    from skytorch.eclipse.shadow import Shadow
    from skytorch.eclipse.shadow_table import ShadowTable
    from skytorch.spectrum import wavelength_grid

    wavelength = wavelength_grid("bands15")
    n = 64 if args.quick else 256
    rows = []
    lunar = {"min_distance_m": 0.9 * MEAN_EARTH_MOON_DISTANCE_M,
             "max_distance_m": 1.1 * MEAN_EARTH_MOON_DISTANCE_M}
    distance = torch.linspace(3.0e8, 5.0e8, n, dtype=torch.float64)[:, None]
    offset = torch.linspace(0.0, 1.2e7, n, dtype=torch.float64)[None, :]
    for label, options in (("full u range", {}), ("0.9-1.1 lunar distance", lunar)):
        seconds = {}
        for scattering in (False, True):
            def build(scattering=scattering, options=options):
                shadow = Shadow.earth(scattering=scattering)  # fresh: ring + kernel included
                ShadowTable.compute(shadow, wavelength, n_u=n, n_v=n, progress=False,
                                    **options)

            seconds[scattering] = median_seconds(build, repeat=1, warmup=0)
            print(f"table {label} scattering={scattering}: {seconds[scattering]:.3g} s",
                  file=sys.stderr)
        for scattering in (False, True):
            rows.append({"workload": f"Earth shadow table {n}x{n}x15, {label}, scattering="
                                     f"{scattering}", "median s": seconds[scattering],
                         "ratio to no scattering": seconds[scattering] / seconds[False],
                         "target s": TARGET_TABLE_S,
                         "ratio to target": seconds[scattering] / TARGET_TABLE_S})
    for scattering in (False, True):
        shadow = Shadow.earth(scattering=scattering)
        shadow.ring_profile(wavelength)
        seconds = median_seconds(
            lambda shadow=shadow: shadow.relative_illuminance(distance, offset, wavelength),
            repeat=1, warmup=1)
        rows.append({"workload": f"relative_illuminance {n * n} points x 15 (direct, kernel "
                                 f"cached), scattering={scattering}", "median s": seconds})
        seconds = median_seconds(lambda shadow=shadow: lunar_eclipse(
            "2015-09-28", n_times=200, n_images=0, shadow=shadow), repeat=args.repeat,
            warmup=1)
        rows.append({"workload": f"lunar_eclipse 2015-09-28, 200 times, scattering="
                                 f"{scattering}", "median s": seconds,
                     "target s": TARGET_CURVE_S, "ratio to target": seconds / TARGET_CURVE_S})
    keys = ("workload", "median s", "ratio to no scattering", "target s", "ratio to target")
    rows = [{key: row.get(key, "-") for key in keys} for row in rows]
    text = (f"\n## Eclipse shadow with single-scattered light (`benchmarks/bench_eclipse_shadow."
            f"py --scattering`)\n\nMachine: {machine_description()}\n\n"
            f"{markdown_table(rows)}\n")
    return _report(text, args.append)


def _report(text: str, append: bool) -> int:
    """Print ``text`` and, with ``append``, add it to docs/benchmarks.md."""
    report(text, append)
    return 0


def _curve(turbidity, ozone_du):
    """2015-09-28 light curve for scalar or broadcastable (turbidity, ozone) [mag]."""
    from skytorch.atmosphere import Atmosphere
    from skytorch.eclipse.lunar import lunar_light_curve

    out = lunar_light_curve("2015-09-28", Atmosphere.earth(turbidity=turbidity,
                                                           ozone_du=ozone_du))
    return {"v_magnitude": out["v_magnitude"],
            "greatest_v_magnitude": out["greatest_v_magnitude"]}


def _sweep(args) -> int:
    import time

    import numpy as np

    import skytorch as st

    turbidity = np.linspace(1.5, 4.0, 10)
    ozone = np.linspace(200.0, 400.0, 10)
    t = torch.as_tensor(turbidity)[:, None]
    o = torch.as_tensor(ozone)[None, :]
    rows = []

    def row(name, seconds):
        rows.append({"workload": name, "median s": seconds, "target s": TARGET_SWEEP_S,
                     "ratio to target": seconds / TARGET_SWEEP_S})

    row("10x10 light curves, one batched lunar_light_curve",
        median_seconds(lambda: _curve(t, o), repeat=1, warmup=0))
    row("10x10 light curves, st.sweep(backend='broadcast')",
        median_seconds(lambda: st.sweep(_curve, turbidity=turbidity, ozone_du=ozone,
                                        backend="broadcast", progress=False),
                       repeat=1, warmup=0))
    start = time.perf_counter()
    st.sweep(_curve, turbidity=turbidity[:2], ozone_du=ozone[:2], backend="serial",
             progress=False)
    row("10x10 light curves, st.sweep(backend='serial'), 2x2 scaled x25",
        25.0 * (time.perf_counter() - start))
    text = (f"\n## Eclipse light-curve sweep (`benchmarks/bench_eclipse_shadow.py --sweep`)\n\n"
            f"Machine: {machine_description()}\n\n{markdown_table(rows)}\n")
    return _report(text, args.append)


if __name__ == "__main__":
    raise SystemExit(main())
