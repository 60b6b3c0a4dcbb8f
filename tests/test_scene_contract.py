"""Input contract of Scene construction and rendering (hypothesis property tests).

A Scene either builds from its arguments or refuses them with a ValueError/TypeError
naming the parameter (tests/_contract.py); once built, its render either returns a finite
Dataset or refuses by name — never another exception type. Every range the Scene accepts
is one the render accepts (one definition: the ephemeris' observer ranges, the
atmosphere's turbidity, ozone and observer height, the spectrum's 360–830 nm).
"""

from __future__ import annotations

import importlib
import math

import numpy as np
import pytest
import torch
from _contract import bad_values, check_contract, expect_rejected
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as hs

import skytorch as st

FAST = settings(max_examples=60, derandomize=True, deadline=None,
                suppress_health_check=[HealthCheck.too_slow,
                                       HealthCheck.function_scoped_fixture])
#: renders are slower: few examples, cheapest fidelity, tiny images
RENDERS = settings(max_examples=8, derandomize=True, deadline=None,
                   suppress_health_check=[HealthCheck.too_slow,
                                       HealthCheck.function_scoped_fixture])

#: valid (value) and invalid values of each numeric parameter: valid ones include the range
#: ends, integers and integer / one-element tensors
NUMERIC = {
    "lat_deg": ((-90.0, 90.0, 0, 52.52, torch.tensor(45)), (-90.5, 91.0)),
    "lon_deg": ((-180.0, 359.9, 0, torch.tensor(13.4)), (360.0, -180.5, 720.0)),
    "elevation_m": ((0.0, 0, 2500, 20_000.0), (-100.0, -0.5, 100_001.0)),
    "turbidity": ((1.0, 1, 2.0, 10.0, torch.tensor(3)), (0.5, 0.0, -2.0)),
    "ozone_du": ((0.0, 300, 600.0), (-1.0,)),
    "tolerance": ((0.0, 1.0, 0.01, 0), (-0.1, 1.5)),
    "star_limit_mag": ((-30.0, 3.0, 6, 15.0), (15.5, -31.0)),
    "natural_mag_arcsec2": ((14.0, 22.0, 26.0, 21), (13.0, 30.0, -5.0)),
    "airglow_fraction": ((0.0, 0.6, 1.0, 1), (-0.1, 1.1)),
    "airglow_height_m": ((30_000.0, 90_000, 1_000_000.0), (9_000.0, 2e6, -1.0)),
}
#: valid and invalid values of the other parameters
OTHER = {
    "time": (("2015-09-28T02:47", np.datetime64("2024-04-08T18:00"), "2053-10-08T23:00"),
             ("1850-01-01", "never", 3.0, None, ["2015-01-01", "2016-01-01"])),
    "size": ((2, 8, 16.0), (1, 0, -4, 2.5, "8", None, 10**6)),
    "fidelity": (("fast", "default"), ("quick", None, 3)),
    "natural_model": (("garstang1989", "constant"), ("garstang", None)),
    "wavelengths": (("rgb", "bands15", (450.0, 550.0, 650.0), [550], torch.tensor([500, 600])),
                    ("rainbow", (300.0, 550.0), (550.0, 450.0), (), [[500.0]], None,
                     (550.0, math.nan))),
    "outputs": ((("v_mag",), "xyz,srgb", ()), (("v_mag", "png"), 3)),
    "force": ((("stars",), "sun,moon", ()), (("starz",), 5)),
    "exclude": ((("skyglow",), "refraction"), (("nothing",), 2.0)),
    "lamp": (("white", "hps"), ("neon", None)),
    "observer_xy": (((0.0, 0.0), (1e3, -2e3), torch.tensor([1, 2])),
                    ((math.nan, 0.0), (1.0, 2.0, 3.0), "here", None)),
    "dtype": ((torch.float32, torch.float64), (torch.int64, "float32", np.float64)),
    "light_map": ((None,), ("city", 3.0, {"flux": 1.0})),
}
#: one-element tensors that ask for gradients, and batches: refused (scenes are not batched
#: and not differentiable)
REFUSED_TENSORS = {"turbidity": torch.tensor([2.0, 3.0]),
                   "ozone_du": torch.tensor(300.0, requires_grad=True),
                   "natural_mag_arcsec2": np.array([21.0, 22.0])}
VIEWS = (
    ({"view": "fisheye"}, True),
    ({"view": "panorama"}, True),
    ({"view": "directions", "directions": {"altitude_deg": [90, 10.0], "azimuth_deg": [0, 5]}},
     True),
    ({"view": "camera", "camera": {"fov_deg": 2.0, "target": "moon"}}, True),
    ({"view": "camera", "camera": {"fov_deg": 30, "altitude_deg": 45, "azimuth_deg": 180}},
     True),
    ({"view": "directions"}, False),
    ({"view": "directions", "directions": {"alt": [10.0]}}, False),
    ({"view": "directions", "directions": {"azimuth_deg": [10.0]}}, False),
    ({"view": "directions", "directions": [[10.0], [0.0]]}, False),
    ({"view": "directions", "directions": {"altitude_deg": [95.0], "azimuth_deg": [0.0]}},
     False),
    ({"view": "directions", "directions": {"altitude_deg": [10.0, 20.0], "azimuth_deg": [0.0]}},
     False),
    ({"view": "camera", "camera": {"fov_deg": 200.0, "target": "moon"}}, False),
    ({"view": "camera", "camera": {"fov_deg": 2.0, "target": "mars"}}, False),
    ({"view": "camera", "camera": {"fov_deg": 2.0, "azimuth_deg": 10.0}}, False),
    ({"view": "camera", "camera": {"fov_deg": 2.0, "target": "moon", "zoom": 2}}, False),
    ({"view": "camera"}, False),
    ({"view": "sphere"}, False),
)


def _parameter(name):
    """(value, is_valid) of one parameter: valid three times in four."""
    if name in NUMERIC:
        valid, bad = NUMERIC[name]
        bad = (*bad, *bad_values())
    else:
        valid, bad = OTHER[name]
    return hs.integers(0, 3).flatmap(
        lambda k: hs.tuples(hs.sampled_from(valid), hs.just(True)) if k
        else hs.tuples(hs.sampled_from(bad), hs.just(False)))


NAMES = (*NUMERIC, *OTHER)


@hs.composite
def scene_arguments(draw):
    """Keyword arguments for Scene and whether every one of them is valid."""
    chosen = draw(hs.lists(hs.sampled_from(NAMES), min_size=1, max_size=4, unique=True))
    kwargs, valid, named = {}, True, []
    for name in chosen:
        value, ok = draw(_parameter(name))
        kwargs[name] = value
        valid &= ok
        named.append(name)
    good_views = [v for v in VIEWS if v[1]]
    bad_views = [v for v in VIEWS if not v[1]]
    view, ok = draw(hs.sampled_from(good_views if draw(hs.integers(0, 3)) else bad_views))
    kwargs.update(view)
    valid &= ok
    named += ["view", "directions", "camera"]
    if draw(hs.integers(0, 9)) == 0:
        kwargs["turbidty"] = 2.0  # a misspelled keyword
        valid = False
        named.append("turbidty")
    if draw(hs.integers(0, 9)) == 0:
        name = draw(hs.sampled_from(sorted(REFUSED_TENSORS)))
        kwargs[name] = REFUSED_TENSORS[name]
        valid = False
        named.append(name)
    if {"force", "exclude"} <= set(kwargs) and valid:
        both = set(st.Scene(force=kwargs["force"]).force) & set(
            st.Scene(exclude=kwargs["exclude"]).exclude)
        if both:
            valid = False
    return kwargs, valid, tuple(named)


@FAST
@given(arguments=scene_arguments())
def test_scene_construction_contract(arguments):
    kwargs, valid, names = arguments
    call = lambda: st.Scene(**kwargs)  # noqa: E731
    if valid:
        scene = check_contract(call, names)
        assert isinstance(scene, st.Scene), scene
        # idempotent: a copy (dataclasses.replace) passes the same checks
        assert scene.replace().parameters() == scene.parameters()
    else:
        expect_rejected(call, names)


@pytest.mark.parametrize(("kwargs", "names"), [
    ({"elevation_m": -100.0}, ("elevation_m",)),  # the render's atmosphere refuses it
    ({"turbidity": 0.5}, ("turbidity",)),  # Atmosphere.earth refuses it
    ({"turbidity": math.inf}, ("turbidity",)),
    ({"natural_mag_arcsec2": math.nan}, ("natural_mag_arcsec2",)),
    ({"natural_mag_arcsec2": "dark"}, ("natural_mag_arcsec2",)),
    ({"turbidity": torch.tensor([2.0, 3.0])}, ("turbidity",)),
    ({"elevation_m": 95_000.0}, ("elevation_m", "airglow_height_m")),  # above the airglow
    ({"lat_deg": [10.0, 20.0], "lon_deg": [0.0, 1.0, 2.0]}, ("lat_deg",)),
    ({"lat_deg": [], "lon_deg": []}, ("lat_deg",)),
    ({"lat_deg": [10.0, 20.0], "observer_xy": [(0.0, 0.0)] * 3}, ("observer_xy",)),
    ({"force": ("moon",), "exclude": ("moon",)}, ("force", "exclude")),
])
def test_refused_at_construction(kwargs, names):
    error = expect_rejected(lambda: st.Scene(**kwargs), names)
    text = str(error)
    for name in names[:1]:
        assert name in text


def test_unknown_keyword_is_named():
    with pytest.raises(TypeError, match="turbidty"):
        st.Scene(turbidty=2.0)
    with pytest.raises(TypeError, match="sise"):
        st.Scene().replace(sise=8)


def test_scene_parameters_are_refused_when_they_ask_for_gradients():
    turbidity = torch.tensor(2.0, requires_grad=True)
    with pytest.raises(TypeError, match="turbidity.*not differentiable"):
        st.Scene(turbidity=turbidity)


def test_toml_tables_missing_a_direction_key_are_refused():
    """Used to raise KeyError: 'altitude_deg'."""
    config = {"view": {"kind": "directions", "azimuth_deg": [0.0]}}
    expect_rejected(lambda: st.Scene.from_dict(config), ("directions",))
    expect_rejected(lambda: st.Scene.from_dict({"view": {"kind": "fisheye", "sise": 8}}),
                    ("sise",))
    expect_rejected(lambda: st.Scene.from_dict({"observer": 52.0}), ("observer",))
    # a key of another table is refused (it was taken: [observer] turbidity = 3)
    with pytest.raises(ValueError, match=r"unknown keys \['turbidity'\] in \[observer\]"):
        st.Scene.from_dict({"observer": {"lat_deg": 52.5, "turbidity": 3.0}})
    with pytest.raises(ValueError, match=r"unknown keys \['lat_deg'\] in \[planner\]"):
        st.Scene.from_dict({"planner": {"lat_deg": 52.5}})
    expect_rejected(lambda: st.Scene.from_dict([("time", "2015-01-01")]), ("config",))


def test_render_refuses_what_is_not_a_scene_or_a_plan():
    expect_rejected(lambda: st.scene.render("scene"), ("scene",))
    scene = st.Scene(view="directions", fidelity="fast",
                     directions={"altitude_deg": [90.0], "azimuth_deg": [0.0]})
    expect_rejected(lambda: scene.render(plan="all"), ("plan",))
    expect_rejected(lambda: st.scene.render_times(None, ["2015-01-01"]), ("scene",))
    # a plan of another scene (here noon instead of night) would draw that scene's sky
    noon = scene.replace(time="2015-06-21T12:00")
    with pytest.raises(ValueError, match="plan was made for another scene"):
        scene.render(plan=noon.plan())
    assert scene.render(plan=scene.plan()).attrs["effects_computed"] == \
        scene.render().attrs["effects_computed"]


#: render arguments: cheap (fast fidelity, tiny images, few stars) but covering the hard
#: corners: the poles, the dateline, the range ends of height and the atmosphere, a
#: single wavelength, every view and natural model, day, twilight, night and eclipse
RENDER_CHOICES = {
    "time": ("2015-09-28T02:47", "2015-06-21T12:00", "2015-06-21T19:50",
             "2053-10-08T23:00", "1899-07-29T01:00"),
    "lat_deg": (52.52, -90.0, 90.0, 0),
    "lon_deg": (13.40, -180.0, 359.99),
    "elevation_m": (0.0, 3000, 20_000.0, 80_000.0),
    "turbidity": (1.0, 2.0, 10.0),
    "ozone_du": (0.0, 300.0),
    "wavelengths": ("rgb", (550.0,), (360.0, 830.0)),
    "natural_model": ("garstang1989", "vanrhijn1921", "constant"),
    "outputs": (("spectral", "xyz", "srgb", "v_mag"), ("v_mag",), ("srgb",)),
    "dtype": (torch.float64, torch.float32),
}
RENDER_VIEWS = (
    {"view": "fisheye", "size": 4},
    {"view": "panorama", "size": 3},
    {"view": "directions", "directions": {"altitude_deg": [90.0, 0.0, 45.0],
                                          "azimuth_deg": [0.0, 359.0, -30.0]}},
    {"view": "camera", "size": 4, "camera": {"fov_deg": 2.0, "target": "moon"}},
    {"view": "camera", "size": 4, "camera": {"fov_deg": 60.0, "altitude_deg": -10.0,
                                             "azimuth_deg": 90.0}},
)


@hs.composite
def render_arguments(draw):
    kwargs = {name: draw(hs.sampled_from(values)) for name, values in RENDER_CHOICES.items()}
    kwargs.update(draw(hs.sampled_from(RENDER_VIEWS)))
    kwargs.update(fidelity="fast", star_limit_mag=2.0)
    return kwargs


@pytest.fixture(autouse=True)
def _private_cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("SKYTORCH_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "cache"))


@RENDERS
@given(kwargs=render_arguments())
def test_render_contract(kwargs):
    scene = st.Scene(**kwargs)  # every drawn value is valid: construction must succeed
    ds = check_contract(scene.render, tuple(kwargs), finite=False)
    assert not isinstance(ds, Exception), f"a valid scene failed to render: {ds!r}"
    sky = np.asarray(ds["solid_angle"].values > 0) | (kwargs["view"] == "directions")
    for name, variable in ds.data_vars.items():
        values = np.asarray(variable.values)
        if values.dtype.kind != "f":
            continue
        if "mag" in name:
            # magnitudes are NaN off the sky (and, per component, where it adds no light)
            if name == "v_mag_arcsec2":
                assert np.isfinite(values[sky]).all(), name
        else:
            assert np.isfinite(values).all(), name
    if "component_radiance" in ds:
        assert (ds["component_radiance"].values >= 0.0).all()


def test_natural_gradient_carries_gradients_and_refuses_observers_above_the_layer():
    """The one tensor function of the scene's composition that the Notes call differentiable.

    Its zenith derivative against finite differences.
    """
    natural_gradient = importlib.import_module("skytorch.scene.render").natural_gradient
    zenith = torch.tensor([0.0, 0.7, 1.5, math.pi / 2], dtype=torch.float64,
                          requires_grad=True)
    assert torch.autograd.gradcheck(natural_gradient, (zenith,), eps=1e-6, atol=1e-7)
    expect_rejected(lambda: natural_gradient(zenith, observer_height_m=95_000.0),
                    ("observer_height_m",))
    expect_rejected(lambda: natural_gradient("up"), ("zenith_rad",))


def test_scene_refuses_a_light_map_with_nan_or_negative_flux_before_planning():
    """plan() took such a map (only render refused it); the Scene refuses it on creation."""
    from skytorch.skyglow.citymap import synthetic_city

    city = synthetic_city(20e3, 2e3, population=1e5)
    for value, message in ((float("nan"), "must be finite"), (-1.0, "non-negative")):
        bad = city.copy()
        bad["flux"] = city["flux"].copy()
        bad["flux"][0, 0] = value
        with pytest.raises(ValueError, match=message):
            st.Scene(time="2015-09-13T23:00", lat_deg=52.5, lon_deg=13.4, light_map=bad,
                     size=8, fidelity="fast")
