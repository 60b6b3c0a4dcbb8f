"""The input contract of every public entry point family of ``skytorch.atmosphere``.

Each property test draws valid, hard and bad inputs (wrong types, None, strings, NaN/inf,
out-of-range values, integer tensors, mismatched shapes, misspelled keywords) and asserts
with :func:`tests._contract.check_contract` that every call either returns an all-finite
result or raises ValueError/TypeError naming a parameter; inputs that are certainly
invalid must be refused (:func:`tests._contract.expect_rejected`).
"""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from skytorch.atmosphere import Atmosphere, geometry, optical_depth, ozone, rayleigh, scattering
from skytorch.atmosphere import refraction as refraction_module
from skytorch.atmosphere.tables import TransmittanceTable
from tests._contract import ContractViolation, check_contract, expect_rejected

SETTINGS = settings(derandomize=True, max_examples=60, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])
#: slow entry points (ray tracing, scattering): fewer examples
SLOW = settings(derandomize=True, max_examples=25, deadline=None,
                suppress_health_check=[HealthCheck.too_slow])

EARTH = Atmosphere.earth()
BATCHED = Atmosphere.earth(turbidity=torch.tensor([2.0, 3.0], dtype=torch.float64))
WAVELENGTH = torch.tensor([440.0, 550.0, 680.0], dtype=torch.float64)
TABLE = TransmittanceTable.build(EARTH, WAVELENGTH, n_mu=16, n_r=8)

#: inputs no numeric parameter accepts
BAD = ["3", None, object(), [1.0, "x"], math.nan, math.inf, -math.inf, True]


def numbers(low: float, high: float):
    """Return Valid floats in [low, high], their edges, and the hard and bad neighbours."""
    return st.one_of(
        st.floats(low, high, allow_nan=False, allow_infinity=False),
        st.sampled_from([low, high, math.nan, math.inf, -math.inf, -1.0, 1e308, -1e-300]),
    )


def tensors(low: float, high: float):
    """Tensors of several shapes and dtypes (integer ones too) with values in a range."""
    shapes = st.sampled_from([(), (1,), (3,), (2, 1), (4,), (2, 3)])
    dtypes = st.sampled_from([torch.float64, torch.float32, torch.int64])

    def build(shape, dtype, fill):
        value = torch.full(shape, fill, dtype=torch.float64)
        if dtype == torch.int64:
            value = value.round()
        return value.to(dtype)

    return st.builds(build, shapes, dtypes, st.floats(low, high, allow_nan=False))


def inputs(low: float, high: float):
    """Any input for a numeric parameter: numbers, tensors and bad values."""
    return st.one_of(numbers(low, high), tensors(low, high), st.sampled_from(BAD))


def _is_bad(value) -> bool:
    """Certainly invalid for any numeric parameter."""
    if value is None or isinstance(value, (bool, str, list)):
        return True
    if isinstance(value, torch.Tensor):
        return False
    if isinstance(value, float):
        return not math.isfinite(value)
    return not isinstance(value, int)  # object()


# --- constructors --------------------------------------------------------------------------------


@SETTINGS
@given(turbidity=inputs(0.0, 80.0), ozone_du=inputs(-10.0, 2e5))
def test_earth(turbidity, ozone_du):
    outcome = check_contract(lambda: Atmosphere.earth(turbidity=turbidity, ozone_du=ozone_du),
                             ("turbidity", "ozone_du", "parameters"))
    if isinstance(outcome, Atmosphere):
        low, high = 1.0, 64.0
        t = torch.as_tensor(2.0 if turbidity is None else turbidity, dtype=torch.float64)
        assert bool(((t >= low) & (t <= high)).all()), "accepted an out-of-range turbidity"
        o = torch.as_tensor(ozone_du, dtype=torch.float64)
        assert bool(((o >= 0) & (o <= 1e5)).all()), "accepted an out-of-range ozone column"
    if _is_bad(turbidity) and turbidity is not None:  # (None: the default turbidity, 2)
        expect_rejected(lambda: Atmosphere.earth(turbidity=turbidity), ("turbidity",))


@SETTINGS
@given(key=st.sampled_from(["surface_pressure_pa", "rayleigh_scale_height_m",
                            "aerosol_scale_height_m", "aerosol_asymmetry", "angstrom_alpha",
                            "ozone_half_width_m", "gravity_m_s2", "reference_refractivity"]),
       value=inputs(-2.0, 2e8), misspelled=st.booleans())
def test_constructor_parameters(key, value, misspelled):
    name = key + "x" if misspelled else key
    outcome = check_contract(lambda: Atmosphere.earth(**{name: value}), (name,))
    if misspelled:
        assert isinstance(outcome, TypeError), "a misspelled keyword was accepted"
    elif isinstance(outcome, Atmosphere):
        # every accepted atmosphere gives finite optical depths, even at the horizon
        check_contract(lambda: outcome.optical_depth(WAVELENGTH, torch.tensor(
            [0.0, math.pi / 2, 1.7], dtype=torch.float64)), ("wavelength_nm",))


@SETTINGS
@given(dust=inputs(-1.0, 200.0), extra=st.sampled_from([{}, {"ozone_du": 0.0},
                                                         {"dust_depth": 1.0}]))
def test_mars(dust, extra):
    outcome = check_contract(lambda: Atmosphere.mars(dust_optical_depth=dust, **extra),
                             ("dust_optical_depth", "dust_depth", "ozone_du"))
    if "dust_depth" in extra:
        assert isinstance(outcome, TypeError)


# --- straight optical depth, transmittance, air mass ----------------------------------------------


@SETTINGS
@given(wavelength=inputs(100.0, 2000.0), zenith=inputs(-1.0, 4.0),
       altitude=inputs(-100.0, 2e5), method=st.sampled_from(["gauss", "trapezoid",
                                                              "adaptive", "gaus", 3]),
       rtol=st.sampled_from([1e-9, 1e-3, 0.0, -1e-9, math.nan, "x"]),
       atmosphere=st.sampled_from([EARTH, BATCHED]))
def test_optical_depth(wavelength, zenith, altitude, method, rtol, atmosphere):
    names = ("wavelength_nm", "zenith_rad", "altitude_m", "method", "rtol", "shapes")
    check_contract(lambda: atmosphere.optical_depth(wavelength, zenith, altitude,
                                                    method=method, rtol=rtol), names)
    check_contract(lambda: atmosphere.transmittance(wavelength, zenith, altitude), names)
    check_contract(lambda: atmosphere.air_mass(zenith, altitude), names)
    if isinstance(rtol, float) and not rtol > 0:
        expect_rejected(lambda: atmosphere.optical_depth(550.0, rtol=rtol), ("rtol",))
    if isinstance(altitude, float) and altitude < 0:
        expect_rejected(lambda: atmosphere.optical_depth(550.0, 0.0, altitude), ("altitude_m",))


@SETTINGS
@given(keyword=st.sampled_from(["methd", "n_step", "per_specie", "refract", "step_m",
                                "n_nodes"]))
def test_optical_depth_keywords(keyword):
    outcome = check_contract(lambda: EARTH.optical_depth(WAVELENGTH, **{keyword: 1}),
                             (keyword,))
    assert isinstance(outcome, TypeError)


# --- refracted rays ----------------------------------------------------------------------------------


@SLOW
@given(zenith=inputs(-0.5, 3.5), altitude=inputs(-10.0, 2e5),
       method=st.sampled_from(["gauss", "bouguer", "rk4", "rk5"]),
       atmosphere=st.sampled_from([EARTH, BATCHED]))
def test_refracted_optical_depth(zenith, altitude, method, atmosphere):
    if method == "rk4" and isinstance(zenith, torch.Tensor) and zenith.numel() > 3:
        zenith = zenith.reshape(-1)[:3]  # (RK4 is slow; the contract does not depend on it)
    check_contract(lambda: atmosphere.optical_depth(WAVELENGTH, zenith, altitude,
                                                    refraction=True, method=method),
                   ("zenith_rad", "altitude_m", "method", "shapes"))


@SLOW
@given(elevation=inputs(-2.0, 2.0), altitude=inputs(-10.0, 2e5),
       wavelength=st.sampled_from([None, 550.0, 100.0, math.nan, "x"]),
       atmosphere=st.sampled_from([EARTH, BATCHED]))
def test_refraction_and_apparent_altitude(elevation, altitude, wavelength, atmosphere):
    names = ("apparent_altitude_rad", "true_altitude_rad", "altitude_m", "wavelength_nm",
             "shapes")
    check_contract(lambda: atmosphere.refraction(elevation, altitude,
                                                 wavelength_nm=wavelength), names)
    check_contract(lambda: atmosphere.apparent_altitude(elevation, altitude), names)


@SLOW
@given(impact=inputs(-1e4, 2e5), which=st.sampled_from(["impact_altitude_m",
                                                        "periapsis_altitude_m",
                                                        "impact_parameter_m"]))
def test_grazing_rays(impact, which):
    if which == "impact_parameter_m" and isinstance(impact, (int, float)) and not isinstance(
            impact, bool) and math.isfinite(impact):
        impact = impact + EARTH.planet_radius_m
    check_contract(lambda: refraction_module.trace_grazing_rays(
        EARTH, wavelength_nm=WAVELENGTH, **{which: impact}), (which, "shapes"))


# --- single scattering ----------------------------------------------------------------------------


@SLOW
@given(view=inputs(-1.0, 3.5), sun=inputs(-1.0, 3.5), altitude=inputs(-10.0, 2e5),
       n_samples=st.sampled_from([8, 1, 0, 2.5, "8"]),
       table=st.sampled_from([None, TABLE, "table"]),
       wavelength=st.sampled_from([WAVELENGTH, torch.tensor([400.0, 500.0, 600.0]),
                                   torch.tensor([550.0]), 300.0]),
       atmosphere=st.sampled_from([EARTH, BATCHED, "earth", None]))
def test_sky_radiance(view, sun, altitude, n_samples, table, wavelength, atmosphere):
    names = ("view_zenith_rad", "sun_zenith_rad", "altitude_m", "n_samples", "table",
             "wavelength_nm", "atmosphere", "shapes")
    outcome = check_contract(lambda: scattering.single_scattering_radiance(
        atmosphere, wavelength, view, 0.0, sun, 0.0, altitude, n_samples=n_samples,
        table=table), names)
    if table is TABLE and isinstance(outcome, torch.Tensor):
        # a table is only used for the atmosphere and wavelengths it was built for
        assert atmosphere is EARTH and wavelength is WAVELENGTH


# --- tables -----------------------------------------------------------------------------------------


@SETTINGS
@given(zenith=inputs(-1.0, 4.0), altitude=inputs(-1e3, 2e5))
def test_table_lookups(zenith, altitude):
    outcome = check_contract(lambda: TABLE.optical_depth(zenith, altitude),
                             ("zenith_rad", "altitude_m", "shapes"))
    if isinstance(outcome, torch.Tensor):
        a = torch.as_tensor(altitude, dtype=torch.float64)
        assert bool(((a >= 0) & (a <= EARTH.top_altitude_m)).all()), \
            "accepted an altitude outside the table"


@SLOW
@given(n_mu=st.sampled_from([2, 4, 1, 0, 3.5, "4"]), n_r=st.sampled_from([2, 5, 1, -1]),
       wavelength=st.sampled_from([WAVELENGTH, 550.0, [], 100.0, math.nan]),
       atmosphere=st.sampled_from([EARTH, BATCHED, "earth"]))
def test_table_build(n_mu, n_r, wavelength, atmosphere):
    check_contract(lambda: TransmittanceTable.build(atmosphere, wavelength, n_mu=n_mu,
                                                    n_r=n_r),
                   ("n_mu", "n_r", "wavelength_nm", "atmosphere", "scalar parameters"))


# --- geometry helpers --------------------------------------------------------------------------------


@SETTINGS
@given(r=inputs(-1.0, 7e6), mu=inputs(-1.5, 1.5),
       radius=st.sampled_from([6.371e6, 0.0, -1.0, math.nan, "R"]),
       function=st.sampled_from(["distance_to_top", "distance_to_ground", "ray_hits_ground",
                                 "ray_segment"]))
def test_geometry(r, mu, radius, function):
    def call():
        if function == "distance_to_top":
            return geometry.distance_to_top(r, mu, 6.471e6 if radius == 6.371e6 else radius)
        if function == "distance_to_ground":
            return geometry.distance_to_ground(r, mu, radius)
        if function == "ray_hits_ground":
            return geometry.ray_hits_ground(r, mu, radius)
        return geometry.ray_segment(r, mu, radius, 6.471e6)

    check_contract(call, ("r", "mu", "radius", "shapes"))


@SETTINGS
@given(x_r=inputs(-0.5, 1.5), x_mu=inputs(-0.5, 1.5), altitude=inputs(-10.0, 2e5),
       mu=inputs(-1.5, 1.5))
def test_texture_coordinates(x_r, x_mu, altitude, mu):
    check_contract(lambda: geometry.texture_rays(x_r, x_mu, 6.371e6, 6.471e6),
                   ("x_r", "x_mu", "shapes"))
    check_contract(lambda: geometry.texture_coordinates(altitude, mu, 6.371e6, 6.471e6),
                   ("altitude_m", "mu", "shapes"))


# --- species, phase functions, air-mass formulas -----------------------------------------------------


@SETTINGS
@given(wavelength=inputs(100.0, 2000.0), cos_theta=inputs(-1.5, 1.5), g=inputs(-1.2, 1.2),
       x=inputs(-10.0, 2000.0), zenith=inputs(-1.0, 4.0))
def test_species_and_formulas(wavelength, cos_theta, g, x, zenith):
    check_contract(lambda: ozone.ozone_cross_section(wavelength), ("wavelength_nm",))
    check_contract(lambda: rayleigh.rayleigh_cross_section(wavelength), ("wavelength_nm",))
    check_contract(lambda: scattering.rayleigh_phase(cos_theta), ("cos_theta",))
    check_contract(lambda: scattering.henyey_greenstein(cos_theta, g),
                   ("cos_theta", "g", "shapes"))
    check_contract(lambda: scattering.cornette_shanks(cos_theta, g),
                   ("cos_theta", "g", "shapes"))
    check_contract(lambda: optical_depth.chapman(x, zenith), ("x", "zenith_rad", "shapes"))
    check_contract(lambda: optical_depth.chapman_horizontal(x), ("x",))
    check_contract(lambda: optical_depth.kasten_young_air_mass(zenith), ("zenith_rad",))
    check_contract(lambda: EARTH.extinction_coefficient(x, wavelength),
                   ("altitude_m", "wavelength_nm"))


def test_contract_helper_catches_a_raw_runtime_error():
    # the assertion itself can fail: a raw torch error is a violation
    with pytest.raises(ContractViolation):
        check_contract(lambda: torch.zeros(3) + torch.zeros(4), ("x",))


def test_batch_shape_error_names_the_keyword_given():
    """A turbidity of shape (2,) against ozone (3,): the message names the turbidity."""
    with pytest.raises(ValueError, match=r"angstrom_beta \(from turbidity or "
                                         r"aerosol_optical_depth\) \(2,\), ozone_du \(3,\)"):
        Atmosphere.earth(turbidity=torch.tensor([2.0, 3.0]),
                         ozone_du=torch.tensor([200.0, 300.0, 400.0]))
