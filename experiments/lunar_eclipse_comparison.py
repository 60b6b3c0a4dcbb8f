"""Modelled lunar eclipses against the observed ones: V, B-V and Danjon L at mid-totality.

For every eclipse of ``observed_lunar_eclipses()`` with a V magnitude (or, for
2015-09-28, a magnitude below the full Moon) the Moon's light curve is modelled through
``eclipse_shadow(date)`` (the year's stratospheric sulfate layer, global-mean troposphere
and ozone, the ISCCP cloud deck; nothing fitted to eclipses) and compared at its faintest
sample: residual model - observed, rms and bias. Then, for one eclipse (2015-09-28), each
ingredient is added in turn (molecules only; + ozone; + tropospheric aerosol;
+ stratospheric aerosol; + clouds) to state what it changes.

Writes ``lunar_eclipse_comparison.nc`` / ``.png`` (per-eclipse table) and
``lunar_eclipse_ingredients.nc`` / ``.png`` (light curves of the ingredients),
``lunar_eclipse_umbral_edge`` (the modelled umbral edge) and ``lunar_eclipse_retrieval``
(stratospheric AOD retrieved from each observed V, beside the record).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import torch
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402
from skytorch.atmosphere import Atmosphere  # noqa: E402
from skytorch.eclipse import (  # noqa: E402
    Shadow,
    eclipse_shadow,
    lunar_light_curve,
    observed_lunar_eclipses,
    stratospheric_aod,
)
from skytorch.eclipse.eclipse_atmosphere import (  # noqa: E402
    CLOUD_FRACTION,
    CLOUD_TOP_ALTITUDE_M,
    OZONE_DU,
    TROPOSPHERIC_AOD_550,
)


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
    rows = []
    start = time.perf_counter()
    for date in observed.eclipse.values:
        day = np.datetime_as_string(date, "D")
        curve = lunar_light_curve(day, shadow=eclipse_shadow(day), n_times=n_times,
                                  table_n_v=n_v)
        rows.append((*_faintest(curve), stratospheric_aod(day)))
    seconds = time.perf_counter() - start
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
               "cloud_top_altitude_m": CLOUD_TOP_ALTITUDE_M,
               "cloud_fraction": CLOUD_FRACTION})
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
        stratospheric_aerosol_optical_depth=torch.tensor([0.0, 0.0, 0.0, saod], dtype=f64))
    clear = lunar_light_curve(date, shadow=Shadow.earth(atm), n_times=n_times,
                              table_n_v=n_v)
    cloudy = lunar_light_curve(date, shadow=eclipse_shadow(date), n_times=n_times,
                               table_n_v=n_v)
    values = [_faintest(clear, (i,)) for i in range(4)] + [_faintest(cloudy)]
    labels.append("+ clouds")
    curves = torch.cat([clear["v_magnitude"], cloudy["v_magnitude"][None]]).numpy()
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
        axis.plot(curve, label=label)
    axis.invert_yaxis()
    axis.set(xlabel="sample (P1-5% .. P4+5%)", ylabel="V [mag]", title=date)
    axis.legend(fontsize=8)
    figure.tight_layout()
    summary = {f"V {label}": v for label, v in zip(labels, values[:, 0], strict=True)}
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
               "airless": Shadow.earth(False)}
    reference = shadows["airless"]
    radii = {kind: float(shadow_radii(distance_m, reference.sun_distance_m,
                                      reference.sun_radius_m, EARTH_MEAN_RADIUS_M,
                                      enlargement=kind)[0]) for kind in ("none", "danjon")}
    umbra = radii["none"]
    f64 = torch.float64
    offset = torch.linspace(0.85 * umbra, 1.15 * umbra, 151 if quick else 601, dtype=f64)
    wavelength = torch.tensor([550.0], dtype=f64)
    edges, curves = [], []
    for shadow in shadows.values():
        light = shadow.relative_illuminance(torch.full_like(offset, distance_m), offset,
                                            wavelength)[..., 0]
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


def retrieval_series(quick: bool):
    """Stratospheric AOD retrieved from each observed V, beside the record's value.

    The V uncertainty is the printed one, at least 0.1 mag (0.3 mag where none is
    printed); the other parameters keep the ``eclipse_atmosphere`` defaults.
    """
    from skytorch.eclipse import retrieve_atmosphere

    observed = observed_lunar_eclipses()
    observed = observed.isel(eclipse=np.flatnonzero(np.isfinite(observed.v_magnitude.values)))
    if quick:
        observed = observed.isel(eclipse=[0])
    rows = []
    for date in observed.eclipse.values:
        day = np.datetime_as_string(date, "D")
        printed = float(observed.v_uncertainty.sel(eclipse=date))
        sigma = max(printed, 0.1) if np.isfinite(printed) else 0.3
        fit = retrieve_atmosphere(
            {"v_magnitude": (float(observed.v_magnitude.sel(eclipse=date)), sigma)}, day)
        rows.append((float(fit.best_fit[0]), float(fit.uncertainty[0]),
                     stratospheric_aod(day)))
    rows = np.array(rows)
    dims = ("eclipse",)
    dataset = xr.Dataset(
        {"retrieved_stratospheric_aod_550": (dims, rows[:, 0], {"units": "1"}),
         "retrieved_uncertainty": (dims, rows[:, 1], {"units": "1"}),
         "record_stratospheric_aod_550": (dims, rows[:, 2], {"units": "1"})},
        coords={"eclipse": observed.eclipse.values},
        attrs={"title": "Stratospheric AOD retrieved from observed lunar eclipses"})
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


def main(argv=None) -> int:
    args = parse_arguments(__doc__.splitlines()[0], argv)
    for build, stem in ((comparison, "lunar_eclipse_comparison"),
                        (ingredients, "lunar_eclipse_ingredients"),
                        (umbral_edge, "lunar_eclipse_umbral_edge"),
                        (retrieval_series, "lunar_eclipse_retrieval")):
        dataset, figure, summary = build(args.quick)
        save_outputs(dataset, figure, args.output_dir, stem)
        for key, value in summary.items():
            print(f"{key}: {value:.6g}")
        if stem == "lunar_eclipse_comparison":
            print(dataset[["model_v_magnitude", "observed_v_magnitude",
                           "observed_v_below_full_moon", "model_v_below_full_moon",
                           "residual_v", "model_b_minus_v", "model_danjon_l",
                           "observed_danjon_l"]].to_dataframe().round(2).to_string())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
