"""Accuracy vs cost of the airglow scattered into the line of sight (quadrature nodes).

Knobs of :func:`skytorch.nightsky.scattered_light.scattered_diffuse_radiance`: the nodes
along the line of sight (``n_steps``, default 96), in the incoming zenith cosine
(``n_mu``, default 16) and in the relative azimuth (``n_azimuth``, default 8), each varied
with the others at their defaults, against a converged run (192 × 64 × 16). Source: the
airglow layer at 90 km (van Rhijn brightening of each incoming ray), observer at sea
level, ``Atmosphere.earth()`` (turbidity 2, 300 DU, 1.4 cm water), view zeniths of the
scene's table (0–90°), 440 / 560 / 660 nm. Error: largest relative error over views and
wavelengths; cost: median wall time (1 torch thread). Writes
``scattered_light_accuracy_cost.nc`` / ``.png``.

Run: ``python experiments/scattered_light_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._harness import median_seconds  # noqa: E402
from experiments._common import parse_arguments, save_outputs  # noqa: E402
from skytorch.atmosphere import Atmosphere  # noqa: E402
from skytorch.nightsky.airglow import layer_path_factor  # noqa: E402
from skytorch.nightsky.scattered_light import scattered_diffuse_radiance  # noqa: E402
from skytorch.scene.resources import SCATTERED_AIRGLOW_ZENITH_DEG  # noqa: E402

DEFAULT = {"n_steps": 96, "n_mu": 16, "n_azimuth": 8}
REFERENCE = {"n_steps": 192, "n_mu": 64, "n_azimuth": 16}
VARIANTS = {"n_steps": (8, 16, 32, 48, 96, 128), "n_mu": (4, 8, 16, 32), "n_azimuth": (2, 4, 8, 16)}
LAYER_HEIGHT_M = 90_000.0


def _airglow(planet_radius_m: float):
    def incident(mu, altitude):
        return layer_path_factor(mu, altitude, layer_height_m=LAYER_HEIGHT_M,
                                 planet_radius_m=planet_radius_m)[..., None]

    return incident


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    torch.set_num_threads(1)
    atm = Atmosphere.earth()
    zenith = torch.deg2rad(torch.tensor(SCATTERED_AIRGLOW_ZENITH_DEG, dtype=torch.float64))
    wavelength = torch.tensor([440.0, 560.0, 660.0], dtype=torch.float64)
    incident = _airglow(atm.planet_radius_m)
    variants = {key: values[:2] for key, values in VARIANTS.items()} if arguments.quick \
        else VARIANTS
    reference_nodes = DEFAULT if arguments.quick else REFERENCE
    reference = scattered_diffuse_radiance(atm, zenith, wavelength, incident, **reference_nodes)
    labels, knob, value, error, seconds = [], [], [], [], []
    for key, values in variants.items():
        for n in values:
            nodes = {**DEFAULT, key: n}

            def run(nodes=nodes):
                return scattered_diffuse_radiance(atm, zenith, wavelength, incident, **nodes)

            result = run()
            labels.append(f"{key}={n}")
            knob.append(key)
            value.append(n)
            error.append(float(((result - reference).abs() / reference).max()))
            seconds.append(median_seconds(run, repeat=1 if arguments.quick else 3, warmup=0))
    dataset = xr.Dataset(
        {"max_rel_error": ("variant", np.array(error),
                           {"units": "1", "long_name": "largest relative error over views "
                            "and wavelengths"}),
         "seconds": ("variant", np.array(seconds),
                     {"units": "s", "long_name": "median wall time, 1 thread"}),
         "knob": ("variant", np.array(knob)), "nodes": ("variant", np.array(value))},
        coords={"variant": ("variant", np.array(labels))},
        attrs={"title": "Airglow scattered into the line of sight: accuracy vs cost",
               "reference": str(reference_nodes), "default": str(DEFAULT),
               "atmosphere": "Atmosphere.earth()", "layer_height_m": LAYER_HEIGHT_M,
               "n_view": int(zenith.numel()), "wavelength_nm": "440, 560, 660"})
    figure, axis = plt.subplots(figsize=(5, 3.5))
    for key in variants:
        chosen = dataset.where(dataset.knob == key, drop=True)
        axis.loglog(chosen.seconds, np.maximum(chosen.max_rel_error, 1e-12), "o-", label=key)
    axis.set_xlabel(f"time of {zenith.numel()} views x 3 wl [s]")
    axis.set_ylabel("largest relative error")
    axis.set_title("scattered airglow: quadrature nodes")
    axis.legend(fontsize=8)
    save_outputs(dataset, figure, arguments.output_dir, "scattered_light_accuracy_cost")
    rows = ["| variant | max rel error | time [s] |", "| --- | --- | --- |"]
    rows += [f"| {label} | {e:.2e} | {t:.2f} |"
             for label, e, t in zip(labels, error, seconds, strict=True)]
    print("\n".join(rows))
    return dataset


if __name__ == "__main__":
    main()
