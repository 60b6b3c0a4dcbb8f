"""Orders >= 3 of the sky at totality: accuracy against a Monte-Carlo, and what it costs.

Reference: ``tests/data/ms_reference/montecarlo_eclipse_sky.nc`` (backward Monte-Carlo of
every order in spherical shells with the Sun's visible fraction at every next event;
U.S. 1976 molecules + Henyey-Greenstein aerosol g 0.7, τ550 0.1, albedo 0.95, 300 DU
ozone; the totalities of 2017-08-21 at Lowman, Idaho, and 2026-08-12 at Burgos; the zenith
and 60° / 85° towards, across and away from the Sun; its bin of orders >= 3).

For each setting of :func:`skytorch.scene.eclipse_higher_orders.eclipsed_higher_orders`
(final gather ``n_view`` x ``2 n_mu`` x ``n_phi``; the sphere of the neighbourhood
``2 n_neighbourhood_mu`` x ``n_neighbourhood_phi``; ``n_path`` samples per path; the
neighbourhood tabulated or evaluated at every point): the ratio to the Monte-Carlo at
every view, site and wavelength, its largest deviation, and the time for the seven views
of a site (coarse clear-sky tables 8 x 32 x 16 x 6, every order).

Writes ``eclipse_higher_orders_accuracy_cost.nc`` / ``.png``. Run:
``python experiments/eclipse_higher_orders_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import torch
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import load_script, parse_arguments, save_outputs  # noqa: E402
from skytorch.atmosphere.multiple_scattering import (  # noqa: E402
    TableResolution,
    precompute_scattering,
)
from skytorch.scene.eclipse_higher_orders import eclipsed_higher_orders  # noqa: E402

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "ms_reference"
WAVELENGTHS = (400.0, 550.0)
#: name -> keywords; "default" first
SETTINGS = {
    "default": {},
    "quick": dict(n_view=6, n_mu=3, n_phi=8, n_neighbourhood_mu=3, n_neighbourhood_phi=8,
                  n_path=8),
    "gather 8 samples": dict(n_view=8),
    "gather 16 x 12 x 16": dict(n_view=16, n_mu=6, n_phi=16),
    "neighbourhood 12 x 24, 16 samples": dict(n_neighbourhood_mu=6, n_neighbourhood_phi=24,
                                              n_path=16),
    "neighbourhood at every point": dict(neighbourhood_grid=None),
}


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    torch.set_num_threads(2)
    generator = load_script(DATA / "generate_eclipse_montecarlo.py",
                            "generate_eclipse_montecarlo")
    with xr.open_dataset(DATA / "montecarlo_eclipse_sky.nc") as reference:
        reference = reference.sel(wavelength=list(WAVELENGTHS)).load()
    settings = ["quick"] if arguments.quick else list(SETTINGS)
    views = [0] if arguments.quick else list(range(reference.sizes["view"]))
    sites = list(reference.site.values[1:]) if arguments.quick else list(reference.site.values)
    atmosphere, wavelength, table = generator.model_inputs(WAVELENGTHS)
    tables = precompute_scattering(atmosphere, wavelength, scattering_orders="converged",
                                   resolution=TableResolution(n_r=8, n_mu=32, n_mu_s=16,
                                                              n_phi=6, n_ray=48,
                                                              mu_vertical_weight=0.0,
                                                              r_ground_weight=0.0,
                                                              sphere_phi_refinement=1,
                                                              ray_quadrature="trapezoid"))
    ratio = np.full((len(settings), len(sites), len(WAVELENGTHS), len(views)), np.nan)
    seconds = np.full((len(settings), len(sites)), np.nan)
    for j, site in enumerate(sites):
        geometry, zenith, azimuth = generator.site_lines(site, views)
        mc = reference.order_3plus.sel(site=site).values[:, views]
        for i, name in enumerate(settings):
            start = time.perf_counter()
            higher = eclipsed_higher_orders(atmosphere, wavelength, zenith, azimuth, geometry,
                                            generator.mc.OBSERVER_ALTITUDE_M, tables=tables,
                                            table=table, **SETTINGS[name])
            seconds[i, j] = time.perf_counter() - start
            ratio[i, j] = higher.T.numpy() / mc
            print(f"{site} {name}: {seconds[i, j]:.1f} s, model / Monte-Carlo "
                  f"{np.nanmin(ratio[i, j]):.2f}-{np.nanmax(ratio[i, j]):.2f}", flush=True)
    dataset = xr.Dataset(
        {"ratio_to_montecarlo": (("setting", "site", "wavelength", "view"), ratio,
                                 {"long_name": "orders >= 3, model / Monte-Carlo"}),
         "largest_deviation": (("setting",), np.nanmax(np.abs(ratio - 1.0), axis=(1, 2, 3)),
                               {"long_name": "largest |model / Monte-Carlo - 1|"}),
         "seconds": (("setting", "site"), seconds,
                     {"long_name": "time for the views of a site", "units": "s"}),
         "montecarlo_stderr": (("site", "wavelength", "view"),
                               (reference.order_3plus_stderr / reference.order_3plus)
                               .sel(site=sites).values[..., views],
                               {"long_name": "relative standard error of the reference"})},
        coords={"setting": settings, "site": sites, "wavelength": list(WAVELENGTHS),
                "view": views,
                "view_zenith": ("view", reference.view_zenith.values[views]),
                "relative_azimuth": ("view", reference.relative_azimuth.values[views])},
        attrs={"title": "Orders >= 3 of the sky at totality against a Monte-Carlo",
               "reference": "tests/data/ms_reference/montecarlo_eclipse_sky.nc"})
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 2, figsize=(11, 4))
    for j, site in enumerate(sites):
        for k, wl in enumerate(WAVELENGTHS):
            axes[0].scatter(seconds[:, j], np.nanmax(np.abs(ratio[:, j, k] - 1.0), axis=-1),
                            label=f"{site}, {wl:.0f} nm")
    axes[0].set_xlabel("time for the views of a site [s]")
    axes[0].set_ylabel("largest |model / Monte-Carlo - 1|")
    axes[0].legend(fontsize=7)
    default = ratio[0]
    for j, site in enumerate(sites):
        for k, wl in enumerate(WAVELENGTHS):
            axes[1].plot(views, default[j, k], "o-", label=f"{site}, {wl:.0f} nm")
    axes[1].axhline(1.0, color="k", lw=0.8)
    axes[1].set_xlabel("view (0 zenith; 1-3 60° and 4-6 85°: towards, across, away)")
    axes[1].set_ylabel(f"orders >= 3, model / Monte-Carlo ({settings[0]})")
    axes[1].legend(fontsize=7)
    save_outputs(dataset, figure, arguments.output_dir, "eclipse_higher_orders_accuracy_cost")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
