"""Shared plumbing for the experiment scripts: arguments, output paths, saving.

Every experiment is a standalone script that writes a netCDF Dataset and a PNG plot into
an output directory (default ``out/experiments``) and accepts ``--quick`` for a reduced
run (used by the test suite to check that the script works).
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")


def parse_arguments(description: str, argv: list[str] | None = None) -> argparse.Namespace:
    """Return standard ``--quick`` / ``--output-dir`` arguments."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--quick", action="store_true", help="reduced run for smoke tests")
    parser.add_argument("--output-dir", type=Path, default=Path("out/experiments"),
                        help="where the netCDF and PNG files go (default out/experiments)")
    return parser.parse_args(argv)


def save_outputs(dataset, figure, output_dir: Path, stem: str) -> tuple[Path, Path]:
    """Write ``<stem>.nc`` and ``<stem>.png`` into ``output_dir``; return both paths."""
    import matplotlib.pyplot as plt

    from skytorch.dataset import to_netcdf

    output_dir = Path(output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    netcdf_path = to_netcdf(dataset, output_dir / f"{stem}.nc")
    png_path = output_dir / f"{stem}.png"
    figure.savefig(png_path, dpi=120, bbox_inches="tight")
    plt.close(figure)
    return netcdf_path, png_path


def load_script(path: Path, name: str):
    """Import a generator script that is not a package module (``tests/data/...``).

    Registered in ``sys.modules`` under ``name`` before it runs (its dataclasses look
    their module up there); a module already registered under that name is returned.
    """
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(name, module)
    spec.loader.exec_module(module)
    return sys.modules[name]


def median_cpu_seconds(function, repeat: int, warm_up: bool = False) -> float:
    """Median CPU time [s] of ``repeat`` calls of ``function()`` (all threads of the process).

    CPU time is steadier than wall time on a shared machine. With ``warm_up`` one more call
    runs first, untimed (it fills the caches).
    """
    if warm_up:
        function()
    samples = []
    for _ in range(repeat):
        clock = time.process_time()
        function()
        samples.append(time.process_time() - clock)
    return statistics.median(samples)
