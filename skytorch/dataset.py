"""Tensors to CF-annotated ``xarray.Dataset`` objects, and lossless netCDF I/O.

This is the boundary layer: tensors become numpy arrays only here. Metadata is declared
next to the computation that produces a variable (as in xclim): a module describes each
output once with :class:`VariableSpec` and builds its Dataset with :func:`build_dataset`,
which enforces the conventions of ``DESIGN.md``:

* every dimension has a coordinate;
* every variable and coordinate has ``units``, ``long_name`` and ``description``, and a
  CF ``standard_name`` where one exists;
* global attributes ``Conventions``, ``title``, ``source`` (with the skytorch version),
  ``history``, ``references``, and the full parameter set that produced the Dataset
  (``parameters`` as JSON, plus one ``parameter_<name>`` attribute per scalar).

:func:`to_netcdf` writes atomically (a temporary file renamed into place, so an
interrupted write never destroys an existing file) and :func:`open_dataset` reads the file
back fully into memory; the round trip is exact. :func:`to_zarr` does the same for a Zarr
store (a directory; needs the optional ``zarr`` package, ``pip install 'skytorch[zarr]'``),
:func:`write_dataset` chooses between the two by the path's suffix (``.zarr`` or not) and
:func:`open_dataset` reads both.

Examples
--------
>>> import torch
>>> from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable
>>> ds = build_dataset(
...     {"tau": variable(("wavelength",), torch.tensor([0.36, 0.097]),
...                      VariableSpec("1", "optical depth", "Rayleigh optical depth"))},
...     {"wavelength": coordinate("wavelength", [400.0, 550.0],
...                               VariableSpec("nm", "wavelength", "vacuum wavelength"))},
...     title="example", parameters={"pressure_pa": 101325.0})
>>> ds.attrs["Conventions"]
'CF-1.10'
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import os
import shutil
import stat
import uuid
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import xarray as xr

from skytorch import __version__

__all__ = [
    "UNIT_SUFFIXES",
    "VariableSpec",
    "batch_coordinates",
    "build_dataset",
    "coordinate",
    "import_zarr",
    "open_dataset",
    "sanitized_attributes",
    "to_netcdf",
    "to_numpy",
    "to_zarr",
    "units_from_name",
    "variable",
    "write_dataset",
]

CONVENTIONS = "CF-1.10"
#: path suffix of a Zarr store (:func:`write_dataset`, :func:`open_dataset`)
ZARR_SUFFIX = ".zarr"
#: Zarr format written by :func:`to_zarr`: version 2, which every Zarr reader supports and
#: which, unlike version 3 in zarr-python 3.1, has a specified encoding for string arrays
ZARR_FORMAT = 2
#: the ``pip install`` extra that provides zarr
ZARR_EXTRA = "skytorch[zarr]"


@dataclass(frozen=True)
class VariableSpec:
    """Metadata of one Dataset variable, declared next to the code computing it.

    Parameters
    ----------
    units : str
        UDUNITS string (``"1"`` for dimensionless, ``"degree"`` for angles).
    long_name : str
        Human-readable name.
    description : str
        One or two sentences: what the quantity is and how it was computed.
    standard_name : str, optional
        CF standard name, only where CF defines one.
    """

    units: str
    long_name: str
    description: str = ""
    standard_name: str | None = None

    def attrs(self) -> dict[str, str]:
        """Return the attribute dictionary for xarray."""
        attrs = {"units": self.units, "long_name": self.long_name,
                 "description": self.description or self.long_name}
        if self.standard_name:
            attrs["standard_name"] = self.standard_name
        return attrs


def to_numpy(value) -> np.ndarray:
    """Detach a tensor (or pass through array-likes) and return a numpy array."""
    if isinstance(value, torch.Tensor):
        return value.detach().cpu().numpy()
    return np.asarray(value)


def _is_time(values: np.ndarray) -> bool:
    return np.issubdtype(values.dtype, np.datetime64) or np.issubdtype(
        values.dtype, np.timedelta64
    )


def variable(dims, values, spec: VariableSpec | Mapping[str, str]) -> xr.Variable:
    """One annotated ``xarray.Variable`` from a tensor or array.

    Datetime variables keep their metadata but no ``units`` attribute: their units are an
    encoding chosen when writing netCDF (CF ``"nanoseconds since ..."``).
    """
    if isinstance(dims, str):
        dims = (dims,)
    array = to_numpy(values)
    attrs = spec.attrs() if isinstance(spec, VariableSpec) else dict(spec)
    missing = {"units", "long_name"} - set(attrs)
    if missing and not _is_time(array):
        raise ValueError(f"variable metadata lacks {sorted(missing)}: {attrs}")
    if _is_time(array):
        attrs.pop("units", None)
    if array.ndim != len(dims):
        raise ValueError(
            f"values of shape {array.shape} do not match dimensions {tuple(dims)}"
        )
    return xr.Variable(tuple(dims), array, attrs=attrs)


def coordinate(dim: str, values, spec: VariableSpec | Mapping[str, str]) -> xr.Variable:
    """Build a one-dimensional coordinate variable for dimension ``dim``."""
    return variable((dim,), values, spec)


#: UDUNITS strings of the parameter-name suffixes :func:`units_from_name` recognises, the
#: longest first (``gravity_m_s2`` is ``m s-2``, not ``1``; ``pressure_hpa`` is ``hPa``)
UNIT_SUFFIXES = (
    ("_kg_mol", "kg mol-1"), ("_m_s2", "m s-2"), ("_m_s", "m s-1"),
    ("_mag_arcsec2", "mag arcsec-2"), ("_hpa", "hPa"), ("_deg", "degree"), ("_rad", "rad"),
    ("_mag", "mag"), ("_nm", "nm"), ("_km", "km"), ("_cm", "cm"), ("_mm", "mm"),
    ("_pa", "Pa"), ("_du", "DU"), ("_au", "au"), ("_lm", "lm"), ("_m", "m"), ("_k", "K"),
    ("_s", "s"),
)


def units_from_name(name: str, units: Mapping[str, str] | None = None) -> str:
    """UDUNITS string of a parameter, given explicitly or read from its name's suffix.

    Parameters
    ----------
    name : str
        Parameter name, by the project's convention ending in its unit (``ozone_du``,
        ``wavelength_nm``, ``surface_pressure_pa``; case-insensitive).
    units : mapping of str to str, optional
        Explicit units by name; they take precedence over the suffix.

    Returns
    -------
    str
        ``units[name]`` if given, else the unit of the first matching suffix of
        :data:`UNIT_SUFFIXES`, else ``"1"`` (dimensionless or unknown).

    Examples
    --------
    >>> units_from_name("ozone_du"), units_from_name("gravity_m_s2"), units_from_name("turbidity")
    ('DU', 'm s-2', '1')
    >>> units_from_name("precipitable_water_cm"), units_from_name("wind_m_s")
    ('cm', 'm s-1')
    >>> units_from_name("turbidity", {"turbidity": "1e-3"})
    '1e-3'
    """
    if units and name in units:
        return units[name]
    lower = name.lower()
    for suffix, unit in UNIT_SUFFIXES:
        if lower.endswith(suffix):
            return unit
    return "1"


def batch_coordinates(
    sizes: Mapping[str, int],
    parameters: Mapping[str, tuple[Iterable[str], object]] | None = None,
    *,
    units: Mapping[str, str] | None = None,
    long_name: str = "{label}",
    description: str = "Parameter {name} of the batch members",
    index_long_name: str = "index along {dim}",
    index_description: str = "Position along the batch dimension {dim}",
) -> dict[str, xr.Variable]:
    """Coordinates of batch dimensions: the parameters that vary along them, else an index.

    Each parameter becomes a coordinate over the dimensions it varies along, with units
    from :func:`units_from_name`. A dimension named after a parameter that varies along
    it alone is labelled by that parameter's values; every other dimension of ``sizes``
    gets an integer index coordinate ``0 .. n - 1``.

    Parameters
    ----------
    sizes : mapping of str to int
        The batch dimensions and their lengths, in order.
    parameters : mapping of str to (dims, values), optional
        Values of each parameter over the named subset of ``sizes``' dimensions (a tensor
        or array of that shape, as in ``xarray.Variable((dims), values)``).
    units : mapping of str to str, optional
        Explicit units of parameters (see :func:`units_from_name`).
    long_name, description : str
        Templates of a parameter coordinate's metadata; ``{name}`` is the parameter's
        name, ``{label}`` the name with spaces for underscores.
    index_long_name, index_description : str
        Templates of an index coordinate's metadata; ``{dim}`` is the dimension's name,
        ``{axis}`` its position in ``sizes``.

    Returns
    -------
    dict of str to xarray.Variable
        The parameter coordinates (in the order given), then the index coordinates.

    Raises
    ------
    ValueError
        If a parameter names a dimension not in ``sizes`` or its shape differs from the
        sizes, or if a dimension is named after a parameter that varies along other
        dimensions too.

    Examples
    --------
    >>> import torch
    >>> coords = batch_coordinates({"ozone_du": 2, "case": 3},
    ...                            {"ozone_du": (("ozone_du",), torch.tensor([250.0, 350.0]))})
    >>> coords["ozone_du"].attrs["units"], coords["case"].values.tolist()
    ('DU', [0, 1, 2])
    """
    coords: dict[str, xr.Variable] = {}
    for name, (dims, values) in (parameters or {}).items():
        dims = (dims,) if isinstance(dims, str) else tuple(dims)
        array = to_numpy(values)
        expected = tuple(sizes.get(dim, -1) for dim in dims)
        if array.shape != expected:
            raise ValueError(
                f"batch coordinate {name} over {dims} must have shape "
                f"{tuple(sizes.get(dim) for dim in dims)} (batch dimensions "
                f"{dict(sizes)}); got {array.shape}")
        text = {"name": name, "label": name.replace("_", " ")}
        coords[name] = variable(dims, array, VariableSpec(
            units_from_name(name, units), long_name.format(**text),
            description.format(**text)))
    for axis, (dim, size) in enumerate(sizes.items()):
        if dim in coords and coords[dim].dims == (dim,):
            continue  # labelled by the parameter's values
        if dim in coords:
            raise ValueError(f"batch dimension {dim!r} is named after a parameter that "
                             f"varies along {coords[dim].dims}")
        text = {"dim": dim, "axis": axis}
        coords[dim] = coordinate(dim, np.arange(size), VariableSpec(
            "1", index_long_name.format(**text), index_description.format(**text)))
    return coords


TIME_SPEC = VariableSpec("", "time (UTC)", "Instant in Coordinated Universal Time.", "time")


def time_coordinate(times, dim: str = "time") -> xr.Variable:
    """Build a ``datetime64[ns]`` UTC time coordinate from datetime64 values."""
    values = np.asarray(times, dtype="datetime64[ns]").reshape(-1)
    return coordinate(dim, values, TIME_SPEC)


def _attribute_value(value):
    """Return a netCDF-safe attribute value (str, int, float or 1-D numeric array)."""
    if isinstance(value, torch.Tensor):
        value = to_numpy(value)
    if isinstance(value, np.ndarray):
        if value.ndim == 0:
            value = value.item()
        elif value.dtype.kind in "fiu" and value.ndim == 1:
            return value
        else:
            return json.dumps(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return str(bool(value))
    if value is None:
        return "None"
    if isinstance(value, (int, float, str, np.integer, np.floating)):
        return value
    if isinstance(value, (_dt.datetime, _dt.date, np.datetime64)):
        return str(value)
    return json.dumps(value, default=str)


def _json_default(value):
    if isinstance(value, torch.Tensor):
        return to_numpy(value).tolist()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.integer, np.floating)):
        return value.item()
    return str(value)


def build_dataset(
    data_vars: Mapping[str, xr.Variable],
    coords: Mapping[str, xr.Variable],
    *,
    title: str,
    references: Iterable[str] | str = (),
    parameters: Mapping[str, object] | None = None,
    history: str | None = None,
    **attrs,
) -> xr.Dataset:
    """Assemble a CF-annotated Dataset and check the conventions.

    Parameters
    ----------
    data_vars : mapping of str to xarray.Variable
        Built with :func:`variable`.
    coords : mapping of str to xarray.Variable
        Built with :func:`coordinate`; every dimension used must have one.
    title : str
        Short description of the Dataset.
    references : str or iterable of str
        Literature the computation follows (one entry per reference, with DOI).
    parameters : mapping, optional
        Every parameter that affects the result, so a file is reproducible on its own.
    history : str, optional
        Provenance line; defaults to a UTC timestamp and the skytorch version.
    **attrs
        Further global attributes (netCDF-safe values are produced automatically).

    Returns
    -------
    xarray.Dataset

    Raises
    ------
    ValueError
        If a dimension has no coordinate.
    """
    dataset = xr.Dataset(dict(data_vars), coords=dict(coords))
    uncovered = [dim for dim in dataset.dims if dim not in dataset.coords]
    if uncovered:
        raise ValueError(f"dimensions without a coordinate: {uncovered}")
    if isinstance(references, str):
        references = [references]
    now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    parameters = dict(parameters or {})
    global_attrs = {
        "Conventions": CONVENTIONS,
        "title": title,
        "source": f"skytorch {__version__}",
        "history": history or f"{now}: created with skytorch {__version__}",
        "references": "\n".join(references),
        "parameters": json.dumps(parameters, default=_json_default, sort_keys=True),
    }
    for key, value in parameters.items():
        global_attrs[f"parameter_{key}"] = _attribute_value(value)
    for key, value in attrs.items():
        global_attrs[key] = _attribute_value(value)
    dataset.attrs.update(global_attrs)
    return dataset


def sanitized_attributes(dataset: xr.Dataset) -> xr.Dataset:
    """Copy of ``dataset`` whose attributes netCDF can store.

    Parameters
    ----------
    dataset : xarray.Dataset
        Any Dataset; its data are shared, not copied.

    Returns
    -------
    xarray.Dataset
        A shallow copy whose global and variable attributes are netCDF-safe values
        (booleans, None, sequences and mappings converted as :func:`build_dataset` does).
    """
    out = dataset.copy(deep=False)
    out.attrs = {k: _attribute_value(v) for k, v in dataset.attrs.items()}
    for name in out.variables:
        out[name].attrs = {k: _attribute_value(v) for k, v in dataset[name].attrs.items()}
    return out


#: time units for stored datetimes, coarsest first, with their length [ns]; UDUNITS (and
#: so CF checkers) knows all but nanoseconds, which are used only when a value needs them
_TIME_UNITS = (("seconds", 10**9), ("milliseconds", 10**6), ("microseconds", 10**3),
               ("nanoseconds", 1))


def _exact_time_units(values: np.ndarray) -> str:
    """Return the coarsest ``"<unit> since 1970-01-01"`` in which every datetime is an integer."""
    ticks = np.asarray(values, dtype="datetime64[ns]").view("int64").reshape(-1)
    ticks = ticks[ticks != np.iinfo(np.int64).min]  # NaT
    for unit, length in _TIME_UNITS:
        if not (ticks % length).any():
            return f"{unit} since 1970-01-01"
    return "nanoseconds since 1970-01-01"  # pragma: no cover - length 1 always divides


def _time_encoding(dataset: xr.Dataset) -> dict[str, dict[str, str]]:
    """Encode datetimes as int64 counts since 1970 in the coarsest exact unit.

    Seconds for whole seconds, ..., nanoseconds only where needed, so that the round trip
    is exact.
    """
    return {name: {"units": _exact_time_units(var.values), "dtype": "int64"}
            for name, var in dataset.variables.items()
            if np.issubdtype(var.dtype, np.datetime64)}


#: zlib level :func:`to_netcdf` uses by default (1 fastest ... 9 smallest); 4 is within a few
#: per cent of level 9 in size for skytorch's renders and several times faster to write
DEFAULT_COMPRESSION_LEVEL = 4


#: arrays smaller than this are stored uncompressed [bytes]: the chunk index of a chunked
#: HDF5 dataset costs more than deflate saves on a few kilobytes
MIN_COMPRESSED_BYTES = 16384


def _compressible(var: xr.Variable) -> bool:
    """Tell whether netCDF-4 can deflate ``var`` with profit.

    Deflation needs chunked storage: not scalars, strings or small arrays.
    """
    return (var.ndim > 0 and var.nbytes >= MIN_COMPRESSED_BYTES
            and var.dtype.kind in "biufcmM")


def _netcdf_encoding(dataset: xr.Dataset, compress: bool, level: int,
                     significant_digits: int | None = None) -> dict[str, dict[str, object]]:
    """Return the encoding of every variable: exact datetimes and, with ``compress``, zlib+shuffle.

    zlib (deflate) with the byte-shuffle filter is lossless, so float32/float64 values come
    back bit for bit; scalars and strings are stored uncompressed (netCDF-4 can only deflate
    chunked fixed-size data). With ``significant_digits`` the floating-point arrays that are
    compressed are first quantised by netCDF-4's granular bit rounding (lossy, opt-in).
    """
    encoding: dict[str, dict[str, object]] = {name: {} for name in dataset.variables}
    for name, spec in _time_encoding(dataset).items():
        encoding[name].update(spec)
    for name, var in dataset.variables.items():
        if compress and _compressible(var):
            encoding[name].update(zlib=True, complevel=level, shuffle=True)
            if significant_digits is not None and np.issubdtype(var.dtype, np.floating):
                encoding[name].update(significant_digits=significant_digits,
                                      quantize_mode="GranularBitRound")
        else:
            encoding[name].update(zlib=False)
    return {name: spec for name, spec in encoding.items() if spec}


def _check_dataset_and_path(dataset, path, file: bool = False) -> Path:
    """Check the Dataset and the path of a writer; ``file``: a directory there is refused."""
    if not isinstance(dataset, xr.Dataset):
        raise TypeError(f"dataset must be an xarray.Dataset; got {type(dataset).__name__}")
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path must be a str or os.PathLike; got {type(path).__name__}")
    path = Path(path)
    if not str(path) or path.name in ("", ".", ".."):
        raise ValueError(f"path must name a file; got {str(path)!r}")
    if file and path.is_dir():
        raise ValueError(f"path must name a file; {str(path)!r} is a directory")
    return path


def _new_temporary_file(path: Path, suffix: str) -> Path:
    """Create an empty file beside ``path`` with the mode ``open(path, "w")`` would give.

    ``open()`` creates a file with mode ``0o666`` less the process umask (0644 under umask
    022) and keeps the mode of a file it overwrites; ``tempfile.mkstemp`` would create
    0600, unreadable for colleagues sharing the directory. The netCDF library writes into
    this file in place, so the mode survives the write and the rename.
    """
    while True:
        temporary = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}{suffix}")
        try:
            handle = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:  # pragma: no cover - a 48-bit random name collision
            continue
        os.close(handle)
        break
    with contextlib.suppress(OSError):  # as open() does, an overwritten file keeps its mode
        if path.is_file():
            os.chmod(temporary, stat.S_IMODE(path.stat().st_mode))
    return temporary


def to_netcdf(dataset: xr.Dataset, path: str | os.PathLike, *, compress: bool = True,
              compression_level: int = DEFAULT_COMPRESSION_LEVEL,
              significant_digits: int | None = None) -> Path:
    """Write ``dataset`` to a netCDF-4 file atomically and return the path.

    The file is first written next to its destination and then renamed, so an interrupted
    write never leaves a truncated file or destroys an existing one. Datetimes are stored
    as int64 counts since 1970-01-01 in the coarsest unit that holds them exactly
    (``seconds`` for whole seconds, down to ``nanoseconds``), so that the round trip is
    exact and, where nanoseconds are not needed, the units are valid UDUNITS as CF
    requires. Variables are compressed with
    zlib and the shuffle filter by default (lossless: values come back bit for bit; a
    256 x 256 all-sky render shrinks several-fold).

    The new file gets the permissions ``open(path, "w")`` would give it: ``0o666`` less the
    process umask (``-rw-r--r--`` under umask 022, ``-rw-------`` under 077), or the mode of
    the file it replaces.

    Parameters
    ----------
    dataset : xarray.Dataset
        Built by :func:`build_dataset` (attributes that netCDF cannot hold are encoded).
        Encodings carried from a file it was read from are ignored.
    path : str or os.PathLike
        Destination; missing parent directories are created.
    compress : bool
        Deflate every numeric array variable of at least :data:`MIN_COMPRESSED_BYTES`
        (default True); ``False`` writes them uncompressed (faster to write, larger).
        Scalars, strings and smaller arrays are stored uncompressed.
    compression_level : int
        zlib level, 1 (fastest) to 9 (smallest); default
        :data:`DEFAULT_COMPRESSION_LEVEL` (4); checked but unused when ``compress`` is False.
    significant_digits : int, optional
        **Lossy, opt-in.** Keep this many significant decimal digits (1-15) of the
        compressed floating-point arrays, by netCDF-4's granular bit rounding (Kouznetsov
        2021, doi:10.5194/gmd-14-377-2021), before deflating: the relative error of every
        value is below half a unit in the last kept digit,
        ``5 * 10**-significant_digits``, and the files shrink further (a
        384 x 384 all-sky render: 1.8x lossless, 4.7x with 7 digits). The default (None)
        keeps the exact round trip. Needs ``compress=True``. The number of digits is
        recorded in each quantised variable's attributes.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    TypeError
        If ``dataset`` is not an ``xarray.Dataset``, ``path`` not a path, ``compress`` not a
        bool or ``compression_level`` not an integer.
    ValueError
        If ``compression_level`` is outside 1-9 or ``path`` names no file.

    Examples
    --------
    >>> import os, stat, tempfile, pathlib
    >>> import skytorch as st
    >>> ds = st.ephemeris.sun_moon(["2024-06-20T20:51Z"])
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     mask = os.umask(0o022)
    ...     try:
    ...         path = to_netcdf(ds, pathlib.Path(folder) / "sun_moon.nc")
    ...     finally:
    ...         _ = os.umask(mask)
    ...     mode = stat.filemode(path.stat().st_mode)
    ...     back = open_dataset(path)
    >>> mode
    '-rw-r--r--'
    >>> bool((back.sun_dec == ds.sun_dec).all()), back.time.dtype
    (True, dtype('<M8[ns]'))
    """
    path = _check_dataset_and_path(dataset, path, file=True)
    if not isinstance(compress, (bool, np.bool_)):
        raise TypeError(f"compress must be True or False; got {compress!r:.80}")
    if isinstance(compression_level, (bool, np.bool_)) or not isinstance(
            compression_level, (int, np.integer)):
        raise TypeError(
            f"compression_level must be an integer from 1 to 9; got {compression_level!r:.80}")
    if not 1 <= int(compression_level) <= 9:
        raise ValueError(f"compression_level must be from 1 to 9; got {int(compression_level)}")
    if significant_digits is not None:
        if isinstance(significant_digits, (bool, np.bool_)) or not isinstance(
                significant_digits, (int, np.integer)):
            raise TypeError("significant_digits must be None or an integer from 1 to 15; "
                            f"got {significant_digits!r:.80}")
        if not 1 <= int(significant_digits) <= 15:
            raise ValueError("significant_digits must be from 1 to 15; "
                             f"got {int(significant_digits)}")
        if not compress:
            raise ValueError("significant_digits needs compress=True (quantisation only "
                             "pays off before deflation); got compress=False")
        significant_digits = int(significant_digits)
    path.parent.mkdir(parents=True, exist_ok=True)
    dataset = sanitized_attributes(dataset)
    for var in dataset.variables.values():
        var.encoding = {}  # stale chunk sizes or filters of a file it was read from
    encoding = _netcdf_encoding(dataset, bool(compress), int(compression_level),
                                significant_digits)
    temporary = _new_temporary_file(path, ".nc.tmp")
    try:
        dataset.to_netcdf(temporary, engine="netcdf4", encoding=encoding)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path


def import_zarr():
    """Import the optional zarr package.

    Returns
    -------
    module
        The ``zarr`` module.

    Raises
    ------
    ImportError
        When zarr is not installed; the message names the extra that provides it.
    """
    try:
        import zarr
    except ImportError as error:
        raise ImportError(
            f"Zarr export needs the optional dependency zarr: pip install '{ZARR_EXTRA}' "
            "(or pip install zarr); netCDF (to_netcdf) needs nothing extra"
        ) from error
    return zarr


def _replace_path(source: Path, destination: Path) -> None:
    """Move ``source`` (a file or directory) to ``destination``, replacing what is there.

    An existing destination is first renamed aside and only deleted once ``source`` is in
    place, so at every instant either the old or the new content is complete on disk.
    """
    if not destination.exists() and not destination.is_symlink():
        os.replace(source, destination)
        return
    aside = destination.with_name(f".{destination.name}.{uuid.uuid4().hex[:12]}.old")
    os.replace(destination, aside)
    try:
        os.replace(source, destination)
    except BaseException:
        os.replace(aside, destination)
        raise
    if aside.is_dir() and not aside.is_symlink():
        shutil.rmtree(aside, ignore_errors=True)
    else:
        aside.unlink(missing_ok=True)


def _new_temporary_directory(path: Path, suffix: str) -> Path:
    """Create an empty directory beside ``path`` with the mode ``os.mkdir`` gives.

    That is ``0o777`` less the umask; ``tempfile.mkdtemp`` would give 0700.
    """
    while True:
        temporary = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}{suffix}")
        try:
            os.mkdir(temporary, 0o777)
        except FileExistsError:  # pragma: no cover - a 48-bit random name collision
            continue
        return temporary


def to_zarr(dataset: xr.Dataset, path: str | os.PathLike) -> Path:
    """Write ``dataset`` to a Zarr store (a directory) atomically and return the path.

    The store is first written to a temporary directory next to its destination and then
    renamed into place; an existing store at ``path`` is renamed aside first and deleted
    only after the new store is in place, so an interrupted write never leaves a partial
    store or destroys the existing one. The store is Zarr format 2 with consolidated
    metadata (readable by zarr-python 2 and 3, xarray and netCDF-C's NCZarr); datetimes are
    int64 counts as in :func:`to_netcdf`, so the round trip through
    :func:`open_dataset` is exact.

    Parameters
    ----------
    dataset : xarray.Dataset
        Built by :func:`build_dataset` (attributes are encoded as for netCDF).
    path : str or os.PathLike
        Destination directory, conventionally ending in ``.zarr``; missing parent
        directories are created.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ImportError
        If the optional ``zarr`` package is not installed (``pip install 'skytorch[zarr]'``).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import skytorch as st
    >>> ds = st.sweep(lambda x, n: x**n, x=[2.0, 3.0], n=[1, 2], progress=False)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     store = to_zarr(ds, pathlib.Path(folder) / "powers.zarr")
    ...     print(store.name, store.is_dir(), open_dataset(store).identical(ds))
    powers.zarr True True
    """
    path = _check_dataset_and_path(dataset, path)
    import_zarr()
    path.parent.mkdir(parents=True, exist_ok=True)
    dataset = sanitized_attributes(dataset)
    temporary = _new_temporary_directory(path, ".zarr.tmp")
    try:
        dataset.to_zarr(temporary, mode="w", encoding=_time_encoding(dataset),
                        zarr_format=ZARR_FORMAT, consolidated=True)
        _replace_path(temporary, path)
    except BaseException:
        shutil.rmtree(temporary, ignore_errors=True)
        raise
    return path


def _is_zarr(path: Path) -> bool:
    return path.suffix.lower() == ZARR_SUFFIX


def write_dataset(dataset: xr.Dataset, path: str | os.PathLike) -> Path:
    """Write ``dataset`` as a Zarr store if ``path`` ends in ``.zarr``, else as netCDF.

    Both writes are atomic (:func:`to_zarr`, :func:`to_netcdf`).

    Parameters
    ----------
    dataset : xarray.Dataset
        Built by :func:`build_dataset`.
    path : str or os.PathLike
        ``*.zarr`` for a Zarr store (needs the optional ``zarr`` package), anything else
        (conventionally ``*.nc``) for netCDF-4.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = _check_dataset_and_path(dataset, path)
    return to_zarr(dataset, path) if _is_zarr(path) else to_netcdf(dataset, path)


def open_dataset(path: str | os.PathLike) -> xr.Dataset:
    """Read a netCDF file or Zarr store written by this module fully into memory.

    A path ending in ``.zarr`` or naming a directory is read as a Zarr store, anything
    else as netCDF.

    Raises
    ------
    TypeError
        If ``path`` is not a str or os.PathLike.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path must be a str or os.PathLike; got {type(path).__name__}")
    path = Path(path)
    if _is_zarr(path) or path.is_dir():
        import_zarr()
        engine = "zarr"
    else:
        engine = "netcdf4"
    with xr.open_dataset(path, engine=engine) as dataset:
        return dataset.load()
