"""The fast paths of straight-ray columns give the values of the plain evaluation.

Nodes evaluated in cache-sized blocks of rays, the U.S. 1976 layer looked up once per
quadrature piece, band laws added at their band's wavelengths and the linear species as
one matrix product are rearrangements of the same arithmetic: each is compared here with
the plain evaluation (the reference is the path without the rearrangement, not a stored
number), over rays from the ground to above the top, looking up, down and grazing.
"""

from __future__ import annotations

import dataclasses

import pytest
import torch

from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere import optical_depth as od
from skytorch.atmosphere.constituents import Profile, Species, column_integrals
from skytorch.atmosphere.profiles import US1976_KINK_ALTITUDES_M, us1976_state

#: relative agreement of rearranged sums of the same float64 terms
REARRANGED = 1e-13
WAVELENGTH = torch.linspace(360.0, 1000.0, 60, dtype=torch.float64)


@pytest.fixture(scope="module")
def rays():
    """Rays from 0-120 km, zenith angles 0-180°, plus the horizontal ray from the ground."""
    generator = torch.Generator().manual_seed(7)
    n = 3000
    zenith = torch.rand(n, generator=generator, dtype=torch.float64) * torch.pi
    altitude = torch.rand(n, generator=generator, dtype=torch.float64) ** 3 * 120e3
    zenith = torch.cat([zenith, torch.tensor([torch.pi / 2], dtype=torch.float64)])
    altitude = torch.cat([altitude, torch.zeros(1, dtype=torch.float64)])
    return zenith, altitude


@pytest.fixture(scope="module")
def atmosphere():
    return Atmosphere.earth(turbidity=2.5, ozone_du=300.0,
                            stratospheric_aerosol_optical_depth=0.05)


def _columns(constituents, zenith, altitude, *, profiles=None, batch_shape=()):
    r = constituents.planet_radius_m + altitude
    return column_integrals(profiles or constituents.profiles, r, torch.cos(zenith),
                            constituents.planet_radius_m, constituents.top_radius_m,
                            batch_shape=batch_shape)


def test_us1976_layer_looked_up_elsewhere_in_the_layer():
    """A layer altitude anywhere in the same layer gives the state of the point itself."""
    bounds = (0.0, *US1976_KINK_ALTITUDES_M, 110e3)
    generator = torch.Generator().manual_seed(3)
    for low, high in zip(bounds[:-1], bounds[1:], strict=True):
        points = low + (high - low) * torch.rand(50, 1, generator=generator,
                                                 dtype=torch.float64)
        elsewhere = low + (high - low) * torch.rand(1, 1, generator=generator,
                                                    dtype=torch.float64)
        alone = us1976_state(points)
        shared = us1976_state(points, elsewhere)
        for a, b in zip(alone, shared, strict=True):
            assert torch.allclose(a, b, rtol=REARRANGED, atol=0.0), (low, high)


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_piecewise_state_equals_the_state_at_every_node(atmosphere, rays, dtype):
    """Air, H2O, O2, O2-O2 (``piecewise_state``) vs the same profiles looked up per node."""
    c = atmosphere.constituents(WAVELENGTH.to(dtype))
    rays = tuple(x.to(dtype) for x in rays)
    rtol = REARRANGED if dtype == torch.float64 else 1e-5
    piecewise = {name: p for name, p in c.profiles.items() if p.piecewise_state}
    assert set(piecewise) == {"rayleigh", "h2o", "o2", "o2o2"}
    per_node = {name: dataclasses.replace(p, piecewise_state=False)
                for name, p in piecewise.items()}
    fast = _columns(c, *rays, profiles=piecewise)
    plain = _columns(c, *rays, profiles=per_node)
    for name in piecewise:
        assert torch.allclose(fast[name], plain[name], rtol=rtol, atol=0.0), name
        assert bool((fast[name] > 0).any())


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_blocks_of_rays_equal_one_evaluation(atmosphere, rays, dtype):
    """Nodes in cache-sized blocks (unbatched parameters) vs every ray at once.

    Bit for bit in float64; in float32 within rounding.
    """
    c = atmosphere.constituents(WAVELENGTH.to(dtype))
    zenith, altitude = (x.to(dtype) for x in rays)
    r = c.planet_radius_m + altitude
    for name, profile in c.profiles.items():
        if c[name].vanishes:
            continue
        args = (lambda h, p=profile: p(h), r, torch.cos(zenith), c.planet_radius_m,
                c.top_radius_m, profile.levels())
        options = {"truncate": profile.truncate, "support": profile.support}
        whole = od.column_integral(*args, **options)
        blocked = od.column_integral(*args, **options, block_bytes=4096)  # blocks of ~8 rays
        if dtype == torch.float64:
            assert torch.equal(whole, blocked), name
        else:  # vectorised float32 kernels round differently with the array length
            assert torch.allclose(whole, blocked, rtol=1e-6, atol=0.0), name


def test_total_equals_the_sum_of_the_species(atmosphere, rays):
    """The matrix product and the band sums vs the per-species optical depths added up."""
    zenith, altitude = rays
    c = atmosphere.constituents(WAVELENGTH)
    columns = _columns(c, zenith, altitude)
    per_species = c.optical_depth(columns, per_species=True)
    total = c.optical_depth(columns)
    assert torch.allclose(total, sum(per_species.values()), rtol=REARRANGED, atol=1e-300)
    # the band species are zero outside their bands and nonzero inside
    for name in ("h2o", "o2"):
        species = c[name]
        assert species.law_indices is not None
        outside = torch.ones(WAVELENGTH.numel(), dtype=torch.bool)
        outside[species.law_indices] = False
        assert torch.equal(per_species[name][:, outside],
                           torch.zeros_like(per_species[name][:, outside]))
        assert bool((per_species[name][:, species.law_indices] > 0).any())


def test_fast_paths_keep_gradients(rays):
    """Gradients through the blocked, piecewise and band paths vs central differences."""
    zenith, altitude = (x[:40] for x in rays)
    water = torch.tensor(1.4, dtype=torch.float64, requires_grad=True)
    atm = Atmosphere.earth(turbidity=2.5, ozone_du=300.0, precipitable_water_cm=water)
    atm.optical_depth(WAVELENGTH, zenith, altitude).sum().backward()
    step = 1e-4
    plus = Atmosphere.earth(turbidity=2.5, ozone_du=300.0, precipitable_water_cm=1.4 + step)
    minus = Atmosphere.earth(turbidity=2.5, ozone_du=300.0, precipitable_water_cm=1.4 - step)
    with torch.no_grad():
        difference = (plus.optical_depth(WAVELENGTH, zenith, altitude).sum()
                      - minus.optical_depth(WAVELENGTH, zenith, altitude).sum()) / (2 * step)
    assert abs(float(water.grad) - float(difference)) <= 1e-6 * abs(float(difference))


def test_inconsistent_declarations_raise():
    profile = Profile(lambda h: h, {}, torch.tensor(1.0), breakpoints_m=torch.tensor([1.0]))
    with pytest.raises(ValueError, match="piecewise_state"):
        dataclasses.replace(profile, piecewise_state=True)
    with pytest.raises(ValueError, match="law_indices"):
        Species("band", profile, torch.zeros(3), law_indices=torch.tensor([1]))
    with pytest.raises(ValueError, match="layer_altitude_m of shape \\(3,\\)"):
        us1976_state(torch.zeros(2), torch.zeros(3))
    with pytest.raises(ValueError, match="block_bytes"):
        od.column_integral(lambda h: h, torch.tensor(6.4e6), torch.tensor(1.0), 6.371e6,
                           6.471e6, torch.tensor([1e3]), block_bytes=0)


def test_water_on_the_air_nodes_is_converged(atmosphere):
    """H2O integrated on the air's levels (layer kinks of (p/p_s)^m) vs a converged run.

    Measured: 1e-10 (ground) to 4e-8 (15 km observers) relative for zenith angles 0-120°,
    where levels in water scale heights from each leg's base gave 1.4e-7 to 4.8e-7.
    """
    c = atmosphere.constituents(WAVELENGTH)
    altitude = torch.tensor([0.0, 2e3, 5e3, 10e3, 15e3], dtype=torch.float64)[:, None]
    zenith = torch.tensor([0.0, 60.0, 85.0, 89.0, 90.0, 91.0, 95.0, 120.0],
                          dtype=torch.float64).deg2rad()
    r, mu = c.planet_radius_m + altitude, torch.cos(zenith)
    water = {"h2o": c.profiles["h2o"]}
    converged = column_integrals(water, r, mu, c.planet_radius_m, c.top_radius_m,
                                 method="adaptive", rtol=1e-13)["h2o"]
    default = c.column_integrals(r, mu)["h2o"]
    assert torch.allclose(default, converged, rtol=1e-7, atol=0.0)


def test_water_seen_from_above_is_converged(atmosphere):
    """Limb rays from 37 km grazing just above the 20 km layer boundary (the worst case).

    Measured over 50 000 random rays from above 20 km with columns above 1 m: at most
    9.2e-6 relative, on such rays (tangent 20.1-20.5 km: the air's piece up to 32 km is
    wide for the water there); rays looking down to the ground 7e-11.
    """
    c = atmosphere.constituents(WAVELENGTH)
    observer = c.planet_radius_m + 37e3
    tangent = c.planet_radius_m + torch.tensor([20.14e3, 20.4e3, 21e3, 25e3],
                                               dtype=torch.float64)
    mu = torch.cat([-torch.sqrt(1.0 - (tangent / observer) ** 2),
                    torch.tensor([-0.5, -1.0], dtype=torch.float64)])
    r = torch.full_like(mu, observer)
    converged = column_integrals({"h2o": c.profiles["h2o"]}, r, mu, c.planet_radius_m,
                                 c.top_radius_m, method="adaptive", rtol=1e-13)["h2o"]
    default = c.column_integrals(r, mu)["h2o"]
    assert bool((converged > 0.1).all())
    assert torch.allclose(default, converged, rtol=2e-5, atol=0.0)
