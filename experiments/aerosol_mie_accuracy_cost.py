"""Mie size integrals of the aerosol types: error versus nodes and ln r span, and cost.

The OPAC type tables (``data/make_aerosol_tables.py``) integrate Mie efficiencies over
each lognormal component with the trapezoid rule on nodes uniform in ln r over OPAC's
[r_min, r_max]. This experiment scales every component's node count (``node_scale``
times the shipped 600 to 2400 of ``N_NODES_COMPONENT``) and
shrinks the ln r interval about the mode radius (``span_scale`` 1 = OPAC's bounds), and
compares the extinction relative to 550 nm, the single-scattering albedo and the
asymmetry g at 350 and 1000 nm with a reference at 4x the shipped nodes on the full span.
The cost is the wall time of the three-wavelength evaluation (miepython, one core).

Usage: ``python experiments/aerosol_mie_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr

from experiments._common import load_script, parse_arguments, save_outputs

GENERATOR = Path(__file__).resolve().parents[1] / "data" / "make_aerosol_tables.py"
TYPES = ("continental_average", "desert", "maritime_clean")
NODE_SCALES = (0.125, 0.25, 0.5, 1.0, 2.0)
SPAN_SCALES = (0.75, 1.0)
REFERENCE_NODE_SCALE = 4.0
WAVELENGTH_NM = (350.0, 1000.0)


def evaluate(gen, name, wavelength, node_scale, span_scale):
    """(ratio, albedo, g) at ``wavelength`` and the wall time [s]."""
    start = time.perf_counter()
    ext, sca, g = gen.type_averages(name, np.append(wavelength, 550.0),
                                    node_scale=node_scale, span_scale=span_scale)
    seconds = time.perf_counter() - start
    return gen.ratio_albedo_g(ext, sca, g), seconds


def main(argv=None):
    args = parse_arguments(__doc__.splitlines()[0], argv)
    gen = load_script(GENERATOR, "make_aerosol_tables")
    types = ("continental_clean",) if args.quick else TYPES
    node_scales = (0.125, 0.25, 0.5) if args.quick else NODE_SCALES
    span_scales = (0.75, 1.0) if args.quick else SPAN_SCALES
    reference_scale = 1.0 if args.quick else REFERENCE_NODE_SCALE
    wavelength = np.array(WAVELENGTH_NM)
    shape = (len(types), len(span_scales), len(node_scales))
    ratio_error, albedo_error, g_error, seconds = (np.zeros(shape) for _ in range(4))
    for i, name in enumerate(types):
        (ref_ratio, ref_albedo, ref_g), _ = evaluate(gen, name, wavelength, reference_scale,
                                                     1.0)
        for j, span in enumerate(span_scales):
            for k, scale in enumerate(node_scales):
                (ratio, albedo, g), cost = evaluate(gen, name, wavelength, scale, span)
                ratio_error[i, j, k] = np.max(np.abs(ratio / ref_ratio - 1.0))
                albedo_error[i, j, k] = np.max(np.abs(albedo - ref_albedo))
                g_error[i, j, k] = np.max(np.abs(g - ref_g))
                seconds[i, j, k] = cost
    dims = ("aerosol_type", "span_scale", "node_scale")
    result = xr.Dataset(
        {"extinction_ratio_error": (dims, ratio_error), "albedo_error": (dims, albedo_error),
         "asymmetry_error": (dims, g_error), "seconds": (dims, seconds)},
        coords={"aerosol_type": list(types), "span_scale": list(span_scales),
                "node_scale": list(node_scales)})
    result["extinction_ratio_error"].attrs.update(
        units="1", long_name="largest relative error of extinction(lambda)/extinction(550)")
    result["albedo_error"].attrs.update(units="1",
                                        long_name="largest error of the single-scattering albedo")
    result["asymmetry_error"].attrs.update(units="1", long_name="largest error of g")
    result["seconds"].attrs.update(units="s", long_name="wall time, 3 wavelengths")
    result["node_scale"].attrs.update(units="1", long_name="nodes / shipped nodes")
    result["span_scale"].attrs.update(units="1",
                                      long_name="ln r interval / OPAC's [r_min, r_max]")
    result.attrs.update(title="Aerosol Mie size integrals: error versus nodes and span",
                        wavelengths_nm=str(list(WAVELENGTH_NM)),
                        reference=f"node_scale {reference_scale}, span_scale 1")

    figure, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, name in enumerate(types):
        for axis, error in zip(axes, (ratio_error, albedo_error, g_error), strict=True):
            for j, span in enumerate(span_scales):
                axis.loglog(node_scales, np.maximum(error[i, j], 1e-12),
                            "o-" if span == 1.0 else ":", color=colours[i % len(colours)],
                            label=name if span == 1.0 else None)
    for axis, label in zip(axes, ("extinction ratio, relative", "albedo", "g"), strict=True):
        axis.axhline(1e-4, color="k", ls="--", lw=0.8)
        axis.set_xlabel("node scale (1 = shipped)")
        axis.set_ylabel(f"max error, {label}")
        axis.set_title(f"{label} (solid: full span; dotted: shrunk)")
    axes[0].legend(fontsize=8)
    paths = save_outputs(result, figure, args.output_dir, "aerosol_mie_accuracy_cost")
    print(result.to_dataframe().to_string())
    return paths


if __name__ == "__main__":
    main()
