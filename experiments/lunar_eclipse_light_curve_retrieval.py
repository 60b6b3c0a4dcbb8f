"""The atmosphere of the 2019-01-21 lunar eclipse retrieved from its photometric light curve.

The six samples of the published SSP-3 photometry (Georgia Journal of Science 80(1) art.
32: three in V, three in B, 04:43-05:31 UTC; ``tests/data/lunar_eclipse_2019_01_21_photometry
.csv``) are fitted with :func:`skytorch.eclipse.retrieve_atmosphere` in its light-curve
form (each sample modelled at its own time and in its band, global limb atmosphere of
``eclipse_atmosphere`` with the limb cloud profile):

* the stratospheric AOD alone, from V only and from V and B;
* the stratospheric and tropospheric AOD and the ozone column together, from V and B;
* the stratospheric AOD with the limb cloud profile's clear-line-of-sight probability at
  7 km (``cloud_climatology``; SAGE measured 0.30-0.60), and with the ozone column too.

The paper prints no uncertainty per sample: each gets 0.1 mag (the floor of the
mid-totality series in ``lunar_eclipse_comparison.py``). With equal uncertainties the best
fit does not depend on that choice; the Laplace uncertainties scale with it and chi2 with
its inverse square. Outputs ``lunar_eclipse_light_curve_retrieval.{nc,png}``: the fits,
their uncertainties, residuals and CPU times, and the model light curves of the prior
(the ``eclipse_atmosphere`` defaults of the date) and of each fit.

Run: ``python experiments/lunar_eclipse_light_curve_retrieval.py [--quick]``.
"""

from __future__ import annotations

import time

import numpy as np
import torch
import xarray as xr

from experiments._common import parse_arguments, save_outputs
from experiments.lunar_eclipse_comparison import _read_photometry

DATE = "2019-01-21"
#: uncertainty given to each printed sample [mag]
SAMPLE_UNCERTAINTY_MAG = 0.1
#: (label, bands used, fitted parameters)
FITS = (("stratospheric AOD from V", ("V",), ("stratospheric_aod_550",)),
        ("stratospheric AOD from V and B", ("V", "B"), ("stratospheric_aod_550",)),
        ("three parameters from V and B", ("V", "B"),
         ("stratospheric_aod_550", "tropospheric_aod", "ozone_du")),
        ("stratospheric AOD and limb clouds from V and B", ("V", "B"),
         ("stratospheric_aod_550", "limb_clear_7km")),
        ("stratospheric AOD, ozone and limb clouds from V and B", ("V", "B"),
         ("stratospheric_aod_550", "ozone_du", "limb_clear_7km")))


def _observations(bands_used):
    times, bands, magnitude = _read_photometry()
    keep = np.isin(bands, bands_used)
    return xr.Dataset({"time": ("sample", times[keep]), "band": ("sample", bands[keep]),
                       "magnitude": ("sample", magnitude[keep]),
                       "uncertainty": ("sample", np.full(keep.sum(), SAMPLE_UNCERTAINTY_MAG))})


def _curve(parameters: dict, times, table_n_v: int):
    from skytorch.eclipse import lunar_light_curve
    from skytorch.eclipse.retrieval import retrieval_shadow

    with torch.no_grad():
        curve = lunar_light_curve(DATE, shadow=retrieval_shadow(DATE, parameters),
                                  times=times, table_n_v=table_n_v)
    return curve["v_magnitude"].numpy(), curve["b_magnitude"].numpy()


def retrieval(quick: bool):
    """Fit the light curve; model curves of the prior and of each fit."""
    from skytorch.eclipse import retrieve_atmosphere
    from skytorch.eclipse.retrieval import PARAMETERS

    table_n_v, n_curve = (32, 24) if quick else (64, 121)
    fits = FITS[:1] if quick else FITS
    all_times, all_bands, all_observed = _read_photometry()
    grid = (np.datetime64(f"{DATE}T04:00") + np.linspace(0, 150, n_curve).astype(int)
            * np.timedelta64(1, "m")).astype("datetime64[ns]")
    names = PARAMETERS
    best = np.full((len(fits), len(names)), np.nan)
    spread = np.full((len(fits), len(names)), np.nan)
    residual = np.full((len(fits), all_times.size), np.nan)
    chi2, seconds = np.zeros(len(fits)), np.zeros(len(fits))
    curves = [_curve({}, grid, table_n_v)]
    for i, (_, bands_used, fitted) in enumerate(fits):
        start = time.process_time()
        fit = retrieve_atmosphere(_observations(bands_used), DATE, parameters=fitted,
                                  table_n_v=table_n_v, max_iter=30)
        seconds[i] = time.process_time() - start
        chi2[i] = fit.attrs["chi2"]
        for name in fitted:
            best[i, names.index(name)] = float(fit.best_fit.sel(parameter=name))
            spread[i, names.index(name)] = float(fit.uncertainty.sel(parameter=name))
        parameters = {name: float(fit.best_fit.sel(parameter=name)) for name in fitted}
        v, b = _curve(parameters, all_times, table_n_v)
        residual[i] = np.where(all_bands == "V", v, b) - all_observed
        curves.append(_curve(parameters, grid, table_n_v))
    prior_v, prior_b = _curve({}, all_times, table_n_v)
    prior_residual = np.where(all_bands == "V", prior_v, prior_b) - all_observed
    labels = [label for label, _, _ in fits]
    dataset = xr.Dataset(
        {"best_fit": (("fit", "parameter"), best, {"units": "1, 1, DU"}),
         "uncertainty": (("fit", "parameter"), spread,
                         {"long_name": "Laplace uncertainty (NaN: not fitted)"}),
         "residual": (("fit", "sample"), residual,
                      {"units": "mag", "long_name": "model minus observed"}),
         "prior_residual": (("sample",), prior_residual, {"units": "mag"}),
         "observed_magnitude": (("sample",), all_observed, {"units": "mag"}),
         "band": (("sample",), all_bands),
         "chi2": (("fit",), chi2),
         "cpu_seconds": (("fit",), seconds, {"units": "s"}),
         "model_v_magnitude": (("curve", "time"), np.stack([c[0] for c in curves]),
                               {"units": "mag"}),
         "model_b_magnitude": (("curve", "time"), np.stack([c[1] for c in curves]),
                               {"units": "mag"})},
        coords={"fit": labels, "parameter": list(names), "sample_time": ("sample", all_times),
                "time": grid, "curve": ["prior", *labels]},
        attrs={"title": f"Atmosphere retrieved from the light curve of {DATE}",
               "sample_uncertainty_mag": SAMPLE_UNCERTAINTY_MAG, "table_n_v": table_n_v,
               "source": "Georgia Journal of Science 80(1) art. 32 (SSP-3, Johnson B, V)"})
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(7, 4.5))
    styles = ("-", "--", "-.", ":")
    for k, label in enumerate(dataset.curve.values):
        for band, colour in (("v", "g"), ("b", "b")):
            axis.plot(grid, dataset[f"model_{band}_magnitude"].values[k], colour,
                      ls=styles[k % len(styles)], label=f"{band.upper()}: {label}")
    for band, colour in (("V", "g"), ("B", "b")):
        pick = all_bands == band
        axis.plot(all_times[pick], all_observed[pick], colour + "o", label=f"observed {band}")
    axis.set_ylim(1.0, -6.0)
    axis.set(xlabel="UTC", ylabel="magnitude", title=f"{DATE}: light-curve retrieval")
    axis.legend(fontsize=6)
    figure.autofmt_xdate()
    figure.tight_layout()
    summary = {}
    for i, label in enumerate(labels):
        for j, name in enumerate(names):
            if np.isfinite(best[i, j]):
                summary[f"{label}: {name}"] = best[i, j]
                summary[f"{label}: {name} uncertainty"] = spread[i, j]
        summary[f"{label}: rms residual"] = float(np.sqrt(np.mean(residual[i] ** 2)))
        summary[f"{label}: chi2"] = chi2[i]
        summary[f"{label}: cpu seconds"] = seconds[i]
    summary["prior: rms residual"] = float(np.sqrt(np.mean(prior_residual ** 2)))
    return dataset, figure, summary


def main(argv=None) -> int:
    args = parse_arguments(__doc__.splitlines()[0], argv)
    dataset, figure, summary = retrieval(args.quick)
    save_outputs(dataset, figure, args.output_dir, "lunar_eclipse_light_curve_retrieval")
    for key, value in summary.items():
        print(f"{key}: {value:.6g}")
    print(dataset.residual.reset_coords(drop=True).to_pandas().round(3).to_string())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
