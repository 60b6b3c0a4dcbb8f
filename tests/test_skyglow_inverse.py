"""Inverse tools: Q_i (eq. 10–11), S_i (eq. 13–14), eq. 12, minimal reduction."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import xarray as xr
from _conditioning import well_scaled_linprog
from _skyglow_standin import cached_model, single_torch_thread  # noqa: F401

from skytorch.constants import PERCENT
from skytorch.skyglow.citymap import synthetic_city
from skytorch.skyglow.inverse import (
    apply_reduction,
    minimal_reduction,
    pollution_influence,
    reduction_factors,
    sky_region,
    skyglow_influence,
)


def _map(x, y, flux):
    return xr.Dataset({"flux": (("y", "x"), np.asarray(flux, dtype=float))},
                      coords={"x": np.asarray(x, float), "y": np.asarray(y, float)})


def test_pollution_level_is_norm_of_kernel_image():
    model = cached_model()
    j = 5
    r = float(model.distance_m[j])
    ds = pollution_influence(model, _map([0.0], [r], [[2.5e5]]))
    # reference: root-sum-square norm of the kernel image itself (no PCA) at that distance
    kernel = model.kernel[0, j, 0]
    expected = 2.5e5 * float(kernel.pow(2).sum().sqrt())
    assert float(ds["pollution_level"].values[0, 0]) == pytest.approx(expected, rel=0.1 * PERCENT)
    beyond = pollution_influence(model, _map([0.0], [3e5], [[1e6]]), as_dataset=False)
    assert float(beyond[0, 0]) == 0.0


def test_skyglow_influence_adds_up_to_region_luminance():
    model = cached_model()
    x = np.array([-6e3, -1e3, 4e3])
    flux = np.array([[2e5, 0.0, 5e5], [1e5, 3e5, 0.0]])
    city = _map(x, [-2e3, 5e3], flux)
    region = sky_region(model, elevation_deg=(0.0, 30.0), azimuth_deg=(300.0, 60.0))
    s = skyglow_influence(model, city, region)["skyglow_influence"].values
    # independent reference: render each lit cell alone and sum the region's pixels
    for iy, ix in zip(*np.nonzero(flux), strict=True):
        alone = np.zeros_like(flux)
        alone[iy, ix] = flux[iy, ix]
        lum = model.render(_map(x, [-2e3, 5e3], alone))["luminance"].values
        assert s[iy, ix] == pytest.approx(lum[region.numpy()].sum(), rel=1e-9)
    assert np.all(s[flux == 0] == 0)


def test_reduction_factors_equation_12():
    q = torch.tensor([0.0, 1.0, 2.0, 3.0, 4.0])
    gamma = reduction_factors(q, q_a=1.0, q_b=3.0, gamma_user=0.5)
    torch.testing.assert_close(gamma, torch.tensor([0.0, 0.0, 0.25, 0.5, 0.5]))
    with pytest.raises(ValueError, match="q_b"):
        reduction_factors(q, 2.0, 1.0)
    city = _map([0.0, 1.0], [0.0], [[10.0, 20.0]])
    reduced = apply_reduction(city, np.array([[0.5, 1.0]]))
    np.testing.assert_allclose(reduced["flux"].values, [[5.0, 0.0]])


def test_sky_region_wraps_and_rejects_empty():
    model = cached_model()
    mask = sky_region(model, azimuth_deg=(350.0, 10.0))
    az = torch.rad2deg(model.azimuth_rad)
    assert bool(mask[:, az == 0].all()) and not bool(mask[:, (az > 20) & (az < 340)].any())
    with pytest.raises(ValueError, match="no pixel"):
        sky_region(model, elevation_deg=(89.9, 89.95))


def test_minimal_reduction_matches_linear_programme():
    model = cached_model()
    x = np.array([-8e3, -2e3, 3e3, 9e3])
    y = np.array([-3e3, 6e3])
    flux = np.array([[2e5, 8e5, 1e5, 4e5], [6e5, 3e5, 9e5, 2e5]])
    city = _map(x, y, flux)
    region = sky_region(model, elevation_deg=(0.0, 40.0), azimuth_deg=(0.0, 120.0))
    result = minimal_reduction(model, city, region, target_fraction=0.4)
    initial = result.attrs["parameter_initial_luminance_cd_m2"]
    final = result.attrs["parameter_final_luminance_cd_m2"]
    assert final == pytest.approx(0.4 * initial, rel=1e-6)
    # independent reference: scipy's LP with per-cell contributions from single renders
    contributions = []
    for iy, ix in np.ndindex(flux.shape):
        alone = np.zeros_like(flux)
        alone[iy, ix] = flux[iy, ix]
        lum = model.render(_map(x, y, alone))["luminance"].values
        contributions.append(lum[region.numpy()].mean())
    contributions = np.array(contributions)
    # scaled to O(1): the cost as a fraction of the total flux, the constraint as a
    # fraction of the region's initial luminance (final <= 0.4 initial)
    total_flux, total_luminance = flux.sum(), contributions.sum()
    lp = well_scaled_linprog(c=flux.ravel() / total_flux,
                             A_ub=[-contributions / total_luminance], b_ub=[0.4 - 1.0],
                             bounds=[(0.0, 1.0)] * flux.size)
    removed = result.attrs["parameter_removed_flux_lm"]
    assert removed == pytest.approx(lp.fun * total_flux, rel=1e-6)
    assert float(result["reduction"].min()) >= 0 and float(result["reduction"].max()) <= 1


@pytest.mark.parametrize("iterations", [1, 2, 3])
def test_minimal_reduction_is_the_same_after_any_number_of_iterations(iterations):
    """With tolerance 0 a round-off excess repeats the linearised step: it must keep γ.

    The linearisation's right-hand side took +Σ grad γ for −Σ grad γ: every second
    iteration reset γ to 0 (final/initial 1.0, nothing removed at 2 iterations).
    """
    model = cached_model()
    city = synthetic_city(20e3, 1000.0, population=1e5, centre_xy=(3000.0, 0.0))
    region = sky_region(model, elevation_deg=(0.0, 30.0))
    one = minimal_reduction(model, city, region, target_fraction=0.5, tolerance=0.0,
                            max_iterations=1, as_dataset=False)
    result = minimal_reduction(model, city, region, target_fraction=0.5, tolerance=0.0,
                               max_iterations=iterations, as_dataset=False)
    assert result["final_luminance"] == pytest.approx(0.5 * result["initial_luminance"],
                                                      rel=1e-9)
    assert result["removed_flux_lm"] == pytest.approx(one["removed_flux_lm"], rel=1e-9)
    dark = minimal_reduction(model, city, region, target_fraction=0.0, tolerance=0.0,
                             max_iterations=iterations, as_dataset=False)
    assert dark["final_luminance"] <= 1e-12 * dark["initial_luminance"]


def test_reduction_applied_by_dimension_name_on_a_transposed_map():
    """A map stored as (x, y): gamma goes to the cells it was computed for.

    It was applied by position: 98 % of the peak flux moved, 3.59e7 lm removed instead of
    5.64e6. The influence DataArray itself is accepted by reduction_factors.
    """
    model = cached_model()
    city = synthetic_city(20e3, 1000.0, population=1e5, centre_xy=(6000.0, 0.0))
    transposed = city.transpose("x", "y")
    influence = pollution_influence(model, transposed)["pollution_level"]
    gamma = reduction_factors(influence, 0.0, float(influence.max()))
    reduced = apply_reduction(transposed, gamma)["flux"]
    assert reduced.dims == ("x", "y")
    expected = apply_reduction(city, gamma)["flux"]
    np.testing.assert_array_equal(reduced.transpose("y", "x").values, expected.values)
    same = apply_reduction(city, influence / float(influence.max()))["flux"]
    assert float(same.sum()) < float(city["flux"].sum())
