"""Skyglow beyond single scattering: the Monte-Carlo factor and what its precision costs.

Part 1 — the factor (all orders over the single-scattering kernel) of a ground source
with Garstang's emission function (F 0.1, G 0.15), source radius 250 m, black ground, for
an observer on the ground: distances 0.5–50 km, lines of sight at the zenith and at 10°
and 30° elevation towards the source and away from it, 440 / 550 / 680 nm,
``Atmosphere.earth(turbidity=T)`` for T = 2 and 4 (line estimator, ``--paths`` paths per
line of sight, 30 orders).

Part 2 — accuracy vs cost of ``multiple_scattering_paths``: the factor's error against a
run with 16× as many paths (another seed), at the zenith and at 10° towards the source,
10 km away, 550 nm, turbidity 2; the collision estimator (every order scored at its own
collision, no kernel) with as many paths and as much time for comparison.

Writes ``skyglow_multiple_scattering.nc`` / ``.png``. Run:
``python experiments/skyglow_multiple_scattering.py [--quick] [--output-dir DIR]``.
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
from skytorch.skyglow.kernel import Medium  # noqa: E402
from skytorch.skyglow.multiple_scattering import skyglow_scattering_orders  # noqa: E402

WAVELENGTHS_NM = (440.0, 550.0, 680.0)
TURBIDITIES = (2.0, 4.0)
#: (label, elevation [deg], azimuth from the source [deg])
LINES = (("zenith", 90.0, 0.0), ("10 deg towards", 10.0, 0.0), ("10 deg away", 10.0, 180.0),
         ("30 deg towards", 30.0, 0.0), ("30 deg away", 30.0, 180.0))
SOURCE_RADIUS_M = 250.0
COST_PATHS = (250, 1000, 4000, 16000)


def _factor_part(distance, n_paths):
    """Factor and its error (turbidity, line, distance, wavelength)."""
    factor, error, seconds = [], [], []
    elevation = torch.deg2rad(torch.tensor([e for _, e, _ in LINES], dtype=torch.float64))
    azimuth = torch.deg2rad(torch.tensor([a for _, _, a in LINES], dtype=torch.float64))
    for turbidity in TURBIDITIES:
        medium = Medium(Atmosphere.earth(turbidity=turbidity), list(WAVELENGTHS_NM))
        clock = time.perf_counter()
        orders = skyglow_scattering_orders(medium, azimuth[:, None], elevation[:, None],
                                           distance[None, :], n_paths=n_paths,
                                           source_radius_m=SOURCE_RADIUS_M, seed=11)
        seconds.append(time.perf_counter() - clock)
        factor.append(orders.factor.numpy())
        error.append(orders.factor_error.numpy())
    return np.array(factor), np.array(error), np.array(seconds)


def _cost_part(paths, reference_paths):
    """Error of the factor vs paths for both estimators, and the times (estimator, line, paths)."""
    medium = Medium(Atmosphere.earth(turbidity=2.0), [550.0])
    elevation = torch.deg2rad(torch.tensor([90.0, 10.0], dtype=torch.float64))
    common = {"source_radius_m": SOURCE_RADIUS_M}
    reference = skyglow_scattering_orders(medium, 0.0, elevation, 10e3, n_paths=reference_paths,
                                          seed=99, **common).factor[:, 0].numpy()
    error = np.zeros((2, 2, len(paths)))
    seconds = np.zeros((2, len(paths)))
    for k, estimator in enumerate(("line", "collision")):
        for j, n in enumerate(paths):
            clock = time.perf_counter()
            factor = skyglow_scattering_orders(medium, 0.0, elevation, 10e3, n_paths=n,
                                               estimator=estimator, seed=5 + j,
                                               **common).factor[:, 0].numpy()
            seconds[k, j] = time.perf_counter() - clock
            error[k, :, j] = np.abs(factor - reference)
    return reference, error, seconds


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    quick = arguments.quick
    distance = torch.tensor([0.5e3, 2e3, 10e3] if quick else
                            [0.5e3, 1e3, 2e3, 5e3, 10e3, 20e3, 50e3], dtype=torch.float64)
    n_paths = 200 if quick else 20_000
    paths = COST_PATHS[:2] if quick else COST_PATHS
    reference_paths = 1000 if quick else 16 * COST_PATHS[-1]
    factor, error, seconds = _factor_part(distance, n_paths)
    reference, cost_error, cost_seconds = _cost_part(paths, reference_paths)
    lines = [label for label, _, _ in LINES]
    dataset = xr.Dataset(
        {"factor": (("turbidity", "line_of_sight", "distance", "wavelength"), factor,
                    {"units": "1", "long_name": "all orders of scattering over the first"}),
         "factor_error": (("turbidity", "line_of_sight", "distance", "wavelength"), error,
                          {"units": "1", "long_name": "standard error of the factor"}),
         "factor_seconds": (("turbidity",), seconds,
                            {"units": "s", "long_name": "wall time of part 1 per turbidity"}),
         "reference_factor": (("cost_line",), reference,
                              {"units": "1", "long_name": "factor with 16x the paths"}),
         "cost_error": (("estimator", "cost_line", "paths"), cost_error,
                        {"units": "1", "long_name": "absolute error of the factor"}),
         "cost_seconds": (("estimator", "paths"), cost_seconds,
                          {"units": "s", "long_name": "wall time of both lines of sight"})},
        coords={"turbidity": ("turbidity", np.array(TURBIDITIES)),
                "line_of_sight": ("line_of_sight", np.array(lines)),
                "elevation": ("line_of_sight", np.array([e for _, e, _ in LINES]),
                              {"units": "degree"}),
                "azimuth": ("line_of_sight", np.array([a for _, _, a in LINES]),
                            {"units": "degree", "long_name": "azimuth from the source"}),
                "distance": ("distance", distance.numpy(), {"units": "m"}),
                "wavelength": ("wavelength", np.array(WAVELENGTHS_NM), {"units": "nm"}),
                "estimator": ("estimator", np.array(["line", "collision"])),
                "cost_line": ("cost_line", np.array(["zenith", "10 deg towards"])),
                "paths": ("paths", np.array(paths))},
        attrs={"title": "Skyglow: multiple-scattering factor of a ground source",
               "paths_per_line_of_sight": n_paths, "reference_paths": reference_paths,
               "source_radius_m": SOURCE_RADIUS_M, "emission": "garstang1986",
               "observer_altitude_m": 0.0, "torch_threads": torch.get_num_threads()})
    figure, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8))
    for i, label in enumerate(lines):
        left.semilogx(distance.numpy() / 1e3, factor[0, i, :, 1], "o-", label=label)
    left.semilogx(distance.numpy() / 1e3, factor[1, 0, :, 1], "k--", label="zenith, T 4")
    left.set_xlabel("distance of the source [km]")
    left.set_ylabel("all orders / single scattering")
    left.set_title("550 nm, turbidity 2")
    left.legend(fontsize=7)
    for k, estimator in enumerate(("line", "collision")):
        for j, line in enumerate(("zenith", "10 deg towards")):
            right.loglog(cost_seconds[k], cost_error[k, j], "o-" if k == 0 else "s--",
                         label=f"{estimator}, {line}")
    right.set_xlabel("time of both lines of sight [s]")
    right.set_ylabel("|factor - reference|")
    right.set_title("accuracy vs cost (10 km, 550 nm)")
    right.legend(fontsize=7)
    save_outputs(dataset, figure, arguments.output_dir, "skyglow_multiple_scattering")
    rows = ["| line of sight | " + " | ".join(f"{d / 1e3:g} km" for d in distance.tolist())
            + " |", "| --- " * (len(distance) + 1) + "|"]
    for i, label in enumerate(lines):
        rows.append(f"| {label} | " + " | ".join(
            f"{factor[0, i, j, 1]:.2f}" for j in range(len(distance))) + " |")
    print("\n".join(rows))
    for k, estimator in enumerate(("line", "collision")):
        print(estimator, "paths", list(paths), "seconds", np.round(cost_seconds[k], 2).tolist(),
              "errors", np.round(cost_error[k], 4).tolist())
    return 0


if __name__ == "__main__":
    sys.exit(main())
