"""Benchmark: torch threads x sweep workers on a small machine (issue 12, item 7).

The same sweep -- slant optical depths of ``Atmosphere.earth`` over 8 turbidities, each
point 25 wavelengths x 5000 zenith angles, 1e6 optical depths in all -- runs serially and
on dask with 2 workers, threads (a LocalCluster in this process) and processes, each with

* the sweep's default torch thread count per worker (``max(1, cores // worker threads)``,
  one thread each for two workers on two cores), and
* the old behaviour, reproduced by ``torch_threads=<cores>``: every worker keeps all the
  cores' threads, so 2 workers run 2 x cores busy OpenMP threads.

Clusters are started (and every worker warmed up) before the clock starts and reused by
all runs of a row; each row gives the median of ``--repeat`` runs (default 3), side by
side in one process, with the load average before and after.

Run: ``python benchmarks/bench_sweep_threads.py [--append] [--repeat N]``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import skytorch as st  # noqa: E402
from benchmarks._harness import (  # noqa: E402
    argument_parser,
    machine_description,
    markdown_table,
    median_seconds,
    parse_arguments,
    report,
)
from skytorch.sweep import usable_cores  # noqa: E402

TURBIDITY = [1.0 + 0.5 * i for i in range(8)]
N_WAVELENGTH = 25
N_ZENITH = 5000
EVALUATIONS = len(TURBIDITY) * N_WAVELENGTH * N_ZENITH


def optical_depths(turbidity):
    """Slant optical depth (zenith, wavelength) for one turbidity: 125,000 evaluations."""
    wavelength_nm = torch.linspace(400.0, 700.0, N_WAVELENGTH, dtype=torch.float64)
    zenith_rad = torch.linspace(0.0, 1.4, N_ZENITH, dtype=torch.float64)[:, None]
    atmosphere = st.Atmosphere.earth(turbidity=turbidity, ozone_du=300.0)
    return atmosphere.optical_depth(wavelength_nm, zenith_rad=zenith_rad)[..., 0, :]


def _load() -> str:
    return "/".join(f"{value:.2f}" for value in os.getloadavg())


def main(argv=None) -> int:
    parser = argument_parser(__doc__.splitlines()[0], repeat=3)
    args = parse_arguments(parser, argv)
    from distributed import Client, LocalCluster

    cores = usable_cores()
    load_before = _load()
    rows = []

    def row(label, workers, threads, **options):
        seconds = median_seconds(
            lambda: st.sweep(optical_depths, progress=False, turbidity=TURBIDITY,
                             torch_threads=threads, **options),
            repeat=args.repeat, warmup=1)
        busy = workers * (threads or max(1, min(torch.get_num_threads(), cores // workers)))
        rows.append({"backend": label, "workers": workers,
                     "torch threads/worker": threads or f"default ({busy // workers})",
                     "busy threads": busy, "median [s]": seconds})
        print(rows[-1], flush=True)
        return seconds

    serial = row("serial", 1, None)
    row("serial, 1 torch thread", 1, 1)
    for processes in (False, True):
        kind = "dask processes" if processes else "dask threads"
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=processes,
                          dashboard_address=":0") as cluster, Client(cluster) as client:
            client.run(lambda: torch.ones(1).sum().item())
            row(kind, 2, None, backend="dask", client=client, chunk_size=1)
            row(f"{kind}, old ({cores} torch threads each)", 2, cores, backend="dask",
                client=client, chunk_size=1)
    for item in rows:
        item["vs serial"] = f"{item['median [s]'] / serial:.2f}x"
    text = (
        "\n## Sweep workers x torch threads (`benchmarks/bench_sweep_threads.py`)\n\n"
        f"{machine_description()}; {cores} usable cores; {EVALUATIONS:.0e} optical depths "
        f"per sweep (8 turbidities x {N_WAVELENGTH} wavelengths x {N_ZENITH} zenith "
        f"angles, one chunk per turbidity); median of {args.repeat} runs; load average "
        f"(1/5/15 min) {load_before} before, {_load()} after.\n\n"
        + markdown_table(rows) + "\n"
    )
    report(text, args.append)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
