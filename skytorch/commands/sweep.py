"""``skytorch sweep``: a parameter sweep described in a TOML file, written to netCDF or Zarr.

The TOML file names the function by import path and gives one list per swept parameter;
constant keyword arguments go in ``[fixed]`` and options of :func:`skytorch.sweep.sweep`
in ``[options]``::

    function = "skytorch.spectrum:bv_to_temperature"

    [parameters]
    bv = [0.0, 0.3, 0.65, 1.0]

    [fixed]        # optional: keyword arguments passed unchanged at every point

    [options]      # optional: backend, chunk_size, memory_budget_bytes, store, key,
    backend = "serial"   # n_workers, scheduler_address, cluster_options, units = {bv = "mag"}

The output format follows the suffix of ``-o``: ``*.zarr`` writes a Zarr store (optional
``zarr`` package, ``pip install 'skytorch[zarr]'``), anything else netCDF-4.

Examples
--------
::

    skytorch sweep sweep.toml -o out/sweep.nc
    skytorch sweep sweep.toml -o out/sweep.zarr
    skytorch sweep sweep.toml -o out/sweep.nc --backend dask --workers 2 --store out/chunks
    skytorch sweep sweep.toml -o out/sweep.nc --backend dask --workers 2 --processes

TOML is read with the standard library's ``tomllib`` (Python >= 3.11) or, on Python 3.10,
with the ``tomli`` package when it is installed.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import json
import logging
from pathlib import Path

from skytorch._toml import loads as toml_loads

logger = logging.getLogger(__name__)

#: option names accepted in the TOML ``[options]`` table
OPTIONS = ("backend", "chunk_size", "memory_budget_bytes", "store", "key", "n_workers",
           "scheduler_address", "cluster_options", "units", "progress")


def resolve_function(path: str):
    """Import the callable named ``"package.module:function"`` (attributes may be dotted)."""
    if not isinstance(path, str) or ":" not in path:
        raise ValueError(f"function must be given as 'module:function'; got {path!r}")
    module_name, attribute = path.split(":", 1)
    try:
        target = importlib.import_module(module_name)
    except ModuleNotFoundError as error:
        raise ValueError(f"cannot import module {module_name!r} for function {path!r}") from error
    for part in attribute.split("."):
        if not hasattr(target, part):
            raise ValueError(f"module {module_name!r} has no attribute {attribute!r}")
        target = getattr(target, part)
    if not callable(target):
        raise ValueError(f"{path!r} is not callable")
    return target


def load_config(path: str | Path) -> dict:
    """Read and check a sweep TOML file; returns function, parameters, fixed, options."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"sweep configuration {str(path)!r} not found")
    config = toml_loads(path.read_text(encoding="utf-8"))
    unknown = set(config) - {"function", "parameters", "fixed", "options"}
    if unknown:
        raise ValueError(f"unknown keys in {path.name}: {sorted(unknown)} (valid: function, "
                         "parameters, fixed, options)")
    if "function" not in config:
        raise ValueError(f"{path.name} must name the function: function = 'module:function'")
    parameters = config.get("parameters", {})
    if not isinstance(parameters, dict) or not parameters:
        raise ValueError(f"{path.name} needs a [parameters] table with one list per parameter")
    fixed = config.get("fixed", {})
    if not isinstance(fixed, dict):
        raise ValueError(f"{path.name}: [fixed] must be a table of keyword arguments")
    both = sorted(set(parameters) & set(fixed))
    if both:
        raise ValueError(f"{path.name}: {both} in both [parameters] and [fixed] (a keyword is "
                         "swept or fixed, not both)")
    options = dict(config.get("options", {}))
    bad = set(options) - set(OPTIONS)
    if bad:
        raise ValueError(f"unknown [options] {sorted(bad)}; valid: {OPTIONS}")
    return {"function": resolve_function(config["function"]), "parameters": parameters,
            "fixed": dict(config.get("fixed", {})), "options": options,
            "function_path": config["function"]}


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``skytorch sweep`` to ``parser``."""
    parser.add_argument("config", help="TOML file naming the function and the parameter grids")
    parser.add_argument("-o", "--output", required=True,
                        help="netCDF file to write, or a Zarr store if it ends in .zarr")
    parser.add_argument("--backend", choices=("serial", "broadcast", "dask"),
                        help="override the backend of the configuration")
    parser.add_argument("--chunk-size", type=int, help="grid points per chunk")
    parser.add_argument("--store", help="directory of resumable chunk results")
    parser.add_argument("--workers", type=int, help="LocalCluster workers for --backend dask")
    parser.add_argument("--scheduler", help="dask scheduler address (instead of a LocalCluster)")
    parser.add_argument("--processes", action="store_true",
                        help="LocalCluster workers as processes (--backend dask; the function "
                             "must be importable by the workers)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """Run the sweep a TOML configuration describes and write its Dataset; exit status."""
    from skytorch.dataset import ZARR_SUFFIX, import_zarr, write_dataset
    from skytorch.sweep import sweep

    if Path(args.output).suffix.lower() == ZARR_SUFFIX:
        try:
            import_zarr()  # before the sweep runs, not after
        except ImportError as error:
            raise ValueError(str(error)) from error
    config = load_config(args.config)
    options = config["options"]
    if options.get("store") is not None and not Path(options["store"]).is_absolute():
        # a path in the file is relative to the file, as the render command's light map
        options["store"] = str(Path(args.config).parent / options["store"])
    for option, value in (("backend", args.backend), ("chunk_size", args.chunk_size),
                          ("store", args.store), ("n_workers", args.workers),
                          ("scheduler_address", args.scheduler)):
        if value is not None:
            options[option] = value
    if args.no_progress:
        options["progress"] = False
    if args.processes:
        options["cluster_options"] = {**options.get("cluster_options", {}), "processes": True}
    fn = config["function"]
    if config["fixed"]:
        fn = functools.partial(fn, **config["fixed"])
    dataset = sweep(fn, **options, **config["parameters"])
    dataset.attrs["sweep_function"] = config["function_path"]
    # the fixed keywords too, so that the file reproduces the run on its own
    dataset.attrs["sweep_fixed"] = json.dumps(config["fixed"], sort_keys=True, default=str)
    path = write_dataset(dataset, args.output)
    logger.info("wrote %s", path)
    print(f"wrote {path}: {dict(dataset.sizes)}")
    return 0
