"""The Monte-Carlo reference sky shared by the day-to-twilight table experiments.

``tests/data/ms_reference/montecarlo_sky.nc`` (backward Monte-Carlo of the sky seen from the
ground in spherical geometry; generator and provenance in that folder's README): U.S. 1976
molecules without and with a Henyey-Greenstein aerosol (g 0.7, albedo 0.95) of optical depth
0.1 at 550 nm, 400 and 550 nm, black ground, Sun zenith 30-98 deg, the zenith and the views
60 and 85 deg from it at relative azimuth 0, 90, 180 deg. Below the horizon it is the only
reference (sasktran2's successive orders are not one there,
docs/multiple_scattering_validation.md).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import torch
import xarray as xr

from experiments._common import load_script, median_cpu_seconds
from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
from skytorch.atmosphere.scattering import constituent_radiance

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "ms_reference"
#: Sun zenith angles of the reference [deg]
SUN_ZENITH_DEG = (30.0, 60.0, 80.0, 90.0, 94.0, 98.0)
#: the reference's two atmospheres
CASES = ("rayleigh", "rayleigh_aerosol")
#: the statistics of :func:`montecarlo_errors`
STATISTICS = ("max over decided views", "zenith")
#: provenance, for the experiments' netCDF attributes
REFERENCE = ("tests/data/ms_reference/montecarlo_sky.nc (backward Monte-Carlo, spherical)")


def load_montecarlo():
    """Return the generator module and the reference table (loaded into memory)."""
    mc = load_script(DATA / "generate_montecarlo.py", "generate_montecarlo")
    with xr.open_dataset(DATA / "montecarlo_sky.nc") as ds:
        return mc, ds.load()


def montecarlo_errors(mc, reference, case: str, resolution: dict):
    """Errors of what scenes render against the Monte-Carlo, per Sun zenith.

    The ray-marched single scattering (256 samples) plus the orders >= 2 of tables built
    with ``TableResolution(**resolution)`` for the case's atmosphere at the reference's two
    wavelengths. Returns the (sun, statistic) relative errors — the largest |model / MC − 1|
    over the view-wavelength points the Monte-Carlo decides (standard error below a third
    of the issue's tolerance, 3 % to Sun 80 deg and 10 % below) and at the zenith — the
    number of decided points per Sun, and the precompute time [s].
    """
    atmosphere = mc.skytorch_atmosphere(mc.CASES[case])
    wavelength = torch.tensor(reference.wavelength.values, dtype=torch.float64)
    zenith = torch.deg2rad(torch.tensor([v[0] for v in mc.VIEWS], dtype=torch.float64))
    azimuth = torch.deg2rad(torch.tensor([v[1] for v in mc.VIEWS], dtype=torch.float64))
    height = torch.tensor(mc.OBSERVER_ALTITUDE_M, dtype=torch.float64)
    clock = time.perf_counter()
    tables = precompute_scattering(atmosphere, wavelength, ground_albedo=0.0,
                                   scattering_orders="converged",
                                   resolution=TableResolution(**resolution))
    seconds = time.perf_counter() - clock
    error = np.zeros((len(SUN_ZENITH_DEG), len(STATISTICS)))
    decided_count = np.zeros(len(SUN_ZENITH_DEG), dtype=int)
    for k, sun_zenith in enumerate(SUN_ZENITH_DEG):
        sun = torch.tensor(math.radians(sun_zenith), dtype=torch.float64)
        single = constituent_radiance(atmosphere.constituents(wavelength), zenith, azimuth, sun,
                                      0.0 * sun, height, n_samples=256)
        higher = (tables.radiance(height, zenith, azimuth, sun)
                  - tables.radiance(height, zenith, azimuth, sun, scattering_orders=1))
        ref = reference.sel(case=case, sun_zenith=sun_zenith)
        relative = (single + higher).numpy().T / ref.total.values - 1.0   # (wavelength, view)
        tolerance = 0.03 if sun_zenith <= 80.0 else 0.10
        decided = ref.total_stderr.values < tolerance / 3.0 * ref.total.values
        decided_count[k] = decided.sum()
        error[k, 0] = np.abs(relative[decided]).max() if decided.any() else np.nan
        error[k, 1] = np.abs(relative[:, 0]).max()
    return error, decided_count, seconds


def scene_build_seconds(resolution: dict, repeat: int, warm_up: bool = True) -> float:
    """Median CPU time [s] of a scene's tables: ``Atmosphere.earth()``, 6 wavelengths.

    Converged orders, black ground, ``TableResolution(**resolution)``, at the scene
    presets' 6 wavelength nodes (400-700 nm); CPU time of the process (all its threads):
    steadier than wall time on a shared machine. ``warm_up``: one untimed build first.
    """
    from skytorch.scene.presets import FIDELITY

    atmosphere = Atmosphere.earth()
    wavelength = torch.linspace(400.0, 700.0, FIDELITY["default"]["ms_wavelength_nodes"],
                                dtype=torch.float64)
    return median_cpu_seconds(
        lambda: precompute_scattering(atmosphere, wavelength, ground_albedo=0.0,
                                      scattering_orders="converged",
                                      resolution=TableResolution(**resolution)),
        repeat, warm_up=warm_up)
