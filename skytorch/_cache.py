"""Verified cache files, and bounded in-memory tables keyed by value.

:class:`MemoryCache` (with :func:`value_key` and :func:`atmosphere_key`) holds small
tables derived from an atmosphere in memory, bounded, thread-safe and keyed by the
parameters' values, never by object identity.

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
import threading
from collections import OrderedDict
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

__all__ = ["MemoryCache", "atmosphere_key", "clone_tables", "discard", "file_sha256",
           "read_verified", "record_path", "value_key", "verify", "write_verified"]

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
    """Return the JSON record that belongs to cache file ``path``."""
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


# --- in-memory tables keyed by value --------------------------------------------------------


def value_key(*parts) -> str:
    """SHA-256 hex digest of JSON-serialisable parts: a key that depends on values only.

    Floats are written by ``repr`` (round-trip exact), mappings with sorted keys; other
    objects by ``str``. Two calls with equal values give the same key whatever the objects'
    identities.

    Examples
    --------
    >>> value_key("refraction", {"b": 2.0, "a": 1}) == value_key("refraction", {"a": 1, "b": 2.0})
    True
    """
    text = json.dumps(parts, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def atmosphere_key(atmosphere) -> str | None:
    """Value key of an atmosphere model, or ``None`` when it cannot be keyed by value.

    The key hashes the model's class, its ``parameters_dict()`` (every parameter, lists for
    batched ones) and the dtypes of its buffers: two atmospheres built with the same
    parameters share it, any difference in a parameter changes it. An object without
    ``parameters_dict`` (a user's duck-typed model) gets ``None``: tables derived from it
    are computed afresh on every call (:meth:`MemoryCache.get` does not store them).
    """
    parameters = getattr(atmosphere, "parameters_dict", None)
    if not callable(parameters):
        return None
    kind = f"{type(atmosphere).__module__}.{type(atmosphere).__qualname__}"
    buffers = getattr(atmosphere, "buffers", None)
    dtypes = sorted({str(b.dtype) for b in buffers()}) if callable(buffers) else []
    return value_key(kind, parameters(), dtypes)


def clone_tables(table: dict) -> dict:
    """Copy a dict of tensors, cloning every tensor (what table caches hand out)."""
    return {key: value.clone() for key, value in table.items()}


class MemoryCache:
    """A bounded, thread-safe, least-recently-used cache of computed values keyed by value.

    Used for small tables derived from an atmosphere (refraction, extinction, colour) that
    cost milliseconds to seconds and are asked for again with the same parameters. Keys are
    value keys (:func:`value_key`, :func:`atmosphere_key`), never object identities, so an
    atmosphere garbage-collected and another allocated at the same address cannot be
    served the first one's table. ``copy`` is applied to every value handed out, so a
    caller that modifies its table in place does not change the stored one.

    Thread safety: the dictionary is only touched under a lock; the computation runs
    outside it, so two threads missing the same key at once both compute (identical values;
    the first one stored is kept) and threads computing other keys never wait.

    Parameters
    ----------
    maxsize : int
        Entries kept; the least recently used is dropped beyond it.
    copy : callable, optional
        ``value -> value`` applied to what :meth:`get` returns (default: the value itself).

    Examples
    --------
    >>> cache = MemoryCache(2)
    >>> cache.get("a", lambda: 1), cache.get("a", lambda: 2), cache.get(None, lambda: 3)
    (1, 1, 3)
    >>> cache.cache_info()
    {'hits': 1, 'misses': 1, 'uncached': 1, 'size': 1, 'maxsize': 2}
    """

    def __init__(self, maxsize: int, copy: Callable[[T], T] | None = None) -> None:
        if isinstance(maxsize, bool) or not isinstance(maxsize, int) or maxsize < 1:
            raise ValueError(f"maxsize must be an integer >= 1; got {maxsize!r}")
        self.maxsize = maxsize
        self._copy = copy
        self._data: OrderedDict[str, object] = OrderedDict()
        self._lock = threading.Lock()
        self._counts = {"hits": 0, "misses": 0, "uncached": 0}

    def get(self, key: str | None, compute: Callable[[], T]) -> T:
        """Return the value stored under ``key``, else store and return ``compute()``.

        A ``None`` key (no value key exists) computes without storing.
        """
        if key is None:
            with self._lock:
                self._counts["uncached"] += 1
            return self._hand_out(compute())
        with self._lock:
            found = key in self._data
            if found:
                self._data.move_to_end(key)
                value = self._data[key]
            self._counts["hits" if found else "misses"] += 1
        if not found:
            value = compute()
            with self._lock:
                value = self._data.setdefault(key, value)
                self._data.move_to_end(key)
                while len(self._data) > self.maxsize:
                    self._data.popitem(last=False)
        return self._hand_out(value)

    def _hand_out(self, value):
        return value if self._copy is None else self._copy(value)

    def clear(self) -> None:
        """Drop every entry and reset the counts."""
        with self._lock:
            self._data.clear()
            self._counts = dict.fromkeys(self._counts, 0)

    def cache_info(self) -> dict[str, int]:
        """Return the counts of hits, misses and unkeyed calls, the entries held and the bound."""
        with self._lock:
            return {**self._counts, "size": len(self._data), "maxsize": self.maxsize}
