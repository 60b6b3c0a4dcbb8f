"""The ``skytorch`` command: a thin layer over the Dataset functions.

Each subcommand lives in its own module under :mod:`skytorch.commands` and exposes two
functions::

    def configure(parser: argparse.ArgumentParser) -> None   # add arguments
    def run(args: argparse.Namespace) -> int                  # do the work, 0 on success

Subcommands write netCDF files (``-o``) and optionally PNG figures (``--png``).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from skytorch import __version__

#: subcommand name -> (module, one-line help); modules are imported on demand
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "ephemeris": ("skytorch.commands.ephemeris", "Sun and Moon positions over time"),
    "eclipse": ("skytorch.commands.eclipse",
                "lunar eclipses (circumstances, light curve) and solar eclipses (local sky)"),
    "stars": ("skytorch.commands.stars", "apparent star positions, magnitudes and a chart"),
    "planets": ("skytorch.commands.planets",
                "places, phases and V magnitudes of the planets over time"),
    "moon": ("skytorch.commands.moon",
             "phase, illumination, libration, brightness and disc images of the Moon"),
    "skyglow": ("skytorch.commands.skyglow", "artificial sky brightness from a light map"),
    "render": ("skytorch.commands.render", "render a scene described in a TOML file"),
    "sweep": ("skytorch.commands.sweep", "parameter sweep described in a TOML file"),
    "demo": ("skytorch.commands.demo", "the end-to-end demonstration job (make demo)"),
}


def _load(module_name: str):
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as error:
        if error.name == module_name:
            return None  # subcommand not available in this version
        raise


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser with every available subcommand."""
    parser = argparse.ArgumentParser(
        prog="skytorch",
        description="Batched physics of the sky: atmosphere, eclipses, stars, Moon, skyglow.",
    )
    parser.add_argument("--version", action="version", version=f"skytorch {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log output (-v info, -vv debug)")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module_name, help_text) in SUBCOMMANDS.items():
        module = _load(module_name)
        if module is None:
            continue
        sub = subparsers.add_parser(name, help=help_text, description=help_text)
        module.configure(sub)
        sub.set_defaults(_run=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``skytorch`` command; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=[logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)],
        format="%(levelname)s %(name)s: %(message)s",
    )
    if not hasattr(args, "_run"):
        parser.print_help()
        return 0
    try:
        return int(args._run(args) or 0)
    except (ValueError, TypeError, OSError) as error:
        # bad input (named by the entry point) or an unreadable/unwritable file
        print(f"skytorch {args.command}: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
