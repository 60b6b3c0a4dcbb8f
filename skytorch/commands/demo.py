"""``skytorch demo``: the end-to-end demonstration job run by ``make demo``.

The 2015-09-28 total lunar eclipse, end to end:

1. ephemeris of the night from Berlin;
2. circumstances (:func:`skytorch.eclipse.lunar_eclipses`);
3. the Moon's light curve and colour for a typical atmosphere and the atmosphere of the
   eclipse date, with the stratospheric sulfate of 2015 after Calbuco
   (:func:`skytorch.eclipse.lunar_eclipse`);
4. the Earth's shadow profile at the Moon's distance against lunar-eclipse theory:
   the geometric umbra/penumbra radii (Danjon enlargement) and the umbra centre of a
   molecular atmosphere, 1/2400 of sunlight (Vollmer & Gedzelman 2008);
5. all-sky renders at three phases from Berlin with stars, the Moon and a city's
   skyglow (:class:`skytorch.Scene`): U1 + 30 min, greatest eclipse, U4 − 20 min;
6. the Moon through a telescope at the same phases (a camera view of 1.2°): the edge of
   the umbra across the disc;
7. a 3 × 3 turbidity × ozone sweep of the Moon's colour at totality
   (:func:`skytorch.sweep`);
8. next to it, the total solar eclipse of 2026-08-12 at Burgos: local circumstances
   (:func:`skytorch.eclipse.solar_eclipse_local`), the obscuration map at the local
   maximum and the all-sky render there (the sky with the Sun's visible fraction at
   every scattering point, :mod:`skytorch.scene.solar_eclipse_sky`).

Every part writes netCDF and PNG files into ``--output-dir`` and one line or two of the
summary. A part whose module cannot be imported is skipped with the reason printed.
``--quick`` runs everything at reduced resolution (for tests).

The Calbuco case is the atmosphere of the eclipse date,
:func:`skytorch.eclipse.eclipse_atmosphere` (global-mean troposphere and ozone, and the
stratospheric sulfate layer of 2015 after the April eruption of Calbuco; Keen 2016
reports the 2015 eclipse 33 % dimmer than expected for a clear stratosphere).
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

import numpy as np

logger = logging.getLogger(__name__)

#: the demonstration site (Berlin) and night
SITE = {"lat_deg": 52.52, "lon_deg": 13.40, "elevation_m": 34.0}
NIGHT = ("2015-09-27T18:00", "2015-09-28T06:00")
ECLIPSE_DATE = "2015-09-28"
#: umbra centre of a molecular atmosphere without ozone, 400–700 nm (Vollmer & Gedzelman
#: 2008, Appl. Opt. 47, H52, doi:10.1364/AO.47.000H52)
VG2008_UMBRA_CENTRE = 1.0 / 2400.0
#: the city of the all-sky renders: centre 12 km south-east of the observer
CITY = {"population": 1_000_000.0, "scale_length_m": 4_000.0, "centre_xy": (8_000.0, -9_000.0)}
#: the solar-eclipse panel: Burgos, the total solar eclipse of 2026-08-12
SOLAR_SITE = {"lat_deg": 42.34, "lon_deg": -3.70, "elevation_m": 850.0}
SOLAR_ECLIPSE_DATE = "2026-08-12"
#: sweep grid of the Moon's colour at totality
#: significant digits kept in the demo's all-sky render files (see to_netcdf)
RENDER_SIGNIFICANT_DIGITS = 7
SWEEP_TURBIDITY = (1.5, 3.0, 6.0)
SWEEP_OZONE_DU = (0.0, 300.0, 450.0)


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``skytorch demo``."""
    parser.add_argument("--output-dir", type=Path, default=Path("out"),
                        help="where netCDF and PNG files are written (default out/)")
    parser.add_argument("--quick", action="store_true", help="reduced resolution (tests)")


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def ephemeris_part(output_dir: Path, quick: bool, state: dict) -> list[str]:
    """Sun and Moon over the night from Berlin (netCDF + altitude plot)."""
    from skytorch import plot
    from skytorch.dataset import to_netcdf
    from skytorch.ephemeris import parse_times, sun_moon

    start, end = parse_times(list(NIGHT))
    step = np.timedelta64(30 if quick else 5, "m")
    times = np.arange(start, end + step, step)
    ds = sun_moon(times, **SITE)
    path = to_netcdf(ds, output_dir / "eclipse_night_ephemeris.nc")
    axes = plot.profile(ds["time"].values, {"Moon": ds["moon_altitude"].values,
                                            "Sun": ds["sun_altitude"].values},
                        ylabel="altitude [degree]",
                        title="Berlin, night of the 2015-09-28 lunar eclipse")
    axes.axhline(0.0, color="grey", lw=0.5)
    axes.figure.autofmt_xdate()
    png = plot.savefig(axes.figure, output_dir / "eclipse_night_ephemeris.png")
    highest = int(np.argmax(ds["moon_altitude"].values))
    return [
        f"ephemeris: {ds.sizes['time']} times -> {path.name}, {png.name}",
        f"  Moon highest at {str(ds['time'].values[highest])[:16]} UTC, "
        f"altitude {float(ds['moon_altitude'][highest]):.1f} deg",
    ]


def circumstances_part(output_dir: Path, quick: bool, state: dict) -> list[str]:
    """Circumstances of the eclipse (contacts, magnitudes, gamma)."""
    from skytorch.dataset import to_netcdf
    from skytorch.eclipse import lunar_eclipses

    ds = lunar_eclipses("2015-09-01", "2015-10-31")
    path = to_netcdf(ds, output_dir / "eclipse_circumstances.nc")
    row = ds.isel(eclipse=0)
    state["circumstances"] = row
    return [
        f"circumstances -> {path.name}",
        f"  {str(row['kind'].values)} eclipse, greatest {str(row['time'].values)[:19]} UTC, "
        f"umbral magnitude {float(row['umbral_magnitude']):.4f}, gamma "
        f"{float(row['gamma']):.4f}, totality {float(row['total_duration']):.1f} min",
    ]


def _atmospheres():
    from skytorch.atmosphere import Atmosphere
    from skytorch.eclipse import eclipse_atmosphere

    return {
        "typical": Atmosphere.earth(turbidity=2.0, ozone_du=300.0),
        "calbuco": eclipse_atmosphere(ECLIPSE_DATE),
    }


def _eclipse_options(quick: bool) -> dict:
    if quick:
        return {"n_times": 24, "n_images": 5, "n_disc": 4, "image_pixels": 24,
                "table_n_v": 48}
    return {"n_times": 120, "n_images": 9, "n_disc": 10, "image_pixels": 48,
            "table_n_v": 256}


def light_curve_part(output_dir: Path, quick: bool, state: dict) -> list[str]:
    """Light curves and colours for the typical atmosphere and that of the eclipse date."""
    from skytorch import plot
    from skytorch.dataset import to_netcdf
    from skytorch.eclipse import lunar_eclipse

    lines = []
    curves = {}
    for name, atm in _atmospheres().items():
        ds = lunar_eclipse(ECLIPSE_DATE, atmosphere=atm, **_eclipse_options(quick))
        to_netcdf(ds, output_dir / f"eclipse_light_curve_{name}.nc")
        curves[name] = ds
        greatest = int(np.argmax(ds["v_magnitude"].values))
        lines.append(f"  {name:8s}: greatest V {float(ds['v_magnitude'][greatest]):+.2f}, "
                     f"B-V {float(ds['b_minus_v'][greatest]):.2f}, Danjon L ~ "
                     f"{float(ds.attrs['parameter_danjon_l']):.1f}, sRGB "
                     + " ".join(f"{v:.2f}" for v in ds["colour"].values[greatest]))
    state["curves"] = curves
    plt = _plt()
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True)
    first = next(iter(curves.values()))
    events = {key: first.attrs[f"parameter_{key}"] for key in ("p1", "u1", "u2", "u3", "u4",
                                                               "p4")
              if f"parameter_{key}" in first.attrs and first.attrs[f"parameter_{key}"] != ""}
    plot.light_curve(first["time"].values, {n: c["v_magnitude"].values
                                            for n, c in curves.items()}, axes=top,
                     title="Moon's V magnitude, 2015-09-28", events=events)
    plot.profile((first["time"].values - first["time"].values[0]) / np.timedelta64(1, "h"),
                 {n: c["b_minus_v"].values for n, c in curves.items()}, axes=bottom,
                 xlabel="hours", ylabel="B - V [mag]")
    png = plot.savefig(figure, output_dir / "eclipse_light_curve.png")
    strip = plot.eclipse_strip(curves["typical"]["image"].values,
                               [np.datetime_as_string(t, unit="m")[11:]
                                for t in curves["typical"]["image_time"].values])
    plot.savefig(strip, output_dir / "eclipse_moon_strip.png")
    return [f"light curve -> eclipse_light_curve_{{typical,calbuco}}.nc, {png.name}, "
            "eclipse_moon_strip.png", *lines]


def shadow_profile_part(output_dir: Path, quick: bool, state: dict) -> list[str]:
    """Shadow profile at the Moon's distance against lunar-eclipse theory."""
    import torch

    from skytorch import plot
    from skytorch.constants import SUN_RADIUS_M
    from skytorch.dataset import VariableSpec, build_dataset, coordinate, to_netcdf, variable
    from skytorch.eclipse import Shadow, shadow_radii
    from skytorch.spectrum import solar_irradiance, v_band_response

    row = state.get("circumstances")
    distance = float(row["moon_distance"]) if row is not None else 3.569e8
    atmospheres = _atmospheres()
    from skytorch.atmosphere import Atmosphere

    cases = {
        "geometry only": Shadow.earth(atmospheres["typical"], refraction=False,
                                      extinction=False),
        "molecules": Shadow.earth(Atmosphere.earth(aerosol_optical_depth=0.0, ozone_du=0.0)),
        "typical": Shadow.earth(atmospheres["typical"]),
        "calbuco": Shadow.earth(atmospheres["calbuco"]),
    }
    step = 40.0 if quick else 10.0
    wavelength = torch.arange(400.0, 700.0 + 0.5 * step, step, dtype=torch.float64)
    offset = torch.linspace(0.0, 1.0e7, 21 if quick else 201, dtype=torch.float64)
    weight = solar_irradiance(wavelength) * v_band_response(wavelength)
    weight = weight / weight.sum()
    energy = solar_irradiance(wavelength)
    energy = energy / energy.sum()
    spectra = torch.stack([c.relative_illuminance(torch.tensor(distance, dtype=torch.float64),
                                                  offset, wavelength)
                           for c in cases.values()])
    v_band = spectra @ weight
    centre_energy = float(spectra[1, 0] @ energy)
    sun_distance = 1.496e11
    umbra, penumbra = shadow_radii(torch.tensor(distance, dtype=torch.float64), sun_distance,
                                   SUN_RADIUS_M, 6.371e6, enlargement="danjon")
    names = list(cases)
    ds = build_dataset(
        {"relative_illuminance": variable(("case", "offset", "wavelength"), spectra,
                                          VariableSpec("1", "relative illuminance",
                                                       "I / I_sun at the Moon's distance")),
         "v_band": variable(("case", "offset"), v_band, VariableSpec(
             "1", "V-band relative illuminance", "Solar x V-passband weighted I / I_sun"))},
        {"case": coordinate("case", np.array(names), VariableSpec("1", "shadow case",
                                                                  "atmosphere case")),
         "offset": coordinate("offset", offset, VariableSpec(
             "m", "distance from the shadow axis", "At the Moon's distance")),
         "wavelength": coordinate("wavelength", wavelength, VariableSpec(
             "nm", "wavelength", "Vacuum wavelength", "radiation_wavelength"))},
        title="Earth's shadow at the Moon, 2015-09-28",
        references=["Vollmer, M., Gedzelman, S. D. 2008, Appl. Opt. 47, H52, "
                    "doi:10.1364/AO.47.000H52"],
        parameters={"moon_distance_m": distance, "umbra_radius_m": float(umbra),
                    "penumbra_radius_m": float(penumbra),
                    "molecular_umbra_centre_400_700": centre_energy,
                    "vg2008_umbra_centre": VG2008_UMBRA_CENTRE})
    to_netcdf(ds, output_dir / "eclipse_shadow_profile.nc")
    axes = plot.profile(offset / 1e3, {n: v_band[i].clamp(min=1e-12)
                                       for i, n in enumerate(names)}, log=True,
                        xlabel="distance from the shadow axis [km]",
                        ylabel="I / I_sun (V band)",
                        title="Earth's shadow at the Moon's distance, 2015-09-28")
    for radius, label in ((umbra, "umbra (Danjon)"), (penumbra, "penumbra (Danjon)")):
        axes.axvline(float(radius) / 1e3, color="0.5", ls="--", lw=0.8)
        axes.text(float(radius) / 1e3, 2e-9, label, rotation=90, fontsize=7, va="bottom")
    axes.axhline(VG2008_UMBRA_CENTRE, color="r", ls=":", lw=0.8,
                 label="1/2400 (Vollmer & Gedzelman 2008)")
    axes.set_ylim(1e-9, 2)
    axes.legend(fontsize=7)
    png = plot.savefig(axes.figure, output_dir / "eclipse_shadow_profile.png")
    # where the geometric shadow (no atmosphere) reaches half light: the penumbra's middle
    geometric = v_band[0]
    return [f"shadow profile -> eclipse_shadow_profile.nc, {png.name}",
            f"  umbra {float(umbra) / 1e3:.0f} km, penumbra {float(penumbra) / 1e3:.0f} km "
            f"(Danjon); geometric shadow at the umbra edge "
            f"{float(np.interp(float(umbra), offset.numpy(), geometric.numpy())):.3f}",
            f"  molecular umbra centre {centre_energy:.2e} of sunlight "
            f"(Vollmer & Gedzelman 2008: {VG2008_UMBRA_CENTRE:.2e}, ratio "
            f"{centre_energy / VG2008_UMBRA_CENTRE:.2f})"]


def _phases(state: dict) -> dict[str, np.datetime64]:
    """Partial ingress (U1 + 30 min), greatest eclipse, partial egress (U4 - 20 min)."""
    row = state.get("circumstances")
    if row is None:
        from skytorch.ephemeris import parse_times

        u1, greatest, u4 = parse_times(["2015-09-28T01:07", "2015-09-28T02:47",
                                        "2015-09-28T04:27"])
    else:
        u1, greatest, u4 = row["u1"].values, row["time"].values, row["u4"].values
    return {"partial ingress": u1 + np.timedelta64(30, "m"),
            "totality": greatest,
            "partial egress": u4 - np.timedelta64(20, "m")}


def all_sky_part(output_dir: Path, quick: bool, state: dict) -> list[str]:
    """All-sky renders at three phases with stars, the Moon and a city's skyglow."""
    from skytorch import plot
    from skytorch.dataset import to_netcdf
    from skytorch.scene import Scene
    from skytorch.skyglow.citymap import synthetic_city

    city = synthetic_city(extent_m=60_000.0, cell_m=1_000.0 if quick else 500.0, **CITY)
    plt = _plt()
    phases = _phases(state)
    figure, axes = plt.subplots(1, len(phases), figsize=(4.2 * len(phases), 4.6))
    figure.patch.set_facecolor("black")
    lines = []
    exposure = None
    for index, (label, when) in enumerate(phases.items()):
        scene = Scene(time=str(when)[:19], **SITE, size=96 if quick else 384,
                      light_map=city, fidelity="fast" if quick else "default",
                      star_limit_mag=5.0 if quick else 6.5)
        start = time.perf_counter()
        ds = scene.render()
        seconds = time.perf_counter() - start
        stem = f"allsky_{index + 1}_{label.split()[0]}"
        # 7 significant digits (relative error < 5e-7, far below the model's own accuracy
        # of about 1e-2): the 384 x 384 render shrinks 4.7x instead of 1.8x lossless
        to_netcdf(ds, output_dir / f"{stem}.nc", significant_digits=RENDER_SIGNIFICANT_DIGITS)
        exposure = float(ds.attrs["parameter_exposure"]) if exposure is None else exposure
        moon = (ds.attrs["parameter_moon_altitude_deg"], ds.attrs["parameter_moon_azimuth_deg"])
        plot.all_sky(ds, axes[index], exposure=exposure, night=True,
                     title=f"{label}\n{str(when)[:16]} UTC",
                     markers={"Moon": moon} if moon[0] > 0 else None)
        axes[index].title.set_color("white")
        zenith = float(ds["v_mag_arcsec2"].sel(x=0.0, y=0.0, method="nearest"))
        lines.append(f"  {label:24s} zenith {zenith:.2f} mag/arcsec2, computed "
                     f"[{ds.attrs['effects_computed']}], {seconds:.1f} s -> {stem}.nc")
        lines.append(f"    skipped: {ds.attrs['effects_skipped']}")
    png = plot.savefig(figure, output_dir / "allsky_three_phases.png")
    return [f"all-sky renders (Berlin, city 12 km SE) -> {png.name}", *lines]


#: field of view of the Moon close-ups [degree]
CAMERA_FOV_DEG = 1.2


def moon_camera_part(output_dir: Path, quick: bool, state: dict) -> list[str]:
    """Render the Moon through a telescope (camera view) at the three phases of the all-sky part."""
    import torch

    from skytorch.dataset import to_netcdf
    from skytorch.scene import Scene, tonemap

    plt = _plt()
    phases = _phases(state)
    figure, axes = plt.subplots(1, len(phases), figsize=(3.4 * len(phases), 3.8))
    figure.patch.set_facecolor("black")
    lines = []
    for index, (label, when) in enumerate(phases.items()):
        scene = Scene(time=str(when)[:19], **SITE, view="camera", size=48 if quick else 192,
                      camera={"target": "moon", "fov_deg": CAMERA_FOV_DEG},
                      fidelity="fast" if quick else "default", exclude=["stars"],
                      outputs=("spectral", "xyz", "v_mag"))
        ds = scene.render()
        stem = f"moon_camera_{index + 1}_{label.split()[0]}"
        to_netcdf(ds, output_dir / f"{stem}.nc")
        half = 0.5 * CAMERA_FOV_DEG
        # exposed for the brightest part of the disc, as a photograph of the Moon would be
        xyz = torch.as_tensor(ds["xyz"].values)
        rgb, _ = tonemap(xyz, exposure=2.0 / float(xyz[..., 1].max()))
        axes[index].imshow(rgb.numpy(), extent=(-half, half, -half, half))
        axes[index].set_title(f"{label}\n{str(when)[:16]} UTC", color="white", fontsize=9)
        axes[index].set_xlabel("degree", color="white")
        axes[index].tick_params(colors="white")
        moon = ds["component_v_mag_arcsec2"].sel(component="moon").values
        disc = moon[np.isfinite(moon) & (moon < np.nanmedian(moon) - 3.0)]
        if disc.size:
            lines.append(f"  {label:24s} lunar disc {disc.min():.1f} .. {disc.max():.1f} "
                         f"mag/arcsec2 -> {stem}.nc")
    png = _save(figure, output_dir / "moon_camera_three_phases.png")
    return [f"Moon close-ups ({CAMERA_FOV_DEG} deg field) -> {png.name}", *lines]


def _save(figure, path: Path) -> Path:
    from skytorch import plot

    return plot.savefig(figure, path)


def moon_colour_at_totality(turbidity, ozone_du, quick: bool = False):
    """Moon's V, B−V and sRGB colour at greatest eclipse for one atmosphere (a sweep point)."""
    from skytorch.atmosphere import Atmosphere
    from skytorch.eclipse import lunar_eclipse

    options = ({"n_disc": 4, "table_n_v": 32} if quick else {"n_disc": 6, "table_n_v": 64})
    ds = lunar_eclipse(ECLIPSE_DATE, atmosphere=Atmosphere.earth(
        turbidity=float(turbidity), ozone_du=float(ozone_du)), n_times=3, n_images=0,
        **options)
    middle = ds.isel(time=1)
    return {"v_magnitude": float(middle["v_magnitude"]),
            "b_minus_v": float(middle["b_minus_v"]),
            "colour": np.asarray(middle["colour"].values)}


def sweep_part(output_dir: Path, quick: bool, state: dict) -> list[str]:
    """Turbidity x ozone sweep of the Moon's colour at totality."""
    from functools import partial

    from skytorch import plot
    from skytorch.dataset import to_netcdf
    from skytorch.sweep import sweep

    turbidity = SWEEP_TURBIDITY[::2] if quick else SWEEP_TURBIDITY
    ozone = SWEEP_OZONE_DU[::2] if quick else SWEEP_OZONE_DU
    ds = sweep(partial(moon_colour_at_totality, quick=quick), turbidity=list(turbidity),
               ozone_du=list(ozone), progress=False,
               units={"turbidity": "1", "ozone_du": "DU"})
    path = to_netcdf(ds, output_dir / "sweep_moon_colour.nc")
    plt = _plt()
    figure, (left, right) = plt.subplots(1, 2, figsize=(9, 3.8))
    colours = np.clip(ds["colour"].transpose("turbidity", "ozone_du", ...).values, 0, 1)
    right.imshow(colours, origin="lower", aspect="auto")
    right.set_xticks(range(len(ozone)), [f"{v:.0f}" for v in ozone])
    right.set_yticks(range(len(turbidity)), [f"{v:g}" for v in turbidity])
    right.set_xlabel("ozone [DU]")
    right.set_ylabel("turbidity")
    right.set_title("Moon's colour at totality (sRGB)", fontsize=10)
    for t in turbidity:
        plot.profile(list(ozone), {f"T = {t:g}": ds["b_minus_v"].sel(turbidity=t).values},
                     axes=left, xlabel="ozone [DU]", ylabel="B - V [mag]")
    left.set_title("B - V at totality", fontsize=10)
    left.legend(fontsize=8)
    png = plot.savefig(figure, output_dir / "sweep_moon_colour.png")
    bv = ds["b_minus_v"].values
    vmag = ds["v_magnitude"].values
    return [f"sweep {len(turbidity)} x {len(ozone)} turbidity x ozone -> {path.name}, "
            f"{png.name}",
            f"  totality V {vmag.min():+.2f} .. {vmag.max():+.2f}, "
            f"B-V {bv.min():.2f} .. {bv.max():.2f}"]


def solar_eclipse_part(output_dir: Path, quick: bool, state: dict) -> list[str]:
    """Show the 2026-08-12 total solar eclipse at Burgos: circumstances, map and sky."""
    from skytorch import plot
    from skytorch.dataset import to_netcdf
    from skytorch.eclipse import obscuration_map, solar_eclipse_local
    from skytorch.scene import Scene

    site = SOLAR_SITE
    local = solar_eclipse_local(SOLAR_ECLIPSE_DATE, site["lat_deg"], site["lon_deg"],
                                site["elevation_m"])
    to_netcdf(local, output_dir / "solar_eclipse_local.nc")
    instant = np.datetime_as_string(local.maximum_time.values, unit="s")
    step = 2.0 if quick else 0.5
    lat = np.arange(-90.0 + step / 2, 90.0, step)
    lon = np.arange(-180.0 + step / 2, 180.0, step)
    shadow = obscuration_map(instant, lat, lon)
    start = time.perf_counter()
    sky = Scene(time=instant, **site, size=64 if quick else 256,
                fidelity="fast" if quick else "default").render()
    seconds = time.perf_counter() - start
    to_netcdf(sky, output_dir / "solar_eclipse_sky.nc",
              significant_digits=RENDER_SIGNIFICANT_DIGITS)
    plt = _plt()
    figure, axes = plt.subplots(1, 2, figsize=(11, 4.6),
                                gridspec_kw={"width_ratios": [1.7, 1]})
    image = axes[0].pcolormesh(lon, lat, shadow.obscuration.where(shadow.sun_altitude > 0),
                               shading="auto", vmin=0.0, vmax=1.0, cmap="magma_r")
    axes[0].plot(site["lon_deg"], site["lat_deg"], "c+", markersize=12)
    axes[0].set_title(f"obscuration at {instant} UTC (day side)")
    axes[0].set_xlabel("longitude [degree east]")
    axes[0].set_ylabel("latitude [degree north]")
    figure.colorbar(image, ax=axes[0], label="obscuration")
    plot.all_sky(sky, axes[1], title=f"Burgos at maximum ({local.kind.values})")
    png = plot.savefig(figure, output_dir / "solar_eclipse.png")
    zenith = float(sky["v_mag_arcsec2"].sel(x=0.0, y=0.0, method="nearest"))
    orders = int(sky.attrs["sky_scattering_orders"])
    scattering = "single scattering" if orders == 1 else f"orders of scattering 1-{orders}"
    return [f"solar eclipse {SOLAR_ECLIPSE_DATE} at Burgos -> {png.name}",
            f"  {local.kind.values}, obscuration {float(local.obscuration):.4f}, maximum "
            f"{instant} UTC, central phase {float(local.central_duration):.1f} s",
            f"  sky at maximum: zenith {zenith:.2f} mag/arcsec2 ({scattering}), computed "
            f"[{sky.attrs['effects_computed']}], {seconds:.1f} s"]


PARTS = (
    ("ephemeris", ephemeris_part),
    ("circumstances", circumstances_part),
    ("light curve", light_curve_part),
    ("shadow profile", shadow_profile_part),
    ("all-sky renders", all_sky_part),
    ("Moon close-ups", moon_camera_part),
    ("sweep", sweep_part),
    ("solar eclipse", solar_eclipse_part),
)


def run(args: argparse.Namespace) -> int:
    """Run the demonstration job and print a one-screen summary."""
    output_dir = Path(args.output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    lines = ["skytorch demo: the 2015-09-28 total lunar eclipse"
             + (" (quick)" if args.quick else "")]
    state: dict = {}
    start = time.perf_counter()
    for name, part in PARTS:
        began = time.perf_counter()
        try:
            lines += part(output_dir, args.quick, state)
        except ImportError as error:
            lines.append(f"{name}: SKIPPED ({error})")
            continue
        logger.info("%s: %.1f s", name, time.perf_counter() - began)
    lines.append(f"done in {time.perf_counter() - start:.0f} s; files in {output_dir}")
    print("\n".join(lines))
    return 0
