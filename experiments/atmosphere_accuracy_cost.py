"""Accuracy against wall time of the atmosphere's numerical knobs.

Three studies, each error against a converged reference versus the time of a call:

1. straight-ray optical depth: method (gauss, trapezoid, adaptive) x resolution x dtype,
   for zenith and horizon rays from the ground (reference: float64 adaptive quadrature
   with 64 nodes per piece, which agrees with the exact closed forms to 1e-12);
2. transmittance table resolution (n_mu x n_r): bilinear look-up against direct
   integration on random rays below 89 deg zenith angle, and the build time;
3. single-scattering sky radiance: samples along the view ray against 4096 samples.

Writes ``atmosphere_accuracy_cost.nc`` and ``.png`` (``--quick`` for a fast smoke run).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from experiments._common import parse_arguments, save_outputs  # noqa: E402
from skytorch.atmosphere import Atmosphere  # noqa: E402
from skytorch.atmosphere.tables import TransmittanceTable  # noqa: E402
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable  # noqa: E402

WAVELENGTH_NM = torch.linspace(360.0, 830.0, 15, dtype=torch.float64)


def _timed(function, repeat):
    function()
    samples = []
    for _ in range(repeat):
        start = time.perf_counter()
        result = function()
        samples.append(time.perf_counter() - start)
    return result, float(np.median(samples))


def optical_depth_study(atm, quick):
    n_rays = 200 if quick else 20_000
    generator = torch.Generator().manual_seed(1)
    rays = {
        "zenith": torch.rand(n_rays, generator=generator, dtype=torch.float64) * 0.2,
        "horizon": math.pi / 2 - torch.rand(n_rays, generator=generator,
                                            dtype=torch.float64) * 0.02,
    }
    settings = [("gauss", n) for n in ((2, 6) if quick else (2, 3, 4, 5, 6, 8, 12))]
    settings += [("trapezoid", n) for n in ((50,) if quick else (50, 100, 500, 2000,
                                                                     8000))]
    settings += [("adaptive", 4)]
    rows = []
    for ray, zenith in rays.items():
        reference = atm.optical_depth(WAVELENGTH_NM, zenith, method="adaptive", n_steps=64)
        for dtype in (torch.float64, torch.float32):
            for method, n_steps in settings:
                if method == "trapezoid" and n_steps > 2000 and dtype == torch.float32:
                    continue
                def run(m=method, n=n_steps, d=dtype, z=zenith):
                    return atm.optical_depth(WAVELENGTH_NM.to(d), z.to(d), method=m, n_steps=n)

                tau, seconds = _timed(run, 1 if quick else 3)
                error = float(((tau.double() - reference).abs() / reference).max())
                rows.append((ray, method, n_steps, str(dtype).replace("torch.", ""), error,
                             seconds / n_rays * 1e6))
    return rows


def table_study(atm, quick):
    generator = torch.Generator().manual_seed(2)
    n_rays = 200 if quick else 20_000
    zenith = torch.rand(n_rays, generator=generator, dtype=torch.float64) * math.radians(89.0)
    altitude = torch.rand(n_rays, generator=generator, dtype=torch.float64) ** 2 * 50e3
    direct = atm.optical_depth(WAVELENGTH_NM, zenith, altitude)
    sizes = [(16, 4), (32, 8)] if quick else [(32, 8), (64, 16), (128, 32),
                                                           (256, 64), (512, 128), (1024, 256)]
    rows = []
    for n_mu, n_r in sizes:
        table, seconds = _timed(lambda a=n_mu, b=n_r: TransmittanceTable.build(
            atm, WAVELENGTH_NM, n_mu=a, n_r=b), 1 if quick else 3)
        looked_up = table.optical_depth(zenith, altitude)
        relative = ((looked_up - direct).abs() / direct)
        transmittance_error = (torch.exp(-looked_up) - torch.exp(-direct)).abs()
        rows.append((n_mu, n_r, float(relative.max()), float(transmittance_error.max()),
                     seconds))
    return rows


def scattering_study(atm, quick):
    view = torch.tensor([0.0, 0.7, 1.2, 1.45, 1.55, 1.5707], dtype=torch.float64)
    if quick:
        view = view[::2]
    sun = torch.tensor(1.1, dtype=torch.float64)
    reference = atm.sky_radiance(WAVELENGTH_NM, view, 0.0, sun, 0.3,
                                 n_samples=256 if quick else 4096, scattering_orders=1)
    rows = []
    for n in ((16, 32) if quick else (8, 16, 32, 64, 128, 256, 512)):
        radiance, seconds = _timed(lambda k=n: atm.sky_radiance(WAVELENGTH_NM, view, 0.0,
                                                                sun, 0.3, n_samples=k,
                                                                scattering_orders=1),
                                   1 if quick else 3)
        error = float(((radiance - reference).abs() / reference).max())
        rows.append((n, error, seconds / view.numel() * 1e3))
    return rows


def build(od_rows, table_rows, scattering_rows, atm):
    def column(rows, index):
        return [row[index] for row in rows]

    unit = VariableSpec("1", "index", "Configuration index.")
    data_vars = {
        "od_ray": variable("od_case", np.array(column(od_rows, 0)), VariableSpec(
            "1", "ray family", "zenith: 0-11 deg; horizon: 88.9-90 deg zenith angle.")),
        "od_method": variable("od_case", np.array(column(od_rows, 1)), VariableSpec(
            "1", "quadrature", "Column-integral method of Atmosphere.optical_depth.")),
        "od_steps": variable("od_case", np.array(column(od_rows, 2)), VariableSpec(
            "1", "resolution", "Nodes per piece (gauss/adaptive) or steps (trapezoid).")),
        "od_dtype": variable("od_case", np.array(column(od_rows, 3)), VariableSpec(
            "1", "floating-point type", "dtype of the inputs and the computation.")),
        "od_error": variable("od_case", np.array(column(od_rows, 4)), VariableSpec(
            "1", "maximum relative error of the optical depth",
            "Against float64 adaptive quadrature (64 nodes per piece), 15 bands.")),
        "od_time": variable("od_case", np.array(column(od_rows, 5)), VariableSpec(
            "us", "time per ray", "Median wall time per ray, 15 wavelengths.")),
        "table_n_mu": variable("table_case", np.array(column(table_rows, 0)), VariableSpec(
            "1", "samples along x_mu", "Table resolution in direction.")),
        "table_n_r": variable("table_case", np.array(column(table_rows, 1)), VariableSpec(
            "1", "samples along x_r", "Table resolution in altitude.")),
        "table_error": variable("table_case", np.array(column(table_rows, 2)), VariableSpec(
            "1", "maximum relative error of looked-up optical depth",
            "Random rays, altitude 0-50 km, zenith 0-89 deg, against direct quadrature.")),
        "table_transmittance_error": variable("table_case", np.array(column(table_rows, 3)),
                                              VariableSpec("1", "maximum absolute "
                                                           "transmittance error", "")),
        "table_time": variable("table_case", np.array(column(table_rows, 4)), VariableSpec(
            "s", "build time", "Median wall time to compute the table (15 wavelengths).")),
        "sky_samples": variable("sky_case", np.array(column(scattering_rows, 0)),
                                VariableSpec("1", "samples along the view ray", "")),
        "sky_error": variable("sky_case", np.array(column(scattering_rows, 1)), VariableSpec(
            "1", "maximum relative error of single-scattering radiance",
            "Six view directions from zenith to horizon, Sun at 63 deg zenith angle.")),
        "sky_time": variable("sky_case", np.array(column(scattering_rows, 2)), VariableSpec(
            "ms", "time per view direction", "")),
    }
    coords = {name: coordinate(name, np.arange(len(rows)), unit) for name, rows in
              (("od_case", od_rows), ("table_case", table_rows),
               ("sky_case", scattering_rows))}
    return build_dataset(data_vars, coords, title="Atmosphere accuracy versus cost",
                         references=["Bruneton, E. 2017, "
                                     "https://ebruneton.github.io/"
                                     "precomputed_atmospheric_scattering/"],
                         parameters=atm.parameters_dict(),
                         threads=torch.get_num_threads())


def plot(dataset):
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    od = dataset
    styles = {"gauss": "o-", "trapezoid": "s--", "adaptive": "^"}
    for ray in ("zenith", "horizon"):
        for dtype in ("float64", "float32"):
            for method, style in styles.items():
                mask = ((od["od_ray"] == ray) & (od["od_method"] == method)
                        & (od["od_dtype"] == dtype)).values
                if mask.any():
                    axes[0].loglog(od["od_time"].values[mask],
                                   np.maximum(od["od_error"].values[mask], 1e-17), style,
                                   label=f"{ray} {method} {dtype}", alpha=0.8)
    axes[0].set_xlabel("time per ray [µs] (15 wavelengths)")
    axes[0].set_ylabel("max relative error of optical depth")
    axes[0].set_title("straight-ray optical depth")
    axes[0].legend(fontsize=6)
    axes[1].loglog(od["table_time"], od["table_error"], "o-", label="optical depth")
    axes[1].loglog(od["table_time"], od["table_transmittance_error"], "s--",
                   label="transmittance (absolute)")
    for t, e, m, r in zip(od["table_time"].values, od["table_error"].values,
                          od["table_n_mu"].values, od["table_n_r"].values, strict=True):
        axes[1].annotate(f"{m}x{r}", (t, e), fontsize=7)
    axes[1].set_xlabel("build time [s]")
    axes[1].set_ylabel("max error of look-up")
    axes[1].set_title("transmittance table resolution")
    axes[1].legend(fontsize=7)
    axes[2].loglog(od["sky_time"], od["sky_error"], "o-")
    for t, e, n in zip(od["sky_time"].values, od["sky_error"].values,
                       od["sky_samples"].values, strict=True):
        axes[2].annotate(str(n), (t, e), fontsize=7)
    axes[2].set_xlabel("time per view direction [ms]")
    axes[2].set_ylabel("max relative error")
    axes[2].set_title("single-scattering samples")
    figure.tight_layout()
    return figure


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    atm = Atmosphere.earth(turbidity=2.5, ozone_du=300.0)
    threads = torch.get_num_threads()
    if arguments.quick:  # tiny batches: one thread avoids thread start-up and contention
        torch.set_num_threads(1)
    try:
        od_rows = optical_depth_study(atm, arguments.quick)
        table_rows = table_study(atm, arguments.quick)
        scattering_rows = scattering_study(atm, arguments.quick)
    finally:
        torch.set_num_threads(threads)
    dataset = build(od_rows, table_rows, scattering_rows, atm)
    paths = save_outputs(dataset, plot(dataset), arguments.output_dir,
                         "atmosphere_accuracy_cost")
    for path in paths:
        print(path)
    return dataset


if __name__ == "__main__":
    main()
