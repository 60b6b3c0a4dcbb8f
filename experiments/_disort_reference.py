"""The DISORT reference sky shared by the multiple-scattering experiments.

``tests/data/ms_reference/disort_sky.nc`` (DisORT++, plane-parallel, U.S. 1976 molecules +
Henyey-Greenstein aerosol; generator and provenance in that folder's README), the
atmosphere it was computed for, and the coarse tables of the validation tests.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import torch
import xarray as xr

from experiments._common import save_outputs
from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
from skytorch.atmosphere.scattering import constituent_radiance

REFERENCE = Path(__file__).resolve().parents[1] / "tests" / "data" / "ms_reference" / \
    "disort_sky.nc"
#: sasktran2's spherical radiance leaving the top (observer at 100 km, nadir 0, 30, 60 deg)
SPHERICAL_TOP = REFERENCE.parent / "sasktran2_top.nc"
#: the two comparisons of :func:`sky_and_top_errors`
WHERE = ("top (sasktran2, spherical)", "sky from the ground (DISORT)")
#: view zenith angles of the reference used by the experiments [deg]
VIEW_ZENITH_DEG = (0.0, 30.0, 60.0)
#: the coarse tables of the sasktran2 / DISORT / Monte-Carlo tests
COARSE = dict(n_r=8, n_mu=32, n_mu_s=16, n_phi=6, n_ray=24, n_sphere_mu=6,
              transmittance_r=32, transmittance_mu=128, mu_vertical_weight=0.0,
              r_ground_weight=0.0, sphere_phi_refinement=1, ray_quadrature="trapezoid")


def disort_atmosphere(aod) -> Atmosphere:
    """Return the atmosphere of the reference (``tests/data/ms_reference/generate_disort.py``)."""
    return Atmosphere.earth(ozone_du=0.0, precipitable_water_cm=0.0,
                            aerosol_phase_model="henyeygreenstein1941",
                            aerosol_optical_depth=aod, angstrom_alpha=1.3,
                            aerosol_asymmetry=0.7, aerosol_single_scattering_albedo=0.95)


def load_reference() -> xr.Dataset:
    """Return the reference table, loaded into memory."""
    with xr.open_dataset(REFERENCE) as ds:
        return ds.load()


def error_coords(aods, sun_zenith_deg) -> dict:
    """Coordinates of :func:`sky_and_top_errors`' (where, statistic, aod, sun_zenith) axes."""
    return {"where": ("where", np.array(WHERE)),
            "statistic": ("statistic", np.array(["max over views", "vertical view"])),
            "aod": ("aod", np.array(aods), {"long_name": "aerosol optical depth at 550 nm"}),
            "sun_zenith": ("sun_zenith", np.asarray(sun_zenith_deg), {"units": "degree"})}


#: provenance of both references, for the experiments' netCDF attributes
REFERENCES = ("tests/data/ms_reference/disort_sky.nc (DisORT++, 64 streams), "
              "tests/data/ms_reference/sasktran2_top.nc (sasktran2, successive orders)")


def sky_and_top_errors(references, aods, resolution: dict):
    """Largest relative errors of the scenes' sum against both references, and the build time.

    The ray-marched single scattering (1024 samples) plus the tables' orders >= 2 built with
    ``TableResolution(**resolution)`` for the optical depths ``aods`` in one call.
    ``references`` is (DISORT's table, sasktran2's top table). Returns the errors
    |model / reference - 1| with shape (where: :data:`WHERE`, statistic: max over views |
    vertical view, aod, sun zenith) and the precompute time [s].
    """
    disort, top = references
    wavelength = torch.tensor(disort.wavelength.values, dtype=torch.float64)
    atm = disort_atmosphere(torch.tensor(aods, dtype=torch.float64))
    clock = time.perf_counter()
    tables = precompute_scattering(atm, wavelength, scattering_orders="converged",
                                   resolution=TableResolution(**resolution))
    seconds = time.perf_counter() - clock
    vertical = torch.tensor(VIEW_ZENITH_DEG, dtype=torch.float64)
    azimuth = torch.deg2rad(torch.tensor(disort.relative_azimuth.values,
                                         dtype=torch.float64))[None, :, None]
    views = ((torch.deg2rad(180.0 - vertical), tables.top_altitude_m),
             (torch.deg2rad(vertical), 0.0))
    error = np.zeros((2, 2, len(aods), disort.sun_zenith.size))
    for k, sun_zenith in enumerate(disort.sun_zenith.values):
        sun = torch.tensor(math.radians(sun_zenith), dtype=torch.float64)
        theirs = (top.successive_orders.sel(aod=list(aods), sun_zenith=sun_zenith,
                                            wavelength=disort.wavelength.values),
                  disort.sky_streams_64.sel(aod=list(aods), sun_zenith=sun_zenith,
                                            view_zenith=list(VIEW_ZENITH_DEG)))
        for w, ((zenith, altitude), reference) in enumerate(zip(views, theirs, strict=True)):
            zenith = zenith[:, None, None]
            height = torch.tensor(altitude, dtype=torch.float64)
            higher = (tables.radiance(height, zenith, azimuth, sun)
                      - tables.radiance(height, zenith, azimuth, sun, scattering_orders=1))
            single = constituent_radiance(atm.constituents(wavelength), zenith, azimuth, sun,
                                          0.0 * sun, height, n_samples=1024)
            values = reference.transpose(reference.dims[-2], "relative_azimuth", "aod",
                                         "wavelength").values
            relative = np.abs((single + higher).detach().numpy() / values - 1.0)
            error[w, 0, :, k] = relative.max(axis=(0, 1, 3))
            error[w, 1, :, k] = relative[0].max(axis=(0, 2))
    return error, seconds


def compare_table_sizes(arguments, cases, quick_cases, stem: str, title: str,
                        case_variables=None) -> xr.Dataset:
    """Run :func:`sky_and_top_errors` for each table size; write ``<stem>.nc`` / ``.png``.

    References: DISORT's sky seen from the ground (``tests/data/ms_reference/disort_sky.nc``,
    view zenith 0, 30, 60 deg) and sasktran2's spherical radiance leaving the top
    (``sasktran2_top.nc``, observer at 100 km, nadir 0, 30, 60 deg), both at relative
    azimuth 0, 90, 180 deg, 400 and 550 nm, Sun at 30 and 60 deg, U.S. 1976 molecules +
    Henyey-Greenstein aerosol (g 0.7, albedo 0.95) of optical depth 0.05, 0.3 and 1 at
    550 nm, black ground.

    ``cases`` and ``quick_cases`` (``arguments.quick``: 550 nm and optical depth 1 only)
    are (name, sizes on top of the default :class:`TableResolution`) pairs;
    ``case_variables`` maps a variable name to a function of the sizes giving its value
    (and to its attributes) per case. Prints one line per case and returns the Dataset.
    """
    import matplotlib.pyplot as plt

    disort = load_reference()
    with xr.open_dataset(SPHERICAL_TOP) as ds:
        top = ds.load()
    cases = quick_cases if arguments.quick else cases
    aods = [1.0] if arguments.quick else [0.05, 0.3, 1.0]
    if arguments.quick:
        disort = disort.sel(wavelength=[550.0])
    error = np.zeros((len(cases), 2, 2, len(aods), disort.sun_zenith.size))
    seconds = np.zeros(len(cases))
    for i, (_, sizes) in enumerate(cases):
        error[i], seconds[i] = sky_and_top_errors((disort, top), aods, sizes)
    extra = {name: ("case", np.array([value(sizes) for _, sizes in cases]), attrs)
             for name, (value, attrs) in (case_variables or {}).items()}
    dataset = xr.Dataset(
        {"error": (("case", "where", "statistic", "aod", "sun_zenith"), error,
                   {"units": "1", "long_name": "largest |model / reference - 1| over the "
                    "views (or at the vertical) and wavelengths"}),
         "precompute_seconds": ("case", seconds, {"units": "s"}), **extra},
        coords={"case": ("case", np.array([c[0] for c in cases])),
                **error_coords(aods, disort.sun_zenith.values)},
        attrs={"title": title, "references": REFERENCES,
               "wavelengths_nm": str(disort.wavelength.values.tolist()),
               "torch_threads": torch.get_num_threads()})
    figure, axes = plt.subplots(1, 2, figsize=(9.5, 3.8), squeeze=False)
    for w, label in enumerate(WHERE):
        axis = axes[0, w]
        for i, (name, _) in enumerate(cases):
            axis.semilogy(aods, 100 * error[i, w, 0].max(axis=-1), "o-",
                          label=f"{name} ({seconds[i]:.0f} s)")
        axis.axhline(1.0, color="grey", lw=0.8, ls=":")
        axis.set_title(label, fontsize=9)
        axis.set_xlabel("aerosol optical depth at 550 nm")
        axis.set_ylabel("largest error, views and Suns [%]")
        axis.legend(fontsize=7)
    figure.tight_layout()
    save_outputs(dataset, figure, arguments.output_dir, stem)
    for i, (name, _) in enumerate(cases):
        print(f"{name} ({seconds[i]:.1f} s): " + " | ".join(
            f"{label.split()[0]}: " + "; ".join(
                f"τ {aod:g} " + " / ".join(f"{100 * error[i, w, 0, j, k]:.2f}"
                                           for k in range(disort.sun_zenith.size))
                for j, aod in enumerate(aods))
            for w, label in enumerate(WHERE)), flush=True)
    return dataset
