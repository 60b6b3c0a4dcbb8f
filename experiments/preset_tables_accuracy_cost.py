"""The scene presets' multiple-scattering tables, knob by knob, from day to deep twilight.

What each of the small tables' sizes costs in accuracy: the ``default`` preset's tables of
before 2026-12-07 (8 radii × 16 view × 24 Sun-zenith × 5 azimuth nodes, 16 samples per ray,
4 × 1 sphere directions, transmittance 16 × 32), each of their knobs raised alone to the
default ``TableResolution()``'s value, the sphere quadrature and the view nodes together
(the ``default`` preset since 2026-12-07), the ``reference`` and ``fast`` presets. Two
references:

* the backward Monte-Carlo of the sky seen from the ground
  (``tests/data/ms_reference/montecarlo_sky.nc``, experiments/_montecarlo_reference.py),
  Sun zenith 30-98 deg: what scenes render (ray-marched single scattering + the tables'
  orders >= 2), the largest relative error over the views the Monte-Carlo decides and at
  the zenith;
* below 98 deg, where the Monte-Carlo's standard error no longer decides, the converged
  solver: the orders >= 2 of ``TableResolution()`` (24 radii, 48 Sun-zenith nodes; its own
  convergence to the Sun at 108 deg in docs/scene.md), same atmospheres, wavelengths and
  views, Sun zenith 94-108 deg: the largest relative error of the orders >= 2 over views
  and wavelengths, and at the zenith.

Cost: the scene's build of the tables, ``Atmosphere.earth()`` at the preset's 6 wavelength
nodes, converged orders, CPU time (all threads), median of 5 builds after a warm-up.

Writes ``preset_tables_accuracy_cost.nc`` / ``.png``. Run:
``python experiments/preset_tables_accuracy_cost.py [--quick] [--output-dir DIR]``
(``--quick``: the former and the present default, Rayleigh only, a smaller converged
reference of 16 radii × 48 view × 32 Sun-zenith nodes, one build for the cost).
"""

from __future__ import annotations

import dataclasses
import math
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
from skytorch.atmosphere.multiple_scattering import (  # noqa: E402
    TableResolution,
    precompute_scattering,
)
from skytorch.scene.presets import FIDELITY  # noqa: E402

#: the default preset's tables of 2026-12-06 (8 radii on the fast preset's small tables)
FORMER_DEFAULT = {**FIDELITY["fast"]["ms_tables"], "n_r": 8}
#: the default TableResolution, the converged end of each knob
CONVERGED = dataclasses.asdict(TableResolution())
#: knobs raised one at a time (fields set together: a size and its node mapping)
KNOBS = (("24 radii", ("n_r", "r_ground_weight")),
         ("64 view nodes", ("n_mu", "mu_vertical_weight")),
         ("48 Sun-zenith nodes", ("n_mu_s",)),
         ("8 azimuth nodes", ("n_phi",)),
         ("96 ray samples", ("n_ray",)),
         ("sphere 12 x 2", ("n_sphere_mu", "sphere_phi_refinement")),
         ("transmittance 64 x 256", ("transmittance_r", "transmittance_mu")))
VARIANTS = ((("default until 2026-12-07", FORMER_DEFAULT),)
            + tuple((f"+ {label}", {**FORMER_DEFAULT, **{k: CONVERGED[k] for k in fields}})
                    for label, fields in KNOBS)
            + (("+ sphere 8 x 2", {**FORMER_DEFAULT, "n_sphere_mu": 8,
                                   "sphere_phi_refinement": 2}),
               ("+ sphere 12 x 2, 24 view nodes", {**FORMER_DEFAULT, "n_sphere_mu": 12,
                                                   "sphere_phi_refinement": 2, "n_mu": 24}),
               ("default: + sphere 8 x 2, 24 view nodes", dict(FIDELITY["default"]["ms_tables"])),
               ("reference preset", dict(FIDELITY["reference"]["ms_tables"])),
               ("fast preset", dict(FIDELITY["fast"]["ms_tables"]))))
QUICK_VARIANTS = (VARIANTS[0], VARIANTS[-3])
#: Sun zenith angles of the comparison with the converged solver [deg]
TWILIGHT_SUN_ZENITH_DEG = (94.0, 98.0, 100.0, 102.0, 104.0, 106.0, 108.0)
#: the statistics of the comparison with the converged solver
CONVERGED_STATISTICS = ("max over views", "zenith")
#: the quick run's smaller converged reference
QUICK_CONVERGED = TableResolution(n_r=16, n_mu=48, n_mu_s=32, n_ray=48, n_sphere_mu=8)


def higher_orders(tables, views, sun_zenith_deg: float) -> torch.Tensor:
    """Orders >= 2 of ``tables`` seen from the Monte-Carlo's observer, (view, wavelength)."""
    zenith, azimuth, height = views
    sun = torch.tensor(math.radians(sun_zenith_deg), dtype=torch.float64)
    return (tables.radiance(height, zenith, azimuth, sun)
            - tables.radiance(height, zenith, azimuth, sun, scattering_orders=1))


def twilight_errors(mc, reference, case: str, variants, converged: TableResolution):
    """(variant, Sun, statistic) errors of the orders >= 2 against the converged solver."""
    atmosphere = mc.skytorch_atmosphere(mc.CASES[case])
    wavelength = torch.tensor(reference.wavelength.values, dtype=torch.float64)
    views = (torch.deg2rad(torch.tensor([v[0] for v in mc.VIEWS], dtype=torch.float64)),
             torch.deg2rad(torch.tensor([v[1] for v in mc.VIEWS], dtype=torch.float64)),
             torch.tensor(mc.OBSERVER_ALTITUDE_M, dtype=torch.float64))

    def build(resolution):
        return precompute_scattering(atmosphere, wavelength, ground_albedo=0.0,
                                     scattering_orders="converged", resolution=resolution)

    truth = build(converged)
    expected = [higher_orders(truth, views, sun) for sun in TWILIGHT_SUN_ZENITH_DEG]
    error = np.zeros((len(variants), len(TWILIGHT_SUN_ZENITH_DEG), len(CONVERGED_STATISTICS)))
    for j, (_, resolution) in enumerate(variants):
        tables = build(TableResolution(**resolution))
        for k, sun in enumerate(TWILIGHT_SUN_ZENITH_DEG):
            relative = (higher_orders(tables, views, sun) / expected[k] - 1.0).abs()
            error[j, k] = float(relative.max()), float(relative[0].max())
    return error


def _plot(error_mc, error_twilight, seconds, labels, cases):
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(2, 2, figsize=(11.0, 8.0), squeeze=False)
    for i, case in enumerate(cases):
        for j, label in enumerate(labels):
            style = dict(color=f"C{j % 10}", ls="-" if j < 10 else "--",
                         label=f"{label} ({seconds[j]:.2f} s)")
            axes[0, i].semilogy(SUN_ZENITH_DEG, 100 * error_mc[i, j, :, 0], "o", **style)
            axes[1, i].semilogy(TWILIGHT_SUN_ZENITH_DEG, 100 * error_twilight[i, j, :, 0],
                                "s", **style)
        axes[0, i].set_title(f"{case}: scene sky against the Monte-Carlo", fontsize=9)
        axes[1, i].set_title(f"{case}: orders >= 2 against the converged solver", fontsize=9)
        for axis in axes[:, i]:
            axis.axhline(3.0, color="grey", lw=0.6)
            axis.axhline(10.0, color="grey", lw=0.6, ls=":")
            axis.set_xlabel("Sun zenith [deg]")
            axis.set_ylabel("largest error over views and wavelengths [%]")
    axes[0, 0].legend(fontsize=6)
    for axis in axes[:, len(cases):].ravel():
        axis.set_axis_off()
    figure.tight_layout()
    return figure


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    quick = arguments.quick
    mc, reference = load_montecarlo()
    cases = CASES[:1] if quick else CASES
    variants = QUICK_VARIANTS if quick else VARIANTS
    converged = QUICK_CONVERGED if quick else TableResolution()
    error_mc = np.zeros((len(cases), len(variants), len(SUN_ZENITH_DEG), len(STATISTICS)))
    error_twilight = np.zeros((len(cases), len(variants), len(TWILIGHT_SUN_ZENITH_DEG),
                               len(CONVERGED_STATISTICS)))
    for i, case in enumerate(cases):
        for j, (_, resolution) in enumerate(variants):
            error_mc[i, j], _, _ = montecarlo_errors(mc, reference, case, resolution)
        error_twilight[i] = twilight_errors(mc, reference, case, variants, converged)
    seconds = np.array([scene_build_seconds(resolution, 1 if quick else 5, warm_up=not quick)
                        for _, resolution in variants])
    labels = [label for label, _ in variants]
    long_name = "largest |model / reference - 1| over the views and the two wavelengths"
    dataset = xr.Dataset(
        {"error_montecarlo": (("case", "tables", "sun_zenith", "statistic"), error_mc,
                              {"units": "1", "long_name": long_name + " (the views the "
                               "Monte-Carlo decides) or at the zenith; scene sky: "
                               "ray-marched order 1 + the tables' orders >= 2"}),
         "error_converged": (("case", "tables", "sun_zenith_twilight", "statistic_converged"),
                             error_twilight,
                             {"units": "1", "long_name": long_name + " or at the zenith; "
                              "orders >= 2 against those of the converged solver"}),
         "build_seconds": (("tables",), seconds,
                           {"units": "s", "long_name": "CPU time of the converged tables "
                            "of Atmosphere.earth() at 6 wavelengths, median of 5 builds"})},
        coords={"case": ("case", np.array(cases)),
                "tables": ("tables", np.array(labels)),
                "sun_zenith": ("sun_zenith", np.array(SUN_ZENITH_DEG), {"units": "degree"}),
                "sun_zenith_twilight": ("sun_zenith_twilight",
                                        np.array(TWILIGHT_SUN_ZENITH_DEG),
                                        {"units": "degree"}),
                "statistic": ("statistic", np.array(STATISTICS)),
                "statistic_converged": ("statistic_converged",
                                        np.array(CONVERGED_STATISTICS))},
        attrs={"title": "Scene presets' multiple-scattering tables knob by knob, day to "
                        "deep twilight",
               "reference": REFERENCE + "; converged solver TableResolution("
                            f"{dataclasses.asdict(converged)})",
               "table_sizes": "; ".join(f"{label}: {r}" for label, r in variants),
               "torch_threads": torch.get_num_threads()})
    figure = _plot(error_mc, error_twilight, seconds, labels, cases)
    save_outputs(dataset, figure, arguments.output_dir, "preset_tables_accuracy_cost")
    for j, label in enumerate(labels):
        print(f"{label} ({seconds[j]:.2f} s): " + "; ".join(
            f"{case} MC " + " / ".join(f"{100 * x:.1f}" for x in error_mc[i, j, :, 0])
            + ", converged " + " / ".join(f"{100 * x:.1f}" for x in error_twilight[i, j, :, 0])
            for i, case in enumerate(cases)) + " %", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
