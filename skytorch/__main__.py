"""``python -m skytorch`` runs the command-line interface."""

from skytorch.cli import main

if __name__ == "__main__":
    raise SystemExit(main())
