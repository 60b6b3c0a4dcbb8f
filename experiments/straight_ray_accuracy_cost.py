"""Accuracy vs cost of straight-ray optical depths (Gauss–Legendre nodes per piece).

Knob: ``n_steps``, the Gauss–Legendre nodes per piece of ``Atmosphere.optical_depth``
(default 6; the pieces are cut at the profiles' breakpoints), against a converged
reference (32 nodes per piece, float64). Rays: zenith angles uniform in [0, 1.5] rad
from sea level (the benchmark's rays) plus the horizontal ray; 60 wavelengths over
360–1000 nm, ``Atmosphere.earth(turbidity=2.5, ozone_du=300)`` (all species).
Error: largest absolute optical-depth error [1] and the same in magnitudes
(1.0857 dtau) over rays and wavelengths; cost: median wall time of the rays
[s] (1 torch thread). Writes ``straight_ray_accuracy_cost.nc`` / ``.png``.

Run: ``python experiments/straight_ray_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import torch
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._harness import median_seconds  # noqa: E402
from experiments._common import parse_arguments, save_outputs  # noqa: E402
from skytorch.atmosphere import Atmosphere  # noqa: E402

MAGNITUDE_PER_TAU = 2.5 / math.log(10.0)
NODES = (2, 3, 4, 5, 6, 8)
REFERENCE_NODES = 32


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    n_rays = 300 if arguments.quick else 100_000
    repeat = 1 if arguments.quick else 3
    torch.set_num_threads(1)
    atm = Atmosphere.earth(turbidity=2.5, ozone_du=300.0)
    wavelength = torch.linspace(360.0, 1000.0, 60, dtype=torch.float64)
    generator = torch.Generator().manual_seed(0)
    zenith = torch.rand(n_rays, generator=generator, dtype=torch.float64) * 1.5
    zenith = torch.cat([zenith, torch.tensor([0.5 * math.pi], dtype=torch.float64)])
    reference = atm.optical_depth(wavelength, zenith, n_steps=REFERENCE_NODES)
    error, relative, seconds = [], [], []
    for n in NODES:
        tau = atm.optical_depth(wavelength, zenith, n_steps=n)
        difference = (tau - reference).abs()
        error.append(float(difference.max()))
        relative.append(float((difference / reference.abs().clamp(min=1e-300)).max()))
        seconds.append(median_seconds(lambda n=n: atm.optical_depth(wavelength, zenith,
                                                                      n_steps=n),
                                      repeat=repeat, warmup=0 if arguments.quick else 1))
    error = np.array(error)
    dataset = xr.Dataset(
        {"max_abs_error_tau": ("n_steps", error,
                               {"units": "1", "long_name": "largest absolute optical-depth error"}),
         "max_abs_error_mag": ("n_steps", MAGNITUDE_PER_TAU * error,
                               {"units": "mag", "long_name": "largest extinction error"}),
         "max_rel_error": ("n_steps", np.array(relative),
                           {"units": "1", "long_name": "largest relative optical-depth error"}),
         "seconds": ("n_steps", np.array(seconds),
                     {"units": "s", "long_name": "median wall time of the rays"})},
        coords={"n_steps": ("n_steps", np.array(NODES),
                            {"units": "1", "long_name": "Gauss-Legendre nodes per piece"})},
        attrs={"title": "Straight-ray optical depth: accuracy vs cost",
               "n_rays": n_rays + 1, "n_wavelength": 60,
               "reference": f"{REFERENCE_NODES} nodes per piece, float64",
               "atmosphere": "Atmosphere.earth(turbidity=2.5, ozone_du=300)"})
    figure, axis = plt.subplots(figsize=(5, 3.5))
    axis.loglog(dataset["seconds"], np.maximum(dataset["max_abs_error_mag"], 1e-17), "o-")
    for n, x, y in zip(NODES, dataset["seconds"].values,
                       np.maximum(dataset["max_abs_error_mag"].values, 1e-17), strict=True):
        axis.annotate(str(n), (x, y))
    axis.set_xlabel(f"time of {n_rays + 1} rays x 60 wl [s]")
    axis.set_ylabel("largest extinction error [mag]")
    axis.set_title("straight rays: Gauss-Legendre nodes per piece")
    save_outputs(dataset, figure, arguments.output_dir, "straight_ray_accuracy_cost")
    rows = ["| nodes per piece | max abs error tau | max error [mag] | max rel error | time [s] |",
            "| --- | --- | --- | --- | --- |"]
    for i, n in enumerate(NODES):
        rows.append(f"| {n} | {error[i]:.2e} | {MAGNITUDE_PER_TAU * error[i]:.2e} | "
                    f"{relative[i]:.2e} | {seconds[i]:.3f} |")
    print("\n".join(rows))
    return dataset


if __name__ == "__main__":
    main()
