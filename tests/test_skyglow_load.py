"""A saved skyglow model is loaded exactly or refused: corrupted files never become models.

``SkyglowModel.save`` records the SHA-256 of the tables; ``load`` verifies it, checks the
tables' shapes, finiteness and grids, and the mirror symmetry of the basis, and raises
``ValueError`` (so that a cache rebuilds) for anything else.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
import xarray as xr
from _skyglow_standin import cached_model, single_torch_thread  # noqa: F401

from skytorch.skyglow import SkyglowModel
from skytorch.skyglow.model import _tables_digest

BUFFERS = ("azimuth_rad", "elevation_rad", "distance_m", "distance_edges_m",
           "source_altitude_m", "observer_altitude_m", "wavelength_nm", "basis",
           "coefficients", "explained_variance_ratio")


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    path = tmp_path_factory.mktemp("skyglow") / "model.nc"
    cached_model().save(path)
    return path


def _same_tables(a: SkyglowModel, b: SkyglowModel) -> bool:
    return all(torch.equal(getattr(a, n), getattr(b, n)) for n in BUFFERS)


def test_round_trip_is_exact(saved):
    assert _same_tables(SkyglowModel.load(saved), SkyglowModel.load(saved))
    loaded = SkyglowModel.load(saved)
    original = cached_model()
    for name in ("basis", "coefficients", "distance_m", "wavelength_nm"):
        assert torch.equal(getattr(loaded, name), getattr(original, name)), name


def test_byte_corruptions_are_refused_or_harmless(saved, tmp_path):
    """Change one byte at 24 offsets spread over the file.

    Each load either raises ValueError or gives tables identical to the original (the
    byte was padding).
    """
    data = saved.read_bytes()
    reference = SkyglowModel.load(saved)
    refused = harmless = 0
    for offset in np.linspace(0, len(data) - 1, 24).astype(int):
        corrupted = bytearray(data)
        corrupted[offset] ^= 0x5A
        path = tmp_path / f"corrupt_{offset}.nc"
        path.write_bytes(bytes(corrupted))
        try:
            model = SkyglowModel.load(path)
        except ValueError:
            refused += 1
            continue
        assert _same_tables(model, reference), f"byte {offset}: a different model was served"
        harmless += 1
    assert refused >= 1 and refused + harmless == 24


def test_changed_table_value_is_refused(saved, tmp_path):
    with xr.open_dataset(saved) as ds:
        ds = ds.load()
    ds["coefficients"].values[0, 3, 0, 1] *= 1.001  # a plausible value, caught by the digest
    path = tmp_path / "changed.nc"
    ds.to_netcdf(path)
    with pytest.raises(ValueError, match="SHA-256"):
        SkyglowModel.load(path)


def test_asymmetric_basis_is_refused_without_a_digest(saved, tmp_path):
    """A file without the digest (another writer) still has its basis checked."""
    with xr.open_dataset(saved) as ds:
        ds = ds.load()
    ds["basis"].values[0, 1, 3, 0, 0] += 1.0
    del ds.attrs["tables_sha256"]
    path = tmp_path / "asymmetric.nc"
    ds.to_netcdf(path)
    with pytest.raises(ValueError, match="mirror-symmetric"):
        SkyglowModel.load(path)
    # with a matching digest the symmetry check still refuses it
    ds.attrs["tables_sha256"] = _tables_digest(ds)
    ds.to_netcdf(tmp_path / "asymmetric_digest.nc")
    with pytest.raises(ValueError, match="mirror-symmetric"):
        SkyglowModel.load(tmp_path / "asymmetric_digest.nc")


@pytest.mark.parametrize("change", ["nan", "shape", "missing", "parameters"])
def test_inconsistent_files_are_refused(saved, tmp_path, change):
    with xr.open_dataset(saved) as ds:
        ds = ds.load()
    del ds.attrs["tables_sha256"]
    if change == "nan":
        ds["coefficients"].values[0, 0, 0, 0] = np.nan
    elif change == "shape":
        ds = ds.isel(distance=slice(0, -1))
    elif change == "missing":
        ds = ds.drop_vars("coefficients")
    else:
        ds.attrs["parameters"] = "{not json"
    path = tmp_path / f"{change}.nc"
    ds.to_netcdf(path)
    with pytest.raises(ValueError, match="not a valid skyglow model"):
        SkyglowModel.load(path)


def test_truncated_and_missing_files(saved, tmp_path):
    path = tmp_path / "truncated.nc"
    path.write_bytes(saved.read_bytes()[: len(saved.read_bytes()) // 2])
    with pytest.raises(ValueError, match="skyglow model"):
        SkyglowModel.load(path)
    with pytest.raises(FileNotFoundError):
        SkyglowModel.load(tmp_path / "absent.nc")
