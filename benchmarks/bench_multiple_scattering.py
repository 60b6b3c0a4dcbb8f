"""Benchmark of the multiple-scattering tables (skytorch.atmosphere.multiple_scattering).

Medians of repeated runs: precompute of 4 orders against table size and wavelength
count, and the look-up of a 512 x 512 fisheye. ``--quick`` runs the small cases only;
``--target DTYPE`` runs only the issue's target once (4 orders at Bruneton 2017's table
sizes for 15 wavelengths, tables in float32 or float64) and prints its wall and CPU time.
Run with OMP_NUM_THREADS set to the cores to measure (the targets are for 2 cores).
"""

import argparse
import math
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._harness import median_seconds  # noqa: E402
from skytorch.atmosphere import Atmosphere  # noqa: E402
from skytorch.atmosphere.multiple_scattering import (  # noqa: E402
    TableResolution,
    precompute_scattering,
)


def main(quick: bool) -> None:
    atm = Atmosphere.earth(turbidity=2.0)
    sizes = [("tiny", TableResolution.tiny()),
             ("8x32x16x6", TableResolution(n_r=8, n_mu=32, n_mu_s=16, n_phi=6, n_ray=32,
                                           n_sphere_mu=6, mu_vertical_weight=0.0,
                                           r_ground_weight=0.0, sphere_phi_refinement=1,
                                           ray_quadrature="trapezoid")),
             ("former default 16x64x24x8, n_ray 48",
              TableResolution(n_r=16, n_mu_s=24, n_ray=48, mu_vertical_weight=0.0,
                              r_ground_weight=0.0, sphere_phi_refinement=1,
                              ray_quadrature="trapezoid")),
             ("default 24x64x48x8, n_ray 96, exponential", TableResolution())]
    if not quick:
        sizes.append(("bruneton2017 32x128x32x8", TableResolution.bruneton2017()))
    counts = (1, 3) if quick else (1, 3, 15)
    for name, res in sizes:
        for n in counts:
            if name.startswith("bruneton") and n > 1:
                continue
            wavelength = torch.linspace(400.0, 700.0, n, dtype=torch.float64)
            t = median_seconds(lambda w=wavelength, r=res: precompute_scattering(
                atm, w, scattering_orders=4, resolution=r), 1 if n > 1 else 2, warmup=0)
            print(f"precompute 4 orders, {name}, {n} wavelengths: {t:.2f} s", flush=True)
    tables = precompute_scattering(atm, torch.linspace(400.0, 700.0, 3, dtype=torch.float64),
                                   scattering_orders=4)
    x = torch.linspace(-1.0, 1.0, 512, dtype=torch.float64)
    xx, yy = torch.meshgrid(x, x, indexing="ij")
    radius = torch.sqrt(xx * xx + yy * yy)
    inside = radius <= 1.0
    zenith = (radius[inside] * math.pi / 2)
    azimuth = torch.atan2(yy[inside], xx[inside])
    t = median_seconds(lambda: tables.radiance(0.0, zenith, azimuth, 1.0), 5, warmup=0)
    print(f"512x512 fisheye look-up ({int(inside.sum())} pixels, 3 wavelengths): {t:.3f} s")


def target(dtype_name: str) -> None:
    """Time the issue's target once: 4 orders, Bruneton 2017's sizes, 15 wavelengths."""
    dtype = {"float32": torch.float32, "float64": torch.float64}[dtype_name]
    atm = Atmosphere.earth(turbidity=2.0)
    wavelength = torch.linspace(400.0, 700.0, 15, dtype=torch.float64)
    wall, cpu = time.perf_counter(), time.process_time()
    precompute_scattering(atm, wavelength, scattering_orders=4, dtype=dtype,
                          resolution=TableResolution.bruneton2017())
    print(f"precompute 4 orders, bruneton2017 32x128x32x8, 15 wavelengths, {dtype_name}: "
          f"{time.perf_counter() - wall:.1f} s wall, {time.process_time() - cpu:.1f} s CPU "
          f"({torch.get_num_threads()} threads)", flush=True)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--target", choices=("float32", "float64"))
    arguments = parser.parse_args()
    if arguments.target:
        target(arguments.target)
    else:
        main(arguments.quick)
