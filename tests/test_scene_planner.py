"""Planner: which effects each scene computes, spies on skipped ones, forcing everything.

Reference situations (geometry from DE421 through skytorch.ephemeris):
day — Paris, 2015-06-21 12:00 UTC (Sun at 64°); twilight — Paris 2015-06-21 20:30
(Sun at −5°, civil twilight); dark night — Berlin 2015-09-13 23:00 (new Moon below the
horizon); moonlit night — Berlin 2015-09-27 23:00 (full Moon, 70 min before P1 of the
eclipse, Five Millennium Canon: P1 00:11:47 UTC); eclipse night — Berlin 2015-09-28
02:47 (greatest eclipse 02:47:08 UTC); city — the dark night with a synthetic city.
"""

import importlib
import math

import pytest
import torch

import skytorch as st
from skytorch.scene.planner import EFFECTS

render_module = importlib.import_module("skytorch.scene.render")

PARIS = {"lat_deg": 48.85, "lon_deg": 2.35}
BERLIN = {"lat_deg": 52.52, "lon_deg": 13.40}
SCENES = {
    "day": {"time": "2015-06-21T12:00", **PARIS},
    "twilight": {"time": "2015-06-21T20:30", **PARIS},
    "dark": {"time": "2015-09-13T23:00", **BERLIN},
    "moonlit": {"time": "2015-09-27T23:00", **BERLIN},
    "eclipse": {"time": "2015-09-28T02:47", **BERLIN},
}
#: twilight (Sun 4.8° down) and moonlight: the starlight is a tiny share of the image
#: flux, but Venus (twilight) and the brightest stars stand out of the darkest sky of
#: their pixels (the point-source test of the planner)
EXPECTED = {
    "day": {"sky", "sun"},
    "twilight": {"sky", "stars", "refraction"},
    "dark": {"stars", "refraction"},
    "moonlit": {"moon", "stars", "refraction"},
    "eclipse": {"moon", "eclipse", "stars", "refraction"},
}
#: the scenes' tolerance: 1 % of the image's V-band flux
TOLERANCE = 0.01


def scene(name, **kwargs):
    options = {"size": 24, "fidelity": "fast", "tolerance": TOLERANCE, "star_limit_mag": 4.5}
    options.update(kwargs)
    return st.Scene(**SCENES[name], **options)


def l1_change(a, b):
    """Relative L1 change of the luminance over the pixels (the planner's metric)."""
    weight = a["solid_angle"].values
    ya, yb = a["luminance"].values, b["luminance"].values
    return float((abs(ya - yb) * weight).sum() / (ya * weight).sum())


@pytest.mark.parametrize("name", list(SCENES))
def test_computed_and_skipped_sets(name):
    plan = scene(name).plan()
    assert set(plan.computed) == EXPECTED[name]
    assert set(plan.computed) | set(plan.skipped) == set(EFFECTS)
    assert all(reason for reason in plan.skipped.values())


def test_reasons_name_the_cause():
    day = scene("day").plan()
    assert "of the image flux" in day.skipped["stars"]
    assert day.skipped["skyglow"] == "no light map"
    assert "within its pixel" in day.skipped["refraction"]
    moonlit = scene("moonlit").plan()
    assert "outside the penumbra" in moonlit.skipped["eclipse"]
    dark = scene("dark").plan()
    assert "below the horizon" in dark.skipped["moon"]


@pytest.mark.parametrize("size", [24, 512])
def test_point_sources_appear_in_civil_twilight(size):
    """Stars are skipped at noon and drawn at the end of civil twilight.

    "At the end of civil twilight [Sun 6° below the horizon] ... the brightest stars and
    planets can be seen" (U.S. Naval Observatory, Rise, Set, and Twilight Definitions).
    Paris, 2015-06-21: at noon (Sun 64.5° up) the brightest point source that can be up
    is well under 1 % of the darkest sky in its pixel, at 20:40 UTC (Sun 6.0° down) above.
    The share of the image flux alone would skip them in both.
    """
    options = {**PARIS, "size": size, "fidelity": "fast", "tolerance": TOLERANCE}
    noon = st.Scene(time="2015-06-21T12:00", **options).plan()
    dusk = st.Scene(time="2015-06-21T20:40", **options)
    assert dusk.resources().geometry(dusk).sun_altitude_deg == pytest.approx(-6.0, abs=0.1)
    dusk = dusk.plan()
    assert "stars" in noon.skipped and "darkest sky in its pixel" in noon.skipped["stars"]
    assert "stars" in dusk.computed
    assert dusk.shares["stars"] < TOLERANCE


def test_city_scene_computes_skyglow():
    from skytorch.skyglow.citymap import synthetic_city

    city = synthetic_city(extent_m=20_000.0, cell_m=2_000.0, population=1e6)
    plan = scene("dark", light_map=city).plan()
    assert "skyglow" in plan.computed
    # the same city cannot matter in daylight (Falchi 2016 brightest sky bound)
    assert "skyglow" in scene("day", light_map=city).plan().skipped
    # a map whose lamps are all off sends no light at any hour
    dark_city = city.assign(flux=city["flux"] * 0.0)
    assert scene("dark", light_map=dark_city).plan().skipped["skyglow"] == (
        "the light map emits no light")


def test_attributes_are_netcdf_strings():
    ds = scene("eclipse", view="directions",
               directions={"altitude_deg": [90.0], "azimuth_deg": [0.0]}).render()
    assert isinstance(ds.attrs["effects_computed"], str)
    assert ds.attrs["effects_computed"].split(",") == ["moon", "eclipse"]
    assert ds.attrs["effects_skipped"].startswith("sky: ")
    assert "stars: a directions view holds no point sources" in ds.attrs["effects_skipped"]


def test_force_and_exclude():
    plan = scene("day", force=["stars"], exclude=["sun"]).plan()
    assert "stars" in plan.computed
    assert plan.skipped["sun"] == "excluded by the user"
    with pytest.raises(ValueError, match="force"):
        scene("day", force=["sun"], exclude=["sun"])
    with pytest.raises(ValueError, match="planets"):
        scene("day", force=["planets"])


def _spy(monkeypatch, names):
    calls = []
    for name in names:
        original = getattr(render_module, name)

        def wrapper(*args, _name=name, _original=original, **kwargs):
            calls.append(_name)
            return _original(*args, **kwargs)

        monkeypatch.setattr(render_module, name, wrapper)
    return calls


def _spy_method(monkeypatch, calls, name):
    """Record the calls of a SceneResources method in ``calls``."""
    from skytorch.scene.resources import SceneResources

    original = getattr(SceneResources, name)

    def wrapper(self, *args, **kwargs):
        calls.append(name)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(SceneResources, name, wrapper)


COMPONENT_FUNCTIONS = {"sky": "sky_component", "sun": "sun_component",
                       "moon": "moon_component", "stars": "stars_component",
                       "skyglow": "skyglow_component"}


@pytest.mark.parametrize("name", ["day", "dark", "eclipse"])
def test_skipped_effects_are_never_called(monkeypatch, name):
    sc = scene(name)

    sc.resources().clear()
    calls = _spy(monkeypatch, [*COMPONENT_FUNCTIONS.values(), "eclipse_factor",
                               "shadow_illuminance"])
    _spy_method(monkeypatch, calls, "refracted_altitude")
    plan = sc.plan()
    # the planner decides the eclipse from geometry and bounds, without the shadow model
    assert "shadow_illuminance" not in calls and "eclipse_factor" not in calls
    calls.clear()
    sc.render(plan)
    for effect, function in COMPONENT_FUNCTIONS.items():
        assert (function in calls) == (effect in plan.computed), (effect, calls)
    # the render evaluates the disc-averaged shadow once, only for an eclipsed Moon
    assert calls.count("eclipse_factor") == (1 if "eclipse" in plan.computed else 0)
    assert ("shadow_illuminance" in calls) == ("eclipse" in plan.computed)
    # refraction of the Sun's or Moon's place: to draw them, or for stars occulted by a
    # Moon above the horizon
    moon_up = plan.geometry.moon_altitude_deg > 0.0
    assert ("refracted_altitude" in calls) == ("refraction" in plan.computed and bool(
        {"sun", "moon"} & set(plan.computed) or ("stars" in plan.computed and moon_up)))


def test_earthshine_flag_follows_the_plan(monkeypatch):
    import skytorch.moon

    flags = []
    original = skytorch.moon.lunar_irradiance

    def spy(*args, **kwargs):
        flags.append(kwargs.get("earthshine"))
        return original(*args, **kwargs)

    monkeypatch.setattr(skytorch.moon, "lunar_irradiance", spy)
    sc = scene("moonlit")
    plan = sc.plan()
    assert "earthshine" in plan.skipped  # full Moon: earthshine ~1e-4 of the Moon's light
    sc.render(plan)
    assert flags == [False]


@pytest.mark.parametrize("name", ["day", "twilight", "dark", "moonlit", "eclipse"])
def test_forcing_everything_changes_the_image_within_tolerance(name):
    planned = scene(name).render()
    forced = scene(name, force=list(EFFECTS)).render()
    assert set(forced.attrs["effects_computed"].split(",")) == (set(EFFECTS)
                                                               - {"skyglow", "scintillation"})
    assert "cannot be forced" in forced.attrs["effects_skipped"]
    assert l1_change(forced, planned) <= TOLERANCE


def test_planner_overhead_is_recorded():
    ds = scene("twilight").render()
    assert math.isfinite(float(ds.attrs["parameter_seconds_plan"]))
    assert float(ds.attrs["parameter_seconds_plan"]) > 0.0


def test_invalid_scene_parameters():
    with pytest.raises(ValueError, match="tolerance"):
        scene("day", tolerance=-0.1)
    with pytest.raises(ValueError, match="view"):
        scene("day", view="cylinder")
    with pytest.raises(ValueError, match="lat_deg"):
        st.Scene(time="2015-06-21T12:00", lat_deg=91.0, lon_deg=0.0)
    with pytest.raises(TypeError, match="dtype"):
        scene("day", dtype=torch.int32)


def test_a_skipped_sun_gives_its_share_as_the_reason():
    """The Sun's skip reason read "above the horizon" (a reason to compute it)."""
    plan = st.Scene(time="2024-06-21T12:00:00", lat_deg=48.85, lon_deg=2.35, tolerance=0.9,
                    size=16, fidelity="fast").plan()
    share = float(plan.skipped["sun"].split()[1])
    assert plan.skipped["sun"].startswith("Sun ") and 0.5 < share < 0.9
