"""Benchmarks of the atmosphere module against the targets of its issue.

Medians of repeated runs, measured side by side in one run:

* transmittance table 256 x 64 x 15 wavelengths (target <= 0.5 s);
* straight-ray optical depth, 1e6 rays x 15 wavelengths (target <= 2 s), float64 and
  float32, and with 1 wavelength (the spectral dimension costs one multiplication);
* single-scattering sky radiance on a 32 x 64 view grid (no target; for the record).

Run ``python benchmarks/bench_atmosphere.py [--rays N] [--threads T]``.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks._harness import (  # noqa: E402
    argument_parser,
    machine_description,
    markdown_table,
    median_seconds,
    parse_arguments,
)
from skytorch.atmosphere import Atmosphere  # noqa: E402
from skytorch.atmosphere.tables import transmittance_table  # noqa: E402


def main(argv=None) -> str:
    parser = argument_parser(__doc__.splitlines()[0], repeat=5, append_option=False)
    parser.add_argument("--rays", type=int, default=1_000_000)
    arguments = parse_arguments(parser, argv)
    atm = Atmosphere.earth(turbidity=2.5, ozone_du=300.0)
    wavelength = torch.linspace(360.0, 830.0, 15, dtype=torch.float64)
    generator = torch.Generator().manual_seed(0)
    zenith = torch.rand(arguments.rays, generator=generator, dtype=torch.float64) * 1.5
    repeat = arguments.repeat
    rows = []

    def add(name, function, target=None):
        seconds = median_seconds(function, repeat=repeat, warmup=1)
        rows.append({"benchmark": name, "median [s]": seconds,
                     "target [s]": "-" if target is None else target,
                     "ratio to target": "-" if target is None else f"{seconds / target:.2f}"})
        return seconds

    add("transmittance table 256x64x15", lambda: transmittance_table(atm, wavelength), 0.5)
    rays = f"{arguments.rays:.0e}".replace("+0", "")
    add(f"optical depth {rays} rays x 15 wl, float64",
        lambda: atm.optical_depth(wavelength, zenith), 2.0)
    add(f"optical depth {rays} rays x 15 wl, float32",
        lambda: atm.optical_depth(wavelength.float(), zenith.float()), 2.0)
    add(f"optical depth {rays} rays x 1 wl, float64",
        lambda: atm.optical_depth(wavelength[7:8], zenith))
    add(f"optical depth {rays} rays x 15 wl, trapezoid 500, float64 (1/10 of the rays)",
        lambda: atm.optical_depth(wavelength, zenith[: arguments.rays // 10],
                                  method="trapezoid"))
    view_zenith = torch.linspace(0.0, math.radians(89.0), 32, dtype=torch.float64)[:, None]
    view_azimuth = torch.linspace(0.0, 2 * math.pi, 64, dtype=torch.float64)
    add("single-scattering sky 32x64 views x 15 wl (128 samples)",
        lambda: atm.sky_radiance(wavelength, view_zenith, view_azimuth, 1.2, 0.0,
                                 scattering_orders=1))
    table = markdown_table(rows)
    text = f"Machine: {machine_description()}\n\n{table}\n"
    print(text)
    return text


if __name__ == "__main__":
    main()
