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


def median_seconds(function: Callable[[], object], repeat: int = 5, warmup: int = 1) -> float:
    """Median wall time of ``function()`` over ``repeat`` runs after ``warmup`` runs [s]."""
    for _ in range(warmup):
        function()
    samples = []
    for _ in range(repeat):
        gc.collect()
        start = time.perf_counter()
        function()
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


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
