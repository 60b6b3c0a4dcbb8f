"""Sky radiance against DISORT in the plane-parallel limit (issue 14).

The reference ``tests/data/ms_reference/disort_sky.nc`` was written by
``tests/data/ms_reference/generate_disort.py`` with DisORT++ (``disortpp``, a C++
implementation of DISORT) in its own environment, from skytorch's layer optics (U.S. 1976
molecules, Henyey-Greenstein aerosol g = 0.7, single-scattering albedo 0.95, aerosol
optical depth 0, 0.05, 0.3 and 1 at 550 nm; no ozone, no water; black ground), so these
tests check the radiative transfer, not the optics. DISORT is plane-parallel and
skytorch spherical: at the Sun zeniths of the table (30 and 60 deg) and views up to 60 deg
from the vertical the difference is that of single scattering along curved and flat
paths, measured below (<= 0.3 %) for the ground observer. From the top it is larger: a
line of sight leaving 100 km at nadir 60 deg meets the ground at a local zenith angle of
61.6 deg, and spherical single scattering is 3.8-4.7 % above the flat one there
(tests/test_ms_top.py compares the top with sasktran2 in spherical geometry). Radiance per unit solar irradiance normal to the beam
[sr^-1], ground observer looking up and observer at the top (100 km) looking down.
"""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
import torch
import xarray as xr

import skytorch as st

DATA = Path(__file__).parent / "data" / "ms_reference"
TABLE = DATA / "disort_sky.nc"
HAS_SOLVER = importlib.util.find_spec("skytorch.atmosphere.multiple_scattering") is not None
PERCENT = 0.01
#: views compared: up to 60 deg from the vertical (ground) and from the nadir (top)
VIEW_ZENITH_DEG = [0.0, 30.0, 60.0]
NADIR_DEG = [0.0, 30.0, 60.0]
#: molecular scale height and Earth radius of the curvature bound [m]
SCALE_HEIGHT_M, EARTH_RADIUS_M = 8000.0, 6.371e6


@pytest.fixture(scope="module")
def reference() -> xr.Dataset:
    with xr.open_dataset(TABLE) as ds:
        return ds.load()


def _atmosphere(aod) -> st.Atmosphere:
    """Return the atmosphere of the reference (``generate_disort.layers``), batched over AOD."""
    return st.Atmosphere.earth(ozone_du=0.0, precipitable_water_cm=0.0,
                               aerosol_phase_model="henyeygreenstein1941",
                               aerosol_optical_depth=aod, angstrom_alpha=1.3,
                               aerosol_asymmetry=0.7, aerosol_single_scattering_albedo=0.95)


def _plane_parallel_single_scattering(ds: xr.Dataset, sun_zenith_deg: float,
                                      view_zenith_deg: float, azimuth_deg: float):
    r"""Closed-form single scattering at the ground of a stack of homogeneous flat layers.

    Per layer of extinction :math:`\Delta\tau` from optical depth :math:`t_1` (top) to
    :math:`t_2`, source :math:`J = (\tau_R P_R + \tau_a P_{HG}) / (4\pi\Delta\tau)` and
    :math:`L = \sum J\,e^{-T/\mu}\,(e^{-a t_1} - e^{-a t_2}) / (a\mu)` with
    :math:`a = 1/\mu_0 - 1/\mu`; shape (aod, wavelength).
    """
    tau = ds.extinction_optical_depth.values[:, ::-1]          # (aod, layer top first, λ)
    rayleigh = ds.rayleigh_optical_depth.values[:, ::-1]
    aerosol = ds.aerosol_scattering_optical_depth.values[:, ::-1]
    mu0 = math.cos(math.radians(sun_zenith_deg))
    mu = math.cos(math.radians(view_zenith_deg))
    sun = np.array([math.sin(math.radians(sun_zenith_deg)), 0.0, mu0])
    view = np.array([math.sin(math.radians(view_zenith_deg)) * math.cos(math.radians(azimuth_deg)),
                     math.sin(math.radians(view_zenith_deg)) * math.sin(math.radians(azimuth_deg)),
                     mu])
    cosine = float(sun @ view)
    g = 0.7
    phase_r = 0.75 * (1.0 + cosine ** 2)
    phase_a = (1.0 - g * g) / (1.0 + g * g - 2.0 * g * cosine) ** 1.5
    top = np.cumsum(tau, axis=1) - tau
    total = tau.sum(axis=1, keepdims=True)
    source = (rayleigh * phase_r + aerosol * phase_a) / (4.0 * math.pi * tau)
    a = 1.0 / mu0 - 1.0 / mu
    if abs(a) < 1e-12:
        path = tau * np.exp(-total / mu)
    else:
        path = np.exp(-total / mu) * (np.exp(-a * top) - np.exp(-a * (top + tau))) / a
    return (source * path).sum(axis=1) / mu


def test_reference_is_converged(reference):
    """DISORT with 32 and 64 streams agree to 0.1 %; halving every layer changes 0.01 %."""
    for where in ("sky", "top"):
        streams = reference[f"{where}_streams_32"] / reference[f"{where}_streams_64"] - 1
        layers = reference[f"{where}_split_layers"] / reference[f"{where}_streams_32"] - 1
        assert float(abs(streams).max()) < 0.1 * PERCENT
        assert float(abs(layers).max()) < 0.01 * PERCENT
    flux = reference.diffuse_down_streams_32 / reference.diffuse_down_streams_64 - 1
    assert float(abs(flux).max()) < 0.1 * PERCENT


def test_disort_agrees_with_sasktran2_plane_parallel(reference):
    """Two independent codes on the same optics: the radiance leaving the top.

    sasktran2's plane-parallel discrete ordinates (``sasktran2_sky.nc``: skytorch's
    coefficients on its own 0-100 km grid, linear between levels) against DISORT (layers
    integrated by Gauss-Legendre), aerosol τ 0.05, 0.3, 1, Sun 30 and 60 deg, 400 and
    550 nm, nadir 0-60 deg: within 0.5 % (measured 0.22 %; the two codes sample the
    optics differently).
    """
    with xr.open_dataset(DATA / "sasktran2_sky.nc") as ds:
        sasktran = ds.plane_parallel_discrete_ordinates.load()
    sasktran = sasktran.sel(wavelength=reference.wavelength.values,
                            view_zenith=NADIR_DEG).rename(
        aod_pp="aod", sun_zenith_pp="sun_zenith", view_zenith="nadir")
    disort = reference.top_streams_64.sel(aod=sasktran.aod.values, nadir=NADIR_DEG)
    assert float(abs(sasktran / disort - 1).max()) < 0.5 * PERCENT


@pytest.mark.parametrize("sun_zenith_deg", [30.0, 60.0])
def test_direct_single_scattering_is_the_plane_parallel_limit(reference, sun_zenith_deg):
    r"""Spherical single scattering of skytorch against the closed form on DISORT's layers.

    Checks that the shipped layers are skytorch's atmosphere and that the azimuths are read
    alike (the aureole at azimuth 0). Tolerance: 0.1 % plus the curvature of the slant
    paths, :math:`(H/R)(\tan^2\theta_0 + \tan^2\theta)` with H = 8 km, R = 6371 km
    (0.4 % of the slant optical depth at 60 deg); measured 0.08-0.54 % (0.3 % at the zenith
    with the Sun at 60 deg; 1.3 % at 75 deg, not compared).
    """
    from skytorch.atmosphere.scattering import constituent_radiance

    wavelength = torch.tensor(reference.wavelength.values, dtype=torch.float64)
    atm = _atmosphere(torch.tensor(reference.aod.values, dtype=torch.float64))
    one = torch.tensor(1.0, dtype=torch.float64)
    sun = torch.tensor(math.radians(sun_zenith_deg), dtype=torch.float64)
    for view_zenith in VIEW_ZENITH_DEG:
        for azimuth in reference.relative_azimuth.values:
            ours = constituent_radiance(
                atm.constituents(wavelength), torch.tensor(math.radians(view_zenith)),
                torch.tensor(math.radians(azimuth)), sun, 0.0 * one, one, n_samples=512)
            flat = _plane_parallel_single_scattering(reference, sun_zenith_deg, view_zenith,
                                                     azimuth)
            curvature = SCALE_HEIGHT_M / EARTH_RADIUS_M * (
                math.tan(math.radians(sun_zenith_deg)) ** 2
                + math.tan(math.radians(view_zenith)) ** 2)
            np.testing.assert_allclose(ours.numpy(), flat, rtol=0.1 * PERCENT + curvature)


def _solver_radiance(reference: xr.Dataset, resolution=None, direct_single=False,
                     ground_albedo=0.0, tables=None):
    """Return the converged tables on the reference's grid: {"sky", "top"} DataArrays.

    ``direct_single`` replaces the tables' order 1 with the ray-marched single scattering,
    as scenes do. Dims (aod, sun_zenith, wavelength, view_zenith | nadir, relative_azimuth).
    ``tables`` (built for the reference's optical depths and wavelengths) skips the build.
    """
    from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
    from skytorch.atmosphere.scattering import constituent_radiance

    aod = torch.tensor(reference.aod.values, dtype=torch.float64)
    wavelength = torch.tensor(reference.wavelength.values, dtype=torch.float64)
    atm = _atmosphere(aod)
    if tables is None:
        tables = precompute_scattering(atm, wavelength, ground_albedo=ground_albedo,
                                       scattering_orders="converged",
                                       resolution=resolution or TableResolution())
    azimuth = torch.deg2rad(torch.tensor(reference.relative_azimuth.values,
                                         dtype=torch.float64))[None, :, None]
    one = torch.tensor(1.0, dtype=torch.float64)
    out = {}
    for where, name, zenith_deg, altitude in (
            ("sky", "view_zenith", np.array(VIEW_ZENITH_DEG), 0.0),
            ("top", "nadir", 180.0 - np.array(NADIR_DEG), tables.top_altitude_m)):
        zenith = torch.deg2rad(torch.tensor(zenith_deg, dtype=torch.float64))[:, None, None]
        values = []
        for sun_zenith_deg in reference.sun_zenith.values:
            sun = torch.tensor(math.radians(sun_zenith_deg), dtype=torch.float64)
            height = torch.tensor(altitude, dtype=torch.float64)
            value = tables.radiance(height, zenith, azimuth, sun)     # (view, az, aod, λ)
            if direct_single:
                value = value - tables.radiance(height, zenith, azimuth, sun,
                                                scattering_orders=1)
                value = value + constituent_radiance(
                    atm.constituents(wavelength), zenith, azimuth, sun, 0.0 * one, height,
                    n_samples=512)
            values.append(value.detach().permute(2, 3, 0, 1).numpy())
        coords = {"aod": reference.aod.values, "sun_zenith": reference.sun_zenith.values,
                  "wavelength": reference.wavelength.values,
                  name: VIEW_ZENITH_DEG if where == "sky" else NADIR_DEG,
                  "relative_azimuth": reference.relative_azimuth.values}
        out[where] = xr.DataArray(np.stack(values, axis=1), coords=coords,
                                  dims=tuple(coords))
    return out


def solver_errors(reference: xr.Dataset, resolution=None, direct_single=False,
                  ground_albedo=False, tables=None):
    """Relative errors against DISORT: {"sky", "top"} DataArrays.

    Black ground against the 64-stream run; ``ground_albedo=True``: the reference's
    Lambertian ground (``ground_albedo_run`` attribute) against its 32-stream run.
    """
    albedo = float(reference.attrs["ground_albedo_run"]) if ground_albedo else 0.0
    ours = _solver_radiance(reference, resolution, direct_single, albedo, tables)
    run = "ground_albedo" if ground_albedo else "streams_64"
    return {"sky": ours["sky"] / reference[f"sky_{run}"].sel(view_zenith=VIEW_ZENITH_DEG) - 1,
            "top": ours["top"] / reference[f"top_{run}"].sel(nadir=NADIR_DEG) - 1}


#: the coarse tables of the sasktran2 and Monte-Carlo comparisons (seconds to build)
COARSE = dict(n_r=8, n_mu=32, n_mu_s=16, n_phi=6, n_ray=24, n_sphere_mu=6,
              transmittance_r=32, transmittance_mu=128, mu_vertical_weight=0.0,
              r_ground_weight=0.0, sphere_phi_refinement=1, ray_quadrature="trapezoid")


def _max_error(errors, **selection) -> float:
    return max(float(abs(value.sel(**selection)).max()) for value in errors.values())


@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_molecular_and_thin_aerosol_sky_against_disort(reference):
    """Coarse tables, molecules alone and aerosol optical depth 0.05, Sun 30 and 60 deg.

    As scenes add them up: the ray-marched single scattering plus the tables' orders >= 2.
    The sky seen from the ground within 3 % of DISORT at every view (the issue's day-sky
    tolerance; measured 2.4 %); as regression bounds of the coarse tables, the radiance
    leaving the top within 6 % (measured 4.7 %, at nadir 60 deg with the Sun at 60 deg,
    most of it DISORT's flat geometry: the exact spherical single scattering alone is
    3.8-4.7 % above the flat one there; tests/test_ms_top.py holds the top against a
    spherical reference) and at nadir within 1.5 % (measured 1.1 %); 400 and 550 nm. Not
    the issue's 1 % (next test; default tables in docs/multiple_scattering_validation.md).
    """
    from skytorch.atmosphere.multiple_scattering import TableResolution

    errors = solver_errors(reference.sel(aod=[0.0, 0.05]), TableResolution(**COARSE),
                           direct_single=True)
    assert _max_error({"sky": errors["sky"]}) < 3 * PERCENT, errors["sky"].values
    assert _max_error({"top": errors["top"]}) < 6 * PERCENT, errors["top"].values
    assert float(abs(errors["top"].sel(nadir=0.0)).max()) < 1.5 * PERCENT


@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_forward_peak_factored_against_disort(reference):
    """Coarse tables, aerosol optical depth 0.3: the forward peak factored out of the orders.

    The tables alone (``ScatteringTables.radiance``), Sun 30 and 60 deg, 400 and 550 nm,
    every view: within 6 % of DISORT (measured 3.9 %), where the same tables interpolating
    the orders as they are (``forward_peak="none"``) are 23 % off 60 deg from the Sun.
    """
    from skytorch.atmosphere.multiple_scattering import TableResolution

    errors = solver_errors(reference.sel(aod=[0.3]), TableResolution(**COARSE))
    assert float(abs(errors["sky"]).max()) < 6 * PERCENT, errors["sky"].values


@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_lambertian_ground_against_disort(reference):
    """Ground albedo 0.3 (DISORT's Lambertian surface), coarse tables, Sun 30 and 60 deg.

    The tables' total (order 1 with the Sun reflected once by the ground, and the orders
    >= 2 with the ground's reflections). Molecules: the sky within 2 % (measured 1.3 %);
    aerosol optical depth 0.05 within 5 % (measured 4.5 %); regression bounds of the
    coarse tables (default tables: 1.2 / 1.2 / 1.0 %; the former default 0.9 / 1.2 / 2.0 %;
    docs/multiple_scattering_validation.md).
    Aerosol optical depth 0.3, the forward peak factored out of the light from the Sun and
    the ground's light followed apart: within 8 % (measured 5.7 %; 22 % with
    ``forward_peak="none"``). The radiance leaving the top at nadir, where the lit ground
    dominates: within 1.5 % for molecules and 0.05 (measured 0.3 and 1.1 %; 3.2 and 3.3 %
    when the Sun reflected once by the ground was interpolated from the table's nodes),
    within 4 % at 0.3 (measured 3.1 %).
    """
    from skytorch.atmosphere.multiple_scattering import TableResolution

    errors = solver_errors(reference.sel(aod=[0.0, 0.05, 0.3]), TableResolution(**COARSE),
                           ground_albedo=True)
    assert float(abs(errors["sky"].sel(aod=0.0)).max()) < 2 * PERCENT
    assert float(abs(errors["sky"].sel(aod=0.05)).max()) < 5 * PERCENT
    assert float(abs(errors["sky"].sel(aod=0.3)).max()) < 8 * PERCENT
    assert float(abs(errors["top"].sel(aod=[0.0, 0.05], nadir=0.0)).max()) < 1.5 * PERCENT
    assert float(abs(errors["top"].sel(nadir=0.0)).max()) < 4 * PERCENT


@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_diffuse_irradiance_against_disort(reference):
    """The diffuse horizontal irradiance of batched tables against DISORT's diffuse flux.

    Coarse tables batched over the four aerosol optical depths,
    ``ScatteringTables.diffuse_irradiance`` at the ground, Sun 30 and 60 deg, 400 and
    550 nm: molecules and τ 0.05 within 3 % (measured 1.9 %), τ 0.3 within 5 % (measured
    3.4 %); and a member of the batch equals the tables built for it alone.
    """
    from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering

    wavelength = torch.tensor(reference.wavelength.values, dtype=torch.float64)
    aod = torch.tensor(reference.aod.values, dtype=torch.float64)
    resolution = TableResolution(**COARSE)
    batched = precompute_scattering(_atmosphere(aod), wavelength, resolution=resolution,
                                    scattering_orders="converged")
    sun = torch.deg2rad(torch.tensor(reference.sun_zenith.values, dtype=torch.float64))
    ground = torch.tensor(0.0, dtype=torch.float64)
    ours = batched.diffuse_irradiance(ground, sun[:, None])              # (sun, aod, λ)
    assert ours.shape == (2, 4, 2)
    theirs = reference.diffuse_down_streams_64.transpose("sun_zenith", "aod",
                                                         "wavelength").values
    error = np.abs(ours.numpy() / theirs - 1.0)
    assert error[:, :2].max() < 3 * PERCENT, error
    assert error[:, 2].max() < 5 * PERCENT, error
    # the same orders ("converged" stops on the whole batch; its extrapolated remainder
    # is left out by an integer number of orders)
    alone = precompute_scattering(_atmosphere(float(aod[1])), wavelength,
                                  resolution=resolution,
                                  scattering_orders=batched.orders_computed)
    exact = batched.diffuse_irradiance(ground, sun[:, None],
                                       scattering_orders=batched.orders_computed)
    np.testing.assert_allclose(alone.diffuse_irradiance(ground, sun).numpy(),
                               exact[:, 1].numpy(), rtol=1e-10)


@pytest.mark.slow
@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_aerosol_sky_against_disort_within_one_percent():
    """Issue 14: the sky from the ground within 1 % of DISORT for aerosol τ 0.05-1.

    Default tables (24 radii and the exponential ray quadrature since 2026-12-07), 400 and
    550 nm, Sun 30 and 60 deg, view zenith 0-60 deg at relative azimuth 0, 90 and 180 deg.
    The tables alone (``ScatteringTables.radiance``, order 1 looked up too) within the
    issue's 1 %: measured at 400 nm 0.62 / 0.61 % (τ 0.05, Sun 30 / 60 deg), 0.42 / 0.49 %
    (τ 0.3), 0.53 / 0.45 % (τ 1; total optical depth 1.9), at 550 nm 0.90 / 0.93, 0.42 /
    0.80, 0.69 / 0.60 %. On 16 radii with the trapezoid (the default before) 550 nm was
    within 0.97 % and 400 nm 1.14 % off at τ 1; with the exact rays alone on 16 radii 1.54 %
    (docs/multiple_scattering_validation.md, "Exact rays and 24 radii"). The scenes' sum
    (ray-marched order 1 + the tables' orders >= 2, what ``Atmosphere.sky_radiance``
    returns over a black ground) is held within 1.5 %: measured 1.01 / 1.02 % at τ 0.05,
    550 nm (view zenith 60 deg, azimuth 180 deg, too dark: of the size of the sphere's
    shorter slant path, which DISORT's flat geometry does not have), 0.82 % and 0.64 % at
    most at τ 0.3 and 1. The radiance leaving the top is DISORT's flat geometry only at the
    nadir; tests/test_ms_top.py holds it against sasktran2's spherical radiance.
    """
    from skytorch.atmosphere.multiple_scattering import precompute_scattering

    with xr.open_dataset(TABLE) as ds:
        reference = ds.load().sel(aod=[0.05, 0.3, 1.0], wavelength=[400.0, 550.0])
    tables = precompute_scattering(
        _atmosphere(torch.tensor(reference.aod.values, dtype=torch.float64)),
        torch.tensor(reference.wavelength.values, dtype=torch.float64),
        scattering_orders="converged")
    alone = abs(solver_errors(reference, tables=tables)["sky"])
    assert float(alone.max()) < 1 * PERCENT, alone.max(("view_zenith", "relative_azimuth"))
    summed = abs(solver_errors(reference, direct_single=True, tables=tables)["sky"])
    assert float(summed.max()) < 1.5 * PERCENT, summed.max(("view_zenith", "relative_azimuth"))


def gathered_errors(reference: xr.Dataset, resolution, ground_albedo=False, top_reference=None):
    """Relative errors of the final gather against DISORT: {"sky", "top"} DataArrays.

    Per aerosol optical depth (the gather takes scalar parameters): converged tables, the
    tables' order 1 (with the Sun reflected once by the ground) or, over a black ground,
    the ray-marched single scattering, plus
    :func:`skytorch.atmosphere.final_gather.higher_orders_gathered` at its defaults.
    ``top_reference`` (aod, sun_zenith, wavelength, nadir, relative_azimuth): another
    reference for the radiance leaving the top (sasktran2's spherical one).
    """
    from skytorch.atmosphere.final_gather import higher_orders_gathered
    from skytorch.atmosphere.multiple_scattering import precompute_scattering
    from skytorch.atmosphere.scattering import constituent_radiance

    albedo = float(reference.attrs["ground_albedo_run"]) if ground_albedo else 0.0
    run = "ground_albedo" if ground_albedo else "streams_64"
    wavelength = torch.tensor(reference.wavelength.values, dtype=torch.float64)
    azimuth = torch.deg2rad(torch.tensor(reference.relative_azimuth.values,
                                         dtype=torch.float64))[None, :]
    errors = {"sky": [], "top": []}
    for aod in reference.aod.values:
        atm = _atmosphere(float(aod))
        tables = precompute_scattering(atm, wavelength, ground_albedo=albedo,
                                       scattering_orders="converged", resolution=resolution)
        for where, name, zenith_deg, altitude in (
                ("sky", "view_zenith", np.array(VIEW_ZENITH_DEG), 0.0),
                ("top", "nadir", 180.0 - np.array(NADIR_DEG), tables.top_altitude_m)):
            zenith = torch.deg2rad(torch.tensor(zenith_deg, dtype=torch.float64))[:, None]
            height = torch.tensor(altitude, dtype=torch.float64)
            per_sun = []
            for sun_zenith_deg in reference.sun_zenith.values:
                sun = torch.tensor(math.radians(sun_zenith_deg), dtype=torch.float64)
                if albedo:
                    first = tables.radiance(height, zenith, azimuth, sun, scattering_orders=1)
                else:
                    first = constituent_radiance(atm.constituents(wavelength), zenith, azimuth,
                                                 sun, 0.0 * sun, height, n_samples=512)
                ours = first + higher_orders_gathered(tables, atm, height, zenith, azimuth, sun)
                theirs = (top_reference if where == "top" and top_reference is not None
                          else reference[f"{where}_{run}"])
                theirs = theirs.sel(aod=aod, sun_zenith=sun_zenith_deg)
                theirs = theirs.sel({name: VIEW_ZENITH_DEG if where == "sky" else NADIR_DEG})
                theirs = theirs.transpose(name, "relative_azimuth", "wavelength").values
                per_sun.append(ours.numpy() / theirs - 1.0)
            errors[where].append(per_sun)
    dims = ("aod", "sun_zenith", "view", "relative_azimuth", "wavelength")
    return {where: xr.DataArray(np.array(value), dims=dims,
                                coords={"aod": reference.aod.values,
                                        "sun_zenith": reference.sun_zenith.values})
            for where, value in errors.items()}


@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_final_gather_removes_the_aerosol_smearing(reference):
    """The last scattering gathered along the line of sight, coarse tables (issue 14).

    Aerosol optical depth 0.3 and 1, Sun 30 and 60 deg, 400 and 550 nm, nine views: the
    tables alone (scenes' sum) are 3.9 % and 21 % off DISORT in the sky (23 % and 51 %
    with ``forward_peak="none"``); with the final gather the sky is within 5 % at τ 0.3
    (measured 4.0 %; 3.3 % over the former tables) and 20 % at τ 1 (measured 11 %; 2.4 %
    on the default tables), the radiance leaving the top within 5 % at τ 0.3 (measured
    3.5 %). These are regression bounds of the coarse tables; on the default tables the
    gather meets the issue's 1 % at τ 0.05 and 0.3 (0.88 / 0.48 %, next test).
    """
    from skytorch.atmosphere.multiple_scattering import TableResolution

    errors = gathered_errors(reference.sel(aod=[0.3, 1.0]), TableResolution(**COARSE))
    sky, top = abs(errors["sky"]), abs(errors["top"])
    assert float(sky.sel(aod=0.3).max()) < 5 * PERCENT, sky.sel(aod=0.3).values
    assert float(top.sel(aod=0.3).max()) < 5 * PERCENT, top.sel(aod=0.3).values
    assert float(sky.sel(aod=1.0).max()) < 20 * PERCENT, sky.sel(aod=1.0).values


@pytest.mark.slow
@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_final_gather_on_default_tables_against_disort(reference):
    """Default tables (forward peak factored out) and the final gather, the sky from the ground.

    Aerosol optical depth 0.05 and 0.3, Sun 30 and 60 deg, 400 and 550 nm, nine views:
    within the issue's 1 % of DISORT (measured 0.77 / 0.88 % and 0.44 / 0.48 %, Sun 30 /
    60 deg; 1.0 / 0.9 % and 0.8 / 0.9 % on the former default tables, 16 x 64 x 24 x 8
    with 48 samples per ray). τ 1 (1.3 / 2.4 %) is not asserted.

    The radiance leaving the top (nadir 0-60 deg) against sasktran2's spherical radiance
    (``sasktran2_top.nc``; DISORT's flat geometry is not the limit there): τ 0.05 within
    the issue's 1 % (measured 0.32 / 0.54 %); τ 0.3 (1.5 / 1.7 %) is not asserted.
    """
    with xr.open_dataset(DATA / "sasktran2_top.nc") as ds:
        spherical_top = ds.successive_orders.load()
    errors = gathered_errors(reference.sel(aod=[0.05, 0.3]), None, top_reference=spherical_top)
    sky = abs(errors["sky"])
    assert float(sky.max()) < 1 * PERCENT, sky.max(("view", "relative_azimuth")).values
    top = abs(errors["top"].sel(aod=0.05))
    assert float(top.max()) < 1 * PERCENT, top.max(("view", "relative_azimuth")).values


@pytest.mark.skipif(not HAS_SOLVER, reason="multiple-scattering solver not available")
def test_final_gather_over_a_lambertian_ground(reference):
    """Ground albedo 0.3 (DISORT's Lambertian run), coarse tables, final gather.

    The gather adds the ground's reflection of the tables' diffuse irradiance at the end
    of lines of sight that meet the ground. Molecules and aerosol τ 0.05 and 0.3: the sky
    within 5 % (measured 0.9 / 4.1 / 3.9 %; the tables alone 1.2 / 4.2 / 22 %), the
    radiance leaving the top at nadir, where the lit ground dominates, within 4 %
    (measured 3.1 %; tables alone 3.6 %). Regression bounds of the coarse tables.
    """
    from skytorch.atmosphere.multiple_scattering import TableResolution

    errors = gathered_errors(reference.sel(aod=[0.0, 0.05, 0.3]), TableResolution(**COARSE),
                             ground_albedo=True)
    assert float(abs(errors["sky"]).max()) < 5 * PERCENT, errors["sky"].values
    assert float(abs(errors["top"].isel(view=0)).max()) < 4 * PERCENT
