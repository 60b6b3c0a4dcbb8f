"""Verified cache files: a content checksum and the parameter hash, checked on every load.

Every file that skytorch caches on disk (transmittance tables, skyglow models, sweep
chunks) is written with :func:`write_verified` and read back with :func:`read_verified`.
Beside each file ``NAME`` a small JSON record ``NAME.sha256.json`` holds

* ``content_sha256`` -- the SHA-256 digest of the file's bytes, and
* ``parameter_sha256`` -- the hash of the parameters the file was built for.

:func:`read_verified` returns ``None`` (and logs why) when the record is missing, names
other parameters, or the bytes no longer match; the caller then rebuilds the file and
:func:`write_verified` replaces it. A corrupted, truncated or swapped file is therefore
never served, and it does not stay on disk for later runs.

Examples
--------
>>> import tempfile, pathlib
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> def write(path):
...     path.write_bytes(b"table")
>>> path = write_verified(folder / "t.bin", "key-1", write)
>>> read_verified(path, "key-1", lambda p: p.read_bytes())
b'table'
>>> read_verified(path, "key-2", lambda p: p.read_bytes()) is None
True
>>> _ = path.write_bytes(b"tablf")
>>> read_verified(path, "key-1", lambda p: p.read_bytes()) is None
True
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

__all__ = ["discard", "file_sha256", "read_verified", "record_path", "verify", "write_verified"]

logger = logging.getLogger(__name__)

T = TypeVar("T")

#: format of the JSON record kept beside each cache file
RECORD_FORMAT = 1


def file_sha256(path: str | os.PathLike) -> str:
    """SHA-256 hex digest of a file's bytes (read in 1 MiB blocks)."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def record_path(path: str | os.PathLike) -> Path:
    """The JSON record that belongs to cache file ``path``."""
    path = Path(path)
    return path.with_name(path.name + ".sha256.json")


def _write_text_atomically(path: Path, text: str) -> None:
    handle, temporary = tempfile.mkstemp(suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(handle, "w") as stream:
            stream.write(text)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def write_verified(path: str | os.PathLike, parameter_hash: str,
                   write: Callable[[Path], object]) -> Path:
    """Write a cache file with ``write(path)`` and record its checksum and parameters.

    Parameters
    ----------
    path : str or os.PathLike
        Destination of the cache file; missing directories are created.
    parameter_hash : str
        Hash of every parameter the content depends on.
    write : callable
        ``write(path)`` writes the file (atomically, e.g. :func:`skytorch.dataset.to_netcdf`).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    record = record_path(path)
    record.unlink(missing_ok=True)  # never a stale record beside a half-replaced file
    write(path)
    payload = {"format": RECORD_FORMAT, "file": path.name,
               "parameter_sha256": str(parameter_hash), "content_sha256": file_sha256(path)}
    _write_text_atomically(record, json.dumps(payload, sort_keys=True))
    return path


def verify(path: str | os.PathLike, parameter_hash: str) -> str | None:
    """``None`` if ``path`` is intact and built for ``parameter_hash``, else the reason."""
    path = Path(path)
    record = record_path(path)
    if not path.is_file():
        return "no file"
    try:
        payload = json.loads(record.read_text())
    except (OSError, ValueError) as error:
        return f"no valid checksum record ({error.__class__.__name__})"
    if not isinstance(payload, dict) or payload.get("format") != RECORD_FORMAT:
        return "checksum record of an unknown format"
    if payload.get("file") != path.name:
        return f"checksum record names another file ({payload.get('file')!r})"
    if payload.get("parameter_sha256") != str(parameter_hash):
        return "built for other parameters"
    if payload.get("content_sha256") != file_sha256(path):
        return "content checksum mismatch (corrupted or replaced file)"
    return None


def read_verified(path: str | os.PathLike, parameter_hash: str,
                  read: Callable[[Path], T]) -> T | None:
    """Read a verified cache file, or ``None`` if it is absent, stale or corrupted.

    A file that fails the check, or that ``read`` cannot parse, is deleted together with its
    record so that it is rebuilt, and a warning names the file and the reason.

    Parameters
    ----------
    path : str or os.PathLike
        The cache file.
    parameter_hash : str
        The parameters the caller needs.
    read : callable
        ``read(path)`` loads the file; any exception it raises marks the file as bad.

    Returns
    -------
    object or None
        What ``read`` returned, or ``None``.
    """
    path = Path(path)
    if not path.exists():
        return None
    reason = verify(path, parameter_hash)
    if reason is None:
        try:
            return read(path)
        except Exception as error:  # noqa: BLE001 - any unreadable file is rebuilt
            reason = f"unreadable ({error.__class__.__name__}: {error})"
    logger.warning("cache file %s rejected: %s; it will be rebuilt", path, reason)
    discard(path)
    return None


def discard(path: str | os.PathLike) -> None:
    """Delete a cache file and its record (missing ones are ignored)."""
    path = Path(path)
    path.unlink(missing_ok=True)
    record_path(path).unlink(missing_ok=True)
