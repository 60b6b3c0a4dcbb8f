"""Accuracy versus cost of the scene fidelity presets ("fast", "default", "reference").

Two scenes, rendered at each preset (fisheye, RGB, float64, caches warm):

* low Sun — Paris, 2015-06-21 18:30 UTC (Sun about 10° high): the sky component is
  compared, at 64 fixed directions, with a direct single-scattering evaluation
  (:meth:`Atmosphere.sky_radiance` without look-up tables, 256 samples per ray, Sun
  transmittance integrated), i.e. an independent converged reference for the tables;
* eclipse night — Berlin, 2015-09-28 02:47 with a synthetic city of a million people
  (Moon in the umbra, stars, skyglow): the whole image is compared with the
  "reference" preset (L1 relative luminance error and the largest V-magnitude difference
  over the pixels).

The wall time of each render is measured on the same run. Output:
``scene_accuracy_cost.nc`` / ``.png``; ``--quick`` uses tiny images and two presets
("fast" and "reference" for the sky, "fast" and "default" for the night image, whose
errors are then relative to "default").
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402

PRESETS = ("fast", "default", "reference")


def _directions(n: int):
    generator = np.random.default_rng(0)
    altitude = np.degrees(np.arcsin(generator.uniform(0.02, 1.0, n)))
    azimuth = generator.uniform(0.0, 360.0, n)
    return altitude, azimuth


def sky_errors(presets, n_directions: int, samples: int):
    import skytorch as st
    from skytorch.spectrum import spectrum_to_xyz

    altitude, azimuth = _directions(n_directions)
    base = st.Scene(time="2015-06-21T18:30", lat_deg=48.85, lon_deg=2.35, view="directions",
                    directions={"altitude_deg": altitude, "azimuth_deg": azimuth},
                    exclude=("sun",), scattering_orders=1)
    # the single-scattering knobs against a converged single-scattering reference; the
    # orders of scattering have their own experiment (scene_ms_accuracy_cost.py)
    g = base.plan().geometry
    wl = base.wavelength_nm()
    zenith = torch.deg2rad(torch.tensor(90.0 - altitude))
    az = torch.deg2rad(torch.tensor(azimuth))
    reference = base.atmosphere().sky_radiance(
        wl, zenith, az, torch.full_like(zenith, math.radians(90.0 - g.sun_altitude_deg)),
        torch.full_like(zenith, math.radians(g.sun_azimuth_deg)), base.elevation_m,
        solar_irradiance=True, n_samples=samples, scattering_orders=1)
    y_ref = spectrum_to_xyz(reference, wl, luminous=True)[..., 1]
    rows = []
    for preset in presets:
        scene = base.replace(fidelity=preset)
        plan = scene.plan()
        scene.render(plan)  # warm caches
        start = time.perf_counter()
        ds = scene.render(plan)
        seconds = time.perf_counter() - start
        sky = torch.as_tensor(ds["component_radiance"].sel(component="sky").values)
        y = spectrum_to_xyz(sky, wl, luminous=True)[..., 1]
        rows.append((float(((y - y_ref).abs() / y_ref).max()),
                     float(((y - y_ref).abs()).sum() / y_ref.sum()), seconds))
    return np.array(rows)


def night_errors(presets, size: int):
    import skytorch as st
    from skytorch.commands.demo import CITY, SITE
    from skytorch.skyglow.citymap import synthetic_city

    city = synthetic_city(extent_m=60_000.0, cell_m=1_000.0, **CITY)
    results = {}
    for preset in presets:
        scene = st.Scene(time="2015-09-28T02:47", **SITE, size=size, light_map=city,
                         fidelity=preset, star_limit_mag=6.0, scattering_orders=1)
        plan = scene.plan()
        scene.render(plan)
        start = time.perf_counter()
        ds = scene.render(plan)
        results[preset] = (ds, time.perf_counter() - start)
    reference = results[presets[-1]][0]
    weight = reference["solid_angle"].values
    y_ref = reference["luminance"].values
    rows = []
    for preset in presets:
        ds, seconds = results[preset]
        y = ds["luminance"].values
        l1 = float((np.abs(y - y_ref) * weight).sum() / (y_ref * weight).sum())
        dmag = np.nanmax(np.abs(ds["v_mag_arcsec2"].values - reference["v_mag_arcsec2"].values))
        rows.append((l1, float(dmag), seconds))
    return np.array(rows)


def main(argv=None) -> int:
    args = parse_arguments(__doc__.splitlines()[0], argv)
    # quick: the sky at the two ends of the ladder; the night image (whose reference preset
    # needs the largest skyglow tables) between "fast" and "default"
    presets = ("fast", "reference") if args.quick else PRESETS
    sky = sky_errors(presets, 16 if args.quick else 64, 64 if args.quick else 256)
    night_presets = ("fast", "default") if args.quick else PRESETS
    night = night_errors(night_presets, 24 if args.quick else 256)
    from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable

    dims = ("preset",)
    night_dims = ("night_preset",)
    ds = build_dataset(
        {"sky_max_relative_error": variable(dims, sky[:, 0], VariableSpec(
            "1", "largest relative sky luminance error",
            "Against direct single scattering at fixed directions (low Sun scene).")),
         "sky_l1_relative_error": variable(dims, sky[:, 1], VariableSpec(
             "1", "L1 relative sky luminance error", "Sum |dY| / sum Y over the directions.")),
         "sky_seconds": variable(dims, sky[:, 2], VariableSpec(
             "s", "render time (directions view)", "Wall time of one render.")),
         "night_l1_relative_error": variable(night_dims, night[:, 0], VariableSpec(
             "1", "L1 relative luminance error", "Against the finest preset run.")),
         "night_max_mag_error": variable(night_dims, night[:, 1], VariableSpec(
             "mag arcsec-2", "largest V surface-brightness error",
             "Against the finest preset run, over the pixels.")),
         "night_seconds": variable(night_dims, night[:, 2], VariableSpec(
             "s", "render time (fisheye)", "Wall time of one render, caches warm."))},
        {"preset": coordinate("preset", np.array(presets), VariableSpec(
            "1", "fidelity preset", "skytorch.scene.planner.FIDELITY")),
         "night_preset": coordinate("night_preset", np.array(night_presets), VariableSpec(
             "1", "fidelity preset (night image)", "skytorch.scene.planner.FIDELITY"))},
        title="Scene fidelity presets: accuracy vs cost",
        parameters={"quick": bool(args.quick)})
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 2, figsize=(10, 4))
    for axis, (error, seconds, label, names) in zip(axes, (
            (sky[:, 0], sky[:, 2], "sky: max relative error vs direct single scattering",
             presets),
            (night[:, 0], night[:, 2], f"eclipse night: L1 error vs {night_presets[-1]}",
             night_presets)), strict=True):
        axis.loglog(seconds, np.maximum(error, 1e-8), "o-")
        for x, y, name in zip(seconds, np.maximum(error, 1e-8), names, strict=True):
            axis.annotate(name, (x, y), fontsize=8)
        axis.set_xlabel("render time [s]")
        axis.set_ylabel("error")
        axis.set_title(label, fontsize=9)
        axis.grid(alpha=0.3, which="both")
    figure.tight_layout()
    save_outputs(ds, figure, args.output_dir, "scene_accuracy_cost")
    for i, preset in enumerate(presets):
        print(f"sky   {preset:9s} max {sky[i, 0]:.2e} L1 {sky[i, 1]:.2e} ({sky[i, 2]:.2f} s)")
    for i, preset in enumerate(night_presets):
        print(f"night {preset:9s} L1 {night[i, 0]:.2e} max {night[i, 1]:.3f} mag "
              f"({night[i, 2]:.2f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
