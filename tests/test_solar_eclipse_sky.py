"""The sky during a solar eclipse: per-point visible fraction, the planner's bound, the scene."""

import math

import numpy as np
import pytest
import torch

import skytorch as st
from skytorch.scene.geometry import site_geometries
from skytorch.scene.solar_eclipse_sky import (
    baumbach_corona,
    eclipsed_second_order,
    eclipsed_single_scattering,
    penumbra_touches,
    sight_radius_m,
    visible_fraction_at,
)

BURGOS = (42.34, -3.70, 850.0)
#: greatest eclipse at Burgos on 2026-08-12 (solar_eclipse_local: totality 18:28:27-18:30:10)
TOTALITY = "2026-08-12T18:29:18"
NEXT_DAY = "2026-08-13T18:29:18"


def _geometry(time, lat, lon, elevation=0.0):
    return site_geometries(np.datetime64(time), [lat], [lon], [elevation])[0]


def test_far_from_the_shadow_equals_the_atmosphere_single_scattering():
    # the Moon's shadow far away: the per-point fraction is 1, and the kernel must agree with
    # the atmosphere's own single-scattering code (relative azimuth from the Sun)
    g = _geometry(NEXT_DAY, *BURGOS)
    atm = st.Atmosphere.earth(2.0)
    wl = torch.tensor([450.0, 650.0], dtype=torch.float64)
    zenith = torch.tensor([0.0, 0.6, 1.2, 1.5, 1.56], dtype=torch.float64)
    azimuth = torch.tensor([0.3, 2.0, 4.0, math.radians(g.sun_azimuth_deg), 5.5],
                           dtype=torch.float64)
    ours = eclipsed_single_scattering(atm, wl, zenith, azimuth, g, BURGOS[2], n_samples=48)
    sun_zenith = torch.full_like(zenith, math.radians(90.0 - g.sun_altitude_deg))
    reference = atm.sky_radiance(wl, zenith, azimuth - math.radians(g.sun_azimuth_deg),
                                 sun_zenith, torch.zeros_like(zenith), BURGOS[2],
                                 n_samples=48, scattering_orders=1)
    # the Sun's direction from its vector vs from the rounded altitude and azimuth
    assert torch.allclose(ours, reference, rtol=1e-6, atol=0.0)


def test_visible_fraction_at_the_observer_matches_the_local_circumstances():
    # without limb darkening the visible fraction is one minus the obscured area, which
    # solar_eclipse_local computes from the shadow geometry on its own
    for lat, lon in ((48.85, 2.35), (51.5, -0.13), (40.42, -3.70)):
        local = st.eclipse.solar_eclipse_local("2026-08-12", lat, lon)
        g = _geometry(str(local.maximum_time.values)[:26], lat, lon)
        fraction = visible_fraction_at(g, torch.zeros(3, dtype=torch.float64),
                                       limb_darkening=0.0)
        assert abs(float(fraction) - (1.0 - float(local.obscuration))) < 0.005


def test_umbra_is_a_cone_of_the_right_size_at_the_ground():
    # at totality the observer is dark; 400 km across the shadow (perpendicular to the Sun,
    # the path of 2026 is under 300 km wide) the Sun shows again, while along the Sun's
    # direction the low Sun (8 deg) stretches the shadow's footprint on the ground
    g = _geometry(TOTALITY, *BURGOS)
    sun = torch.tensor(g.sun_horizontal_m, dtype=torch.float64)
    sun = sun / torch.linalg.vector_norm(sun)
    across = torch.linalg.cross(sun, torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64))
    across = across / torch.linalg.vector_norm(across)
    near = visible_fraction_at(g, torch.zeros(3, dtype=torch.float64))
    sideways = visible_fraction_at(g, torch.stack([4e5 * across, -4e5 * across]))
    along = visible_fraction_at(g, torch.stack([-2e5 * sun, 2e5 * sun]))
    assert float(near) == 0.0
    assert bool((sideways > 0.0).all())
    assert float(along.max()) < float(sideways.min())


@pytest.mark.parametrize("time, lat, lon", [
    (TOTALITY, *BURGOS[:2]),
    ("2026-08-12T17:00:00", 60.0, 10.0),
    ("2026-08-12T19:30:00", 30.0, -20.0),
    ("2026-08-12T16:00:00", 20.0, 40.0),   # far from the penumbra
    ("2026-08-12T18:00:00", 75.0, -60.0),
])
def test_penumbra_bound_is_never_wrong(time, lat, lon):
    # brute force: points filling the ball of all the air in sight; wherever one of them sees
    # less than the whole Sun the bound must say "may touch"
    g = _geometry(time, lat, lon)
    radius = sight_radius_m(6_371_000.0, 100_000.0, 0.0)
    generator = torch.Generator().manual_seed(1)
    directions = torch.randn(20000, 3, generator=generator, dtype=torch.float64)
    directions = directions / torch.linalg.vector_norm(directions, dim=-1, keepdim=True)
    depth = radius * torch.rand(20000, 1, generator=generator, dtype=torch.float64) ** (1 / 3)
    fraction = visible_fraction_at(g, depth * directions, limb_darkening=0.0)
    touches, clearance = penumbra_touches(g, radius)
    if bool((fraction < 1.0).any()):
        assert touches
    if not touches:
        assert clearance > 0.0


def test_penumbra_bound_rejects_the_next_day():
    touches, clearance = penumbra_touches(_geometry(NEXT_DAY, *BURGOS), 2.3e6)
    assert not touches and clearance > 1e7


def test_baumbach_corona_checks():
    with pytest.raises(ValueError, match="rho"):
        baumbach_corona(torch.tensor(0.5))
    with pytest.raises(ValueError, match="level"):
        baumbach_corona(torch.tensor(2.0), level=0.0)


def _render(time):
    scene = st.Scene(time=time, lat_deg=BURGOS[0], lon_deg=BURGOS[1], elevation_m=BURGOS[2],
                     view="fisheye", size=64, fidelity="fast")
    return scene.render()


def test_scene_at_totality_is_dark_overhead_with_a_bright_horizon():
    total, normal = _render(TOTALITY), _render(NEXT_DAY)
    assert "solar_eclipse" in total.attrs["effects_computed"].split(",")
    assert "solar_eclipse" in normal.attrs["effects_skipped"]
    sky_total = total.component_radiance.sel(component="sky")
    sky_normal = normal.component_radiance.sel(component="sky")
    alt = total.altitude
    zenith = float(sky_total.where(alt > 80).mean())
    zenith_normal = float(sky_normal.where(alt > 80).mean())
    low = float(sky_total.where((alt > 3) & (alt < 8)).mean())
    assert zenith < 1e-3 * zenith_normal   # the umbra's air is dark
    assert low > 100.0 * zenith            # light scattered outside the umbra: the glow
    # the solar disc is hidden: what remains of the 'sun' component is the corona,
    # ~1e-6 of the Sun's flux (Baumbach), far below the uneclipsed disc
    sun_total = float((total.component_radiance.sel(component="sun")
                       * total.solid_angle).sum())
    sun_normal = float((normal.component_radiance.sel(component="sun")
                        * normal.solid_angle).sum())
    assert 1e-7 < sun_total / sun_normal < 1e-5


def test_second_order_far_from_the_shadow_is_the_atmosphere_second_order():
    """The next day the visible fraction is 1 everywhere: the generic kernel's value."""
    from skytorch.atmosphere.scattering import second_order_radiance
    from skytorch.atmosphere.tables import TransmittanceTable

    g = _geometry(NEXT_DAY, *BURGOS)
    atm = st.Atmosphere.earth(2.0)
    wl = torch.tensor([550.0], dtype=torch.float64)
    table = TransmittanceTable.build(atm, wl, cache=False, n_mu=64, n_r=16)
    zenith = torch.tensor([0.0, 1.2], dtype=torch.float64)
    azimuth = torch.tensor([0.0, 2.0], dtype=torch.float64)
    ours = eclipsed_second_order(atm, wl, zenith, azimuth, g, BURGOS[2], table=table,
                                 n_view=12, n_phi=8, n_samples=12)
    north, east, up = g.sun_horizontal_m
    reference = second_order_radiance(
        atm.constituents(wl), zenith, azimuth,
        torch.tensor(math.atan2(math.hypot(north, east), up), dtype=torch.float64),
        torch.tensor(math.atan2(east, north), dtype=torch.float64),
        torch.tensor(BURGOS[2], dtype=torch.float64), table=table, n_view=12, n_phi=8,
        n_samples=12)
    assert torch.allclose(ours, reference, rtol=1e-9, atol=0.0)


def test_zenith_at_totality_about_four_orders_below_the_day_sky():
    """Dandekar & Turtle (1971): the zenith at totality "about four orders of magnitude lower".

    Single scattering alone puts it six orders down (the air overhead is in the umbra);
    the second order, light scattered once in the sunlit air outside the umbra, brings
    it to 10^-3.6 at 550 nm (both days with orders 1 and 2).
    """
    from skytorch.atmosphere.tables import TransmittanceTable

    atm = st.Atmosphere.earth(2.0)
    wl = torch.tensor([550.0], dtype=torch.float64)
    table = TransmittanceTable.build(atm, wl, cache=False, n_mu=128, n_r=32)
    zero = torch.zeros(1, dtype=torch.float64)
    sky = {}
    for name, time in (("total", TOTALITY), ("normal", NEXT_DAY)):
        g = _geometry(time, *BURGOS)
        single = eclipsed_single_scattering(atm, wl, zero, zero, g, BURGOS[2], table=table,
                                            n_samples=48)
        second = eclipsed_second_order(atm, wl, zero, zero, g, BURGOS[2], table=table)
        sky[name] = (float(single), float(second))
    assert sky["total"][1] > 100.0 * sky["total"][0]  # the second order dominates
    ratio = sum(sky["total"]) / sum(sky["normal"])
    assert -4.5 < math.log10(ratio) < -3.0
    assert math.log10(sky["total"][0] / sky["normal"][0]) < -5.0  # single scattering alone


def test_the_planner_keeps_two_orders_during_the_eclipse():
    scene = st.Scene(time=TOTALITY, lat_deg=BURGOS[0], lon_deg=BURGOS[1],
                     elevation_m=BURGOS[2], size=16, fidelity="default")
    plan = scene.plan()
    assert "solar_eclipse" in plan.computed
    assert plan.scattering_orders["sky"] == 2
    assert "orders >= 3 are not computed" in plan.scattering_reason
    assert "the 'reference' preset computes them" in plan.scattering_reason


def test_the_reference_preset_adds_the_higher_orders_at_totality():
    """The plan records orders 3..N; the scene's table holds eclipsed_higher_orders' values.

    The table's zenith row is the zenith line of sight of the function at the tables'
    wavelength nodes (no interpolation there), every azimuth alike, the first azimuth
    repeated after the last; without the knob the table refuses.
    """
    from skytorch.scene.eclipse_higher_orders import eclipsed_higher_orders
    from skytorch.scene.presets import FIDELITY
    from skytorch.scene.render import Knobs, eclipse_higher_orders_table
    from skytorch.spectrum import solar_irradiance

    plan = st.Scene(time=TOTALITY, lat_deg=BURGOS[0], lon_deg=BURGOS[1],
                    elevation_m=BURGOS[2], size=16, fidelity="reference").plan()
    assert plan.scattering_orders["sky"] >= 3
    assert "dimmed by one step of diffusion" in plan.scattering_reason
    scene = st.Scene(time=TOTALITY, lat_deg=BURGOS[0], lon_deg=BURGOS[1],
                     elevation_m=BURGOS[2], size=16, fidelity="fast")
    resources = scene.resources()
    setting = {"lut": (2, 3), "quadrature": (6, 3, 8)}
    knobs = Knobs({**FIDELITY["fast"], "eclipse_higher": setting}, torch.float64, TOTALITY,
                  *BURGOS, solar_eclipse=True,
                  scattering_orders={"sky": 5, "moon": 1, "tables": 4})
    tables = resources.scattering_tables(4, FIDELITY["fast"]["ms_tables"],
                                         FIDELITY["fast"]["ms_wavelength_nodes"])
    geometry = _geometry(TOTALITY, *BURGOS)
    table = eclipse_higher_orders_table(resources, geometry, knobs, tables.wavelength_nm)
    assert table.shape == (2, 4, tables.wavelength_nm.numel())
    zero = torch.zeros(1, dtype=torch.float64)
    direct = eclipsed_higher_orders(resources.atmosphere, tables.wavelength_nm, zero, zero,
                                    geometry, BURGOS[2], tables=tables, scattering_orders=5,
                                    n_view=6, n_mu=3, n_phi=8)[0]
    expected = direct * solar_irradiance(tables.wavelength_nm)
    assert torch.allclose(table[0], expected.expand(4, -1), rtol=1e-9, atol=0.0)
    assert torch.equal(table[:, 0], table[:, -1])
    with pytest.raises(ValueError, match="eclipse_higher"):
        eclipse_higher_orders_table(resources, geometry, Knobs(
            FIDELITY["fast"], torch.float64, TOTALITY, *BURGOS, solar_eclipse=True,
            scattering_orders={"sky": 5, "moon": 1, "tables": 4}), tables.wavelength_nm)
