"""Light scattered two or more times into the eclipse shadows of the Earth and Mars.

Part 1 — across the umbra (offset 0, 0.25, 0.5, 0.75 of the umbra's radius) of the Earth
at the Moon's mean distance and of Mars at Phobos' and Deimos' orbits, at 450 / 550 /
650 nm: the refracted direct light (``Shadow.relative_illuminance`` without scattering),
the single scattering (``scattering=True`` minus that) and the orders >= 2
(``Shadow.multiple_scattered_illuminance``, the final gather of the atmosphere's
converged multiple-scattering tables along the ring's lines of sight). Default
``Atmosphere.earth()`` and ``Atmosphere.mars()`` (background dust, Wolff et al. 2009
albedo spectrum).

Part 2 — accuracy vs cost of the ring quadrature (``n_impact`` × ``n_azimuth``) on the
axis: the orders >= 2 against the finest setting, with the time per point.

Writes ``shadow_multiple_scattering.nc`` / ``.png``. Run:
``python experiments/shadow_multiple_scattering.py [--quick] [--output-dir DIR]``.
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
from skytorch.atmosphere.multiple_scattering import (  # noqa: E402
    TableResolution,
    precompute_scattering,
)
from skytorch.constants import SUN_RADIUS_M  # noqa: E402
from skytorch.eclipse.shadow import Shadow  # noqa: E402

WAVELENGTHS_NM = (450.0, 550.0, 650.0)
#: (label, shadow preset, distance behind the centre [m])
CASES = (("Earth at the Moon", "earth", 384.4e6), ("Mars at Phobos", "mars", 9376e3),
         ("Mars at Deimos", "mars", 23463e3))
OFFSET_FRACTIONS = (0.0, 0.25, 0.5, 0.75)
#: (n_impact, n_azimuth); the last is the finest, the reference of part 2
RING_NODES = ((6, 4), (12, 6), (16, 8), (24, 12), (32, 16))
#: coarse tables (seconds) for --quick
COARSE = TableResolution(n_r=16, n_mu=32, n_mu_s=16, n_phi=6, n_ray=24, n_sphere_mu=6,
                         transmittance_r=32, transmittance_mu=128, mu_vertical_weight=0.0,
                         r_ground_weight=0.0, sphere_phi_refinement=1, ray_quadrature="trapezoid")


def _umbra_radius(shadow, distance_m: float) -> float:
    """Radius of the geometric umbra (the solid occluder's) at ``distance_m`` [m]."""
    half_angle = math.asin((SUN_RADIUS_M - shadow.occluder_radius_m) / shadow.sun_distance_m)
    return shadow.occluder_radius_m / math.cos(half_angle) - distance_m * math.tan(half_angle)


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    quick = arguments.quick
    wavelength = torch.tensor(WAVELENGTHS_NM, dtype=torch.float64)
    # the default TableResolution before 2026-12-05, on which docs/accuracy.md's numbers are
    resolution = COARSE if quick else TableResolution(n_r=16, n_mu_s=24, n_ray=48,
                                                      mu_vertical_weight=0.0,
                                                      r_ground_weight=0.0, sphere_phi_refinement=1,
                                                      ray_quadrature="trapezoid")
    cases = CASES[:2] if quick else CASES
    ring_nodes = RING_NODES[:2] if quick else RING_NODES
    n_off = len(OFFSET_FRACTIONS)
    shape = (len(cases), n_off, len(WAVELENGTHS_NM))
    refracted, single, higher = np.zeros(shape), np.zeros(shape), np.zeros(shape)
    seconds = np.zeros(len(cases))
    nodes_error = np.zeros((len(cases), len(ring_nodes), len(WAVELENGTHS_NM)))
    nodes_seconds = np.zeros((len(cases), len(ring_nodes)))
    offsets = np.zeros((len(cases), n_off))
    tables_by_body = {}
    for i, (_, body, distance_m) in enumerate(cases):
        shadow = getattr(Shadow, body)(scattering=True)
        plain = getattr(Shadow, body)()
        if body not in tables_by_body:
            tables_by_body[body] = precompute_scattering(
                shadow.atmosphere, wavelength, scattering_orders="converged",
                resolution=resolution)
        tables = tables_by_body[body]
        offsets[i] = np.array(OFFSET_FRACTIONS) * _umbra_radius(shadow, distance_m)
        distance = torch.full((n_off,), distance_m, dtype=torch.float64)
        offset = torch.tensor(offsets[i], dtype=torch.float64)
        direct = plain.relative_illuminance(distance, offset, wavelength)
        refracted[i] = direct.numpy()
        single[i] = (shadow.relative_illuminance(distance, offset, wavelength) - direct).numpy()
        clock = time.perf_counter()
        higher[i] = shadow.multiple_scattered_illuminance(distance, offset, tables).numpy()
        seconds[i] = (time.perf_counter() - clock) / n_off
        values = []
        for k, (n_impact, n_azimuth) in enumerate(ring_nodes):
            clock = time.perf_counter()
            values.append(shadow.multiple_scattered_illuminance(
                distance[:1], offset[:1], tables, n_impact=n_impact,
                n_azimuth=n_azimuth)[0].numpy())
            nodes_seconds[i, k] = time.perf_counter() - clock
        for k in range(len(ring_nodes)):
            nodes_error[i, k] = np.abs(values[k] / values[-1] - 1.0)
    labels = [label for label, _, _ in cases]
    dims = ("case", "offset_fraction", "wavelength")
    dataset = xr.Dataset(
        {"refracted": (dims, refracted, {"units": "1", "long_name": "refracted direct "
                                         "sunlight over the unobstructed Sun"}),
         "single_scattering": (dims, single, {"units": "1", "long_name": "light scattered "
                                              "once, over the unobstructed Sun"}),
         "higher_orders": (dims, higher, {"units": "1", "long_name": "light scattered two "
                                          "or more times, over the unobstructed Sun"}),
         "offset": (("case", "offset_fraction"), offsets, {"units": "m"}),
         "higher_orders_seconds_per_point": (("case",), seconds, {"units": "s"}),
         "ring_nodes_error": (("case", "ring_nodes", "wavelength"), nodes_error,
                              {"units": "1", "long_name": "relative difference from the "
                               "finest ring quadrature, on the axis"}),
         "ring_nodes_seconds": (("case", "ring_nodes"), nodes_seconds, {"units": "s"})},
        coords={"case": ("case", np.array(labels)),
                "distance": ("case", np.array([d for _, _, d in cases]), {"units": "m"}),
                "offset_fraction": ("offset_fraction", np.array(OFFSET_FRACTIONS),
                                    {"long_name": "offset over the umbra's radius"}),
                "wavelength": ("wavelength", np.array(WAVELENGTHS_NM), {"units": "nm"}),
                "ring_nodes": ("ring_nodes", np.array([f"{a} x {b}" for a, b in ring_nodes]),
                               {"long_name": "n_impact x n_azimuth"})},
        attrs={"title": "Light scattered into the eclipse shadow: orders >= 2",
               "tables": "16x64x24x8, n_ray 48, converged" if not quick else "coarse",
               "torch_threads": torch.get_num_threads()})
    figure, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8))
    colours = ("tab:blue", "tab:green", "tab:red")
    for i, label in enumerate(labels):
        style = ("o-", "s--", "^:")[i]
        for k, colour in enumerate(colours):
            left.semilogy(OFFSET_FRACTIONS, higher[i, :, k] / single[i, :, k], style,
                          color=colour, label=f"{label}, {WAVELENGTHS_NM[k]:.0f} nm")
    left.set_xlabel("offset / umbra radius")
    left.set_ylabel("orders ≥ 2 / single scattering")
    left.legend(fontsize=6)
    for i, label in enumerate(labels):
        right.loglog(nodes_seconds[i, :-1], np.maximum(nodes_error[i, :-1].max(-1), 1e-7),
                     "o-", label=label)
    right.set_xlabel("time per point [s]")
    right.set_ylabel("|relative difference| from the finest ring")
    right.set_title("ring quadrature, on the axis")
    right.legend(fontsize=7)
    save_outputs(dataset, figure, arguments.output_dir, "shadow_multiple_scattering")
    for i, label in enumerate(labels):
        print(f"{label} ({seconds[i]:.1f} s per point):")
        for j, fraction in enumerate(OFFSET_FRACTIONS):
            row = {name: " ".join(f"{x:.3g}" for x in values[i, j]) for name, values in
                   (("refracted", refracted), ("single", single), ("higher", higher))}
            print(f"  offset {fraction}: " + ", ".join(f"{k} [{v}]" for k, v in row.items()))
        print("  ring nodes", [f"{a}x{b}" for a, b in ring_nodes], "error",
              np.round(nodes_error[i].max(-1), 4).tolist(), "s",
              np.round(nodes_seconds[i], 2).tolist())
    return 0


if __name__ == "__main__":
    sys.exit(main())
