"""The forward peak factored out of the orders >= 2, and the tables' dtype: accuracy and cost.

Reference: ``tests/data/ms_reference/disort_sky.nc`` (DisORT++, plane-parallel, U.S. 1976
molecules + Henyey-Greenstein aerosol g 0.7, albedo 0.95; the sky seen from the ground at
view zenith 0, 30, 60 deg and relative azimuth 0, 90, 180 deg, 400 and 550 nm, Sun at 30
and 60 deg; black ground against the 64-stream run, Lambertian ground of albedo 0.3
against its own run).

For each table resolution and each variant of ``precompute_scattering`` — the orders
interpolated as they are (``forward_peak="none"``), the forward peak factored out
(``"factored"``, the default), and the same with ``dtype=torch.float32`` (the ray
integrals of the orders >= 2, the storage and the look-ups in float32) — the largest
relative error of the sky over those views, per aerosol optical depth and Sun, of (a) the
tables alone (``ScatteringTables.radiance``) and (b) the ray-marched single scattering
plus the tables' orders >= 2 (what scenes render), and the precompute time (the optical
depths batched in one call).

Writes ``forward_peak_accuracy_cost.nc`` / ``.png``. Run:
``python experiments/forward_peak_accuracy_cost.py [--quick] [--output-dir DIR]``.
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
from skytorch.atmosphere.multiple_scattering import (  # noqa: E402
    TableResolution,
    precompute_scattering,
)
from skytorch.atmosphere.scattering import constituent_radiance  # noqa: E402

#: (name, resolution, ground albedo of the DISORT run or 0); "default" is the default
#: TableResolution before 2026-12-05 (16 x 64 x 24 x 8, 48 samples per ray)
CASES = (("coarse", TableResolution(**COARSE), 0.0),
         ("coarse, ground 0.3", TableResolution(**COARSE), 0.3),
         ("default", TableResolution(n_r=16, n_mu_s=24, n_ray=48, mu_vertical_weight=0.0,
                                     r_ground_weight=0.0, sphere_phi_refinement=1,
                                     ray_quadrature="trapezoid"),
          0.0))
#: (label, forward_peak, dtype)
VARIANTS = (("none", "none", torch.float64), ("factored", "factored", torch.float64),
            ("factored, float32", "factored", torch.float32))


def _errors(reference, aods, resolution, albedo, mode, dtype):
    """Largest |model / DISORT - 1| (method, aod, sun) and the precompute time [s]."""
    wavelength = torch.tensor(reference.wavelength.values, dtype=torch.float64)
    aod = torch.tensor(aods, dtype=torch.float64)
    atm = disort_atmosphere(aod)
    clock = time.perf_counter()
    tables = precompute_scattering(atm, wavelength, ground_albedo=albedo,
                                   scattering_orders="converged", resolution=resolution,
                                   forward_peak=mode, dtype=dtype)
    seconds = time.perf_counter() - clock
    zenith = torch.deg2rad(torch.tensor(VIEW_ZENITH_DEG, dtype=torch.float64))[:, None, None]
    azimuth = torch.deg2rad(torch.tensor(reference.relative_azimuth.values,
                                         dtype=torch.float64))[None, :, None]
    ground = torch.tensor(0.0, dtype=torch.float64)
    run = "sky_ground_albedo" if albedo else "sky_streams_64"
    error = np.zeros((2, len(aods), reference.sun_zenith.size))
    for k, sun_zenith in enumerate(reference.sun_zenith.values):
        sun = torch.tensor(math.radians(sun_zenith), dtype=torch.float64)
        total = tables.radiance(ground, zenith.to(dtype), azimuth.to(dtype),
                                sun.to(dtype)).double()                 # (view, az, aod, λ)
        higher = total - tables.radiance(ground, zenith.to(dtype), azimuth.to(dtype),
                                         sun.to(dtype), scattering_orders=1).double()
        single = constituent_radiance(atm.constituents(wavelength), zenith, azimuth, sun,
                                      0.0 * sun, ground, n_samples=512)
        disort = reference[run].sel(aod=list(aods), sun_zenith=sun_zenith,
                                    view_zenith=list(VIEW_ZENITH_DEG)).transpose(
            "view_zenith", "relative_azimuth", "aod", "wavelength").values
        for m, model in enumerate((total, single + higher)):
            relative = np.abs(model.detach().numpy() / disort - 1.0)
            error[m, :, k] = relative.max(axis=(0, 1, 3))
    return error, seconds


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    reference = load_reference()
    quick = arguments.quick
    cases = CASES[:1] if quick else CASES
    aods = [0.0, 0.3] if quick else [0.0, 0.05, 0.3, 1.0]
    if quick:
        reference = reference.sel(wavelength=[550.0])
    error = np.zeros((len(cases), len(VARIANTS), 2, len(aods), reference.sun_zenith.size))
    seconds = np.zeros((len(cases), len(VARIANTS)))
    for i, (_, resolution, albedo) in enumerate(cases):
        # the ground run has no optical depth 1
        rows = [j for j, a in enumerate(aods) if not (albedo and a > 0.5)]
        for m, (_, mode, dtype) in enumerate(VARIANTS):
            part, seconds[i, m] = _errors(reference, [aods[j] for j in rows], resolution,
                                          albedo, mode, dtype)
            error[i, m] = np.nan
            error[i, m][:, rows] = part
    dataset = xr.Dataset(
        {"sky_error": (("case", "variant", "method", "aod", "sun_zenith"), error,
                       {"units": "1", "long_name": "largest |model / DISORT - 1| over the "
                        "sky views and wavelengths"}),
         "precompute_seconds": (("case", "variant"), seconds, {"units": "s"})},
        coords={"case": ("case", np.array([c[0] for c in cases])),
                "variant": ("variant", np.array([v[0] for v in VARIANTS])),
                "method": ("method", np.array(["tables", "ray-marched order 1 + tables"])),
                "aod": ("aod", np.array(aods), {"long_name": "aerosol optical depth at "
                                                "550 nm"}),
                "sun_zenith": ("sun_zenith", reference.sun_zenith.values,
                               {"units": "degree"})},
        attrs={"title": "Orders >= 2 with the forward peak factored out, against DISORT",
               "reference": "tests/data/ms_reference/disort_sky.nc (DisORT++)",
               "wavelengths_nm": str(reference.wavelength.values.tolist()),
               "torch_threads": torch.get_num_threads()})
    figure, axes = plt.subplots(1, len(cases), figsize=(4 * len(cases), 3.6), squeeze=False)
    for i, (name, _, _) in enumerate(cases):
        axis = axes[0, i]
        for m, (label, _, _) in enumerate(VARIANTS):
            for k, sun in enumerate(reference.sun_zenith.values):
                axis.semilogy(aods, 100 * error[i, m, 1, :, k], ("s--", "o-", "x:")[m],
                              label=f"{label}, Sun {sun:g}° ({seconds[i, m]:.0f} s)")
        axis.set_title(name)
        axis.set_xlabel("aerosol optical depth at 550 nm")
        axis.set_ylabel("largest sky error vs DISORT [%]")
        axis.legend(fontsize=7)
    save_outputs(dataset, figure, arguments.output_dir, "forward_peak_accuracy_cost")
    for i, (name, _, _) in enumerate(cases):
        for m, (label, _, _) in enumerate(VARIANTS):
            print(f"{name}, {label} ({seconds[i, m]:.1f} s): " + "; ".join(
                f"τ {aod:g}: " + " / ".join(f"{100 * error[i, m, 1, j, k]:.1f}"
                                             for k in range(reference.sun_zenith.size))
                + " %" for j, aod in enumerate(aods)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
