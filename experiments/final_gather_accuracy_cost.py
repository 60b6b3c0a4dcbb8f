"""The final gather of the orders >= 2: accuracy against DISORT and what it costs.

Reference: ``tests/data/ms_reference/disort_sky.nc`` (DisORT++ 64 streams, plane-parallel,
U.S. 1976 molecules + Henyey-Greenstein aerosol g 0.7, albedo 0.95, black ground; the sky
seen from the ground at view zenith 0, 30, 60 deg and relative azimuth 0, 90, 180 deg,
400 and 550 nm, Sun at 30 and 60 deg).

Part 1 — the sky's largest relative error over those views of (a) the looked-up orders
(ray-marched single scattering + the tables' orders >= 2, what scenes render) and (b) the
same single scattering plus
:func:`skytorch.atmosphere.final_gather.higher_orders_gathered` at its defaults, per
aerosol optical depth and table resolution, with the precompute's and the gather's times.

Part 2 — the gather's quadrature (``n_view`` samples along the line of sight, ``n_mu`` ×
``n_phi`` directions at each): error against DISORT and against the finest setting, and
the time per line of sight, on the coarse tables.

Writes ``final_gather_accuracy_cost.nc`` / ``.png``. Run:
``python experiments/final_gather_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
import torch
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402
from experiments._disort_reference import (  # noqa: E402
    COARSE,
    VIEW_ZENITH_DEG,
    disort_atmosphere,
    load_reference,
)
from skytorch.atmosphere.final_gather import higher_orders_gathered  # noqa: E402
from skytorch.atmosphere.multiple_scattering import (  # noqa: E402
    TableResolution,
    precompute_scattering,
)
from skytorch.atmosphere.scattering import constituent_radiance  # noqa: E402

#: "default" is the default TableResolution before 2026-12-05 (16 x 64 x 24 x 8, 48 samples)
RESOLUTIONS = {"coarse": TableResolution(**COARSE),
               "coarse, 16 radii": TableResolution(**{**COARSE, "n_r": 16}),
               "default": TableResolution(n_r=16, n_mu_s=24, n_ray=48, mu_vertical_weight=0.0,
                                          r_ground_weight=0.0, sphere_phi_refinement=1,
                                          ray_quadrature="trapezoid")}
#: (n_view, n_mu, n_phi); the last is the finest, the reference of part 2
QUADRATURES = ((8, 4, 16), (16, 8, 32), (32, 16, 64), (48, 24, 96), (64, 32, 128))
DEFAULT_QUADRATURE = (32, 16, 64)


def _geometry(reference):
    zenith = torch.deg2rad(torch.tensor(VIEW_ZENITH_DEG, dtype=torch.float64))[:, None]
    azimuth = torch.deg2rad(torch.tensor(reference.relative_azimuth.values,
                                         dtype=torch.float64))[None, :]
    return zenith, azimuth, torch.tensor(0.0, dtype=torch.float64)


def _disort(reference, aod, sun_zenith_deg):
    sky = reference.sky_streams_64.sel(aod=aod, sun_zenith=sun_zenith_deg,
                                       view_zenith=list(VIEW_ZENITH_DEG))
    return sky.transpose("view_zenith", "relative_azimuth", "wavelength").values


def _cases(reference, aods, resolutions):
    """Part 1: errors (resolution, method, aod, sun) and times (resolution, aod)."""
    wavelength = torch.tensor(reference.wavelength.values, dtype=torch.float64)
    zenith, azimuth, ground = _geometry(reference)
    suns = reference.sun_zenith.values
    error = np.zeros((len(resolutions), 2, len(aods), len(suns)))
    precompute_s = np.zeros((len(resolutions), len(aods)))
    gather_s = np.zeros((len(resolutions), len(aods)))
    for i, name in enumerate(resolutions):
        for j, aod in enumerate(aods):
            atm = disort_atmosphere(aod)
            clock = time.perf_counter()
            tables = precompute_scattering(atm, wavelength, scattering_orders="converged",
                                           resolution=RESOLUTIONS[name])
            precompute_s[i, j] = time.perf_counter() - clock
            for k, sun_zenith in enumerate(suns):
                sun = torch.tensor(math.radians(sun_zenith), dtype=torch.float64)
                single = constituent_radiance(atm.constituents(wavelength), zenith, azimuth,
                                              sun, 0.0 * sun, ground, n_samples=512)
                looked_up = (tables.radiance(ground, zenith, azimuth, sun)
                             - tables.radiance(ground, zenith, azimuth, sun,
                                               scattering_orders=1))
                clock = time.perf_counter()
                gathered = higher_orders_gathered(tables, atm, ground, zenith, azimuth, sun)
                gather_s[i, j] += (time.perf_counter() - clock) / zenith.numel() / \
                    azimuth.numel() / len(suns)
                disort = _disort(reference, aod, sun_zenith)
                for m, higher in enumerate((looked_up, gathered)):
                    error[i, m, j, k] = np.abs((single + higher).numpy() / disort - 1).max()
    return error, precompute_s, gather_s


def _quadrature(reference, aods, quadratures):
    """Part 2 on the coarse tables: errors vs DISORT and vs the finest, time per line."""
    wavelength = torch.tensor(reference.wavelength.values, dtype=torch.float64)
    zenith, azimuth, ground = _geometry(reference)
    suns = reference.sun_zenith.values
    against_disort = np.zeros((len(aods), len(quadratures)))
    against_finest = np.zeros((len(aods), len(quadratures)))
    seconds = np.zeros(len(quadratures))
    for j, aod in enumerate(aods):
        atm = disort_atmosphere(aod)
        tables = precompute_scattering(atm, wavelength, scattering_orders="converged",
                                       resolution=RESOLUTIONS["coarse"])
        results = []
        for q, (n_view, n_mu, n_phi) in enumerate(quadratures):
            per_sun = []
            for sun_zenith in suns:
                sun = torch.tensor(math.radians(sun_zenith), dtype=torch.float64)
                single = constituent_radiance(atm.constituents(wavelength), zenith, azimuth,
                                              sun, 0.0 * sun, ground, n_samples=512)
                clock = time.perf_counter()
                higher = higher_orders_gathered(tables, atm, ground, zenith, azimuth, sun,
                                                n_view=n_view, n_mu=n_mu, n_phi=n_phi)
                seconds[q] += (time.perf_counter() - clock) / zenith.numel() / \
                    azimuth.numel() / len(suns) / len(aods)
                per_sun.append((single + higher).numpy())
            results.append(np.array(per_sun))
            disort = np.array([_disort(reference, aod, s) for s in suns])
            against_disort[j, q] = np.abs(results[-1] / disort - 1).max()
        for q in range(len(quadratures)):
            against_finest[j, q] = np.abs(results[q] / results[-1] - 1).max()
    return against_disort, against_finest, seconds


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    reference = load_reference()
    quick = arguments.quick
    aods = [0.3] if quick else [0.05, 0.3, 1.0]
    resolutions = ["coarse"] if quick else list(RESOLUTIONS)
    quadratures = QUADRATURES[:2] if quick else QUADRATURES
    if quick:
        reference = reference.sel(wavelength=[550.0])
    error, precompute_s, gather_s = _cases(reference, aods, resolutions)
    against_disort, against_finest, seconds = _quadrature(reference, aods, quadratures)
    labels = [f"{v} x {2 * m} x {p}" for v, m, p in quadratures]
    dataset = xr.Dataset(
        {"sky_error": (("resolution", "method", "aod", "sun_zenith"), error,
                       {"units": "1", "long_name": "largest |model / DISORT - 1| over the "
                        "sky views and wavelengths"}),
         "precompute_seconds": (("resolution", "aod"), precompute_s, {"units": "s"}),
         "gather_seconds_per_line": (("resolution", "aod"), gather_s, {"units": "s"}),
         "quadrature_error_disort": (("aod", "quadrature"), against_disort,
                                     {"units": "1", "long_name": "largest |model / DISORT "
                                      "- 1|, coarse tables"}),
         "quadrature_error_finest": (("aod", "quadrature"), against_finest,
                                     {"units": "1", "long_name": "largest relative "
                                      "difference from the finest quadrature"}),
         "quadrature_seconds_per_line": (("quadrature",), seconds, {"units": "s"})},
        coords={"resolution": ("resolution", np.array(resolutions)),
                "method": ("method", np.array(["tables", "final gather"])),
                "aod": ("aod", np.array(aods), {"long_name": "aerosol optical depth at "
                                                "550 nm"}),
                "sun_zenith": ("sun_zenith", reference.sun_zenith.values,
                               {"units": "degree"}),
                "quadrature": ("quadrature", np.array(labels),
                               {"long_name": "n_view x directions (2 n_mu) x n_phi"})},
        attrs={"title": "Final gather of the orders >= 2 against DISORT",
               "reference": "tests/data/ms_reference/disort_sky.nc (DisORT++ 64 streams)",
               "wavelengths_nm": str(reference.wavelength.values.tolist()),
               "torch_threads": torch.get_num_threads()})
    figure, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8))
    for i, name in enumerate(resolutions):
        for m, method in enumerate(("tables", "final gather")):
            left.semilogy(aods, 100 * error[i, m].max(axis=-1), "o-" if m else "s--",
                          label=f"{method}, {name}")
    left.set_xlabel("aerosol optical depth at 550 nm")
    left.set_ylabel("largest sky error vs DISORT [%]")
    left.legend(fontsize=7)
    for j, aod in enumerate(aods):
        right.loglog(seconds, 100 * against_disort[j], "o-", label=f"vs DISORT, τ {aod:g}")
        right.loglog(seconds[:-1], 100 * np.maximum(against_finest[j, :-1], 1e-6), "s--",
                     label=f"vs finest, τ {aod:g}")
    right.set_xlabel("time per line of sight [s]")
    right.set_ylabel("largest sky error [%]")
    right.set_title("gather quadrature, coarse tables")
    right.legend(fontsize=7)
    save_outputs(dataset, figure, arguments.output_dir, "final_gather_accuracy_cost")
    for i, name in enumerate(resolutions):
        print(f"{name}: precompute {np.round(precompute_s[i], 1).tolist()} s, gather "
              f"{np.round(1e3 * gather_s[i], 1).tolist()} ms per line of sight")
        for m, method in enumerate(("tables", "final gather")):
            print(f"  {method}: " + ", ".join(
                f"τ {aod:g}: {100 * error[i, m, j, 0]:.1f} / {100 * error[i, m, j, -1]:.1f} %"
                for j, aod in enumerate(aods)))
    for q, label in enumerate(labels):
        print(f"{label}: {1e3 * seconds[q]:.1f} ms, vs DISORT "
              f"{np.round(100 * against_disort[:, q], 2).tolist()} %, vs finest "
              f"{np.round(100 * against_finest[:, q], 3).tolist()} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
