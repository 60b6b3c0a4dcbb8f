"""Modelled lunar eclipses against the observed ones: V, B-V and Danjon L at mid-totality.

For every eclipse of ``observed_lunar_eclipses()`` with a V magnitude (or, for
2015-09-28, a magnitude below the full Moon) the Moon's light curve is modelled through
``eclipse_shadow(date)`` (the year's stratospheric sulfate layer, global-mean troposphere
and ozone, the limb cloud profile of ISCCP and SAGE; nothing fitted to eclipses) and
compared at its faintest sample: residual model - observed, rms and bias; with each the
Danjon class read from the modelled umbra (``danjon_class_l``) beside the L of Vital's
correlation. Then, for one eclipse (2015-09-28), each ingredient is added in turn
(molecules only; + ozone; + tropospheric aerosol; + stratospheric aerosol; + clouds) to
state what it changes, with the former single deck and the SAGE range of the cloud profile
beside it, and the altitudes whose rays light the umbra's centre.

Writes ``lunar_eclipse_comparison.nc`` / ``.png`` (per-eclipse table),
``lunar_eclipse_ingredients.nc`` / ``.png`` (light curves of the ingredients),
``lunar_eclipse_altitudes`` (umbra-centre light by periapsis altitude),
``lunar_eclipse_light_curve_2019`` (the 2019-01-21 photometry overlaid),
``lunar_eclipse_umbral_edge`` (the modelled umbral edge) and ``lunar_eclipse_retrieval``
(stratospheric AOD retrieved from each observed V, beside the record) and
``lunar_eclipse_limb_clouds`` (the limb's clear probability at 7 km retrieved from each V,
beside SAGE's range).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
import torch
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402
from skytorch.atmosphere import Atmosphere  # noqa: E402
from skytorch.atmosphere.climatology import afgl_profile  # noqa: E402
from skytorch.eclipse import (  # noqa: E402
    Shadow,
    danjon_class_l,
    eclipse_shadow,
    lunar_light_curve,
    observed_lunar_eclipses,
    stratospheric_aod,
    stratospheric_model,
)
from skytorch.eclipse.eclipse_atmosphere import (  # noqa: E402
    OZONE_DU,
    SAGE_CLEAR_7KM,
    TROPOSPHERIC_AOD_550,
    cloud_climatology,
    terminator_bands,
)
from skytorch.eclipse.shadow_mixture import ShadowMixture  # noqa: E402

#: the 2019-01-21 photometry (Georgia J. Sci. 80(1) art. 32), samples as printed
PHOTOMETRY_2019 = (Path(__file__).resolve().parents[1] / "tests" / "data"
                   / "lunar_eclipse_2019_01_21_photometry.csv")
#: the umbral rim of Danjon's classes: this fraction of the umbra radius from the axis
RIM_FRACTION = 0.95


def _band_offsets(shadow, distance_m, offsets_m):
    """V and B of sunlight through the shadow minus those of the unobstructed Sun [mag].

    At ``offsets_m`` from the axis at ``distance_m``; (n_offset,) each. The Moon's own
    colour cancels in the difference (it multiplies both spectra).
    """
    from skytorch.spectrum import solar_irradiance, spectrum_to_magnitude, wavelength_grid

    wavelength = wavelength_grid("bands15")
    offset = torch.as_tensor(offsets_m, dtype=torch.float64)
    light = shadow.relative_illuminance(torch.full_like(offset, distance_m), offset,
                                        wavelength)
    sun = solar_irradiance(wavelength)
    return [spectrum_to_magnitude(light * sun, wavelength, band)
            - spectrum_to_magnitude(sun, wavelength, band) for band in ("V", "B")]


def danjon_class_of(day: str, shadow, v_full: float) -> tuple[float, float, float, float]:
    """Danjon's verbal class of the modelled umbra at greatest eclipse, and its inputs.

    The centre (axis) as the V of a Moon uniformly that bright (``v_full`` plus the
    centre's V below sunlight), the rim at ``RIM_FRACTION`` of the umbra radius (Danjon's
    1/85 enlargement) at the Moon's distance; returns (class, centre V [mag], rim/centre,
    rim B-V [mag]).
    """
    from skytorch.constants import EARTH_MEAN_RADIUS_M
    from skytorch.eclipse import shadow_radii
    from skytorch.eclipse.danjon import MOON_B_MINUS_V
    from skytorch.eclipse.lunar import nearest_eclipse
    from skytorch.ephemeris import sun_moon

    row = nearest_eclipse(day).isel(eclipse=0)
    ephemeris = sun_moon(np.atleast_1d(row.time.values))
    distance = float(ephemeris.moon_distance.values.reshape(-1)[0])  # [m]
    umbra = float(shadow_radii(distance, shadow.sun_distance_m, shadow.sun_radius_m,
                               EARTH_MEAN_RADIUS_M, enlargement="danjon")[0])
    v, b = _band_offsets(shadow, distance, [0.0, RIM_FRACTION * umbra])
    centre_v = v_full + float(v[0])
    rim_to_centre = float(10.0 ** (-0.4 * (v[1] - v[0])))
    rim_b_minus_v = MOON_B_MINUS_V + float(b[1] - v[1])
    level = float(danjon_class_l(torch.tensor(centre_v), torch.tensor(rim_to_centre),
                                 torch.tensor(rim_b_minus_v)))
    return level, centre_v, rim_to_centre, rim_b_minus_v


def _faintest(curve, index=()):
    """V, B-V, magnitudes below the uneclipsed Moon and L at the faintest sample."""
    v = curve["v_magnitude"][index]
    k = int(torch.argmax(v))
    below = -2.5 * torch.log10(curve["relative_brightness"][index][k])
    return (float(v[k]), float(curve["b_minus_v"][index][k]), float(below),
            float(curve["danjon_l"][index]))


def comparison(quick: bool):
    """Model every observed eclipse with V (or V below full Moon); residuals, rms, bias."""
    observed = observed_lunar_eclipses()
    has = np.isfinite(observed.v_magnitude.values) | np.isfinite(
        observed.v_below_full_moon.values)
    observed = observed.isel(eclipse=np.flatnonzero(has))
    n_times, n_v = (16, 96) if quick else (48, 192)
    rows, classes = [], []
    start = time.perf_counter()
    for date in observed.eclipse.values:
        day = np.datetime_as_string(date, "D")
        shadow = eclipse_shadow(day)
        curve = lunar_light_curve(day, shadow=shadow, n_times=n_times, table_n_v=n_v)
        rows.append((*_faintest(curve), stratospheric_aod(day)))
        classes.append((rows[-1][0], rows[-1][2], shadow))
    seconds = time.perf_counter() - start
    # Danjon's classes read from the modelled umbra (not timed with the light curves)
    danjon = np.array([danjon_class_of(np.datetime_as_string(date, "D"), shadow, v - below)
                       for date, (v, below, shadow) in zip(observed.eclipse.values, classes,
                                                           strict=True)])
    model = np.array(rows)
    obs_v = observed.v_magnitude.values
    obs_below = observed.v_below_full_moon.values
    # model minus observed V; where only the magnitude below the full Moon is observed,
    # model minus observed of that (the same difference, the full Moon's V cancels)
    residual = np.where(np.isfinite(obs_v), model[:, 0] - obs_v, model[:, 2] - obs_below)
    dims = ("eclipse",)
    dataset = xr.Dataset(
        {"model_v_magnitude": (dims, model[:, 0], {"units": "mag"}),
         "model_b_minus_v": (dims, model[:, 1], {"units": "mag"}),
         "model_v_below_full_moon": (dims, model[:, 2], {"units": "mag"}),
         "model_danjon_l": (dims, model[:, 3], {"units": "1"}),
         "model_danjon_class": (dims, danjon[:, 0], {"units": "1", "long_name":
                                "Danjon verbal class of the modelled umbra"}),
         "model_centre_v_magnitude": (dims, danjon[:, 1], {"units": "mag", "long_name":
                                      "V of a Moon as bright as the umbral centre"}),
         "model_rim_to_centre": (dims, danjon[:, 2], {"units": "1"}),
         "model_rim_b_minus_v": (dims, danjon[:, 3], {"units": "mag"}),
         "stratospheric_aod_550": (dims, model[:, 4], {"units": "1"}),
         "observed_v_magnitude": (dims, obs_v, {"units": "mag"}),
         "observed_v_below_full_moon": (dims, obs_below, {"units": "mag"}),
         "observed_b_minus_v": (dims, observed.b_minus_v.values, {"units": "mag"}),
         "observed_danjon_l": (dims, observed.danjon_l.values, {"units": "1"}),
         "residual_v": (dims, residual, {"units": "mag",
                                         "long_name": "model minus observed V"})},
        coords={"eclipse": observed.eclipse.values},
        attrs={"title": "Modelled against observed lunar eclipses",
               "rms_v_mag": float(np.sqrt(np.mean(residual ** 2))),
               "bias_v_mag": float(np.mean(residual)),
               "model_seconds": seconds, "n_times": n_times, "table_n_v": n_v,
               "tropospheric_aod_550": TROPOSPHERIC_AOD_550, "ozone_du": OZONE_DU,
               "clouds": "rossow1999 (LimbCloudCover, limb exponent "
                         f"{float(cloud_climatology().limb_exponent):.3f})",
               "danjon_rim_fraction_of_umbra": RIM_FRACTION})
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 2, figsize=(11, 4))
    years = observed.eclipse.dt.year.values + observed.eclipse.dt.dayofyear.values / 366
    axes[0].plot(years, np.where(np.isfinite(obs_v), obs_v, model[:, 0] - residual), "ko",
                 label="observed")
    axes[0].plot(years, model[:, 0], "rs", label="model (eclipse_shadow)")
    axes[0].invert_yaxis()
    axes[0].set(xlabel="year", ylabel="V at mid-totality [mag]")
    axes[0].legend()
    axes[1].bar(years, residual, width=0.4)
    axes[1].set(xlabel="year", ylabel="model - observed V [mag]",
                title=f"rms {dataset.attrs['rms_v_mag']:.2f}, "
                      f"bias {dataset.attrs['bias_v_mag']:+.2f} mag")
    figure.tight_layout()
    summary = {"rms_v_mag": dataset.attrs["rms_v_mag"],
               "bias_v_mag": dataset.attrs["bias_v_mag"], "model_seconds": seconds}
    return dataset, figure, summary


def ingredients(quick: bool, date: str = "2015-09-28"):
    """Add molecules, ozone, tropospheric and stratospheric aerosol and clouds in turn."""
    n_times, n_v = (16, 96) if quick else (48, 192)
    saod = stratospheric_aod(date)
    labels = ["molecules", "+ ozone", "+ tropospheric aerosol", "+ stratospheric aerosol"]
    f64 = torch.float64
    atm = Atmosphere.earth(
        aerosol_optical_depth=torch.tensor([0.0, 0.0, TROPOSPHERIC_AOD_550,
                                            TROPOSPHERIC_AOD_550], dtype=f64),
        ozone_du=torch.tensor([0.0, OZONE_DU, OZONE_DU, OZONE_DU], dtype=f64),
        stratospheric_aerosol_optical_depth=torch.tensor([0.0, 0.0, 0.0, saod], dtype=f64),
        stratospheric_aerosol_profile=stratospheric_model(date))
    clear = lunar_light_curve(date, shadow=Shadow.earth(atm), n_times=n_times,
                              table_n_v=n_v)
    gaussian = Atmosphere.earth(aerosol_optical_depth=TROPOSPHERIC_AOD_550, ozone_du=OZONE_DU,
                                stratospheric_aerosol_optical_depth=saod)
    cloudy = {name: lunar_light_curve(date, shadow=shadow, n_times=n_times, table_n_v=n_v)
              for name, shadow in (
                  ("+ clouds (ISCCP + SAGE profile)", eclipse_shadow(date)),
                  ("+ clouds, SAGE tropics 0.30 at 7 km", eclipse_shadow(
                      date, cloud_cover=cloud_climatology(SAGE_CLEAR_7KM["tropics"]))),
                  ("+ clouds, SAGE extratropics 0.60 at 7 km", eclipse_shadow(
                      date, cloud_cover=cloud_climatology(SAGE_CLEAR_7KM["extratropics"]))),
                  ("+ clouds, single deck 5 km 0.66", eclipse_shadow(date, clouds="deck")),
                  # the former layer, no clouds: compare with "+ stratospheric aerosol"
                  ("+ stratospheric aerosol, Gaussian 20 km, 3 km (before 2026-12-06)",
                   Shadow.earth(gaussian)))}
    values = [_faintest(clear, (i,)) for i in range(4)] + [_faintest(c)
                                                          for c in cloudy.values()]
    labels += list(cloudy)
    curves = torch.cat([clear["v_magnitude"]] + [c["v_magnitude"][None]
                                                 for c in cloudy.values()]).numpy()
    values = np.array(values)
    dataset = xr.Dataset(
        {"v_magnitude": (("ingredient", "sample"), curves, {"units": "mag"}),
         "greatest_v_magnitude": (("ingredient",), values[:, 0], {"units": "mag"}),
         "greatest_b_minus_v": (("ingredient",), values[:, 1], {"units": "mag"}),
         "v_below_full_moon": (("ingredient",), values[:, 2], {"units": "mag"}),
         "danjon_l": (("ingredient",), values[:, 3], {"units": "1"})},
        coords={"ingredient": labels},
        attrs={"title": f"Ingredients of the modelled {date} eclipse",
               "stratospheric_aod_550": saod})
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(7, 4))
    for label, curve in zip(labels, curves, strict=True):
        axis.plot(curve, label=label, ls="--" if "," in label else "-")
    axis.invert_yaxis()
    axis.set(xlabel="sample (P1-5% .. P4+5%)", ylabel="V [mag]", title=date)
    axis.legend(fontsize=8)
    figure.tight_layout()
    summary = {f"V {label}": v for label, v in zip(labels, values[:, 0], strict=True)}
    return dataset, figure, summary


def _moon_geometry(date: str):
    """Moon distance [m] and offset of its centre from the shadow axis [m] at greatest."""
    from skytorch.eclipse.lunar import nearest_eclipse, sun_moon_vectors

    row = nearest_eclipse(date).isel(eclipse=0)
    vectors = sun_moon_vectors(np.atleast_1d(row.time.values))
    sun, moon = vectors["sun_gcrs_m"][0], vectors["moon_gcrs_m"][0]
    anti_sun = -sun / torch.linalg.norm(sun)
    along = float(moon @ anti_sun)
    return float(torch.linalg.norm(moon)), float(torch.linalg.norm(moon - along * anti_sun))


def altitude_contribution(quick: bool, date: str = "2015-09-28"):
    """Which rays light the eclipsed Moon: V left with every ray below ``h`` blocked.

    At greatest eclipse, at three points: the shadow axis (the umbra's centre), the
    Moon's centre and the Moon's limb nearest the umbra's edge; for the clear atmosphere
    of ``date`` and with the cloud profile; the light left when the rays with periapsis
    below ``h`` are removed, as a fraction of all of it (V band).
    """
    from skytorch.constants import MOON_RADIUS_M
    from skytorch.eclipse.shadow import LimbCloudCover

    distance, centre = _moon_geometry(date)
    points = {"umbra centre": 0.0, "Moon centre": centre, "Moon limb": centre + MOON_RADIUS_M}
    heights = (np.array([0.0, 4.0, 8.0, 12.0, 16.0, 24.0]) if quick
               else np.array([0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 14.0, 16.0, 20.0, 25.0,
                              30.0])) * 1e3
    profile = cloud_climatology()
    z, f = profile.altitude_m, profile.cover.detach()
    f64 = torch.float64
    atmosphere = eclipse_shadow(date, clouds="none").atmosphere
    left = {"clear": [], "clouds": []}
    for h in heights:
        for name in left:
            cloudy = name == "clouds"
            if h == 0.0:
                cover = LimbCloudCover(z, f, profile.limb_exponent if cloudy else 0.0)
            else:
                above = z > h + 1e-3
                rest = (torch.cat([profile.cover_at(torch.tensor(h + 1e-3, dtype=f64))[None],
                                   f[above]]) if cloudy
                        else torch.zeros(int(above.sum()) + 1, dtype=f64))
                nodes = torch.cat([torch.tensor([0.0, h, h + 1e-3], dtype=f64), z[above]])
                values = torch.cat([torch.ones(2, dtype=f64), rest])
                cover = LimbCloudCover(nodes, values,
                                       profile.limb_exponent if cloudy else 1.0)
            shadow = Shadow.earth(atmosphere, cloud_cover=cover)
            left[name].append(_band_offsets(shadow, distance, list(points.values()))[0]
                              .numpy())
    fractions = {name: 10.0 ** (-0.4 * (np.array(v) - v[0])) for name, v in left.items()}
    dims = ("periapsis_altitude", "position")
    dataset = xr.Dataset(
        {f"fraction_{name}": (dims, value, {"units": "1", "long_name": "V light left when "
                                             "rays below the altitude are blocked"})
         for name, value in fractions.items()},
        coords={"periapsis_altitude": ("periapsis_altitude", heights, {"units": "m"}),
                "position": list(points),
                "offset": ("position", np.array(list(points.values())), {"units": "m"})},
        attrs={"title": f"Light at greatest eclipse by periapsis altitude, {date}",
               "moon_distance_m": distance})
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(6, 4))
    for name, value in fractions.items():
        for k, point in enumerate(points):
            axis.plot(heights / 1e3, value[:, k], "o-" if name == "clouds" else "s:",
                      label=f"{point} ({name})")
    axis.set_yscale("log")
    axis.set_ylim(1e-4, 1.5)
    axis.set(xlabel="rays below this periapsis altitude removed [km]",
             ylabel="V light left", title=date)
    axis.legend(fontsize=7)
    figure.tight_layout()
    summary = {f"{name} {point} left above {h / 1e3:g} km": value[i, k]
               for name, value in fractions.items() for k, point in enumerate(points)
               for i, h in enumerate(heights) if h in (4e3, 8e3, 12e3)}
    return dataset, figure, summary


def _read_photometry(path=PHOTOMETRY_2019):
    """Read the times (datetime64[ns]), bands and magnitudes of the stored photometry."""
    import csv

    with open(path, newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(line for line in handle if not line.startswith("#")))
    times = np.array([row["time_utc"] for row in rows], dtype="datetime64[ns]")
    return times, np.array([row["band"] for row in rows]), np.array(
        [float(row["magnitude"]) for row in rows])


def light_curve_2019(quick: bool, date: str = "2019-01-21"):
    """Model the 2019-01-21 light curve and compare it with the printed photometry (V, B).

    Model interpolated linearly in time at the observed instants; residual model -
    observed [mag], for the cloud profile and for no clouds.
    """
    from skytorch.eclipse import lunar_eclipse

    n_times, n_v = (48, 96) if quick else (240, 192)
    times, bands, observed = _read_photometry()
    models, residuals = {}, {}
    for name, clouds in (("clouds", "rossow1999"), ("no clouds", "none")):
        ds = lunar_eclipse(date, shadow=eclipse_shadow(date, clouds=clouds),
                           n_times=n_times, n_images=0, table_n_v=n_v)
        t = ds.time.values.astype("datetime64[ns]").astype(np.int64).astype(float)
        models[name] = ds
        at = times.astype(np.int64).astype(float)
        model = np.where(bands == "V", np.interp(at, t, ds.v_magnitude.values),
                         np.interp(at, t, ds.b_magnitude.values))
        residuals[name] = model - observed
    dims = ("sample",)
    dataset = xr.Dataset(
        {"observed_magnitude": (dims, observed, {"units": "mag"}),
         "band": (dims, bands),
         **{f"residual_{name.replace(' ', '_')}": (dims, value, {"units": "mag",
            "long_name": "model minus observed"}) for name, value in residuals.items()},
         "model_time": ("time", models["clouds"].time.values),
         "model_v_magnitude": ("time", models["clouds"].v_magnitude.values,
                               {"units": "mag"}),
         "model_b_magnitude": ("time", models["clouds"].b_magnitude.values,
                               {"units": "mag"})},
        coords={"sample_time": (dims, times)},
        attrs={"title": f"Modelled and observed light curve, {date}",
               "source": "Georgia Journal of Science 80(1) art. 32 (SSP-3, Johnson B, V)"})
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(7, 4))
    for name, ds in models.items():
        for band, colour in (("v", "g"), ("b", "b")):
            axis.plot(ds.time.values, ds[f"{band}_magnitude"].values, colour,
                      ls="-" if name == "clouds" else ":",
                      label=f"model {band.upper()} ({name})")
    for band, colour in (("V", "g"), ("B", "b")):
        pick = bands == band
        axis.plot(times[pick], observed[pick], colour + "o", label=f"observed {band}")
    axis.set_xlim(times.min() - np.timedelta64(40, "m"), times.max() + np.timedelta64(40, "m"))
    axis.set_ylim(1.0, -6.0)
    axis.set(xlabel="UTC", ylabel="magnitude", title=date)
    axis.legend(fontsize=7)
    figure.autofmt_xdate()
    figure.tight_layout()
    summary = {f"{name} {band} {str(t)[11:19]}": r for name, value in residuals.items()
               for band, t, r in zip(bands, times, value, strict=True)}
    return dataset, figure, summary


def umbral_edge(quick: bool, date: str = "2015-09-28", distance_m: float = 3.844e8):
    """Where the modelled umbral edge falls: the steepest d log I / dr at 550 nm.

    Against the geometric umbra (no enlargement), as a percentage of its radius; the
    same for molecules only and the airless Earth (a check: 0 within the grid step), and
    Danjon's 1/85 rule through ``shadow_radii(enlargement="danjon")``.
    """
    from skytorch.constants import EARTH_MEAN_RADIUS_M
    from skytorch.eclipse import shadow_radii

    shadows = {"eclipse_shadow": eclipse_shadow(date),
               "molecules": Shadow.earth(Atmosphere.earth(aerosol_optical_depth=0.0,
                                                          ozone_du=0.0)),
               "airless": Shadow.earth(False),
               "latitude bands, azimuthal mean": eclipse_shadow(
                   date, terminator="latitude_bands_mean")}
    bands = eclipse_shadow(date, terminator="latitude_bands")
    directions = {"latitude bands, north (position angle 0)": 0.0,
                  "latitude bands, east/west (90 deg)": 0.5 * math.pi,
                  "latitude bands, south (180 deg)": math.pi}
    reference = shadows["airless"]
    radii = {kind: float(shadow_radii(distance_m, reference.sun_distance_m,
                                      reference.sun_radius_m, EARTH_MEAN_RADIUS_M,
                                      enlargement=kind)[0]) for kind in ("none", "danjon")}
    umbra = radii["none"]
    f64 = torch.float64
    offset = torch.linspace(0.85 * umbra, 1.15 * umbra, 151 if quick else 601, dtype=f64)
    wavelength = torch.tensor([550.0], dtype=f64)
    edges, curves = [], []
    along = torch.full_like(offset, distance_m)
    lights = [shadow.relative_illuminance(along, offset, wavelength)[..., 0]
              for shadow in shadows.values()]
    # every offset at the three position angles: (offset, angle, wavelength)
    resolved = bands.relative_illuminance(
        along, offset, wavelength,
        position_angle_rad=torch.tensor(list(directions.values()), dtype=f64))[..., 0]
    lights += list(resolved.unbind(-1))
    shadows.update(directions)
    for light in lights:
        slope = torch.gradient(torch.log10(light.clamp_min(1e-30)), spacing=(offset,))[0]
        edges.append(100.0 * (float(offset[int(torch.argmax(slope))]) / umbra - 1.0))
        curves.append(light.numpy())
    danjon = 100.0 * (radii["danjon"] / umbra - 1.0)
    dataset = xr.Dataset(
        {"relative_illuminance": (("model", "offset"), np.array(curves), {"units": "1"}),
         "umbral_enlargement": (("model",), np.array(edges),
                                {"units": "%", "long_name": "steepest d log I / dr beyond "
                                 "the geometric umbra"})},
        coords={"model": list(shadows), "offset": ("offset", offset.numpy(), {"units": "m"})},
        attrs={"title": f"Umbral edge of the modelled {date} shadow at 550 nm",
               "geometric_umbra_radius_m": umbra, "danjon_enlargement_percent": danjon,
               "observed_enlargement_percent": "1.7-1.9 (Vital 2004, 2008)"})
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(7, 4))
    for name, curve in zip(shadows, curves, strict=True):
        axis.semilogy(100.0 * (offset.numpy() / umbra - 1.0), curve, label=name)
    axis.axvspan(1.7, 1.9, color="0.8", label="observed 1.7-1.9 %")
    axis.axvline(danjon, color="k", ls="--", label="Danjon 1/85")
    axis.set(xlabel="offset beyond the geometric umbra [%]", ylabel="I / I_sun (550 nm)")
    axis.legend(fontsize=8)
    figure.tight_layout()
    summary = {f"edge {name} [%]": edge for name, edge in zip(shadows, edges, strict=True)}
    summary["Danjon 1/85 [%]"] = danjon
    return dataset, figure, summary


def _observed_v_only(quick: bool):
    """Observed eclipses with a printed V (the first only when ``quick``)."""
    observed = observed_lunar_eclipses()
    observed = observed.isel(eclipse=np.flatnonzero(np.isfinite(observed.v_magnitude.values)))
    return observed.isel(eclipse=[0]) if quick else observed


def _v_observation(observed, date) -> dict:
    """Return the V of one eclipse for the retrieval (printed σ, at least 0.1; 0.3 if none)."""
    printed = float(observed.v_uncertainty.sel(eclipse=date))
    sigma = max(printed, 0.1) if np.isfinite(printed) else 0.3
    return {"v_magnitude": (float(observed.v_magnitude.sel(eclipse=date)), sigma)}


def retrieval_series(quick: bool, terminator: str = "global"):
    """Stratospheric AOD retrieved from each observed V, beside the record's value.

    The V uncertainty is the printed one, at least 0.1 mag (0.3 mag where none is
    printed); the other parameters keep the ``eclipse_atmosphere`` defaults (with the
    latitude bands: the bands' own ozone, the same tropospheric aerosol).
    """
    from skytorch.eclipse import retrieve_atmosphere

    observed = _observed_v_only(quick)
    rows = []
    for date in observed.eclipse.values:
        day = np.datetime_as_string(date, "D")
        fit = retrieve_atmosphere(_v_observation(observed, date), day, terminator=terminator)
        rows.append((float(fit.best_fit[0]), float(fit.uncertainty[0]),
                     stratospheric_aod(day)))
    rows = np.array(rows)
    dims = ("eclipse",)
    dataset = xr.Dataset(
        {"retrieved_stratospheric_aod_550": (dims, rows[:, 0], {"units": "1"}),
         "retrieved_uncertainty": (dims, rows[:, 1], {"units": "1"}),
         "record_stratospheric_aod_550": (dims, rows[:, 2], {"units": "1"})},
        coords={"eclipse": observed.eclipse.values},
        attrs={"title": "Stratospheric AOD retrieved from observed lunar eclipses",
               "terminator": terminator})
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(7, 4))
    years = observed.eclipse.dt.year.values + observed.eclipse.dt.dayofyear.values / 366
    axis.errorbar(years, rows[:, 0], rows[:, 1], fmt="rs", label="retrieved from V")
    axis.plot(years, rows[:, 2], "ko", label="record (data/stratospheric_aod.csv)")
    axis.set(xlabel="year", ylabel="stratospheric AOD 550 nm")
    axis.legend()
    figure.tight_layout()
    summary = {f"{str(d)[:10]} retrieved": r for d, r in
               zip(observed.eclipse.values, rows[:, 0], strict=True)}
    return dataset, figure, summary


def retrieval_series_bands(quick: bool):
    """Retrieve the series through the latitude bands resolved in direction."""
    return retrieval_series(quick, terminator="latitude_bands")


def limb_cloud_series(quick: bool):
    """Retrieve the limb's clear probability at 7 km from each observed V.

    The stratosphere is the record's, the rest the ``eclipse_atmosphere`` defaults (global
    limb); against SAGE's 0.30 (tropics) - 0.60 (higher latitudes) and the terminator mean
    0.516 of ``cloud_climatology``.
    """
    from skytorch.eclipse import retrieve_atmosphere
    from skytorch.eclipse.eclipse_atmosphere import LIMB_CLEAR_7KM, SAGE_CLEAR_7KM

    observed = _observed_v_only(quick)
    rows = []
    for date in observed.eclipse.values:
        fit = retrieve_atmosphere(_v_observation(observed, date),
                                  np.datetime_as_string(date, "D"),
                                  parameters=("limb_clear_7km",))
        rows.append((float(fit.best_fit[0]), float(fit.uncertainty[0]),
                     bool(fit.at_bound[0]), float(fit.residual[0])))
    best, spread, at_bound, residual = (np.array(column) for column in zip(*rows, strict=True))
    dims = ("eclipse",)
    dataset = xr.Dataset(
        {"retrieved_limb_clear_7km": (dims, best, {"units": "1"}),
         "retrieved_uncertainty": (dims, spread, {"units": "1"}),
         "at_bound": (dims, at_bound),
         "residual_v": (dims, residual, {"units": "mag"})},
        coords={"eclipse": observed.eclipse.values},
        attrs={"title": "The limb's clear probability at 7 km retrieved from observed V",
               "sage_tropics": SAGE_CLEAR_7KM["tropics"],
               "sage_extratropics": SAGE_CLEAR_7KM["extratropics"],
               "climatology": LIMB_CLEAR_7KM})
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(7, 4))
    years = observed.eclipse.dt.year.values + observed.eclipse.dt.dayofyear.values / 366
    axis.axhspan(SAGE_CLEAR_7KM["tropics"], SAGE_CLEAR_7KM["extratropics"], color="0.9",
                 label="SAGE 1979-81: tropics - higher latitudes")
    axis.axhline(LIMB_CLEAR_7KM, color="k", ls=":", label="terminator mean (the default)")
    axis.errorbar(years, best, np.nan_to_num(spread), fmt="bs", label="retrieved from V")
    axis.set(xlabel="year", ylabel="limb clear-line-of-sight probability at 7 km",
             ylim=(0.0, 1.0))
    axis.legend(fontsize=7)
    figure.tight_layout()
    summary = {f"{str(d)[:10]} limb clear 7 km": r for d, r in
               zip(observed.eclipse.values, best, strict=True)}
    return dataset, figure, summary


def _observed_with_v():
    """Observed eclipses with a V (or a magnitude below the full Moon)."""
    observed = observed_lunar_eclipses()
    has = np.isfinite(observed.v_magnitude.values) | np.isfinite(
        observed.v_below_full_moon.values)
    return observed.isel(eclipse=np.flatnonzero(has))


def _residual(curve, observed, date) -> tuple[float, float, float]:
    """Model V, B-V at the faintest sample and model minus observed (V or below full)."""
    v, b_minus_v, below, _ = _faintest(curve)
    obs_v = float(observed.v_magnitude.sel(eclipse=date))
    obs_below = float(observed.v_below_full_moon.sel(eclipse=date))
    return v, b_minus_v, (v - obs_v if np.isfinite(obs_v) else below - obs_below)


def _terminator_variants(date: str) -> dict:
    """Shadows of one date: what each part of the latitude bands changes."""
    bands = terminator_bands(date)
    weights = [band.weight for band in bands]
    names = [band.profile for band in bands]
    saod = stratospheric_aod(date)

    def mixture(atmospheres, covers):
        return ShadowMixture([Shadow.earth(a, cloud_cover=c)
                              for a, c in zip(atmospheres, covers, strict=True)],
                             weights, names=names)

    global_atm = eclipse_shadow(date, clouds="none").atmosphere
    same_cover = [cloud_climatology()] * len(bands)
    zoned = [band.cloud_cover for band in bands]
    fixed_columns = [Atmosphere.earth(aerosol_optical_depth=TROPOSPHERIC_AOD_550,
                                      ozone_du=OZONE_DU, profile=afgl_profile(band.profile),
                                      stratospheric_aerosol_optical_depth=saod)
                     for band in bands]
    return {
        "global": eclipse_shadow(date),
        "global atmosphere, clouds by zone": mixture([global_atm] * len(bands), zoned),
        "AFGL T and p, 300 DU and 1.4 cm, global clouds": mixture(fixed_columns, same_cover),
        "AFGL T and p, 300 DU and 1.4 cm, clouds by zone": mixture(fixed_columns, zoned),
        "latitude bands (AFGL ozone and water, clouds by zone)":
            eclipse_shadow(date, terminator="latitude_bands_mean"),
        "latitude bands resolved in direction": eclipse_shadow(date,
                                                               terminator="latitude_bands"),
    }


def _near_limb_band(day: str) -> tuple[float, int]:
    """Latitude [deg] of the limb point nearest the Moon at greatest eclipse, its band.

    The limb point in the direction of the Moon's offset from the shadow's axis (true
    equator and equinox of date) lies at the latitude ``asin(u_z)`` of that unit vector.
    """
    from skytorch.eclipse.eclipse_atmosphere import TERMINATOR_BAND_BOUNDARIES_DEG
    from skytorch.eclipse.lunar import nearest_eclipse
    from skytorch.ephemeris import sun_moon_vectors

    row = nearest_eclipse(day).isel(eclipse=0)
    vectors = sun_moon_vectors(np.atleast_1d(row.time.values), frames=("tod",))
    sun, moon = vectors["sun_tod_m"][0], vectors["moon_tod_m"][0]
    axis = -sun / torch.linalg.norm(sun)
    offset = moon - (moon @ axis) * axis
    latitude = float(torch.rad2deg(torch.asin(offset[2] / torch.linalg.norm(offset))))
    edges = (-90.0, *TERMINATOR_BAND_BOUNDARIES_DEG, 90.0)
    return latitude, int(np.searchsorted(edges, latitude)) - 1


def terminator_comparison(quick: bool, date: str = "2015-09-28"):
    """Model the observed set with one global limb atmosphere and with latitude bands."""
    observed = _observed_with_v()
    n_times, n_v = (16, 96) if quick else (48, 192)
    models = ("global", "latitude_bands_mean", "latitude_bands")
    values = {model: [] for model in models}
    seconds = dict.fromkeys(models, 0.0)
    near, near_profile = [], []
    for day in observed.eclipse.values:
        text = np.datetime_as_string(day, "D")
        for model in models:
            start = time.perf_counter()
            curve = lunar_light_curve(text, shadow=eclipse_shadow(text, terminator=model),
                                      n_times=n_times, table_n_v=n_v)
            seconds[model] += time.perf_counter() - start
            values[model].append(_residual(curve, observed, day))
        latitude, k = _near_limb_band(text)
        band = terminator_bands(text)[k]
        curve = lunar_light_curve(text, shadow=Shadow.earth(band.atmosphere,
                                                            cloud_cover=band.cloud_cover),
                                  n_times=n_times, table_n_v=n_v)
        near.append((latitude, *_residual(curve, observed, day)))
        near_profile.append(band.profile)
    variants = _terminator_variants(date)
    parts = []
    for shadow in variants.values():
        curve = lunar_light_curve(date, shadow=shadow, n_times=n_times, table_n_v=n_v)
        parts.append(_residual(curve, observed, np.datetime64(date, "ns")))
    parts = np.array(parts)
    data, attrs = {}, {"title": "Lunar eclipses: one limb atmosphere or latitude bands",
                       "n_times": n_times, "table_n_v": n_v, "variant_date": date}
    for model in models:
        array = np.array(values[model])
        data[f"{model}_v_magnitude"] = ("eclipse", array[:, 0], {"units": "mag"})
        data[f"{model}_b_minus_v"] = ("eclipse", array[:, 1], {"units": "mag"})
        data[f"{model}_residual_v"] = ("eclipse", array[:, 2], {"units": "mag", "long_name":
                                       f"model ({model}) minus observed V"})
        attrs[f"{model}_rms_v_mag"] = float(np.sqrt(np.mean(array[:, 2] ** 2)))
        attrs[f"{model}_bias_v_mag"] = float(np.mean(array[:, 2]))
        attrs[f"{model}_scatter_v_mag"] = float(np.std(array[:, 2]))
        attrs[f"{model}_seconds"] = seconds[model]
    near = np.array(near)
    data["near_limb_latitude"] = ("eclipse", near[:, 0], {"units": "degree", "long_name":
                                  "latitude of the limb point nearest the Moon at greatest "
                                  "eclipse"})
    data["near_limb_profile"] = ("eclipse", np.array(near_profile))
    data["near_limb_v_magnitude"] = ("eclipse", near[:, 1], {"units": "mag", "long_name":
                                     "V with the near limb's band alone"})
    data["near_limb_residual_v"] = ("eclipse", near[:, 3], {"units": "mag"})
    attrs["near_limb_rms_v_mag"] = float(np.sqrt(np.mean(near[:, 3] ** 2)))
    attrs["near_limb_bias_v_mag"] = float(np.mean(near[:, 3]))
    data["variant_v_magnitude"] = ("variant", parts[:, 0], {"units": "mag"})
    data["variant_b_minus_v"] = ("variant", parts[:, 1], {"units": "mag"})
    data["variant_residual_v"] = ("variant", parts[:, 2], {"units": "mag"})
    dataset = xr.Dataset(data, coords={"eclipse": observed.eclipse.values,
                                       "variant": list(variants)}, attrs=attrs)
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(8, 4))
    years = observed.eclipse.dt.year.values + observed.eclipse.dt.dayofyear.values / 366
    for offset, model in ((-0.25, "global"), (0.0, "latitude_bands_mean"),
                          (0.25, "latitude_bands")):
        axis.bar(years + offset, dataset[f"{model}_residual_v"], width=0.25,
                 label=f"{model}: rms {attrs[f'{model}_rms_v_mag']:.2f}, bias "
                       f"{attrs[f'{model}_bias_v_mag']:+.2f} mag")
    axis.axhline(0.0, color="k", lw=0.5)
    axis.set(xlabel="year", ylabel="model - observed V [mag]",
             title="Observed lunar eclipses: the limb atmosphere along the terminator")
    axis.legend()
    figure.tight_layout()
    summary = {key: value for key, value in attrs.items() if key.endswith(("_mag", "seconds"))}
    return dataset, figure, summary


def position_angle_accuracy(quick: bool, date: str = "2015-09-28"):
    """V and B-V of the resolved latitude bands against position angles and arc nodes."""
    n_times, n_v = (16, 96) if quick else (48, 192)
    settings = ([(4, 8), (7, 8), (13, 8), (13, 16), (25, 16)] if quick else
                [(4, 8), (7, 8), (13, 8), (25, 8), (13, 16), (13, 32), (25, 32), (49, 32)])
    rows = []
    for n_angle, n_arc in settings:
        base = eclipse_shadow(date, terminator="latitude_bands", n_arc=n_arc)
        shadow = ShadowMixture(base.shadows, base.weights, base.names, base.limb_windows,
                               n_position_angle=n_angle)
        start = time.perf_counter()
        curve = lunar_light_curve(date, shadow=shadow, n_times=n_times, table_n_v=n_v)
        seconds = time.perf_counter() - start
        v, b_minus_v, _, _ = _faintest(curve)
        rows.append((n_angle, n_arc, v, b_minus_v, seconds))
    rows = np.array(rows)
    reference = rows[-1]
    dims = ("setting",)
    dataset = xr.Dataset(
        {"n_position_angle": (dims, rows[:, 0].astype(int)),
         "n_arc": (dims, rows[:, 1].astype(int)),
         "v_magnitude": (dims, rows[:, 2], {"units": "mag"}),
         "b_minus_v": (dims, rows[:, 3], {"units": "mag"}),
         "v_error": (dims, rows[:, 2] - reference[2], {"units": "mag", "long_name":
                     "V minus the finest setting's"}),
         "b_minus_v_error": (dims, rows[:, 3] - reference[3], {"units": "mag"}),
         "seconds": (dims, rows[:, 4], {"units": "s"})},
        coords={"setting": np.arange(len(rows))},
        attrs={"title": "Lunar eclipse resolved in direction: accuracy against cost",
               "date": date, "n_times": n_times, "table_n_v": n_v,
               "reference": f"{int(reference[0])} position angles, {int(reference[1])} arc "
                            "nodes"})
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(6, 4))
    for n_arc in np.unique(rows[:-1, 1]):
        pick = rows[:-1, 1] == n_arc
        axis.loglog(rows[:-1][pick, 4], np.abs(rows[:-1][pick, 2] - reference[2]) + 1e-4,
                    "o-", label=f"{int(n_arc)} arc nodes")
        for row in rows[:-1][pick]:
            axis.annotate(f"{int(row[0])}", (row[4], abs(row[2] - reference[2]) + 1e-4))
    axis.set(xlabel="light curve [s]", ylabel="|V - reference| + 1e-4 [mag]",
             title=f"{date}: position angles (labels) and arc nodes")
    axis.legend()
    figure.tight_layout()
    summary = {f"v_error_{int(r[0])}x{int(r[1])}": float(r[2] - reference[2]) for r in rows}
    return dataset, figure, summary


def main(argv=None) -> int:
    args = parse_arguments(__doc__.splitlines()[0], argv)
    for build, stem in ((comparison, "lunar_eclipse_comparison"),
                        (ingredients, "lunar_eclipse_ingredients"),
                        (altitude_contribution, "lunar_eclipse_altitudes"),
                        (light_curve_2019, "lunar_eclipse_light_curve_2019"),
                        (umbral_edge, "lunar_eclipse_umbral_edge"),
                        (retrieval_series, "lunar_eclipse_retrieval"),
                        (retrieval_series_bands, "lunar_eclipse_retrieval_bands"),
                        (limb_cloud_series, "lunar_eclipse_limb_clouds"),
                        (terminator_comparison, "lunar_eclipse_terminator"),
                        (position_angle_accuracy, "lunar_eclipse_position_angles")):
        dataset, figure, summary = build(args.quick)
        save_outputs(dataset, figure, args.output_dir, stem)
        for key, value in summary.items():
            print(f"{key}: {value:.6g}")
        if stem == "lunar_eclipse_comparison":
            print(dataset[["model_v_magnitude", "observed_v_magnitude",
                           "observed_v_below_full_moon", "model_v_below_full_moon",
                           "residual_v", "model_b_minus_v", "model_danjon_l",
                           "observed_danjon_l", "model_danjon_class",
                           "model_centre_v_magnitude", "model_rim_to_centre",
                           "model_rim_b_minus_v"]].to_dataframe().round(2).to_string())
        if stem == "lunar_eclipse_terminator":
            print(dataset.drop_dims("variant").to_dataframe().round(2).to_string())
            print(dataset.drop_dims("eclipse").to_dataframe().round(2).to_string())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
