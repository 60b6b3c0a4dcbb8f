r"""Write the sasktran2 reference table of ground-level sky radiance (sasktran2_sky.nc).

Independent radiative-transfer code: sasktran2 (Bourassa, Zawada et al., University of
Saskatchewan), scalar mode (``num_stokes = 1``, no polarisation), no refraction.

The optics are skytorch's, sampled on the sasktran2 altitude grid and handed over as
user-defined (``Manual``) constituents, so that the comparison tests the radiative
transfer and not the optics:

- molecules: ``Atmosphere.scattering_coefficients(...)["rayleigh"]`` (U.S. 1976 density,
  skytorch's Rayleigh cross section), phase :math:`\frac{3}{4}(1 + \cos^2\theta)`
  (Legendre coefficients 1, 0, 1/2: the phase skytorch uses, no depolarisation term);
- aerosol: skytorch's aerosol scattering coefficient with a Henyey-Greenstein phase
  (Legendre coefficients :math:`(2l + 1) g^l`, 64 moments) and the given
  single-scattering albedo;
- absorption: the rest of skytorch's extinction (O2/O2-O2 only: ozone 0 DU, water 0 cm)
  as a pure absorber.

One extra case ("sasktran_rayleigh") uses sasktran2's own Rayleigh (Bates 1984 cross
section and King factor, number density from skytorch's U.S. 1976 pressure and
temperature) to show the size of the optics difference.

Plane-parallel cases (``GeometryType.PlaneParallel``, discrete ordinates) stand in for
DISORT (see README.md). sasktran2 computes only upwelling radiance in plane-parallel
mode, so these are the radiances leaving the top of the atmosphere (observer at 100 km
looking down at the listed nadir angles, black ground).

Run: ``OMP_NUM_THREADS=1 .venv/bin/python tests/data/ms_reference/generate_sasktran2.py``
(about two minutes on one core).

``... generate_sasktran2.py top`` writes ``sasktran2_top.nc``: the radiance leaving the top of
the atmosphere (observer at 100 km looking down at nadir 0, 30, 60 deg) in spherical
geometry, on the optics and Suns of DISORT's table ``disort_sky.nc`` (aerosol optical depth
0, 0.05, 0.3, 1; Sun zenith 30, 60 deg; 400 and 550 nm; black ground and a Lambertian
ground of albedo 0.3): what a spherical model should be held to where DISORT's flat
geometry is not the limit (about 5 minutes on one core).

``... generate_sasktran2.py twilight`` writes ``sasktran2_twilight.nc`` instead: spherical
successive orders with the Sun at 90-102 deg for several ``num_sza`` (the number of
solar-zenith columns of the multiple-scattering source, spread over the range of solar
zenith angles met along the lines of sight) at the seven views of the Monte-Carlo table
``montecarlo_sky.nc``, 400 and 550 nm, plus a sensitivity of the Sun 94 deg Rayleigh row
to the other successive-orders settings (see README.md; about 25 minutes on one core).
"""
from __future__ import annotations

import sys
import time
from importlib import metadata
from pathlib import Path

import numpy as np
import sasktran2 as sk
import torch
import xarray as xr

import skytorch as st

HERE = Path(__file__).resolve().parent
WAVELENGTH_NM = np.array([400.0, 550.0, 700.0])
ALTITUDE_M = np.concatenate([np.arange(0.0, 10000.0, 250.0), np.arange(10000.0, 100001.0,
                                                                        1000.0)])
SUN_ZENITH_DEG = np.array([30.0, 60.0, 80.0, 85.0, 90.0, 92.0, 94.0, 96.0, 98.0, 100.0,
                           102.0, 104.0, 106.0, 108.0])
VIEW_ZENITH_DEG = np.array([0.0, 30.0, 60.0, 75.0, 85.0])
RELATIVE_AZIMUTH_DEG = np.array([0.0, 90.0, 180.0])
OBSERVER_ALTITUDE_M = 1.0
TOA_OBSERVER_ALTITUDE_M = 100000.0
AEROSOL = {"aerosol_optical_depth": 0.1, "angstrom_alpha": 1.3, "aerosol_asymmetry": 0.7,
           "aerosol_single_scattering_albedo": 0.95}
N_MOMENTS = 64
PLANE_PARALLEL_AOD = np.array([0.05, 0.3, 1.0])
PLANE_PARALLEL_SUN_ZENITH_DEG = np.array([30.0, 60.0])
#: the optics, Suns, views and grounds of disort_sky.nc, for sasktran2_top.nc
TOP_AOD = np.array([0.0, 0.05, 0.3, 1.0])
TOP_SUN_ZENITH_DEG = np.array([30.0, 60.0])
TOP_WAVELENGTH_NM = np.array([400.0, 550.0])
TOP_NADIR_DEG = np.array([0.0, 30.0, 60.0])
TOP_GROUND_ALBEDO = 0.3
TOP_NUM_SZA = 5
TWILIGHT_SUN_ZENITH_DEG = np.array([90.0, 94.0, 98.0, 102.0])
TWILIGHT_WAVELENGTH_NM = np.array([400.0, 550.0])
TWILIGHT_NUM_SZA = np.array([1, 8, 16])
#: (view_zenith, relative_azimuth) [deg] of montecarlo_sky.nc's `view` dimension
TWILIGHT_VIEWS = ((0.0, 0.0), (60.0, 0.0), (60.0, 90.0), (60.0, 180.0), (85.0, 0.0),
                  (85.0, 90.0), (85.0, 180.0))
#: other successive-orders settings tried at Sun 94 deg (Rayleigh, num_sza = 1)
TWILIGHT_SETTINGS = {
    "default": ("SuccessiveOrders", {}),
    "legacy_interpolation": ("SuccessiveOrders",
                             {"successive_orders_legacy_interpolation": True}),
    "lebedev_incoming": ("SuccessiveOrders",
                         {"successive_orders_reduced_horizon_quadrature": False}),
    "incoming_outgoing_302": ("SuccessiveOrders", {"num_successive_orders_incoming": 302,
                                                   "num_successive_orders_outgoing": 302}),
    "picard_50_iterations": ("SuccessiveOrders",
                             {"successive_orders_anderson_depth": 0,
                              "successive_orders_relative_tolerance": 0.0,
                              "successive_orders_absolute_tolerance": 0.0}),
    "legacy_source": ("SuccessiveOrdersLegacy", {}),
}


def skytorch_atmosphere(aod: float) -> st.Atmosphere:
    """Build the skytorch atmosphere of the references: U.S. 1976, no ozone, no water."""
    options = dict(AEROSOL, aerosol_optical_depth=aod)
    return st.Atmosphere.earth(ozone_du=0.0, precipitable_water_cm=0.0,
                               aerosol_phase_model="henyeygreenstein1941", **options)


def manual_constituents(atm: st.Atmosphere, wavelength_nm=WAVELENGTH_NM) -> dict:
    """Hand skytorch's optics on the sasktran2 grid over as Manual constituents."""
    altitude = torch.tensor(ALTITUDE_M, dtype=torch.float64)
    wavelength = torch.tensor(np.asarray(wavelength_nm, dtype=float), dtype=torch.float64)
    scattering = atm.scattering_coefficients(altitude, wavelength)
    extinction = atm.extinction_coefficient(altitude, wavelength).numpy()
    rayleigh = scattering["rayleigh"].numpy()
    aerosol_sca = scattering["aerosol"].numpy()
    ssa = float(AEROSOL["aerosol_single_scattering_albedo"])
    aerosol_ext = aerosol_sca / ssa
    absorber = np.clip(extinction - rayleigh - aerosol_ext, 0.0, None)
    shape = (N_MOMENTS, *rayleigh.shape)
    leg_rayleigh = np.zeros(shape)
    leg_rayleigh[0], leg_rayleigh[2] = 1.0, 0.5
    g = float(AEROSOL["aerosol_asymmetry"])
    leg_aerosol = np.stack([np.full(rayleigh.shape, (2 * k + 1) * g ** k)
                            for k in range(N_MOMENTS)])
    out = {"rayleigh": sk.constituent.Manual(rayleigh, np.ones_like(rayleigh), leg_rayleigh),
           "absorber": sk.constituent.Manual(absorber + 1e-30, np.zeros_like(absorber),
                                             np.zeros(shape))}
    if aerosol_ext.max() > 0.0:
        out["aerosol"] = sk.constituent.Manual(aerosol_ext, np.full_like(aerosol_ext, ssa),
                                               leg_aerosol)
    return out


def run(constituents: dict, sun_zenith_deg: float, source, *, plane_parallel=False,
        state=None, num_sza=1, wavelength_nm=WAVELENGTH_NM, views=None,
        config_options=None, from_top=False, ground_albedo=0.0) -> np.ndarray:
    """Radiance (wavelength, view_zenith, relative_azimuth) per unit solar irradiance.

    ``views``: optional list of (view_zenith, relative_azimuth) pairs [deg]; the result
    is then (wavelength, view). ``num_sza``: sasktran2's number of solar-zenith
    discretisations of the multiple-scattering source (1: the reference point only).
    ``wavelength_nm`` must be the wavelengths the constituents were built for.
    ``config_options``: further ``sasktran2.Config`` attributes to set (name: value).
    ``from_top``: the observer at 100 km looking down, ``view_zenith`` read as the nadir
    angle (always so in plane-parallel geometry, which computes only upwelling radiance).
    ``ground_albedo``: Lambertian albedo of the ground.
    """
    wavelength_nm = np.asarray(wavelength_nm, dtype=float)
    config = sk.Config()
    config.num_stokes = 1
    config.num_threads = 1
    config.num_sza = num_sza
    config.multiple_scatter_source = source
    config.num_streams = 16
    config.num_singlescatter_moments = N_MOMENTS
    if source == sk.MultipleScatterSource.SuccessiveOrders:
        config.num_successive_orders_iterations = 50
    for name, value in (config_options or {}).items():
        setattr(config, name, value)
    cos_sza = float(np.cos(np.deg2rad(sun_zenith_deg)))
    geometry = sk.Geometry1D(
        cos_sza=cos_sza, solar_azimuth=0.0, earth_radius_m=st.Atmosphere.earth().planet_radius_m,
        altitude_grid_m=ALTITUDE_M, interpolation_method=sk.InterpolationMethod.LinearInterpolation,
        geometry_type=(sk.GeometryType.PlaneParallel if plane_parallel
                       else sk.GeometryType.Spherical))
    viewing = sk.ViewingGeometry()
    pairs = (views if views is not None
             else [(vz, az) for vz in VIEW_ZENITH_DEG for az in RELATIVE_AZIMUTH_DEG])
    for vz, az in pairs:
        cos_view = float(np.cos(np.deg2rad(vz)))
        down = plane_parallel or from_top
        viewing.add_ray(sk.SolarAnglesObserverLocation(
            cos_sza, float(np.deg2rad(az)), -cos_view if down else cos_view,
            TOA_OBSERVER_ALTITUDE_M if down else OBSERVER_ALTITUDE_M))
    atmo = sk.Atmosphere(geometry, config, wavelengths_nm=wavelength_nm)
    if state is not None:
        atmo.pressure_pa, atmo.temperature_k = state
    atmo.surface.albedo[:] = ground_albedo
    for name, constituent in constituents.items():
        atmo[name] = constituent
    radiance = sk.Engine(config, geometry, viewing).calculate_radiance(atmo)
    values = radiance["radiance"].values[:, :, 0]
    if views is not None:
        return values.reshape(len(wavelength_nm), len(pairs))
    return values.reshape(len(wavelength_nm), len(VIEW_ZENITH_DEG),
                          len(RELATIVE_AZIMUTH_DEG))


def spherical(dims) -> dict:
    """Spherical runs: single scattering and successive orders (and DO for the day)."""
    cases = {"rayleigh": 0.0, "rayleigh_aerosol": float(AEROSOL["aerosol_optical_depth"])}
    single, multiple, discrete = (np.full((len(cases), len(SUN_ZENITH_DEG),
                                           len(WAVELENGTH_NM), len(VIEW_ZENITH_DEG),
                                           len(RELATIVE_AZIMUTH_DEG)), np.nan)
                                  for _ in range(3))
    for i, aod in enumerate(cases.values()):
        constituents = manual_constituents(skytorch_atmosphere(aod))
        for j, sza in enumerate(SUN_ZENITH_DEG):
            single[i, j] = run(constituents, sza, sk.MultipleScatterSource.NoSource)
            multiple[i, j] = run(constituents, sza, sk.MultipleScatterSource.SuccessiveOrders)
            if sza < 89.0:
                discrete[i, j] = run(constituents, sza,
                                     sk.MultipleScatterSource.DiscreteOrdinates)
    return xr.Dataset(
        {"single_scattering": (dims, single), "successive_orders": (dims, multiple),
         "discrete_ordinates": (dims, discrete)},
        coords={"case": list(cases), "aerosol_optical_depth": ("case", list(cases.values()))})


def own_rayleigh() -> xr.Dataset:
    """sasktran2's own Rayleigh (Bates 1984) on skytorch's U.S. 1976 p and T."""
    atm = skytorch_atmosphere(0.0)
    altitude = torch.tensor(ALTITUDE_M, dtype=torch.float64)
    state = (atm.pressure_pa(altitude).numpy(), atm.temperature_k(altitude).numpy())
    sza = SUN_ZENITH_DEG[:2]
    values = np.stack([run({"rayleigh": sk.constituent.Rayleigh()}, z,
                           sk.MultipleScatterSource.SuccessiveOrders, state=state) for z in sza])
    return xr.Dataset({"sasktran_rayleigh": (("sun_zenith_own", "wavelength", "view_zenith",
                                              "relative_azimuth"), values)},
                      coords={"sun_zenith_own": sza})


def plane_parallel() -> xr.Dataset:
    """Plane-parallel discrete ordinates (the DISORT stand-in): upwelling at the top."""
    dims = ("aod_pp", "sun_zenith_pp", "wavelength", "view_zenith", "relative_azimuth")
    total = np.zeros([len(PLANE_PARALLEL_AOD), len(PLANE_PARALLEL_SUN_ZENITH_DEG),
                      len(WAVELENGTH_NM), len(VIEW_ZENITH_DEG), len(RELATIVE_AZIMUTH_DEG)])
    single = np.zeros_like(total)
    for i, aod in enumerate(PLANE_PARALLEL_AOD):
        constituents = manual_constituents(skytorch_atmosphere(float(aod)))
        for j, sza in enumerate(PLANE_PARALLEL_SUN_ZENITH_DEG):
            total[i, j] = run(constituents, sza, sk.MultipleScatterSource.DiscreteOrdinates,
                              plane_parallel=True)
            single[i, j] = run(constituents, sza, sk.MultipleScatterSource.NoSource,
                               plane_parallel=True)
    return xr.Dataset({"plane_parallel_discrete_ordinates": (dims, total),
                       "plane_parallel_single_scattering": (dims, single)},
                      coords={"aod_pp": PLANE_PARALLEL_AOD,
                              "sun_zenith_pp": PLANE_PARALLEL_SUN_ZENITH_DEG})


def main() -> None:
    start = time.perf_counter()
    dims = ("case", "sun_zenith", "wavelength", "view_zenith", "relative_azimuth")
    ds = xr.merge([spherical(dims), own_rayleigh(), plane_parallel()])
    ds = ds.assign_coords(sun_zenith=SUN_ZENITH_DEG, wavelength=WAVELENGTH_NM,
                          view_zenith=VIEW_ZENITH_DEG, relative_azimuth=RELATIVE_AZIMUTH_DEG)
    for name in ds.data_vars:
        ds[name].attrs.update(units="sr-1", long_name=f"{name} radiance per unit TOA solar "
                              "irradiance normal to the beam (sasktran2, scalar)")
    for name in ("sun_zenith", "view_zenith", "relative_azimuth", "sun_zenith_own",
                 "sun_zenith_pp"):
        ds[name].attrs["units"] = "degree"
    ds["relative_azimuth"].attrs["description"] = "0: looking toward the Sun's azimuth"
    ds["wavelength"].attrs["units"] = "nm"
    ds.attrs.update(
        title="sasktran2 reference sky radiance for skytorch multiple scattering",
        source=f"sasktran2 {metadata.version('sasktran2')}, skytorch {st.__version__} optics",
        observer_altitude_m=OBSERVER_ALTITUDE_M, ground_albedo=0.0,
        altitude_grid_m=ALTITUDE_M, n_legendre_moments=N_MOMENTS, num_streams=16,
        successive_orders_iterations=50, aerosol=repr(AEROSOL), ozone_du=0.0,
        precipitable_water_cm=0.0, refraction="none", polarisation="none (num_stokes=1)",
        generator="tests/data/ms_reference/generate_sasktran2.py",
        wall_time_s=round(time.perf_counter() - start, 1))
    ds.to_netcdf(HERE / "sasktran2_sky.nc")
    print(f"wrote sasktran2_sky.nc in {time.perf_counter() - start:.0f} s")


def top() -> None:
    """Write sasktran2_top.nc: spherical radiance leaving the top, on DISORT's cases."""
    start = time.perf_counter()
    views = [(nadir, az) for nadir in TOP_NADIR_DEG for az in RELATIVE_AZIMUTH_DEG]
    shape = (len(TOP_AOD), len(TOP_SUN_ZENITH_DEG), len(TOP_WAVELENGTH_NM),
             len(TOP_NADIR_DEG), len(RELATIVE_AZIMUTH_DEG))
    values = {name: np.full(shape, np.nan) for name in (
        "single_scattering", "successive_orders", "discrete_ordinates",
        "successive_orders_ground_albedo")}
    sources = {"single_scattering": sk.MultipleScatterSource.NoSource,
               "successive_orders": sk.MultipleScatterSource.SuccessiveOrders,
               "discrete_ordinates": sk.MultipleScatterSource.DiscreteOrdinates,
               "successive_orders_ground_albedo": sk.MultipleScatterSource.SuccessiveOrders}
    for i, aod in enumerate(TOP_AOD):
        constituents = manual_constituents(skytorch_atmosphere(float(aod)), TOP_WAVELENGTH_NM)
        for j, sza in enumerate(TOP_SUN_ZENITH_DEG):
            for name, source in sources.items():
                albedo = TOP_GROUND_ALBEDO if name.endswith("ground_albedo") else 0.0
                if albedo and aod > 0.3:
                    continue                    # DISORT's bright-ground run stops at 0.3
                values[name][i, j] = run(
                    constituents, sza, source, num_sza=TOP_NUM_SZA, from_top=True,
                    wavelength_nm=TOP_WAVELENGTH_NM, views=views, ground_albedo=albedo,
                ).reshape(shape[2:])
    dims = ("aod", "sun_zenith", "wavelength", "nadir", "relative_azimuth")
    ds = xr.Dataset(
        {name: (dims, value, {"units": "sr-1", "long_name": f"{name} radiance leaving the "
                              "top per unit TOA solar irradiance normal to the beam "
                              "(sasktran2, scalar, spherical)"})
         for name, value in values.items()},
        coords={"aod": ("aod", TOP_AOD, {"long_name": "aerosol optical depth at 550 nm"}),
                "sun_zenith": ("sun_zenith", TOP_SUN_ZENITH_DEG, {"units": "degree"}),
                "wavelength": ("wavelength", TOP_WAVELENGTH_NM, {"units": "nm"}),
                "nadir": ("nadir", TOP_NADIR_DEG, {"units": "degree"}),
                "relative_azimuth": ("relative_azimuth", RELATIVE_AZIMUTH_DEG, {
                    "units": "degree", "description": "0: looking toward the Sun's azimuth"})})
    ds.attrs.update(
        title="sasktran2 spherical radiance leaving the top on the cases of disort_sky.nc",
        source=f"sasktran2 {metadata.version('sasktran2')}, skytorch {st.__version__} optics",
        observer_altitude_m=TOA_OBSERVER_ALTITUDE_M, ground_albedo_run=TOP_GROUND_ALBEDO,
        sun_angles="at the observer (100 km), as skytorch's tables take them",
        altitude_grid_m=ALTITUDE_M, n_legendre_moments=N_MOMENTS, num_streams=16,
        num_sza=TOP_NUM_SZA, successive_orders_iterations=50, aerosol=repr(AEROSOL),
        ozone_du=0.0, precipitable_water_cm=0.0, refraction="none",
        polarisation="none (num_stokes=1)", num_threads=1,
        generator="tests/data/ms_reference/generate_sasktran2.py top",
        wall_time_s=round(time.perf_counter() - start, 1))
    ds.to_netcdf(HERE / "sasktran2_top.nc")
    print(f"wrote sasktran2_top.nc in {time.perf_counter() - start:.0f} s")


def twilight() -> None:
    """Write sasktran2_twilight.nc: successive orders vs num_sza below the horizon."""
    start = time.perf_counter()
    cases = {"rayleigh": 0.0, "rayleigh_aerosol": float(AEROSOL["aerosol_optical_depth"])}
    wavelength = TWILIGHT_WAVELENGTH_NM
    shape = (len(cases), len(TWILIGHT_SUN_ZENITH_DEG), len(wavelength), len(TWILIGHT_VIEWS))
    multiple = np.full((len(TWILIGHT_NUM_SZA), *shape), np.nan)
    single = np.full(shape, np.nan)
    seconds = np.full(multiple.shape[:3], np.nan)
    settings = np.full((len(TWILIGHT_SETTINGS), len(wavelength), len(TWILIGHT_VIEWS)), np.nan)
    settings_seconds = np.full(len(TWILIGHT_SETTINGS), np.nan)
    so = sk.MultipleScatterSource.SuccessiveOrders
    for i, aod in enumerate(cases.values()):
        constituents = manual_constituents(skytorch_atmosphere(aod), wavelength)
        if aod == 0.0:
            for k, (source, options) in enumerate(TWILIGHT_SETTINGS.values()):
                tick = time.perf_counter()
                settings[k] = run(constituents, 94.0, getattr(sk.MultipleScatterSource, source),
                                  wavelength_nm=wavelength, views=TWILIGHT_VIEWS,
                                  config_options=options)
                settings_seconds[k] = time.perf_counter() - tick
        for j, sza in enumerate(TWILIGHT_SUN_ZENITH_DEG):
            single[i, j] = run(constituents, sza, sk.MultipleScatterSource.NoSource,
                               wavelength_nm=wavelength, views=TWILIGHT_VIEWS)
            for n, num_sza in enumerate(TWILIGHT_NUM_SZA):
                tick = time.perf_counter()
                multiple[n, i, j] = run(constituents, sza, so, num_sza=int(num_sza),
                                        wavelength_nm=wavelength, views=TWILIGHT_VIEWS)
                seconds[n, i, j] = time.perf_counter() - tick
                print(f"{list(cases)[i]} Sun {sza:g} num_sza {num_sza}: "
                      f"{seconds[n, i, j]:.0f} s", flush=True)
    dims = ("case", "sun_zenith", "wavelength", "view")
    long_name = ("radiance per unit TOA solar irradiance normal to the beam (sasktran2, "
                 "scalar, ground observer 1 m up)")
    ds = xr.Dataset(
        {"successive_orders": (("num_sza", *dims), multiple, {
            "units": "sr-1", "long_name": f"successive-orders {long_name}",
            "description": "spherical successive orders (MultipleScatterSource."
                           "SuccessiveOrders, 50 iterations at most), the multiple-scattering "
                           "source on num_sza solar-zenith columns spaced linearly in "
                           "cos(solar zenith) over the range met along the lines of sight "
                           "(num_sza = 1: the observer's solar zenith everywhere)"}),
         "single_scattering": (dims, single, {
             "units": "sr-1", "long_name": f"single-scattering {long_name}",
             "description": "MultipleScatterSource.NoSource"}),
         "wall_time": (("num_sza", "case", "sun_zenith"), seconds, {
             "units": "s", "long_name": "wall time of one successive-orders run",
             "description": "2 wavelengths, 7 lines of sight, one thread"}),
         "settings_sensitivity": (("setting", "wavelength", "view"), settings, {
             "units": "sr-1", "long_name": f"successive-orders {long_name}",
             "description": "case rayleigh, Sun zenith 94 deg, num_sza = 1, one "
                            "successive-orders setting changed per row (see the global "
                            "attribute settings_sensitivity)"}),
         "settings_wall_time": (("setting",), settings_seconds, {
             "units": "s", "long_name": "wall time of one settings_sensitivity run"})},
        coords={"num_sza": TWILIGHT_NUM_SZA, "case": list(cases),
                "aerosol_optical_depth": ("case", list(cases.values())),
                "sun_zenith": ("sun_zenith", TWILIGHT_SUN_ZENITH_DEG, {"units": "degree"}),
                "wavelength": ("wavelength", wavelength, {"units": "nm"}),
                "view": np.arange(len(TWILIGHT_VIEWS)),
                "view_zenith": ("view", [v[0] for v in TWILIGHT_VIEWS], {"units": "degree"}),
                "relative_azimuth": ("view", [v[1] for v in TWILIGHT_VIEWS], {
                    "units": "degree", "description": "0: looking toward the Sun's azimuth"}),
                "setting": list(TWILIGHT_SETTINGS)})
    ds.attrs.update(
        title="sasktran2 twilight sky radiance for several solar-zenith source columns",
        source=f"sasktran2 {metadata.version('sasktran2')}, skytorch {st.__version__} optics",
        observer_altitude_m=OBSERVER_ALTITUDE_M, ground_albedo=0.0,
        altitude_grid_m=ALTITUDE_M, n_legendre_moments=N_MOMENTS, num_streams=16,
        successive_orders_iterations=50, num_successive_orders_incoming=110,
        num_successive_orders_outgoing=110, successive_orders_relative_tolerance=1e-6,
        successive_orders_anderson_depth=3, aerosol=repr(AEROSOL), ozone_du=0.0,
        precipitable_water_cm=0.0, refraction="none", polarisation="none (num_stokes=1)",
        num_threads=1, views="those of montecarlo_sky.nc",
        settings_sensitivity=repr(TWILIGHT_SETTINGS),
        generator="tests/data/ms_reference/generate_sasktran2.py twilight",
        wall_time_s=round(time.perf_counter() - start, 1))
    ds.to_netcdf(HERE / "sasktran2_twilight.nc")
    print(f"wrote sasktran2_twilight.nc in {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    if sys.argv[1:] == ["twilight"]:
        twilight()
    elif sys.argv[1:] == ["top"]:
        top()
    elif sys.argv[1:]:
        sys.exit(f"usage: {sys.argv[0]} [twilight | top]")
    else:
        main()
