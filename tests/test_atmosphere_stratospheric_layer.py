"""Stratospheric aerosol layer of Atmosphere.

A Gaussian in altitude (width = standard deviation) whose column from the ground to the top is the
requested optical depth at 550 nm. References: the closed form of the truncated Gaussian (erf),
scipy quad of the layer along the straight limb chord, bit-identity of the default, gradcheck.
"""

import math

import pytest
import torch
from scipy.integrate import quad
from scipy.special import erf

from skytorch.atmosphere import SPECIES, Atmosphere

WL = torch.tensor([550.0], dtype=torch.float64)
AOD = 0.1
CENTER, WIDTH = 20e3, 3e3


def _f64(*values):
    return torch.tensor(values, dtype=torch.float64)


def _closed_form_column(center, width, top):
    """Integral of exp(-(h-c)^2/(2 w^2)) over [0, top] [m]."""
    scale = math.sqrt(2.0) * width
    return width * math.sqrt(0.5 * math.pi) * (erf((top - center) / scale)
                                               + erf(center / scale))


def _limb_reference(atm, tangent_m, aod=AOD, center=CENTER, width=WIDTH, ratio=1.0):
    """Optical depth of the layer along the full straight chord through the tangent altitude.

    Integrated with scipy quad over the path length (independent of the model's quadrature and of
    its profile code).
    """
    radius, top = atm.planet_radius_m, atm.top_altitude_m
    k = aod * ratio / _closed_form_column(center, width, top)
    rt = radius + tangent_m
    half = math.sqrt((radius + top) ** 2 - rt ** 2)
    points = [math.sqrt((radius + center + d * width) ** 2 - rt ** 2)
              for d in (-3.0, 0.0, 3.0, 8.0) if radius + center + d * width > rt]

    def integrand(s):
        h = math.sqrt(rt ** 2 + s * s) - radius
        return k * math.exp(-0.5 * ((h - center) / width) ** 2)

    return 2.0 * quad(integrand, 0.0, half, points=points, limit=400, epsabs=0.0,
                      epsrel=1e-12)[0]


def _limb_model(atm, tangent_m):
    """Return the model's optical depth along the full chord.

    From an observer at the top looking down through the tangent point.
    """
    radius, top = atm.planet_radius_m, atm.top_altitude_m
    zenith = math.pi - math.asin((radius + tangent_m) / (radius + top))
    return atm.optical_depth(WL, _f64(zenith), _f64(top),
                             per_species=True)["stratospheric_aerosol"][0, 0]


def test_species_listed():
    assert "stratospheric_aerosol" in SPECIES


@pytest.mark.parametrize(("center", "width"), [(20e3, 3e3), (2e3, 3e3), (95e3, 4e3),
                                               (30e3, 10e3)])
def test_vertical_column_equals_requested_aod(center, width):
    """Vertical optical depth at 550 nm from the ground equals the requested AOD to 1e-6 relative.

    Also where the Gaussian is cut by the ground or the top.
    """
    atm = Atmosphere.earth(stratospheric_aerosol_optical_depth=AOD,
                           stratospheric_aerosol_altitude_m=center,
                           stratospheric_aerosol_width_m=width)
    tau = float(atm.optical_depth(WL, per_species=True)["stratospheric_aerosol"][0])
    assert abs(tau / AOD - 1.0) < 1e-6
    # the reference coefficient is AOD over the closed-form truncated column
    k = float(atm.reference_extinction(WL)["stratospheric_aerosol"][0])
    assert k * _closed_form_column(center, width, atm.top_altitude_m) == pytest.approx(
        AOD, rel=1e-12)


def test_limb_path_at_20_km_matches_chord_integral():
    atm = Atmosphere.earth(stratospheric_aerosol_optical_depth=AOD)
    model = float(_limb_model(atm, 20e3))
    reference = _limb_reference(atm, 20e3)
    assert reference > 5.0  # ~ AOD * sqrt(2 pi R / H)-like limb enhancement
    assert model == pytest.approx(reference, rel=1e-6)
    # the half chord from the tangent point is half of it
    half = float(atm.optical_depth(WL, _f64(math.pi / 2), _f64(20e3),
                                   per_species=True)["stratospheric_aerosol"][0, 0])
    assert 2.0 * half == pytest.approx(reference, rel=1e-6)


def test_layer_absent_from_limb_path_at_35_km():
    """Tangent at 35 km (5 widths above the peak).

    < 1e-4 of the 20 km value, and the model agrees with the chord integral there too (absolute
    1e-9).
    """
    atm = Atmosphere.earth(stratospheric_aerosol_optical_depth=AOD)
    high = float(_limb_model(atm, 35e3))
    low = float(_limb_model(atm, 20e3))
    assert high < 1e-4 * low
    assert high == pytest.approx(_limb_reference(atm, 35e3), abs=1e-9)


def test_total_extinction_includes_the_layer():
    """optical_depth (total) and extinction_coefficient grow by exactly the layer."""
    base = Atmosphere.earth()
    layer = Atmosphere.earth(stratospheric_aerosol_optical_depth=AOD)
    tau = layer.optical_depth(WL) - base.optical_depth(WL)
    assert float(tau[0]) == pytest.approx(AOD, rel=1e-6)
    h = _f64(CENTER)
    peak = layer.extinction_coefficient(h, WL) - base.extinction_coefficient(h, WL)
    expected = AOD / _closed_form_column(CENTER, WIDTH, layer.top_altitude_m)
    assert float(peak[0]) == pytest.approx(expected, rel=1e-9)


def test_spectrum_follows_mie_table():
    from skytorch.atmosphere.aerosol import sulfate_mie_properties

    wl = _f64(400.0, 550.0, 1000.0)
    atm = Atmosphere.earth(stratospheric_aerosol_optical_depth=AOD)
    tau = atm.optical_depth(wl, per_species=True)["stratospheric_aerosol"]
    ratio = sulfate_mie_properties(wl)[0]
    torch.testing.assert_close(tau, AOD * ratio, rtol=1e-6, atol=0.0)
    scattering = atm.scattering_coefficients(_f64(CENTER), wl)["stratospheric_aerosol"]
    local = (atm.extinction_coefficient(_f64(CENTER), wl)
             - Atmosphere.earth().extinction_coefficient(_f64(CENTER), wl))
    assert torch.all(scattering <= local * (1 + 1e-12)) and torch.all(scattering > 0.99 * local)


def test_phase_function_normalised():
    atm = Atmosphere.earth(stratospheric_aerosol_optical_depth=AOD)
    mu = torch.linspace(-1.0, 1.0, 20001, dtype=torch.float64)
    p = atm.stratospheric_aerosol_phase(mu, _f64(550.0))[:, 0]
    assert 2.0 * math.pi * float(torch.trapezoid(p, mu)) == pytest.approx(1.0, rel=1e-4)


def test_default_is_bit_identical():
    """Defaults given explicitly or omitted.

    Identical optical depths (also per species, slant, batched) and extinction coefficients.
    """
    plain = Atmosphere.earth(turbidity=3.0)
    explicit = Atmosphere.earth(turbidity=3.0, stratospheric_aerosol_optical_depth=0.0,
                                stratospheric_aerosol_altitude_m=20e3,
                                stratospheric_aerosol_width_m=3e3)
    wl = _f64(300.0, 550.0, 1000.0)
    zenith = torch.linspace(0.0, 1.7, 40, dtype=torch.float64)
    altitude = _f64(0.0, 5e3, 30e3)[:, None]
    assert torch.equal(plain.optical_depth(wl, zenith, altitude),
                       explicit.optical_depth(wl, zenith, altitude))
    a = plain.optical_depth(wl, zenith, per_species=True)
    b = explicit.optical_depth(wl, zenith, per_species=True)
    for s in ("rayleigh", "aerosol", "ozone"):
        assert torch.equal(a[s], b[s])
    assert not bool(b["stratospheric_aerosol"].any())
    h = torch.linspace(0.0, 50e3, 11, dtype=torch.float64)
    assert torch.equal(plain.extinction_coefficient(h, wl),
                       explicit.extinction_coefficient(h, wl))


def test_float32():
    atm = Atmosphere.earth(stratospheric_aerosol_optical_depth=AOD)
    tau = atm.optical_depth(torch.tensor([550.0]), per_species=True)["stratospheric_aerosol"]
    assert tau.dtype == torch.float32
    assert float(tau[0]) == pytest.approx(AOD, rel=1e-5)


def test_gradcheck_wrt_optical_depth():
    def tau(aod):
        atm = Atmosphere.earth(stratospheric_aerosol_optical_depth=aod)
        return atm.optical_depth(_f64(450.0, 800.0), _f64(0.3, 1.5))

    aod = torch.tensor(0.07, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(tau, (aod,))
    # a zero AOD that requires a gradient is not skipped: d tau / d AOD = air mass * ratio
    zero = torch.tensor(0.0, dtype=torch.float64, requires_grad=True)
    Atmosphere.earth(stratospheric_aerosol_optical_depth=zero).optical_depth(WL).sum().backward()
    assert float(zero.grad) == pytest.approx(1.0, rel=1e-6)


def test_batched_parameters():
    aod = _f64(0.0, 0.05, 0.2)
    atm = Atmosphere.earth(stratospheric_aerosol_optical_depth=aod,
                           stratospheric_aerosol_altitude_m=_f64(15e3, 20e3, 25e3))
    tau = atm.optical_depth(WL, per_species=True)["stratospheric_aerosol"]
    assert tau.shape == (3, 1)
    torch.testing.assert_close(tau[:, 0], aod, rtol=1e-6, atol=1e-12)


@pytest.mark.parametrize(("name", "value"), [
    ("stratospheric_aerosol_optical_depth", -0.1),
    ("stratospheric_aerosol_optical_depth", float("nan")),
    ("stratospheric_aerosol_optical_depth", float("inf")),
    ("stratospheric_aerosol_optical_depth", 101.0),
    ("stratospheric_aerosol_altitude_m", -1.0),
    ("stratospheric_aerosol_width_m", 0.0),
    ("stratospheric_aerosol_width_m", float("nan")),
])
def test_bad_values_refused_by_name(name, value):
    with pytest.raises(ValueError, match=name):
        Atmosphere.earth(**{name: value})


def test_bad_types_and_typos_refused():
    with pytest.raises(TypeError, match="stratospheric_aerosol_optical_depth"):
        Atmosphere.earth(stratospheric_aerosol_optical_depth=True)
    with pytest.raises((TypeError, ValueError), match="stratospheric_aerosol_optical_depth"):
        Atmosphere.earth(stratospheric_aerosol_optical_depth="0.1")
    with pytest.raises(TypeError, match="stratospheric_aerosol_optical_dept"):
        Atmosphere.earth(stratospheric_aerosol_optical_dept=0.1)


def test_refracted_per_species_includes_the_layer():
    """Refracted rays report the layer too.

    At the zenith (no bending) its optical depth is the AOD (1e-6), and the species add up to the
    refracted total.
    """
    atm = Atmosphere.earth(stratospheric_aerosol_optical_depth=AOD)
    parts = atm.optical_depth(WL, _f64(0.0, 1.2), refraction=True, per_species=True)
    assert float(parts["stratospheric_aerosol"][0, 0]) == pytest.approx(AOD, rel=1e-6)
    total = atm.optical_depth(WL, _f64(0.0, 1.2), refraction=True)
    torch.testing.assert_close(sum(parts.values()), total, rtol=1e-9, atol=0.0)


def test_single_scattering_of_a_thin_layer():
    """Sky radiance at the zenith, no molecules or other aerosol, optically thin layer (tau = 1e-4).

    The single-scattering closed form omega tau P_HG(theta) times the attenuation to first order, 1
    - tau/2 (1 + 1/mu_sun) (half the layer lies above the mean scatterer), within 2e-5 relative.
    """
    from skytorch.atmosphere.aerosol import sulfate_mie_properties

    tau, sun_zenith = 1e-4, 0.8
    atm = Atmosphere.earth(aerosol_optical_depth=0.0, ozone_du=0.0, surface_pressure_pa=0.0,
                           stratospheric_aerosol_optical_depth=tau)
    radiance = float(atm.sky_radiance(WL, 0.0, 0.0, sun_zenith, 0.0, scattering_orders=1)[0])
    _, albedo, g = (float(v[0]) for v in sulfate_mie_properties(WL))
    mu = math.cos(sun_zenith)
    phase = (1 - g * g) / (4 * math.pi * (1 + g * g - 2 * g * mu) ** 1.5)
    expected = albedo * tau * phase * (1 - 0.5 * tau * (1 + 1 / mu))
    assert radiance == pytest.approx(expected, rel=2e-5)


def test_sky_radiance_default_bit_identical():
    plain = Atmosphere.earth()
    explicit = Atmosphere.earth(stratospheric_aerosol_optical_depth=0.0)
    wl = _f64(400.0, 700.0)
    view = _f64(0.1, 0.9, 1.5)
    assert torch.equal(plain.sky_radiance(wl, view, 0.3, 1.0, 0.0, scattering_orders=1),
                       explicit.sky_radiance(wl, view, 0.3, 1.0, 0.0, scattering_orders=1))
