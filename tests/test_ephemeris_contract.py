"""Input contract of the ephemeris entry points (hypothesis property tests).

Every call either returns an all-finite result or raises ValueError/TypeError naming one
of its parameters (tests/_contract.py); inputs outside the documented ranges, of the
wrong type, of shapes that do not broadcast or with misspelled keywords are refused.
Ranges (docs/ephemeris.md): latitude [-90, 90], east longitude [-180, 360), height
[-500, 1e5] m, times 1899-07-29 .. 2053-10-09 (TIME_MIN .. TIME_MAX).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from _contract import bad_values, check_contract, expect_rejected
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from skytorch import ephemeris as eph
from skytorch.constants import ARCSECOND, SPEED_OF_LIGHT_M_S

SETTINGS = settings(max_examples=60, derandomize=True, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])

#: valid instants, the range ends included
VALID_TIMES = ["2015-09-28T02:47Z", "2000-01-01 12:00", np.datetime64("2024-03-20T03:06"),
               str(eph.TIME_MIN), str(eph.TIME_MAX), ["2016-12-31T23:59:59",
                                                       "2017-01-01T00:00:01"]]
#: invalid times: outside DE421, unparseable, leap-second labels, NaT, numbers, tensors
BAD_TIMES = ["1850-01-01", "2100-01-01", "not a time", "2016-12-31T23:59:60", "2015-13-45",
             np.datetime64("NaT"), 5, 2.5, None, torch.tensor([1.0]), [], [["2015-01-01"]],
             str(eph.TIME_MAX + np.timedelta64(1, "s")),
             # beyond datetime64[ns] (1678-2261): converting them wrapped them round into
             # valid years (2600 became 2015-06-13) until 2026-12-07
             "2600-01-01", "1400-01-01", np.datetime64("2600-01-01"),
             np.array(["2500-06-01", "2015-01-01"], dtype="datetime64[D]")]


def _labelled(valid, bad):
    """(value, is_valid) pairs."""
    return st.one_of(st.tuples(valid, st.just(True)), st.tuples(bad, st.just(False)))


def _numbers(low, high, *, hard=(), high_inclusive=True):
    """Draw valid floats, ints and integer/float tensors in [low, high]; ends included."""
    floats = st.floats(low, high, allow_nan=False, exclude_max=not high_inclusive)
    ints = st.integers(math.ceil(low), math.floor(high) - (0 if high_inclusive else 1))
    return st.one_of(floats, ints, st.sampled_from(list(hard)),
                     ints.map(lambda v: torch.tensor(v)),  # integer tensor
                     floats.map(lambda v: torch.tensor([v, v])))


def _bad_numbers(low, high):
    return st.one_of(st.sampled_from(bad_values()),
                     st.floats(-1e9, low, exclude_max=True, allow_nan=False),
                     st.floats(high, 1e9, exclude_min=True, allow_nan=False))


LAT = _labelled(_numbers(-90.0, 90.0, hard=(-90.0, 90.0, 0.0)), _bad_numbers(-90.0, 90.0))
LON = _labelled(_numbers(-180.0, 360.0, hard=(-180.0, 359.999999, 0.0), high_inclusive=False),
                st.one_of(_bad_numbers(-180.0, 360.0), st.just(360.0)))
HEIGHT = _labelled(_numbers(-500.0, 1e5, hard=(-500.0, 1e5)), _bad_numbers(-500.0, 1e5))
TIMES = _labelled(st.sampled_from(VALID_TIMES), st.sampled_from(BAD_TIMES))


def _valid(*labelled) -> bool:
    return all(ok for _, ok in labelled)


@SETTINGS
@given(times=TIMES, lat=LAT, lon=LON, height=HEIGHT, observer=st.booleans())
def test_sun_moon_contract(times, lat, lon, height, observer):
    names = ("time", "lat_deg", "lon_deg", "elevation_m")
    kwargs = {"lat_deg": lat[0], "lon_deg": lon[0]} if observer else {}
    used = [times, height] + ([lat, lon] if observer else [])
    call = lambda: eph.sun_moon(times[0], elevation_m=height[0], **kwargs)  # noqa: E731
    # a height other than 0 without an observer would go unused: refused
    unused = not observer and height[1] and bool((torch.as_tensor(height[0]) != 0).any())
    if _valid(*used) and not unused:
        ds = check_contract(call, names)
        assert not isinstance(ds, Exception), ds
        assert set(ds.data_vars) >= {"sun_ra", "sun_dec", "moon_distance"}
        if observer:
            assert float(np.abs(ds["sun_altitude"]).max()) <= 90.0
            assert float(ds["moon_azimuth"].min()) >= 0.0
            assert float(ds["moon_azimuth"].max()) < 360.0
    else:
        expect_rejected(call, names)


@SETTINGS
@given(times=TIMES, lat=LAT, lon=LON, height=HEIGHT)
def test_rotation_and_velocity_contract(times, lat, lon, height):
    names = ("time", "lat_deg", "lon_deg", "elevation_m")
    for function in (eph.icrs_to_horizontal_matrices, eph.observer_gcrs_velocity):
        def call(function=function):
            return function(times[0], lat[0], lon[0], height[0])
        if _valid(times, lat, lon, height):
            result = check_contract(call, names)
            assert isinstance(result, torch.Tensor), result
            assert result.dtype == torch.float64
        else:
            expect_rejected(call, names)


@pytest.mark.parametrize("shapes", [((2,), (3,), ()), ((2,), (), (3,)), ((4, 1), (3,), (2,)),
                                    ((2, 3), (3, 2), ())])
def test_observer_shapes_that_do_not_broadcast_are_named(shapes):
    values = [torch.zeros(shape, dtype=torch.float64) for shape in shapes]
    for call in (lambda: eph.sun_moon("2015-01-01", *values),
                 lambda: eph.icrs_to_horizontal_matrices("2015-01-01", *values),
                 lambda: eph.observer_gcrs_velocity("2015-01-01", *values)):
        error = expect_rejected(call, ("lat_deg",))
        assert isinstance(error, ValueError)
        assert all(name in str(error) for name in ("lat_deg", "lon_deg", "elevation_m"))
        assert str(shapes[0]) in str(error)


def test_sun_moon_observers_broadcast_and_two_dimensional_ones_are_refused():
    ds = eph.sun_moon("2015-01-01", lat_deg=[10, 20, 30], lon_deg=5, elevation_m=0)
    assert ds.sizes["observer"] == 3
    expect_rejected(lambda: eph.sun_moon("2015-01-01", lat_deg=[[10.0, 20.0]], lon_deg=5.0),
                    ("lat_deg",))
    expect_rejected(lambda: eph.sun_moon("2015-01-01", lat_deg=10.0), ("lat_deg", "lon_deg"))
    expect_rejected(lambda: eph.sun_moon("2015-01-01", elevation_m="x"), ("elevation_m",))
    with pytest.raises(TypeError, match="lat_dge"):
        eph.sun_moon("2015-01-01", lat_dge=10.0, lon_deg=0.0)


def test_integer_observer_inputs_equal_float_ones():
    floats = eph.icrs_to_horizontal_matrices("2015-01-01", 48.0, 11.0, 500.0)
    ints = eph.icrs_to_horizontal_matrices("2015-01-01", 48, 11, 500)
    tensors = eph.icrs_to_horizontal_matrices("2015-01-01", torch.tensor(48),
                                              torch.tensor(11), torch.tensor(500))
    assert torch.equal(floats, ints) and torch.equal(floats, tensors)
    a = eph.sun_moon("2015-01-01", lat_deg=48, lon_deg=11, elevation_m=500)
    b = eph.sun_moon("2015-01-01", lat_deg=48.0, lon_deg=11.0, elevation_m=500.0)
    assert float(abs(a.moon_altitude - b.moon_altitude).max()) == 0.0


_VECTORS = st.one_of(
    st.tuples(st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=3), st.just(True)),
    st.tuples(st.lists(st.integers(-5, 5), min_size=3, max_size=3)
              .map(lambda v: torch.tensor(v)), st.just(True)),
    st.tuples(st.sampled_from([torch.zeros(2), torch.zeros(4, 2), torch.tensor(1.0), "x",
                               None, [1.0, "y", 2.0]]), st.just(False)),
)


@SETTINGS
@given(vectors=_VECTORS)
def test_altaz_from_horizontal_contract(vectors):
    value, ok = vectors
    call = lambda: eph.altaz_from_horizontal(  # noqa: E731
        torch.tensor(value, dtype=torch.float64) if isinstance(value, list) and ok else value)
    if ok:
        altitude, azimuth = check_contract(call, ("vectors",))
        assert altitude.is_floating_point()
        # bounds in the result's dtype (integer tensors are promoted to float32)
        half_pi = torch.tensor(math.pi / 2, dtype=altitude.dtype)
        assert bool((altitude.abs() <= half_pi).all())
        assert bool((azimuth >= 0).all()) and bool((azimuth <= 2 * math.pi).all())
    else:
        expect_rejected(call, ("vectors",))


_SPEED = st.floats(0.0, 0.99 * SPEED_OF_LIGHT_M_S)


@SETTINGS
@given(direction=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
       speed=_SPEED, n_direction=st.sampled_from([1, 3]), n_velocity=st.sampled_from([1, 2, 3]),
       bad=st.sampled_from([None, "nan", "fast", "short_direction", "short_velocity"]))
def test_aberrate_contract(direction, speed, n_direction, n_velocity, bad):
    u = torch.tensor([direction] * n_direction, dtype=torch.float64)
    u = u / torch.linalg.vector_norm(u, dim=-1, keepdim=True).clamp(min=1e-12)
    u = torch.where(torch.isfinite(u), u, torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64))
    v = torch.tensor([[speed, 0.0, 0.0]] * n_velocity, dtype=torch.float64)
    if bad == "nan":
        v[0, 1] = math.nan
    elif bad == "fast":
        v[0, 0] = SPEED_OF_LIGHT_M_S
    elif bad == "short_direction":
        u = u[..., :2]
    elif bad == "short_velocity":
        v = v[..., :2]
    names = ("direction", "velocity_m_s")
    call = lambda: eph.aberrate(u, v)  # noqa: E731
    mismatch = n_direction != n_velocity and 1 not in (n_direction, n_velocity)
    if bad is None and not mismatch and float(u.norm(dim=-1).min()) > 0.5:
        moved = check_contract(call, names)
        assert torch.allclose(moved.norm(dim=-1), torch.ones(()).double(), atol=1e-12)
        matrix, beta = check_contract(lambda: eph.aberration_matrix(v), ("velocity_m_s",))
        assert matrix.shape == (n_velocity, 3, 3)
    elif bad is not None or mismatch:
        expect_rejected(call, names)


def test_aberration_of_a_zero_velocity_is_the_identity():
    u = torch.tensor([[0.6, 0.8, 0.0]], dtype=torch.float64)
    moved = eph.aberrate(u, torch.zeros(1, 3, dtype=torch.float64))
    assert float((moved - u).abs().max()) < 1e-6 * ARCSECOND


def test_parse_times_contract():
    for value in VALID_TIMES:
        values = check_contract(lambda value=value: eph.parse_times(value), ("time",),
                                finite=False)
        assert values.dtype == np.dtype("datetime64[ns]")
    for value in BAD_TIMES:
        expect_rejected(lambda value=value: eph.parse_times(value), ("time",))


def test_rotation_and_velocity_gradients_match_finite_differences():
    """Check the documented differentiability in latitude, longitude (height: velocity).

    Against central finite differences (torch.autograd.gradcheck).
    """
    times = ["2015-09-28T02:47Z", "2024-06-20T20:51Z"]
    lat = torch.tensor([52.52, -89.9], dtype=torch.float64, requires_grad=True)
    lon = torch.tensor([13.40, 359.5], dtype=torch.float64, requires_grad=True)
    height = torch.tensor([34.0, 2500.0], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(
        lambda a, b: eph.icrs_to_horizontal_matrices(times, a, b), (lat, lon),
        eps=1e-6, atol=1e-8)
    assert torch.autograd.gradcheck(
        lambda a, b, c: eph.observer_gcrs_velocity(times, a, b, c), (lat, lon, height),
        eps=1e-6, atol=1e-6)
