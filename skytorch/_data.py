"""Locate the small data tables shipped with skytorch (``data/`` in the source tree).

In an installed wheel the folder is ``skytorch/data``; in an editable install or a source
checkout it is ``data/`` beside the package. Nothing is ever downloaded.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parent


@lru_cache(maxsize=1)
def data_dir() -> Path:
    """Return the directory holding skytorch's shipped data files."""
    for candidate in (_PACKAGE_DIR / "data", _PACKAGE_DIR.parent / "data"):
        if (candidate / "README.md").is_file():
            return candidate
    raise FileNotFoundError(
        "skytorch's data directory is missing; reinstall skytorch (looked in "
        f"{_PACKAGE_DIR / 'data'} and {_PACKAGE_DIR.parent / 'data'})"
    )


def data_path(name: str) -> Path:
    """Path of a shipped data file, raising ``FileNotFoundError`` naming it if absent."""
    path = data_dir() / name
    if not path.is_file():
        raise FileNotFoundError(f"shipped data file {name!r} not found in {data_dir()}")
    return path
