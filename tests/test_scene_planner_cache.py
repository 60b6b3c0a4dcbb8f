"""The planner's per-(time, site) cache changes no decision and no result."""

import dataclasses

import torch

import skytorch as st
from skytorch.scene import planner


def _eclipse_night():
    return st.Scene(time="2015-09-28T02:47", lat_deg=52.52, lon_deg=13.40, size=32,
                    outputs=("xyz",))


def test_cold_and_warm_plans_are_identical():
    scene = _eclipse_night()
    planner.clear_cache()
    cold = scene.plan()
    warm = scene.plan()
    assert cold.computed == warm.computed
    assert cold.skipped == warm.skipped
    assert cold.shares == warm.shares
    assert dataclasses.asdict(cold.geometry) == dataclasses.asdict(warm.geometry)
    assert "eclipse" in cold.computed
    assert torch.equal(cold.eclipse_factor, warm.eclipse_factor)


def test_cached_values_are_copies():
    scene = _eclipse_night()
    first = scene.plan()
    first.geometry.moon_altitude_deg = -90.0
    first.eclipse_factor.fill_(0.0)
    second = scene.plan()
    assert second.geometry.moon_altitude_deg > 0.0
    assert bool((second.eclipse_factor > 0.0).all())


def test_cache_keys_on_site_and_time():
    scene = _eclipse_night()
    here = scene.plan().geometry
    elsewhere = scene.replace(lon_deg=-100.0).plan().geometry
    later = scene.replace(time="2015-09-28T14:47").plan().geometry
    assert abs(here.sun_azimuth_deg - elsewhere.sun_azimuth_deg) > 1.0
    assert abs(here.moon_altitude_deg - later.moon_altitude_deg) > 1.0
