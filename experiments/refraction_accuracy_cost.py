"""Accuracy vs cost of refracted rays (astronomical refraction, grazing rays, tables).

Knobs, each against a converged reference (Bouguer integrals with 256 Gauss–Legendre
nodes in float64, which the RK4 tracer confirms to 1e-4" at small steps):

* ``n_nodes`` — Gauss–Legendre nodes of the Bouguer integrals, float64 and float32;
* ``step_m`` — RK4 ray-tracing step (Schneegans et al. 2025 use 10 km), float64;
* the deviation-table resolution (Schneegans' eq. 2 parametrisation, bilinear look-up)
  vs the direct integral at random rays.

Rays: an observer at sea level at apparent altitudes 0-80 degrees and rays from space
grazing the limb at impact altitudes 2-60 km (``Atmosphere.earth()``: U.S. Standard
Atmosphere 1976 refractivity, n - 1 = 2.77e-4 at the ground; its layer bases are panel
edges of the Bouguer quadrature and RK4 steps end on them).
Error: largest absolute deviation error over the rays [arcsec]. Cost: median wall time of
one evaluation of all rays (tables: build time and look-up error at 2 000 random rays).
Writes ``refraction_accuracy_cost.nc`` / ``.png``.

Run: ``python experiments/refraction_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._harness import median_seconds  # noqa: E402
from experiments._common import parse_arguments, save_outputs  # noqa: E402
from skytorch.atmosphere import Atmosphere  # noqa: E402
from skytorch.atmosphere import refraction as rf  # noqa: E402
from skytorch.constants import ARCSECOND, DEGREE  # noqa: E402
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable  # noqa: E402

REFERENCE_NODES = 256


def _rays(dtype):
    elevation = torch.tensor([0.0, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 45.0, 80.0],
                             dtype=dtype) * DEGREE
    impact = torch.tensor([2e3, 5e3, 10e3, 20e3, 40e3, 60e3], dtype=dtype)
    return elevation, impact


def _evaluate(atm, dtype, **options):
    elevation, impact = _rays(dtype)
    with torch.no_grad():
        observer = rf.refraction_angle(atm, elevation, **options)
        grazing = rf.trace_grazing_rays(atm, impact_altitude_m=impact, **options)
    return torch.cat([observer, grazing["deviation_rad"]]).double()


def _error(value, reference) -> float:
    return float((value - reference).abs().max() / ARCSECOND)


def _measure(function, reference, repeat: int) -> tuple[float, float]:
    """Largest error [arcsec] and median wall time [s] (one timed run when repeat is 1)."""
    start = time.perf_counter()
    error = _error(function(), reference)
    seconds = time.perf_counter() - start
    if repeat > 1:
        seconds = median_seconds(function, repeat=repeat, warmup=0)
    return error, seconds


def main(argv=None) -> int:  # noqa: C901 (sequential experiment steps)
    args = parse_arguments(__doc__.splitlines()[0], argv)
    quick = args.quick
    atm = Atmosphere.earth(turbidity=1.0, ozone_du=0.0)
    repeat = 1 if quick else 3
    reference = _evaluate(atm, torch.float64, n_nodes=REFERENCE_NODES)

    nodes = [8, 16] if quick else [4, 6, 8, 12, 16, 24, 32, 48, 64, 128]
    dtypes = [torch.float64, torch.float32]
    node_error = np.zeros((len(nodes), len(dtypes)))
    node_time = np.zeros_like(node_error)
    for i, n in enumerate(nodes):
        for j, dtype in enumerate(dtypes):
            node_error[i, j], node_time[i, j] = _measure(
                lambda dtype=dtype, n=n: _evaluate(atm, dtype, n_nodes=n), reference, repeat)

    steps = [10e3] if quick else [40e3, 20e3, 10e3, 5e3, 2e3]
    step_error = np.zeros(len(steps))
    step_time = np.zeros(len(steps))
    for i, step in enumerate(steps):
        options = {"method": "rk4", "step_m": step, "max_dh_m": step / 10.0}
        step_error[i], step_time[i] = _measure(
            lambda options=options: _evaluate(atm, torch.float64, **options), reference, 1)

    sizes = [(16, 8)] if quick else [(32, 16), (64, 32), (128, 64), (256, 128),
                                                (512, 256)]
    generator = torch.Generator().manual_seed(3)
    n_random = 100 if quick else 2000
    height = torch.rand(n_random, generator=generator, dtype=torch.float64) ** 2 * 1e5
    zenith = torch.rand(n_random, generator=generator, dtype=torch.float64) * 89.5 * DEGREE
    with torch.no_grad():
        direct = rf.refraction_angle(atm, math.pi / 2 - zenith, height, n_nodes=64)
    table_max = np.zeros(len(sizes))
    table_median = np.zeros(len(sizes))
    table_time = np.zeros(len(sizes))
    for i, (n_alt, n_ang) in enumerate(sizes):
        def build(n_alt=n_alt, n_ang=n_ang):
            return rf.deviation_table(atm, n_alt, n_ang, progress=False)

        start = time.perf_counter()
        table = build()
        table_time[i] = time.perf_counter() - start
        error = (rf.lookup_deviation(table, height, zenith)["deviation_rad"] - direct).abs()
        table_max[i] = float(error.max() / ARCSECOND)
        table_median[i] = float(error.median() / ARCSECOND)

    error_spec = VariableSpec("arcsec", "largest deviation error",
                              "Largest absolute error of the ray deviation over the test rays "
                              f"against Bouguer integrals with {REFERENCE_NODES} nodes.")
    time_spec = VariableSpec("s", "wall time", "Median wall time of one evaluation of all "
                             "test rays (shared 2-core machine, noisy).")
    dataset = build_dataset(
        {
            "bouguer_error": variable(("n_nodes", "dtype"), node_error, error_spec),
            "bouguer_time": variable(("n_nodes", "dtype"), node_time, time_spec),
            "rk4_error": variable(("step",), step_error, error_spec),
            "rk4_time": variable(("step",), step_time, time_spec),
            "table_max_error": variable(("table",), table_max, VariableSpec(
                "arcsec", "largest look-up error", "Largest absolute error of the bilinear "
                "look-up at random rays against the direct integral.")),
            "table_median_error": variable(("table",), table_median, VariableSpec(
                "arcsec", "median look-up error", "Median absolute error of the bilinear "
                "look-up at random rays against the direct integral.")),
            "table_time": variable(("table",), table_time, VariableSpec(
                "s", "table build time", "Wall time to build the deviation table.")),
        },
        {
            "n_nodes": coordinate("n_nodes", np.array(nodes), VariableSpec(
                "1", "Gauss-Legendre nodes", "Nodes of the Bouguer integrals per panel.")),
            "dtype": coordinate("dtype", np.array(["float64", "float32"]), VariableSpec(
                "1", "floating-point type", "Computation dtype.")),
            "step": coordinate("step", np.array(steps), VariableSpec(
                "m", "RK4 step", "RK4 step along the ray (altitude change per step at most "
                "a tenth of it).")),
            "table": coordinate("table", np.array([f"{a}x{b}" for a, b in sizes]),
                                VariableSpec("1", "table size", "n_altitude x n_angle.")),
        },
        title="Refracted rays: accuracy versus cost",
        references=["Schneegans, S. et al. 2025, Computer Graphics Forum, "
                    "doi:10.1111/cgf.70220"],
        parameters={"quick": quick, "reference_nodes": REFERENCE_NODES,
                    "atmosphere": atm.parameters_dict()},
    )

    import matplotlib.pyplot as plt

    figure, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
    floor = 1e-7
    for j, name in enumerate(["float64", "float32"]):
        left.loglog(node_time[:, j], np.maximum(node_error[:, j], floor), "o-",
                    label=f"Bouguer, {name} (nodes {nodes[0]}-{nodes[-1]})")
    left.loglog(step_time, np.maximum(step_error, floor), "s-",
                label=f"RK4 (steps {steps[0] / 1e3:g}-{steps[-1] / 1e3:g} km)")
    left.set_xlabel("wall time for 15 rays [s]")
    left.set_ylabel("largest deviation error [arcsec]")
    left.set_title("ray integration")
    left.legend(fontsize=8)
    right.loglog(table_time, table_max, "o-", label="largest")
    right.loglog(table_time, table_median, "s-", label="median")
    for t, e, (a, b) in zip(table_time, table_max, sizes, strict=True):
        right.annotate(f"{a}x{b}", (t, e), fontsize=7)
    right.set_xlabel("table build time [s]")
    right.set_ylabel("look-up error [arcsec]")
    right.set_title("deviation table (bilinear look-up)")
    right.legend(fontsize=8)
    figure.tight_layout()
    netcdf, png = save_outputs(dataset, figure, args.output_dir, "refraction_accuracy_cost")
    print(f"wrote {netcdf} and {png}")
    for i, n in enumerate(nodes):
        print(f"bouguer n={n}: {node_error[i, 0]:.2e}\" / {node_error[i, 1]:.2e}\" "
              f"(f64/f32) in {node_time[i, 0]:.3f} / {node_time[i, 1]:.3f} s")
    for i, step in enumerate(steps):
        print(f"rk4 step={step / 1e3:g} km: {step_error[i]:.2e}\" in {step_time[i]:.3f} s")
    for i, (a, b) in enumerate(sizes):
        print(f"table {a}x{b}: max {table_max[i]:.3g}\" median {table_median[i]:.3g}\" "
              f"build {table_time[i]:.2f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
