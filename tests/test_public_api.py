"""The public API contract of DESIGN.md ("Public API", "Datasets").

For ephemeris, stars, moon, sweeps and Dataset I/O: names, signatures, dimensions, units, CF
metadata and the netCDF round trip.

References for the numbers checked here (independent of the code):

* Sirius (HIP 32349): ICRS α = 06h45m08.917s, δ = −16°42′58.02″ at epoch J2000 (SIMBAD,
  from Hipparcos 2, van Leeuwen 2007, doi:10.1051/0004-6361:20078357), V = −1.46 (Yale
  Bright Star Catalogue).
* Obliquity of the ecliptic 23.4393° (IAU 2006, J2000): the Sun's declination at the June
  solstice.
* Refraction of the standard atmosphere (n − 1 = 2.77e-4 at the ground, DESIGN.md):
  R = (n − 1) tan z to first order (Smart 1977, Textbook on Spherical Astronomy, §54).
* Moon V magnitude against phase angle: Krisciunas & Schaefer 1991, eq. 9,
  doi:10.1086/132921.
"""

from __future__ import annotations

import importlib
import inspect
import math
import subprocess
import sys

import numpy as np
import pytest
import torch
import xarray as xr

import skytorch as st
from skytorch.constants import ARCSECOND, DEGREE, MAG

ARCMINUTE = 60.0 * ARCSECOND
TIMES = ["2025-09-07T20:00", "2025-09-07T22:00"]
SITE = {"lat_deg": 52.5, "lon_deg": 13.4}
GLOBAL_ATTRIBUTES = ("Conventions", "title", "source", "history", "references", "parameters")


def _parameters(fn):
    return {name: p.default for name, p in inspect.signature(fn).parameters.items()}


def assert_cf_metadata(ds: xr.Dataset) -> None:
    """Every variable and coordinate documented; global attributes complete."""
    for key in GLOBAL_ATTRIBUTES:
        assert ds.attrs.get(key), f"global attribute {key!r} missing"
    assert ds.attrs["Conventions"] == "CF-1.10"
    assert st.__version__ in ds.attrs["source"]
    for dim in ds.dims:
        assert dim in ds.coords, f"dimension {dim!r} has no coordinate"
    for name, var in ds.variables.items():
        attrs = var.attrs
        assert attrs.get("long_name") and attrs.get("description"), name
        if np.issubdtype(var.dtype, np.datetime64):
            # units of datetime64 are written by the netCDF encoder ("... since ...")
            assert attrs.get("standard_name") == "time"
        else:
            assert attrs.get("units"), f"{name} has no units"
        if attrs.get("units") == "degree":
            finite = np.asarray(var.values, dtype=float)
            assert np.all(np.abs(finite[np.isfinite(finite)]) <= 360.0), name


def assert_round_trip(ds: xr.Dataset, tmp_path) -> xr.Dataset:
    path = st.to_netcdf(ds, tmp_path / "round_trip.nc")
    back = st.open_dataset(path)
    assert set(back.variables) == set(ds.variables)
    for name, var in ds.variables.items():
        np.testing.assert_array_equal(back[name].values, var.values, err_msg=name)
        for key in ("units", "long_name", "description", "standard_name"):
            assert back[name].attrs.get(key) == var.attrs.get(key), (name, key)
        assert back[name].dims == var.dims
    for key in GLOBAL_ATTRIBUTES:
        assert back.attrs[key] == ds.attrs[key]
    if "time" in back.coords:
        assert back.time.dtype == np.dtype("datetime64[ns]")
        assert "since" in back.time.encoding.get("units", "")
    return back


# --------------------------------------------------------------------------- top level


def test_version_and_top_level_names():
    from importlib.metadata import version

    assert st.__version__ == version("skytorch")
    for name in ("ephemeris", "stars", "moon", "spectrum", "dataset", "sweep", "to_netcdf",
                 "open_dataset"):
        assert hasattr(st, name), name
    assert st.to_netcdf is st.dataset.to_netcdf
    assert st.open_dataset is st.dataset.open_dataset


def test_cli_version(capsys):
    from skytorch.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.strip() == f"skytorch {st.__version__}"


def test_cli_version_as_a_module():
    out = subprocess.run([sys.executable, "-m", "skytorch", "--version"], check=True,
                         capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == f"skytorch {st.__version__}"


# --------------------------------------------------------------------------- ephemeris


def test_sun_moon_signature():
    params = _parameters(st.ephemeris.sun_moon)
    assert list(params)[:4] == ["times", "lat_deg", "lon_deg", "elevation_m"]
    assert params["lat_deg"] is None and params["lon_deg"] is None
    assert params["elevation_m"] == 0.0


def test_sun_moon_dataset(tmp_path):
    geocentric = st.ephemeris.sun_moon(["2024-06-20T20:51Z"])
    assert set(geocentric.data_vars) == {"sun_ra", "sun_dec", "sun_distance", "moon_ra",
                                         "moon_dec", "moon_distance"}
    ds = st.ephemeris.sun_moon(["2024-06-20T20:51Z", "2024-06-21T00:00Z"], 48.0, 11.0)
    assert set(ds.data_vars) == set(geocentric.data_vars) | {
        "sun_altitude", "sun_azimuth", "moon_altitude", "moon_azimuth"}
    assert dict(ds.sizes) == {"time": 2}
    for name in ds.data_vars:
        assert ds[name].dims == ("time",)
        expected = "m" if name.endswith("distance") else "degree"
        assert ds[name].attrs["units"] == expected, name
    # the June solstice (2024-06-20 20:51 UTC): declination = obliquity
    assert abs(float(geocentric.sun_dec[0]) - 23.4393) < 0.01
    assert_cf_metadata(ds)
    assert_round_trip(ds, tmp_path)


# --------------------------------------------------------------------------- stars

CATALOG_UNITS = {"hip": "1", "ra": "degree", "dec": "degree", "vmag": "mag", "bv": "mag",
                 "pm_ra": "mas yr-1", "pm_dec": "mas yr-1", "parallax": "mas"}


@pytest.fixture(scope="module")
def catalog():
    return st.stars.bright_stars(limit_magnitude=2.0)


def test_bright_stars_signature_and_catalogue(catalog, tmp_path):
    assert _parameters(st.stars.bright_stars)["limit_magnitude"] == 6.5
    assert set(catalog.dims) == {"star"}
    for name, units in CATALOG_UNITS.items():
        assert catalog[name].dims == ("star",), name
        assert catalog[name].attrs["units"] == units, name
    assert float(catalog.vmag.max()) <= 2.0
    sirius = catalog.where(catalog.hip == 32349, drop=True)
    assert sirius.sizes["star"] == 1
    ra_ref = 15.0 * (6.0 + 45.0 / 60.0 + 8.917 / 3600.0)
    dec_ref = -(16.0 + 42.0 / 60.0 + 58.02 / 3600.0)
    assert abs(float(sirius.ra[0]) - ra_ref) * DEGREE < 0.05 * ARCSECOND
    assert abs(float(sirius.dec[0]) - dec_ref) * DEGREE < 0.05 * ARCSECOND
    assert abs(float(sirius.vmag[0]) - (-1.46)) < 0.01 * MAG
    assert_cf_metadata(catalog)
    assert_round_trip(catalog, tmp_path)


def test_observe_signature():
    params = _parameters(st.stars.observe)
    assert list(params)[:4] == ["catalog", "times", "lat_deg", "lon_deg"]
    assert params["elevation_m"] == 0.0
    assert params["atmosphere"] is None
    assert params["refraction"] is True


@pytest.fixture(scope="module")
def observations(catalog):
    return (st.stars.observe(catalog, TIMES, **SITE),
            st.stars.observe(catalog, TIMES, **SITE, refraction=False))


def test_observe_dataset(catalog, observations, tmp_path):
    ds, _ = observations
    assert dict(ds.sizes)["time"] == 2 and dict(ds.sizes)["star"] == catalog.sizes["star"]
    for name, units in {"altitude": "degree", "azimuth": "degree", "magnitude": "mag",
                        "airmass": "1"}.items():
        assert ds[name].dims == ("time", "star"), name
        assert ds[name].attrs["units"] == units, name
        assert np.all(np.isfinite(ds[name].values)), name
    assert "color" in ds and ds.color.dims[-1] == "channel" and ds.sizes["channel"] == 3
    assert np.all((ds.color.values >= 0.0) & (ds.color.values <= 1.0))
    assert np.all((ds.azimuth.values >= 0.0) & (ds.azimuth.values < 360.0))
    up = ds.altitude.values > 20.0
    # extinction only dims: magnitude after extinction is fainter than above the atmosphere
    assert np.all(ds.magnitude.values[up] > np.broadcast_to(ds.vmag.values, up.shape)[up])
    assert_cf_metadata(ds)
    assert_round_trip(ds, tmp_path)


def test_observe_refraction_switch(observations):
    refracted, geometric = observations
    h = geometric.altitude.values
    up = h > 20.0
    assert up.sum() >= 5
    bend = (refracted.altitude.values - h)[up] * DEGREE
    zenith = (90.0 - h[up]) * DEGREE
    # first-order refraction (n − 1) tan z of the standard atmosphere (n − 1 = 2.77e-4)
    np.testing.assert_allclose(bend, 2.77e-4 * np.tan(zenith), rtol=0, atol=3 * ARCSECOND)
    np.testing.assert_array_equal(refracted.azimuth.values, geometric.azimuth.values)


# --------------------------------------------------------------------------- moon


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_moon_magnitude(dtype):
    assert list(_parameters(st.moon.magnitude))[0] == "phase_angle_rad"
    alpha_deg = torch.tensor([0.0, 45.0, 90.0, 120.0], dtype=dtype)
    m = st.moon.magnitude(alpha_deg * DEGREE)
    assert m.dtype == dtype and m.shape == alpha_deg.shape
    ks1991 = -12.73 + 0.026 * alpha_deg.double() + 4e-9 * alpha_deg.double() ** 4
    assert float((m.double() - ks1991).abs().max()) < 0.3 * MAG


def test_moon_datasets(tmp_path):
    geometry = st.moon.moon_geometry(TIMES, **SITE)
    assert geometry.magnitude.attrs["units"] == "mag"
    assert_cf_metadata(geometry)
    assert_round_trip(geometry, tmp_path)
    image = st.moon.moon_disc_image(60.0, n_pixels=16)
    assert image.radiance.dims == ("y", "x", "wavelength")
    assert_cf_metadata(image)
    assert_round_trip(image, tmp_path)


def test_reflectance_function_and_submodule():
    """``st.moon.reflectance`` is the submodule, callable as its function of that name."""
    module = importlib.import_module("skytorch.moon.reflectance")
    assert st.moon.reflectance is module
    assert inspect.ismodule(module) and callable(module)
    from skytorch.moon.reflectance import HAPKE_PARAMETERS, albedo, reflectance

    assert inspect.isfunction(reflectance) and albedo is st.moon.albedo
    assert "helfenstein1987" in HAPKE_PARAMETERS
    import skytorch.moon.reflectance as aliased

    assert aliased is module
    from skytorch.moon import reflectance as from_package

    assert from_package is module
    mu0, mu, g = torch.tensor([0.3, 0.9]), torch.tensor([0.8, 0.5]), torch.tensor([0.4, 1.2])
    torch.testing.assert_close(module(mu0, mu, g, model="lommel_seeliger"),
                               reflectance(mu0, mu, g, model="lommel_seeliger"), rtol=0, atol=0)
    params = _parameters(st.moon.reflectance)
    assert list(params)[:3] == ["mu0", "mu", "phase_angle_rad"]
    assert params["model"] == "hapke2012" and params["wavelength_nm"] is None
    # lit at normal incidence: positive; Sun below the local horizon (μ0 < 0): exactly 0
    r = st.moon.reflectance(torch.tensor([1.0, -0.1]), torch.tensor([1.0, 1.0]),
                            torch.tensor([0.0, 0.0]))
    assert float(r[0]) > 0.0 and float(r[1]) == 0.0


# --------------------------------------------------------------------------- sweep


def test_sweep_contract(tmp_path):
    params = inspect.signature(st.sweep).parameters
    assert list(params)[0] == "fn"
    assert any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())
    ds = st.sweep(lambda turbidity, wavelength_nm: torch.tensor(turbidity * wavelength_nm),
                  turbidity=[1.0, 2.0, 3.0], wavelength_nm=[440.0, 550.0], progress=False)
    assert ds["result"].dims == ("turbidity", "wavelength_nm")
    np.testing.assert_array_equal(ds["result"].values,
                                  np.outer([1.0, 2.0, 3.0], [440.0, 550.0]))
    assert ds.wavelength_nm.attrs["units"] == "nm"
    assert_cf_metadata(ds)
    assert_round_trip(ds, tmp_path)


def test_angles_in_datasets_are_degrees(observations):
    """Radian-valued angles would stay within ±2π; the apparent sky spans degrees."""
    ds, _ = observations
    assert float(ds.azimuth.max()) - float(ds.azimuth.min()) > 2.0 * math.pi


def test_sweep_attribute_is_the_callable_module():
    import importlib

    import skytorch as st

    sweep_attribute = st.sweep
    module = importlib.import_module("skytorch.sweep")
    assert sweep_attribute is module and callable(sweep_attribute)
    import skytorch.sweep as imported

    assert imported is module
