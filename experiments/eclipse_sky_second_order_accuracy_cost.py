"""Accuracy versus cost of the solar-eclipse sky's second order of scattering.

Burgos (42.34 N, 3.70 W, 850 m) at totality, 2026-08-12 18:29:18 UTC (Sun 8.4° up),
turbidity 2, 550 nm: :func:`skytorch.scene.solar_eclipse_sky.eclipsed_second_order` on
three lines of sight (zenith; 60° from the zenith opposite the Sun; 85° at right angles
to it) for quadratures ``(n_view, n_mu, n_phi, n_samples)`` from coarse to fine, against
the finest as the converged reference; the wall time of each (three lines of sight, one
wavelength, one thread). The scene presets use ``(12, 4, 16, 8)`` ("fast"),
``(16, 4, 16, 16)`` ("default") and ``(48, 8, 32, 32)`` ("reference").

Convergence per dimension: with fine angles (8 direction cosines per hemisphere, 32
azimuths) the samples along the line of sight (``n_view`` 8–48, 16 samples per ray) and
along each ray of the first scattering (``n_samples`` 6–48, 24 along the line of sight),
each against the finest of its series.

Second knob: the scene's (zenith, azimuth) grid of the second order
(``"eclipse_ms_lut"``), linear or log interpolation, at 40 random lines of sight above 1°
against direct evaluations with the same quadrature (the scene's wavelengths).

Output: ``eclipse_sky_second_order_accuracy_cost.nc`` / ``.png``; ``--quick`` drops the two
finest quadratures (the reference is then ``(32, 6, 24, 24)``) and the finest of each
dimension's series, uses 10 lines of sight and two grids.
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

GRIDS = ((4, 8), (5, 10), (6, 12), (8, 16))
QUADRATURES = ((12, 2, 8, 8), (16, 3, 12, 12), (12, 4, 16, 8), (16, 4, 16, 16),
               (24, 4, 16, 16), (32, 6, 24, 24), (48, 8, 32, 32), (64, 12, 48, 48))
#: one dimension refined at a time, the others fine: (name, values, quadrature of a value)
DIMENSIONS = (("n_view", (8, 12, 16, 24, 48), lambda n: (n, 8, 32, 16)),
              ("n_samples", (6, 8, 16, 32, 48), lambda n: (24, 8, 32, n)))
BURGOS = (42.34, -3.70, 850.0)
TOTALITY = "2026-08-12T18:29:18"


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    import skytorch as st
    from skytorch.atmosphere.tables import TransmittanceTable
    from skytorch.scene.geometry import site_geometries
    from skytorch.scene.solar_eclipse_sky import eclipsed_second_order

    torch.set_num_threads(1)
    quadratures = QUADRATURES[:-2] if arguments.quick else QUADRATURES
    atmosphere = st.Atmosphere.earth(2.0)
    wavelength = torch.tensor([550.0], dtype=torch.float64)
    table = TransmittanceTable.build(atmosphere, wavelength, cache=False, n_mu=128, n_r=32)
    geometry = site_geometries(np.datetime64(TOTALITY), [BURGOS[0]], [BURGOS[1]],
                               [BURGOS[2]])[0]
    sun_azimuth = math.radians(geometry.sun_azimuth_deg)
    zenith = torch.tensor([0.0, math.radians(60.0), math.radians(85.0)], dtype=torch.float64)
    azimuth = torch.tensor([0.0, sun_azimuth + math.pi, sun_azimuth + 0.5 * math.pi],
                           dtype=torch.float64)
    def evaluate(quadrature):
        n_view, n_mu, n_phi, n_samples = quadrature
        start = time.perf_counter()
        value = eclipsed_second_order(atmosphere, wavelength, zenith, azimuth, geometry,
                                      BURGOS[2], n_view=n_view, n_mu=n_mu, n_phi=n_phi,
                                      n_samples=n_samples, table=table)[:, 0]
        return value.numpy(), time.perf_counter() - start

    values, seconds = (list(x) for x in zip(*(evaluate(q) for q in quadratures), strict=True))
    values = np.array(values)
    relative = values / values[-1] - 1.0
    labels = [f"{a}/{b}/{c}/{d}" for a, b, c, d in quadratures]
    line = ["zenith", "60 deg anti-Sun", "85 deg side"]
    dataset = xr.Dataset(
        {"second_order": (("quadrature", "line_of_sight"), values,
                          {"units": "sr-1", "long_name": "second-order radiance per unit "
                                                         "solar irradiance at 550 nm"}),
         "relative_error": (("quadrature", "line_of_sight"), relative,
                            {"units": "1", "long_name": "relative difference from the "
                                                        "finest quadrature"}),
         "seconds": ("quadrature", np.array(seconds),
                     {"units": "s", "long_name": "wall time, three lines of sight"})},
        coords={"quadrature": ("quadrature", labels,
                               {"long_name": "n_view/n_mu/n_phi/n_samples"}),
                "line_of_sight": ("line_of_sight", line, {"long_name": "line of sight"})},
        attrs={"title": "Solar-eclipse sky, second order: accuracy vs cost",
               "scene": f"Burgos {BURGOS}, {TOTALITY} UTC (totality), turbidity 2",
               "reference": labels[-1]})
    dataset = dataset.merge(_dimension_convergence(evaluate, arguments.quick))
    grids = ((4, 8), (6, 12)) if arguments.quick else GRIDS
    grid_error, grid_seconds = _grid_errors(grids, 10 if arguments.quick else 40)
    dataset["grid_error"] = (("grid", "interpolation", "statistic"), grid_error,
                             {"units": "1", "long_name": "relative look-up error of the "
                                                         "second order"})
    dataset["grid_seconds"] = ("grid", grid_seconds,
                               {"units": "s", "long_name": "wall time of the grid"})
    dataset = dataset.assign_coords(
        grid=("grid", [f"{a}x{b}" for a, b in grids], {"long_name": "zenith x azimuth nodes"}),
        interpolation=("interpolation", ["linear", "log"]),
        statistic=("statistic", ["median", "p90", "max"]))
    figure, axis = plt.subplots(figsize=(5, 3.5))
    for j, name in enumerate(line):
        axis.loglog(seconds[:-1], np.maximum(np.abs(relative[:-1, j]), 1e-6), "o-", label=name)
    for label, x, y in zip(labels[:-1], seconds[:-1],
                           np.maximum(np.abs(relative[:-1]).max(1), 1e-6), strict=True):
        axis.annotate(label, (x, y), fontsize=7)
    axis.set_xlabel("time, three lines of sight, one wavelength [s]")
    axis.set_ylabel(f"|relative difference from {labels[-1]}|")
    axis.set_title("eclipse sky at totality: second order")
    axis.legend(fontsize=7)
    save_outputs(dataset, figure, arguments.output_dir, "eclipse_sky_second_order_accuracy_cost")
    rows = ["| n_view/n_mu/n_phi/n_samples | zenith | 60° anti-Sun | 85° side | time [s] |",
            "| --- | --- | --- | --- | --- |"]
    for i, label in enumerate(labels):
        cells = " | ".join(f"{100 * r:+.1f} %" for r in relative[i])
        rows.append(f"| {label} | {cells} | {seconds[i]:.2f} |")
    print("\n".join(rows))
    rows = ["| grid | linear: median / p90 / max | log: median / p90 / max | time [s] |",
            "| --- | --- | --- | --- |"]
    for i, (a, b) in enumerate(grids):
        cells = [" / ".join(f"{100 * v:.1f} %" for v in grid_error[i, k]) for k in range(2)]
        rows.append(f"| {a} × {b} | {cells[0]} | {cells[1]} | {grid_seconds[i]:.2f} |")
    print("\n".join(rows))
    return dataset


def _dimension_convergence(evaluate, quick: bool) -> xr.Dataset:
    """Relative error of each dimension's series against its finest member; print a table."""
    variables, rows = {}, ["| dimension | value | zenith | 60° anti-Sun | 85° side |",
                           "| --- | --- | --- | --- | --- |"]
    for name, steps, quadrature in DIMENSIONS:
        steps = steps[:-1] if quick else steps
        values = np.array([evaluate(quadrature(n))[0] for n in steps])
        relative = values / values[-1] - 1.0
        variables[f"{name}_relative_error"] = (
            (name, "line_of_sight"), relative,
            {"units": "1", "long_name": f"relative difference from {name} = {steps[-1]}, "
                                        "the other dimensions fine"})
        variables[name] = (name, np.array(steps), {"long_name": name})
        rows += [f"| {name} | {n} | " + " | ".join(f"{100 * r:+.1f} %" for r in relative[i])
                 + " |" for i, n in enumerate(steps)]
    print("\n".join(rows))
    return xr.Dataset({key: value for key, value in variables.items()
                       if key not in ("n_view", "n_samples")},
                      coords={key: variables[key] for key in ("n_view", "n_samples")})


def _grid_errors(grids, n_lines):
    """Look-up errors (grid, linear/log, median/p90/max) of the scene's second-order grid."""
    import skytorch as st
    from skytorch.scene.render import Knobs, _lookup_full, eclipse_second_order_table
    from skytorch.scene.solar_eclipse_sky import eclipsed_second_order
    from skytorch.spectrum import solar_irradiance

    scene = st.Scene(time=TOTALITY, lat_deg=BURGOS[0], lon_deg=BURGOS[1],
                     elevation_m=BURGOS[2], size=16, fidelity="default")
    resources = scene.resources()
    geometry = resources.geometry(scene)
    knobs = Knobs.of(scene, scene.plan())
    wavelength = resources.wavelength_nm
    table = resources.transmittance_table(*knobs["transmittance"])
    n_view, n_mu, n_phi, n_samples = knobs["eclipse_ms"]
    rng = np.random.default_rng(1)
    zenith = torch.tensor(0.5 * math.pi - np.arcsin(rng.uniform(0.02, 1.0, n_lines)))
    azimuth = torch.tensor(rng.uniform(0.0, 2.0 * math.pi, n_lines))
    direct = torch.cat([
        eclipsed_second_order(resources.atmosphere, wavelength, zenith[i:i + 2],
                              azimuth[i:i + 2], geometry, BURGOS[2], n_view=n_view,
                              n_mu=n_mu, n_phi=n_phi, n_samples=n_samples, table=table)
        for i in range(0, n_lines, 2)]) * solar_irradiance(wavelength)
    errors, seconds = [], []
    for grid in grids:
        fidelity = dict(knobs.fidelity, eclipse_ms_lut=grid)
        start = time.perf_counter()
        second = eclipse_second_order_table(resources, geometry,
                                            Knobs(**{**knobs.__dict__, "fidelity": fidelity}),
                                            wavelength)
        seconds.append(time.perf_counter() - start)
        linear = _lookup_full(second, zenith, azimuth)
        logarithmic = torch.exp(_lookup_full(torch.log(second), zenith, azimuth))
        errors.append([[float(q) for q in (rel.median(), rel.quantile(0.9), rel.max())]
                       for rel in ((linear / direct - 1.0).abs(),
                                   (logarithmic / direct - 1.0).abs())])
    return np.array(errors), np.array(seconds)


if __name__ == "__main__":
    main()
