"""Accuracy versus cost of the scene's multiple-scattering tables (resolution, wavelength nodes).

The scene's sky is its exact single-scattering table plus the orders 2..N of coarse
multiple-scattering tables at a few wavelength nodes, interpolated in log radiance to
the scene's wavelengths (:func:`skytorch.scene.render.higher_orders`). This experiment
varies the table resolution (``tiny``: ``TableResolution.tiny()``; ``small``: the
"fast" preset's (the "default" preset's until 2026-12-06, now with 8 radii instead of 5),
tiny with 24 Sun zenith nodes; ``coarse``: the "reference"
preset's) and the number of wavelength nodes (3, 6, 8 and every scene wavelength), and
measures on the default sky look-up grid (24 zenith x 25 azimuth nodes) the relative
error of the whole sky (single + higher orders) against the finest affordable case,
``coarse`` tables at every scene wavelength (no interpolation), and the wall time of
the table build. Scene: turbidity 2, 300 DU, "bands15" wavelengths (376-814 nm), ground
observer; Sun at zenith 60 deg (day) and 96 deg (6 deg below the horizon).

Output ``scene_ms_accuracy_cost.nc`` / ``.png``; ``--quick`` runs tiny tables with 3 and
every node against small tables at every node (a smoke test of the script).
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402

SUN_ZENITH_DEG = (60.0, 96.0)


def resolutions():
    """Return the table resolutions compared (TableResolution fields)."""
    from skytorch.scene.presets import FIDELITY

    small = dict(FIDELITY["fast"]["ms_tables"])  # the default preset's until 2026-12-06
    return {"tiny": dict(small, n_mu_s=8), "small": small,
            "coarse": dict(FIDELITY["reference"]["ms_tables"])}


def sky(resources, wavelength, sun_zenith_deg, resolution, n_nodes, single):
    """Whole sky (z, a, wl) per unit irradiance with the given tables, and the build time."""
    from skytorch.scene.presets import FIDELITY
    from skytorch.scene.render import Knobs, _azimuth_nodes, _zenith_nodes, higher_orders

    fidelity = dict(FIDELITY["default"], ms_tables=resolution, ms_wavelength_nodes=n_nodes)
    start = time.perf_counter()
    tables = resources.scattering_tables("converged", resolution, n_nodes)
    seconds = time.perf_counter() - start
    knobs = Knobs(fidelity, torch.float64, None, 0.0, 0.0, 0.0,
                  scattering_orders={"sky": tables.orders_computed, "moon": 1,
                                     "tables": "converged"})
    n_z, n_a = fidelity["sky_lut"]
    z, a = torch.meshgrid(_zenith_nodes(n_z, torch.float64), _azimuth_nodes(n_a, torch.float64),
                          indexing="ij")
    higher = higher_orders(resources, knobs, math.radians(sun_zenith_deg), z, a, wavelength,
                           tables.orders_computed)
    return single + higher, seconds


def run(quick: bool):
    """Return the Dataset of errors and build times."""
    import xarray as xr

    from skytorch.scene.presets import FIDELITY
    from skytorch.scene.render import _azimuth_nodes, _zenith_nodes
    from skytorch.scene.resources import SceneResources, SceneSpec
    from skytorch.spectrum import wavelength_grid

    wavelength = torch.as_tensor(wavelength_grid("bands15"), dtype=torch.float64)
    grid = tuple(float(v) for v in wavelength)
    all_nodes = len(grid)
    tables = resolutions()
    if quick:
        cases = [("tiny", 3), ("tiny", all_nodes)]
        reference = ("small", all_nodes)
    else:
        cases = [(name, n) for name in ("tiny", "small") for n in (3, 6, 8, all_nodes)]
        cases += [("coarse", 6), ("coarse", 8)]
        reference = ("coarse", all_nodes)
    n_z, n_a = FIDELITY["default"]["sky_lut"]
    z, a = torch.meshgrid(_zenith_nodes(n_z, torch.float64), _azimuth_nodes(n_a, torch.float64),
                          indexing="ij")
    labels = [f"{name}/{n}" for name, n in cases]
    max_error = np.zeros((len(SUN_ZENITH_DEG), len(cases)))
    mean_error = np.zeros_like(max_error)
    seconds = np.zeros(len(cases))
    ms_share = np.zeros(len(SUN_ZENITH_DEG))
    for i, sun in enumerate(SUN_ZENITH_DEG):
        # fresh resources per Sun: every build is timed cold
        atm = SceneResources(SceneSpec(2.0, 300.0, grid)).atmosphere
        single = atm.sky_radiance(wavelength, z, a, torch.full_like(z, math.radians(sun)),
                                  torch.zeros_like(z), 0.0, n_samples=48, scattering_orders=1)
        resources = SceneResources(SceneSpec(2.0, 300.0, grid))
        truth, _ = sky(resources, wavelength, sun, tables[reference[0]], reference[1], single)
        ms_share[i] = float(1.0 - single.sum() / truth.sum())
        for j, (name, n) in enumerate(cases):
            resources = SceneResources(SceneSpec(2.0, 300.0, grid))
            value, build = sky(resources, wavelength, sun, tables[name], n, single)
            relative = ((value - truth) / truth).abs()
            max_error[i, j] = float(relative.max())
            mean_error[i, j] = float(relative.mean())
            seconds[j] = max(seconds[j], build) if i else build
    return xr.Dataset(
        {"max_relative_error": (("sun_zenith", "case"), max_error, {
            "units": "1", "long_name": "largest relative error of the sky",
            "description": "max over the sky look-up nodes and wavelengths of |sky/reference"
                           " - 1| (single scattering + orders >= 2)"}),
         "mean_relative_error": (("sun_zenith", "case"), mean_error, {
             "units": "1", "long_name": "mean relative error of the sky"}),
         "build_seconds": (("case",), seconds, {
             "units": "s", "long_name": "table build wall time",
             "description": "converged orders, larger of the two Sun runs, 1 thread"}),
         "higher_order_share": (("sun_zenith",), ms_share, {
             "units": "1", "long_name": "share of orders >= 2 in the reference sky"})},
        coords={"sun_zenith": ("sun_zenith", np.array(SUN_ZENITH_DEG), {"units": "degree"}),
                "case": ("case", np.array(labels, dtype=np.str_), {
                    "long_name": "table resolution / wavelength nodes"})},
        attrs={"title": "Scene multiple-scattering tables: accuracy vs cost",
               "reference": f"{reference[0]} tables at every one of {all_nodes} wavelengths",
               "torch_threads": torch.get_num_threads(),
               "load_average": " ".join(f"{v:.2f}" for v in os.getloadavg())})


def plot(ds):
    """Return the error-versus-time figure."""
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(7, 4.5))
    for k, sun in enumerate(ds.sun_zenith.values):
        axis.scatter(ds.build_seconds, ds.max_relative_error.isel(sun_zenith=k),
                     marker="os"[k % 2], label=f"Sun zenith {sun:.0f} deg (max)")
    for j, label in enumerate(ds.case.values):
        axis.annotate(str(label), (float(ds.build_seconds[j]),
                                   float(ds.max_relative_error[0, j])), fontsize=7)
    axis.set_xscale("log")
    axis.set_yscale("log")
    axis.set_xlabel("table build [s] (1 thread)")
    axis.set_ylabel("largest relative error of the sky")
    axis.set_title(f"orders >= 2 tables vs {ds.attrs['reference']}", fontsize=9)
    axis.legend(fontsize=8)
    return figure


def main(argv=None):
    """Run the experiment and write its netCDF and PNG."""
    args = parse_arguments(__doc__.splitlines()[0], argv)
    ds = run(args.quick)
    print(ds.to_dataframe().to_string())
    save_outputs(ds, plot(ds), args.output_dir, "scene_ms_accuracy_cost")


if __name__ == "__main__":
    main()
