"""Subcommands of the ``skytorch`` command line (one module each)."""
