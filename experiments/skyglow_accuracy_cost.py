"""Skyglow accuracy vs cost: Dobashi et al. (2023) Fig. 6 and 7, and the kernel quadrature.

* Fig. 6(a): runtime of one panorama vs the number of lighting cells, PCA + FFT (largest
  M) against the naive direct integration (``render_naive(sources="cells")``);
* Fig. 6(b): runtime vs the number of components M at 2048 lighting cells;
* Fig. 6(c): mean relative error of the luminance vs M for 128 … 2048 lighting cells,
  against the naive sum on the model's own grid (the stored kernel table,
  :func:`~skytorch.skyglow.naive.kernel_table_sum`), i.e. the PCA truncation error;
* Fig. 7: panoramas from the naive reference with exact cell positions, from PCA + FFT
  with M = 32, and their relative difference (PCA truncation plus the polar resampling
  of the light map) for 1024 lighting cells;
* kernel quadrature: Gauss nodes per half view ray vs the error against a 512-node
  reference and the cost per kernel geometry (and the implied precompute time at the
  paper's resolution, 2.7e8 geometries on this machine).

Run ``python experiments/skyglow_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # no busy-waiting threads on shared cores

import numpy as np  # noqa: E402
import torch  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402

PAPER_GEOMETRIES = 129 * 64 * 128 * 16 * 16


def _timed(function, repeat=3):
    samples = []
    for _ in range(repeat):
        start = time.perf_counter()
        result = function()
        samples.append(time.perf_counter() - start)
    return float(np.median(samples)), result


def main(argv=None) -> int:  # noqa: C901 (sequential experiment steps)
    args = parse_arguments(__doc__.splitlines()[0], argv)
    from skytorch.atmosphere import Atmosphere
    from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable
    from skytorch.skyglow.citymap import point_sources
    from skytorch.skyglow.kernel import Medium, kernel_radiance
    from skytorch.skyglow.lamps import luminance_weights
    from skytorch.skyglow.model import SkyglowModel, light_map_arrays
    from skytorch.skyglow.naive import kernel_table_sum, naive_radiance_per_lumen
    from skytorch.spectrum import wavelength_grid

    quick = args.quick
    n_t, n_p, n_r, n_h = (16, 4, 8, 2) if quick else (64, 16, 48, 4)
    cell_counts = [1, 4, 16] if quick else [1, 4, 16, 64, 256, 1024, 2048]
    naive_counts = [1, 4] if quick else [1, 4, 16, 64]
    error_counts = [16] if quick else [128, 256, 512, 1024, 2048]
    m_values = [2, 4, 8, 16] if quick else [4, 8, 16, 32, 64, 128, 192]
    steps = [2, 4, 8] if quick else [2, 4, 8, 16, 32, 64]
    reference_steps = 64 if quick else 512
    panorama_cells = 16 if quick else 1024
    atmosphere = Atmosphere.earth(turbidity=2.0)
    medium = Medium(atmosphere, wavelength_grid("rgb"))
    start = time.perf_counter()
    base = SkyglowModel.precompute(atmosphere, n_azimuth=n_t, n_elevation=n_p, n_distance=n_r,
                                   n_source_altitude=n_h, source_altitude_range_m=(0.0, 600.0),
                                   max_distance_m=20_000.0, n_components=max(m_values),
                                   n_steps=4 if quick else 8, medium=medium, keep_kernel=True,
                                   progress=False)
    precompute_s = time.perf_counter() - start
    weights, _ = luminance_weights("white", base.wavelength_nm)
    extent = 2 * 20_000.0 / math.sqrt(2.0)

    def cells_for(n, seed):
        ds = point_sources(n, extent, extent / 128, seed=seed)
        cells = light_map_arrays(ds)
        cells["altitude"] = torch.as_tensor(
            np.random.default_rng(seed).uniform(0.0, 600.0, cells["flux"].shape))
        return cells

    def polar_of(cells):
        return base.polar_flux(cells["x"].reshape(-1), cells["y"].reshape(-1),
                               cells["flux"].reshape(-1), cells["altitude"].reshape(-1),
                               torch.zeros(1, 2, dtype=torch.float64))[0]

    # --- Fig. 6(a): time vs lighting cells ------------------------------------------------
    ours_time, naive_time = [], []
    for n in cell_counts:
        cells = cells_for(n, n)
        seconds, _ = _timed(lambda cells=cells: base.radiance_per_lumen(cells, (0.0, 0.0)))
        ours_time.append(seconds)
        if n in naive_counts:
            seconds, _ = _timed(lambda cells=cells: naive_radiance_per_lumen(
                base, cells, (0.0, 0.0), sources="cells"), repeat=1)
            naive_time.append(seconds)
        else:
            naive_time.append(float("nan"))
    per_cell = naive_time[cell_counts.index(naive_counts[-1])] / naive_counts[-1]
    naive_scaled = [t if not math.isnan(t) else per_cell * n
                    for t, n in zip(naive_time, cell_counts, strict=True)]

    # --- Fig. 6(b), 6(c): time and error vs M ----------------------------------------------
    models = {m: base.refit(m) for m in m_values}
    big = cells_for(max(error_counts), 7)
    time_vs_m = [_timed(lambda model=models[m]: model.radiance_per_lumen(big, (0.0, 0.0)))[0]
                 for m in m_values]
    error = np.zeros((len(m_values), len(error_counts)))
    for j, n in enumerate(error_counts):
        cells = cells_for(n, 100 + n)
        reference = kernel_table_sum(base, polar_of(cells)) @ weights
        for i, m in enumerate(m_values):
            ours = models[m].radiance_per_lumen(cells, (0.0, 0.0))[0] @ weights
            error[i, j] = float(((ours - reference).abs() / reference).mean())

    # --- Fig. 7: panoramas ---------------------------------------------------------------
    cells = cells_for(panorama_cells, 11)
    m7 = 32 if 32 in models else max(m_values)
    ours7 = models[m7].radiance_per_lumen(cells, (0.0, 0.0))[0] @ weights
    naive7 = naive_radiance_per_lumen(base, cells, (0.0, 0.0), sources="cells")[0] @ weights
    same_grid7 = kernel_table_sum(base, polar_of(cells)) @ weights
    relative7 = (ours7 - naive7).abs() / naive7

    # --- kernel quadrature: nodes vs error vs time -----------------------------------------
    rng = np.random.default_rng(5)
    n_probe = 200 if quick else 2000
    probe = [torch.as_tensor(v) for v in (
        rng.uniform(0, math.pi, n_probe), rng.uniform(0.0, math.pi / 2, n_probe),
        20_000.0 * rng.uniform(0, 1, n_probe) ** 2, rng.uniform(0, 600.0, n_probe))]
    reference = kernel_radiance(medium, *probe, n_steps=reference_steps)
    schemes = ("single", "split")
    q_error_mean = np.zeros((len(schemes), len(steps)))
    q_error_max = np.zeros_like(q_error_mean)
    q_time = np.zeros_like(q_error_mean)
    lit = reference > 0  # rays entirely below the source's horizon carry no light
    for i, scheme in enumerate(schemes):
        for j, n in enumerate(steps):
            seconds, values = _timed(lambda n=n, scheme=scheme: kernel_radiance(
                medium, *probe, n_steps=n, quadrature=scheme), repeat=3)
            if bool((values[~lit] != 0).any()):
                raise RuntimeError("the kernel lit a ray that the reference leaves dark")
            relative = (values - reference).abs()[lit] / reference[lit]
            q_error_mean[i, j] = float(relative.mean())
            q_error_max[i, j] = float(relative.max())
            q_time[i, j] = seconds / n_probe

    # --- Dataset ---------------------------------------------------------------------------
    def spec(units, long_name, description):
        return VariableSpec(units, long_name, description)

    coords = {
        "lighting_cells": coordinate("lighting_cells", cell_counts, spec(
            "1", "number of lighting cells", "Lit cells of a random map.")),
        "n_components": coordinate("n_components", m_values, spec(
            "1", "principal components M", "PCA components kept.")),
        "error_cells": coordinate("error_cells", error_counts, spec(
            "1", "lighting cells in the error test", "Lit cells of the random map.")),
        "elevation": coordinate("elevation", torch.rad2deg(base.elevation_rad), spec(
            "degree", "elevation", "View elevation (cell centres).")),
        "azimuth": coordinate("azimuth", torch.rad2deg(base.azimuth_rad), spec(
            "degree", "azimuth", "View azimuth from north through east.")),
        "gauss_nodes": coordinate("gauss_nodes", steps, spec(
            "1", "Gauss nodes per half view ray", "Half the kernel quadrature's nodes.")),
        "quadrature": coordinate("quadrature", list(schemes), spec(
            "1", "view-ray quadrature", "single: one rule over the substituted variable; "
            "split: n nodes on each side of the closest point (Dobashi 2023).")),
    }
    data = {
        "time_pca_fft": variable("lighting_cells", ours_time, spec(
            "s", "runtime PCA + FFT", f"Median runtime of one panorama, M = {max(m_values)}.")),
        "time_naive": variable("lighting_cells", naive_scaled, spec(
            "s", "runtime naive", "Direct kernel integration per cell and view direction; "
            f"measured up to {naive_counts[-1]} cells, scaled linearly beyond.")),
        "time_vs_components": variable("n_components", time_vs_m, spec(
            "s", "runtime vs M", f"Median runtime, {max(error_counts)} lighting cells.")),
        "mean_relative_error": variable(("n_components", "error_cells"), error, spec(
            "1", "mean relative error", "PCA + FFT luminance against the naive sum on the "
            "same grid.")),
        "luminance_naive": variable(("elevation", "azimuth"), naive7, spec(
            "cd m-2", "naive panorama", "Exact cell positions, white lamps.")),
        "luminance_pca_fft": variable(("elevation", "azimuth"), ours7, spec(
            "cd m-2", "PCA + FFT panorama", f"M = {m7}.")),
        "luminance_same_grid": variable(("elevation", "azimuth"), same_grid7, spec(
            "cd m-2", "naive panorama on the polar grid", "Kernel table sum.")),
        "relative_error_panorama": variable(("elevation", "azimuth"), relative7, spec(
            "1", "relative error", "|PCA + FFT − naive (exact positions)| / naive.")),
        "quadrature_mean_error": variable(("quadrature", "gauss_nodes"), q_error_mean, spec(
            "1", "kernel mean relative error", f"Against {reference_steps} nodes.")),
        "quadrature_max_error": variable(("quadrature", "gauss_nodes"), q_error_max, spec(
            "1", "kernel max relative error", f"Against {reference_steps} nodes.")),
        "quadrature_time": variable(("quadrature", "gauss_nodes"), q_time, spec(
            "s", "time per kernel geometry", "Wall time per (θ, φ, r, h_c) geometry, "
            "3 wavelengths.")),
        "paper_precompute_time": variable(("quadrature", "gauss_nodes"),
                                          q_time * PAPER_GEOMETRIES,
                                          spec("s", "implied precompute time",
                                               "Kernel time at N_θ 256, N_φ 64, N_r 128, "
                                               "N_hc 16, N_ho 16 (mirrored azimuths).")),
    }
    parameters = {"n_azimuth": n_t, "n_elevation": n_p, "n_distance": n_r,
                  "n_source_altitude": n_h, "turbidity": 2.0, "quick": quick,
                  "model_precompute_s": precompute_s, "threads": torch.get_num_threads()}
    dataset = build_dataset(data, coords, title="Skyglow accuracy and cost",
                            references=["Dobashi, Y., Ishikawa, N. & Iwasaki, K. 2023, ACM "
                                        "Trans. Graph. 42, 219, doi:10.1145/3618337"],
                            parameters=parameters)

    import matplotlib.pyplot as plt
    import matplotlib.ticker

    figure, axes = plt.subplots(2, 3, figsize=(15, 8))
    ax = axes[0, 0]
    ax.loglog(cell_counts, ours_time, "o-", label=f"PCA + FFT (M = {max(m_values)})")
    ax.loglog(cell_counts, naive_scaled, "s--", label="naive (dashed: scaled)")
    ax.set(xlabel="lighting cells", ylabel="time [s]", title="(a) time vs lighting cells")
    ax.legend()
    ax = axes[0, 1]
    ax.plot(m_values, np.array(time_vs_m) * 1e3, "o-")
    ax.set(xlabel="components M", ylabel="time [ms]",
           title=f"(b) time vs M ({max(error_counts)} cells)")
    ax = axes[0, 2]
    for j, n in enumerate(error_counts):
        ax.semilogy(m_values, error[:, j] * 100, "o-", label=f"{n} cells")
    ax.set(xlabel="components M", ylabel="mean relative error [%]",
           title="(c) error vs M (same grid)")
    ax.legend()
    extent_deg = [0, 360, 0, 90]
    for ax, image, title in ((axes[1, 0], naive7, "naive (exact cell positions)"),
                             (axes[1, 1], ours7, f"PCA + FFT, M = {m7}")):
        shown = ax.imshow(np.log10(image.numpy()), origin="lower", aspect="auto",
                          extent=extent_deg, cmap="magma")
        ax.set(xlabel="azimuth [deg]", ylabel="elevation [deg]", title=title)
        figure.colorbar(shown, ax=ax, label="log10 luminance [cd m$^{-2}$]")
    shown = axes[1, 2].imshow(relative7.numpy() * 100, origin="lower", aspect="auto",
                              extent=extent_deg, cmap="viridis")
    axes[1, 2].set(xlabel="azimuth [deg]", title="relative error [%]")
    figure.colorbar(shown, ax=axes[1, 2])
    inset = axes[0, 0].inset_axes([0.62, 0.08, 0.35, 0.35])
    for i, scheme in enumerate(schemes):
        inset.loglog(steps, q_error_max[i], "o-", label=f"{scheme} max")
        inset.loglog(steps, q_error_mean[i], "s--", label=f"{scheme} mean")
    inset.legend(fontsize=5)
    inset.set_title("kernel rel. error vs nodes/2", fontsize=7)
    inset.tick_params(labelsize=6, which="both")
    inset.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    figure.tight_layout()
    netcdf, png = save_outputs(dataset, figure, args.output_dir, "skyglow_accuracy_cost")
    print(f"wrote {netcdf} and {png}")
    print("error vs M (rows M, columns cells):", m_values, error_counts)
    print(np.array2string(error * 100, precision=3))
    for i, scheme in enumerate(schemes):
        print(f"quadrature {scheme}: nodes/2 {steps} mean err {q_error_mean[i]} "
              f"max err {q_error_max[i]} s/geometry {q_time[i]}")
    print("Fig 7 mean relative error (exact positions):", float(relative7.mean()),
          "same grid:", float(((ours7 - same_grid7).abs() / same_grid7).mean()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
