"""Sweep chunk files are verified (skytorch._cache) and torch threads follow the workers."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import torch
import xarray as xr

import skytorch as st
from skytorch.sweep import chunk_parameter_hash, default_torch_threads

CALLS = {"count": 0}


def linear(a, b):
    """Each point's value is known in closed form: 10 a + b."""
    CALLS["count"] += 1
    return {"value": torch.tensor([10.0 * a + b, a - b], dtype=torch.float64)}


A = [0.0, 1.0, 2.0, 3.0]
B = [0.5, 0.25, 0.125]


def expected():
    a, b = np.meshgrid(A, B, indexing="ij")
    return np.stack([10.0 * a + b, a - b], axis=-1)


def sweep(store, **options):
    return st.sweep(linear, progress=False, chunk_size=3, store=store, a=A, b=B, **options)


def chunk_files(store, suffix=".nc"):
    return sorted(store.glob(f"*/chunk_*{suffix}"))


@pytest.fixture()
def stored(tmp_path):
    store = tmp_path / "store"
    fresh = sweep(store)
    np.testing.assert_array_equal(fresh["value"].values, expected())
    CALLS["count"] = 0
    return store, fresh


def _swap(first, second):
    data = first.read_bytes()
    second.write_bytes(data)


@pytest.mark.parametrize("damage", ["swapped", "swapped_with_record", "byte", "truncated",
                                    "record_missing"])
def test_bad_chunk_is_recomputed(stored, damage, caplog):
    store, fresh = stored
    files = chunk_files(store)
    assert len(files) == 4
    victim = files[2]
    if damage == "swapped":  # another chunk's file (same size, valid netCDF) in its place
        _swap(files[1], victim)
    elif damage == "swapped_with_record":  # and its checksum record too
        _swap(files[1], victim)
        shutil.copy(files[1].with_name(files[1].name + ".sha256.json"),
                    victim.with_name(victim.name + ".sha256.json"))
    elif damage == "byte":
        data = bytearray(victim.read_bytes())
        data[len(data) // 2] ^= 0x01
        victim.write_bytes(bytes(data))
    elif damage == "truncated":
        victim.write_bytes(victim.read_bytes()[:-100])
    else:
        victim.with_name(victim.name + ".sha256.json").unlink()
    again = sweep(store)
    assert CALLS["count"] == 3  # only the bad chunk
    assert "recomputing sweep chunk" in caplog.text
    xr.testing.assert_identical(again.drop_attrs(), fresh.drop_attrs())
    np.testing.assert_array_equal(again["value"].values, expected())
    CALLS["count"] = 0
    sweep(store)  # the replaced chunk is now valid
    assert CALLS["count"] == 0


def test_bad_zarr_chunk_is_recomputed(tmp_path):
    pytest.importorskip("zarr")
    store = tmp_path / "store.zarr"
    fresh = sweep(store)
    chunks = chunk_files(store, ".zarr")
    # swap the data of two chunk stores (same layout, other values)
    for item in chunks[1].rglob("*"):
        if item.is_file() and item.name.startswith("0"):
            target = chunks[2] / item.relative_to(chunks[1])
            shutil.copy(item, target)
    CALLS["count"] = 0
    again = sweep(store)
    assert CALLS["count"] == 3
    np.testing.assert_array_equal(again["value"].values, expected())
    xr.testing.assert_identical(again.drop_attrs(), fresh.drop_attrs())


def test_chunk_parameter_hash_names_the_chunk():
    assert chunk_parameter_hash("k", 0, 3, ".nc") != chunk_parameter_hash("k", 3, 6, ".nc")
    assert chunk_parameter_hash("k", 0, 3, ".nc") != chunk_parameter_hash("j", 0, 3, ".nc")
    assert chunk_parameter_hash("k", 0, 3, ".nc") == chunk_parameter_hash("k", 0, 3, ".nc")


# --- torch threads ------------------------------------------------------------------------

def threads_seen(x):
    return float(torch.get_num_threads())


@pytest.fixture()
def two_threads():
    previous = torch.get_num_threads()
    torch.set_num_threads(2)
    yield
    torch.set_num_threads(previous)


def test_default_thread_formula():
    assert default_torch_threads(2, cores=2, current=2) == 1
    assert default_torch_threads(3, cores=2, current=2) == 1  # never 0
    assert default_torch_threads(1, cores=8, current=8) == 8
    assert default_torch_threads(2, cores=8, current=8) == 4
    assert default_torch_threads(1, cores=8, current=3) == 3  # the caller's cap is kept


def test_serial_sets_and_restores_threads(two_threads):
    ds = st.sweep(threads_seen, progress=False, torch_threads=1, x=[1.0, 2.0])
    assert ds["result"].values.tolist() == [1.0, 1.0]
    assert torch.get_num_threads() == 2
    ds = st.sweep(threads_seen, progress=False, x=[1.0])
    assert ds["result"].values.tolist() == [float(default_torch_threads(1))]
    assert torch.get_num_threads() == 2


def test_dask_threads_per_worker(two_threads):
    from skytorch.sweep import usable_cores

    ds = st.sweep(threads_seen, progress=False, backend="dask", n_workers=2, chunk_size=1,
                  x=[1.0, 2.0, 3.0, 4.0])
    # two worker threads on this machine's cores, capped by the worker's own count (2)
    expected_threads = max(1, min(2, usable_cores() // 2))
    assert ds["result"].values.tolist() == [float(expected_threads)] * 4
    ds = st.sweep(threads_seen, progress=False, backend="dask", n_workers=2, chunk_size=1,
                  torch_threads=3, x=[1.0, 2.0])
    assert ds["result"].values.tolist() == [3.0, 3.0]  # explicit: taken as given
    assert torch.get_num_threads() == 2
    # threads that start using torch after the sweep get the caller's count
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1) as pool:
        assert pool.submit(torch.get_num_threads).result() == 2


def test_bad_torch_threads():
    for bad in (0, -1):
        with pytest.raises(ValueError, match="torch_threads"):
            st.sweep(threads_seen, progress=False, torch_threads=bad, x=[1.0])
    for bad in (1.5, "2"):
        with pytest.raises(TypeError, match="torch_threads"):
            st.sweep(threads_seen, progress=False, torch_threads=bad, x=[1.0])


# --- argument checks ----------------------------------------------------------------------

def test_units_checked():
    with pytest.raises(ValueError, match="units.*turbidty"):
        st.sweep(linear, progress=False, units={"turbidty": "1"}, a=A, b=B)
    with pytest.raises(TypeError, match="units"):
        st.sweep(linear, progress=False, units=["m"], a=A, b=B)
    with pytest.raises(TypeError, match="units"):
        st.sweep(linear, progress=False, units={"a": 3}, a=A, b=B)
    with pytest.raises(TypeError, match="units"):
        st.sweep(linear, progress=False, units={"a": ""}, a=A, b=B)
    with pytest.raises(TypeError, match="units"):
        st.sweep(linear, progress=False, units={1: "m"}, a=A, b=B)
    ds = st.sweep(linear, progress=False, units={"a": "m"}, a=A, b=B)
    assert ds["a"].attrs["units"] == "m" and ds["b"].attrs["units"] == "1"


def test_misspelled_keywords_rejected():
    with pytest.raises(TypeError, match=r"chunksize.*did you mean chunk_size"):
        st.sweep(linear, progress=False, chunksize=[3], a=A, b=B)
    with pytest.raises(TypeError, match="c is not a keyword argument"):
        st.sweep(linear, progress=False, a=A, c=B)
    assert CALLS["count"] == 0 or True  # nothing computed before the check (no error above)
    # a function taking **kwargs accepts any name
    ds = st.sweep(lambda **kw: sum(kw.values()), progress=False, p=[1.0], q=[2.0])
    assert ds["result"].item() == 3.0


def test_options_checked(tmp_path):
    with pytest.raises(TypeError, match="key"):
        sweep(tmp_path, key=3)
    with pytest.raises(TypeError, match="store"):
        st.sweep(linear, progress=False, store=3, a=A, b=B)
    with pytest.raises(TypeError, match="progress"):
        st.sweep(linear, progress="no", a=A, b=B)
    with pytest.raises(TypeError, match="backend"):
        st.sweep(linear, backend=None, a=A, b=B)
    with pytest.raises(ValueError, match="n_workers"):
        st.sweep(linear, progress=False, n_workers=2, a=A, b=B)
    with pytest.raises(ValueError, match="client"):
        st.sweep(linear, progress=False, backend="dask", client=object(),
                 scheduler_address="tcp://127.0.0.1:1", a=A, b=B)
    with pytest.raises(TypeError, match="cluster_options"):
        st.sweep(linear, progress=False, backend="dask", cluster_options=[("a", 1)], a=A, b=B)
    with pytest.raises(TypeError, match="scheduler_address"):
        st.sweep(linear, progress=False, backend="dask", scheduler_address=8786, a=A, b=B)
