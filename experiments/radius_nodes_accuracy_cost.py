"""The radius nodes crowded towards the ground (``r_ground_weight``): accuracy and cost.

References: DISORT's sky seen from the ground (``tests/data/ms_reference/disort_sky.nc``,
view zenith 0, 30, 60 deg) and sasktran2's spherical radiance leaving the top
(``sasktran2_top.nc``, observer at 100 km, nadir 0, 30, 60 deg), both at relative azimuth
0, 90, 180 deg, 400 and 550 nm, Sun at 30 and 60 deg, U.S. 1976 molecules +
Henyey-Greenstein aerosol (g 0.7, albedo 0.95) of optical depth 0.05-1 at 550 nm, black
ground.

An aerosol a kilometre or two deep puts most of the light scattered twice and more below
the third radius node of ref. 2's mapping (16 radii: 0, 0.45, 1.8, 4.0 km), where the
scattered light of the orders >= 2 is interpolated linearly in r. For the default table
sizes with ``TableResolution.r_ground_weight`` 0 (ref. 2), 1/4, 1/2 and 3/4, and for 32
radii on ref. 2's mapping (twice the cost): the ray-marched single scattering plus the
tables' orders >= 2 (what scenes render), the largest relative error over the views and
wavelengths and at the vertical, per aerosol optical depth and Sun; and the precompute time
(the optical depths batched in one call).

Writes ``radius_nodes_accuracy_cost.nc`` / ``.png``. Run:
``python experiments/radius_nodes_accuracy_cost.py [--quick] [--output-dir DIR]``.
``--quick``: the coarse tables of the tests, weights 0 and 1/2, 550 nm, optical depth 1.
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

#: (name, table sizes on top of the default TableResolution)
CASES = (("w 0 (ref. 2)", {}), ("w 1/4", {"r_ground_weight": 0.25}),
         ("w 1/2", {"r_ground_weight": 0.5}), ("w 3/4", {"r_ground_weight": 0.75}),
         ("32 radii, w 0", {"n_r": 32}))
QUICK_CASES = (("coarse, w 0", COARSE), ("coarse, w 1/2", {**COARSE, "r_ground_weight": 0.5}))


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    disort = load_reference()
    with xr.open_dataset(SPHERICAL_TOP) as ds:
        top = ds.load()
    quick = arguments.quick
    cases = QUICK_CASES if quick else CASES
    aods = [1.0] if quick else [0.05, 0.3, 1.0]
    if quick:
        disort = disort.sel(wavelength=[550.0])
    error = np.zeros((len(cases), 2, 2, len(aods), disort.sun_zenith.size))
    seconds = np.zeros(len(cases))
    for i, (_, sizes) in enumerate(cases):
        error[i], seconds[i] = sky_and_top_errors((disort, top), aods, sizes)
    dataset = xr.Dataset(
        {"error": (("case", "where", "statistic", "aod", "sun_zenith"), error,
                   {"units": "1", "long_name": "largest |model / reference - 1| over the "
                    "views (or at the vertical) and wavelengths"}),
         "precompute_seconds": ("case", seconds, {"units": "s"}),
         "r_ground_weight": ("case", np.array([s.get("r_ground_weight", 0.0)
                                               for _, s in cases]), {"units": "1"}),
         "n_r": ("case", np.array([s.get("n_r", 16) for _, s in cases]))},
        coords={"case": ("case", np.array([c[0] for c in cases])),
                **error_coords(aods, disort.sun_zenith.values)},
        attrs={"title": "Radius nodes crowded towards the ground: ray-marched order 1 + the "
                        "tables' orders >= 2 against flat and spherical references",
               "references": REFERENCES,
               "wavelengths_nm": str(disort.wavelength.values.tolist()),
               "torch_threads": torch.get_num_threads()})
    figure, axes = plt.subplots(1, 2, figsize=(9.5, 3.8), squeeze=False)
    for w, label in enumerate(WHERE):
        axis = axes[0, w]
        for i, (name, _) in enumerate(cases):
            axis.semilogy(aods, 100 * error[i, w, 0].max(axis=-1), "o-",
                          label=f"{name} ({seconds[i]:.0f} s)")
        axis.axhline(1.0, color="grey", lw=0.8, ls=":")
        axis.set_title(label, fontsize=9)
        axis.set_xlabel("aerosol optical depth at 550 nm")
        axis.set_ylabel("largest error, views and Suns [%]")
        axis.legend(fontsize=7)
    figure.tight_layout()
    save_outputs(dataset, figure, arguments.output_dir, "radius_nodes_accuracy_cost")
    for i, (name, _) in enumerate(cases):
        print(f"{name} ({seconds[i]:.1f} s): " + " | ".join(
            f"{label.split()[0]}: " + "; ".join(
                f"τ {aod:g} " + " / ".join(f"{100 * error[i, w, 0, j, k]:.2f}"
                                           for k in range(disort.sun_zenith.size))
                for j, aod in enumerate(aods))
            for w, label in enumerate(WHERE)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
