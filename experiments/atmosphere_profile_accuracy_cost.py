"""Profile layers: error in optical depth, horizon transmittance and refraction versus cost.

Two knobs of the vertical structure are measured against converged references.

1. Sounding levels: the U.S. Standard Atmosphere 1976 sampled every ``step`` km (its own
   pressure and temperature) is given as a user sounding
   (``Atmosphere.earth(profile=...)``: log-linear p/(kT) between levels) and compared with
   the built-in standard (its defining layers): Rayleigh optical depth at 550 nm at zenith
   angles 0, 80 and 90 degrees from the ground, the horizon transmittance at 400 nm and the
   horizon refraction. Cost: wall time of 4096 straight rays x 60 wavelengths.
2. Quadrature panels: the built-in standard with ``n_steps`` Gauss-Legendre nodes per piece
   (pieces between the profile's breakpoints) against ``method="adaptive"`` at
   ``rtol=1e-12``; same quantities (refraction excepted) and cost.

Usage: ``python experiments/atmosphere_profile_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import math
import time

import matplotlib.pyplot as plt
import numpy as np
import torch
import xarray as xr

from experiments._common import parse_arguments, save_outputs
from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.profiles import us1976_pressure_ratio, us1976_temperature

STEPS_KM = (0.25, 0.5, 1.0, 2.0, 5.0, 10.0)
NODES = (2, 3, 4, 6, 8, 12)
ZENITH_DEG = (0.0, 80.0, 90.0)
TIMING_RAYS = 4096
TIMING_WAVELENGTHS = 60


def us1976_sounding(step_m: float, top_m: float = 100e3) -> xr.Dataset:
    """Return the standard sampled every ``step_m`` from 0 m to ``top_m``."""
    altitude = np.arange(0.0, top_m + step_m / 2, step_m)
    h = torch.tensor(altitude, dtype=torch.float64)
    return xr.Dataset(
        {"pressure": ("altitude", 101325.0 * us1976_pressure_ratio(h).numpy(), {"units": "Pa"}),
         "temperature": ("altitude", us1976_temperature(h).numpy(), {"units": "K"})},
        coords={"altitude": ("altitude", altitude, {"units": "m"})})


def _quantities(atm, *, n_steps=None, method="gauss", rtol=1e-9, refraction=True):
    """Rayleigh tau(550) at ZENITH_DEG, horizon T(400) and horizon refraction [arcmin]."""
    zenith = torch.tensor(ZENITH_DEG, dtype=torch.float64) * (math.pi / 180.0)
    options = {"method": method, "n_steps": n_steps, "rtol": rtol}
    tau = atm.optical_depth(torch.tensor([550.0], dtype=torch.float64), zenith,
                            per_species=True, **options)["rayleigh"][:, 0]
    horizon = atm.transmittance(torch.tensor([400.0], dtype=torch.float64),
                                torch.tensor(math.pi / 2, dtype=torch.float64), **options)[0]
    arcmin = (float(atm.refraction(torch.tensor([0.0], dtype=torch.float64))) * 180.0
              / math.pi * 60.0) if refraction else float("nan")
    return tau.numpy(), float(horizon), arcmin


def _seconds(atm, n_steps=None, n_rays=TIMING_RAYS) -> float:
    """Median wall time of ``n_rays`` straight rays x TIMING_WAVELENGTHS [s]."""
    zenith = torch.linspace(0.0, 1.55, n_rays, dtype=torch.float64)
    wavelength = torch.linspace(360.0, 1000.0, TIMING_WAVELENGTHS, dtype=torch.float64)
    times = []
    for _ in range(3):
        start = time.perf_counter()
        atm.optical_depth(wavelength, zenith, n_steps=n_steps)
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def main(argv=None):
    args = parse_arguments(__doc__.splitlines()[0], argv)
    steps_km = (1.0, 5.0) if args.quick else STEPS_KM
    nodes = (3, 6) if args.quick else NODES
    n_rays = 256 if args.quick else TIMING_RAYS
    builtin = Atmosphere.earth(ozone_du=0.0, aerosol_optical_depth=0.0,
                               precipitable_water_cm=0.0)
    tau_ref, horizon_ref, arcmin_ref = _quantities(builtin, method="adaptive", rtol=1e-12)

    n = len(steps_km)
    tau_error, horizon_error, refraction_error, seconds = (
        np.zeros((n, len(ZENITH_DEG))), np.zeros(n), np.zeros(n), np.zeros(n))
    for i, step in enumerate(steps_km):
        atm = Atmosphere.earth(ozone_du=0.0, aerosol_optical_depth=0.0,
                               precipitable_water_cm=0.0, profile=us1976_sounding(step * 1e3))
        tau, horizon, arcmin = _quantities(atm)
        tau_error[i] = np.abs(tau / tau_ref - 1.0)
        horizon_error[i] = abs(horizon / horizon_ref - 1.0)
        refraction_error[i] = abs(arcmin - arcmin_ref)
        seconds[i] = _seconds(atm, n_rays=n_rays)

    m = len(nodes)
    q_tau_error, q_horizon_error, q_seconds = (np.zeros((m, len(ZENITH_DEG))), np.zeros(m),
                                               np.zeros(m))
    for j, count in enumerate(nodes):
        tau, horizon, _ = _quantities(builtin, n_steps=count, refraction=False)
        q_tau_error[j] = np.abs(tau / tau_ref - 1.0)
        q_horizon_error[j] = abs(horizon / horizon_ref - 1.0)
        q_seconds[j] = _seconds(builtin, count, n_rays)

    result = xr.Dataset(
        {"sounding_tau_error": (("sounding_step", "zenith"), tau_error),
         "sounding_horizon_transmittance_error": (("sounding_step",), horizon_error),
         "sounding_refraction_error": (("sounding_step",), refraction_error),
         "sounding_seconds": (("sounding_step",), seconds),
         "quadrature_tau_error": (("gauss_nodes", "zenith"), q_tau_error),
         "quadrature_horizon_transmittance_error": (("gauss_nodes",), q_horizon_error),
         "quadrature_seconds": (("gauss_nodes",), q_seconds)},
        coords={"sounding_step": list(steps_km), "gauss_nodes": list(nodes),
                "zenith": list(ZENITH_DEG)})
    attributes = {
        "sounding_tau_error": ("1", "relative error of the Rayleigh optical depth at 550 nm"),
        "sounding_horizon_transmittance_error": ("1", "relative error of T(400 nm, 90 deg)"),
        "sounding_refraction_error": ("arcmin", "error of the horizon refraction"),
        "sounding_seconds": ("s", f"{n_rays} rays x {TIMING_WAVELENGTHS} wavelengths"),
        "quadrature_tau_error": ("1", "relative error of the Rayleigh optical depth at 550 nm"),
        "quadrature_horizon_transmittance_error": ("1", "relative error of T(400 nm, 90 deg)"),
        "quadrature_seconds": ("s", f"{n_rays} rays x {TIMING_WAVELENGTHS} wavelengths"),
        "sounding_step": ("km", "spacing of the US 1976 sounding's levels"),
        "gauss_nodes": ("1", "Gauss-Legendre nodes per piece"),
        "zenith": ("degree", "zenith angle at the ground"),
    }
    for name, (units, long_name) in attributes.items():
        result[name].attrs.update(units=units, long_name=long_name)
    result.attrs.update(
        title="Profile layers and quadrature panels: accuracy versus cost",
        reference="built-in US 1976, method='adaptive', rtol=1e-12",
        reference_horizon_refraction_arcmin=arcmin_ref,
        reference_horizon_transmittance_400nm=horizon_ref)

    figure, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for k, zenith in enumerate(ZENITH_DEG):
        axes[0].loglog(steps_km, np.maximum(tau_error[:, k], 1e-16), "o-",
                       label=f"tau, {zenith:g} deg")
        axes[1].loglog(nodes, np.maximum(q_tau_error[:, k], 1e-16), "o-",
                       label=f"tau, {zenith:g} deg")
    axes[0].loglog(steps_km, np.maximum(horizon_error, 1e-16), "s--", label="T horizon")
    axes[0].loglog(steps_km, np.maximum(refraction_error, 1e-16), "^:",
                   label="refraction [arcmin]")
    axes[1].loglog(nodes, np.maximum(q_horizon_error, 1e-16), "s--", label="T horizon")
    axes[0].set_xlabel("sounding level spacing [km]")
    axes[1].set_xlabel("Gauss-Legendre nodes per piece")
    for axis in axes:
        axis.set_ylabel("error (relative; refraction in arcmin)")
        axis.legend(fontsize=8)
    axes[0].set_title("US 1976 as a sounding vs built-in")
    axes[1].set_title("built-in US 1976: quadrature nodes")
    paths = save_outputs(result, figure, args.output_dir, "atmosphere_profile_accuracy_cost")
    print(result.to_dataframe().to_string())
    print("reference horizon refraction", arcmin_ref, "arcmin; T_horizon(400)", horizon_ref)
    return paths


if __name__ == "__main__":
    main()
