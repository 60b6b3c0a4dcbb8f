"""Sun-zenith nodes of the tables (``TableResolution.n_mu_s``), day to twilight: accuracy, cost.

Reference: the backward Monte-Carlo of the sky seen from the ground in spherical geometry
(``tests/data/ms_reference/montecarlo_sky.nc``, generator and provenance in that folder's
README): U.S. 1976 molecules without and with a Henyey-Greenstein aerosol (g 0.7, albedo
0.95) of optical depth 0.1 at 550 nm, 400 and 550 nm, black ground, Sun zenith 30-98 deg,
the zenith and the views 60 and 85 deg from it at relative azimuth 0, 90, 180 deg. Below
the horizon it is the only reference (sasktran2's successive orders are not one there,
docs/multiple_scattering_validation.md).

For each number of Sun-zenith nodes on the default tables' other sizes, what scenes
render (the ray-marched single scattering, 256 samples, plus the tables' orders >= 2): the
largest relative error over the views the Monte-Carlo decides (its standard error below a
third of the issue's tolerance, 3 % to Sun 80 deg and 10 % below) and at the zenith, per
Sun zenith; and the precompute time of the two wavelengths (converged orders).

Writes ``twilight_sun_nodes_accuracy_cost.nc`` / ``.png``. Run:
``python experiments/twilight_sun_nodes_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402
from experiments._disort_reference import COARSE  # noqa: E402
from experiments._montecarlo_reference import (  # noqa: E402
    CASES,
    REFERENCE,
    STATISTICS,
    SUN_ZENITH_DEG,
    load_montecarlo,
    montecarlo_errors,
)

#: the default tables of 2026-12-05 without their Sun-zenith nodes
DEFAULT = dict(n_r=16, n_mu=64, n_phi=8, n_ray=96, n_sphere_mu=12, transmittance_r=64,
               transmittance_mu=256, mu_vertical_weight=0.5,
               r_ground_weight=0.0, sphere_phi_refinement=1, ray_quadrature="trapezoid")
SUN_NODES = (24, 48, 96, 192)


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    mc, reference = load_montecarlo()
    quick = arguments.quick
    cases = CASES[:1] if quick else CASES
    nodes = (16, 32) if quick else SUN_NODES
    sizes = {k: v for k, v in COARSE.items() if k != "n_mu_s"} if quick else DEFAULT
    error = np.zeros((len(cases), len(nodes), len(SUN_ZENITH_DEG), len(STATISTICS)))
    decided = np.zeros((len(cases), len(SUN_ZENITH_DEG)), dtype=int)
    seconds = np.zeros((len(cases), len(nodes)))
    for i, case in enumerate(cases):
        for j, n_mu_s in enumerate(nodes):
            error[i, j], decided[i], seconds[i, j] = montecarlo_errors(
                mc, reference, case, {**sizes, "n_mu_s": n_mu_s})
    dataset = xr.Dataset(
        {"error": (("case", "n_mu_s", "sun_zenith", "statistic"), error,
                   {"units": "1", "long_name": "largest |model / Monte-Carlo - 1| over the "
                    "decided views (or at the zenith) and the two wavelengths"}),
         "decided_views": (("case", "sun_zenith"), decided,
                           {"units": "1", "long_name": "view-wavelength points whose "
                            "Monte-Carlo standard error is below a third of the tolerance"}),
         "precompute_seconds": (("case", "n_mu_s"), seconds, {"units": "s"})},
        coords={"case": ("case", np.array(cases)),
                "n_mu_s": ("n_mu_s", np.array(nodes), {"long_name": "Sun-zenith nodes"}),
                "sun_zenith": ("sun_zenith", np.array(SUN_ZENITH_DEG), {"units": "degree"}),
                "statistic": ("statistic", np.array(STATISTICS))},
        attrs={"title": "Sun-zenith nodes of the multiple-scattering tables: ray-marched "
                        "order 1 + the tables' orders >= 2 against the Monte-Carlo, day "
                        "to twilight",
               "reference": REFERENCE,
               "other_table_sizes": str(sizes),
               "torch_threads": torch.get_num_threads()})
    figure, axes = plt.subplots(1, 2, figsize=(10.5, 4.2))
    for i, case in enumerate(cases):
        for j, n_mu_s in enumerate(nodes):
            axes[0].semilogy(SUN_ZENITH_DEG, 100 * error[i, j, :, 0], ("o-", "s--")[i],
                             color=f"C{j}", label=f"{case}, {n_mu_s} Sun nodes")
        twilight = SUN_ZENITH_DEG.index(94.0)
        axes[1].loglog(seconds[i], 100 * error[i, :, twilight, 0], ("o-", "s--")[i],
                       label=case)
        for j, n_mu_s in enumerate(nodes):
            axes[1].annotate(str(n_mu_s), (seconds[i, j], 100 * error[i, j, twilight, 0]),
                             fontsize=7)
    for axis in axes:
        axis.axhline(3.0, color="grey", lw=0.6)
        axis.axhline(10.0, color="grey", lw=0.6, ls=":")
        axis.set_ylabel("error, max over decided views [%]")
        axis.legend(fontsize=6)
    axes[0].set_xlabel("Sun zenith [deg]")
    axes[1].set_xlabel("precompute, 2 wavelengths, converged [s]")
    axes[1].set_title("Sun 94 deg", fontsize=9)
    figure.tight_layout()
    save_outputs(dataset, figure, arguments.output_dir, "twilight_sun_nodes_accuracy_cost")
    for i, case in enumerate(cases):
        for j, n_mu_s in enumerate(nodes):
            print(f"{case}, {n_mu_s} Sun nodes ({seconds[i, j]:.1f} s): " + " / ".join(
                f"{100 * error[i, j, k, 0]:.1f}" for k in range(len(SUN_ZENITH_DEG)))
                + " % (zenith " + " / ".join(f"{100 * error[i, j, k, 1]:.1f}"
                                              for k in range(len(SUN_ZENITH_DEG))) + ")")
    return 0


if __name__ == "__main__":
    sys.exit(main())
