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

A second part varies ``scattering_resolution`` of the single-scattered component
(:mod:`skytorch.eclipse.shadow_scattering`) against resolution 4: maximum relative error of
the scattered illuminance ``E_sca / E_sun`` alone over the same points for the typical Earth
atmosphere and the stratospheric one of 2015 (``eclipse_atmosphere("2015-09-28")``), and
over the shadow of Mars at Phobos' and Deimos' orbits; cost: kernel precomputation +
evaluation. Writes ``eclipse_scattering_accuracy_cost.nc`` / ``.png`` (run alone with
``--scattering-only``).

Run: ``python experiments/eclipse_accuracy_cost.py [--quick] [--output-dir DIR]
[--scattering-only]``.
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


SCATTERING_RESOLUTIONS = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0)
SCATTERING_REFERENCE = 4.0


def scattering(quick: bool, output_dir) -> dict:
    """Error of the scattered component vs ``scattering_resolution`` (module docstring)."""
    from skytorch.atmosphere import Atmosphere
    from skytorch.constants import DEIMOS_SEMI_MAJOR_AXIS_M, PHOBOS_SEMI_MAJOR_AXIS_M
    from skytorch.eclipse import eclipse_atmosphere
    from skytorch.eclipse.shadow import Shadow

    distance, offset = _points(quick)
    mars_distance = torch.tensor([PHOBOS_SEMI_MAJOR_AXIS_M, DEIMOS_SEMI_MAJOR_AXIS_M],
                                 dtype=torch.float64)[:, None]
    mars_offset = torch.linspace(0.0, 3.4e6, 8 if quick else 35, dtype=torch.float64)[None, :]
    mars_points = torch.broadcast_tensors(mars_distance, mars_offset)
    cases = {
        "earth typical": (lambda **k: Shadow.earth(Atmosphere.earth(), **k), (distance, offset)),
        "earth stratospheric 2015": (
            lambda **k: Shadow.earth(eclipse_atmosphere("2015-09-28"), **k),
            (distance, offset)),
        "mars": (lambda **k: Shadow.mars(**k), mars_points),
    }
    resolutions = SCATTERING_RESOLUTIONS[:2] if quick else SCATTERING_RESOLUTIONS
    reference_resolution = 1.0 if quick else SCATTERING_REFERENCE
    names, values, errors, seconds = [], [], [], []
    for name, (make, points) in cases.items():
        base = make().relative_illuminance(*points, RGB)

        def scattered(resolution, make=make, points=points, base=base):
            shadow = make(scattering=True, scattering_resolution=resolution)
            shadow.ring_profile(RGB)
            start = time.perf_counter()
            total = shadow.relative_illuminance(*points, RGB)
            return total - base, time.perf_counter() - start

        reference, _ = scattered(reference_resolution)
        for resolution in resolutions:
            result, elapsed = scattered(resolution)
            relative = float(((result - reference).abs() / reference.clamp_min(1e-300)).max())
            names.append(name)
            values.append(resolution)
            errors.append(relative)
            seconds.append(elapsed)
            print(f"scattering {name:>24} resolution {resolution:>5}: max rel. error "
                  f"{relative:.3g}, {elapsed:.3f} s")
    dataset = build_dataset(
        {"max_relative_error": variable(("variant",), np.array(errors), VariableSpec(
            "1", "maximum relative error of the scattered illuminance",
            f"against scattering_resolution {reference_resolution}, R G B")),
         "seconds": variable(("variant",), np.array(seconds), VariableSpec(
             "s", "wall time", "kernel precomputation + evaluation of all points")),
         "case": variable(("variant",), np.array(names), VariableSpec(
             "1", "occluder and atmosphere", "Earth at 0.95-1.05 lunar distances, Mars at "
             "Phobos and Deimos")),
         "resolution": variable(("variant",), np.array(values), VariableSpec(
             "1", "scattering_resolution", "factor on the node counts"))},
        {"variant": coordinate("variant", np.arange(len(names)),
                               VariableSpec("1", "variant", "row number"))},
        title="Single-scattered light in the shadow: accuracy vs cost",
        references=["Schneegans, S. et al. 2025, Computer Graphics Forum, "
                    "doi:10.1111/cgf.70220"],
        parameters={"reference_resolution": reference_resolution, "quick": bool(quick)})
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(7, 4.5))
    for name in cases:
        mask = np.array(names) == name
        axis.loglog(np.array(seconds)[mask], np.maximum(np.array(errors)[mask], 1e-16), "o-",
                    label=name)
        for x, y, v in zip(np.array(seconds)[mask], np.array(errors)[mask],
                           np.array(values)[mask], strict=True):
            axis.annotate(f"{v:g}", (x, max(y, 1e-16)), fontsize=7)
    axis.set_xlabel("wall time: kernel + evaluation [s]")
    axis.set_ylabel("max relative error of E_sca / E_sun")
    axis.set_title("single-scattered light vs scattering_resolution")
    axis.grid(alpha=0.3, which="both")
    axis.legend(fontsize=8)
    figure.tight_layout()
    save_outputs(dataset, figure, output_dir, "eclipse_scattering_accuracy_cost")
    return dict(zip(zip(names, values, strict=True), errors, strict=True))


def main(argv=None) -> int:  # noqa: C901 (sequential experiment steps)
    argv = list(argv) if argv is not None else sys.argv[1:]
    only_scattering = "--scattering-only" in argv
    argv = [a for a in argv if a != "--scattering-only"]
    args = parse_arguments(__doc__.splitlines()[0], argv)
    scattering(args.quick, args.output_dir)
    if only_scattering:
        return 0
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
