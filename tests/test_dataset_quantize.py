"""to_netcdf(significant_digits=...): lossy quantisation, opt-in, bounded relative error."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from skytorch.dataset import open_dataset, to_netcdf


def _render_like(n: int = 192) -> xr.Dataset:
    """Smooth sky-like fields with full float64 mantissas (as a render produces)."""
    x = np.linspace(-1.0, 1.0, n)
    r2 = x[:, None] ** 2 + x[None, :] ** 2
    radiance = np.exp(-3.0 * r2)[..., None] * np.array([1.0, 1.3, 1.9]) * 1e-9
    radiance *= 1.0 + 0.01 * np.sin(37.0 * x)[:, None, None]
    return xr.Dataset({"radiance": (("y", "x", "channel"), radiance),
                       "v_mag_arcsec2": (("y", "x"), 21.0 + 2.5 * r2)},
                      coords={"y": x, "x": x, "channel": ["r", "g", "b"]})


@pytest.mark.parametrize("digits", [3, 5, 7])
def test_relative_error_is_below_the_requested_digits(tmp_path, digits):
    ds = _render_like()
    back = open_dataset(to_netcdf(ds, tmp_path / "q.nc", significant_digits=digits))
    for name in ds.data_vars:
        relative = np.abs(back[name].values - ds[name].values) / np.abs(ds[name].values)
        # half a unit in the last kept digit: 0.5 * 10**(1 - digits)
        assert relative.max() < 5.0 * 10.0 ** -digits, name
    # coordinates below the compression threshold stay exact
    np.testing.assert_array_equal(back["x"].values, ds["x"].values)


def test_quantised_file_is_smaller_than_the_lossless_one(tmp_path):
    ds = _render_like()
    lossless = to_netcdf(ds, tmp_path / "exact.nc").stat().st_size
    quantised = to_netcdf(ds, tmp_path / "q.nc", significant_digits=7).stat().st_size
    raw = to_netcdf(ds, tmp_path / "raw.nc", compress=False).stat().st_size
    assert quantised < 0.6 * lossless
    assert raw / quantised > 3.0
    # the default is exact
    back = open_dataset(tmp_path / "exact.nc")
    np.testing.assert_array_equal(back["radiance"].values, ds["radiance"].values)


@pytest.mark.parametrize("bad, error", [(0, ValueError), (16, ValueError), (2.5, TypeError),
                                        (True, TypeError), ("7", TypeError)])
def test_bad_significant_digits_are_refused_by_name(tmp_path, bad, error):
    with pytest.raises(error, match="significant_digits"):
        to_netcdf(_render_like(16), tmp_path / "q.nc", significant_digits=bad)


def test_quantisation_needs_compression(tmp_path):
    with pytest.raises(ValueError, match="significant_digits needs compress=True"):
        to_netcdf(_render_like(16), tmp_path / "q.nc", compress=False, significant_digits=7)
