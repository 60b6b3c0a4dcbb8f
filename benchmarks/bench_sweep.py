"""Benchmark of parameter sweeps: plain loop vs sweep backends on a 10 x 10 grid.

The swept function integrates a toy slant optical depth along straight rays through a
spherical shell (exponential air and aerosol profiles, ozone tent; 15 wavelengths, 1000
path steps, 32 zenith angles) for one turbidity and one ozone column: a few tens of ms of
torch work per grid point. Rows:

* plain loop — nested Python loops building the array by hand (the baseline);
* sweep serial — ``st.sweep`` with one chunk (overhead of the Dataset assembly);
* sweep serial, chunks of 10 — chunking overhead;
* sweep broadcast — one batched call per slab of 10 points ((1, 1) turbidity, (1, 10) ozone);
* sweep dask, 1 and 2 workers — LocalCluster threads (torch releases the GIL), chunks of 10
  points; started by each sweep (the default) or an existing client reused across sweeps;
* sweep dask, 1 and 2 worker processes — a reused LocalCluster with ``processes=True``
  (the function and results are pickled between processes).

All rows but the first run torch with one intra-op thread, so that workers do not compete
for the two cores.

A second table times the real job of issue 7: the 2015-09-28 lunar eclipse light curve
(``lunar_eclipse``, 50 times) swept over a 10 x 10 turbidity x ozone grid, serial and on
dask with 1 and 2 thread workers and 1 and 2 worker processes (one run each, each in a
fresh process; the process clusters are started and every worker warmed up with one
call before the clock starts; ``--eclipse-grid 0`` skips it).

Run: ``python benchmarks/bench_sweep.py [--append]`` (``--append`` adds the table to
``docs/benchmarks.md``). Timings on a shared 2-core machine are noisy.
"""

from __future__ import annotations

import contextlib
import os
import statistics
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

N = 10
TURBIDITY = [1.0 + 0.5 * i for i in range(N)]
OZONE_DU = [200.0 + 20.0 * i for i in range(N)]
WAVELENGTH_NM = torch.linspace(360.0, 830.0, 15, dtype=torch.float64)
PATH_M = torch.linspace(0.0, 600e3, 1000, dtype=torch.float64)
ZENITH_RAD = torch.linspace(0.0, 1.55, 32, dtype=torch.float64)
EARTH_RADIUS_M = 6.371e6


def optical_depth(turbidity, ozone_du):
    """Toy slant optical depth (..., zenith, wavelength) for broadcastable parameters."""
    turbidity = torch.as_tensor(turbidity, dtype=torch.float64)[..., None, None, None]
    ozone = torch.as_tensor(ozone_du, dtype=torch.float64)[..., None, None, None]
    s = PATH_M[:, None, None]
    mu = torch.cos(ZENITH_RAD)[:, None]
    h = torch.sqrt(EARTH_RADIUS_M**2 + s**2 + 2 * EARTH_RADIUS_M * s * mu) - EARTH_RADIUS_M
    wl = WAVELENGTH_NM / 550.0
    rayleigh = 1.2e-5 * wl**-4.05 * torch.exp(-h / 8000.0)
    aerosol = 1e-5 * (turbidity - 1.0) * wl**-1.3 * torch.exp(-h / 1200.0)
    ozone_density = ozone * 1e-9 * torch.clamp(1 - (h - 25e3).abs() / 15e3, min=0.0)
    extinction = rayleigh + aerosol + ozone_density  # (..., path, zenith, wavelength)
    return torch.trapezoid(extinction, PATH_M, dim=-3)


def plain_loop():
    out = torch.empty(N, N, len(ZENITH_RAD), len(WAVELENGTH_NM), dtype=torch.float64)
    for i, t in enumerate(TURBIDITY):
        for j, o in enumerate(OZONE_DU):
            out[i, j] = optical_depth(t, o)
    return out


def run_sweep(**options):
    return st.sweep(optical_depth, progress=False, turbidity=TURBIDITY, ozone_du=OZONE_DU,
                    **options)


@contextlib.contextmanager
def torch_threads(count: int | None):
    previous = torch.get_num_threads()
    if count is not None:
        torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(previous)


def eclipse_light_curve(turbidity, ozone_du):
    """V magnitude and B-V of the Moon through the 2015-09-28 eclipse (50 times)."""
    from skytorch.atmosphere import Atmosphere
    from skytorch.eclipse import lunar_eclipse

    atmosphere = Atmosphere.earth(turbidity=turbidity, ozone_du=ozone_du)
    ds = lunar_eclipse("2015-09-28", atmosphere=atmosphere, n_times=50, n_images=0)
    return ds[["v_magnitude", "b_minus_v"]]


ECLIPSE_CASES = {
    "serial": {},
    "dask, 1 worker": {"backend": "dask", "n_workers": 1},
    "dask, 2 workers": {"backend": "dask", "n_workers": 2},
    "dask, 1 worker process": {"backend": "dask", "n_workers": 1, "processes": True},
    "dask, 2 worker processes": {"backend": "dask", "n_workers": 2, "processes": True},
}


def _warm_up() -> None:
    """One light curve at a point outside the grid: imports, ephemeris and caches."""
    torch.set_num_threads(1)
    eclipse_light_curve(2.2, 310.0)


def process_cluster(n_workers: int):
    """Return a LocalCluster of single-threaded worker processes.

    Set up as ``st.sweep`` sets up its own (glibc's malloc trimming, see
    ``skytorch.sweep.WORKER_PROCESS_CONFIG``).
    """
    import dask
    from distributed import LocalCluster

    from skytorch.sweep import WORKER_PROCESS_CONFIG

    with dask.config.set(WORKER_PROCESS_CONFIG):
        return LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                            dashboard_address=":0")


def eclipse_case(label: str, n: int) -> float:
    """Seconds for the n x n eclipse light-curve sweep with one backend.

    After a warm-up call at a point outside the grid in this process and, for worker processes, in
    each worker.
    """
    import time

    options = dict(ECLIPSE_CASES[label])
    _warm_up()
    with contextlib.ExitStack() as stack:
        if options.pop("processes", False):
            cluster = stack.enter_context(process_cluster(options.pop("n_workers")))
            from distributed import Client

            options["client"] = stack.enter_context(Client(cluster))
            options["client"].run(_warm_up)
        start = time.perf_counter()
        st.sweep(eclipse_light_curve, progress=False,
                 turbidity=[1.0 + 0.5 * i for i in range(n)],
                 ozone_du=[200.0 + 20.0 * i for i in range(n)], **options)
        return time.perf_counter() - start


def eclipse_rows(n: int) -> list[dict[str, object]]:
    """One timing per backend, each in a fresh process so no run reuses another's caches."""
    import subprocess

    rows = []
    for label in ECLIPSE_CASES:
        output = subprocess.run(
            [sys.executable, __file__, "--eclipse-case", label, "--eclipse-grid", str(n)],
            check=True, capture_output=True, text=True).stdout
        rows.append({"eclipse light curve sweep": f"{n} x {n}, {label}",
                     "torch threads": 1,
                     "seconds (one run)": float(output.strip().splitlines()[-1])})
    return rows


def main(argv=None) -> int:
    parser = argument_parser(__doc__.splitlines()[0], repeat=5, thread_option=False)
    parser.add_argument("--eclipse-grid", type=int, default=10,
                        help="n for the n x n eclipse light-curve sweep (0 skips it)")
    parser.add_argument("--eclipse-case", choices=tuple(ECLIPSE_CASES),
                        help="time only this eclipse case and print the seconds")
    args = parse_arguments(parser, argv)
    if args.eclipse_case:
        print(eclipse_case(args.eclipse_case, args.eclipse_grid))
        return 0

    load_before = os.getloadavg()
    reference = plain_loop()
    from distributed import Client, LocalCluster

    stack = contextlib.ExitStack()
    clients = {}
    for workers in (1, 2):
        threads = LocalCluster(n_workers=workers, threads_per_worker=1, processes=False,
                               dashboard_address=":0")
        for processes, cluster in ((False, threads), (True, process_cluster(workers))):
            stack.enter_context(cluster)
            clients[workers, processes] = stack.enter_context(Client(cluster))
    # One intra-op torch thread everywhere except the first row: on a shared, oversubscribed
    # 2-core machine OpenMP's barriers make 2-thread torch calls up to 10x slower.
    cases = [
        ("plain loop, torch default threads", None, plain_loop),
        ("plain loop", 1, plain_loop),
        ("sweep serial", 1, lambda: run_sweep()),
        ("sweep serial, chunks of 10", 1, lambda: run_sweep(chunk_size=10)),
        ("sweep broadcast, slabs of 10", 1,
         lambda: run_sweep(backend="broadcast", chunk_size=10)),
        ("sweep dask, 1 worker", 1, lambda: run_sweep(backend="dask", n_workers=1,
                                                      chunk_size=10)),
        ("sweep dask, 2 workers", 1, lambda: run_sweep(backend="dask", n_workers=2,
                                                       chunk_size=10)),
        ("sweep dask, 1 worker, reused client", 1,
         lambda: run_sweep(backend="dask", client=clients[1, False], chunk_size=10)),
        ("sweep dask, 2 workers, reused client", 1,
         lambda: run_sweep(backend="dask", client=clients[2, False], chunk_size=10)),
        ("sweep dask, 1 worker process, reused client", 1,
         lambda: run_sweep(backend="dask", client=clients[1, True], chunk_size=10)),
        ("sweep dask, 2 worker processes, reused client", 1,
         lambda: run_sweep(backend="dask", client=clients[2, True], chunk_size=10)),
    ]
    # Cases are timed round-robin (one run of each per round) so that load from other
    # processes on the shared machine affects every case alike; medians over rounds.
    samples: dict[str, list[float]] = {label: [] for label, _, _ in cases}
    identical = {}
    for label, threads, function in cases:
        with torch_threads(threads):
            result = function()
        values = result if isinstance(result, torch.Tensor) else torch.from_numpy(
            result["result"].values)
        identical[label] = bool(torch.equal(values, reference))
    for round_index in range(args.repeat):
        for label, threads, function in cases:
            if threads is None and round_index > 0:
                continue  # the oversubscribed row is slow: one sample is enough
            with torch_threads(threads):
                samples[label].append(median_seconds(function, repeat=1, warmup=0))
    stack.close()
    rows = []
    baseline = statistics.median(samples["plain loop"])
    for label, threads, _ in cases:
        seconds = statistics.median(samples[label])
        rows.append({"case (10 x 10 grid)": label,
                     "torch threads": threads or torch.get_num_threads(),
                     "median [s]": seconds, "vs plain loop": seconds / baseline,
                     "identical to loop": "yes" if identical[label] else "no"})
    seconds = {row["case (10 x 10 grid)"]: row["median [s]"] for row in rows}
    dask_1, dask_2 = seconds["sweep dask, 1 worker"], seconds["sweep dask, 2 workers"]
    reused_1 = seconds["sweep dask, 1 worker, reused client"]
    reused_2 = seconds["sweep dask, 2 workers, reused client"]
    process_1 = seconds["sweep dask, 1 worker process, reused client"]
    process_2 = seconds["sweep dask, 2 worker processes, reused client"]
    table = markdown_table(rows)
    text = (
        f"\n## Parameter sweeps (`benchmarks/bench_sweep.py`)\n\n"
        f"Machine: {machine_description()}; load average (1 min) {load_before[0]:.1f} at "
        f"the start, {os.getloadavg()[0]:.1f} after the toy sweeps. Medians of {args.repeat} "
        f"interleaved rounds (one sample for the first row); the machine is shared, so "
        f"timings are noisy."
        f"\n\n{table}\n\n"
        f"Dask speed-up with 2 workers vs 1 (one torch thread each): {dask_1 / dask_2:.2f}x "
        f"with a LocalCluster started per sweep, {reused_1 / reused_2:.2f}x with a reused "
        f"client, {process_1 / process_2:.2f}x with reused worker processes.\n"
    )
    if args.eclipse_grid:
        eclipse = eclipse_rows(args.eclipse_grid)
        serial, one, two, process_one, process_two = (row["seconds (one run)"]
                                                      for row in eclipse)
        text += (
            f"\nThe 2015-09-28 lunar eclipse light curve (`lunar_eclipse`, 50 times, 15 bands, "
            f"V and B-V) swept over turbidity x ozone:\n\n{markdown_table(eclipse)}\n\n"
            f"Target (issue 7): 10 x 10 within 60 s. Dask speed-up 2 workers vs 1: "
            f"{one / two:.2f}x with threads, {process_one / process_two:.2f}x with worker "
            f"processes; 2 worker processes vs serial: {serial / process_two:.2f}x. Load "
            f"average (1 min) after these runs: {os.getloadavg()[0]:.1f}.\n"
        )
    report(text, args.append)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
