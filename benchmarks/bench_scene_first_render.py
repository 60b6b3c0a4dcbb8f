"""Benchmark of the first scene render in a fresh process, and of a warm render.

Each run starts a new interpreter (``python -c``) that imports skytorch, renders a day
scene (Paris, 2015-06-21 12:00 UTC, 128 × 128 fisheye, RGB, default fidelity, float64)
and then renders it again three times: the same :class:`~skytorch.scene.Scene` (its
resources kept), a new Scene of the same parameters (``new scene``; in a tree with
``Scene.resources`` the new scene is given the first one's resources, as a time series
does) and another new Scene left to its own resources (``new scene, own resources``: in
a tree with module caches it finds them warm; with ``SceneResources`` it builds its
tables again, the transmittance table from disk). The disk cache
(``SKYTORCH_CACHE_DIR``, a private folder) is filled by one untimed run first, so the
numbers are those of a user's second session: the transmittance table is read from disk,
the rest is built in the process.

Timed, per run: the whole process from its start to its exit (``process``, interpreter
start-up included), ``import skytorch`` alone, the first render (construction of the
Scene, planning and rendering), the CPU time of the import and first render together
(one thread: less disturbed by other processes on a shared machine) and the warm
renders. Several source trees can be timed
side by side (``--tree``), interleaved run by run so that the load of a shared machine
falls on all of them alike; medians over ``--repeat`` runs.

Run: ``python benchmarks/bench_scene_first_render.py --tree before=/path/a
--tree after=/path/b [--repeat 5] [--append]`` (``--append`` adds the table to
``docs/benchmarks.md``). Timings on a shared 2-core machine are noisy.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._harness import machine_description, markdown_table  # noqa: E402

#: the child process: prints the timings [s] as JSON
CHILD = """
import time
start, start_cpu = time.perf_counter(), time.process_time()
import skytorch as st
imported = time.perf_counter()
options = dict(time="2015-06-21T12:00", lat_deg=48.85, lon_deg=2.35, size={size},
               outputs=("xyz", "srgb"))
scene = st.Scene(**options)
scene.render()
first, first_cpu = time.perf_counter(), time.process_time()
scene.render()
warm = time.perf_counter()
other = st.Scene(**options)
if hasattr(other, "resources"):
    other.render(resources=scene.resources())
else:
    other.render()
new = time.perf_counter()
st.Scene(**options).render()
bare = time.perf_counter()
import json
print(json.dumps({{"import": imported - start, "first render": first - imported,
                  "import + first CPU": first_cpu - start_cpu,
                  "warm render": warm - first, "new scene": new - warm,
                  "new scene, own resources": bare - new}}))
"""

COLUMNS = ("process", "import", "first render", "import + first CPU", "warm render",
           "new scene", "new scene, own resources")


def run_once(tree: str, size: int, cache: str) -> dict[str, float]:
    """Return timings [s] of one fresh process running the child against ``tree``."""
    env = dict(os.environ, PYTHONPATH=tree, SKYTORCH_CACHE_DIR=cache, OMP_NUM_THREADS="1")
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", CHILD.format(size=size)], env=env,
                          capture_output=True, text=True, check=True, cwd=tempfile.gettempdir())
    total = time.perf_counter() - start
    values = json.loads(done.stdout.strip().splitlines()[-1])
    values["process"] = total
    return values


def main(argv=None) -> int:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tree", action="append", default=[],
                        help="NAME=PATH of a source tree (repeatable; default: this tree)")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--append", action="store_true",
                        help="append the table to docs/benchmarks.md")
    args = parser.parse_args(argv)
    trees = [t.split("=", 1) for t in args.tree] or [
        ["this", str(Path(__file__).resolve().parents[1])]]
    with tempfile.TemporaryDirectory() as cache:
        for _, path in trees:  # fill the disk cache (untimed)
            run_once(path, args.size, cache)
        runs: dict[str, list[dict]] = {name: [] for name, _ in trees}
        for _ in range(args.repeat):
            for name, path in trees:
                runs[name].append(run_once(path, args.size, cache))
    rows = []
    for name, _ in trees:
        row = {"tree": name}
        for column in COLUMNS:
            row[f"{column} [s]"] = f"{statistics.median(r[column] for r in runs[name]):.3f}"
        rows.append(row)
    table = markdown_table(rows)
    text = (f"### Scene: first render in a fresh process ({args.size}² day fisheye, "
            f"medians of {args.repeat})\n\n{machine_description()}\n\n{table}\n")
    print(text)
    if args.append:
        path = Path(__file__).resolve().parents[1] / "docs" / "benchmarks.md"
        with path.open("a", encoding="utf-8") as handle:
            handle.write("\n" + text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
