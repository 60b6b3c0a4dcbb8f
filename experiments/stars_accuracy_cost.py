"""Accuracy versus cost of star positions and magnitudes.

Four questions, each answered against an independent or converged reference:

1. Positions — which corrections matter? Apparent altitude/azimuth of Hipparcos stars at
   times 1900–2050 against skyfield's ``observe().apparent().altaz()``: the full model
   (float64 and float32), without aberration, without parallax, without nutation
   (mean sidereal time and precession only) and Müller et al.'s (2012, eq. 7) single
   rotation (precession, no aberration, no proper motion). Error: largest and median
   angular distance; cost: time for the stars × times.
2. Refraction — Bennett's (1982) formula against the atmosphere's ray-traced refraction,
   as a function of apparent altitude.
3. Extinction — the plane-parallel shortcut (zenith optical depth × Kasten & Young air
   mass) against integration along the refracted path, as a function of altitude.
4. Extinction table — interpolation error of the path-integrated table against direct
   V-band integration at off-node altitudes, against the number of nodes and build time.

Run: ``python experiments/stars_accuracy_cost.py [--quick] [--output-dir DIR]``; writes
``stars_accuracy_cost.nc`` and ``.png``.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402

LAT, LON, ELEVATION = 52.5, 13.4, 34.0
ARCSEC = math.pi / 180.0 / 3600.0


def bennett_refraction_rad(apparent_altitude_rad: torch.Tensor) -> torch.Tensor:
    """Bennett (1982): R [arcmin] = cot(h + 7.31/(h + 4.4)), h the apparent altitude [deg]."""
    h = torch.rad2deg(apparent_altitude_rad)
    return torch.deg2rad(1.0 / torch.tan(torch.deg2rad(h + 7.31 / (h + 4.4))) / 60.0)


def _timed(function, repeat: int = 5):
    """Return result and smallest CPU time of this process over ``repeat`` calls [s].

    CPU time rather than wall time: the machine is shared, and wall times there vary by
    factors of several from run to run.
    """
    function()
    best = math.inf
    result = None
    for _ in range(repeat):
        start = time.process_time()
        result = function()
        best = min(best, time.process_time() - start)
    return result, best


def _separation(alt1, az1, alt2, az2):
    cos = np.sin(alt1) * np.sin(alt2) + np.cos(alt1) * np.cos(alt2) * np.cos(az1 - az2)
    sin = np.hypot(np.cos(alt2) * np.sin(az1 - az2),
                   np.cos(alt1) * np.sin(alt2) - np.sin(alt1) * np.cos(alt2)
                   * np.cos(az1 - az2))
    return np.arctan2(sin, cos)


def position_variants(n_star: int, n_time: int):
    """Errors [arcsec] and costs [s] of position variants against skyfield."""
    from skyfield.api import Star, wgs84
    from skyfield.framelib import ICRS_to_J2000

    from skytorch import ephemeris
    from skytorch.stars import bright_stars
    from skytorch.stars.positions import (
        aberration_operators,
        horizontal_planes,
        star_vectors,
        time_operators,
    )

    catalog = bright_stars(6.5)
    rng = np.random.default_rng(5)
    sub = catalog.isel(star=np.sort(rng.choice(catalog.sizes["star"], n_star, replace=False)))
    span = (np.datetime64("2050-01-01", "ns") - np.datetime64("1900-01-01", "ns"))
    times = np.datetime64("1900-01-01", "ns") + np.sort(rng.random(n_time)) * span
    times = times.astype("datetime64[ns]")

    eph = ephemeris.load_ephemeris()
    observer = eph["earth"] + wgs84.latlon(LAT, LON, ELEVATION)
    star = Star(ra_hours=sub.ra.values / 15.0, dec_degrees=sub.dec.values,
                ra_mas_per_year=sub.pm_ra.values, dec_mas_per_year=sub.pm_dec.values,
                parallax_mas=np.clip(sub.parallax.values, 0.0, None))
    t = ephemeris.skyfield_time(times)
    ref_alt, ref_az, far, apparent_list = [], [], [], []
    start = time.process_time()
    for i in range(n_time):
        apparent = observer.at(t[i]).observe(star).apparent()
        alt, az, _ = apparent.altaz()
        ref_alt.append(alt.radians)
        ref_az.append(az.radians)
        apparent_list.append(apparent)
    skyfield_cost = time.process_time() - start
    for i, apparent in enumerate(apparent_list):
        sun = observer.at(t[i]).observe(eph["sun"]).apparent()
        far.append(apparent.separation_from(sun).degrees > 3.0)
    ref_alt, ref_az, far = np.array(ref_alt), np.array(ref_az), np.array(far)

    def altaz(stars, operators, velocity):
        if velocity is not None:
            operators = aberration_operators(operators, velocity)
        north, east, up = horizontal_planes(stars.T.contiguous(), operators)
        return (torch.atan2(up, torch.hypot(north, east)).double().numpy(),
                torch.remainder(torch.atan2(east, north), 2 * math.pi).double().numpy())

    def stars_of(dtype, proper_motion=True):
        pm_ra = sub.pm_ra.values if proper_motion else np.zeros(n_star)
        pm_dec = sub.pm_dec.values if proper_motion else np.zeros(n_star)
        return star_vectors(sub.ra.values, sub.dec.values, pm_ra, pm_dec, sub.parallax.values,
                            dtype=dtype)

    def mean_of_date_operators(with_pm: bool, with_aberration: bool):
        """Precession and mean sidereal time only (no nutation), from skyfield's P and GMST.

        Optionally aberration from Earth's barycentric and the diurnal velocity.
        """
        t_fresh = ephemeris.skyfield_time(times)  # skyfield caches P/gmst on a Time
        precession = np.moveaxis(np.asarray(t_fresh.P), -1, 0).reshape(-1, 3, 3) @ ICRS_to_J2000
        theta = np.asarray(t_fresh.gmst).reshape(-1) * (np.pi / 12.0)
        rotation = np.zeros((n_time, 3, 3))
        rotation[:, 0, 0] = rotation[:, 1, 1] = np.cos(theta)
        rotation[:, 0, 1], rotation[:, 1, 0] = np.sin(theta), -np.sin(theta)
        rotation[:, 2, 2] = 1.0
        lat, lon = math.radians(LAT), math.radians(LON)
        local = np.array([[-math.sin(lat) * math.cos(lon), -math.sin(lat) * math.sin(lon),
                           math.cos(lat)], [-math.sin(lon), math.cos(lon), 0.0],
                          [math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon),
                           math.sin(lat)]])
        matrices = torch.from_numpy(local @ rotation @ precession)
        dt = (times - np.datetime64("2000-01-01T12:00", "ns")).astype(float) / 1e9 / 31557600.0
        dt_column = torch.from_numpy(dt)[:, None, None] * matrices * float(with_pm)
        operators = torch.cat([matrices, dt_column,
                               torch.zeros(n_time, 3, 2, dtype=torch.float64)], dim=-1)
        if not with_aberration:
            return operators, None
        earth = eph["earth"].at(t_fresh)
        annual = torch.from_numpy(np.ascontiguousarray(np.asarray(earth.velocity.m_per_s).T))
        velocity = (matrices @ annual.unsqueeze(-1)).squeeze(-1)
        velocity[:, 1] += 7.292115e-5 * 6.365e6 * math.cos(math.radians(LAT))  # diurnal
        return operators, velocity

    variants = {
        "full, float64": lambda: altaz(stars_of(torch.float64),
                                       *time_operators(times, LAT, LON, ELEVATION)),
        "full, float32": lambda: altaz(stars_of(torch.float32),
                                       *time_operators(times, LAT, LON, ELEVATION)),
        "no parallax": lambda: altaz(stars_of(torch.float64),
                                     *time_operators(times, LAT, LON, ELEVATION,
                                                     parallax=False)),
        "no aberration": lambda: altaz(stars_of(torch.float64),
                                       *time_operators(times, LAT, LON, ELEVATION,
                                                       aberration=False)),
        "full, per-time nutation": lambda: altaz(
            stars_of(torch.float64),
            *time_operators(times, LAT, LON, ELEVATION, anchor_minutes=None)),
        "no nutation (GMST, precession)": lambda: altaz(
            stars_of(torch.float64), *mean_of_date_operators(True, True)),
        "Mueller eq. 7 (precession only)": lambda: altaz(
            stars_of(torch.float64, proper_motion=False), *mean_of_date_operators(False, False)),
    }
    names, max_error, median_error, cost = [], [], [], []
    for name, function in variants.items():
        (alt, az), seconds = _timed(function)
        error = _separation(alt, az, ref_alt, ref_az)[far] / ARCSEC
        names.append(name)
        max_error.append(float(error.max()))
        median_error.append(float(np.median(error)))
        cost.append(seconds)
    names.append("skyfield (reference)")
    max_error.append(0.0)
    median_error.append(0.0)
    cost.append(skyfield_cost)
    return names, np.array(max_error), np.array(median_error), np.array(cost)


def refraction_comparison(n_altitude: int):
    from skytorch.atmosphere import Atmosphere

    atmosphere = Atmosphere.earth()
    altitude = torch.linspace(0.0, 89.0, n_altitude, dtype=torch.float64) * math.pi / 180
    traced, traced_cost = _timed(lambda: atmosphere.refraction(altitude, ELEVATION), 1)
    formula, formula_cost = _timed(lambda: bennett_refraction_rad(altitude), 3)
    return altitude, traced, formula, traced_cost, formula_cost


def extinction_comparison(n_altitude: int, node_counts):
    from skytorch.atmosphere import Atmosphere
    from skytorch.spectrum import blackbody_radiance, bv_to_temperature, v_band_response
    from skytorch.stars import photometry

    atmosphere = Atmosphere.earth()
    bv = torch.tensor([0.65], dtype=torch.float64)
    rng = np.random.default_rng(3)
    altitude = torch.from_numpy(np.sort(rng.random(n_altitude)) ** 2 * 89.5 + 0.05)
    altitude = altitude * math.pi / 180
    wavelength = torch.linspace(470.0, 700.0, 231, dtype=torch.float64)
    weights = blackbody_radiance(wavelength, bv_to_temperature(bv)) * v_band_response(wavelength)
    with torch.no_grad():
        tau = atmosphere.optical_depth(wavelength, math.pi / 2 - altitude, ELEVATION,
                                       refraction=True)
        direct = -2.5 * torch.log10((weights * torch.exp(-tau)).sum(-1) / weights.sum())
    path = photometry.extinction_table(atmosphere, ELEVATION, refraction=True, cache=False)
    plane = photometry.extinction_table(atmosphere, ELEVATION, method="airmass", cache=False)
    path_m, _ = photometry.extinction(bv, altitude[:, None], path)
    plane_m, _ = photometry.extinction(bv, altitude[:, None], plane)
    node_error, node_cost = [], []
    for n in node_counts:
        start = time.perf_counter()
        table = photometry.extinction_table(atmosphere, ELEVATION, n_nodes=n, refraction=True,
                                            cache=False)
        node_cost.append(time.perf_counter() - start)
        estimate, _ = photometry.extinction(bv, altitude[:, None], table)
        node_error.append(float((estimate[:, 0] - direct).abs().max()))
    return (altitude, direct, path_m[:, 0], plane_m[:, 0], np.array(node_error),
            np.array(node_cost))


def main(argv: list[str] | None = None) -> int:
    args = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    # one intra-op thread: CPU times of spinning OpenMP threads on a shared machine are noise
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return _run(args, plt)
    finally:
        torch.set_num_threads(threads)


def _run(args, plt) -> int:

    from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable

    n_star, n_time = (40, 2) if args.quick else (2000, 40)
    n_altitude = 12 if args.quick else 180
    node_counts = [32] if args.quick else [32, 64, 128, 256, 512, 1024]

    names, max_error, median_error, cost = position_variants(n_star, n_time)
    altitude_r, traced, formula, traced_cost, formula_cost = refraction_comparison(n_altitude)
    altitude_e, direct, path_m, plane_m, node_error, node_cost = extinction_comparison(
        n_altitude, node_counts)

    deg = 180.0 / math.pi
    ds = build_dataset(
        {
            "position_max_error": variable("variant", max_error, VariableSpec(
                "arcsec", "largest position error", "Largest angular distance to skyfield's "
                "apparent alt/az (stars > 3 deg from the Sun).")),
            "position_median_error": variable("variant", median_error, VariableSpec(
                "arcsec", "median position error", "Median angular distance to skyfield.")),
            "position_cost": variable("variant", cost, VariableSpec(
                "s", "CPU time", f"CPU time for {n_star} stars x {n_time} times.")),
            "refraction_ray_traced": variable("refraction_altitude", traced / ARCSEC,
                                              VariableSpec("arcsec", "ray-traced refraction",
                                                           "atmosphere.refraction.")),
            "refraction_bennett": variable("refraction_altitude", formula / ARCSEC,
                                           VariableSpec("arcsec", "Bennett refraction",
                                                        "Bennett (1982) formula.")),
            "extinction_direct": variable("extinction_altitude", direct, VariableSpec(
                "mag", "V extinction, direct", "V-band integral along the refracted path.")),
            "extinction_table_path": variable("extinction_altitude", path_m, VariableSpec(
                "mag", "V extinction, path table", "extinction_table(method='path').")),
            "extinction_table_airmass": variable("extinction_altitude", plane_m, VariableSpec(
                "mag", "V extinction, air-mass shortcut",
                "Zenith optical depth x Kasten-Young air mass.")),
            "table_max_error": variable("n_nodes", node_error, VariableSpec(
                "mag", "table interpolation error", "Largest |table - direct|.")),
            "table_cost": variable("n_nodes", node_cost, VariableSpec(
                "s", "table build time", "Time to build the extinction table.")),
        },
        {
            "variant": coordinate("variant", np.array(names), VariableSpec(
                "1", "position model variant", "Which corrections are applied.")),
            "refraction_altitude": coordinate("refraction_altitude", altitude_r * deg,
                                              VariableSpec("degree", "apparent altitude",
                                                           "Apparent altitude.")),
            "extinction_altitude": coordinate("extinction_altitude", altitude_e * deg,
                                              VariableSpec("degree", "apparent altitude",
                                                           "Apparent altitude.")),
            "n_nodes": coordinate("n_nodes", np.array(node_counts), VariableSpec(
                "1", "table nodes", "Nodes between horizon and zenith.")),
        },
        title="Stars: accuracy versus cost",
        references=["Bennett 1982, J. Navigation 35, 255, doi:10.1017/S0373463300022037",
                    "Kasten & Young 1989, Appl. Opt. 28, 4735, doi:10.1364/AO.28.004735",
                    "Rhodes 2019, Skyfield, ascl:1907.024"],
        parameters={"quick": bool(args.quick), "n_star": n_star, "n_time": n_time,
                    "lat_deg": LAT, "lon_deg": LON, "elevation_m": ELEVATION,
                    "refraction_traced_cost_s": traced_cost,
                    "refraction_bennett_cost_s": formula_cost})

    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    ax = axes[0, 0]
    for name, err, seconds in zip(names[:-1], max_error[:-1], cost[:-1], strict=True):
        ax.scatter(seconds, max(err, 1e-4), label=name)
    ax.axhline(1.0, color="k", linestyle=":", linewidth=0.8, label="1″ target")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(f"CPU time for {n_star} stars × {n_time} times [s] (skyfield: "
                  f"{cost[-1]:.2f} s)")
    ax.set_ylabel("largest error vs skyfield [arcsec]")
    ax.set_title("positions")
    ax.legend(fontsize=7)
    ax = axes[0, 1]
    ax.plot(altitude_r * deg, (formula - traced) / ARCSEC)
    ax.set_yscale("symlog", linthresh=1.0)
    ax.set_xlabel("apparent altitude [deg]")
    ax.set_ylabel("Bennett − ray traced [arcsec]")
    ax.set_title(f"refraction (ray traced {traced_cost * 1e3:.0f} ms for {n_altitude}, "
                 f"formula {formula_cost * 1e6:.0f} µs)")
    ax = axes[1, 0]
    ax.plot(altitude_e * deg, (plane_m - direct).numpy(), label="Kasten–Young × zenith τ")
    ax.plot(altitude_e * deg, (path_m - direct).numpy(), label="path table (256 nodes)")
    ax.set_yscale("symlog", linthresh=1e-3)
    ax.set_xlabel("apparent altitude [deg]")
    ax.set_ylabel("extinction error [mag]")
    ax.set_title("V extinction vs direct integral along the refracted path")
    ax.legend(fontsize=8)
    ax = axes[1, 1]
    ax.loglog(node_cost, node_error, "o-")
    for n, c, e in zip(node_counts, node_cost, node_error, strict=True):
        ax.annotate(str(n), (c, e), fontsize=8)
    ax.set_xlabel("table build time [s]")
    ax.set_ylabel("largest interpolation error [mag]")
    ax.set_title("extinction table: nodes vs error")
    fig.tight_layout()
    nc, png = save_outputs(ds, fig, args.output_dir, "stars_accuracy_cost")
    print(f"wrote {nc} and {png}")
    for name, err, med, seconds in zip(names, max_error, median_error, cost, strict=True):
        print(f"{name:34s} max {err:9.4f}″ median {med:9.4f}″ {seconds * 1e3:9.1f} ms")
    print("refraction Bennett − traced [arcsec] at 0, 1, 5, 10, 45°:",
          np.interp([0, 1, 5, 10, 45], altitude_r.numpy() * deg,
                    ((formula - traced) / ARCSEC).numpy()).round(2))
    print("extinction airmass-shortcut error [mag] at 1, 5, 10, 30°:",
          np.interp([1, 5, 10, 30], altitude_e.numpy() * deg,
                    (plane_m - direct).numpy()).round(4))
    print("table error vs nodes:", dict(zip(node_counts, node_error.round(5), strict=True)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
