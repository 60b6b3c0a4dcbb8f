"""Performance targets of the atmosphere issue, side by side in one run.

One vertical structure, all absorbers, aerosol layers: today's model and a reference tree side by
side in one run.

Rows (medians of ``--repeat`` timed runs per tree, after one warm-up run except for the
shadow table, which builds a fresh shadow model every run):

* ``transmittance_table`` 256 x 64 (x_mu x x_r) x 60 wavelengths (360-1000 nm) of
  ``Atmosphere.earth(turbidity=2.5, ozone_du=300)``. Target: <= 0.5 s.
* ``Atmosphere.optical_depth`` of 1e6 straight rays (zenith angles uniform in [0, 1.5]
  rad, observer at the ground) x 60 wavelengths, float64. Target: <= 4 s.
* ``ShadowTable.compute`` of ``Shadow.earth()`` on 256 x 256 (u, v) x 15 wavelengths
  (``bands15``; a fresh shadow model, so the ring profile traced once is included).
  Target: <= 5 s.

Each tree runs in its own worker process (the same interpreter, ``PYTHONPATH`` set to the
tree, so that the two are imported from their own sources and nothing else differs). The
parent sends one workload at a time and alternates the trees (A B B A ...) so that both
see the same load; the table gives both medians, their ratio and the median of the
per-pair ratios (the more robust number on a loaded machine).

Run: ``python benchmarks/bench_constituents.py --reference /path/to/old/tree
[--current /path/to/tree] [--repeat 5] [--threads 2] [--rays 1000000] [--append]``.
``--current`` defaults to the tree holding this script; without ``--reference`` (as from
``benchmarks/run.py``) nothing is measured. A tree exported with ``git archive`` may name
its commit in a file ``COMMIT`` at its root (quoted in the table's header).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

#: (workload, label, target [s], untimed warm-up runs per tree); the shadow table builds a
#: fresh shadow model every run, so a warm-up would only repeat a run of a minute
WORKLOADS = (
    ("transmittance", "transmittance table 256x64x60 wl (360-1000 nm)", 0.5, 1),
    ("straight_rays", "optical depth {rays} straight rays x 60 wl, float64", 4.0, 1),
    ("shadow_table", "Earth shadow table 256x256x15 (ring profile included)", 5.0, 0),
)


# --- worker (imports skytorch from PYTHONPATH only) ---------------------------------------


def _worker(rays: int) -> int:
    import gc
    import math

    import torch

    import skytorch
    from skytorch.atmosphere import Atmosphere
    from skytorch.atmosphere.tables import transmittance_table
    from skytorch.eclipse.shadow import Shadow
    from skytorch.eclipse.shadow_table import ShadowTable
    from skytorch.spectrum import wavelength_grid

    wavelength = torch.linspace(360.0, 1000.0, 60, dtype=torch.float64)
    bands = wavelength_grid("bands15")
    generator = torch.Generator().manual_seed(0)
    zenith = torch.rand(rays, generator=generator, dtype=torch.float64) * 1.5
    atm = Atmosphere.earth(turbidity=2.5, ozone_du=300.0)
    assert math.isfinite(float(atm.optical_depth(wavelength, 0.3).sum()))

    def shadow_table():
        ShadowTable.compute(Shadow.earth(), bands, n_u=256, n_v=256, progress=False)

    jobs = {
        "transmittance": lambda: transmittance_table(atm, wavelength),
        "straight_rays": lambda: atm.optical_depth(wavelength, zenith),
        "shadow_table": shadow_table,
    }
    print(json.dumps({"ready": True, "skytorch": skytorch.__file__,
                      "threads": torch.get_num_threads(), "torch": torch.__version__}),
          flush=True)
    for line in sys.stdin:
        name = line.strip()
        if not name:
            continue
        gc.collect()
        start = time.perf_counter()
        jobs[name]()
        seconds = time.perf_counter() - start
        print(json.dumps({"workload": name, "seconds": seconds}), flush=True)
    return 0


# --- parent -------------------------------------------------------------------------------


class _Tree:
    """A worker process importing skytorch from ``path``."""

    def __init__(self, label: str, path: Path, threads: int, rays: int):
        self.label, self.path = label, path
        env = dict(os.environ, PYTHONPATH=str(path), OMP_NUM_THREADS=str(threads),
                   MKL_NUM_THREADS=str(threads))
        self.process = subprocess.Popen(
            [sys.executable, str(Path(__file__).resolve()), "--worker", "--rays", str(rays),
             "--threads", str(threads)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env,
            cwd=str(path))
        self.info = json.loads(self.process.stdout.readline())
        expected = (path / "skytorch").resolve()
        if Path(self.info["skytorch"]).resolve().parent != expected:
            raise RuntimeError(f"the {label} worker imported {self.info['skytorch']}, not "
                               f"the tree {path}")

    def run(self, workload: str) -> float:
        self.process.stdin.write(workload + "\n")
        self.process.stdin.flush()
        answer = self.process.stdout.readline()
        if not answer:
            raise RuntimeError(f"the {self.label} worker stopped during {workload}")
        return json.loads(answer)["seconds"]

    def close(self) -> None:
        self.process.stdin.close()
        self.process.wait(timeout=60)


def _describe(path: Path) -> str:
    """Commit of a tree and whether its work tree differs from it."""
    def git(*args):
        result = subprocess.run(["git", "-C", str(path), *args], capture_output=True,
                                text=True)
        return result.stdout.strip() if result.returncode == 0 else ""

    commit = git("rev-parse", "--short", "HEAD")
    if not commit:
        # an exported tree (git archive) may carry its commit in a file COMMIT
        marker = path / "COMMIT"
        if marker.is_file():
            return f"`{path}`, an export of commit {marker.read_text().strip()}"
        return f"`{path}` (not a git work tree)"
    dirty = git("status", "--porcelain", "--untracked-files=no")
    return f"`{path}` at {commit}" + (" (with uncommitted changes)" if dirty else "")


def main(argv: list[str] | None = None) -> int:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from benchmarks._harness import argument_parser, markdown_table, report

    parser = argument_parser(__doc__.splitlines()[0], repeat=5, threads=2)
    parser.add_argument("--reference", type=Path,
                        help="tree of the model to compare with (e.g. the issue's start); "
                             "without it nothing is measured")
    parser.add_argument("--current", type=Path,
                        default=Path(__file__).resolve().parents[1])
    parser.add_argument("--rays", type=int, default=1_000_000)
    parser.add_argument("--reference-label", default="reference")
    parser.add_argument("--current-label", default="current")
    parser.add_argument("--note", default="", help="a paragraph added under the heading")
    parser.add_argument("--only", choices=[w[0] for w in WORKLOADS], action="append",
                        help="measure only this workload (repeatable)")
    args = parser.parse_args(argv)
    if args.reference is None:
        print("bench_constituents: no --reference tree given; skipped")
        return 0
    if args.repeat < 1:
        parser.error(f"--repeat must be >= 1; got {args.repeat}")
    threads = args.threads or 1
    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    load_start = os.getloadavg()
    trees = [_Tree(args.reference_label, args.reference.resolve(), threads, args.rays),
             _Tree(args.current_label, args.current.resolve(), threads, args.rays)]
    rows = []
    try:
        for name, label, target, warmup in WORKLOADS:
            if args.only and name not in args.only:
                continue
            for _ in range(warmup):  # untimed
                for tree in trees:
                    tree.run(name)
            samples = {tree.label: [] for tree in trees}
            for i in range(args.repeat):
                order = trees if i % 2 == 0 else trees[::-1]
                for tree in order:
                    samples[tree.label].append(tree.run(name))
            old = samples[args.reference_label]
            new = samples[args.current_label]
            print(f"{name}: {args.reference_label} {old}, {args.current_label} {new}",
                  file=sys.stderr, flush=True)
            rows.append({
                "workload": label.format(rays=f"{args.rays:.0e}".replace("+0", "")),
                f"{args.reference_label} median s": statistics.median(old),
                f"{args.current_label} median s": statistics.median(new),
                "ratio of medians": statistics.median(new) / statistics.median(old),
                "median of pair ratios": statistics.median(
                    b / a for a, b in zip(old, new, strict=True)),
                "target s": target,
                f"{args.current_label} / target": statistics.median(new) / target,
            })
    finally:
        for tree in trees:
            tree.close()
    info = trees[1].info
    load = os.getloadavg()
    text = (
        f"\n## Atmosphere issue targets, {args.current_label} against {args.reference_label} "
        f"(`benchmarks/bench_constituents.py`, {started})\n\n"
        f"{args.reference_label}: {_describe(args.reference.resolve())}; "
        f"{args.current_label}: {_describe(args.current.resolve())}. One worker process per "
        f"tree (same interpreter `{sys.executable}`, torch {info['torch']}, "
        f"{info['threads']} intra-op threads each), workloads alternated between the trees "
        f"(A B B A ...), {args.repeat} timed runs each (after one warm-up run, except the "
        f"shadow table); {os.cpu_count()} "
        f"logical CPUs, load average (1 / 5 / 15 min) {load_start[0]:.1f} / "
        f"{load_start[1]:.1f} / {load_start[2]:.1f} at the start, {load[0]:.1f} / "
        f"{load[1]:.1f} / {load[2]:.1f} at the end ({time.strftime('%H:%M UTC', time.gmtime())})"
        f".\n\n"
        + (f"{args.note}\n\n" if args.note else "") + f"{markdown_table(rows)}\n")
    report(text, args.append)
    return 0


if __name__ == "__main__":
    if "--worker" in sys.argv[1:]:
        position = sys.argv.index("--rays")
        raise SystemExit(_worker(int(sys.argv[position + 1])))
    raise SystemExit(main())
