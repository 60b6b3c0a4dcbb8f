"""Accuracy versus cost of integrating the lunar disc (magnitude error vs time).

Three ways to integrate the reflectance over the visible disc are compared at phase
angles 0°–150°:

* ``quadrature`` — Gauss–Legendre in photometric latitude and longitude over the sunlit
  part only (:func:`skytorch.moon.disc.lit_disc_quadrature`; n² points);
* ``polar`` — Gauss–Legendre radius × uniform azimuth over the whole disc
  (:func:`skytorch.moon.disc.disc_grid`, the points the eclipse light curve uses; 2n² points);
* ``pixels`` — pixel centres of an n × n image (:func:`skytorch.moon.disc.disc_grid` with
  ``method="pixels"``; ≈ π n²/4 points), what an image-based renderer does;

in float64 and float32. The reference is the quadrature with 256 × 256 nodes in float64.
The error is the largest |Δm| over the phase angles [mag]; the time is the median wall
time of one evaluation of all phase angles with one torch thread (shared machine; noisy).

Usage: ``python experiments/moon_accuracy_cost.py [--quick] [--output-dir DIR]``.
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
from skytorch.constants import DEGREE  # noqa: E402
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable  # noqa: E402
from skytorch.moon.disc import (  # noqa: E402
    disc_grid,
    disc_reflectance,
    lit_disc_quadrature,
    sun_direction,
)
from skytorch.moon.reflectance import reflectance  # noqa: E402

METHODS = ("quadrature", "polar", "pixels")
DTYPES = {"float64": torch.float64, "float32": torch.float32}
PHASES_DEG = (0.0, 10.0, 30.0, 60.0, 90.0, 120.0, 150.0)


def integrate(method: str, n: int, alpha: torch.Tensor) -> torch.Tensor:
    """Disc integral Q(α) [1/sr] by one of the methods."""
    if method == "quadrature":
        mu0, mu, weight = lit_disc_quadrature(alpha, n)
        return (reflectance(mu0, mu, alpha.unsqueeze(-1)) * weight).sum(-1)
    grid = disc_grid(n, method=method, dtype=alpha.dtype)
    r = disc_reflectance(grid["normal"], sun_direction(alpha))
    return (r * grid["weight"]).sum(-1)


def n_points(method: str, n: int) -> int:
    if method == "quadrature":
        return n * n
    return int(disc_grid(n, method=method)["weight"].numel())


def timed(function, quick: bool, repeat: int, warmup: int) -> float:
    """Median wall time; a single un-collected call in quick mode (smoke test only)."""
    if quick:
        start = time.perf_counter()
        function()
        return time.perf_counter() - start
    return median_seconds(function, repeat=repeat, warmup=warmup)


def run(quick: bool = False):
    levels = {"quadrature": (4, 8, 16, 32, 64) if not quick else (4, 8),
              "polar": (4, 8, 16, 32, 64, 128) if not quick else (4, 8),
              "pixels": (16, 32, 64, 128, 256, 512) if not quick else (8, 16)}
    n_level = max(len(v) for v in levels.values())
    phases = PHASES_DEG[::3] if quick else PHASES_DEG
    alpha64 = torch.tensor(phases, dtype=torch.float64) * DEGREE
    reference = integrate("quadrature", 16 if quick else 256, alpha64)
    repeat, warmup = (1, 0) if quick else (5, 1)
    shape = (len(METHODS), len(DTYPES), n_level)
    error = np.full(shape, np.nan)
    seconds = np.full(shape, np.nan)
    resolution = np.full((len(METHODS), n_level), np.nan)
    points = np.full((len(METHODS), n_level), np.nan)
    for i, method in enumerate(METHODS):
        for k, n in enumerate(levels[method]):
            resolution[i, k] = n
            points[i, k] = n_points(method, n)
            for j, dtype in enumerate(DTYPES.values()):
                alpha = alpha64.to(dtype)
                q = integrate(method, n, alpha)
                delta = -2.5 * torch.log10(q.double() / reference)
                error[i, j, k] = float(delta.abs().max())
                seconds[i, j, k] = timed(lambda m=method, nn=n, a=alpha: integrate(m, nn, a),
                                         quick, repeat, warmup)
    dataset = build_dataset(
        {"magnitude_error": variable(("scheme", "dtype", "level"), error, VariableSpec(
            "1", "largest magnitude error over phase angles",
            "max over phase angles 0-150 deg of |-2.5 log10(Q/Q_ref)| [mag], Q the disc "
            "integral of the Hapke reflectance and Q_ref the 256x256 quadrature in float64")),
         "time": variable(("scheme", "dtype", "level"), seconds, VariableSpec(
             "s", "median wall time", "median wall time of one evaluation at all phase angles")),
         "resolution": variable(("scheme", "level"), resolution, VariableSpec(
             "1", "resolution parameter n", "nodes per coordinate (quadrature), radial nodes "
             "(polar) or pixels across the diameter (pixels)")),
         "n_points": variable(("scheme", "level"), points, VariableSpec(
             "1", "number of sample points", "reflectance evaluations per phase angle"))},
        {"scheme": coordinate("scheme", np.array(METHODS), VariableSpec(
            "1", "integration method", "quadrature over the sunlit part, polar disc grid, "
                                       "or image pixels")),
         "dtype": coordinate("dtype", np.array(list(DTYPES)), VariableSpec(
             "1", "floating-point type", "torch dtype of the computation")),
         "level": coordinate("level", np.arange(n_level), VariableSpec(
             "1", "resolution level", "index into the resolutions of each method"))},
        title="Lunar disc integration: magnitude error versus cost",
        references=["Hapke, B. 2012, Theory of Reflectance and Emittance Spectroscopy, "
                    "doi:10.1017/CBO9781139025683"],
        parameters={"quick": quick, "phases_deg": list(phases)})
    return dataset


def figure_of(dataset):
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(6.4, 4.4))
    markers = {"float64": "o-", "float32": "s--"}
    for method in dataset.scheme.values:
        for dtype in dataset.dtype.values:
            sel = dataset.sel(scheme=method, dtype=dtype)
            ok = np.isfinite(sel.time.values)
            axis.loglog(sel.time.values[ok], np.maximum(sel.magnitude_error.values[ok], 1e-9),
                        markers[str(dtype)], label=f"{method} ({dtype})")
    axis.axhline(0.01, color="grey", lw=0.8, ls=":")
    axis.set_xlabel("median time for one evaluation at all phase angles [s]")
    axis.set_ylabel("max |Δm| [mag]")
    axis.set_title("Lunar disc integral: accuracy vs cost")
    axis.legend(fontsize=7)
    return figure


def markdown(dataset) -> str:
    lines = ["| method | dtype | n | points | max abs dm [mag] | time [ms] |",
             "| --- | --- | --- | --- | --- | --- |"]
    for method in dataset.scheme.values:
        for dtype in dataset.dtype.values:
            sel = dataset.sel(scheme=method, dtype=dtype)
            for level in dataset.level.values:
                n = sel.resolution.sel(level=level).item()
                if not np.isfinite(n):
                    continue
                lines.append(f"| {method} | {dtype} | {int(n)} | "
                             f"{int(sel.n_points.sel(level=level).item())} | "
                             f"{sel.magnitude_error.sel(level=level).item():.1e} | "
                             f"{1e3 * sel.time.sel(level=level).item():.2f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    args = parse_arguments(__doc__.splitlines()[0], argv)
    dataset = run(quick=args.quick)
    save_outputs(dataset, figure_of(dataset), args.output_dir, "moon_accuracy_cost")
    print(markdown(dataset))
    return 0


if __name__ == "__main__":
    # one thread: on a shared machine, oversubscribed threads make timings erratic
    torch.set_num_threads(1)
    raise SystemExit(main())
