"""Tests of skytorch.sweep: backends agree with a plain loop, resume, netCDF, CLI."""

from __future__ import annotations

import functools
import itertools
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest
import torch
import xarray as xr

import skytorch as st
from skytorch.dataset import open_dataset, to_netcdf

TURBIDITY = [1.0, 2.0, 3.0, 5.0]
OZONE_DU = [250.0, 300.0, 350.0]
WAVELENGTH_NM = torch.tensor([440.0, 550.0, 680.0], dtype=torch.float64)

#: calls of the spied functions below (reset by each test that reads it)
CALLS = {"count": 0, "fail_at": None, "fail_turbidity": None}


def transmittance_like(turbidity, ozone_du):
    """Element-wise toy model: works with Python floats and with broadcast tensors."""
    CALLS["count"] += 1
    if CALLS["fail_at"] is not None and CALLS["count"] >= CALLS["fail_at"]:
        raise RuntimeError("simulated interruption")
    if turbidity == CALLS["fail_turbidity"]:
        raise RuntimeError("simulated failure")
    turbidity = torch.as_tensor(turbidity, dtype=torch.float64).unsqueeze(-1)
    ozone = torch.as_tensor(ozone_du, dtype=torch.float64).unsqueeze(-1)
    tau = 0.0088 * (WAVELENGTH_NM / 1000.0) ** -4.05 + 0.05 * (turbidity - 1.0) + 1e-4 * ozone
    return {"transmittance": torch.exp(-tau), "tau_v": tau[..., 1]}


def reference_loop():
    """Independent reference: nested Python loops with math.exp."""
    out = np.empty((len(TURBIDITY), len(OZONE_DU), 3))
    for (i, t), (j, o) in itertools.product(enumerate(TURBIDITY), enumerate(OZONE_DU)):
        for k, wl in enumerate(WAVELENGTH_NM.tolist()):
            tau = 0.0088 * (wl / 1000.0) ** -4.05 + 0.05 * (t - 1.0) + 1e-4 * o
            out[i, j, k] = math.exp(-tau)
    return out


@pytest.fixture(autouse=True)
def _reset_calls():
    CALLS.update(count=0, fail_at=None, fail_turbidity=None)
    yield
    CALLS.update(fail_at=None, fail_turbidity=None)


def run(**options):
    return st.sweep(transmittance_like, progress=False, turbidity=TURBIDITY, ozone_du=OZONE_DU,
                    **options)


def test_serial_matches_plain_loop():
    ds = run()
    assert ds["transmittance"].dims == ("turbidity", "ozone_du", "transmittance_dim_0")
    np.testing.assert_allclose(ds["transmittance"].values, reference_loop(), rtol=1e-14)
    assert ds["turbidity"].values.tolist() == TURBIDITY
    assert ds["ozone_du"].values.tolist() == OZONE_DU
    assert CALLS["count"] == len(TURBIDITY) * len(OZONE_DU)


@pytest.mark.parametrize("options", [
    {"chunk_size": 1}, {"chunk_size": 5}, {"memory_budget_bytes": 64},
    {"backend": "broadcast"}, {"backend": "broadcast", "chunk_size": 4},
])
def test_backends_identical_to_serial(options):
    serial = run()
    other = run(**options)
    xr.testing.assert_identical(serial.drop_attrs(), other.drop_attrs())
    assert serial.attrs["parameters"] == other.attrs["parameters"]


def test_broadcast_calls_once_per_slab():
    run(backend="broadcast")
    assert CALLS["count"] == 1
    CALLS["count"] = 0
    run(backend="broadcast", chunk_size=5)  # rounded up to slabs of 3 ozone values
    assert CALLS["count"] == 2


def test_dask_local_cluster_identical():
    serial = run()
    ds = run(backend="dask", n_workers=2, chunk_size=3)
    xr.testing.assert_identical(serial.drop_attrs(), ds.drop_attrs())
    ds = run(backend="dask", n_workers=1, cluster_options={"threads_per_worker": 2})
    xr.testing.assert_identical(serial.drop_attrs(), ds.drop_attrs())


def test_dask_existing_client():
    from distributed import Client, LocalCluster

    serial = run()
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                      dashboard_address=":0") as cluster, Client(cluster) as client:
        first = run(backend="dask", client=client, chunk_size=4)
        second = run(backend="broadcast")
        assert client.status == "running"  # the sweep leaves a given client open
    xr.testing.assert_identical(serial.drop_attrs(), first.drop_attrs())
    xr.testing.assert_identical(serial.drop_attrs(), second.drop_attrs())


@pytest.mark.parametrize("store_name", ["chunks", "chunks.zarr"])
def test_resume_after_interruption(tmp_path, store_name):
    suffix = ".zarr" if store_name.endswith(".zarr") else ".nc"
    if suffix == ".zarr":
        pytest.importorskip("zarr")
    store = tmp_path / store_name
    n_points = len(TURBIDITY) * len(OZONE_DU)
    CALLS["fail_at"] = 8  # dies during the 8th call: chunks 0-2 and 3-5 are finished
    with pytest.raises(RuntimeError, match="simulated interruption"):
        run(chunk_size=3, store=store)
    stored = sorted(store.glob(f"*/chunk_*{suffix}"))
    assert [p.suffix for p in stored] == [suffix, suffix]
    # each beside its checksum record (Zarr: through a manifest of the store's files)
    records = sorted(store.glob("*/chunk_*.sha256.json"))
    assert len(records) == 2
    CALLS["fail_at"] = None
    CALLS["count"] = 0
    resumed = run(chunk_size=3, store=store)
    assert CALLS["count"] == n_points - 6  # only the two missing chunks
    np.testing.assert_allclose(resumed["transmittance"].values, reference_loop(), rtol=1e-14)
    CALLS["count"] = 0
    again = run(chunk_size=3, store=store)
    assert CALLS["count"] == 0
    xr.testing.assert_identical(resumed.drop_attrs(), again.drop_attrs())
    xr.testing.assert_identical(run().drop_attrs(), again.drop_attrs())


@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
def test_unreadable_chunk_is_recomputed(tmp_path, suffix, caplog):
    import shutil

    if suffix == ".zarr":
        pytest.importorskip("zarr")
    store = tmp_path / f"chunks{suffix}"
    run(chunk_size=3, store=store)
    damaged = sorted(store.glob(f"*/chunk_*{suffix}"))[1]
    if damaged.is_dir():  # a Zarr store without its metadata
        shutil.rmtree(damaged)
        damaged.mkdir()
    else:
        damaged.write_bytes(b"not netCDF")
    CALLS["count"] = 0
    ds = run(chunk_size=3, store=store)
    assert CALLS["count"] == 3  # only the damaged chunk
    assert "recomputing sweep chunk" in caplog.text
    np.testing.assert_allclose(ds["transmittance"].values, reference_loop(), rtol=1e-14)


def test_resume_with_dask(tmp_path):
    # every point with turbidity 3 fails: the dask backend still finishes and persists the
    # other chunks (one turbidity value per chunk of 3 points) before raising
    CALLS["fail_turbidity"] = 3.0
    with pytest.raises(RuntimeError, match="simulated failure"):
        run(backend="dask", n_workers=2, chunk_size=3, store=tmp_path)
    assert len(list(tmp_path.glob("*/chunk_*.nc"))) == 3
    CALLS["fail_turbidity"] = None
    CALLS["count"] = 0
    ds = run(backend="dask", n_workers=1, chunk_size=3, store=tmp_path)
    assert CALLS["count"] == 3
    np.testing.assert_allclose(ds["transmittance"].values, reference_loop(), rtol=1e-14)


def test_netcdf_round_trip_exact(tmp_path):
    ds = run()
    back = open_dataset(to_netcdf(ds, tmp_path / "sweep.nc"))
    xr.testing.assert_identical(ds, back)


def test_metadata():
    ds = run()
    assert ds["ozone_du"].attrs["units"] == "DU"
    assert ds["turbidity"].attrs["units"] == "1"
    assert ds["turbidity"].attrs["long_name"] == "swept parameter turbidity"
    assert ds.attrs["sweep_dimensions"] == "turbidity,ozone_du"
    assert "transmittance_like" in ds.attrs["parameters"]
    assert ds.attrs["Conventions"] == "CF-1.10"
    assert "transmittance_dim_0" in ds.coords
    ds = st.sweep(transmittance_like, progress=False, units={"turbidity": "Linke"},
                  turbidity=[1.0], ozone_du=[300.0])
    assert ds["turbidity"].attrs["units"] == "Linke"


def point_dataset(scale, offset):
    wavelength = [400.0, 500.0]
    return xr.Dataset(
        {"radiance": ("wavelength", np.array(wavelength) * scale + offset,
                      {"units": "W m-2 sr-1 nm-1", "long_name": "radiance"})},
        coords={"wavelength": ("wavelength", wavelength, {"units": "nm"})},
        attrs={"title": "toy", "references": "Ref A\nRef B"},
    )


def test_dataset_dataarray_and_number_results():
    ds = st.sweep(point_dataset, progress=False, scale=[1.0, 2.0], offset=[0.0, 1.0, 2.0])
    assert ds["radiance"].dims == ("scale", "offset", "wavelength")
    assert ds["wavelength"].values.tolist() == [400.0, 500.0]
    assert ds["radiance"].attrs["units"] == "W m-2 sr-1 nm-1"
    assert float(ds["radiance"].sel(scale=2.0, offset=1.0, wavelength=500.0)) == 1001.0
    assert ds.attrs["references"] == "Ref A\nRef B"
    da = st.sweep(lambda scale: point_dataset(scale, 0.0)["radiance"].rename("r"),
                  progress=False, scale=[1.0, 3.0])
    assert da["r"].shape == (2, 2)
    number = st.sweep(lambda n, p: n**p, progress=False, n=[2, 3], p=[0, 1, 2])
    assert number["result"].values.tolist() == [[1, 2, 4], [1, 3, 9]]
    labels = st.sweep(lambda model, x: len(model) * x, progress=False,
                      model=["a", "bb"], x=[1.0, 2.0])
    assert labels["result"].sel(model="bb", x=2.0).item() == 4.0


def test_module_is_callable():
    import importlib

    import skytorch.sweep as module

    package = importlib.import_module("skytorch")
    assert callable(module) and callable(package.sweep)
    ds = package.sweep(lambda x: 2 * x, x=[1.0, 2.0], progress=False)
    assert ds["result"].values.tolist() == [2.0, 4.0]
    ds = module(lambda x: 3 * x, x=[1.0], progress=False)
    assert ds["result"].values.tolist() == [3.0]


def test_bad_input():
    with pytest.raises(ValueError, match="at least one parameter"):
        st.sweep(transmittance_like)
    with pytest.raises(ValueError, match="backend"):
        run(backend="threads")
    with pytest.raises(TypeError, match="sequence"):
        st.sweep(transmittance_like, turbidity=2.0, ozone_du=OZONE_DU)
    with pytest.raises(ValueError, match="repeats"):
        st.sweep(transmittance_like, turbidity=[1.0, 1.0], ozone_du=OZONE_DU)
    with pytest.raises(ValueError, match="finite"):
        st.sweep(transmittance_like, turbidity=[1.0, float("nan")], ozone_du=OZONE_DU)
    with pytest.raises(TypeError, match="numeric"):
        st.sweep(lambda m: 1.0, backend="broadcast", m=["a", "b"])
    with pytest.raises(TypeError, match="broadcast"):
        st.sweep(lambda x: xr.Dataset({"a": ("d", np.zeros(2))}), backend="broadcast",
                 progress=False, x=[1.0, 2.0])
    with pytest.raises(ValueError, match="shape"):
        st.sweep(lambda n: torch.zeros(n), progress=False, n=[1, 2])
    with pytest.raises(ValueError, match="chunk_size"):
        run(chunk_size=0)
    with pytest.raises(ValueError, match="n_workers"):
        run(backend="dask", n_workers=0)


def test_cli_sweep(tmp_path):
    from skytorch.cli import main

    config = tmp_path / "sweep.toml"
    config.write_text(
        'function = "skytorch.spectrum:bv_to_temperature"\n'
        "[parameters]\nbv = [0.0, 0.65, 1.5]\n"
        '[options]\nchunk_size = 2\nunits = {bv = "mag"}\n'
    )
    output = tmp_path / "sweep.nc"
    assert main(["sweep", str(config), "-o", str(output), "--no-progress"]) == 0
    ds = open_dataset(output)
    assert ds["bv"].attrs["units"] == "mag"
    # Ballesteros 2012 closed form
    expected = [4600.0 * (1 / (0.92 * bv + 1.7) + 1 / (0.92 * bv + 0.62))
                for bv in (0.0, 0.65, 1.5)]
    np.testing.assert_allclose(ds["result"].values, expected, rtol=1e-12)
    assert ds.attrs["sweep_function"] == "skytorch.spectrum:bv_to_temperature"
    bad = tmp_path / "bad.toml"
    bad.write_text('function = "skytorch.spectrum:no_such"\n[parameters]\nbv = [0.0]\n')
    assert main(["sweep", str(bad), "-o", str(output)]) == 2
    # the fixed keywords are recorded; a keyword both swept and fixed is an error
    fixed = tmp_path / "fixed.toml"
    fixed.write_text('function = "skytorch.atmosphere.rayleigh:rayleigh_cross_section"\n'
                     "[parameters]\nwavelength_nm = [400.0, 550.0]\n"
                     '[fixed]\ngas = "air"\n')
    assert main(["sweep", str(fixed), "-o", str(output), "--no-progress"]) == 0
    assert json.loads(open_dataset(output).attrs["sweep_fixed"]) == {"gas": "air"}
    fixed.write_text(fixed.read_text() + "wavelength_nm = 500.0\n")
    assert main(["sweep", str(fixed), "-o", str(tmp_path / "both.nc")]) == 2
    assert not (tmp_path / "both.nc").exists()


def test_datetime_grid_round_trip(tmp_path):
    times = np.array(["2015-09-28T01:00", "2015-09-28T02:47"], dtype="datetime64[ns]")
    seen = []

    def hours_since_midnight(time):
        seen.append(time)
        return float((time - np.datetime64("2015-09-28T00:00", "ns")) / np.timedelta64(1, "h"))

    ds = st.sweep(hours_since_midnight, progress=False, time=times)
    assert all(isinstance(t, np.datetime64) for t in seen)
    np.testing.assert_allclose(ds["result"].values, [1.0, 2.0 + 47 / 60], rtol=1e-12)
    assert ds["time"].dtype == np.dtype("datetime64[ns]")
    xr.testing.assert_identical(ds, open_dataset(to_netcdf(ds, tmp_path / "t.nc")))


def test_results_changing_type_are_rejected():
    with pytest.raises(ValueError, match="change"):
        st.sweep(lambda x: {"a": x} if x > 1 else xr.Dataset({"a": ((), x)}), progress=False,
                 x=[1.0, 2.0])
    with pytest.raises(ValueError, match="change"):
        st.sweep(lambda x: {"a": x} if x > 1 else {"b": x}, progress=False, x=[1.0, 2.0])


def test_cli_sweep_zarr_output(tmp_path, monkeypatch):
    from skytorch.cli import main

    pytest.importorskip("zarr")
    config = tmp_path / "sweep.toml"
    config.write_text('function = "skytorch.spectrum:bv_to_temperature"\n'
                      "[parameters]\nbv = [0.0, 0.65, 1.5]\n")
    output = tmp_path / "sweep.zarr"
    assert main(["sweep", str(config), "-o", str(output), "--no-progress"]) == 0
    assert (output / ".zmetadata").is_file()
    ds = open_dataset(output)
    expected = [4600.0 * (1 / (0.92 * bv + 1.7) + 1 / (0.92 * bv + 0.62))  # Ballesteros 2012
                for bv in (0.0, 0.65, 1.5)]
    np.testing.assert_allclose(ds["result"].values, expected, rtol=1e-12)
    assert ds.attrs["sweep_function"] == "skytorch.spectrum:bv_to_temperature"
    # without zarr: a clear message naming the extra, before anything is computed
    monkeypatch.setitem(sys.modules, "zarr", None)
    assert main(["sweep", str(config), "-o", str(tmp_path / "other.zarr")]) == 2
    assert not (tmp_path / "other.zarr").exists()
    with pytest.raises(ImportError, match=r"skytorch\[zarr\]"):
        run(store=tmp_path / "chunks.zarr")
    assert CALLS["count"] == 0


# --- dask worker processes and a remote scheduler ------------------------------------------------

def square_and_pid(x):
    """Module-level function: worker processes import it from this module by name."""
    trim = os.environ.get("MALLOC_TRIM_THRESHOLD_")
    return {"square": x * x, "pid": os.getpid(), "malloc_trim": -1 if trim is None else int(trim)}


@pytest.mark.slow  # starting two worker processes that import torch: 5-25 s on 2 cores
def test_dask_worker_processes():
    # the sweep's own LocalCluster with two single-threaded worker processes
    ds = st.sweep(square_and_pid, progress=False, backend="dask", n_workers=2, chunk_size=1,
                  cluster_options={"processes": True}, x=[1.0, 2.0, 3.0, 4.0])
    assert ds["square"].values.tolist() == [1.0, 4.0, 9.0, 16.0]
    pids = set(ds["pid"].values.tolist())
    assert os.getpid() not in pids and 1 <= len(pids) <= 2
    # glibc's malloc trimming as in this process, not dask's 65536 for worker processes
    here = os.environ.get("MALLOC_TRIM_THRESHOLD_")
    assert set(ds["malloc_trim"].values.tolist()) == {-1 if here is None else int(here)}


def test_dask_scheduler_address_identical_to_serial():
    from distributed import LocalCluster

    mu0, mu, phase = [0.3, 0.9], [0.5, 1.0], [0.2, 1.1, 2.0]
    serial_module = st.sweep(st.moon.reflectance, progress=False, mu0=mu0, mu=mu,
                             phase_angle_rad=phase)
    serial = run()
    # a scheduler on the loopback interface, reached only through its address string as a
    # remote cluster would be: tasks, the pickled function and results all cross TCP
    # (worker processes are covered by test_dask_worker_processes; in-process workers
    # keep this test fast)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp",
                      host="127.0.0.1", dashboard_address=":0") as cluster:
        address = cluster.scheduler_address
        assert isinstance(address, str) and address.startswith("tcp://127.0.0.1:")
        remote = run(backend="dask", scheduler_address=address, chunk_size=3)
        # a callable module as the swept function travels to the workers by name
        remote_module = st.sweep(st.moon.reflectance, progress=False, backend="dask",
                                 scheduler_address=address, chunk_size=4, mu0=mu0, mu=mu,
                                 phase_angle_rad=phase)
        assert len(cluster.scheduler_info["workers"]) == 2  # the sweep left the cluster up
    xr.testing.assert_identical(serial.drop_attrs(), remote.drop_attrs())
    np.testing.assert_allclose(remote["transmittance"].values, reference_loop(), rtol=1e-14)
    xr.testing.assert_identical(serial_module.drop_attrs(), remote_module.drop_attrs())
    assert "skytorch.moon.reflectance.reflectance" in remote_module.attrs["parameters"]


# --- the store key follows the function's code ---------------------------------------------------

def test_store_key_follows_function_code(tmp_path):
    calls = []

    def shift(x):
        calls.append(x)
        return x + 1.0

    versions = [shift]

    def shift(x):  # same qualified name, edited body
        calls.append(x)
        return x + 2.0

    versions.append(shift)
    grid = {"x": [0.0, 10.0, 20.0], "store": tmp_path, "chunk_size": 1, "progress": False}
    first = st.sweep(versions[0], **grid)
    assert len(calls) == 3 and first["result"].values.tolist() == [1.0, 11.0, 21.0]
    second = st.sweep(versions[1], **grid)  # nothing of the first version is reused
    assert len(calls) == 6 and second["result"].values.tolist() == [2.0, 12.0, 22.0]
    again = st.sweep(versions[0], **grid)  # the first version's chunks are still there
    assert len(calls) == 6 and again["result"].values.tolist() == [1.0, 11.0, 21.0]
    assert len(list(tmp_path.glob("*/chunk_*.nc"))) == 6

    def scaled(factor):
        return lambda x: calls.append(x) or x * factor

    st.sweep(scaled(2.0), **grid)
    doubled = st.sweep(scaled(2.0), **grid)  # same code and captured value: resumed
    tripled = st.sweep(scaled(3.0), **grid)  # same code, another captured value
    assert len(calls) == 12
    assert doubled["result"].values.tolist() == [0.0, 20.0, 40.0]
    assert tripled["result"].values.tolist() == [0.0, 30.0, 60.0]


#: a function whose code has a set constant (a frozenset, ordered by string hashes)
MEMBER_SOURCE = "import numpy as np\ndef member(x):\n    return x in {'alpha', 'beta', 'gamma'}\n"


def _compiled(source: str, name: str):
    namespace = {"__name__": "generated"}
    exec(compile(source, "<generated>", "exec"), namespace)  # no source file: bytecode hashed
    return namespace[name]


def test_function_fingerprint_without_source():
    from skytorch.sweep import function_fingerprint

    def fingerprint(source):
        return function_fingerprint(_compiled("import numpy as np\n" + source, "f"))

    base = fingerprint("def f(x):\n    return np.sin(x) + 1\n")
    assert fingerprint("def f(x):\n    return np.sin(x) + 1\n") == base
    assert fingerprint("def f(x):\n    return np.sin(x) + 2\n") != base  # a constant
    assert fingerprint("def f(x):\n    return np.cos(x) + 1\n") != base  # a name used
    assert fingerprint("def f(x, y=1):\n    return np.sin(x) + 1\n") != base  # a default
    nested = "def f(x):\n    g = lambda: {0}\n    return g()\n"
    assert fingerprint(nested.format(1)) != fingerprint(nested.format(2))  # nested code
    add = _compiled("def add(x, y):\n    return x + y\n", "add")
    assert (function_fingerprint(functools.partial(add, y=1.0))
            != function_fingerprint(functools.partial(add, y=2.0)))
    assert (function_fingerprint(st.moon.reflectance)
            == function_fingerprint(st.moon.reflectance.reflectance))
    assert len(base) == 64 and int(base, 16) >= 0


def test_function_fingerprint_same_in_another_process():
    from skytorch.spectrum import bv_to_temperature
    from skytorch.sweep import function_fingerprint

    script = (
        "import sys\n"
        "from skytorch.spectrum import bv_to_temperature\n"
        "from skytorch.sweep import function_fingerprint as fp\n"
        "namespace = {'__name__': 'generated'}\n"
        "exec(compile(sys.argv[1], '<generated>', 'exec'), namespace)\n"
        "print(fp(namespace['member']), fp(bv_to_temperature))\n"
    )
    expected = [function_fingerprint(_compiled(MEMBER_SOURCE, "member")),
                function_fingerprint(bv_to_temperature)]
    # another string-hash seed than this process (random unless set), so another frozenset
    # order in the bytecode constants
    seed = "1" if os.environ.get("PYTHONHASHSEED") == "2" else "2"
    env = {**os.environ, "PYTHONHASHSEED": seed}
    out = subprocess.run([sys.executable, "-c", script, MEMBER_SOURCE], env=env, check=True,
                         capture_output=True, text=True).stdout.split()
    assert out == expected


def test_cli_dask_options_reach_sweep(tmp_path, monkeypatch):
    import importlib

    from skytorch.cli import main

    module = importlib.import_module("skytorch.sweep")

    seen = {}
    real = module.sweep

    def spy(fn, **options):
        seen.update(options)
        return real(fn, **{k: v for k, v in options.items()
                           if k not in ("backend", "cluster_options", "n_workers")})

    monkeypatch.setattr(module, "sweep", spy)
    config = tmp_path / "sweep.toml"
    config.write_text('function = "skytorch.spectrum:bv_to_temperature"\n'
                      "[parameters]\nbv = [0.0, 1.5]\n"
                      '[options]\ncluster_options = {memory_limit = "1GiB"}\n')
    output = tmp_path / "sweep.nc"
    assert main(["sweep", str(config), "-o", str(output), "--no-progress", "--backend", "dask",
                 "--workers", "2", "--processes"]) == 0
    assert seen["backend"] == "dask" and seen["n_workers"] == 2
    assert seen["cluster_options"] == {"memory_limit": "1GiB", "processes": True}
    assert open_dataset(output)["bv"].values.tolist() == [0.0, 1.5]


def test_cli_sweep_store_in_the_file_is_relative_to_the_file(tmp_path, monkeypatch):
    """It was relative to the working directory (a render file's paths are to the file)."""
    from skytorch.cli import main

    folder = tmp_path / "configs"
    folder.mkdir()
    config = folder / "sweep.toml"
    config.write_text('function = "skytorch.spectrum:bv_to_temperature"\n'
                      "[parameters]\nbv = [0.0, 0.65]\n"
                      '[options]\nstore = "chunks"\n')
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["sweep", str(config), "-o", str(tmp_path / "out.nc"), "--no-progress"]) == 0
    assert (folder / "chunks").is_dir() and not (elsewhere / "chunks").exists()
