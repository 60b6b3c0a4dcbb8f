"""Timing helpers shared by the benchmark scripts.

Benchmarks record medians measured side by side in one run (never pass/fail timing
tests). Each script prints a Markdown table and can append it to ``docs/benchmarks.md``
(:func:`report`); :func:`argument_parser` and :func:`parse_arguments` give every script
the same ``--append``, ``--repeat`` and ``--threads`` options.
"""

from __future__ import annotations

import argparse
import gc
import os
import platform
import statistics
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import torch

#: the shared benchmark results page that ``--append`` adds to
BENCHMARKS_MD = Path(__file__).resolve().parents[1] / "docs" / "benchmarks.md"


def argument_parser(description: str, *, repeat: int = 5, threads: int | None = None,
                    thread_option: bool = True, append_option: bool = True
                    ) -> argparse.ArgumentParser:
    """Return an argument parser with the options the benchmark scripts share.

    ``--append`` (add the printed Markdown to ``docs/benchmarks.md``), ``--repeat N``
    (timed runs per case, default ``repeat``) and ``--threads T`` (torch intra-op threads,
    default ``threads``; ``None`` keeps torch's own). Scripts add their own options to the
    returned parser and parse with :func:`parse_arguments`.
    """
    parser = argparse.ArgumentParser(description=description)
    if append_option:
        parser.add_argument("--append", action="store_true",
                            help="append to docs/benchmarks.md")
    parser.add_argument("--repeat", type=int, default=repeat)
    if thread_option:
        parser.add_argument("--threads", type=int, default=threads,
                            help="torch intra-op threads")
    return parser


def parse_arguments(parser: argparse.ArgumentParser,
                    argv: Sequence[str] | None = None) -> argparse.Namespace:
    """Parse ``argv`` and apply ``--threads`` (``torch.set_num_threads``) when it is set."""
    args = parser.parse_args(argv)
    if getattr(args, "threads", None):
        torch.set_num_threads(args.threads)
    return args


def report(text: str, append: bool) -> None:
    """Print ``text`` and, with ``append``, add it to ``docs/benchmarks.md``."""
    print(text)
    if append:
        with BENCHMARKS_MD.open("a") as stream:
            stream.write(text)


def report_section(title: str, script: str, load_before: Sequence[float], details: str,
                   rows: list[dict[str, object]], append: bool) -> None:
    """:func:`report` a dated section: title, script, machine, load before → now, table.

    ``load_before`` is :func:`os.getloadavg` taken before the measurements; ``details`` one
    or more sentences on the workload, after the machine line.
    """
    load_after = os.getloadavg()
    header = (f"\n## {title} (`benchmarks/{script}`, "
              f"{time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC)\n\n"
              f"{machine_description()}; load average {load_before[0]:.1f} → "
              f"{load_after[0]:.1f}. {details}\n\n")
    report(header + markdown_table(rows) + "\n", append)


def alternating_medians(cases: dict[str, Callable[[], object]], repeat: int, *,
                        warmup: bool = True) -> dict[str, float]:
    """Median wall time [s] of each case over ``repeat`` rounds, the cases alternating.

    Each round runs every case once in turn, so that a change of the machine's load falls
    on all of them alike; with ``warmup`` every case runs once first, untimed.
    """
    if warmup:
        for case in cases.values():
            case()
    samples: dict[str, list[float]] = {label: [] for label in cases}
    for _ in range(repeat):
        for label, case in cases.items():
            start = time.perf_counter()
            case()
            samples[label].append(time.perf_counter() - start)
    return {label: statistics.median(values) for label, values in samples.items()}


def median_seconds(function: Callable[[], object], repeat: int = 5, warmup: int = 1, *,
                   clock: Callable[[], float] = time.perf_counter) -> float:
    """Median time of ``function()`` over ``repeat`` runs after ``warmup`` runs [s].

    ``clock`` is wall time by default; :func:`median_cpu_seconds` passes the process's CPU
    time.
    """
    for _ in range(warmup):
        function()
    samples = []
    for _ in range(repeat):
        gc.collect()
        start = clock()
        function()
        samples.append(clock() - start)
    return statistics.median(samples)


def median_cpu_seconds(function: Callable[[], object], repeat: int = 5,
                       warmup: int = 0) -> float:
    """Median CPU time of this process (all its threads) for ``function()`` [s].

    Less sensitive than wall time to other jobs on a shared machine; with one torch thread
    it is the wall time on an idle core.
    """
    return median_seconds(function, repeat, warmup, clock=time.process_time)


def machine_description() -> str:
    """One line naming the machine the numbers were measured on."""
    return (
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} logical CPUs, "
        f"torch {torch.__version__} ({torch.get_num_threads()} threads), "
        f"Python {platform.python_version()}"
    )


def markdown_table(rows: list[dict[str, object]]) -> str:
    """Render a list of row dictionaries (same keys) as a Markdown table."""
    if not rows:
        return ""
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "| " + " | ".join("---" for _ in keys) + " |"]
    for row in rows:
        cells = []
        for key in keys:
            value = row[key]
            cells.append(f"{value:.4g}" if isinstance(value, float) else str(value))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
