"""Accuracy versus cost of the occluded fraction of the limb-darkened Sun.

:func:`skytorch.eclipse.sun_visible_fraction` integrates the limb term along the
occluder's rim with ``n_nodes`` Gauss–Legendre nodes. This experiment measures, for
``n_nodes`` in 3 ... 24 and for float64 and float32:

* the largest and median absolute error of the visible fraction over random
  configurations (Sun radius 1e-4 ... 0.2 rad, occluder/Sun radius ratio 1e-2 ... 1e2 with
  the occluder up to 90 degrees, every overlap from containment to tangency, u in [0, 1]);
  the reference is the float64 evaluation with 64 nodes, itself checked against an
  independent ring integration to < 1e-9 in ``tests/test_eclipse_occlusion.py``;
* the median wall time per million evaluations (2 shared cores; noisy).

It also reports the error of the flat (small-angle) approximation that ignores the
1/cos(theta) factor of the solid angle, i.e. the spherical correction, for the Sun seen
from Earth, to show why the correction is kept.

Usage: ``python experiments/eclipse_geometry_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._harness import median_seconds  # noqa: E402
from experiments._common import parse_arguments, save_outputs  # noqa: E402
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable  # noqa: E402
from skytorch.eclipse import sun_visible_fraction  # noqa: E402

DTYPES = {"float64": torch.float64, "float32": torch.float32}
NODES = (3, 4, 5, 6, 8, 10, 12, 16, 24)
REFERENCE_NODES = 64


def configurations(n: int, seed: int = 0) -> dict[str, torch.Tensor]:
    """Random Sun radius, occluder radius, separation and limb darkening (float64)."""
    rng = np.random.default_rng(seed)
    rho_s = 10.0 ** rng.uniform(-4.0, np.log10(0.2), n)
    rho_o = np.minimum(rho_s * 10.0 ** rng.uniform(-2.0, 2.0, n), 0.5 * np.pi)
    d = rng.uniform(0.0, 1.0, n) * (rho_s + rho_o)
    u = rng.uniform(0.0, 1.0, n)
    return {name: torch.as_tensor(value) for name, value in
            (("rho_s", rho_s), ("rho_o", rho_o), ("d", d), ("u", u))}


def timed(function, quick: bool) -> float:
    if quick:
        start = time.perf_counter()
        function()
        return time.perf_counter() - start
    return median_seconds(function, repeat=3, warmup=1)


def run(quick: bool = False):
    n_config = 500 if quick else 100_000
    n_timing = 5_000 if quick else 1_000_000
    nodes = NODES[::3] if quick else NODES
    config = configurations(n_config)
    reference = sun_visible_fraction(config["rho_s"], config["rho_o"], config["d"],
                                     config["u"], n_nodes=REFERENCE_NODES)
    timing = configurations(n_timing, seed=1)
    max_error = np.full((len(DTYPES), len(nodes)), np.nan)
    median_error = np.full_like(max_error, np.nan)
    seconds = np.full_like(max_error, np.nan)
    for i, dtype in enumerate(DTYPES.values()):
        inputs = {k: v.to(dtype) for k, v in config.items()}
        timing_inputs = {k: v.to(dtype) for k, v in timing.items()}
        for j, n_nodes in enumerate(nodes):
            value = sun_visible_fraction(inputs["rho_s"], inputs["rho_o"], inputs["d"],
                                         inputs["u"], n_nodes=n_nodes)
            error = (value.double() - reference).abs()
            max_error[i, j] = float(error.max())
            median_error[i, j] = float(error.median())

            def evaluate(x=timing_inputs, n_nodes=n_nodes):
                with torch.no_grad():
                    sun_visible_fraction(x["rho_s"], x["rho_o"], x["d"], x["u"],
                                         n_nodes=n_nodes)

            seconds[i, j] = timed(evaluate, quick) * 1e6 / n_timing

    # flat approximation: the same configuration with the Sun shrunk 1000x in every angle
    # (spherical effects ~ rho^2 vanish) against the Sun as seen from Earth
    scale = 1e-3
    sun = 4.65e-3
    flat_config = configurations(n_config, seed=2)
    rho_o = flat_config["rho_o"] / flat_config["rho_s"] * sun
    d = flat_config["d"] / flat_config["rho_s"] * sun
    keep = rho_o < 0.5 * np.pi * scale
    spherical = sun_visible_fraction(sun, rho_o[keep], d[keep], flat_config["u"][keep])
    flat = sun_visible_fraction(sun * scale, rho_o[keep] * scale, d[keep] * scale,
                                flat_config["u"][keep])
    flat_error = float((spherical - flat).abs().max())

    dims = ("dtype", "n_nodes")
    dataset = build_dataset(
        {"max_error": variable(dims, max_error, VariableSpec(
            "1", "largest absolute error of the visible fraction",
            f"max over {n_config} random configurations of |f - f_ref|, f_ref with "
            f"{REFERENCE_NODES} nodes in float64")),
         "median_error": variable(dims, median_error, VariableSpec(
             "1", "median absolute error of the visible fraction",
             "median over the same configurations")),
         "time_per_million": variable(dims, seconds, VariableSpec(
             "s", "wall time per million evaluations",
             f"median wall time of {n_timing} evaluations without gradients, scaled to 1e6"))},
        {"dtype": coordinate("dtype", np.array(list(DTYPES)), VariableSpec(
            "1", "floating-point type", "torch dtype of inputs and computation")),
         "n_nodes": coordinate("n_nodes", np.array(nodes), VariableSpec(
             "1", "Gauss-Legendre nodes", "nodes on the occluder's rim"))},
        title="Occultation of the limb-darkened Sun: error versus cost",
        references=["Pál, A. 2012, MNRAS 420, 1630, doi:10.1111/j.1365-2966.2011.20151.x"],
        parameters={"quick": quick, "n_configurations": n_config, "n_timing": n_timing,
                    "reference_nodes": REFERENCE_NODES,
                    "flat_approximation_max_error_sun_from_earth": flat_error},
    )

    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 2, figsize=(10, 4))
    for i, name in enumerate(DTYPES):
        axes[0].semilogy(nodes, np.maximum(max_error[i], 1e-17), "o-", label=f"{name} max")
        axes[0].semilogy(nodes, np.maximum(median_error[i], 1e-17), "s--",
                         label=f"{name} median")
        axes[1].loglog(seconds[i], np.maximum(max_error[i], 1e-17), "o-", label=name)
        for j, n_nodes in enumerate(nodes):
            axes[1].annotate(str(n_nodes), (seconds[i, j], max(max_error[i, j], 1e-17)),
                             fontsize=7)
    for axis in axes:
        axis.axhline(1e-6, color="grey", lw=0.8, ls=":")
        axis.legend(fontsize=8)
    axes[0].set_xlabel("Gauss-Legendre nodes on the rim")
    axes[0].set_ylabel("absolute error of the visible fraction")
    axes[1].set_xlabel("seconds per million evaluations")
    axes[1].set_ylabel("largest absolute error")
    figure.suptitle("sun_visible_fraction: error vs nodes and cost (dotted: 1e-6 target)")
    return dataset, figure


def main(argv: list[str] | None = None) -> int:
    args = parse_arguments(__doc__.splitlines()[0], argv)
    dataset, figure = run(quick=args.quick)
    paths = save_outputs(dataset, figure, args.output_dir, "eclipse_geometry_accuracy_cost")
    print(dataset[["max_error", "time_per_million"]].to_dataframe().to_string())
    print("flat-approximation error (Sun from Earth):",
          dataset.attrs["parameter_flat_approximation_max_error_sun_from_earth"])
    print("wrote", *paths)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
