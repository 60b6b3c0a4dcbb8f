"""Radius nodes of the scene presets' small tables, day to twilight: accuracy and cost.

The ``fast`` preset's multiple-scattering tables (5 radii × 16 view × 24 Sun-zenith × 5
azimuth nodes, 16 samples per ray, 4 sphere nodes; the ``default`` preset's until
2026-12-06) with 5, 6, 7, 8 and 10 radius nodes, 8 radii with 24 samples per ray, and the
``reference`` preset's tables, against the backward Monte-Carlo of the sky seen from the
ground (``tests/data/ms_reference/montecarlo_sky.nc``, experiments/_montecarlo_reference.py):
what scenes render (the ray-marched single scattering plus the tables' orders >= 2), the
largest relative error over the views the Monte-Carlo decides, per Sun zenith 30-98 deg,
for molecules alone and with an aerosol of optical depth 0.1. The cost is the scene's
build of the tables: ``Atmosphere.earth()`` at the preset's 6 wavelength nodes, converged
orders, CPU time (all threads), median of 5 builds after one that warms the caches.

Writes ``preset_radius_nodes_accuracy_cost.nc`` / ``.png``. Run:
``python experiments/preset_radius_nodes_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402
from experiments._montecarlo_reference import (  # noqa: E402
    CASES,
    REFERENCE,
    STATISTICS,
    SUN_ZENITH_DEG,
    load_montecarlo,
    montecarlo_errors,
    scene_build_seconds,
)
from skytorch.scene.presets import FIDELITY  # noqa: E402

SMALL = FIDELITY["fast"]["ms_tables"]
VARIANTS = (("5 radii (fast)", SMALL), ("6 radii", {**SMALL, "n_r": 6}),
            ("7 radii", {**SMALL, "n_r": 7}),
            ("8 radii (default until 2026-12-07)", {**SMALL, "n_r": 8}),
            ("10 radii", {**SMALL, "n_r": 10}),
            ("8 radii, 24 samples", {**SMALL, "n_r": 8, "n_ray": 24}),
            ("reference preset", FIDELITY["reference"]["ms_tables"]))
QUICK = VARIANTS[0], VARIANTS[3]


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    mc, reference = load_montecarlo()
    quick = arguments.quick
    cases = CASES[:1] if quick else CASES
    variants = QUICK if quick else VARIANTS
    error = np.zeros((len(cases), len(variants), len(SUN_ZENITH_DEG), len(STATISTICS)))
    seconds = np.zeros(len(variants))
    for j, (_, resolution) in enumerate(variants):
        for i, case in enumerate(cases):
            error[i, j], _, _ = montecarlo_errors(mc, reference, case, resolution)
        seconds[j] = scene_build_seconds(resolution, 1 if quick else 5)
    labels = [label for label, _ in variants]
    dataset = xr.Dataset(
        {"error": (("case", "tables", "sun_zenith", "statistic"), error,
                   {"units": "1", "long_name": "largest |model / Monte-Carlo - 1| over the "
                    "decided views (or at the zenith) and the two wavelengths"}),
         "build_seconds": (("tables",), seconds,
                           {"units": "s", "long_name": "CPU time of the converged tables "
                            "of Atmosphere.earth() at 6 wavelengths, median of 5 builds"}),
         "n_r": (("tables",), np.array([r["n_r"] for _, r in variants]),
                 {"units": "1", "long_name": "radius nodes"})},
        coords={"case": ("case", np.array(cases)),
                "tables": ("tables", np.array(labels)),
                "sun_zenith": ("sun_zenith", np.array(SUN_ZENITH_DEG), {"units": "degree"}),
                "statistic": ("statistic", np.array(STATISTICS))},
        attrs={"title": "Radius nodes of the scene presets' multiple-scattering tables: "
                        "ray-marched order 1 + the tables' orders >= 2 against the "
                        "Monte-Carlo, day to twilight",
               "reference": REFERENCE,
               "table_sizes": "; ".join(f"{label}: {r}" for label, r in variants),
               "torch_threads": torch.get_num_threads()})
    figure, axes = plt.subplots(1, 2, figsize=(10.5, 4.2))
    for i, case in enumerate(cases):
        for j, label in enumerate(labels):
            axes[i].semilogy(SUN_ZENITH_DEG, 100 * error[i, j, :, 0], "o-", color=f"C{j}",
                             label=f"{label} ({seconds[j]:.2f} s)")
        axes[i].set_title(case, fontsize=9)
    for axis in axes[:len(cases)]:
        axis.axhline(3.0, color="grey", lw=0.6)
        axis.axhline(10.0, color="grey", lw=0.6, ls=":")
        axis.set_xlabel("Sun zenith [deg]")
        axis.set_ylabel("error, max over decided views [%]")
        axis.legend(fontsize=6)
    for axis in axes[len(cases):]:
        axis.set_axis_off()
    figure.tight_layout()
    save_outputs(dataset, figure, arguments.output_dir, "preset_radius_nodes_accuracy_cost")
    for j, label in enumerate(labels):
        print(f"{label} ({seconds[j]:.2f} s): " + "; ".join(
            f"{case} " + " / ".join(f"{100 * error[i, j, k, 0]:.1f}"
                                    for k in range(len(SUN_ZENITH_DEG)))
            for i, case in enumerate(cases)) + " %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
