"""Parameter sweeps: one Dataset dimension per swept parameter, batched, chunked, on dask.

``sweep(fn, turbidity=[1, 2, 3], ozone_du=[250, 300])`` calls
``fn(turbidity=..., ozone_du=...)`` for every point of the Cartesian grid and returns an
``xarray.Dataset`` with dimensions ``("turbidity", "ozone_du", *result_dims)`` whose
coordinates are the swept values. ``fn`` may return an ``xarray.Dataset``, a
``DataArray``, a tensor or numpy array, a number, or a mapping of names to tensors or
numbers.

Backends
--------
``"serial"``
    One call per grid point, in the calling process.
``"broadcast"``
    One call per chunk with the parameters as broadcastable float64 tensors: parameter
    *i* of *k* has shape ``(1, …, n_i, …, 1)`` (``-1`` at position *i*), as a
    ``torch.nn.Module`` with batched parameters accepts them (a ``(5, 1)`` turbidity and
    a ``(1, 4)`` ozone give a 5 × 4 result). ``fn`` must then return tensors (or a
    mapping of them) whose leading *k* dimensions broadcast to the grid shape. Chunks
    are slabs along the first parameter.
``"dask"``
    Chunks run as tasks on ``dask.distributed``: a given ``client``, a scheduler at
    ``scheduler_address``, or a ``LocalCluster`` (threads in this process,
    ``n_workers`` workers of one thread each, default 2; worker processes with
    ``cluster_options={"processes": True}``) started and shut down by the call. Results
    are gathered, persisted and assembled in the calling process. If a chunk fails, the
    other chunks still run and are persisted before the first error is raised (the
    serial backends stop at the first error). Worker processes and remote workers
    receive ``fn`` pickled (cloudpickle): a function defined at module level travels by
    its import name and must be importable there (the module on the workers' path, as
    for the package's own functions and callable modules such as
    ``skytorch.moon.reflectance``); a lambda or a function defined in ``__main__``
    travels by value. Scripts that start worker processes need the usual
    ``if __name__ == "__main__":`` guard.

All backends give the same Dataset (bit-identical for element-wise ``fn``; a function
whose reductions vectorise differently over a batch may differ at the rounding level in
``"broadcast"`` mode).

Chunking and resuming
---------------------
The grid is flattened in C order and cut into chunks of ``chunk_size`` points (by
default the whole grid, or as many points as fit ``memory_budget_bytes`` given the
size of one point's result). With ``store`` (a directory), each finished chunk is
written under ``store/<name>-<key>/``, as a netCDF file or, when ``store`` ends in
``.zarr``, as a Zarr store (optional ``zarr`` package); a rerun loads the chunks that
exist and computes only the missing ones, so an interrupted sweep resumes where it
stopped. The key hashes the grid, the chunk size, the optional ``key`` string and
``fn`` itself (:func:`function_fingerprint`): its qualified name, its code (the source
text when Python can find it, else the bytecode with its constants and the names it
uses), its default arguments, the values it closes over and the arguments bound by
``functools.partial``. Editing ``fn`` therefore starts a new set of chunks. Changes
outside ``fn``'s own code (a helper it calls, a module it imports, the state of a
callable object) are not seen: pass a new ``key`` (e.g. a version) after those.

Every stored chunk goes through :mod:`skytorch._cache`: beside it a record holds the
SHA-256 of its bytes (for a Zarr chunk, of a manifest listing the digests of the store's
files) and a parameter hash of the sweep key and the chunk's bounds
(:func:`chunk_parameter_hash`). A chunk that is corrupted, truncated, another chunk's
file, another sweep's, or without its record is deleted and recomputed, never served.

Threads
-------
torch parallelises each operation over its intra-op threads; a sweep that runs several
workers at once multiplies them, and more busy threads than cores make OpenMP's
spin-waiting threads fight for the cores (three 2-thread processes on 2 cores turned 1e6
optical depths from 1.8 s into 37 s). ``sweep`` therefore sets the torch thread count of
every worker while it computes a chunk: ``torch_threads`` if given, else
``max(1, cores // worker threads on the host)``, never more than the worker's current
``torch.get_num_threads()``. ``"serial"`` and ``"broadcast"`` run in the calling thread
(one worker: all its threads); on dask each task sets the count of the thread it runs in
(LocalCluster threads in this process, worker processes, remote workers alike; the
workers' cores and thread counts are asked from the client) and restores it after the
chunk. ``torch.set_num_threads`` is process-wide in name, but with torch's OpenMP backend
(the CPU wheels) it acts on the calling thread and sets the starting value for threads
that first use torch later, so worker threads of one process each hold their own count;
the caller's count is re-asserted when the sweep ends.

Examples
--------
>>> import torch
>>> import skytorch as st
>>> ds = st.sweep(lambda a, b: torch.tensor([a + b, a * b]), a=[1.0, 2.0], b=[10.0, 20.0, 30.0],
...               progress=False)
>>> ds["result"].dims
('a', 'b', 'result_dim_0')
>>> ds["result"].sel(a=2.0, b=30.0).values.tolist()
[32.0, 60.0]
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import inspect
import json
import logging
import math
import os
import shutil
import types
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np
import torch
import xarray as xr

from skytorch import __version__
from skytorch._cache import discard, file_sha256, read_verified, write_verified
from skytorch._modules import FunctionModule, make_callable
from skytorch._validate import check_choice, check_int, refuse_gradient
from skytorch.dataset import (
    ZARR_SUFFIX,
    batch_coordinates,
    build_dataset,
    import_zarr,
    open_dataset,
    sanitized_attributes,
    to_netcdf,
    to_numpy,
    write_dataset,
)

__all__ = ["BACKENDS", "chunk_parameter_hash", "default_torch_threads", "function_fingerprint",
           "sweep", "usable_cores"]

logger = logging.getLogger(__name__)

#: execution backends of :func:`sweep`
BACKENDS = ("serial", "broadcast", "dask")
#: name of the flattened grid dimension inside stored chunks
POINT_DIM = "sweep_point"
#: variable name for results that are not a Dataset, DataArray with a name, or mapping
RESULT_NAME = "result"
#: default number of LocalCluster workers for ``backend="dask"``
DEFAULT_WORKERS = 2
#: dask configuration for the LocalCluster started by :func:`sweep`: dask sets
#: ``MALLOC_TRIM_THRESHOLD_=65536`` in worker processes, which makes glibc hand the memory of
#: every large tensor back to the OS at once; allocation-heavy torch code then ran 1.6-3x
#: slower in worker processes than in the calling process. glibc's default is kept instead
#: (a ``MALLOC_TRIM_THRESHOLD_`` exported by the user still applies).
WORKER_PROCESS_CONFIG = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}


# --- grid -----------------------------------------------------------------------------------------

def _grid_values(name: str, values) -> np.ndarray:
    """Return the swept values of one parameter as a 1-D numpy array."""
    if isinstance(values, (str, bytes)) or not hasattr(values, "__len__"):
        raise TypeError(
            f"sweep parameter {name} must be a sequence of values; got {values!r:.80}"
        )
    array = to_numpy(values) if isinstance(values, torch.Tensor) else np.asarray(values)
    if array.ndim != 1 or array.size == 0:
        raise ValueError(
            f"sweep parameter {name} must be a non-empty 1-D sequence; got shape {array.shape}"
        )
    if array.dtype.kind not in "biufUM":
        raise TypeError(f"sweep parameter {name} must hold numbers or strings; got {array.dtype}")
    if array.dtype.kind == "f" and not np.isfinite(array).all():
        raise ValueError(f"sweep parameter {name} must be finite; got {array.tolist()}")
    if len(np.unique(array)) != array.size:
        raise ValueError(f"sweep parameter {name} repeats values: {array.tolist()}")
    return array


def _python_value(value):
    """Convert a numpy scalar to the Python value passed to ``fn`` (datetimes stay datetime64)."""
    if isinstance(value, (np.datetime64, np.timedelta64)):
        return value
    return value.item() if isinstance(value, np.generic) else value


def _unwrap(fn: Callable) -> tuple[Callable, list[tuple[tuple, dict]]]:
    """Strip ``functools.partial`` layers and callable-module wrappers from ``fn``.

    Returns the inner function and the arguments the partials bind (outermost first).
    """
    bound = []
    while True:
        if isinstance(fn, functools.partial):
            bound.append((fn.args, dict(fn.keywords)))
            fn = fn.func
        elif isinstance(fn, FunctionModule):
            fn = fn._namesake()
        else:
            return fn, bound


def _function_name(fn: Callable) -> str:
    fn = _unwrap(fn)[0]
    module = getattr(fn, "__module__", None) or type(fn).__module__
    name = getattr(fn, "__qualname__", None) or type(fn).__qualname__
    return f"{module}.{name}"


def _chunks(n_points: int, chunk_size: int) -> list[tuple[int, int]]:
    return [(start, min(start + chunk_size, n_points)) for start in range(0, n_points,
                                                                          chunk_size)]


# --- results to chunk Datasets ------------------------------------------------------------------

def _as_record(result) -> xr.Dataset | dict[str, np.ndarray]:
    """One grid point's result: a Dataset, or a dict of numpy arrays for plain values."""
    if isinstance(result, xr.Dataset):
        return result
    if isinstance(result, xr.DataArray):
        return result.to_dataset(name=result.name if result.name is not None else RESULT_NAME)
    items = result.items() if isinstance(result, Mapping) else [(RESULT_NAME, result)]
    record = {}
    for name, value in items:
        if isinstance(value, (str, bytes)):
            raise TypeError(f"sweep result {name} must be numeric; got {value!r:.80}")
        array = to_numpy(value)
        if array.dtype == object:
            raise TypeError(
                f"sweep function must return a Dataset, DataArray, tensor, number or a "
                f"mapping of them; got {type(value).__name__}"
            )
        record[str(name)] = array
    return record


def _stack_records(records: Sequence[dict[str, np.ndarray]]) -> xr.Dataset:
    """Stack plain-value results along :data:`POINT_DIM` (tensors get ``<name>_dim_<j>``)."""
    first = records[0]
    for other in records[1:]:
        if not isinstance(other, dict) or other.keys() != first.keys() or any(
                other[k].shape != first[k].shape for k in first):
            raise ValueError(
                "sweep results change shape or variables between grid points: "
                f"{ {k: v.shape for k, v in first.items()} } and "
                f"{ {k: getattr(v, 'shape', type(v).__name__) for k, v in dict(other).items()} }"
            )
    return xr.Dataset({
        name: ((POINT_DIM, *(f"{name}_dim_{j}" for j in range(array.ndim))),
               np.stack([record[name] for record in records]))
        for name, array in first.items()
    })


def _same_layout(first: xr.Dataset, other) -> None:
    if not isinstance(other, xr.Dataset):
        raise ValueError(
            f"sweep results change type between grid points: a Dataset and {type(other).__name__}"
        )
    if set(first.data_vars) != set(other.data_vars):
        raise ValueError(
            f"sweep results differ between grid points: variables {sorted(first.data_vars)} "
            f"and {sorted(other.data_vars)}"
        )
    for name in first.data_vars:
        if first[name].dims != other[name].dims or first[name].shape != other[name].shape:
            raise ValueError(
                f"sweep result {name} changes shape between grid points: "
                f"{dict(first[name].sizes)} and {dict(other[name].sizes)}"
            )
    for name, coord in first.coords.items():
        if name not in other.coords or not np.array_equal(coord.values, other[name].values):
            raise ValueError(f"sweep result coordinate {name} differs between grid points")


def _stack_points(results: Sequence[xr.Dataset]) -> xr.Dataset:
    """Stack per-point Datasets along :data:`POINT_DIM`."""
    first = results[0]
    for other in results[1:]:
        _same_layout(first, other)
    data_vars = {
        name: xr.Variable((POINT_DIM, *first[name].dims),
                          np.stack([r[name].values for r in results]),
                          attrs=dict(first[name].attrs))
        for name in first.data_vars
    }
    return xr.Dataset(data_vars, coords=first.coords, attrs=dict(first.attrs))


def _broadcast_chunk(result, grid_shape: tuple[int, ...]) -> xr.Dataset:
    """Convert a broadcast-mode result (leading dims over the grid) to a flat chunk Dataset."""
    if isinstance(result, (xr.Dataset, xr.DataArray)):
        raise TypeError(
            "backend='broadcast' needs fn to return tensors, arrays, numbers or a mapping of "
            "them whose leading dimensions follow the swept parameters; use backend='serial'"
        )
    items = result.items() if isinstance(result, Mapping) else [(RESULT_NAME, result)]
    k = len(grid_shape)
    n_points = math.prod(grid_shape)
    variables = {}
    for name, value in items:
        array = to_numpy(value)
        if array.ndim < k:
            array = array.reshape((1,) * (k - array.ndim) + array.shape)
        inner = array.shape[k:]
        try:
            array = np.broadcast_to(array, grid_shape + inner)
        except ValueError as error:
            raise ValueError(
                f"backend='broadcast': result {name} of shape {array.shape} does not broadcast "
                f"to the grid {grid_shape} in its leading dimensions; use backend='serial'"
            ) from error
        dims = (POINT_DIM, *(f"{name}_dim_{j}" for j in range(len(inner))))
        variables[str(name)] = (dims, np.ascontiguousarray(array).reshape((n_points,) + inner))
    return xr.Dataset(variables)


# --- torch threads per worker --------------------------------------------------------------------

def usable_cores() -> int:
    """CPU cores this process may run on (its affinity mask where the OS has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def default_torch_threads(threads_on_host: int, cores: int | None = None,
                          current: int | None = None) -> int:
    """Return the torch intra-op threads for each of ``threads_on_host`` concurrent workers.

    ``max(1, cores // threads_on_host)``, but never more than the ``current`` setting
    (``torch.get_num_threads()``: a caller who limited torch to one thread keeps one), so
    that workers x threads never exceed the cores.

    Examples
    --------
    >>> default_torch_threads(2, cores=2, current=2)
    1
    >>> default_torch_threads(1, cores=16, current=4)
    4
    >>> default_torch_threads(3, cores=2, current=2)
    1
    """
    cores = usable_cores() if cores is None else cores
    current = torch.get_num_threads() if current is None else current
    return max(1, min(current, cores // max(1, threads_on_host)))


@contextlib.contextmanager
def _torch_threads(n: int) -> Iterator[None]:
    """Run the body with ``torch.set_num_threads(n)`` and restore the previous count.

    With torch's OpenMP backend (the CPU wheels) the count is per thread: it applies to
    the thread that sets it and is the starting value of threads that start using torch
    afterwards; so each dask worker thread sets its own count (restoring it after its
    chunk), and the caller re-asserts its own count when a sweep ends.
    """
    previous = torch.get_num_threads()
    if previous != n:
        torch.set_num_threads(n)
    try:
        yield
    finally:
        if torch.get_num_threads() != previous:
            torch.set_num_threads(previous)


def _compute_on_worker(compute: Callable, threads: int | None,
                       threads_by_worker: Mapping[str, int], start: int,
                       stop: int) -> xr.Dataset:
    """One chunk on a dask worker, with its torch thread count set for the chunk.

    ``threads`` if given, else the count the caller computed for this worker, else (a worker
    that joined later) the default for the worker's own thread count.
    """
    n = threads
    if n is None:
        from distributed import get_worker

        try:
            worker = get_worker()
        except ValueError:  # not on a worker (a client running tasks inline)
            n = default_torch_threads(1)
        else:
            n = threads_by_worker.get(worker.address)
            if n is None:
                n = default_torch_threads(worker.state.nthreads)
    with _torch_threads(n):
        return compute(start, stop)


def _host_of(address: str) -> str:
    try:
        from distributed.comm import get_address_host

        return get_address_host(address)
    except (ValueError, KeyError):
        return address.rsplit("/", 2)[0]


def _threads_by_worker(client, threads: int | None) -> dict[str, int]:
    """Return the torch threads per worker address.

    That is ``threads``, or ``max(1, cores // threads on the host)`` with each worker's own
    core count and current torch setting.
    """
    nthreads = client.nthreads()
    on_host: dict[str, int] = {}
    for address, count in nthreads.items():
        on_host[_host_of(address)] = on_host.get(_host_of(address), 0) + int(count)
    if threads is not None:
        return dict.fromkeys(nthreads, threads)
    try:
        cores = client.run(usable_cores)
        current = client.run(torch.get_num_threads)
    except Exception as error:  # noqa: BLE001 - a worker that cannot run: its own default
        logger.info("could not query the workers' cores (%s); each uses its own", error)
        return {}
    return {address: default_torch_threads(on_host[_host_of(address)], cores.get(address),
                                           current.get(address))
            for address in nthreads if address in cores}


# --- chunk computation (runs on workers for the dask backend) -------------------------------------

def _compute_chunk(fn: Callable, names: tuple[str, ...], grids: tuple[np.ndarray, ...],
                   start: int, stop: int, broadcast: bool) -> xr.Dataset:
    """Evaluate ``fn`` on points ``start:stop`` of the flattened grid.

    Attributes are made netCDF-safe at once, so fresh and resumed chunks are identical.
    """
    shape = tuple(len(g) for g in grids)
    if broadcast:
        inner = math.prod(shape[1:])
        rows = slice(start // inner, stop // inner)
        sliced = (grids[0][rows],) + tuple(grids[1:])
        kwargs = {}
        for i, (name, values) in enumerate(zip(names, sliced, strict=True)):
            view = [1] * len(names)
            view[i] = -1
            kwargs[name] = torch.as_tensor(values, dtype=torch.float64).reshape(view)
        sliced_shape = tuple(len(v) for v in sliced)
        return sanitized_attributes(_broadcast_chunk(fn(**kwargs), sliced_shape))
    indices = np.unravel_index(np.arange(start, stop), shape)
    results = []
    for point in range(stop - start):
        kwargs = {name: _python_value(grid[index[point]])
                  for name, grid, index in zip(names, grids, indices, strict=True)}
        results.append(_as_record(fn(**kwargs)))
    if isinstance(results[0], dict):
        return _stack_records(results)
    return sanitized_attributes(_stack_points(results))


# --- store ---------------------------------------------------------------------------------

def _stable(value, containers: bool = True):
    """Describe ``value`` as JSON-able data that is the same in every process and run.

    Numbers, strings, tuples, frozensets, arrays and tensors are described by value
    (arrays and tensors by dtype, shape and a hash of their bytes), and so are lists, sets
    and mappings when ``containers`` is true; functions, classes and modules by their
    qualified name; anything else (and, with ``containers`` false, a list, set or mapping,
    which may be a cache or an accumulator filled by the calls) by its type only.
    """
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, bytes):
        return {"bytes": hashlib.sha256(value).hexdigest()}
    if isinstance(value, (complex, np.generic, np.datetime64)):
        return repr(value)
    if isinstance(value, (torch.Tensor, np.ndarray)):
        array = np.ascontiguousarray(to_numpy(value))
        return {"array": str(array.dtype), "shape": list(array.shape),
                "sha256": hashlib.sha256(array.tobytes()).hexdigest()}
    if isinstance(value, tuple) or (containers and isinstance(value, list)):
        return [_stable(v, containers) for v in value]
    if isinstance(value, frozenset) or (containers and isinstance(value, set)):
        return sorted((_stable(v, containers) for v in value),
                      key=lambda v: json.dumps(v, sort_keys=True))
    if containers and isinstance(value, Mapping):
        return {str(k): _stable(v, containers) for k, v in value.items()}
    if isinstance(value, types.ModuleType):
        return {"module": value.__name__}
    if isinstance(value, (types.FunctionType, types.BuiltinFunctionType, types.MethodType,
                          type, functools.partial)):
        return {"callable": _function_name(value)}
    return {"object": f"{type(value).__module__}.{type(value).__qualname__}"}


def _code_constant(value) -> str:
    """Return a process-independent text for one constant of a code object."""
    if isinstance(value, types.CodeType):
        return _code_digest(value)
    if isinstance(value, frozenset):
        return "frozenset(" + ",".join(sorted(_code_constant(v) for v in value)) + ")"
    if isinstance(value, tuple):
        return "(" + ",".join(_code_constant(v) for v in value) + ")"
    return repr(value)


def _code_digest(code: types.CodeType) -> str:
    """Hash of a code object's bytecode, constants (nested code included) and names."""
    digest = hashlib.sha256(code.co_code)
    for part in (code.co_names, code.co_varnames, code.co_freevars):
        digest.update(repr(part).encode())
    for const in code.co_consts:
        digest.update(_code_constant(const).encode())
    return digest.hexdigest()


def _code_identity(fn: Callable) -> dict[str, str | None]:
    """Source hash (when Python can find the source) or bytecode hash of ``fn``."""
    target = fn
    if not isinstance(fn, (types.FunctionType, types.MethodType, type,
                           types.BuiltinFunctionType)):
        target = type(fn).__call__  # a callable object: its class's __call__
    target = inspect.unwrap(target)
    try:
        source = inspect.getsource(target)
    except (OSError, TypeError):
        source = None
    if source is not None:
        return {"source_sha256": hashlib.sha256(source.encode()).hexdigest()}
    code = getattr(getattr(target, "__func__", target), "__code__", None)
    return {"bytecode_sha256": None if code is None else _code_digest(code)}


def function_fingerprint(fn: Callable) -> str:
    """Return a hash that changes when the swept function ``fn`` is edited.

    It covers ``fn``'s qualified name; its code: the source text when Python can find it
    (``inspect.getsource``), else its bytecode with the constants (nested functions
    included) and the global and attribute names it uses; its default arguments and the
    values of the variables it closes over (numbers, strings, tuples, arrays, tensors; a
    list, set, dict or other object only by its type, since it may be a cache or a
    counter that the calls change); and the arguments bound by ``functools.partial``
    (containers included, as in the ``[fixed]`` table of ``skytorch sweep``). A callable
    module (``skytorch.sweep``,
    ``skytorch.moon.reflectance``) is identified by its namesake function and a callable
    object by its class's ``__call__``. What ``fn`` calls or imports is not covered.

    Parameters
    ----------
    fn : callable
        The swept function.

    Returns
    -------
    str
        64 hexadecimal digits (SHA-256), the same in every process and run for the same
        code.

    Examples
    --------
    >>> def f(x):
    ...     return x + 1
    >>> def g(x):
    ...     return x + 2
    >>> function_fingerprint(f) == function_fingerprint(f)
    True
    >>> function_fingerprint(f) == function_fingerprint(g)
    False
    """
    target, bound = _unwrap(fn)
    closure = getattr(target, "__closure__", None) or ()
    cells = []
    for cell in closure:
        try:
            cells.append(_stable(cell.cell_contents, containers=False))
        except ValueError:  # an empty cell (a variable not yet assigned)
            cells.append(None)
    description = {
        "function": _function_name(target),
        "code": _code_identity(target),
        "defaults": _stable(getattr(target, "__defaults__", None), containers=False),
        "keyword_defaults": _stable(getattr(target, "__kwdefaults__", None), containers=False),
        "closure": cells,
        "bound": _stable(bound),
    }
    text = json.dumps(description, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def _store_format(store) -> str:
    """``".zarr"`` for a store path ending in ``.zarr`` (Zarr chunks), else ``".nc"``."""
    return ZARR_SUFFIX if Path(store).suffix.lower() == ZARR_SUFFIX else ".nc"


def _store_directory(store, fn, names, grids, chunk_size, backend, key) -> tuple[Path, str]:
    """Return the store's directory for this sweep and the sweep key (SHA-256 of its text)."""
    description = {
        "function": _function_name(fn),
        "function_fingerprint": function_fingerprint(fn),
        "parameters": {n: [str(v) for v in g.tolist()] for n, g in zip(names, grids, strict=True)},
        "dtypes": {n: str(g.dtype) for n, g in zip(names, grids, strict=True)},
        "chunk_size": chunk_size,
        "broadcast": backend == "broadcast",
        "key": key,
    }
    text = json.dumps(description, sort_keys=True)
    digest = hashlib.sha256(text.encode()).hexdigest()
    directory = Path(store) / f"{description['function'].rsplit('.', 1)[-1]}-{digest[:20]}"
    directory.mkdir(parents=True, exist_ok=True)
    manifest = directory / "sweep.json"
    if not manifest.exists():
        manifest.write_text(text + "\n")
    return directory, digest


def _chunk_path(directory: Path, start: int, stop: int, suffix: str = ".nc") -> Path:
    return directory / f"chunk_{start:09d}_{stop:09d}{suffix}"


def chunk_parameter_hash(sweep_key: str, start: int, stop: int, suffix: str) -> str:
    """Return the parameter hash recorded beside a stored chunk.

    It hashes the sweep key and the chunk's bounds and format, so that another chunk's
    file (or another sweep's) is never served.
    """
    text = json.dumps({"sweep": sweep_key, "start": int(start), "stop": int(stop),
                       "format": suffix}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def _zarr_manifest(store: Path) -> Path:
    """Return the verified file standing for a Zarr chunk store (a directory): its file digests."""
    return store.with_name(store.name + ".files.json")


def _tree_digests(store: Path) -> dict[str, str]:
    return {item.relative_to(store).as_posix(): file_sha256(item)
            for item in sorted(store.rglob("*")) if item.is_file()}


def _store_chunk(chunk: xr.Dataset, path: Path, parameter_hash: str) -> None:
    """Write one chunk through :func:`skytorch._cache.write_verified`.

    A netCDF chunk is the verified file itself. A Zarr chunk is a directory, so the
    verified file is a manifest beside it listing the SHA-256 of every file in the store.
    """
    if path.suffix != ZARR_SUFFIX:
        write_verified(path, parameter_hash, lambda target: to_netcdf(chunk, target))
        return

    def write(manifest: Path) -> None:
        write_dataset(chunk, path)
        text = json.dumps({"store": path.name, "files": _tree_digests(path)}, sort_keys=True)
        manifest.write_text(text + "\n")

    write_verified(_zarr_manifest(path), parameter_hash, write)


def _read_zarr_chunk(path: Path, manifest: Path) -> xr.Dataset:
    recorded = json.loads(manifest.read_text())
    if recorded.get("store") != path.name or recorded.get("files") != _tree_digests(path):
        raise ValueError(f"the files of {path.name} differ from its manifest")
    return open_dataset(path)


def _load_chunk(path: Path, parameter_hash: str) -> xr.Dataset | None:
    """Load a stored chunk if it is intact and is this chunk of this sweep, else ``None``.

    :func:`skytorch._cache.read_verified` checks the content checksum and the parameter
    hash (sweep key and bounds); a corrupted, truncated, swapped or unreadable chunk is
    deleted (with its record) and recomputed.
    """
    zarr = path.suffix == ZARR_SUFFIX
    verified = _zarr_manifest(path) if zarr else path
    if not verified.exists() and not path.exists():
        return None
    if zarr:
        loaded = read_verified(verified, parameter_hash,
                               lambda manifest: _read_zarr_chunk(path, manifest))
    else:
        loaded = read_verified(verified, parameter_hash, open_dataset)
    if loaded is None:
        logger.warning("recomputing sweep chunk %s: missing checksum record, unreadable, "
                       "corrupted or not this chunk of this sweep", path)
        if zarr and path.exists():
            shutil.rmtree(path, ignore_errors=True)
        else:
            discard(path)
    return loaded


# --- dask -----------------------------------------------------------------------------------------

@contextlib.contextmanager
def _dask_client(client, scheduler_address, n_workers, cluster_options) -> Iterator[object]:
    if client is not None:
        yield client
        return
    from distributed import Client, LocalCluster

    if scheduler_address is not None:
        with Client(scheduler_address) as remote:
            yield remote
        return
    import dask

    options = {"n_workers": DEFAULT_WORKERS if n_workers is None else n_workers,
               "threads_per_worker": 1, "processes": False, "dashboard_address": ":0"}
    options.update(cluster_options or {})
    with dask.config.set(WORKER_PROCESS_CONFIG):  # read when the workers are created
        cluster = LocalCluster(**options)
    with cluster, Client(cluster) as local:
        yield local


def _run_dask(todo, compute, client, scheduler_address, n_workers, cluster_options,
              on_done, threads: int | None = None) -> None:
    from distributed import as_completed

    with _dask_client(client, scheduler_address, n_workers, cluster_options) as active:
        per_worker = _threads_by_worker(active, threads)
        logger.info("sweep on dask: torch threads per worker %s", per_worker or threads)
        task = functools.partial(_compute_on_worker, compute, threads, per_worker)
        futures = {active.submit(task, start, stop, pure=False): (start, stop)
                   for start, stop in todo}
        failure = None
        try:
            for future in as_completed(futures):
                start, stop = futures[future]
                try:
                    chunk = future.result()
                except Exception as error:  # keep the other chunks, raise at the end
                    logger.error("sweep chunk %d:%d failed: %s", start, stop, error)
                    failure = failure or error
                    continue
                on_done(start, stop, chunk)
        finally:
            for future in futures:
                future.cancel()
        if failure is not None:
            raise failure


# --- assembly ------------------------------------------------------------------------------

def _assemble(chunks: list[xr.Dataset], names, grids, units, fn):
    """Concatenate the flat chunks and reshape the point dimension into the grid."""
    first = chunks[0]
    shape = tuple(len(g) for g in grids)
    data_vars = {}
    for name in first.data_vars:
        values = np.concatenate([c[name].values for c in chunks], axis=0)
        inner_dims = first[name].dims[1:]
        data_vars[name] = xr.Variable(
            (*names, *inner_dims), values.reshape(shape + values.shape[1:]),
            attrs=_result_attrs(name, first[name].attrs),
        )
    function = _function_name(fn).replace("{", "{{").replace("}", "}}")
    coords = batch_coordinates(
        {name: len(grid) for name, grid in zip(names, grids, strict=True)},
        {name: ((name,), grid) for name, grid in zip(names, grids, strict=True)},
        units=units, long_name="swept parameter {name}",
        description=f"Values of the keyword argument {{name}} passed to {function}.")
    for name, coord in first.coords.items():
        coords[name] = coord.variable
    used = {dim for v in data_vars.values() for dim in v.dims}
    coords.update(batch_coordinates(
        {dim: first.sizes[dim] for dim in sorted(used - set(coords))},
        index_description="Position along the result dimension {dim}."))
    references = first.attrs.get("references", ())
    references = [r for r in (references.split("\n") if isinstance(references, str)
                              else references) if r]
    return build_dataset(
        data_vars, coords,
        title=f"parameter sweep of {_function_name(fn)}",
        # a function without references of its own: the method is the sweep itself
        references=references or [f"skytorch {__version__}: skytorch.sweep.sweep, Cartesian "
                                  f"parameter sweep of {_function_name(fn)}"],
        parameters={"function": _function_name(fn),
                    "swept_parameters": list(names),
                    "grid": {n: g.tolist() for n, g in zip(names, grids, strict=True)}},
        sweep_dimensions=",".join(names),
        result_title=first.attrs.get("title", ""),
    )


def _result_attrs(name: str, attrs: Mapping[str, object]) -> dict:
    attrs = dict(attrs)
    attrs.setdefault("units", "1")
    attrs.setdefault("long_name", name)
    attrs.setdefault("description", f"{name} returned by the swept function")
    return attrs


def _point_bytes(fn, names, grids, broadcast) -> int:
    """Size of one grid point's result [bytes] (one evaluation at the first point)."""
    chunk = _compute_chunk(fn, names, tuple(g[:1] for g in grids), 0, 1, broadcast)
    return max(1, sum(v.values.nbytes for v in chunk.data_vars.values()))


# --- public function ------------------------------------------------------------------------------

def sweep(
    fn: Callable,
    *,
    backend: str = "serial",
    chunk_size: int | None = None,
    memory_budget_bytes: int | None = None,
    store: str | Path | None = None,
    key: str | None = None,
    progress: bool = True,
    client=None,
    scheduler_address: str | None = None,
    n_workers: int | None = None,
    cluster_options: Mapping[str, object] | None = None,
    units: Mapping[str, str] | None = None,
    torch_threads: int | None = None,
    **parameter_grids,
) -> xr.Dataset:
    """Evaluate ``fn`` over the Cartesian grid of the keyword parameter grids.

    Parameters
    ----------
    fn : callable
        Called as ``fn(**point)``; returns an ``xarray.Dataset``, ``DataArray``, tensor,
        numpy array, number, or a mapping of names to tensors/arrays/numbers, with the
        same layout at every point.
    backend : {"serial", "broadcast", "dask"}
        How the grid is evaluated (module docstring).
    chunk_size : int, optional
        Grid points per chunk (rounded up to whole slabs of the first parameter for
        ``"broadcast"``). Default: from ``memory_budget_bytes`` if given, else the whole
        grid (``"serial"``, ``"broadcast"``) or about four chunks per worker (``"dask"``).
    memory_budget_bytes : int, optional
        Bound on the result bytes held per chunk; the size of one point's result is
        measured with one evaluation at the first grid point.
    store : str or Path, optional
        Directory for resumable chunk results: netCDF files, or Zarr stores when the path
        ends in ``.zarr`` (needs the optional ``zarr`` package); see the module docstring.
    key : str, optional
        Extra text hashed into the store key, e.g. a version of what ``fn`` calls (``fn``'s
        own code is hashed already, :func:`function_fingerprint`).
    progress : bool
        Show a tqdm progress bar over grid points (only on a terminal).
    client : distributed.Client, optional
        Existing dask client for ``backend="dask"``.
    scheduler_address : str, optional
        Address of a dask scheduler (e.g. ``"tcp://10.0.0.1:8786"``) for ``"dask"``.
    n_workers : int, optional
        Workers of the LocalCluster started for ``"dask"`` (default 2).
    cluster_options : mapping, optional
        Further ``distributed.LocalCluster`` arguments, overriding the defaults
        ``threads_per_worker=1, processes=False, dashboard_address=":0"`` (a free port; e.g.
        ``{"processes": True}`` for worker processes, free of GIL contention but slower
        to start; see :data:`WORKER_PROCESS_CONFIG`). Starting a LocalCluster costs about
        a second with threads, 5-15 s with processes; pass ``client=`` to reuse one across
        sweeps.
    units : mapping of str to str, optional
        Units (UDUNITS strings) of swept parameters for the coordinates' metadata, keyed
        by swept parameter name; by default inferred from suffixes (``_nm`` nm, ``_m`` m,
        ``_k`` K, ``_deg`` degree, ``_du`` DU, ``_m_s2`` m s-2, ...:
        :func:`skytorch.dataset.units_from_name`), otherwise ``"1"``. A key that names
        no swept parameter, or a value that is not a non-empty string, is rejected.
    torch_threads : int, optional
        torch intra-op threads of each worker thread while it computes a chunk (see
        *Threads* in the module docstring). Default: ``max(1, cores // worker threads on
        the host)``, capped by the worker's current ``torch.get_num_threads()`` -- all of
        the caller's threads for ``"serial"``/``"broadcast"``, one each for two dask workers
        on two cores. The caller's count is restored afterwards.
    **parameter_grids : sequence
        One 1-D sequence of distinct values per swept keyword parameter (numbers,
        strings or datetime64). Names of this function's own arguments (``backend``,
        ``key``, ``units``, ...) cannot be swept directly: wrap ``fn`` to rename them.
        Each name must be a keyword ``fn`` accepts (checked against its signature when
        Python can read one), so a misspelled option or parameter raises ``TypeError``.

    Returns
    -------
    xarray.Dataset
        Variables with dimensions ``(*parameters, *result_dims)``; coordinates are the
        swept values; global attributes record the function, the grid
        (``parameters`` JSON, ``sweep_dimensions``) and the result's references.

    Raises
    ------
    ValueError, TypeError
        No parameters, bad grids or options (each error names the argument), swept names
        ``fn`` does not accept, dask-only options with another backend, or results whose
        layout changes.

    Examples
    --------
    >>> ds = sweep(lambda x, n: x**n, x=[2.0, 3.0], n=[1, 2], progress=False)
    >>> ds["result"].values.tolist()
    [[2.0, 4.0], [3.0, 9.0]]
    """
    _check_call(fn, backend, parameter_grids)
    refuse_gradient("sweep", **parameter_grids)
    names = tuple(parameter_grids)
    _check_accepted(fn, names)
    grids = tuple(_grid_values(n, v) for n, v in parameter_grids.items())
    units = _check_units(units, names)
    _check_options(backend=backend, progress=progress, store=store, key=key, client=client,
                   scheduler_address=scheduler_address, n_workers=n_workers,
                   cluster_options=cluster_options)
    if torch_threads is not None:
        torch_threads = check_int("torch_threads", torch_threads, 1)
    broadcast = backend == "broadcast"
    if broadcast:
        _check_numeric_grids(names, grids)
    if n_workers is not None:
        n_workers = check_int("n_workers", n_workers, 1)
    n_points = math.prod(len(g) for g in grids)
    chunk_size = _chunk_size(fn, names, grids, backend, chunk_size, memory_budget_bytes,
                             n_workers)
    spans = _chunks(n_points, chunk_size)
    directory, sweep_key, suffix, results = _stored_chunks(store, fn, names, grids, chunk_size,
                                                           backend, key, spans)
    todo = [span for span in spans if span not in results]

    from tqdm import tqdm

    bar = tqdm(total=n_points, desc=f"sweep {_function_name(fn)}", unit="point",
               disable=None if progress else True,
               initial=sum(stop - start for start, stop in results))

    def done(start: int, stop: int, chunk: xr.Dataset) -> None:
        if directory is not None:
            _store_chunk(chunk, _chunk_path(directory, start, stop, suffix),
                         chunk_parameter_hash(sweep_key, start, stop, suffix))
        results[(start, stop)] = chunk
        bar.update(stop - start)

    compute = functools.partial(_compute_chunk, fn, names, grids, broadcast=broadcast)
    caller_threads = torch.get_num_threads()
    try:
        if backend == "dask" and todo:
            _run_dask(todo, compute, client, scheduler_address, n_workers, cluster_options,
                      done, torch_threads)
        elif todo:
            threads = torch_threads or default_torch_threads(1)
            with _torch_threads(threads):
                for start, stop in todo:
                    done(start, stop, compute(start, stop))
    finally:
        bar.close()
        # worker threads in this process may have changed the default count that threads
        # starting later inherit (OpenMP backend): re-assert the caller's
        torch.set_num_threads(caller_threads)
    ordered = [results[span] for span in spans]
    return _assemble(ordered, names, grids, units, fn)


def _chunk_size(fn, names, grids, backend: str, chunk_size, memory_budget_bytes,
                n_workers) -> int:
    """Return the grid points per chunk (whole slabs of the first parameter for broadcast)."""
    shape = tuple(len(g) for g in grids)
    n_points = math.prod(shape)
    broadcast = backend == "broadcast"
    slab = math.prod(shape[1:]) if broadcast else 1
    if chunk_size is not None:
        chunk_size = check_int("chunk_size", chunk_size, 1)
    elif memory_budget_bytes is not None:
        budget = check_int("memory_budget_bytes", memory_budget_bytes, 1)
        chunk_size = max(1, budget // _point_bytes(fn, names, grids, broadcast))
    elif backend == "dask":
        workers = DEFAULT_WORKERS if n_workers is None else n_workers
        chunk_size = max(1, math.ceil(n_points / (4 * workers)))
    else:
        chunk_size = n_points
    return min(n_points, math.ceil(chunk_size / slab) * slab)


def _stored_chunks(store, fn, names, grids, chunk_size: int, backend: str, key,
                   spans: list[tuple[int, int]]):
    """Load the intact chunks of this sweep from ``store``.

    Returns ``(directory, sweep_key, suffix, results)``: the sweep's directory and key
    (``None`` without a store), the chunk file suffix and the loaded chunks by span.
    """
    results: dict[tuple[int, int], xr.Dataset] = {}
    if store is None:
        return None, None, ".nc", results
    suffix = _store_format(store)
    if suffix == ZARR_SUFFIX:
        import_zarr()  # fail before computing anything
    directory, sweep_key = _store_directory(store, fn, names, grids, chunk_size, backend, key)
    for start, stop in spans:
        loaded = _load_chunk(_chunk_path(directory, start, stop, suffix),
                             chunk_parameter_hash(sweep_key, start, stop, suffix))
        if loaded is not None:
            results[(start, stop)] = loaded
    logger.info("sweep store %s: %d of %d chunks already done", directory, len(results),
                len(spans))
    return directory, sweep_key, suffix, results


# --- argument checks ------------------------------------------------------------------------

#: keyword options of :func:`sweep` (for the hint on a misspelled one)
_OPTIONS = ("backend", "chunk_size", "memory_budget_bytes", "store", "key", "progress",
            "client", "scheduler_address", "n_workers", "cluster_options", "units",
            "torch_threads")


def _check_accepted(fn: Callable, names: Sequence[str]) -> None:
    """Every swept name must be a keyword ``fn`` accepts (when its signature is readable)."""
    try:
        signature = inspect.signature(fn)
    except (TypeError, ValueError):  # builtins and some C callables: nothing to check
        return
    parameters = signature.parameters.values()
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters):
        return
    accepted = {p.name for p in parameters
                if p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD,
                              inspect.Parameter.KEYWORD_ONLY)}
    unknown = [name for name in names if name not in accepted]
    if unknown:
        import difflib

        hints = []
        for name in unknown:
            close = difflib.get_close_matches(name, [*_OPTIONS, *sorted(accepted)], n=1)
            if close:
                hints.append(f"{name} (did you mean {close[0]}?)")
        hint = f"; {', '.join(hints)}" if hints else ""
        raise TypeError(
            f"sweep parameter {', '.join(unknown)} is not a keyword argument of "
            f"{_function_name(fn)}, which accepts {sorted(accepted)}{hint}")


def _check_call(fn, backend, parameter_grids) -> None:
    """Check the backend name, that ``fn`` is callable and that a grid is given."""
    if not isinstance(backend, str):
        raise TypeError(f"backend must be one of {BACKENDS}; got {backend!r:.80}")
    check_choice("backend", backend, BACKENDS)
    if not callable(fn):
        raise TypeError(f"fn must be callable; got {fn!r:.80}")
    if not parameter_grids:
        raise ValueError("sweep needs at least one parameter grid, e.g. turbidity=[1, 2, 3]")


def _check_numeric_grids(names: Sequence[str], grids) -> None:
    """Raise ``TypeError`` unless every grid is numeric (needed by ``backend="broadcast"``)."""
    for name, grid in zip(names, grids, strict=True):
        if grid.dtype.kind not in "biuf":
            raise TypeError(f"backend='broadcast' needs numeric grids; {name} is {grid.dtype}")


def _check_units(units, names: Sequence[str]) -> dict[str, str]:
    if units is None:
        return {}
    if not isinstance(units, Mapping):
        raise TypeError(
            f"units must be a mapping of swept parameter names to unit strings; got "
            f"{type(units).__name__}")
    checked = {}
    for name, unit in units.items():
        if not isinstance(name, str):
            raise TypeError(f"units keys must be parameter names (str); got {name!r:.80}")
        if name not in names:
            raise ValueError(
                f"units names {name!r}, which is not a swept parameter; swept: {list(names)}")
        if not isinstance(unit, str) or not unit.strip():
            raise TypeError(
                f"units[{name!r}] must be a non-empty UDUNITS string (\"1\" for "
                f"dimensionless); got {unit!r:.80}")
        checked[name] = unit
    return checked


def _check_options(*, backend, progress, store, key, client, scheduler_address, n_workers,
                   cluster_options) -> None:
    """Check the types of the options and their combinations (TypeError/ValueError)."""
    if not isinstance(progress, (bool, np.bool_)):
        raise TypeError(f"progress must be True or False; got {progress!r:.80}")
    if store is not None and not isinstance(store, (str, os.PathLike)):
        raise TypeError(f"store must be a directory path (str or os.PathLike); got "
                        f"{type(store).__name__}")
    if key is not None and not isinstance(key, str):
        raise TypeError(f"key must be a str (e.g. a version); got {key!r:.80}")
    if scheduler_address is not None and not isinstance(scheduler_address, str):
        raise TypeError(f"scheduler_address must be a str such as 'tcp://host:8786'; got "
                        f"{scheduler_address!r:.80}")
    if client is not None and scheduler_address is not None:
        raise ValueError("pass either client or scheduler_address, not both")
    _check_dask_options(backend=backend, client=client, scheduler_address=scheduler_address,
                        n_workers=n_workers, cluster_options=cluster_options)


def _check_dask_options(*, backend, client, scheduler_address, n_workers,
                        cluster_options) -> None:
    """Check the options that apply to ``backend="dask"`` only."""
    if cluster_options is not None:
        if not isinstance(cluster_options, Mapping) or not all(
                isinstance(k, str) for k in cluster_options):
            raise TypeError(f"cluster_options must be a mapping of LocalCluster argument "
                            f"names to values; got {cluster_options!r:.80}")
        if client is not None or scheduler_address is not None:
            raise ValueError("cluster_options configure the LocalCluster the sweep starts; "
                             "they cannot apply to a given client or scheduler_address")
    if backend != "dask":
        given = [name for name, value in (("client", client),
                                          ("scheduler_address", scheduler_address),
                                          ("n_workers", n_workers),
                                          ("cluster_options", cluster_options))
                 if value is not None]
        if given:
            raise ValueError(f"{', '.join(given)} apply only to backend='dask'; got "
                             f"backend={backend!r}")


# this module is callable as :func:`sweep`, so ``st.sweep(...)`` always works
make_callable(__name__)
