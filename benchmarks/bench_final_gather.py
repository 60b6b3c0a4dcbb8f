"""Benchmark of the final gather against the tables' look-up, and of the shadow's orders >= 2.

Workload: converged coarse tables (16 × 32 × 16 × 6, 3 wavelengths) of
``Atmosphere.earth(turbidity=2)``; the orders >= 2 of 64 lines of sight from the ground
(8 view zeniths 0-80 deg × 8 azimuths, Sun at 30 deg) looked up in the tables and
gathered along the lines (``higher_orders_gathered`` at its defaults, 65 536 look-ups per
line); and ``Shadow.earth(scattering=True).multiple_scattered_illuminance`` on the axis at
the Moon's distance (16 × 8 lines). Medians of ``--repeat`` calls, the cases alternating.

Run: ``python benchmarks/bench_final_gather.py [--append] [--threads 2] [--repeat 5]``.
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._harness import (  # noqa: E402
    alternating_medians,
    argument_parser,
    parse_arguments,
    report_section,
)


def main(argv: list[str] | None = None) -> int:
    parser = argument_parser(__doc__.splitlines()[0], repeat=5, threads=2)
    args = parse_arguments(parser, argv)
    import torch

    from skytorch.atmosphere import Atmosphere
    from skytorch.atmosphere.final_gather import higher_orders_gathered
    from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
    from skytorch.eclipse.shadow import Shadow

    load_before = os.getloadavg()
    wavelength = torch.tensor([450.0, 550.0, 650.0], dtype=torch.float64)
    resolution = TableResolution(n_r=16, n_mu=32, n_mu_s=16, n_phi=6, n_ray=24,
                                 n_sphere_mu=6, transmittance_r=32, transmittance_mu=128,
                                 mu_vertical_weight=0.0,
                                 r_ground_weight=0.0, sphere_phi_refinement=1,
                                 ray_quadrature="trapezoid")
    atmosphere = Atmosphere.earth(turbidity=2.0)
    clock = time.perf_counter()
    tables = precompute_scattering(atmosphere, wavelength, scattering_orders="converged",
                                   resolution=resolution)
    precompute_s = time.perf_counter() - clock
    shadow = Shadow.earth(scattering=True)
    shadow_tables = precompute_scattering(shadow.atmosphere, wavelength,
                                          scattering_orders="converged",
                                          resolution=resolution)
    zenith = torch.deg2rad(torch.linspace(0.0, 80.0, 8, dtype=torch.float64))[:, None]
    azimuth = torch.deg2rad(torch.linspace(0.0, 315.0, 8, dtype=torch.float64))[None, :]
    ground = torch.tensor(0.0, dtype=torch.float64)
    sun = torch.tensor(math.radians(30.0), dtype=torch.float64)
    distance = torch.tensor([384.4e6], dtype=torch.float64)

    cases = {
        "orders >= 2 looked up, 64 lines": lambda: (
            tables.radiance(ground, zenith, azimuth, sun)
            - tables.radiance(ground, zenith, azimuth, sun, scattering_orders=1)),
        "orders >= 2 gathered, 64 lines": lambda: higher_orders_gathered(
            tables, atmosphere, ground, zenith, azimuth, sun),
        "shadow orders >= 2, one point (16 x 8 lines)": lambda: (
            shadow.multiple_scattered_illuminance(distance, 0.0 * distance, shadow_tables)),
    }
    medians = alternating_medians(cases, args.repeat)
    looked_up = medians["orders >= 2 looked up, 64 lines"]
    rows = [{"case": label, "median [ms]": f"{value * 1e3:.2f}",
             "per line of sight [ms]": (f"{value * 1e3 / 64:.3f}" if "64 lines" in label
                                        else f"{value * 1e3 / 128:.2f}"),
             "vs look-up": f"{value / looked_up:.0f}x"}
            for label, value in medians.items()]
    report_section("Final gather", "bench_final_gather.py", load_before,
                   f"Coarse converged tables 16 × 32 × 16 × 6, 3 wavelengths (precompute "
                   f"{precompute_s:.1f} s); medians of {args.repeat} calls, the cases "
                   "alternating.", rows, args.append)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
