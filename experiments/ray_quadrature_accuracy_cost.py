"""The quadrature along the tables' rays (``TableResolution.ray_quadrature``): accuracy and cost.

The tables integrate source x transmittance along each of their rays on ``n_ray``
samples. ``"trapezoid"`` takes the columns and the product by the trapezoid on the
samples; ``"exponential"`` takes the columns from 8 sub-samples per segment and the
transmittance exponential between the samples (product integration), exact for a source
linear between them however thick the segment. The scene presets' small tables (16
samples per ray, the default preset; 24, the reference preset) and the default tables
(96 samples, 16 radii), each with both quadratures, and the default tables since
2026-12-07 (24 radii, exponential), against three independent references:

* DISORT's plane-parallel sky from the ground and sasktran2's spherical radiance leaving
  the top (:func:`experiments._disort_reference.sky_and_top_errors`: U.S. 1976 +
  Henyey-Greenstein aerosol g 0.7, ω 0.95, optical depth 0.05 / 0.3 / 1 at 550 nm, 400 and
  550 nm, Sun 30 / 60 deg, views 0-60 deg at three azimuths);
* the backward Monte-Carlo of the sky from the ground, day to twilight
  (:func:`experiments._montecarlo_reference.montecarlo_errors`: molecules alone and with an
  aerosol of optical depth 0.1, Sun zenith 30-98 deg).

What is compared is what scenes render: the ray-marched single scattering plus the
tables' orders >= 2; the largest relative error over the views and wavelengths. Cost: the
precompute of the DISORT comparison (3 optical depths x 2 wavelengths in one call), after
one build that warms the caches.

Writes ``ray_quadrature_accuracy_cost.nc`` / ``.png``. Run:
``python experiments/ray_quadrature_accuracy_cost.py [--quick] [--output-dir DIR]``.
``--quick``: the default preset's tables with both quadratures, 550 nm, optical depth 1,
molecules alone against the Monte-Carlo.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import _montecarlo_reference as montecarlo  # noqa: E402
from experiments._common import parse_arguments, save_outputs  # noqa: E402
from experiments._disort_reference import (  # noqa: E402
    REFERENCES,
    SPHERICAL_TOP,
    WHERE,
    error_coords,
    load_reference,
    sky_and_top_errors,
)
from skytorch.atmosphere import Atmosphere  # noqa: E402
from skytorch.atmosphere.multiple_scattering import (  # noqa: E402
    TableResolution,
    precompute_scattering,
)
from skytorch.scene.presets import FIDELITY  # noqa: E402

DEFAULT_PRESET = dict(FIDELITY["default"]["ms_tables"])
REFERENCE_PRESET = dict(FIDELITY["reference"]["ms_tables"])
#: (name, table sizes on top of the default TableResolution)
CASES = tuple(
    (f"{name}, {quadrature}", {**sizes, "ray_quadrature": quadrature})
    for name, sizes in (("default preset", DEFAULT_PRESET),
                        ("default preset, 24 view nodes", {**DEFAULT_PRESET, "n_mu": 24}),
                        ("reference preset", REFERENCE_PRESET),
                        ("default tables, 16 radii", {"n_r": 16}))
    for quadrature in ("trapezoid", "exponential")) + (
    ("default tables (24 radii), exponential", {"n_r": 24, "ray_quadrature": "exponential"}),)
QUICK = CASES[0], CASES[1]
AODS = (0.05, 0.3, 1.0)


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    quick = arguments.quick
    cases = QUICK if quick else CASES
    aods = [1.0] if quick else list(AODS)
    mc_cases = montecarlo.CASES[:1] if quick else montecarlo.CASES
    disort = load_reference()
    if quick:
        disort = disort.sel(wavelength=[550.0])
    with xr.open_dataset(SPHERICAL_TOP) as ds:
        top = ds.load()
    mc, mc_reference = montecarlo.load_montecarlo()
    # one build that warms the caches before the first timed one
    precompute_scattering(Atmosphere.earth(), torch.tensor([550.0], dtype=torch.float64),
                          scattering_orders=2, resolution=TableResolution.tiny())
    error = np.zeros((len(cases), 2, 2, len(aods), disort.sun_zenith.size))
    twilight = np.zeros((len(cases), len(mc_cases), len(montecarlo.SUN_ZENITH_DEG),
                         len(montecarlo.STATISTICS)))
    seconds = np.zeros(len(cases))
    for i, (name, sizes) in enumerate(cases):
        error[i], seconds[i] = sky_and_top_errors((disort, top), aods, sizes)
        for j, case in enumerate(mc_cases):
            twilight[i, j], _, _ = montecarlo.montecarlo_errors(mc, mc_reference, case, sizes)
        print(f"{name} ({seconds[i]:.1f} s): " + " | ".join(
            f"{label.split()[0]}: " + "; ".join(
                f"τ {aod:g} " + " / ".join(f"{100 * error[i, w, 0, j, k]:.2f}"
                                           for k in range(disort.sun_zenith.size))
                for j, aod in enumerate(aods))
            for w, label in enumerate(WHERE)) + " | Monte-Carlo " + "; ".join(
            f"{case} " + " / ".join(f"{100 * v:.1f}" for v in twilight[i, j, :, 0])
            for j, case in enumerate(mc_cases)) + " %", flush=True)
    dataset = xr.Dataset(
        {"error": (("case", "where", "statistic", "aod", "sun_zenith"), error,
                   {"units": "1", "long_name": "largest |model / reference - 1| over the "
                    "views (or at the vertical) and wavelengths"}),
         "montecarlo_error": (("case", "atmosphere", "mc_sun_zenith", "mc_statistic"),
                              twilight,
                              {"units": "1", "long_name": "largest |model / Monte-Carlo - 1| "
                               "over the decided views (or at the zenith) and wavelengths"}),
         "precompute_seconds": ("case", seconds, {"units": "s"}),
         "ray_quadrature": ("case", np.array([s["ray_quadrature"] for _, s in cases])),
         "n_ray": ("case", np.array([s.get("n_ray", TableResolution().n_ray)
                                     for _, s in cases]))},
        coords={"case": ("case", np.array([c[0] for c in cases])),
                "atmosphere": ("atmosphere", np.array(mc_cases)),
                "mc_sun_zenith": ("mc_sun_zenith", np.array(montecarlo.SUN_ZENITH_DEG),
                                  {"units": "degree"}),
                "mc_statistic": ("mc_statistic", np.array(montecarlo.STATISTICS)),
                **error_coords(aods, disort.sun_zenith.values)},
        attrs={"title": "Quadrature along the tables' rays: ray-marched order 1 + the "
                        "tables' orders >= 2 against DISORT, sasktran2 and the Monte-Carlo",
               "references": f"{REFERENCES}; {montecarlo.REFERENCE}",
               "wavelengths_nm": str(disort.wavelength.values.tolist()),
               "table_sizes": "; ".join(f"{name}: {sizes}" for name, sizes in cases),
               "torch_threads": torch.get_num_threads()})
    figure, axes = plt.subplots(1, 3, figsize=(13.5, 4.0))
    for i, (name, sizes) in enumerate(cases):
        style = dict(color=f"C{i // 2}", marker="o", ms=3,
                     ls="-" if sizes["ray_quadrature"] == "exponential" else "--",
                     label=f"{name} ({seconds[i]:.1f} s)")
        for w in range(2):
            axes[w].semilogy(aods, 100 * error[i, w, 0].max(axis=-1), **style)
        axes[2].semilogy(montecarlo.SUN_ZENITH_DEG, 100 * twilight[i, -1, :, 0], **style)
    for w, label in enumerate(WHERE):
        axes[w].set_title(label, fontsize=9)
        axes[w].set_xlabel("aerosol optical depth at 550 nm")
    axes[2].set_title(f"sky from the ground against the Monte-Carlo ({mc_cases[-1]})",
                      fontsize=9)
    axes[2].set_xlabel("Sun zenith [deg]")
    for axis in axes:
        axis.set_ylabel("largest error [%]")
        axis.axhline(1.0, color="grey", lw=0.6, ls=":")
    axes[0].legend(fontsize=6)
    figure.tight_layout()
    save_outputs(dataset, figure, arguments.output_dir, "ray_quadrature_accuracy_cost")
    return 0


if __name__ == "__main__":
    sys.exit(main())
