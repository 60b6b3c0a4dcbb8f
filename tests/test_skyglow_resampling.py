"""Polar resampling of gridded light maps: density sampling against exact areas and splatting."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
import xarray as xr
from _skyglow_standin import cached_model, single_torch_thread  # noqa: F401

from skytorch.constants import PERCENT
from skytorch.skyglow.citymap import synthetic_city
from skytorch.skyglow.model import light_map_arrays

#: a uniform map's flux per polar cell against the annulus-sector area (midpoint rule in r
#: is exact for r dr; only float rounding remains)
AREA_RTOL = 1e-9
#: sampling against splatting of a smooth 200 m city seen from 8 km (two resamplings of the
#: same map; measured 0.5 % with the benchmark's 256 × 128 grid)
SPLAT_AGREEMENT = 3 * PERCENT


def _uniform_map(density, cell_m, extent_m, altitude=None):
    x = np.arange(-extent_m, extent_m + 1.0, cell_m)
    flux = np.full((x.size, x.size), density * cell_m**2)
    data = {"flux": (("y", "x"), flux)}
    if altitude is not None:
        data["altitude"] = (("y", "x"), np.full(flux.shape, float(altitude)))
    return light_map_arrays(xr.Dataset(data, coords={"x": x, "y": x}))


def test_uniform_map_gives_annulus_sector_areas(dtype):
    model = cached_model()
    density = 2.5  # lm m^-2
    cells = {k: v.to(dtype) for k, v in _uniform_map(density, 400.0, 24e3).items()}
    polar = model.polar_sample(cells, torch.zeros(1, 2, dtype=dtype), oversampling=2)[0, ..., 0]
    edges = model.distance_edges_m
    area = (math.pi / model.azimuth_rad.numel()) * (edges[1:] ** 2 - edges[:-1] ** 2)
    expected = (density * area).expand_as(polar)
    rtol = AREA_RTOL if dtype == torch.float64 else 1e-5
    torch.testing.assert_close(polar.to(torch.float64), expected, rtol=rtol, atol=0.0)


def test_source_altitude_split_between_nodes():
    model = cached_model(n_elevation=8, n_source_altitude=6,
                         source_altitude_range_m=(0.0, 1400.0), n_components=128)
    nodes = model.source_altitude_m
    between = float(0.75 * nodes[2] + 0.25 * nodes[3])
    cells = _uniform_map(1.0, 500.0, 24e3, altitude=between)
    polar = model.polar_sample(cells, torch.zeros(1, 2, dtype=torch.float64))[0]
    total = polar.sum(dim=(0, 1))
    share = total / total.sum()
    torch.testing.assert_close(share, torch.tensor([0, 0, 0.75, 0.25, 0, 0],
                                                   dtype=torch.float64), rtol=0, atol=1e-12)


def test_sampling_agrees_with_splatting_on_a_smooth_city():
    model = cached_model()
    city = synthetic_city(40e3, 200.0, population=1e5)
    splat = model.render(city, observer_xy=(8e3, 0.0), as_dataset=False)["luminance"]
    sample = model.render(city, observer_xy=(8e3, 0.0), as_dataset=False,
                          resampling="sample")["luminance"]
    assert float(((sample - splat).abs() / splat).mean()) < SPLAT_AGREEMENT


def test_sampling_is_differentiable_and_batched():
    model = cached_model()
    x = torch.tensor([-3e3, -1e3, 1e3, 3e3], dtype=torch.float64)
    flux = torch.full((4, 4), 1e5, dtype=torch.float64, requires_grad=True)

    def zenith(f):
        return model.render(f, x_m=x, y_m=x, as_dataset=False, resampling="sample")[
            "luminance"][-1].sum()

    assert torch.autograd.gradcheck(zenith, (flux,), eps=1.0, atol=1e-12, rtol=1e-6)
    xy = [[0.0, 0.0], [1.5e3, -2e3]]
    batch = model.render(flux.detach(), x_m=x, y_m=x, observer_xy=xy, as_dataset=False,
                         resampling="sample")["luminance"]
    for i, p in enumerate(xy):
        single = model.render(flux.detach(), x_m=x, y_m=x, observer_xy=p, as_dataset=False,
                              resampling="sample")["luminance"]
        torch.testing.assert_close(batch[i], single, rtol=1e-12, atol=0.0)


def test_sampling_needs_an_even_grid():
    model = cached_model()
    flux = torch.ones(2, 3, dtype=torch.float64)
    with pytest.raises(ValueError, match="evenly spaced"):
        model.render(flux, x_m=torch.tensor([0.0, 1e3, 5e3]), y_m=torch.tensor([0.0, 1e3]),
                      resampling="sample")
    with pytest.raises(ValueError, match="resampling"):
        model.render(flux, x_m=torch.tensor([0.0, 1e3, 2e3]), y_m=torch.tensor([0.0, 1e3]),
                     resampling="nearest")


@pytest.mark.parametrize("resampling", ["splat", "sample"])
def test_large_observer_batches_equal_single_renders(resampling):
    # from 16 observers on the convolution keeps the observers innermost (another layout)
    model = cached_model()
    city = synthetic_city(24e3, 1000.0, population=1e5)
    generator = torch.Generator().manual_seed(4)
    xy = (torch.rand(20, 2, generator=generator, dtype=torch.float64) - 0.5) * 8e3
    batch = model.render(city, observer_xy=xy, as_dataset=False,
                         resampling=resampling)["luminance"]
    for i in (0, 7, 19):
        single = model.render(city, observer_xy=xy[i], as_dataset=False,
                              resampling=resampling)["luminance"]
        torch.testing.assert_close(batch[i], single, rtol=1e-10, atol=0.0)


def _random_cells(n_side, extent_m, seed, altitude=None):
    generator = torch.Generator().manual_seed(seed)
    coords = torch.linspace(-extent_m, extent_m, n_side, dtype=torch.float64)
    flux = torch.rand(n_side, n_side, generator=generator, dtype=torch.float64) * 1e5
    flux[flux < 3e4] = 0.0  # dark cells too
    alt = None if altitude is None else torch.full_like(flux, float(altitude))
    return light_map_arrays(flux, x_m=coords, y_m=coords, altitude_m=alt)


def test_splat_plan_conserves_flux_within_range(dtype):
    # independent reference: the flux of the cells closer than max_distance_m
    model = cached_model()
    cells = {k: v.to(dtype) for k, v in _random_cells(40, 18e3, seed=3).items()}
    observers = torch.tensor([[0.0, 0.0], [6e3, -2e3]], dtype=dtype)
    plan = model.splat_plan(cells["x"].reshape(-1), cells["y"].reshape(-1),
                            cells["altitude"].reshape(-1), observers)
    assert plan.index.dtype == torch.int32
    polar = plan.apply(cells["flux"])
    assert polar.shape == (2, model.azimuth_rad.numel(), model.distance_m.numel(), 1)
    for i in range(2):
        r = torch.hypot(cells["x"] - observers[i, 0], cells["y"] - observers[i, 1])
        expected = cells["flux"][r <= float(model.distance_edges_m[-1])].sum()
        rtol = 1e-12 if dtype == torch.float64 else 1e-5
        torch.testing.assert_close(polar[i].sum(), expected, rtol=rtol, atol=0.0)


def test_reused_splat_plan_follows_the_geometry():
    # the plan kept by the model must match a fresh splat after every change of fluxes,
    # coordinates, altitudes, observers or dtype
    model = cached_model(n_elevation=8, n_source_altitude=6,
                         source_altitude_range_m=(0.0, 1400.0), n_components=128)
    variants = [(_random_cells(30, 15e3, seed=1, altitude=300.0), (0.0, 0.0)),
                (_random_cells(30, 15e3, seed=2, altitude=300.0), (0.0, 0.0)),  # new fluxes
                (_random_cells(30, 15e3, seed=2, altitude=900.0), (0.0, 0.0)),  # altitudes
                (_random_cells(30, 14e3, seed=2, altitude=900.0), (0.0, 0.0)),  # coordinates
                (_random_cells(30, 14e3, seed=2, altitude=900.0), (2e3, 1e3))]  # observer
    for cells, observer in variants:
        reused = model.radiance_per_lumen(cells, observer)
        fresh = model.radiance_per_lumen(cells, observer, reuse_splat=False)
        torch.testing.assert_close(reused, fresh, rtol=1e-12, atol=0.0)
    cells32 = {k: v.float() for k, v in cells.items()}
    assert model.radiance_per_lumen(cells32, observer).dtype == torch.float32


def test_reused_splat_plan_gradient_and_altitude_warning():
    model = cached_model(n_elevation=8, n_source_altitude=6,
                         source_altitude_range_m=(0.0, 1400.0), n_components=128)
    cells = _random_cells(6, 8e3, seed=4, altitude=200.0)
    flux = cells["flux"].clone().requires_grad_(True)

    def zenith_sum(f):
        return model.radiance_per_lumen(dict(cells, flux=f), (0.0, 0.0))[0, -1].sum()

    model.radiance_per_lumen(cells, (0.0, 0.0))  # builds the plan
    assert torch.autograd.gradcheck(zenith_sum, (flux,), eps=1.0, atol=1e-12, rtol=1e-6)
    high = dict(cells, altitude=cells["altitude"].clone())
    high["altitude"][0, 0] = 3000.0
    high["flux"] = cells["flux"].clone()
    high["flux"][0, 0] = 1e4
    for _ in range(2):  # building the plan, then with the kept plan
        with pytest.warns(UserWarning, match="source altitude"):
            model.radiance_per_lumen(high, (0.0, 0.0))


def test_sampling_refuses_a_decreasing_coordinate():
    """A north-up raster (y decreasing) gave negative luminance with 'sample': refused.

    'splat' takes it; the map sorted gives the same splat sky as the unsorted one.
    """
    model = cached_model()
    city = synthetic_city(20e3, 1000.0, population=1e5, centre_xy=(6000.0, 0.0))
    north_up = city.isel(y=slice(None, None, -1))
    with pytest.raises(ValueError, match="evenly spaced increasing 'y'"):
        model.render(north_up, observer_xy=(8e3, 1e3), resampling="sample", as_dataset=False)
    repeated = city.assign_coords(x=np.zeros(city.sizes["x"]))
    with pytest.raises(ValueError, match="evenly spaced increasing 'x'"):
        model.render(repeated, observer_xy=(8e3, 1e3), resampling="sample", as_dataset=False)
    splat = model.render(north_up, observer_xy=(8e3, 1e3), as_dataset=False)["luminance"]
    sorted_ = model.render(north_up.sortby("y"), observer_xy=(8e3, 1e3),
                          as_dataset=False)["luminance"]
    assert bool((splat > 0).all())
    torch.testing.assert_close(sorted_, splat, rtol=1e-12, atol=0.0)
