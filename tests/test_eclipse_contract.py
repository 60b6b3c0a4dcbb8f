"""Input contract of the eclipse entry points (hypothesis property tests).

Every call either returns a finite, in-bounds result or raises ValueError/TypeError naming
a parameter (tests/_contract.py). Families: sun_visible_fraction; Shadow (constructor and
relative_illuminance); ShadowTable (constructor, lookup, lookup_uv, from_dataset);
lunar_eclipses and the nearest-eclipse search; lunar_light_curve / lunar_eclipse with small
settings. Inputs are drawn valid, hard (tangency, containment, the axis, integer tensors,
float32) and bad (wrong types, None, strings, NaN/inf, out of range, mismatched shapes,
misspelled keywords).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from _contract import bad_values, check_contract, expect_rejected
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from skytorch.eclipse import (
    Shadow,
    ShadowTable,
    lunar_eclipse,
    lunar_eclipses,
    lunar_light_curve,
    shadow_cone,
    sun_visible_fraction,
)

SETTINGS = settings(max_examples=60, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow,
                                           HealthCheck.function_scoped_fixture])
SUN = 4.65e-3  # [rad]
MOON_DISTANCE = 3.844e8  # [m]

# --- strategies -------------------------------------------------------------------------------

bad = st.sampled_from(bad_values() + [-1.0, "abc", [[1.0], [2.0, 3.0]]])


def _as(value, kind):
    """Return a number as float, int tensor, float32 tensor or float64 tensor of shape (2,)."""
    if kind == "float":
        return value
    if kind == "int":
        return torch.tensor([int(round(value))] * 2)
    dtype = torch.float32 if kind == "float32" else torch.float64
    return torch.tensor([value, value], dtype=dtype)


kinds = st.sampled_from(["float", "float64", "float32", "int"])


def _number(low, high):
    return st.one_of(st.floats(low, high), st.sampled_from([low, high]))


# --- sun_visible_fraction ----------------------------------------------------------------------

def _geometry():
    """(rho_s, rho_o, d) valid and at hard places: tangencies, containment, the axis."""
    ratio = st.one_of(st.floats(1e-3, 1e3), st.sampled_from([0.5, 1.0, 2.0]))
    where = st.sampled_from(["random", "inner", "outer", "hidden", "axis"])
    offset = st.sampled_from([0.0, 1e-19, -1e-19, 1e-12, -1e-12, 1e-6])

    @st.composite
    def draw(draw_one):
        rho_s = draw_one(st.floats(1e-8, 0.2))
        rho_o = min(rho_s * draw_one(ratio), 0.5 * math.pi)
        kind, delta = draw_one(where), draw_one(offset) * rho_s
        d = {"random": draw_one(st.floats(0.0, 1.2)) * (rho_s + rho_o),
             "inner": abs(rho_s - rho_o) + delta, "outer": rho_s + rho_o + delta,
             "hidden": rho_o - rho_s + delta, "axis": 0.0}[kind]
        return rho_s, rho_o, min(max(d, 0.0), math.pi)

    return draw()


@SETTINGS
@given(_geometry(), st.sampled_from([torch.float64, torch.float32]), st.floats(0.0, 1.0),
       st.booleans())
def test_sun_visible_fraction_valid_inputs(geometry, dtype, u, gradient):
    rho_s, rho_o, d = (torch.tensor(x, dtype=dtype) for x in geometry)
    if gradient:
        d.requires_grad_(True)
    result = check_contract(lambda: sun_visible_fraction(rho_s, rho_o, d, u),
                            ("sun_radius_rad", "occluder_radius_rad", "separation_rad"))
    if isinstance(result, Exception):  # only float32 rounding may move an input out of range
        assert dtype == torch.float32
        return
    assert 0.0 <= result.item() <= 1.0
    if gradient:
        (slope,) = torch.autograd.grad(result, d)
        assert torch.isfinite(slope)
        # |d f / d d| is at most the blocked flux per unit separation: the rim length
        # 2 rho_o over the disc's flux, bounded by 2 / (rho_s (1 - u / 3)) / pi * 2
        assert abs(slope.item()) <= 4.0 / (math.pi * float(rho_s) * (1.0 - u / 3.0)) * 1.01


@SETTINGS
@given(st.data())
def test_sun_visible_fraction_bad_and_mixed_inputs(data):  # noqa: C901 (one check per input kind)
    names = ("sun_radius_rad", "occluder_radius_rad", "separation_rad", "limb_darkening",
             "law", "n_nodes")
    # integer tensors are drawn where an integer is valid: 1 rad occluder, zero separation
    args = {"sun_radius_rad": _as(SUN, data.draw(st.sampled_from(["float", "float64",
                                                                  "float32"]))),
            "occluder_radius_rad": (lambda kind: _as(1.0 if kind == "int" else 0.004, kind))(
                data.draw(kinds)),
            "separation_rad": _as(0.003, data.draw(kinds))}
    choice = data.draw(st.sampled_from(["none", "bad", "shape", "keyword", "law", "nodes",
                                        "range"]))
    keywords = {}
    if choice == "bad":
        args[data.draw(st.sampled_from(list(args)))] = data.draw(bad)
    elif choice == "shape":
        args["separation_rad"] = torch.full((3,), 0.003, dtype=torch.float64)
        args["occluder_radius_rad"] = torch.full((2,), 0.004, dtype=torch.float64)
    elif choice == "keyword":
        keywords["n_node"] = 8
    elif choice == "law":
        keywords["law"] = data.draw(st.sampled_from(["Linear", "quadratic", 3, None]))
    elif choice == "nodes":
        keywords["n_nodes"] = data.draw(st.sampled_from([0, 1, 1000, 2.5, "8", None, True]))
    elif choice == "range":
        key, value = data.draw(st.sampled_from([("sun_radius_rad", 0.3),
                                                ("sun_radius_rad", 1e-9),
                                                ("occluder_radius_rad", 0.0),
                                                ("occluder_radius_rad", 2.0),
                                                ("separation_rad", -1e-3),
                                                ("separation_rad", 4.0)]))
        args[key] = value

    def call():
        return sun_visible_fraction(**args, **keywords)

    if choice in ("none",):
        result = check_contract(call, names)
        assert not isinstance(result, Exception)
        assert bool(((result >= 0) & (result <= 1)).all())
    elif choice == "law" and keywords["law"] == "quadratic":
        expect_rejected(call, ("limb_darkening",))  # 0.6 is not a pair
    elif choice == "keyword":
        with pytest.raises(TypeError, match="n_node"):
            call()
    else:
        expect_rejected(call, names)


# --- Shadow ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def airless():
    return Shadow.earth(atmosphere=False)


@SETTINGS
@given(st.data())
def test_shadow_relative_illuminance(airless, data):  # noqa: C901 (one check per input kind)
    names = ("distance_m", "offset_m", "wavelength_nm", "sun_distance_m")
    distance = data.draw(st.one_of(_number(3e7, 1.5e9), st.just(MOON_DISTANCE)))
    offset = data.draw(st.one_of(_number(0.0, 3e7), st.just(0.0)))
    args = {"distance_m": distance, "offset_m": offset, "wavelength_nm": [450.0, 650.0]}
    choice = data.draw(st.sampled_from(["valid", "int", "bad", "shape", "keyword", "inside",
                                        "wavelength", "sun"]))
    keywords = {}
    if choice == "int":
        args["distance_m"] = torch.tensor([int(distance)] * 3)
        args["offset_m"] = torch.tensor([int(offset)])
        args["wavelength_nm"] = torch.tensor([500])
    elif choice == "bad":
        args[data.draw(st.sampled_from(list(args)))] = data.draw(bad)
    elif choice == "shape":
        args["distance_m"] = torch.full((3,), MOON_DISTANCE)
        args["offset_m"] = torch.zeros(2)
    elif choice == "keyword":
        keywords["wavelength"] = 500.0
    elif choice == "inside":
        args["distance_m"], args["offset_m"] = 1e6, 1e6
    elif choice == "wavelength":
        args["wavelength_nm"] = data.draw(st.sampled_from([-500.0, 0.0, 1e7, math.nan, [],
                                                           [[500.0]]]))
    elif choice == "sun":
        keywords["sun_distance_m"] = data.draw(st.sampled_from([0.0, -1.0, math.nan,
                                                                 torch.ones(4) * 1.5e11]))

    def call():
        return airless.relative_illuminance(**args, **keywords)

    if choice in ("valid", "int"):
        result = check_contract(call, names)
        if not isinstance(result, Exception):
            assert bool(((result >= 0) & (result <= 1)).all())
        else:
            assert "inside" in str(result)  # a drawn point may lie inside the Earth
    elif choice == "keyword":
        with pytest.raises(TypeError, match="wavelength"):
            call()
    elif choice == "sun" and isinstance(keywords["sun_distance_m"], torch.Tensor) \
            and not isinstance(args["distance_m"], torch.Tensor):
        check_contract(call, names)  # (4,) broadcasts with scalars
    else:
        expect_rejected(call, names)


@pytest.mark.parametrize(("keywords", "name"), [
    ({"atmosphere": "earth"}, "atmosphere"), ({"atmosphere": 1.0}, "atmosphere"),
    ({"cloud_fraction": 2.0}, "cloud_fraction"), ({"cloud_fraction": math.nan}, "cloud_fraction"),
    ({"sun_distance_m": -1.0}, "sun_distance_m"), ({"n_altitude": 2}, "n_altitude"),
    ({"n_arc": "8"}, "n_arc"), ({"law": "cubic"}, "law"), ({"limb_darkening": 2.0}, "limb"),
    ({"terrain_height_m": -5.0}, "terrain_height_m"), ({"n_alitude": 64}, "n_alitude"),
])
def test_shadow_constructor_rejects(keywords, name):
    options = {"atmosphere": False, **keywords}
    expect_rejected(lambda: Shadow.earth(**options), (name,))


def test_tables_refuse_gradients_wrt_the_atmosphere():
    # the (u, v) table carries the gradient (tests/test_shadow_gradients.py); the bending
    # and the scattered light (tabulated without gradients) refuse it
    from skytorch.atmosphere import Atmosphere

    turbidity = torch.tensor(2.0, dtype=torch.float64, requires_grad=True)
    shadow = Shadow.earth(Atmosphere.earth(turbidity=turbidity), n_altitude=33)
    table = ShadowTable.compute(shadow, [550.0], n_u=4, n_v=4, progress=False)
    assert table.values.requires_grad
    pressure = torch.tensor(101325.0, dtype=torch.float64, requires_grad=True)
    bending = Shadow.earth(Atmosphere.earth(surface_pressure_pa=pressure), n_altitude=33)
    with pytest.raises(ValueError, match="surface_pressure_pa"):
        bending.relative_illuminance(MOON_DISTANCE, 3.0e6, 550.0)
    scattering = Shadow.earth(Atmosphere.earth(turbidity=turbidity), n_altitude=33,
                              scattering=True)
    with pytest.raises(ValueError, match="not differentiable with respect to the atmosphere"):
        scattering.relative_illuminance(MOON_DISTANCE, 3.0e6, 550.0)


def test_shadow_gradient_wrt_geometry_flows(airless):
    # the geometry of the points keeps its gradient (only the atmosphere's is refused)
    offset = torch.tensor(5.0e6, dtype=torch.float64, requires_grad=True)
    value = airless.relative_illuminance(MOON_DISTANCE, offset, 550.0)[0]
    value.backward()
    step = 1.0e3
    with torch.no_grad():
        plus = airless.relative_illuminance(MOON_DISTANCE, 5.0e6 + step, 550.0)[0]
        minus = airless.relative_illuminance(MOON_DISTANCE, 5.0e6 - step, 550.0)[0]
    assert offset.grad.item() == pytest.approx(float(plus - minus) / (2 * step), rel=1e-4)


# --- ShadowTable ---------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def table(airless):
    return ShadowTable.compute(airless, [450.0, 650.0], n_u=8, n_v=12, progress=False)


@SETTINGS
@given(st.data())
def test_shadow_table_lookup(table, data):  # noqa: C901 (one check per input kind)
    names = ("distance_m", "offset_m", "sun_distance_m", "wavelength_nm")
    args = {"distance_m": data.draw(_number(3e7, 1.5e9)),
            "offset_m": data.draw(_number(0.0, 3e7))}
    choice = data.draw(st.sampled_from(["valid", "int", "bad", "nan", "sun", "shape",
                                        "wavelength", "keyword", "right_wavelength"]))
    keywords = {}
    if choice == "int":
        args = {"distance_m": torch.tensor([384400000, 400000000]),
                "offset_m": torch.tensor([0])}
    elif choice == "bad":
        args[data.draw(st.sampled_from(list(args)))] = data.draw(bad)
    elif choice == "nan":
        args["distance_m"] = data.draw(st.sampled_from([math.nan, math.inf, -math.inf]))
    elif choice == "sun":
        keywords["sun_distance_m"] = data.draw(st.sampled_from([0.0, -1.5e11, math.nan, "x"]))
    elif choice == "shape":
        args = {"distance_m": torch.full((3,), MOON_DISTANCE), "offset_m": torch.zeros(2)}
    elif choice == "wavelength":
        keywords["wavelength_nm"] = data.draw(st.sampled_from([[450.0], [450.0, 651.0],
                                                               [math.nan, 650.0]]))
    elif choice == "right_wavelength":
        keywords["wavelength_nm"] = torch.tensor([450, 650])
    elif choice == "keyword":
        keywords["sun_distance"] = 1.5e11

    def call():
        return table.lookup(**args, **keywords)

    if choice in ("valid", "int", "right_wavelength"):
        result = check_contract(call, names)
        if not isinstance(result, Exception):
            assert bool(((result >= 0) & (result <= 1)).all())
            assert result.shape[-1] == 2
        else:
            assert "inside" in str(result)
    elif choice == "keyword":
        with pytest.raises(TypeError, match="sun_distance"):
            call()
    else:
        expect_rejected(call, names)


@SETTINGS
@given(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(bad_values())),
       st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(bad_values())))
def test_shadow_table_lookup_uv(table, u, v):
    result = check_contract(lambda: table.lookup_uv(u, v), ("u", "v"))
    if not isinstance(result, Exception):
        assert 0.0 <= u <= 1.0 and v >= 0.0  # only in-range coordinates are accepted
        assert bool(((result >= 0) & (result <= 1)).all())


def test_shadow_table_constructor_rejects(table):
    good = {"u": table.u, "v": table.v, "wavelength_nm": table.wavelength_nm,
            "values": table.values, "sun_distance_m": table.sun_distance_m,
            "sun_radius_m": table.sun_radius_m, "occluder_radius_m": table.occluder_radius_m}
    ShadowTable(**good)
    cases = [
        ("values", table.values[:-1]), ("values", table.values[..., :1]),
        ("values", -table.values), ("values", "x"), ("u", table.u.flip(0)),
        ("u", torch.tensor([0.1])), ("v", table.v * 0.5), ("v", None),
        ("wavelength_nm", torch.tensor([450.0, math.nan])), ("sun_distance_m", -1.0),
        ("occluder_radius_m", "6e6"), ("interpolation", "cubic"), ("attrs", 3),
    ]
    for name, value in cases:
        expect_rejected(lambda name=name, value=value: ShadowTable(**{**good, name: value}),
                        (name,))


def test_shadow_table_records_what_it_was_built_for(table, airless):
    assert table.provenance["n_u"] == 8 and table.provenance["n_v"] == 12
    table.check_compatible(airless, wavelength_nm=[450.0, 650.0])
    with pytest.raises(ValueError, match="shadow"):
        table.check_compatible(Shadow.earth(atmosphere=False, cloud_fraction=0.5))
    with pytest.raises(ValueError, match="sun_distance_m"):
        table.check_compatible(Shadow.earth(atmosphere=False, sun_distance_m=1.0e11))
    with pytest.raises(ValueError, match="wavelength_nm"):
        table.check_compatible(wavelength_nm=[450.0, 650.0, 800.0])
    restored = ShadowTable.from_dataset(table.to_dataset())
    assert restored.provenance == table.provenance
    with pytest.raises(ValueError, match="shadow"):
        restored.check_compatible(Shadow.earth(atmosphere=False, n_arc=6))


@pytest.mark.parametrize("shadow", ["earth", None, 3.0])
def test_shadow_table_compute_rejects_other_objects(shadow):
    expect_rejected(lambda: ShadowTable.compute(shadow, [500.0]), ("shadow",))
    expect_rejected(lambda: ShadowTable.from_dataset(shadow), ("dataset",))


def test_shadow_table_compute_rejects_bad_settings(airless):
    for keywords, name in [({"n_u": 1}, "n_u"), ({"n_v": "8"}, "n_v"),
                           ({"interpolation": "cubic"}, "interpolation"),
                           ({"dtype": "float64"}, "dtype"), ({"wavelength_nm": -1.0}, "wavelength_nm"),
                           ({"min_distance_m": math.nan}, "min_distance_m")]:
        options = {"wavelength_nm": [500.0], "n_u": 4, "n_v": 4, "progress": False, **keywords}
        wavelength = options.pop("wavelength_nm")
        expect_rejected(lambda w=wavelength, o=options: ShadowTable.compute(airless, w, **o),
                        (name,))


# --- shadow cone -------------------------------------------------------------------------------

@SETTINGS
@given(st.data())
def test_shadow_cone(data):
    names = ("distance_m", "sun_distance_m", "sun_radius_m", "occluder_radius_m",
             "enlargement")
    args = {"distance_m": _as(data.draw(_number(0.0, 1e9)), data.draw(kinds)),
            "sun_distance_m": 1.496e11, "sun_radius_m": 6.957e8, "occluder_radius_m": 6.378e6}
    choice = data.draw(st.sampled_from(["valid", "bad", "shape", "enlargement"]))
    keywords = {}
    if choice == "bad":
        args[data.draw(st.sampled_from(list(args)))] = data.draw(bad)
    elif choice == "shape":
        args["distance_m"] = torch.zeros(3)
        args["sun_radius_m"] = torch.full((2,), 6.957e8)
    elif choice == "enlargement":
        keywords["enlargement"] = data.draw(st.sampled_from(["Danjon", None, 1]))
    result = check_contract(lambda: shadow_cone(**args, **keywords), names)
    assert isinstance(result, Exception) == (choice != "valid")


# --- lunar_eclipses ------------------------------------------------------------------------------

def test_lunar_eclipses_accepts_its_documented_range():
    # the docstring's range is the one checked (one definition: circumstances._search_range)
    import re

    from skytorch.eclipse.circumstances import _search_range

    low, high = _search_range()
    documented = re.search(r"within (\S+) \.\. (\S+) \(", lunar_eclipses.__doc__)
    assert documented.groups() == (np.datetime_as_string(low, "m"),
                                   np.datetime_as_string(high, "m"))
    first = lunar_eclipses(documented.group(1), "1900-01-01")
    assert first.sizes["eclipse"] >= 1  # 1899-12-17 partial eclipse
    last = lunar_eclipses("2053-06-01", documented.group(2))
    assert last.sizes["eclipse"] >= 1
    minute = np.timedelta64(1, "m")
    with pytest.raises(ValueError, match="start"):
        lunar_eclipses(low - minute, "1900-01-01")
    with pytest.raises(ValueError, match="end"):
        lunar_eclipses("2053-06-01", high + minute)


times = st.one_of(
    st.sampled_from(["2022-01-01", "2022-06-01", "1899-07-30", "2053-10-08", "2100-01-01",
                     "garbage", "", None, 5, math.nan, ["2022-01-01", "2022-02-01"],
                     np.datetime64("NaT")]),
    st.dates(min_value=np.datetime64("1890-01-01").astype(object),
             max_value=np.datetime64("2060-01-01").astype(object)).map(str),
)


@settings(max_examples=30, deadline=None, derandomize=True)
@given(times, times, st.sampled_from(["danjon", "chauvenet", "none", "Danjon", None]))
def test_lunar_eclipses_contract(start, end, enlargement):
    result = check_contract(lambda: lunar_eclipses(start, end, enlargement),
                            ("start", "end", "enlargement"), finite=False)
    if not isinstance(result, Exception):
        for name in ("umbral_magnitude", "penumbral_magnitude", "gamma", "moon_distance"):
            assert np.isfinite(result[name].values).all()
        assert (result.penumbral_magnitude.values > 0).all()


def test_lunar_eclipses_rejects_unknown_keyword():
    with pytest.raises(TypeError, match="enlargment"):
        lunar_eclipses("2022-01-01", "2023-01-01", enlargment="danjon")


# --- lunar eclipse light curve ---------------------------------------------------------------

FAST = {"n_times": 3, "n_disc": 2, "table_n_v": 8, "table_n_u": 2,
        "wavelength_nm": [550.0]}


@pytest.mark.parametrize(("keywords", "name"), [
    ({"time_or_date": None}, "time_or_date"), ({"time_or_date": "1899-08-01"}, "time_or_date"),
    ({"time_or_date": "2015-07-01"}, "time_or_date"),  # no eclipse within 20 days
    ({"n_times": 1}, "n_times"), ({"n_disc": "2"}, "n_disc"),
    ({"wavelength_nm": [math.nan]}, "wavelength_nm"), ({"wavelength_nm": "red"}, "wavelength_nm"),
    ({"shadow": "earth"}, "shadow"), ({"atmosphere": "earth"}, "atmosphere"),
    ({"enlargement": "Danjon"}, "enlargement"), ({"table_n_v": 1}, "table_n_v"),
    ({"progress": "yes"}, "progress"), ({"n_time": 3}, "n_time"),
])
@pytest.mark.parametrize("function", [lunar_light_curve, lunar_eclipse])
def test_light_curve_rejects(function, keywords, name):
    options = {"time_or_date": "2015-09-28", "atmosphere": False, **FAST, **keywords}
    expect_rejected(lambda: function(**options), (name,))


def test_light_curve_small_settings_is_finite_and_in_bounds():
    curve = check_contract(lambda: lunar_light_curve("2015-09-28", False, **FAST),
                           ("time_or_date",), finite=False)
    # an airless Earth's umbra is black: the totally eclipsed Moon sends no light (V = +inf,
    # B - V NaN, relative brightness 0; until 2026-12-07 a floor gave V = 737 mag and the
    # uneclipsed colour); Danjon L is NaN outside Vital's relation; all else is finite
    dark = curve["relative_brightness"] == 0.0
    assert bool(dark.any()) and bool(torch.isinf(curve["v_magnitude"][dark]).all())
    for name in ("v_magnitude", "relative_brightness"):
        assert bool(torch.isfinite(curve[name][~dark]).all()), name
    # one wavelength (550 nm) does not sample the B band: B and B - V are NaN throughout
    assert bool(torch.isnan(curve["b_magnitude"]).all())
    assert bool(torch.isnan(curve["b_minus_v"]).all())
    assert bool(torch.isfinite(curve["spectral_irradiance"]).all())
    v = float(curve["greatest_v_magnitude"])
    assert v == math.inf and math.isnan(float(curve["danjon_l"]))
    assert bool((curve["relative_brightness"] >= 0).all())
    assert bool((curve["relative_brightness"] <= 1.0 + 1e-9).all())
    dataset = check_contract(lambda: lunar_eclipse("2015-09-28", False, n_images=1,
                                                   image_pixels=4, **FAST), ("time_or_date",),
                             finite=False)
    assert dataset.sizes["time"] == 3
    np.testing.assert_array_equal(dataset["v_magnitude"].values, curve["v_magnitude"].numpy())


def test_flags_are_booleans_not_anything_true():
    """'no', None and NaN were taken as True or False by their truth value."""
    from skytorch.eclipse import Shadow, ShadowTable
    from skytorch.eclipse.danjon import danjon_l

    for name, value in (("refraction", "no"), ("scattering", "no"), ("refraction", None),
                        ("extinction", float("nan"))):
        with pytest.raises(TypeError, match=f"{name} must be True or False"):
            Shadow.earth(**{name: value})
    with pytest.raises(TypeError, match="return_uncertainty must be True or False"):
        danjon_l(0.0, return_uncertainty="no")
    with pytest.raises(TypeError, match="progress must be True or False"):
        ShadowTable.compute(Shadow.earth(n_altitude=9), torch.tensor([550.0]), n_u=2, n_v=4,
                            progress="no")


def test_a_sun_distance_that_puts_the_point_inside_the_sun_is_named():
    """It said 'sun_radius_rad must be finite; got nan', an internal name."""
    from skytorch.eclipse import Shadow

    shadow = Shadow.earth(n_altitude=17)
    with pytest.raises(ValueError, match="sun_distance_m: a point lies within the Sun"):
        shadow.relative_illuminance(3.844e8, 0.0, torch.tensor([550.0], dtype=torch.float64),
                                    sun_distance_m=1e8)
