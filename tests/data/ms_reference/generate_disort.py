r"""Write the DISORT reference table of plane-parallel sky radiance (disort_sky.nc).

Independent radiative-transfer code: **DisORT++** (``disortpp`` on the registry; D.
Kitzmann's C++17 implementation of DISORT, Stamnes et al. 1988, Appl. Opt. 27, 2502),
plane-parallel, scalar, delta-M scaling with the Nakajima-Tanaka intensity correction,
black ground. It runs in its own environment (it needs numpy only; ``pydisort`` pins
torch 2.10), so this script has two stages:

1. ``layers`` (skytorch's environment): the layer optics. skytorch's atmosphere of the
   plane-parallel cases -- U.S. 1976 molecules, Henyey-Greenstein aerosol g = 0.7,
   single-scattering albedo 0.95, Angstrom alpha 1.3, aerosol optical depth 0, 0.05, 0.3
   and 1 at 550 nm, no ozone, no water -- the coefficients versus altitude, which do not
   depend on the planet's radius -- integrated over each layer (8-point Gauss-Legendre per
   layer, boundaries every 100 m to 2 km, 250 m to 10 km, 1 km to 30 km, 2 km to
   100 km) into the Rayleigh and aerosol scattering optical depths and the extinction
   optical depth (the rest of the extinction, O2 / O2-O2 only, is a pure absorber).
   Written to ``disort_sky.nc``.
2. ``solve`` (an environment with ``disortpp``, numpy and xarray): DISORT for each case,
   wavelength and Sun zenith with the layers of stage 1 (each layer homogeneous: single
   scattering albedo and Legendre moments mixed by scattering optical depth; Rayleigh
   moments 1, 0, 1/10, i.e. :math:`\frac{3}{4}(1 + \cos^2\theta)`, the phase skytorch uses;
   Henyey-Greenstein moments :math:`g^l`), at 32 and 64 streams and, as a check of the
   layering, at 32 streams on layers split in two. Adds the radiances to the file.

Run from the repository root::

    .venv/bin/python tests/data/ms_reference/generate_disort.py layers
    python -m venv /tmp/disort-venv && /tmp/disort-venv/bin/pip install disortpp xarray \
        netCDF4
    /tmp/disort-venv/bin/python tests/data/ms_reference/generate_disort.py solve

(2 s and about a minute; the ``solve`` stage reproduces the shipped file bit for
bit with disortpp 1.2.1). Radiances are per unit solar irradiance normal to the beam at the top
[sr^-1]; ``relative_azimuth`` 0 is the view towards the Sun's azimuth (DISORT's azimuth of
the photons' travel equal to the beam's, its forward direction).
"""
from __future__ import annotations

import sys
import time
from importlib import metadata
from pathlib import Path

import numpy as np
import xarray as xr

HERE = Path(__file__).resolve().parent
OUTPUT = HERE / "disort_sky.nc"
AEROSOL = {"angstrom_alpha": 1.3, "aerosol_asymmetry": 0.7,
           "aerosol_single_scattering_albedo": 0.95}
AEROSOL_OPTICAL_DEPTH = np.array([0.0, 0.05, 0.3, 1.0])
WAVELENGTH_NM = np.array([400.0, 550.0])
SUN_ZENITH_DEG = np.array([30.0, 60.0])
#: ground observer looking up (view zenith) and top-of-atmosphere observer looking down
#: (nadir angle)
VIEW_ZENITH_DEG = np.array([0.0, 30.0, 60.0, 75.0])
NADIR_DEG = np.array([0.0, 30.0, 60.0])
RELATIVE_AZIMUTH_DEG = np.array([0.0, 90.0, 180.0])
#: layer boundaries [m]: 100 m to 2 km, 250 m to 10 km, 1 km to 30 km, 2 km to 100 km
LEVELS_M = np.concatenate([np.arange(0.0, 2000.0, 100.0), np.arange(2000.0, 10000.0, 250.0),
                           np.arange(10000.0, 30000.0, 1000.0),
                           np.arange(30000.0, 100001.0, 2000.0)])
N_GAUSS = 8
N_MOMENTS = 128
STREAMS = (32, 64)
#: Lambertian ground albedo of the ``ground_albedo`` run (32 streams; the others: black)
GROUND_ALBEDO = 0.3


def layers() -> xr.Dataset:
    """Stage 1: skytorch's layer optical depths (needs skytorch and torch)."""
    import torch

    import skytorch as st

    x, w = np.polynomial.legendre.leggauss(N_GAUSS)
    low, high = LEVELS_M[:-1], LEVELS_M[1:]
    nodes = 0.5 * (low + high)[:, None] + 0.5 * (high - low)[:, None] * x[None, :]
    altitude = torch.tensor(nodes.ravel(), dtype=torch.float64)
    wavelength = torch.tensor(WAVELENGTH_NM, dtype=torch.float64)
    shape = (len(AEROSOL_OPTICAL_DEPTH), len(low), len(WAVELENGTH_NM))
    rayleigh, aerosol, extinction = np.zeros(shape), np.zeros(shape), np.zeros(shape)

    def column(coefficient):
        """Integrate (level x node, wavelength) coefficients [m^-1] over each layer."""
        values = coefficient.detach().numpy().reshape(len(low), N_GAUSS, len(WAVELENGTH_NM))
        return 0.5 * (high - low)[:, None] * np.einsum("lgw,g->lw", values, w)

    for i, aod in enumerate(AEROSOL_OPTICAL_DEPTH):
        atm = st.Atmosphere.earth(ozone_du=0.0, precipitable_water_cm=0.0,
                                  aerosol_phase_model="henyeygreenstein1941",
                                  aerosol_optical_depth=float(aod), **AEROSOL)
        scattering = atm.scattering_coefficients(altitude, wavelength)
        rayleigh[i] = column(scattering["rayleigh"])
        aerosol[i] = column(scattering["aerosol"])
        extinction[i] = column(atm.extinction_coefficient(altitude, wavelength))
    dims = ("aod", "layer", "wavelength")
    ds = xr.Dataset(
        {"rayleigh_optical_depth": (dims, rayleigh, {"units": "1"}),
         "aerosol_scattering_optical_depth": (dims, aerosol, {"units": "1"}),
         "extinction_optical_depth": (dims, extinction, {"units": "1"}),
         "layer_bottom": ("layer", low, {"units": "m"}),
         "layer_top": ("layer", high, {"units": "m"})},
        coords={"aod": AEROSOL_OPTICAL_DEPTH, "wavelength": WAVELENGTH_NM})
    ds["aod"].attrs.update(units="1", long_name="aerosol optical depth at 550 nm")
    ds["wavelength"].attrs["units"] = "nm"
    ds.attrs.update(
        title="DISORT reference sky radiance for skytorch multiple scattering "
              "(plane-parallel limit)",
        optics=f"skytorch {st.__version__}: Atmosphere.earth(ozone_du=0, "
               f"precipitable_water_cm=0, aerosol_phase_model='henyeygreenstein1941', "
               f"{AEROSOL!r}), {N_GAUSS}-point Gauss-Legendre per layer",
        planet_radius_m=float(atm.planet_radius_m), ground_albedo=0.0, ozone_du=0.0,
        precipitable_water_cm=0.0, polarisation="none (scalar)",
        generator="tests/data/ms_reference/generate_disort.py")
    return ds


def _disort(tau, ssa, moments, mu0: float, n_streams: int, mu_user, tau_user,
            albedo: float = 0.0):
    """One DISORT run: intensities (tau_user, mu_user, phi) and fluxes at tau_user."""
    import disortpp

    n_layers = len(tau)
    config = disortpp.DisortConfig(n_layers, n_streams, N_MOMENTS)
    config.flags.use_user_mu = True
    config.flags.use_user_tau = True
    config.flags.use_lambertian_surface = True
    config.flags.intensity_corr_nakajima = True
    config.num_user_mu = len(mu_user)
    config.num_phi = len(RELATIVE_AZIMUTH_DEG)
    config.num_user_tau = len(tau_user)
    config.allocate()
    config.delta_tau = [float(v) for v in tau]
    config.single_scat_albedo = [float(v) for v in ssa]
    config.phase_function_moments = moments
    config.mu_user = [float(v) for v in mu_user]
    config.phi_user = [float(v) for v in RELATIVE_AZIMUTH_DEG]
    config.tau_user = [float(v) for v in tau_user]
    config.bc.direct_beam_flux = 1.0
    config.bc.direct_beam_mu = mu0
    config.bc.direct_beam_phi = 0.0
    config.bc.surface_albedo = albedo
    result = disortpp.DisortSolver().solve(config)
    intensity = np.array([[[result.intensities(iu, lu, j)
                            for j in range(len(RELATIVE_AZIMUTH_DEG))]
                           for iu in range(len(mu_user))] for lu in range(len(tau_user))])
    return intensity, np.array(result.flux_down), np.array(result.flux_direct_beam)


def _mixture(layer: xr.Dataset, split: bool):
    """DISORT layer inputs, top layer first: optical depth, single-scattering albedo, moments.

    ``split`` halves every layer (two of equal optical depths): the layering check.
    """
    tau_r, tau_a, tau = (np.repeat(layer[name].values[::-1], 2) / 2 if split
                         else layer[name].values[::-1]
                         for name in ("rayleigh_optical_depth",
                                      "aerosol_scattering_optical_depth",
                                      "extinction_optical_depth"))
    scattering = tau_r + tau_a
    rayleigh = np.zeros(N_MOMENTS + 1)
    rayleigh[0], rayleigh[2] = 1.0, 0.1
    hg = AEROSOL["aerosol_asymmetry"] ** np.arange(N_MOMENTS + 1)
    moments = (tau_r[:, None] * rayleigh + tau_a[:, None] * hg) / scattering[:, None]
    return tau, scattering / tau, moments


def solve(ds: xr.Dataset) -> xr.Dataset:
    """Stage 2: DISORT radiances and fluxes for every case (needs disortpp)."""
    mu_down = -np.cos(np.deg2rad(VIEW_ZENITH_DEG))   # photons travelling down
    mu_up = np.cos(np.deg2rad(NADIR_DEG))            # photons travelling up
    mu_user = np.concatenate([mu_down, mu_up])
    order = np.argsort(mu_user)
    n_aod, n_wl, n_sun = len(AEROSOL_OPTICAL_DEPTH), len(WAVELENGTH_NM), len(SUN_ZENITH_DEG)
    # name: (streams, layers split in two, ground albedo)
    runs = ({f"streams_{n}": (n, False, 0.0) for n in STREAMS}
            | {"split_layers": (STREAMS[0], True, 0.0),
               "ground_albedo": (STREAMS[0], False, GROUND_ALBEDO)})
    sky = {k: np.zeros((n_aod, n_sun, n_wl, len(VIEW_ZENITH_DEG), 3)) for k in runs}
    top = {k: np.zeros((n_aod, n_sun, n_wl, len(NADIR_DEG), 3)) for k in runs}
    diffuse = {k: np.zeros((n_aod, n_sun, n_wl)) for k in runs}
    direct = np.zeros((n_aod, n_sun, n_wl))
    for name, (n_streams, split, albedo) in runs.items():
        for i in range(n_aod):
            for k in range(n_wl):
                tau, ssa, moments = _mixture(ds.isel(aod=i, wavelength=k), split=split)
                for j, sza in enumerate(SUN_ZENITH_DEG):
                    mu0 = float(np.cos(np.deg2rad(sza)))
                    intensity, flux_down, flux_direct = _disort(
                        tau, ssa, moments, mu0, n_streams, mu_user[order], [0.0, tau.sum()],
                        albedo)
                    back = np.empty_like(intensity)
                    back[:, order] = intensity
                    sky[name][i, j, k] = back[1, :len(VIEW_ZENITH_DEG)]
                    top[name][i, j, k] = back[0, len(VIEW_ZENITH_DEG):]
                    diffuse[name][i, j, k] = flux_down[1]
                    if name == "streams_64":
                        direct[i, j, k] = flux_direct[1]
    dims = ("aod", "sun_zenith", "wavelength")
    out = ds.assign_coords(sun_zenith=SUN_ZENITH_DEG, view_zenith=VIEW_ZENITH_DEG,
                           nadir=NADIR_DEG, relative_azimuth=RELATIVE_AZIMUTH_DEG)
    for name in runs:
        out[f"sky_{name}"] = (dims + ("view_zenith", "relative_azimuth"), sky[name])
        out[f"top_{name}"] = (dims + ("nadir", "relative_azimuth"), top[name])
        out[f"diffuse_down_{name}"] = (dims, diffuse[name])
    out["direct_down"] = (dims, direct)
    return _annotate(out)


def _annotate(out: xr.Dataset) -> xr.Dataset:
    """Units, names and provenance of the variables of :func:`solve`."""
    for var in out.data_vars:
        if var.startswith(("sky_", "top_")):
            out[var].attrs.update(units="sr-1", long_name="radiance per unit solar "
                                  "irradiance normal to the beam (DISORT, scalar)")
        elif var.startswith(("diffuse_", "direct_")):
            out[var].attrs.update(units="1", long_name="downward irradiance on a "
                                  "horizontal surface at the ground per unit solar "
                                  "irradiance normal to the beam")
    for name in ("sun_zenith", "view_zenith", "nadir", "relative_azimuth"):
        out[name].attrs["units"] = "degree"
    out["relative_azimuth"].attrs["description"] = "0: looking toward the Sun's azimuth"
    for where in ("sky", "top", "diffuse_down"):
        out[f"{where}_ground_albedo"].attrs["description"] = (
            f"Lambertian ground of albedo {GROUND_ALBEDO}, 32 streams (the other variables: "
            "black ground)")
    out.attrs.update(source=f"disortpp {metadata.version('disortpp')} (DisORT++)",
                     n_legendre_moments=N_MOMENTS, delta_m="on",
                     intensity_correction="Nakajima-Tanaka",
                     beam="plane-parallel", ground_albedo_run=GROUND_ALBEDO)
    return out


def main(argv=None) -> None:
    """Run the stage named on the command line (``layers`` or ``solve``)."""
    argv = sys.argv[1:] if argv is None else argv
    start = time.perf_counter()
    if argv == ["layers"]:
        ds = layers()
    elif argv == ["solve"]:
        with xr.open_dataset(OUTPUT) as stored:
            base = stored.load()
        keep = [v for v in base.data_vars if v.endswith("_optical_depth")
                or v.startswith("layer_")]
        ds = solve(base[keep])
    else:
        raise SystemExit("usage: generate_disort.py layers | solve")
    ds.attrs[f"wall_time_{argv[0]}_s"] = round(time.perf_counter() - start, 1)
    ds.to_netcdf(OUTPUT)
    print(f"wrote {OUTPUT.name} ({argv[0]}) in {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
