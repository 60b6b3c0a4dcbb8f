"""Spectral resolution of the gas bands against the error in B, V, R, I of the direct beam.

The water vapour, O2 and O2-O2 optical depths (``skytorch.atmosphere.gases``) are
evaluated on grids of 1, 5 and 10 nm (360-920 nm, the B, V, R_C and I_C passbands), their
transmittance interpolated linearly onto a 0.1 nm grid and multiplied with everything else
(Rayleigh, aerosol, ozone and the ASTM G173 solar spectrum, all on the 0.1 nm grid); the
extinction of the direct beam in B, V, R and I and the colours B-V, V-R, V-I (Bessell 1990
passbands, ``skytorch.spectrum``; trapezoid rule on the 0.1 nm grid) is compared with the
gases on the 0.1 nm grid itself (reference; 0.05 nm changes it by less than 1e-5 mag).
The O2 A band (760 nm), the O2 B band (690 nm) and the 720, 820 and 940 nm water bands lie
in R and I. Paths (straight rays, Earth preset,
1.4 cm water): zenith angle 80 deg from sea level, and two-way limb paths from space
grazing at 5, 10 and 15 km (eclipse-like; refraction not included). Also listed: the error
of leaving the gases out, and the change from the pressure-scaling exponent m = 0.5 to 0
or 1 (a model uncertainty, not a resolution error). The band coefficients themselves have
the resolution of SPECTRL2's table (2.5-50 nm), so this measures how finely that model
must be sampled, not how close it is to line-by-line.

Writes ``gas_resolution_accuracy_cost.nc`` and ``.png`` (``--quick`` for a fast smoke run).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from experiments._common import parse_arguments, save_outputs  # noqa: E402
from skytorch.atmosphere import Atmosphere, gases  # noqa: E402
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable  # noqa: E402
from skytorch.spectrum import (  # noqa: E402
    b_band_response,
    i_band_response,
    r_band_response,
    solar_irradiance,
    v_band_response,
)

RANGE_NM = (360.0, 920.0)
RESPONSES = {"B": b_band_response, "V": v_band_response, "R": r_band_response,
             "I": i_band_response}
#: colour indices reported, as (bluer band, redder band)
COLOURS = (("B", "V"), ("V", "R"), ("V", "I"))
FINE_STEP_NM = 0.1
RESOLUTIONS_NM = (1.0, 5.0, 10.0)
GAS_NAMES = gases.GAS_SPECIES


def _grid(step):
    low, high = RANGE_NM
    n = int(round((high - low) / step)) + 1
    return torch.linspace(low, high, n, dtype=torch.float64)


def _paths(atm, quick):
    """Ray origins and direction cosines (path,) and their names."""
    names, r, mu = ["zenith 80 deg"], [atm.planet_radius_m], [math.cos(math.radians(80.0))]
    for tangent_km in ((10.0,) if quick else (5.0, 10.0, 15.0)):
        origin = atm.top_radius_m + 1000.0
        impact = atm.planet_radius_m + tangent_km * 1e3
        names.append(f"limb {tangent_km:g} km")
        r.append(origin)
        mu.append(-math.sqrt(1.0 - (impact / origin) ** 2))
    return names, torch.tensor(r, dtype=torch.float64), torch.tensor(mu, dtype=torch.float64)


def _optical_depths(atm, wavelength, r, mu, extra_species=()):
    c = atm.constituents(wavelength, extra_species=extra_species)
    return c.optical_depth(c.column_integrals(r, mu), per_species=True)


def _extinction_mag(transmittance, fine, solar):
    """Extinction in B, V, R, I [mag] of transmittance (path, wavelength) on the fine grid.

    -2.5 log10 of the solar- and passband-weighted mean transmittance, trapezoid rule on the fine
    grid itself (``spectrum_to_magnitude`` samples spectra at whole nanometres, which would hide
    sub-nanometre structure).
    """
    out = {}
    for band, response in RESPONSES.items():
        weight = solar * response(fine)
        mean = torch.trapezoid(transmittance * weight, fine) / torch.trapezoid(weight, fine)
        out[band] = (-2.5 * torch.log10(mean)).numpy()
    return out


def _timed(function, repeat):
    function()
    samples = []
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        samples.append(time.perf_counter() - start)
    return float(np.median(samples))


def run(quick):
    atm = Atmosphere.earth(aerosol_optical_depth=0.1, ozone_du=300.0,
                           precipitable_water_cm=1.4)
    names, r, mu = _paths(atm, quick)
    fine = _grid(FINE_STEP_NM)
    solar = solar_irradiance(fine)
    tau = _optical_depths(atm, fine, r, mu)
    rest = torch.exp(-sum(v for k, v in tau.items() if k not in GAS_NAMES))
    gas_fine = torch.exp(-sum(tau[k] for k in GAS_NAMES))
    reference = _extinction_mag(rest * gas_fine, fine, solar)
    rows = []

    def add(label, step, transmittance, seconds):
        mag = _extinction_mag(transmittance, fine, solar)
        for i, name in enumerate(names):
            row = {"path": name, "variant": label, "resolution": step, "time": seconds}
            error = {band: float(mag[band][i] - reference[band][i]) for band in RESPONSES}
            for band in RESPONSES:
                row[f"error_{band.lower()}"] = error[band]
            for blue, red in COLOURS:
                key = f"{blue}{red}".lower()
                row[f"error_{key}"] = error[blue] - error[red]
                row[f"reference_{key}"] = float(reference[blue][i] - reference[red][i])
            for band in RESPONSES:
                row[f"reference_{band.lower()}"] = float(reference[band][i])
            rows.append(row)

    repeat = 1 if quick else 5
    for step in RESOLUTIONS_NM:
        grid = _grid(step)

        def gas_on_grid(g=grid):
            t = _optical_depths(atm, g, r, mu)
            return torch.exp(-sum(t[k] for k in GAS_NAMES))

        seconds = _timed(gas_on_grid, repeat)
        coarse = gas_on_grid().numpy()
        interpolated = torch.tensor(np.stack([np.interp(fine.numpy(), grid.numpy(), row)
                                              for row in coarse]))
        add("sampled", step, rest * interpolated, seconds)
    seconds = _timed(lambda: _optical_depths(atm, fine, r, mu), repeat)
    add("reference", FINE_STEP_NM, rest * gas_fine, seconds)
    add("no gases", 0.0, rest, 0.0)
    # convergence of the reference: a 0.05 nm grid
    finer = _grid(FINE_STEP_NM / 2)
    tau_finer = _optical_depths(atm, finer, r, mu)
    finer_mag = _extinction_mag(torch.exp(-sum(tau_finer.values())), finer,
                                solar_irradiance(finer))
    convergence = max(float(np.abs(finer_mag[b] - reference[b]).max()) for b in RESPONSES)
    for exponent in (0.0, 1.0):
        extra = gases.species_builders(exponent, suffix="_alt")
        t = _optical_depths(atm, fine, r, mu, extra)
        alternative = torch.exp(-sum(t[k + "_alt"] for k in GAS_NAMES))
        add(f"exponent m={exponent:g}", FINE_STEP_NM, rest * alternative, 0.0)
    return rows, convergence, atm


def build(rows, convergence, atm):
    def column(key):
        values = np.array([row[key] for row in rows])
        return values if values.dtype.kind in "UO" else values.astype(float)

    unit = VariableSpec("1", "index", "Configuration index.")
    data_vars = {
        "path": variable("case", column("path"), VariableSpec(
            "1", "direct-beam path", "Straight rays: zenith 80 deg from sea level, or a "
            "two-way limb path from space grazing at the given tangent altitude.")),
        "variant": variable("case", column("variant"), VariableSpec(
            "1", "gas representation", "sampled: gas transmittance on the coarse grid, "
            "interpolated; no gases; exponent m: pressure scaling 0 or 1 instead of 0.5.")),
        "resolution": variable("case", column("resolution"), VariableSpec(
            "nm", "grid step of the gas optical depths", "")),
        "time": variable("case", column("time"), VariableSpec(
            "s", "time of the optical depths", "Median wall time, all paths, all species.")),
    }
    for band in RESPONSES:
        key = band.lower()
        data_vars[f"error_{key}"] = variable("case", column(f"error_{key}"), VariableSpec(
            "mag", f"error of the {band} extinction", "Against gases on the 0.1 nm grid."))
        data_vars[f"reference_{key}"] = variable("case", column(f"reference_{key}"),
                                                 VariableSpec(
            "mag", f"{band} extinction of the reference", ""))
    for blue, red in COLOURS:
        key = f"{blue}{red}".lower()
        data_vars[f"error_{key}"] = variable("case", column(f"error_{key}"), VariableSpec(
            "mag", f"error of {blue}-{red}", "Against gases on the 0.1 nm grid."))
        data_vars[f"reference_{key}"] = variable("case", column(f"reference_{key}"),
                                                 VariableSpec(
            "mag", f"{blue}-{red} reddening of the reference", ""))
    coords = {"case": coordinate("case", np.arange(len(rows)), unit)}
    return build_dataset(data_vars, coords,
                         title="Gas band resolution against B, V, R, I and colours of "
                               "the direct beam",
                         references=["Bird & Riordan 1986, doi:10.1175/1520-0450(1986)"
                                     "025<0087:SSSMFD>2.0.CO;2",
                                     "Karman et al. 2019, doi:10.1016/j.icarus.2019.02.034"],
                         parameters={**atm.parameters_dict(),
                                     "reference_convergence_mag": convergence},
                         threads=torch.get_num_threads())


def plot(dataset):
    import matplotlib.pyplot as plt

    panels = (("error_v", "|error of V| [mag]"), ("error_bv", "|error of B-V| [mag]"),
              ("error_r", "|error of R| [mag]"), ("error_i", "|error of I| [mag]"),
              ("error_vr", "|error of V-R| [mag]"), ("error_vi", "|error of V-I| [mag]"))
    figure, grid = plt.subplots(2, 3, figsize=(14, 7.5))
    axes = grid.ravel()
    sampled = (dataset["variant"] == "sampled").values
    for path in np.unique(dataset["path"].values):
        mask = sampled & (dataset["path"] == path).values
        res = dataset["resolution"].values[mask]
        for axis, (name, _) in zip(axes, panels, strict=True):
            axis.loglog(res, np.maximum(np.abs(dataset[name].values[mask]), 1e-7), "o-",
                        label=path)
    for axis, (_, title) in zip(axes, panels, strict=True):
        axis.set_xlabel("grid step of the gas bands [nm]")
        axis.set_ylabel(title)
        axis.legend(fontsize=7)
    figure.suptitle("gas band resolution (reference: 0.1 nm)")
    figure.tight_layout()
    return figure


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    rows, convergence, atm = run(arguments.quick)
    dataset = build(rows, convergence, atm)
    paths = save_outputs(dataset, plot(dataset), arguments.output_dir,
                         "gas_resolution_accuracy_cost")
    print(f"reference convergence (0.05 vs 0.1 nm): {convergence:.2e} mag")
    for row in rows:
        errors = "  ".join(f"d{name} {row['error_' + name.lower().replace('-', '')]:+.5f}"
                           for name in ("B", "V", "R", "I", "B-V", "V-R", "V-I"))
        print(f"{row['path']:>15} {row['variant']:>14} {row['resolution']:5.1f} nm  {errors}"
              f"  {row['time'] * 1e3:7.1f} ms  (V {row['reference_v']:.3f}, R "
              f"{row['reference_r']:.3f}, I {row['reference_i']:.3f}, B-V "
              f"{row['reference_bv']:.3f}, V-R {row['reference_vr']:.3f}, V-I "
              f"{row['reference_vi']:.3f})")
    return paths


if __name__ == "__main__":
    main()
