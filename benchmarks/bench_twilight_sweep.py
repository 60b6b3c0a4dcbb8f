"""Benchmark of a 10 × 10 turbidity × ozone sweep of the zenith twilight (target ≤ 60 s).

Workload of the multiple-scattering issue: the zenith sky radiance at the Sun 6, 9, 12, 15
and 18° below the horizon for turbidity 1.5–6 × ozone 200–450 DU (10 × 10), converged orders
of scattering on the default scene preset's small tables (8 × 24 × 24 × 5 with 8 × 2 sphere
directions since 2026-12-07, 8 × 16 × 24 × 5 with 4 × 1 from 2026-12-06, 5 radii before; 6
wavelengths 400–700 nm). Rows:
one batched ``precompute_scattering`` of the 100 atmospheres, and ``st.sweep`` of one
parameter set per call — serial, and on its dask backend with two single-threaded workers
(threads; worker processes, their start included). Each row runs once (a run is a minute).

Run: ``python benchmarks/bench_twilight_sweep.py [--append] [--threads 2]``.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._harness import (  # noqa: E402
    argument_parser,
    parse_arguments,
    report_section,
)
from skytorch.atmosphere import Atmosphere  # noqa: E402
from skytorch.atmosphere.multiple_scattering import (  # noqa: E402
    TableResolution,
    precompute_scattering,
)
from skytorch.scene.presets import FIDELITY  # noqa: E402

TARGET_S = 60.0
WAVELENGTH = torch.linspace(400.0, 700.0, 6, dtype=torch.float64)
SUN_ZENITH = torch.deg2rad(torch.tensor([96.0, 99.0, 102.0, 105.0, 108.0],
                                        dtype=torch.float64))
TURBIDITY = torch.linspace(1.5, 6.0, 10, dtype=torch.float64)
OZONE_DU = torch.linspace(200.0, 450.0, 10, dtype=torch.float64)


def _resolution() -> TableResolution:
    return TableResolution(**FIDELITY["default"]["ms_tables"])


def zenith_twilight(turbidity, ozone_du):
    """Zenith radiance per unit solar irradiance (Sun depression, wavelength) [sr^-1]."""
    tables = precompute_scattering(Atmosphere.earth(turbidity=turbidity, ozone_du=ozone_du),
                                   WAVELENGTH, scattering_orders="converged",
                                   resolution=_resolution())
    zero = torch.zeros_like(SUN_ZENITH)
    return tables.radiance(0.0, zero, zero, SUN_ZENITH)


def _batched() -> None:
    atmosphere = Atmosphere.earth(turbidity=TURBIDITY[:, None], ozone_du=OZONE_DU[None, :])
    tables = precompute_scattering(atmosphere, WAVELENGTH, scattering_orders="converged",
                                   resolution=_resolution())
    zero = torch.zeros(5, 1, 1, dtype=torch.float64)
    tables.radiance(0.0, zero, zero, SUN_ZENITH[:, None, None])


def main(argv: list[str] | None = None) -> int:
    import skytorch as st

    parser = argument_parser(__doc__.splitlines()[0], repeat=1, threads=2)
    args = parse_arguments(parser, argv)
    grid = {"turbidity": TURBIDITY.tolist(), "ozone_du": OZONE_DU.tolist()}
    cases = [
        ("one batched precompute of the 100 atmospheres", _batched),
        ("st.sweep, serial", lambda: st.sweep(zenith_twilight, **grid)),
        ("st.sweep, dask, 2 single-threaded worker threads",
         lambda: st.sweep(zenith_twilight, backend="dask", **grid)),
        ("st.sweep, dask, 2 single-threaded worker processes (start included)",
         lambda: st.sweep(zenith_twilight, backend="dask",
                          cluster_options={"processes": True}, **grid)),
    ]
    load_before = os.getloadavg()
    rows = []
    for label, function in cases:
        clock = time.perf_counter()
        function()
        seconds = time.perf_counter() - clock
        rows.append({"case": label, "wall [s]": f"{seconds:.1f}", "target [s]": "60",
                     "met": "yes" if seconds <= TARGET_S else "no"})
        print(rows[-1], flush=True)
    report_section("Twilight sweep 10 × 10 × 5", "bench_twilight_sweep.py", load_before,
                   "Zenith radiance at 5 Sun depressions, turbidity × ozone 10 × 10, converged "
                   "orders on the default preset's tables "
                   f"({_resolution().n_r} radii), 6 wavelengths; one run per row.",
                   rows, args.append)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
