"""Input contract of the skyglow entry points, as hypothesis property tests.

Every call either returns an all-finite result within its physical bounds, or raises
``ValueError``/``TypeError`` naming one of its parameters (:mod:`_contract`). The model is
the small stand-in of :mod:`_skyglow_standin` (an exponential atmosphere, a 32 × 16
panorama), so the renders are fast. Arguments are drawn from valid values (integer
tensors, several observers, the ends of the ranges), hard ones (an observer on a lit
cell, at the map's edge, at the top of the tabulated altitudes) and bad ones (wrong
types, None, strings, NaN/inf, observer positions of the wrong shape, altitudes above the
atmosphere, masks of the wrong shape, misspelled keywords). A call with a bad input must be
refused; a call with only valid inputs must be accepted.
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
import torch
from _contract import arg, bad_values, call_and_check, expect_rejected
from _skyglow_standin import cached_model, medium, single_torch_thread  # noqa: F401
from hypothesis import given, settings
from hypothesis import strategies as st

from skytorch.skyglow import SkyglowModel
from skytorch.skyglow.citymap import point_sources, synthetic_city
from skytorch.skyglow.inverse import (
    apply_reduction,
    minimal_reduction,
    pollution_influence,
    reduction_factors,
    sky_region,
    skyglow_influence,
)
from skytorch.skyglow.kernel import Medium, kernel_radiance
from skytorch.skyglow.naive import render_naive
from skytorch.skyglow.units import (
    bortle_class,
    luminance_to_mag_arcsec2,
    naked_eye_limiting_magnitude,
    visible_star_count,
)

SETTINGS = settings(max_examples=60, derandomize=True, deadline=None)
BAD = bad_values()


@pytest.fixture(scope="module")
def model():
    return cached_model()


CITY = point_sources(4, 10e3, 1e3, seed=3)
XY_VALID = [(0.0, 0.0), (4.5e3, -4.5e3), torch.tensor([0, 0]), [(0.0, 0.0), (1e3, 2e3)],
            np.array([[-2e4, 0.0]]), (500.0, 500.0), torch.tensor([[1e3, 0.0]] * 3)]
XY_BAD = [*BAD, (math.nan, 0.0), (0.0, math.inf), (0.0, 0.0, 0.0), (1.0, 2.0, 3.0, 4.0),
          np.zeros((2, 2, 2)), np.zeros((0, 2)), (2e7, 0.0)]
ALTITUDE_VALID = [0.0, 500.0, 5, torch.tensor([0.0]), 1e5]
ALTITUDE_BAD = [*BAD, -1.0, 1e5 + 1.0, torch.tensor([0.0, 1.0, 2.0, 3.0, 4.0])]
LAMP_VALID = ["white", "hps", ([400.0, 700.0], [1.0, 1.0])]
LAMP_BAD = ["sodium", 3, None, ([400.0], [1.0, 2.0]), ([400.0, 700.0], [-1.0, 1.0])]


def _observer_count(xy) -> int:
    return int(np.prod(np.shape(np.asarray(xy, dtype=float))[:-1]))


def _altitude_fits(altitude, n_observers: int) -> bool:
    return int(np.size(np.asarray(torch.as_tensor(altitude)))) in (1, n_observers)


@SETTINGS
@given(xy=arg(XY_VALID, XY_BAD), altitude=arg(ALTITUDE_VALID, ALTITUDE_BAD),
       lamp=arg(LAMP_VALID, LAMP_BAD),
       natural=arg([None, 22.0, 18], [*(v for v in BAD if v is not None), 5.0]),
       resampling=arg(["splat"], ["bilinear", 1]),
       light_map=arg([CITY, synthetic_city(8e3, 1e3, population=5e3)],
                     [None, "city", 3.0, CITY.drop_vars("flux")]),
       as_dataset=arg([True, False], ["no", 0]),
       misspelled=st.sampled_from([None, None, None, "observer_alt_m"]))
def test_render_contract(model, xy, altitude, lamp, natural, resampling, light_map,
                         as_dataset, misspelled):
    bad = not xy[1] and not altitude[1] and not _altitude_fits(altitude[0],
                                                               _observer_count(xy[0]))
    arguments = {"light_map": light_map, "observer_xy": xy, "observer_altitude_m": altitude,
                 "lamp": lamp, "natural_mag_arcsec2": natural, "resampling": resampling,
                 "as_dataset": as_dataset}
    with np.errstate(all="ignore"):
        result = call_and_check(model.render, arguments, bad=bad, misspelled=misspelled)
    if not isinstance(result, Exception):
        luminance = (result["luminance"].values if as_dataset[0]
                     else result["luminance"].detach().numpy())
        assert (luminance >= 0).all() and np.isfinite(luminance).all()


@settings(max_examples=30, derandomize=True, deadline=None)
@given(xy=arg(XY_VALID), altitude=arg([0.0, 500.0, 5, 1e5]), lamp=arg(LAMP_VALID),
       natural=arg([None, 22.0, 18]),
       light_map=arg([CITY, synthetic_city(8e3, 1e3, population=5e3, terrain_amplitude_m=300.0)]))
def test_render_accepts_valid_inputs(model, xy, altitude, lamp, natural, light_map):
    """Only valid (and hard) inputs: every render is finite, non-negative and accepted."""
    arguments = {"light_map": light_map, "observer_xy": xy, "observer_altitude_m": altitude,
                 "lamp": lamp, "natural_mag_arcsec2": natural}
    with np.errstate(all="ignore"), warnings.catch_warnings():
        # altitudes beyond the stand-in's tabulated 0 m are clamped, with this warning
        warnings.filterwarnings("ignore", "(?s).*tabulated range", UserWarning)
        result = call_and_check(model.render, arguments)
    assert (result["luminance"].values >= 0).all()
    n = _observer_count(xy[0])
    assert result["luminance"].shape == ((16, 32) if np.ndim(xy[0]) == 1 else (n, 16, 32))


def test_dataset_records_the_altitude_the_tables_rendered(model):
    """An observer above a one-node model renders at the node: the Dataset says so."""
    assert model.observer_altitude_m.numel() == 1
    node = float(model.observer_altitude_m[0])
    with pytest.warns(UserWarning, match="tabulated range"):
        ds = model.render(CITY, observer_xy=[(0.0, 0.0), (1e3, 0.0)],
                          observer_altitude_m=[node + 3000.0, node])
    parameters = json.loads(ds.attrs["parameters"])
    assert parameters["observer_altitude_m"] == [node + 3000.0, node]
    assert parameters["observer_altitude_rendered_m"] == [node, node]


@SETTINGS
@given(flux=arg([torch.ones(3, 4), torch.ones(3, 4, dtype=torch.long) * 1000,
                 torch.tensor(np.eye(3, 4) * 1e5)],
                [torch.ones(4, 3), torch.full((3, 4), math.nan), -torch.ones(3, 4),
                 torch.ones(3, 4, 1), "flux"]),
       x=arg([torch.arange(4) * 1000, torch.linspace(-3e3, 3e3, 4)],
             [torch.arange(5.0), None, torch.tensor([0.0, 1.0, math.nan, 2.0])]),
       y=arg([torch.arange(3) * 1000], [torch.arange(2.0), "y"]),
       altitude=arg([None, torch.zeros(3, 4), torch.full((3, 4), 100.0)],
                    [torch.zeros(4, 3), torch.full((3, 4), math.inf)]))
def test_render_tensor_map_contract(model, flux, x, y, altitude):
    arguments = {"light_map": flux, "x_m": x, "y_m": y, "altitude_m": altitude}
    with np.errstate(all="ignore"):
        call_and_check(lambda **kw: model.render(as_dataset=False, **kw)["luminance"],
                       arguments, bounds=(0.0, math.inf))


@settings(max_examples=25, derandomize=True, deadline=None)
@given(xy=arg(XY_VALID[:4], XY_BAD), altitude=arg(ALTITUDE_VALID[:3], ALTITUDE_BAD),
       sources=arg(["cells", "polar"], ["grid", None]),
       model_value=arg(["model"], [None, "model", 3]),
       medium_value=arg([None], ["medium", 3.0]))
def test_render_naive_contract(model, xy, altitude, sources, model_value, medium_value):
    bad = not xy[1] and not altitude[1] and not _altitude_fits(altitude[0],
                                                               _observer_count(xy[0]))
    if model_value == ("model", False):
        model_value = (model, False)
    city = point_sources(2, 6e3, 1e3, seed=1)
    arguments = {"model": model_value, "light_map": (city, False), "observer_xy": xy,
                 "observer_altitude_m": altitude, "sources": sources,
                 "medium": medium_value}
    call_and_check(lambda **kw: render_naive(as_dataset=False, **kw)["luminance"], arguments,
                   bad=bad, bounds=(0.0, math.inf))


def _region(model, kind):
    n_p, n_t = model.elevation_rad.numel(), model.azimuth_rad.numel()
    return {"east": sky_region(model, (0.0, 30.0), (45.0, 135.0)),
            "all": torch.ones(n_p, n_t, dtype=torch.bool),
            "wrong shape": torch.ones(3, 3, dtype=torch.bool),
            "empty": torch.zeros(n_p, n_t, dtype=torch.bool),
            "float": torch.ones(n_p, n_t), "none": None, "string": "east"}[kind]


@SETTINGS
@given(xy=arg([(0.0, 0.0), (2e3, -1e3), torch.tensor([0, 0])],
              [*XY_BAD, [(0.0, 0.0), (1.0, 1.0)]]),
       altitude=arg([0.0, 300.0], ALTITUDE_BAD),
       region=arg(["east", "all"], ["wrong shape", "empty", "float", "none", "string"]),
       model_value=arg(["model"], [None, "model"]),
       misspelled=st.sampled_from([None, None, None, "x_n"]))
def test_inverse_tools_contract(model, xy, altitude, region, model_value, misspelled):
    """pollution_influence, skyglow_influence and minimal_reduction on the same inputs."""
    if model_value == ("model", False):
        model_value = (model, False)
    region_value = (_region(model, region[0]), region[1])
    common = {"model": model_value, "light_map": (CITY, False), "observer_xy": xy,
              "observer_altitude_m": altitude}
    with np.errstate(all="ignore"):
        q = call_and_check(pollution_influence, common, misspelled=misspelled)
        if not isinstance(q, Exception):
            assert (q["pollution_level"].values >= 0).all()
        s = call_and_check(skyglow_influence, {**common, "region": region_value},
                           misspelled=misspelled)
        if not isinstance(s, Exception):
            assert (s["skyglow_influence"].values >= -1e-12).all()
        plan = call_and_check(
            lambda **kw: minimal_reduction(target_fraction=0.5, **kw),
            {**common, "region": region_value}, misspelled=misspelled)
        if not isinstance(plan, Exception):
            gamma = plan["reduction"].values
            assert ((gamma >= 0) & (gamma <= 1)).all()


@SETTINGS
@given(influence=arg([torch.tensor([0.0, 1.0, 5.0]), torch.tensor([1, 2])],
                     [*BAD, torch.tensor([1.0, math.nan])]),
       q_a=arg([0.0, 1], [*BAD]), q_b=arg([2.0, 10], [*BAD]),
       gamma=arg([1.0, 0.0, 0.5], [*BAD, 1.5, -0.1]))
def test_reduction_factors_contract(influence, q_a, q_b, gamma):
    arguments = {"influence": influence, "q_a": q_a, "q_b": q_b, "gamma_user": gamma}
    call_and_check(reduction_factors, arguments, bounds=(0.0, 1.0))


@SETTINGS
@given(gamma=arg([0.5, np.zeros((10, 10)), torch.ones(10, 10), 0],
                 [*BAD, 1.5, np.zeros(5), np.full((10, 10), -0.5)]),
       light_map=arg([CITY], [None, "city", torch.ones(10, 10)]))
def test_apply_reduction_contract(gamma, light_map):
    result = call_and_check(apply_reduction, {"light_map": light_map, "gamma": gamma})
    if not isinstance(result, Exception):
        assert (result["flux"].values <= CITY["flux"].values + 1e-9).all()


@SETTINGS
@given(elevation=arg([(0.0, 90.0), (10, 20), [0.0, 5.0]],
                     [*BAD, (math.nan, 10.0), (50.0, 10.0), (0.0, 100.0), (0.0,)]),
       azimuth=arg([(0.0, 360.0), (330.0, 30.0), (-90, 90)], [*BAD, (0.0, math.inf)]))
def test_sky_region_contract(model, elevation, azimuth):
    result = call_and_check(lambda **kw: sky_region(model, **kw),
                            {"elevation_deg": elevation, "azimuth_deg": azimuth})
    if not isinstance(result, Exception):
        assert result.dtype == torch.bool and bool(result.any())


@SETTINGS
@given(azimuth=arg([0.0, torch.tensor([0, 1, 2]), math.pi], [*BAD]),
       elevation=arg([0.0, math.pi / 2, torch.tensor([[0.1], [1.0]])],
                     [*BAD, -0.1, 2.0]),
       distance=arg([0.0, 1e3, torch.tensor([10, 20000])], [*BAD, -1.0]),
       observer=arg([0.0, 2.0, 1e5], [*BAD, -1.0, 2e5]),
       medium_value=arg(["medium"], ["medium", None, 3]))
def test_kernel_radiance_contract(azimuth, elevation, distance, observer, medium_value):
    if medium_value == ("medium", False):
        medium_value = (_MEDIUM, False)
    shapes = [np.shape(np.asarray(v)) for v, _ in (azimuth, elevation, distance)]
    try:
        np.broadcast_shapes(*shapes)
        bad = False
    except ValueError:
        bad = True
    arguments = {"medium": medium_value, "azimuth_rad": azimuth, "elevation_rad": elevation,
                 "distance_m": distance, "observer_altitude_m": observer}
    call_and_check(kernel_radiance, arguments, bad=bad, bounds=(0.0, math.inf))


_MEDIUM = medium((550.0,), n_altitude=401, n_table_radius=16, n_table_mu=32,
                 n_table_steps=16)


@pytest.mark.parametrize("atmosphere", ["earth", None, 3.0, object(), SkyglowModel])
def test_medium_refuses_non_atmospheres(atmosphere):
    expect_rejected(lambda: Medium(atmosphere, [550.0]), ("atmosphere",))


@SETTINGS
@given(extent=arg([1e4, 2000], [*BAD, 0.0, -1e3]),
       cell=arg([1e3, 500], [*BAD, 0.0, 1e-3]),
       centre=arg([(0.0, 0.0), (1e3, -1e3)], [*BAD, (0.0,), (math.nan, 0.0)]),
       population=arg([1e5, 0], [*BAD, -1.0]),
       terrain=arg([0.0, 200.0], [*BAD, -5.0]),
       seed=arg([0, 7], [-1, 1.5, "1"]))
def test_synthetic_city_contract(extent, cell, centre, population, terrain, seed):
    arguments = {"extent_m": extent, "cell_m": cell, "centre_xy": centre,
                 "population": population, "terrain_amplitude_m": terrain, "seed": seed}
    result = call_and_check(synthetic_city, arguments)
    if not isinstance(result, Exception):
        assert (result["flux"].values >= 0).all()


@SETTINGS
@given(n=arg([0, 3], [-1, 2.5, "3", None, 10**9]),
       flux_range=arg([(1e5, 1e6), (0, 1)], [*BAD, (5.0, 1.0), (-1.0, 1.0), (1.0,)]),
       exclude=arg([0.0, 1e3], [*BAD, -1.0]))
def test_point_sources_contract(n, flux_range, exclude):
    arguments = {"n": n, "flux_range_lm": flux_range, "exclude_radius_m": exclude}
    call_and_check(lambda **kw: point_sources(extent_m=8e3, cell_m=1e3, **kw), arguments)


@SETTINGS
@given(value=arg([22.0, torch.tensor([17, 21]), 14.0], [*BAD]))
def test_units_contract(value):
    call_and_check(bortle_class, {"mag_arcsec2": value}, bounds=(1, 9))
    limit = call_and_check(naked_eye_limiting_magnitude, {"mag_arcsec2": value},
                           bounds=(-10.0, 10.0))
    if not isinstance(limit, Exception):
        call_and_check(visible_star_count, {"limiting_magnitude_mag": (limit, False)},
                       bounds=(0.0, 1e7))
    call_and_check(luminance_to_mag_arcsec2,
                   {"luminance_cd_m2": (torch.as_tensor(value[0]) * 1e-5, False)
                    if not value[1] else value}, bounds=(-100.0, 100.0))


def test_render_refuses_a_mask_for_a_flux_and_bools_for_a_position():
    """A bool flux rendered as 0/1 lm, (True, False) as an observer at (1, 0) m."""
    from skytorch.skyglow.citymap import synthetic_city

    model = cached_model()
    city = synthetic_city(20e3, 2000.0, population=1e5)
    mask = city.copy()
    mask["flux"] = city["flux"] > 100.0
    with pytest.raises(TypeError, match=r"light_map\['flux'\] must hold numbers"):
        model.render(mask, as_dataset=False)
    with pytest.raises(TypeError, match="observer_xy must be a number .* bool"):
        model.render(city, observer_xy=(True, False), as_dataset=False)
