r"""Write the Monte-Carlo reference of the sky at totality (montecarlo_eclipse_sky.nc).

The backward Monte-Carlo of ``generate_montecarlo.py`` (spherical geometry, straight rays,
scalar radiance, black ground, every order) with the Sun's light at every next-event
estimate multiplied by the part of its limb-darkened disc the Moon leaves visible from
that point (:func:`skytorch.scene.solar_eclipse_sky.visible_fraction_at`, the exact
occlusion integral, tested against closed forms in ``tests/test_occlusion.py``). Nothing
else of the eclipse-sky kernels is used: the light scattered into the umbra is found by
the random walk, not by a quadrature over directions and distances.

Cases: the local maximum of the total eclipses of 2017-08-21 at Lowman, Idaho and
2026-08-12 at Burgos, with the observer 1 m above the ground (the Monte-Carlo's
observer) at each site's latitude and longitude; the atmosphere of ``montecarlo_sky.nc``
case ``rayleigh_aerosol`` (U.S. 1976 molecules, no water, Henyey-Greenstein aerosol
g = 0.7, optical depth 0.1 at 550 nm, single-scattering albedo 0.95) with 300 DU of ozone
(the Chappuis band absorbs along the long, high paths that bring light into the umbra).
Views: the zenith (``ZENITH_PHOTONS`` histories) and 60° / 85° from the zenith towards,
across (+90°) and away from the Sun's azimuth; 7 wavelengths 400-700 nm, so that the
zenith luminance can be formed.

Run: ``OMP_NUM_THREADS=1 .venv/bin/python tests/data/ms_reference/generate_eclipse_montecarlo.py``
(``--quick`` for a smoke run that writes nothing unless ``--output`` is given).
"""
from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np
import torch
import xarray as xr

import skytorch as st

HERE = Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("generate_montecarlo",
                                               HERE / "generate_montecarlo.py")
mc = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("generate_montecarlo", mc)   # dataclasses look it up
_spec.loader.exec_module(mc)

#: name, date of the eclipse, latitude [deg], longitude [deg]
SITES = (("lowman_2017", "2017-08-21", 44.08, -115.62),
         ("burgos_2026", "2026-08-12", 42.34, -3.70))
CASE = "rayleigh_aerosol"
OZONE_DU = 300.0
WAVELENGTH_NM = (400.0, 450.0, 500.0, 550.0, 600.0, 650.0, 700.0)
#: views: (view zenith [deg], azimuth from the Sun's azimuth [deg])
VIEWS = [(0.0, 0.0)] + [(vz, az) for vz in (60.0, 85.0) for az in (0.0, 90.0, 180.0)]
SEED = 20261204
#: histories of the zenith view, relative to the others'
ZENITH_PHOTONS_FACTOR = 5


def site_geometry(date: str, lat: float, lon: float):
    """Return the local maximum of the eclipse and its geometry for the observer."""
    from skytorch.scene.geometry import site_geometries

    height = mc.OBSERVER_ALTITUDE_M
    local = st.eclipse.solar_eclipse_local(date, lat, lon, height)
    instant = np.datetime64(local.maximum_time.values.reshape(-1)[0], "ns")
    return instant, site_geometries(instant, [lat], [lon], [height])[0]


def eclipse_weight(geometry, planet_radius_m: float):
    """Return the ``sun_weight`` of the Monte-Carlo: the visible fraction (ray, 1)."""
    from skytorch.scene.solar_eclipse_sky import visible_fraction_at

    observer = np.array([0.0, 0.0, planet_radius_m + mc.OBSERVER_ALTITUDE_M])

    def weight(x):
        points = torch.from_numpy(np.ascontiguousarray(x - observer))
        return visible_fraction_at(geometry, points).numpy()[:, None]

    return weight


def view_directions(geometry) -> tuple[np.ndarray, np.ndarray]:
    """Return unit vectors (view, 3) of ``VIEWS`` and the Sun (3,), horizontal frame."""
    sun = np.asarray(geometry.sun_horizontal_m, float)
    sun = sun / np.linalg.norm(sun)
    sun_azimuth = np.arctan2(sun[1], sun[0])
    views = []
    for vz, az in VIEWS:
        z, a = np.deg2rad(vz), sun_azimuth + np.deg2rad(az)
        views.append([np.sin(z) * np.cos(a), np.sin(z) * np.sin(a), np.cos(z)])
    return np.array(views), sun


def model_inputs(wavelengths_nm):
    """Return the reference's atmosphere, ``wavelengths_nm`` as a tensor and its Sun table.

    For the models compared with the reference (tests, experiments): the skytorch
    atmosphere of case ``CASE`` with ``OZONE_DU`` and a transmittance table of 128 x 32.
    """
    from skytorch.atmosphere.tables import TransmittanceTable

    atmosphere = mc.skytorch_atmosphere(mc.CASES[CASE], OZONE_DU)
    wavelength = torch.tensor(list(wavelengths_nm), dtype=torch.float64)
    table = TransmittanceTable.build(atmosphere, wavelength, cache=False, n_mu=128, n_r=32)
    return atmosphere, wavelength, table


def site_lines(name: str, views=None):
    """Return the geometry of site ``name`` and the zenith and azimuth [rad] of its views.

    ``views``: indices into ``VIEWS`` (default all); azimuths absolute (from north through
    east), as the models take them.
    """
    _, date, lat, lon = next(s for s in SITES if s[0] == name)
    _, geometry = site_geometry(date, lat, lon)
    directions, _ = view_directions(geometry)
    index = list(range(len(VIEWS))) if views is None else list(views)
    zenith = torch.tensor(np.radians([VIEWS[i][0] for i in index]))
    azimuth = torch.tensor(np.arctan2(directions[index, 1], directions[index, 0]))
    return geometry, zenith, azimuth


def compute(n_photons: int, sites=SITES, wavelengths_nm=WAVELENGTH_NM) -> xr.Dataset:
    """Return the radiance per order bin (1, 2, >= 3, total) at totality, with errors."""
    start = time.perf_counter()
    shape = (len(sites), len(wavelengths_nm), len(VIEWS), 4)
    mean, error = np.full(shape, np.nan), np.full(shape, np.nan)
    times, sun_zenith, sun_azimuth = [], [], []
    for i, (name, date, lat, lon) in enumerate(sites):
        instant, geometry = site_geometry(date, lat, lon)
        views, sun = view_directions(geometry)
        times.append(instant)
        sun_zenith.append(np.degrees(np.arccos(sun[2])))
        sun_azimuth.append(np.degrees(np.arctan2(sun[1], sun[0])) % 360.0)
        for j, wl in enumerate(wavelengths_nm):
            rng = np.random.default_rng([SEED, SITES.index(sites[i]), int(wl)])
            opt = mc.optics(mc.CASES[CASE], wl, OZONE_DU)
            table = mc.SunTable(opt)
            weight = eclipse_weight(geometry, opt.planet_radius_m)
            for v, d0 in enumerate(views):
                n_view = n_photons * (ZENITH_PHOTONS_FACTOR if v == 0 else 1)
                res = mc.trace(opt, table, d0, sun[None, :], n_view, rng,
                               sun_weight=weight)
                n = res["n"]
                m = res["sum"][0] / n
                mean[i, j, v] = m
                error[i, j, v] = np.sqrt(np.maximum(res["sum2"][0] / n - m ** 2, 0.0)
                                         / (n - 1))
            print(f"{name} {wl:.0f} nm: {time.perf_counter() - start:.0f} s", flush=True)
    dims = ("site", "wavelength", "view")
    data = {}
    for b, name in enumerate(("order_1", "order_2", "order_3plus", "total")):
        data[name] = (dims, mean[..., b], {"units": "sr-1", "long_name":
                      f"{name} radiance per unit TOA solar irradiance normal to the beam"})
        data[f"{name}_stderr"] = (dims, error[..., b], {"units": "sr-1", "long_name":
                                  f"standard error of {name}"})
    ds = xr.Dataset(data, coords={
        "site": np.array([s[0] for s in sites], dtype="<U32"),
        "date": ("site", [s[1] for s in sites]),
        "latitude": ("site", [s[2] for s in sites], {"units": "degree_north"}),
        "longitude": ("site", [s[3] for s in sites], {"units": "degree_east"}),
        "time": ("site", np.array(times, dtype="datetime64[ns]"),
                 {"long_name": "local maximum (solar_eclipse_local), UTC"}),
        "sun_zenith": ("site", sun_zenith, {"units": "degree"}),
        "sun_azimuth": ("site", sun_azimuth, {"units": "degree"}),
        "wavelength": ("wavelength", np.asarray(wavelengths_nm, float), {"units": "nm"}),
        "view": ("view", np.arange(len(VIEWS))),
        "view_zenith": ("view", [v[0] for v in VIEWS], {"units": "degree"}),
        "photons": ("view", [n_photons * (ZENITH_PHOTONS_FACTOR if v == 0 else 1)
                             for v in range(len(VIEWS))]),
        "relative_azimuth": ("view", [v[1] for v in VIEWS], {"units": "degree",
                             "description": "from the Sun's azimuth"})})
    ds.attrs.update(
        title="Backward Monte-Carlo sky radiance at totality (spherical, scalar, black "
              "ground, the Sun's visible fraction at every next event)",
        seed=SEED, case=CASE, ozone_du=OZONE_DU, aerosol=repr(mc.AEROSOL),
        script="tests/data/ms_reference/generate_eclipse_montecarlo.py",
        date_written=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        skytorch_commit=mc._git_commit(), skytorch_version=st.__version__,
        observer_altitude_m=mc.OBSERVER_ALTITUDE_M, roulette_order=mc.ROULETTE_ORDER,
        max_order=mc.MAX_ORDER, cpu_time_s=round(time.process_time(), 1))
    return ds


def main(argv=None) -> None:
    """Compute the table; ``--quick`` for a smoke run."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="few photons, no file")
    parser.add_argument("--photons", type=int, default=None,
                        help="histories per (site, wavelength, view)")
    parser.add_argument("--site", choices=[s[0] for s in SITES], default=None,
                        help="one site only (parts run separately, then --merge)")
    parser.add_argument("--merge", type=Path, nargs="+", default=None,
                        help="part files to merge into the output")
    parser.add_argument("--output", type=Path, default=None)
    args = parser.parse_args(argv)
    output = args.output or (None if args.quick else HERE / "montecarlo_eclipse_sky.nc")
    if args.merge:
        parts = [xr.open_dataset(path).load() for path in args.merge]
        ds = xr.concat(parts, dim="site", data_vars="minimal", coords="minimal",
                       combine_attrs="drop_conflicts")
        ds.attrs["cpu_time_s"] = round(sum(float(p.attrs["cpu_time_s"]) for p in parts), 1)
        ds.to_netcdf(output)
        print(f"wrote {output}")
        return
    n_photons = args.photons or (400 if args.quick else 40000)
    sites = [s for s in SITES if args.site in (None, s[0])]
    ds = compute(n_photons, sites[:1] if args.quick else sites,
                 WAVELENGTH_NM[:1] if args.quick else WAVELENGTH_NM)
    print(ds[["order_1", "order_2", "order_3plus", "total"]].to_dataframe().to_string())
    print(f"cpu {ds.attrs['cpu_time_s']} s")
    if output is not None:
        ds.to_netcdf(output)
        print(f"wrote {output}")


if __name__ == "__main__":
    main()
