"""Accuracy vs cost of the Earth's shadow with atmosphere.

Knobs, each varied alone from the defaults, against a converged reference (48 nodes x 4
pieces in the ring integral, 24 arc nodes, 1601 table rows, 128 ray-integral nodes):

* ``n_ring`` x ``n_split`` — Gauss–Legendre nodes of the ring (impact-parameter) integral;
* ``n_arc`` — nodes on the arc through the solar disc;
* ``n_altitude`` — rows of the bending/optical-depth table (cubic interpolation);
* ``trace_nodes`` — nodes of the Bouguer ray integrals (the "ray step");
* the (u, v) look-up table resolution (bilinear in log I) vs direct evaluation;
* float32 vs float64.

Error: maximum relative error of ``I / I_sun`` over points across the umbra and penumbra
at 0.95, 1.0 and 1.05 mean lunar distances, for R, G, B (the blue umbra centre is ~1e-8).
Cost: wall time of the evaluation (tables built beforehand; their build time is reported
for the table knobs). Writes ``eclipse_accuracy_cost.nc`` / ``.png``.

Run: ``python experiments/eclipse_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402
from skytorch.constants import MEAN_EARTH_MOON_DISTANCE_M  # noqa: E402
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable  # noqa: E402

RGB = torch.tensor([680.0, 550.0, 440.0], dtype=torch.float64)
REFERENCE = {"n_ring": 48, "n_split": 4, "n_arc": 24, "n_altitude": 1601, "trace_nodes": 128}


def _points(quick: bool):
    distance = MEAN_EARTH_MOON_DISTANCE_M * torch.tensor([0.95, 1.0, 1.05],
                                                         dtype=torch.float64)[:, None]
    offset = torch.linspace(0.0, 8.5e6, 18 if quick else 86, dtype=torch.float64)[None, :]
    return torch.broadcast_tensors(distance, offset)


def _timed(function):
    start = time.perf_counter()
    value = function()
    return value, time.perf_counter() - start


def main(argv=None) -> int:
    args = parse_arguments(__doc__.splitlines()[0], argv)
    from skytorch.atmosphere import Atmosphere
    from skytorch.eclipse.shadow import Shadow
    from skytorch.eclipse.shadow_table import ShadowTable

    atmosphere = Atmosphere.earth()
    distance, offset = _points(args.quick)
    reference = Shadow.earth(atmosphere, **REFERENCE).relative_illuminance(distance, offset,
                                                                           RGB)
    variants = []  # (knob, value, settings)
    ring = [(4, 1), (8, 1), (12, 1), (8, 2), (12, 2), (16, 2), (12, 4)]
    arcs = [4, 6, 8, 12]
    rows = [51, 101, 201, 401, 801]
    nodes = [16, 32, 64]
    if args.quick:
        ring, arcs, rows, nodes = ring[1:2], arcs[:1], rows[:1], nodes[:1]
    for n_ring, n_split in ring:
        variants.append(("ring nodes", n_ring * n_split, {"n_ring": n_ring, "n_split": n_split}))
    for n_arc in arcs:
        variants.append(("arc nodes", n_arc, {"n_arc": n_arc}))
    for n_altitude in rows:
        variants.append(("table rows", n_altitude, {"n_altitude": n_altitude}))
    for trace in nodes:
        variants.append(("ray nodes", trace, {"trace_nodes": trace}))

    knob, value, error, seconds, build = [], [], [], [], []

    def record(name, setting, result, elapsed, prepared):
        relative = ((result.double() - reference).abs() / reference).max()
        knob.append(name)
        value.append(float(setting))
        error.append(float(relative))
        seconds.append(elapsed)
        build.append(prepared)
        print(f"{name:>12} {setting:>8}: max rel. error {float(relative):.3g}, "
              f"{elapsed:.3f} s (+ {prepared:.3f} s tables)")

    for name, setting, options in variants:
        shadow = Shadow.earth(atmosphere, **options)
        _, prepared = _timed(lambda shadow=shadow: shadow.ring_profile(RGB))
        result, elapsed = _timed(
            lambda shadow=shadow: shadow.relative_illuminance(distance, offset, RGB))
        record(name, setting, result, elapsed, prepared)
    shadow = Shadow.earth(atmosphere)
    shadow.ring_profile(RGB)
    for dtype in (torch.float64, torch.float32):
        result, elapsed = _timed(lambda dtype=dtype: shadow.relative_illuminance(
            distance.to(dtype), offset.to(dtype), RGB))
        record("dtype", 64 if dtype == torch.float64 else 32, result, elapsed, 0.0)
    sizes = [16, 24] if args.quick else [32, 64, 128, 256]
    for n in sizes:
        table, prepared = _timed(lambda n=n: ShadowTable.compute(shadow, RGB, n_u=n, n_v=n,
                                                                 progress=False))
        result, elapsed = _timed(lambda table=table: table.lookup(distance, offset))
        record("uv table", n, result, elapsed, prepared)

    spec = {
        "max_relative_error": VariableSpec("1", "maximum relative error of I/I_sun",
                                           "against the converged reference, R G B"),
        "seconds": VariableSpec("s", "evaluation wall time", "for all test points"),
        "table_seconds": VariableSpec("s", "table build wall time",
                                      "ring profile or (u, v) table build"),
        "knob": VariableSpec("1", "fidelity knob", "which setting was varied"),
        "value": VariableSpec("1", "knob value", "nodes, rows, bits or table size"),
    }
    index = np.arange(len(knob))
    dataset = build_dataset(
        {"max_relative_error": variable(("variant",), np.array(error),
                                        spec["max_relative_error"]),
         "seconds": variable(("variant",), np.array(seconds), spec["seconds"]),
         "table_seconds": variable(("variant",), np.array(build), spec["table_seconds"]),
         "knob": variable(("variant",), np.array(knob), spec["knob"]),
         "value": variable(("variant",), np.array(value), spec["value"])},
        {"variant": coordinate("variant", index, VariableSpec("1", "variant", "row number"))},
        title="Eclipse shadow: accuracy vs cost",
        references=["Schneegans, S. et al. 2025, Computer Graphics Forum, "
                    "doi:10.1111/cgf.70220"],
        parameters={"reference": REFERENCE, "n_points": int(distance.numel()),
                    "quick": bool(args.quick)})
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(8, 5.5))
    for name in dict.fromkeys(knob):
        mask = np.array(knob) == name
        axis.loglog(np.array(seconds)[mask] + np.array(build)[mask],
                    np.maximum(np.array(error)[mask], 1e-16), "o-", label=name)
        for x, y, v in zip(np.array(seconds)[mask] + np.array(build)[mask],
                           np.array(error)[mask], np.array(value)[mask], strict=True):
            axis.annotate(f"{v:g}", (x, max(y, 1e-16)), fontsize=7)
    axis.set_xlabel("wall time: tables + evaluation [s]")
    axis.set_ylabel("max relative error of I / I_sun")
    axis.set_title(f"Earth shadow, {distance.numel()} points x RGB")
    axis.grid(alpha=0.3, which="both")
    axis.legend(fontsize=8)
    figure.tight_layout()
    save_outputs(dataset, figure, args.output_dir, "eclipse_accuracy_cost")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
