"""Shadow with a refracting atmosphere: limits, energy, references, hard cases.

References used (independent of the code under test):
- :func:`skytorch.eclipse.occlusion.sun_visible_fraction` (a different algorithm: Green's
  theorem on the lens boundary) for the airless and atmosphere-off limits;
- a converged high-resolution run of the same integral (more nodes, finer table) for the
  deep umbra and for float32;
- Vollmer & Gedzelman 2008 (Appl. Opt. 47, H52, doi:10.1364/AO.47.000H52): irradiance at
  the umbra centre ~1/2400 of sunlight for a molecular atmosphere without ozone;
- closed forms: the unobstructed disc flux (pi rho^2 for a uniform disc).
"""

from __future__ import annotations

import math

import pytest
import torch

from skytorch.constants import MEAN_EARTH_MOON_DISTANCE_M, PERCENT
from skytorch.eclipse.occlusion import sun_visible_fraction
from skytorch.eclipse.shadow import (
    Shadow,
    shadow_angles,
    solar_arc_integral,
    solar_normalisation,
)

#: Vollmer & Gedzelman 2008: umbra centre / sunlight, molecules only, no ozone
VG2008_UMBRA_CENTRE_RATIO = 1.0 / 2400.0
#: absolute error of the default ring/arc quadrature against the exact occlusion
QUADRATURE_ERROR = 1e-8
RGB = torch.tensor([680.0, 550.0, 440.0], dtype=torch.float64)
D_MOON = torch.tensor(MEAN_EARTH_MOON_DISTANCE_M, dtype=torch.float64)


@pytest.fixture(scope="module")
def earth():
    from skytorch.atmosphere import Atmosphere

    return Atmosphere.earth()


@pytest.fixture(scope="module")
def shadow(earth):
    return Shadow.earth(earth)


@pytest.fixture(scope="module")
def molecules():
    from skytorch.atmosphere import Atmosphere

    return Atmosphere.earth(ozone_du=0.0, aerosol_optical_depth=0.0)


def _geometric(shadow, distance, offset, radius):
    angles = shadow_angles(distance, offset, shadow.sun_distance_m, shadow.sun_radius_m,
                           radius)
    return sun_visible_fraction(angles["sun_radius_rad"], angles["occluder_radius_rad"],
                                angles["separation_rad"])


def test_normalisation_closed_form():
    # uniform disc: pi rho^2 (small-angle), exact cap: 2 pi (1 - cos rho)
    rho = torch.tensor([1e-3, 0.1], dtype=torch.float64)
    value = solar_normalisation(rho, 0.0)
    assert torch.allclose(value, 2 * math.pi * (1 - torch.cos(rho)), rtol=1e-12)


def test_arc_integral_uniform_is_arc_length():
    # uniform disc: F = 2 psi_max from the spherical law of cosines (independent formula)
    alpha = torch.tensor([0.004, 0.01, 0.012], dtype=torch.float64)
    sigma = torch.tensor(0.01, dtype=torch.float64)
    rho = torch.tensor(0.0047, dtype=torch.float64)
    one, zero = torch.ones(()).double(), torch.zeros(()).double()
    value = solar_arc_integral(alpha, rho, sigma, (one, zero, zero))
    cos_psi = (torch.cos(rho) - torch.cos(alpha) * torch.cos(sigma)) / (
        torch.sin(alpha) * torch.sin(sigma))
    expected = 2 * torch.acos(torch.clamp(cos_psi, -1, 1))
    assert torch.allclose(value, expected, atol=1e-12)


def test_airless_equals_geometric():
    shadow = Shadow.earth(atmosphere=False)
    offset = torch.linspace(0, 1.2e7, 61, dtype=torch.float64)
    value = shadow.relative_illuminance(D_MOON, offset, RGB)
    expected = _geometric(shadow, D_MOON, offset, shadow.occluder_radius_m)
    assert value.shape == (61, 3)
    assert torch.equal(value[:, 0], expected)


@pytest.mark.parametrize("distance", [MEAN_EARTH_MOON_DISTANCE_M, 1.3e9, 2.5e9])
def test_atmosphere_off_equals_geometric(earth, distance):
    shadow = Shadow.earth(earth, refraction=False, extinction=False)
    distance = torch.tensor(distance, dtype=torch.float64)
    offset = torch.linspace(0, 2.5e7, 101, dtype=torch.float64)
    value = shadow.relative_illuminance(distance, offset, RGB)
    expected = _geometric(shadow, distance, offset, shadow.occluder_radius_m)
    # equal up to the quadrature error of the ring integral (measured 1.6e-9 at 1.3e9 m)
    assert (value - expected[:, None]).abs().max() < QUADRATURE_ERROR


def test_atmosphere_off_equals_geometric_mars():
    from skytorch.atmosphere import Atmosphere
    from skytorch.constants import PHOBOS_SEMI_MAJOR_AXIS_M

    shadow = Shadow.mars(Atmosphere.mars(), refraction=False, extinction=False)
    distance = torch.tensor(PHOBOS_SEMI_MAJOR_AXIS_M, dtype=torch.float64)
    offset = torch.linspace(0, 4.5e6, 41, dtype=torch.float64)
    value = shadow.relative_illuminance(distance, offset, RGB)
    expected = _geometric(shadow, distance, offset, shadow.occluder_radius_m)
    assert (value - expected[:, None]).abs().max() < QUADRATURE_ERROR


def test_one_outside_penumbra(shadow):
    angles_edge = shadow.top_radius_m  # penumbra of the top of the atmosphere
    offset = torch.tensor([1.0e7, 2.0e7, 1.0e8], dtype=torch.float64)
    value = shadow.relative_illuminance(D_MOON, offset, RGB)
    assert angles_edge > 0
    assert torch.equal(value, torch.ones_like(value))
    # also far in front of the occluder and beside it
    value = shadow.relative_illuminance(torch.tensor([-1e9, 0.0]), torch.tensor([0.0, 1e8]),
                                        RGB)
    assert torch.equal(value, torch.ones_like(value))


def test_monotone_axis_to_penumbra_edge(shadow):
    offset = torch.linspace(0, 8.5e6, 300, dtype=torch.float64)
    value = shadow.relative_illuminance(D_MOON, offset, RGB)
    assert bool((value.diff(dim=0) >= 0).all())
    assert float(value[-1].min()) == 1.0


def test_umbra_positive_and_reddened(shadow):
    value = shadow.relative_illuminance(D_MOON, torch.tensor(0.0), RGB)
    assert bool((value > 0).all()) and bool(torch.isfinite(value).all())
    assert value[0] > 10 * value[1] > 10 * value[2]  # red >> green >> blue


def test_deep_umbra_relative_accuracy(shadow, earth, dtype):
    """Blue light at the umbra centre (~1e-8) vs a converged high-resolution run."""
    reference = Shadow.earth(earth, n_ring=48, n_split=4, n_arc=16, n_altitude=1601)
    offset = torch.tensor([0.0, 1.0e6], dtype=torch.float64)
    wavelength = torch.tensor([440.0, 400.0], dtype=torch.float64)
    expected = reference.relative_illuminance(D_MOON, offset, wavelength)
    assert float(expected.min()) < 1e-7  # a genuinely deep umbra
    value = shadow.relative_illuminance(D_MOON.to(dtype), offset.to(dtype), wavelength)
    assert value.dtype == dtype
    assert bool((value > 0).all())
    relative = ((value.double() - expected) / expected).abs().max()
    assert relative < (1 * PERCENT if dtype == torch.float64 else 5 * PERCENT)


def _fold_points():
    """Points at 1.05 lunar distances whose blue light comes through the tropopause fold."""
    offset = torch.linspace(1.70e6, 2.00e6, 31, dtype=torch.float64)
    return torch.full_like(offset, 1.05 * MEAN_EARTH_MOON_DISTANCE_M), offset


def test_ring_breakpoints_match_a_dense_scan(shadow):
    """Every crossing of a(beta) with the edges of F, folds included, vs a dense scan.

    Below the U.S. 1976 tropopause the bending grows upwards and a(beta) folds back; an
    edge can be crossed three times there. The crossings found by the bracketed search
    must be the sign changes of a - edge on a grid of 2e6 + 1 nodes in s.
    """
    from skytorch.eclipse.shadow import _apparent_angle, _breakpoints

    distance, offset = _fold_points()
    distance = torch.cat([distance, D_MOON.reshape(1)])
    offset = torch.cat([offset, torch.zeros(1, dtype=torch.float64)])
    profile = shadow.ring_profile(RGB)
    tables = profile.tables(torch.float64)
    angles = shadow._geometry(distance, offset, None, torch.float64)
    centre, rho, sigma = (angles[k] for k in ("centre_distance_m", "sun_radius_rad",
                                               "separation_rad"))
    scale = shadow.sun_distance_m / angles["sun_range_m"]
    radius = shadow.occluder_radius_m
    found = _breakpoints(profile, tables, centre, sigma, rho, scale, radius)
    s = torch.linspace(0.0, 1.0, 2_000_001, dtype=torch.float64)
    step = float(s[1])
    folded = 0
    for i in range(centre.shape[0]):
        a = _apparent_angle(profile, tables, s, centre[i], scale[i], radius)
        folded += int((a[1:] < a[:-1]).any())
        expected = []
        for edge in (-(sigma[i] + rho[i]), -(sigma[i] - rho[i]).abs(),
                     (sigma[i] - rho[i]).abs(), sigma[i] + rho[i]):
            below = a <= edge
            expected += s[1:][below[1:] != below[:-1]].tolist()
        got = sorted(x for x in found[i].tolist() if x < 1.0)
        assert len(got) == len(expected), (i, got, expected)
        for x, y in zip(got, sorted(expected), strict=True):
            assert y - step <= x <= y  # inside the scan's interval
    assert folded == centre.shape[0]
    assert max(int((row < 1.0).sum()) for row in found) > 2  # some edge crossed thrice


def test_fold_band_converged_in_table_rows(earth):
    """Blue light beside the tropopause fold: 401 table rows vs 1601 (0.02 %).

    A crossing missed at the fold used to cost up to 7 % here (I/I_sun ~ 5e-6 at 440 nm).
    """
    distance, offset = _fold_points()
    options = {"n_ring": 48, "n_split": 4}
    value = Shadow.earth(earth, **options).relative_illuminance(distance, offset, RGB)
    reference = Shadow.earth(earth, n_altitude=1601, trace_nodes=128, **options)
    expected = reference.relative_illuminance(distance, offset, RGB)
    assert float(expected[:, 2].max()) < 1e-5  # the deep blue band
    assert float(((value - expected) / expected).abs().max()) < 2e-4


def test_molecular_umbra_centre_vollmer_gedzelman(molecules):
    """Umbra centre / sunlight for molecules only, 400-700 nm irradiance.

    Vollmer & Gedzelman use a standard atmosphere; with the U.S. 1976 profile we measure
    1/2283 (ratio 1.05 to 1/2400), with the 8 km exponential profile 1/2804 (0.86). The
    band weighting of their "irradiance" is not stated in the abstract (a V-band weighting
    gives ~2x darker values, the centre being red): we allow 25 %.
    """
    from skytorch.atmosphere import Atmosphere
    from skytorch.spectrum import solar_irradiance

    atmosphere = Atmosphere.earth(ozone_du=0.0, aerosol_optical_depth=0.0,
                                  molecule_profile="us1976")
    wavelength = torch.arange(400.0, 701.0, 10.0, dtype=torch.float64)
    # 201 table rows: 1e-4 relative here (experiments/eclipse_accuracy_cost.py)
    value = Shadow.earth(atmosphere, n_altitude=201).relative_illuminance(
        D_MOON, torch.tensor(0.0), wavelength)
    weight = solar_irradiance(wavelength)
    ratio = float((value * weight).sum() / weight.sum())
    assert abs(ratio / VG2008_UMBRA_CENTRE_RATIO - 1.0) < 25 * PERCENT


def test_refraction_only_brightens_umbra(molecules):
    clear = Shadow.earth(molecules, extinction=False)
    offset = torch.tensor([0.0, 2.0e6, 4.0e6], dtype=torch.float64)
    value = clear.relative_illuminance(D_MOON, offset, RGB)
    # grey without extinction, and focused towards the axis (Link 1969)
    assert torch.allclose(value[:, 0], value[:, 2], rtol=1e-12)
    assert value[0, 0] > value[1, 0] > value[2, 0] > 1e-3


def test_cloud_top_and_terrain_darken(earth, molecules):
    offset = torch.tensor([0.0, 3.0e6], dtype=torch.float64)
    base = Shadow.earth(earth).relative_illuminance(D_MOON, offset, RGB)
    cloudy = Shadow.earth(earth, cloud_top_altitude_m=10e3).relative_illuminance(
        D_MOON, offset, RGB)
    half = Shadow.earth(earth, cloud_top_altitude_m=10e3, cloud_fraction=0.5)
    half = half.relative_illuminance(D_MOON, offset, RGB)
    # half the rays below the tops pass: the mean of clear and overcast (linear in weight)
    assert torch.allclose(half, 0.5 * (base + cloudy), rtol=1e-3)
    terrain = Shadow.earth(earth, terrain_height_m=240.0).relative_illuminance(
        D_MOON, offset, RGB)
    assert bool((cloudy < base).all())
    # terrain weights are <= 1: darker up to the quadrature error (2e-5 relative measured)
    assert bool((terrain <= base * (1 + 1e-4)).all())
    assert bool((terrain > 0.5 * base).all())
    # with aerosols the rays below 2 h_terrain carry < 1e-6 of this light; without them
    # they light the umbra centre: the terrain ramp (weights in [0, 1] below 480 m) lies
    # between no blocking and a closed deck at 480 m (measured -2.2 % and -4.5 % in red)
    centre = torch.tensor(0.0, dtype=torch.float64)
    clear = Shadow.earth(molecules).relative_illuminance(D_MOON, centre, RGB)
    ramp = Shadow.earth(molecules, terrain_height_m=240.0).relative_illuminance(
        D_MOON, centre, RGB)
    deck = Shadow.earth(molecules, cloud_top_altitude_m=480.0).relative_illuminance(
        D_MOON, centre, RGB)
    assert bool((deck < ramp).all()) and bool((ramp < clear).all())
    assert float(ramp[0] / clear[0]) < 1 - 1 * PERCENT


def test_point_inside_occluder_raises(shadow):
    with pytest.raises(ValueError, match="inside the occluder"):
        shadow.relative_illuminance(torch.tensor(1.0e6), torch.tensor(0.0), RGB)
    with pytest.raises(ValueError, match="atmosphere"):
        shadow.relative_illuminance(torch.tensor(6.4e6), torch.tensor(0.0), RGB)
    with pytest.raises(ValueError, match="offset_m"):
        shadow.relative_illuminance(D_MOON, torch.tensor(-1.0), RGB)
    with pytest.raises(ValueError, match="distance_m"):
        shadow.relative_illuminance(torch.tensor(float("nan")), torch.tensor(0.0), RGB)


def _tangent_offsets(shadow, distance):
    """Offsets where the solar disc touches the top of the atmosphere inside and outside."""
    from skytorch.eclipse.shadow_table import shadow_uv_inverse

    angles = shadow_angles(distance, torch.tensor(0.0, dtype=torch.float64),
                           shadow.sun_distance_m, shadow.sun_radius_m, shadow.top_radius_m)
    u = angles["sun_radius_rad"] / (angles["sun_radius_rad"] + angles["occluder_radius_rad"])
    phi_s, phi_o = angles["sun_radius_rad"], angles["occluder_radius_rad"]
    v_inner = (phi_o - phi_s) / (phi_o + phi_s)
    result = shadow_uv_inverse(u.expand(2), torch.stack([v_inner, torch.ones_like(u)]),
                               shadow.sun_distance_m, shadow.sun_radius_m, shadow.top_radius_m)
    return result["distance_m"], result["offset_m"]


def test_hard_cases_values_and_gradients(shadow, dtype):
    distance, offset = _tangent_offsets(shadow, D_MOON)
    # axis (Sun behind the centre), internal and external tangency, far beyond the umbra
    distance = torch.cat([D_MOON[None], distance, torch.tensor([5e9, 1e12])]).to(dtype)
    offset = torch.cat([torch.zeros(1).double(), offset, torch.tensor([0.0, 0.0])]).to(dtype)
    distance.requires_grad_(True)
    offset.requires_grad_(True)
    value = shadow.relative_illuminance(distance, offset, RGB)
    assert value.dtype == dtype
    assert bool(torch.isfinite(value).all()) and bool((value > 0).all())
    # external tangency: whole Sun visible (sun_visible_fraction is good to 3e-5 in float32)
    tolerance = 1e-6 if dtype == torch.float64 else 1e-4
    assert float(value[2].detach().min()) > 1 - tolerance
    assert float(value[4].detach().min()) > 0.99  # 1e12 m: the occluder hides < 1 % of the Sun
    # gradients; the antumbra on the axis (last point) is left out: sun_visible_fraction's
    # own gradient is NaN at zero separation with the occluder inside the solar disc
    grads = torch.autograd.grad(value[:-1].sum(), [distance, offset])
    assert all(bool(torch.isfinite(g[:-1]).all()) for g in grads)


def test_gradcheck_generic_points(earth):
    shadow = Shadow.earth(earth, n_altitude=101)
    distance = torch.tensor([3.8e8, 4.0e8], dtype=torch.float64, requires_grad=True)
    offset = torch.tensor([2.0e6, 5.5e6], dtype=torch.float64, requires_grad=True)
    wavelength = torch.tensor([650.0], dtype=torch.float64)

    def function(d, o):
        return shadow.relative_illuminance(d, o, wavelength)

    assert torch.autograd.gradcheck(function, (distance, offset), eps=1e-2, atol=1e-9,
                                    rtol=1e-4)


def test_limb_view_integrates_to_ring_light(shadow):
    offset = torch.tensor([0.0, 3.0e6], dtype=torch.float64)
    # the umbra centre sees a thin refracted ring whose light ends sharply at the solar
    # limb: the samples of the limb view are 24 m apart in impact altitude (1.6 km bins
    # with 16 samples gave 0.4 %-7 % depending on where the limb fell between samples)
    view = shadow.limb_view(D_MOON, offset, RGB, n_azimuth=16, n_altitude=256, oversample=16)
    assert view["radiance"].shape == (2, 256, 16, 3)
    direct = _geometric(shadow, D_MOON, offset, shadow.top_radius_m)
    total = shadow.relative_illuminance(D_MOON, offset, RGB)
    angles = shadow_angles(D_MOON, offset, shadow.sun_distance_m, shadow.sun_radius_m,
                           shadow.top_radius_m)
    central = 1.0 / solar_normalisation(angles["sun_radius_rad"])  # I(0)=1 per unit flux
    ring = (view["radiance"] * view["solid_angle_sr"][..., None]).sum((-3, -2))
    ring = ring * central[:, None]
    expected = total - direct[:, None]
    assert ((ring - expected).abs() / expected).max() < 2 * PERCENT  # measured 0.63 %


def test_mars_shadow_at_phobos_and_deimos():
    from skytorch.constants import DEIMOS_SEMI_MAJOR_AXIS_M, PHOBOS_SEMI_MAJOR_AXIS_M

    shadow = Shadow.mars()
    distance = torch.tensor([PHOBOS_SEMI_MAJOR_AXIS_M, DEIMOS_SEMI_MAJOR_AXIS_M],
                            dtype=torch.float64)
    value = shadow.relative_illuminance(distance, torch.zeros(2, dtype=torch.float64), RGB)
    airless = Shadow.mars(atmosphere=False).relative_illuminance(
        distance, torch.zeros(2, dtype=torch.float64), RGB)
    assert bool((airless == 0).all())
    assert bool((value >= 0).all()) and bool(torch.isfinite(value).all())


def test_straight_ray_shadow_sees_every_species():
    """refraction=False traces straight rays through the same species as refracted ones.

    Reference: an Atmosphere whose refractivity is 1e-30 (no bending) traced by the
    refraction module directly; before the straight-ray wrapper forwarded the species, the
    O2 A band and the 940 nm water band were missing (limb optical depth at 762 nm 1.38
    instead of 3.74 for a ray grazing at 5 km).
    """
    from skytorch.atmosphere import Atmosphere
    from skytorch.atmosphere.refraction import trace_grazing_rays
    from skytorch.eclipse.shadow import _NoRefraction

    wavelength = torch.tensor([550.0, 762.0, 940.0], dtype=torch.float64)
    impact = torch.tensor([5e3, 10e3, 20e3], dtype=torch.float64)
    straight = trace_grazing_rays(_NoRefraction(Atmosphere.earth()), wavelength_nm=wavelength,
                                  impact_altitude_m=impact)["optical_depth"]
    flat = Atmosphere.earth(reference_refractivity=1e-30)
    reference = trace_grazing_rays(flat, wavelength_nm=wavelength,
                                   impact_altitude_m=impact)["optical_depth"]
    torch.testing.assert_close(straight, reference, rtol=1e-9, atol=0.0)
