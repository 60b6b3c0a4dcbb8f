"""The view-zenith nodes moved towards the vertical (``mu_vertical_weight``): accuracy and cost.

References: sasktran2's spherical radiance leaving the top
(``tests/data/ms_reference/sasktran2_top.nc``: observer at 100 km, nadir 0, 30, 60 deg) and
DISORT's sky seen from the ground (``disort_sky.nc``: view zenith 0, 30, 60 deg), both at
relative azimuth 0, 90, 180 deg, 400 and 550 nm, Sun at 30 and 60 deg, U.S. 1976 molecules +
Henyey-Greenstein aerosol (g 0.7, albedo 0.95) of optical depth 0-1 at 550 nm, black ground.

For each table size and each ``TableResolution.mu_vertical_weight`` (0: ref. 2's mapping,
the default), the ray-marched single scattering plus the tables' orders >= 2 (what scenes
render): the largest relative error over the views and wavelengths, and at the vertical
(nadir from the top, zenith from the ground), per aerosol optical depth and Sun; and the
precompute time (the optical depths batched in one call).

Writes ``view_nodes_accuracy_cost.nc`` / ``.png``. Run:
``python experiments/view_nodes_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402
from experiments._disort_reference import (  # noqa: E402
    COARSE,
    REFERENCES,
    SPHERICAL_TOP,
    WHERE,
    error_coords,
    load_reference,
    sky_and_top_errors,
)

#: (name, table sizes): "default" is 16 x 64 x 24 x 8 with 48 samples per ray, the default
#: TableResolution before 2026-12-05 (now 48 Sun-zenith nodes, 96 samples, weight 1/2)
#: (the former defaults: radius nodes of ref. 2, the sphere quadrature on the table's azimuths)
_FORMER = {"n_r": 16, "r_ground_weight": 0.0, "sphere_phi_refinement": 1,
           "ray_quadrature": "trapezoid"}
CASES = (("coarse", COARSE), ("default", {**_FORMER, "n_mu_s": 24, "n_ray": 48}),
         ("default, n_ray 96", {**_FORMER, "n_mu_s": 24, "n_ray": 96}))
WEIGHTS = (0.0, 0.5, 1.0)


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    disort = load_reference()
    with xr.open_dataset(SPHERICAL_TOP) as ds:
        top = ds.load()
    quick = arguments.quick
    cases = CASES[:1] if quick else CASES
    weights = WEIGHTS[:2] if quick else WEIGHTS
    aods = [0.0, 1.0] if quick else [0.0, 0.05, 0.3, 1.0]
    if quick:
        disort = disort.sel(wavelength=[550.0])
    error = np.zeros((len(cases), len(weights), 2, 2, len(aods), disort.sun_zenith.size))
    seconds = np.zeros((len(cases), len(weights)))
    for i, (_, sizes) in enumerate(cases):
        for m, weight in enumerate(weights):
            error[i, m], seconds[i, m] = sky_and_top_errors(
                (disort, top), aods, {**sizes, "mu_vertical_weight": weight})
    dataset = xr.Dataset(
        {"error": (("case", "mu_vertical_weight", "where", "statistic", "aod", "sun_zenith"),
                   error, {"units": "1", "long_name": "largest |model / reference - 1| over "
                           "the views (or at the vertical) and wavelengths"}),
         "precompute_seconds": (("case", "mu_vertical_weight"), seconds, {"units": "s"})},
        coords={"case": ("case", np.array([c[0] for c in cases])),
                "mu_vertical_weight": ("mu_vertical_weight", np.array(weights)),
                **error_coords(aods, disort.sun_zenith.values)},
        attrs={"title": "View-zenith nodes moved towards the vertical: ray-marched order 1 + "
                        "the tables' orders >= 2 against spherical and flat references",
               "references": REFERENCES,
               "wavelengths_nm": str(disort.wavelength.values.tolist()),
               "torch_threads": torch.get_num_threads()})
    figure, axes = plt.subplots(2, len(cases), figsize=(4.2 * len(cases), 7.4), squeeze=False)
    for i, (name, _) in enumerate(cases):
        for w, label in enumerate(WHERE):
            axis = axes[w, i]
            for m, weight in enumerate(weights):
                axis.semilogy(aods, 100 * error[i, m, w, 0].max(axis=-1), ("s--", "o-", "x:")[m],
                              label=f"w {weight:g}, max ({seconds[i, m]:.0f} s)")
                axis.semilogy(aods, 100 * error[i, m, w, 1].max(axis=-1), ("s--", "o-", "x:")[m],
                              alpha=0.4, label=f"w {weight:g}, vertical")
            axis.set_title(f"{name}: {label}", fontsize=8)
            axis.set_xlabel("aerosol optical depth at 550 nm")
            axis.set_ylabel("error, worse Sun [%]")
            axis.legend(fontsize=6)
    figure.tight_layout()
    save_outputs(dataset, figure, arguments.output_dir, "view_nodes_accuracy_cost")
    for i, (name, _) in enumerate(cases):
        for m, weight in enumerate(weights):
            print(f"{name}, w {weight:g} ({seconds[i, m]:.1f} s): " + " | ".join(
                f"{label.split()[0]}: " + "; ".join(
                    f"τ {aod:g} " + " / ".join(f"{100 * error[i, m, w, 0, j, k]:.1f}"
                                               for k in range(disort.sun_zenith.size))
                    + " (vertical " + " / ".join(f"{100 * error[i, m, w, 1, j, k]:.1f}"
                                                 for k in range(disort.sun_zenith.size))
                    + ")" for j, aod in enumerate(aods))
                for w, label in enumerate(WHERE)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
