"""Input contract of the Moon's public entry points, as hypothesis property tests.

Every call either returns an all-finite result within its physical bounds, or raises
``ValueError``/``TypeError`` naming one of its parameters (:mod:`tests._contract`). Each
argument is drawn from valid values (including integer tensors and batched shapes), hard
values (full and new Moon, grazing geometry) and bad ones (wrong types, None, strings,
NaN/inf, out-of-range numbers); shapes that do not broadcast and misspelled keywords are
bad too. A call with a bad input must be refused; a call with only valid inputs must be
accepted.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from _contract import arg, bad_values, call_and_check
from hypothesis import given, settings
from hypothesis import strategies as st

import skytorch as st_sky
from skytorch.moon import geometry

SETTINGS = settings(max_examples=60, derandomize=True, deadline=None)
PI = math.pi

# ------------------------------------------------------------------------------ helpers ---


BAD = bad_values()
PHASE_VALID = [0.0, PI, -PI, 1e-12, PI - 1e-9, 1.0, torch.tensor([0, 1, 3]),
               torch.tensor([0.0, PI / 2, PI]), torch.tensor([[0.3], [2.0]]),
               torch.tensor(PI / 2, dtype=torch.float32)]
#: phase angles where the sign is not ignored: the documented range [0, π]
PHASE_NONNEGATIVE = [v for v in PHASE_VALID if bool((torch.as_tensor(v) >= 0).all())]
PHASE_BAD = [*BAD, 3.5, -4.0, torch.tensor([0.0, math.nan]), torch.tensor([1.0, 7.0])]
DISTANCE_VALID = [3.844e8, 3.6e8, torch.tensor([3.6e8, 3.8e8, 4.05e8]), 1e7,
                  torch.tensor([4e8], dtype=torch.float64)]
DISTANCE_BAD = [*BAD, 0.0, -1.0, 1e6, torch.tensor([3.8e8, -3.0])]
SUN_DISTANCE_VALID = [1.496e11, torch.tensor([1.47e11, 1.52e11, 1.5e11]), 1e9]
SUN_DISTANCE_BAD = [*BAD, 0.0, -1.496e11]
QUADRATURE_VALID = [1, 4, 6, np.int64(5), 4.0]
QUADRATURE_BAD = [0, -3, 10**6, 2.5, "8", None, True]
FLAG_BAD = ["no", 1, None]
MISSPELLED = st.sampled_from([None, None, None, "distnce_m"])


# -------------------------------------------------------------------- magnitude family ---


@SETTINGS
@given(phase=arg(PHASE_VALID, PHASE_BAD), distance=arg(DISTANCE_VALID, DISTANCE_BAD),
       sun=arg(SUN_DISTANCE_VALID, SUN_DISTANCE_BAD),
       n=arg(QUADRATURE_VALID, QUADRATURE_BAD),
       earthshine=arg([True, False], FLAG_BAD),
       model=arg(["hapke2012", "lommel_seeliger"], ["hapke", 3, None]),
       parameters=arg(["helfenstein1987", {"roughness_rad": 0.3}],
                      [3, None, "nope", {"roughness": 0.3}, {"asymmetry": 2.0}]),
       misspelled=MISSPELLED)
def test_magnitude_contract(phase, distance, sun, n, earthshine, model, parameters,
                            misspelled):
    # without earthshine the new Moon has no flux (+inf mag): keep the phase away from π
    if not earthshine[0] and not phase[1]:
        phase = (torch.as_tensor(phase[0]).clamp(-3.0, 3.0), False)
    arguments = {"phase_angle_rad": phase, "distance_m": distance, "sun_distance_m": sun,
                 "n_quadrature": n, "earthshine": earthshine, "model": model,
                 "parameters": parameters}
    call_and_check(st_sky.moon.magnitude, arguments,
                   shape_arguments=("phase_angle_rad", "distance_m", "sun_distance_m"),
                   misspelled=misspelled, bounds=(-20.0, 5.0))


@SETTINGS
@given(phase=arg(PHASE_VALID, PHASE_BAD), distance=arg(DISTANCE_VALID, DISTANCE_BAD),
       wavelength=arg([torch.tensor([440.0, 550.0, 680.0]), 550.0, torch.tensor([400, 700])],
                      [*BAD, 100.0, torch.tensor([[500.0, 600.0]] * 2),
                       torch.tensor([550.0, math.inf])]),
       n=arg(QUADRATURE_VALID, QUADRATURE_BAD))
def test_lunar_irradiance_contract(phase, distance, wavelength, n):
    arguments = {"phase_angle_rad": phase, "wavelength_nm": wavelength, "distance_m": distance,
                 "n_quadrature": n}
    call_and_check(st_sky.moon.lunar_irradiance, arguments,
                   shape_arguments=("phase_angle_rad", "distance_m"), bounds=(0.0, 1e-4))


_PHOTOMETRY = {}


def _photometry(n):
    if n not in _PHOTOMETRY:
        _PHOTOMETRY[n] = st_sky.moon.MoonPhotometry(n_quadrature=n)
    return _PHOTOMETRY[n]


@SETTINGS
@given(phase=arg(PHASE_VALID, PHASE_BAD), distance=arg(DISTANCE_VALID, DISTANCE_BAD),
       sun=arg(SUN_DISTANCE_VALID, SUN_DISTANCE_BAD))
def test_moon_photometry_module_contract(phase, distance, sun):
    module = _photometry(6)
    arguments = {"phase_angle_rad": phase, "distance_m": distance, "sun_distance_m": sun}
    call_and_check(module, arguments,
                   shape_arguments=("phase_angle_rad", "distance_m", "sun_distance_m"),
                   bounds=(-20.0, 5.0))


@SETTINGS
@given(n=arg(QUADRATURE_VALID, QUADRATURE_BAD), earthshine=arg([True, False], FLAG_BAD),
       model=arg(["hapke2012"], ["x", None]))
def test_moon_photometry_constructor_contract(n, earthshine, model):
    arguments = {"n_quadrature": n, "earthshine": earthshine, "model": model}
    call_and_check(lambda **kw: st_sky.moon.MoonPhotometry(**kw).reference_magnitude,
                   arguments)


# --------------------------------------------------------------------- geometry family ---

VECTOR_VALID = [torch.tensor([1.496e11, 0.0, 0.0]), torch.tensor([[1.4e11, 2e10, 0.0]] * 4),
                torch.tensor([1, 2, 3]), torch.ones(2, 1, 3) * 1e11]
MOON_VALID = [torch.tensor([0.0, 3.844e8, 0.0]), torch.tensor([[3.8e8, 0.0, 1e7]] * 4),
              torch.tensor([[1e8, 2e8, 3e7]] * 3, dtype=torch.float64)]
VECTOR_BAD = [*BAD, torch.ones(2), torch.ones(4, 4), torch.tensor([1.0, math.nan, 0.0])]


@SETTINGS
@given(sun=arg(VECTOR_VALID, VECTOR_BAD), moon=arg(MOON_VALID, VECTOR_BAD),
       observer=arg([None, torch.tensor([6.4e6, 0.0, 0.0]), torch.zeros(5, 1, 3)],
                    [*BAD[:1], torch.ones(2), torch.tensor([math.inf, 0.0, 0.0])]))
def test_phase_angle_contract(sun, moon, observer):
    arguments = {"sun_vec": sun, "moon_vec": moon, "observer_vec": observer}
    shape_arguments = ("sun_vec", "moon_vec") + (("observer_vec",) if observer[0] is not None
                                                 else ())
    call_and_check(st_sky.moon.phase_angle, arguments, shape_arguments=shape_arguments,
                   trailing=1, bounds=(0.0, PI))


def test_phase_angle_broadcasts_like_torch():
    """(4, 1, 3) Suns against (5, 3) Moons: a (4, 5) result equal to the looped values."""
    sun = torch.randn(4, 1, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(1))
    moon = torch.randn(5, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(2))
    result = st_sky.moon.phase_angle(sun, moon)
    assert result.shape == (4, 5)
    for i in range(4):
        for j in range(5):
            a, b = sun[i, 0] - moon[j], -moon[j]
            expected = math.acos(float(a @ b / (a.norm() * b.norm())))
            assert abs(float(result[i, j]) - expected) < 1e-12


ANGLE_VALID = [0.3, torch.tensor([0, 1]), torch.tensor([[0.1], [0.2], [0.3]]), -1.2]
ANGLE_BAD = [*BAD]


@SETTINGS
@given(h=arg(ANGLE_VALID, ANGLE_BAD), dec=arg(ANGLE_VALID, ANGLE_BAD),
       lat=arg(ANGLE_VALID + [torch.ones(4)], ANGLE_BAD))
def test_parallactic_angle_contract(h, dec, lat):
    arguments = {"hour_angle_rad": h, "dec_rad": dec, "lat_rad": lat}
    call_and_check(st_sky.moon.parallactic_angle, arguments, shape_arguments=tuple(arguments),
                   bounds=(-PI, PI))


@SETTINGS
@given(lon=arg(ANGLE_VALID, ANGLE_BAD), lat=arg(ANGLE_VALID + [torch.ones(4)], ANGLE_BAD),
       t=arg([0.1, torch.tensor([0, 1]), -0.5], ANGLE_BAD),
       physical=arg([True, False]))
def test_libration_contract(lon, lat, t, physical):
    arguments = {"moon_lon_rad": lon, "moon_lat_rad": lat, "julian_centuries_tt": t,
                 "physical": physical}
    call_and_check(st_sky.moon.libration, arguments,
                   shape_arguments=("moon_lon_rad", "moon_lat_rad", "julian_centuries_tt"),
                   bounds=(-PI, PI))


@SETTINGS
@given(distance=arg([3.844e8, torch.tensor([1.8e6, 4e8]), 2e6], [*BAD, 0.5, 0.0, -5.0]),
       radius=arg([1_737_400.0, 1.0], ["x", None, -1.0, 0.0, math.nan]))
def test_apparent_diameter_contract(distance, radius):
    call_and_check(geometry.apparent_diameter, {"distance_m": distance, "radius_m": radius},
                   bounds=(0.0, PI))


@SETTINGS
@given(phase=arg(PHASE_VALID, [*BAD, torch.tensor([math.nan])]))
def test_illuminated_fraction_contract(phase):
    call_and_check(st_sky.moon.illuminated_fraction, {"phase_angle_rad": phase},
                   bounds=(0.0, 1.0))


# ------------------------------------------------------------------- reflectance family ---

MU_VALID = [0.5, 1.0, 0.0, -0.2, torch.tensor([0, 1]), torch.linspace(-1, 1, 5)]
MU_BAD = [*BAD, 1.5, -2.0]


@SETTINGS
@given(mu0=arg(MU_VALID, MU_BAD), mu=arg(MU_VALID, MU_BAD),
       g=arg([0.0, PI, 1.0, torch.tensor([0.2, 0.4, 0.6, 0.8, 1.0])], PHASE_BAD),
       model=arg(["hapke2012", "lommel_seeliger"], ["x", 3]),
       wavelength=arg([None, torch.tensor([440.0, 550.0])], [100.0, "x", math.nan]))
def test_reflectance_contract(mu0, mu, g, model, wavelength):
    arguments = {"mu0": mu0, "mu": mu, "phase_angle_rad": g, "model": model,
                 "wavelength_nm": wavelength}
    call_and_check(st_sky.moon.reflectance, arguments,
                   shape_arguments=("mu0", "mu", "phase_angle_rad"), bounds=(0.0, 10.0))


# ----------------------------------------------------------------- moonlit sky family ---

ZENITH_VALID = [0.0, 1.0, PI / 2, torch.tensor([0.1, 0.5, 1.2])]
ZENITH_BAD = [*BAD, 2.0, -0.1]


@SETTINGS
@given(phase=arg(PHASE_VALID, PHASE_BAD),
       separation=arg([0.2, PI, torch.tensor([0.5, 1.0, 2.0])], [*BAD, -1.0, 4.0]),
       moon_zenith=arg(ZENITH_VALID, ZENITH_BAD), zenith=arg(ZENITH_VALID, ZENITH_BAD),
       k=arg([0.172, 0.0, 1.0], [*BAD, -0.1]))
def test_moonlit_sky_ks1991_contract(phase, separation, moon_zenith, zenith, k):
    arguments = {"phase_angle_rad": phase, "separation_rad": separation,
                 "moon_zenith_rad": moon_zenith, "zenith_rad": zenith, "extinction_mag": k}
    call_and_check(st_sky.moon.moonlit_sky_ks1991, arguments, shape_arguments=tuple(arguments),
                   bounds=(0.0, 1e9))


@SETTINGS
@given(phase=arg(PHASE_NONNEGATIVE, [*PHASE_BAD, -0.5]),
       distance=arg(DISTANCE_VALID, DISTANCE_BAD))
def test_earthshine_ratio_contract(phase, distance):
    arguments = {"phase_angle_rad": phase, "distance_m": distance}
    call_and_check(st_sky.moon.earthshine_irradiance_ratio, arguments,
                   shape_arguments=tuple(arguments), bounds=(0.0, 1.0))


def test_moon_geometry_and_planets_take_one_whole_observer():
    """A latitude without a longitude, a height without an observer, several observers."""
    from skytorch.moon.datasets import moon_geometry
    from skytorch.stars.planets import planets

    for function in (moon_geometry, planets):
        with pytest.raises(ValueError, match="give both lat_deg and lon_deg"):
            function("2024-01-01", lat_deg=52.5)
        with pytest.raises(ValueError, match="elevation_m=100.0 needs an observer"):
            function("2024-01-01", elevation_m=100.0)
        with pytest.raises(ValueError, match="takes one observer"):
            function("2024-01-01", lat_deg=[52.5, 40.0], lon_deg=[13.4, 2.0])
    with pytest.raises(ValueError, match="each planet once"):
        planets("2024-01-01", bodies=("mars", "mars"))


def test_position_angles_stay_below_a_full_turn():
    """remainder(-1e-17, 2 pi) is 2 pi in floating point: the documented range is [0, 2 pi)."""
    from skytorch.moon.geometry import bright_limb_position_angle

    angle = bright_limb_position_angle(1.0, math.pi / 2, 2.0, 0.2)
    assert 0.0 <= float(angle) < 2.0 * math.pi
    with pytest.raises(ValueError, match=r"got -4.0 rad"):
        st_sky.moon.magnitude(torch.tensor(-4.0))
