r"""``skytorch skyglow``: artificial sky brightness panorama from a city light map.

Examples
--------
::

    skytorch skyglow --synthetic --lat 43.6 --lon 1.44 -o sky.nc --png sky.png
    skytorch skyglow --lights map.nc --observer-x 12000 --observer-y -3000 \
        --model skyglow_model.nc -o sky.nc
    skytorch skyglow --synthetic --save-model model.nc --components 64 -o sky.nc

The light map is a netCDF file with variable ``flux`` [lm] on ``(y, x)``, coordinates in
metres east/north, and optionally ``altitude`` [m]. Without ``--model`` the PCA + FFT
tables are precomputed for the given atmosphere (minutes at full resolution); save them
with ``--save-model`` and reuse them with ``--model``.
"""

from __future__ import annotations

import argparse
import logging

from skytorch._validate import check_range

logger = logging.getLogger(__name__)


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``skytorch skyglow``."""
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--lights", help="netCDF light map (flux [lm] on y, x in metres)")
    source.add_argument("--synthetic", action="store_true",
                        help="use a synthetic city (100 000 inhabitants, 1000 lm each)")
    where = parser.add_argument_group("observer")
    where.add_argument("--lat", type=float, help="observer latitude [deg] (recorded)")
    where.add_argument("--lon", type=float, help="observer longitude [deg] (recorded)")
    where.add_argument("--observer-x", type=float, default=0.0,
                       help="observer position east in the map frame [m] (default 0)")
    where.add_argument("--observer-y", type=float, default=0.0,
                       help="observer position north in the map frame [m] (default 0)")
    where.add_argument("--observer-altitude", type=float, default=0.0,
                       help="observer altitude [m] (default 0)")
    model = parser.add_argument_group("model")
    model.add_argument("--model", help="precomputed model file (from --save-model)")
    model.add_argument("--save-model", help="write the precomputed model to this file")
    model.add_argument("--turbidity", type=float,
                       help="atmospheric turbidity (1 = no aerosols; default 2)")
    model.add_argument("--emission",
                       help="upward emission function: garstang1986 (default), lambertian, "
                            "dobashi2023")
    model.add_argument("--n-azimuth", type=int, help="default 128")
    model.add_argument("--n-elevation", type=int, help="default 32")
    model.add_argument("--n-distance", type=int, help="default 64")
    model.add_argument("--max-distance", type=float,
                       help="largest source distance [m] (default 20000)")
    model.add_argument("--components", type=int, help="PCA components M (default 32)")
    model.add_argument("--steps", type=int,
                       help="Gauss nodes per half view ray (default 8: kernel error 0.014 %% "
                            "mean, 0.36 %% max)")
    model.add_argument("--kernel-dtype", choices=("float64", "float32"),
                       help="dtype of the kernel quadrature (float32: about twice as fast, "
                            "within 0.01 %% of float64; the PCA stays float64)")
    parser.add_argument("--lamp", default="led4000k",
                        help="lamp spectrum: white, incandescent, led3000k, led4000k, hps, lps")
    parser.add_argument("-o", "--output", required=True, help="netCDF file to write")
    parser.add_argument("--png", help="also draw the panorama into this PNG file")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")


#: the model options and their values when a model is built (None on the command line:
#: not given, which --model requires)
MODEL_DEFAULTS = {"turbidity": 2.0, "emission": "garstang1986", "n_azimuth": 128,
                  "n_elevation": 32, "n_distance": 64, "max_distance": 20_000.0,
                  "components": 32, "steps": 8, "kernel_dtype": "float64"}


def _plot(ds, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(10, 3.2))
    brightness = ds["total_brightness"]
    image = axis.pcolormesh(ds["azimuth"].values, ds["elevation"].values, brightness.values,
                            cmap="magma_r", shading="nearest")
    axis.set_xlabel("azimuth [degree] (0 = north, 90 = east)")
    axis.set_ylabel("elevation [degree]")
    axis.set_title("Sky brightness with artificial light [mag arcsec$^{-2}$, V]")
    figure.colorbar(image, ax=axis, label="mag arcsec$^{-2}$")
    figure.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(figure)


def _model(args: argparse.Namespace):
    """Load the model of ``--model`` or build one from the model options."""
    from skytorch.skyglow.model import SkyglowModel

    given = [name for name in MODEL_DEFAULTS if getattr(args, name) is not None]
    if args.model:
        if given:
            # a loaded model is already built: its settings would be ignored
            raise ValueError(f"{', '.join('--' + n.replace('_', '-') for n in given)}: "
                             f"settings of a model to build, not of --model {args.model}")
        if args.save_model:
            raise ValueError(f"--save-model {args.save_model}: writes a model this command "
                             f"builds, not the one read with --model {args.model}")
        model = SkyglowModel.load(args.model)
    else:
        import torch

        from skytorch.atmosphere import Atmosphere

        if args.observer_altitude != 0.0:  # before the precomputation
            raise ValueError(f"--observer-altitude must be 0 m for the model this command "
                             f"builds (one observer-altitude node at the ground); got "
                             f"{args.observer_altitude:g} m (a model with more altitude "
                             f"nodes comes from SkyglowModel.precompute("
                             f"n_observer_altitude=...), read with --model)")
        options = {name: MODEL_DEFAULTS[name] if getattr(args, name) is None
                   else getattr(args, name) for name in MODEL_DEFAULTS}
        model = SkyglowModel.precompute(
            Atmosphere.earth(turbidity=options["turbidity"]), n_azimuth=options["n_azimuth"],
            n_elevation=options["n_elevation"], n_distance=options["n_distance"],
            max_distance_m=options["max_distance"], n_components=options["components"],
            emission=options["emission"], n_steps=options["steps"],
            progress=not args.no_progress,
            compute_dtype=getattr(torch, options["kernel_dtype"]))
        if args.save_model:
            model.save(args.save_model)
            logger.info("model written to %s", args.save_model)
    nodes = model.observer_altitude_m
    low, high = float(nodes.min()), float(nodes.max())
    if not low - 1e-6 <= args.observer_altitude <= high + 1e-6:
        # the Python API clamps with a warning; here the command's models have one node
        raise ValueError(f"--observer-altitude must be within the model's observer "
                         f"altitudes [{low:g}, {high:g}] m; got {args.observer_altitude:g} m "
                         f"(a model with more altitude nodes comes from "
                         f"SkyglowModel.precompute(n_observer_altitude=...), read with "
                         f"--model)")
    return model


def run(args: argparse.Namespace) -> int:
    """Render the panorama and write the files."""
    from skytorch.dataset import open_dataset, to_netcdf
    from skytorch.skyglow.citymap import synthetic_city
    from skytorch.skyglow.model import light_map_arrays

    for name, low, high in (("lat", -90.0, 90.0), ("lon", -180.0, 360.0)):
        if getattr(args, name) is not None:
            check_range(f"--{name}", getattr(args, name), low, high, unit=" degree")
    light_map = synthetic_city() if args.synthetic else open_dataset(args.lights)
    light_map_arrays(light_map)  # fail early on a bad map, before any precomputation
    model = _model(args)
    ds = model.render(light_map, observer_xy=(args.observer_x, args.observer_y),
                      observer_altitude_m=args.observer_altitude, lamp=args.lamp)
    if args.lat is not None:
        ds.attrs["observer_lat_deg"] = args.lat
    if args.lon is not None:
        ds.attrs["observer_lon_deg"] = args.lon
    to_netcdf(ds, args.output)
    zenith = float(ds["total_brightness"].isel(elevation=-1).mean())
    print(f"zenith sky brightness {zenith:.2f} mag/arcsec^2 V -> {args.output}")
    if args.png:
        _plot(ds, args.png)
    return 0
