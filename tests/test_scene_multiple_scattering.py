"""Multiple scattering in the scene's sunlit and moonlit sky (``Scene.scattering_orders``).

The scene keeps its exact single-scattering look-up table and adds the orders 2..N of
coarse multiple-scattering tables (:func:`skytorch.scene.render.higher_orders`). Checks:

* plumbing: ``scattering_orders=1`` draws the single-scattering sky of the unchanged code
  path bit for bit; the plan and the Dataset record the orders; bad values raise;
* energy: the multiply-scattered sky is nowhere darker than the single-scattered one;
* independent references: SPECTRL2's diffuse horizontal irradiance (Bird & Riordan
  1986, pvlib), the moonlit sky of Krisciunas & Schaefer (1991), and what is physically
  certain of the twilight (a monotone fall of the zenith brightness; single scattering
  alone loses the deep twilight, Patat et al. 2006: multiple scattering dominates there).

Measured numbers are in docs/scene.md ("Multiple scattering").
"""

from __future__ import annotations

import dataclasses
import math
import types
from pathlib import Path

import numpy as np
import pytest
import torch

import skytorch as st
from skytorch.atmosphere.multiple_scattering import TableResolution
from skytorch.constants import DEGREE, MAG, MEAN_EARTH_MOON_DISTANCE_M, PERCENT
from skytorch.scene.presets import FIDELITY
from skytorch.scene.render import Knobs, _lookup, moon_table, sky_component, sky_table
from skytorch.scene.resources import SceneResources, SceneSpec

DAY = {"time": "2015-06-21T10:00", "lat_deg": 48.85, "lon_deg": 2.35, "size": 24}
#: the V-band grid of the moonlit-sky comparison [nm]
V_GRID_NM = tuple(float(w) for w in np.arange(470.0, 701.0, 5.0))
#: SPECTRL2 case (issue 14): AOD 0.1 at 500 nm, Angstrom exponent 1.14, 300 DU, no water
AOD_500, ALPHA, OZONE_DU = 0.1, 1.14, 300.0


def _knobs(orders=None, fidelity="default", elevation_m=0.0):
    """Knobs of a bare geometry: single scattering (None) or ``orders`` of converged tables."""
    scattering = None if orders is None else {"sky": orders, "moon": orders,
                                              "tables": "converged"}
    return Knobs(FIDELITY[fidelity], torch.float64, None, 0.0, 0.0, elevation_m,
                 scattering_orders=scattering)


def _converged_orders(resources, fidelity="default"):
    knobs = FIDELITY[fidelity]
    return resources.scattering_tables("converged", knobs["ms_tables"],
                                       knobs["ms_wavelength_nodes"]).orders_computed


# ------------------------------------------------------------------ plumbing
def test_scattering_tables_keep_every_resolution_field_as_given():
    """Weights and the ray quadrature reach the tables unchanged (and key their build)."""
    resources = SceneResources(SceneSpec(2.0, 300.0, (550.0,)))
    sizes = {**dataclasses.asdict(TableResolution.tiny()), "r_ground_weight": 0.5,
             "ray_quadrature": "exponential"}
    tables = resources.scattering_tables(1, sizes, 2)
    assert tables.resolution == TableResolution(**sizes)
    other = resources.scattering_tables(1, {**sizes, "r_ground_weight": 0.25}, 2)
    assert other is not tables and other.resolution.r_ground_weight == 0.25
    assert resources.scattering_tables(1, dict(sizes), 2) is tables


def test_single_order_is_the_single_scattering_path_bit_for_bit():
    """scattering_orders=1: the sky component is the code path without a plan's orders."""
    scene = st.Scene(**DAY, scattering_orders=1)
    ds = scene.render()
    assert ds.attrs["sky_scattering_orders"] == 1
    assert "scattering" not in str(scene.resources().built())
    resources = scene.resources()
    view = scene.make_view(resources)
    plan = scene.plan(resources)
    expected = sky_component(resources, view, plan.geometry, scene.wavelength_nm(),
                             Knobs.of(scene))
    got = ds["component_radiance"].sel(component="sky").values
    assert np.array_equal(np.nan_to_num(got), np.nan_to_num(expected.numpy()))


def test_plan_records_the_orders_and_the_sky_brightens():
    """Default fidelity: converged tables, the orders kept recorded; MS >= SS everywhere."""
    single = st.Scene(**DAY, scattering_orders=1).render()
    multiple = st.Scene(**DAY).render()
    orders = multiple.attrs["sky_scattering_orders"]
    assert orders >= 2 and "sky:" in multiple.attrs["scattering_orders_reason"]
    a = single["component_radiance"].sel(component="sky").values
    b = multiple["component_radiance"].sel(component="sky").values
    inside = np.isfinite(a) & (a > 0)
    assert (b[inside] >= a[inside] * (1.0 - 1e-12)).all()
    # the orders >= 2 add of the order of the Rayleigh optical depth: 5-60 % here
    ratio = b[inside].sum() / a[inside].sum()
    assert 1.05 < ratio < 1.6


def test_fast_fidelity_stays_single_and_the_tolerance_sets_the_orders():
    """'fast' means 1; a looser tolerance keeps fewer orders (never more)."""
    fast = st.Scene(**DAY, fidelity="fast").plan()
    assert fast.scattering_orders["sky"] == 1
    tight = st.Scene(**DAY, tolerance=1e-4).plan()
    loose = st.Scene(**DAY, tolerance=0.05).plan()
    assert 1 <= loose.scattering_orders["sky"] <= tight.scattering_orders["sky"]
    fixed = st.Scene(**DAY, scattering_orders=2).plan()
    assert fixed.scattering_orders == {"sky": 2, "moon": 1, "tables": 2}


@pytest.mark.parametrize("bad", [0, -1, 2.5, "all", True])
def test_bad_scattering_orders_raise(bad):
    """Anything but 'auto', 'converged' or an integer >= 1 is refused, naming the field."""
    with pytest.raises(ValueError, match="scattering_orders"):
        st.Scene(**DAY, scattering_orders=bad)


def test_toml_and_parameters_carry_the_orders():
    """[planner] scattering_orders reads back; the Dataset parameters carry it."""
    scene = st.Scene.from_dict({"planner": {"scattering_orders": 3}, "view": {"size": 8}})
    assert scene.scattering_orders == 3
    assert scene.parameters()["scattering_orders"] == 3
    assert st.Scene().parameters()["scattering_orders"] == "auto"


# ------------------------------------------------------------------ SPECTRL2
def _spectrl2_dhi(zenith_deg):
    """SPECTRL2 diffuse horizontal irradiance per unit extraterrestrial irradiance."""
    import pvlib
    from pvlib.spectrum import spectrl2

    air_mass = pvlib.atmosphere.get_relative_airmass(zenith_deg, model="kasten1966")
    out = spectrl2(apparent_zenith=zenith_deg, aoi=zenith_deg, surface_tilt=0.0,
                   ground_albedo=0.0, surface_pressure=101325.0, relative_airmass=air_mass,
                   precipitable_water=0.0, ozone=OZONE_DU / 1000.0,
                   aerosol_turbidity_500nm=AOD_500, dayofyear=np.full(zenith_deg.shape, 172),
                   alpha=ALPHA)
    keep = (out["wavelength"] >= 400.0) & (out["wavelength"] <= 685.0)
    return out["wavelength"][keep], (out["dhi"] / out["dni_extra"]).T[:, keep]


class _GivenAtmosphere(SceneResources):
    """Resources whose atmosphere is given (SPECTRL2's AOD and Angstrom exponent)."""

    def __init__(self, spec, atmosphere):
        super().__init__(spec)
        self._given = atmosphere

    @property
    def atmosphere(self):
        return self._get("atmosphere", lambda: self._given)


def _scene_dhi(resources, wavelength, sun_zenith_deg, orders):
    """Hemisphere integral of the scene's sky table, cos-weighted (wavelength,) [1]."""
    from skytorch.spectrum import solar_irradiance

    x, w = np.polynomial.legendre.leggauss(32)
    mu = torch.tensor(0.5 * (x + 1.0))
    weight = torch.tensor(0.5 * w) * mu * (2.0 * math.pi / 128)
    zenith, azimuth = torch.meshgrid(torch.acos(mu), torch.arange(128, dtype=torch.float64)
                                     * (2.0 * math.pi / 128), indexing="ij")
    geometry = types.SimpleNamespace(sun_altitude_deg=90.0 - sun_zenith_deg)
    table = sky_table(resources, geometry, _knobs(orders), wavelength) / solar_irradiance(
        wavelength)
    return (_lookup(table, zenith, azimuth) * weight[:, None, None]).sum((0, 1)).numpy()


@pytest.fixture(scope="module")
def dhi_ratios():
    from skytorch.atmosphere import Atmosphere

    zenith = np.array([30.0, 60.0])
    wavelength, reference = _spectrl2_dhi(zenith)
    atm = Atmosphere.earth(aerosol_optical_depth=AOD_500 * (550.0 / 500.0) ** -ALPHA,
                           angstrom_alpha=ALPHA, ozone_du=OZONE_DU)
    resources = _GivenAtmosphere(SceneSpec(2.0, OZONE_DU, tuple(float(v) for v in wavelength)),
                                 atm)
    wl = torch.tensor(wavelength, dtype=torch.float64)
    n = _converged_orders(resources)
    return {orders: np.stack([_scene_dhi(resources, wl, z, orders) for z in zenith])
            / reference for orders in (None, n)}


def test_multiple_scattering_raises_the_diffuse_irradiance_past_single(dhi_ratios):
    """Single scattering is below SPECTRL2 (0.70-0.99); the converged sky is above it."""
    single, multiple = dhi_ratios[None], dhi_ratios[max(k for k in dhi_ratios if k)]
    assert (single < 1.0).all() and (multiple > single).all()
    # at 400 nm, where the Rayleigh optical depth is 0.36, the converged sky is closer
    assert (np.abs(multiple[:, 0] - 1.0) < np.abs(single[:, 0] - 1.0)).all()


@pytest.mark.xfail(strict=True, reason="measured skytorch/SPECTRL2 diffuse horizontal "
                   "irradiance 1.06-1.16 (Sun 30 deg) and 1.12-1.19 (Sun 60 deg) over "
                   "400-685 nm with the default preset's tables of 2026-12-07 (12 view "
                   "nodes per half, 8 x 2 sphere directions, exponential ray quadrature; "
                   "1.06-1.15 and 1.14-1.19 with 8 view nodes and 4 x 1 directions, "
                   "1.06-1.16 and 1.14-1.21 with the trapezoid; "
                   "1.03-1.15 and 1.07-1.17 with the "
                   "reference preset and its final gather); the issue asks 10 %. With "
                   "SPECTRL2's own aerosol (albedo 0.945 exp(-0.095 ln^2), HG g 0.65): "
                   "1.01-1.10 at 440-668 nm (tested), 1.08-1.13 at 400-430 nm (5 radii), "
                   "where SPECTRL2's molecular diffuse light is 8-10 % below DISORT's at "
                   "400 nm (tested)")
def test_diffuse_irradiance_against_spectrl2_within_10_percent(dhi_ratios):
    """Issue 14: the day sky's diffuse horizontal irradiance within 10 % of SPECTRL2."""
    multiple = dhi_ratios[max(k for k in dhi_ratios if k)]
    assert (np.abs(multiple - 1.0) < 10 * PERCENT).all()


#: SPECTRL2's aerosol (Bird & Riordan 1986, eqs. 3-11 to 3-16; pvlib's defaults): single-
#: scattering albedo 0.945 at 400 nm falling as exp(-0.095 ln^2(lambda / 400 nm)), and
#: the asymmetry factor 0.65 of its forward-scattered fraction
SPECTRL2_OMEGA_400, SPECTRL2_OMEGA_PRIME, SPECTRL2_ASYMMETRY = 0.945, 0.095, 0.65
#: wavelength groups [nm] of the comparison with SPECTRL2's aerosol, each with one albedo
SPECTRL2_GROUPS = ((435.0, 475.0), (475.0, 545.0), (545.0, 615.0), (615.0, 686.0))


def _spectrl2_albedo(wavelength_nm):
    return SPECTRL2_OMEGA_400 * np.exp(-SPECTRL2_OMEGA_PRIME
                                       * np.log(np.asarray(wavelength_nm) / 400.0) ** 2)


@pytest.fixture(scope="module")
def dhi_ratios_spectrl2_aerosol():
    """Ratio of the diffuse horizontal irradiance to SPECTRL2's, with its own aerosol.

    Henyey-Greenstein g = 0.65 and SPECTRL2's albedo at each group's middle (within 0.004
    of its value at every wavelength of the group), 440-685 nm, Sun 30 and 60 deg.
    """
    from skytorch.atmosphere import Atmosphere

    zenith = np.array([30.0, 60.0])
    wavelength, reference = _spectrl2_dhi(zenith)
    ratios = []
    for low, high in SPECTRL2_GROUPS:
        keep = (wavelength >= low) & (wavelength < high)
        omega = float(_spectrl2_albedo(0.5 * (low + high)))
        assert np.abs(_spectrl2_albedo(wavelength[keep]) - omega).max() < 0.004
        atm = Atmosphere.earth(aerosol_optical_depth=AOD_500 * (550.0 / 500.0) ** -ALPHA,
                               angstrom_alpha=ALPHA, ozone_du=OZONE_DU,
                               aerosol_single_scattering_albedo=omega,
                               aerosol_asymmetry=SPECTRL2_ASYMMETRY,
                               aerosol_phase_model="henyeygreenstein1941")
        group = tuple(float(v) for v in wavelength[keep])
        resources = _GivenAtmosphere(SceneSpec(2.0, OZONE_DU, group), atm)
        wl = torch.tensor(group, dtype=torch.float64)
        n = _converged_orders(resources)
        ratios.append(np.stack([_scene_dhi(resources, wl, z, n) for z in zenith])
                      / reference[:, keep])
    return np.concatenate(ratios, axis=1)


@pytest.mark.slow
def test_diffuse_irradiance_with_spectrl2_aerosol_within_10_percent(dhi_ratios_spectrl2_aerosol):
    """With SPECTRL2's own aerosol optics, 440-685 nm: within the issue's 10 %.

    Measured 1.01-1.07 (Sun 30 deg) and 1.02-1.09 (Sun 60 deg) at SPECTRL2's wavelengths
    440-668 nm with the default preset's tables of 2026-12-07 (12 view nodes per half,
    8 x 2 sphere directions, exponential ray quadrature; 1.01-1.06 and 1.03-1.09 with 8 view
    nodes and 4 x 1 directions, 1.01-1.07 and 1.03-1.10 with the trapezoid, 1.02-1.06 and
    1.04-1.09 with 5 radii); at
    400-430 nm 1.08-1.13 with 5 radii (1.100 at 430 nm, Sun 60 deg), where SPECTRL2's
    molecular diffuse light falls below DISORT's (next test). With the default aerosol
    (albedo 0.9, Cornette-Shanks g = 0.8) 1.06-1.16 and 1.12-1.19 (strict xfail above).
    """
    ratio = dhi_ratios_spectrl2_aerosol
    assert (np.abs(ratio - 1.0) < 10 * PERCENT).all(), ratio


def test_spectrl2_rayleigh_diffuse_below_disort_at_400_nm():
    """SPECTRL2's own diffuse irradiance of a molecular atmosphere against DISORT.

    Why 400-420 nm stay above 10 %: without aerosol and ozone SPECTRL2's diffuse
    horizontal irradiance is 0.90 / 0.92 of DISORT's (64 streams, the reference table of
    tests/test_ms_disort.py) at 400 nm and 0.97 at 550 nm (Sun 30 / 60 deg), while the two
    direct beams agree within 0.7 %: its Rayleigh term, half of the light removed from
    the beam, has no higher orders. skytorch's diffuse flux is within 1.5 % of DISORT
    there (tests/test_ms_disort.py).
    """
    import pvlib
    import xarray as xr
    from pvlib.spectrum import spectrl2

    table = Path(__file__).parent / "data" / "ms_reference" / "disort_sky.nc"
    with xr.open_dataset(table) as ds:
        disort = ds.sel(aod=0.0).load()
    zenith = disort.sun_zenith.values
    air_mass = pvlib.atmosphere.get_relative_airmass(zenith, model="kasten1966")
    out = spectrl2(apparent_zenith=zenith, aoi=zenith, surface_tilt=0.0, ground_albedo=0.0,
                   surface_pressure=101325.0, relative_airmass=air_mass,
                   precipitable_water=0.0, ozone=0.0, aerosol_turbidity_500nm=1e-9,
                   dayofyear=np.full(zenith.shape, 172), alpha=ALPHA)
    for wavelength, low, high in ((400.0, 0.88, 0.94), (550.0, 0.95, 0.99)):
        i = int(np.argmin(np.abs(out["wavelength"] - wavelength)))
        direct = out["dni"][i] / out["dni_extra"][i] * np.cos(np.radians(zenith))
        assert np.allclose(direct, disort.direct_down.sel(wavelength=wavelength).values,
                           rtol=0.01)
        ratio = (out["dhi"][i] / out["dni_extra"][i]
                 / disort.diffuse_down_streams_64.sel(wavelength=wavelength).values)
        assert ((ratio > low) & (ratio < high)).all(), (wavelength, ratio)


# ------------------------------------------------------------------ moonlit sky
#: (turbidity, phase angle, view zenith, azimuth from the Moon) [-, deg, deg, deg]; the
#: Moon at zenith 30 deg (docs/moon.md's single-scattering table)
KS_CASES = ((1, 10, 0, 0), (1, 10, 60, 180), (1, 10, 85, 90), (2, 10, 0, 0),
            (2, 10, 30, 180), (2, 10, 60, 180), (2, 10, 85, 90), (2, 90, 0, 0),
            (4, 10, 0, 0), (4, 10, 60, 180))


@pytest.fixture(scope="module")
def moonlit_against_ks():
    """V [mag arcsec^-2] of single, multiple scattering and K&S for KS_CASES."""
    from skytorch.moon import sky

    wl = torch.tensor(V_GRID_NM, dtype=torch.float64)
    rows = []
    for turbidity in (1, 2, 4):
        resources = SceneResources(SceneSpec(float(turbidity), 300.0, V_GRID_NM))
        k = float(sky.extinction_coefficient_v(resources.atmosphere))
        n = _converged_orders(resources)
        for t, alpha, z, daz in KS_CASES:
            if t != turbidity:
                continue
            g = types.SimpleNamespace(phase_angle_rad=alpha * DEGREE, moon_altitude_deg=60.0,
                                      moon_distance_m=MEAN_EARTH_MOON_DISTANCE_M)
            direction = (torch.tensor([z * DEGREE], dtype=torch.float64),
                         torch.tensor([daz * DEGREE], dtype=torch.float64))
            v = [float(sky.radiance_to_mag_arcsec2(
                _lookup(moon_table(resources, g, _knobs(o), wl), *direction), wl)[0])
                for o in (None, n)]
            zm, zv = 30.0 * DEGREE, z * DEGREE
            rho = math.acos(math.cos(zm) * math.cos(zv)
                            + math.sin(zm) * math.sin(zv) * math.cos(daz * DEGREE))
            ks = float(sky.nanolambert_to_mag_arcsec2(sky.moonlit_sky_ks1991(
                torch.tensor(alpha * DEGREE), torch.tensor(rho), torch.tensor(zm),
                torch.tensor(zv), k)))
            rows.append((t, v[0], v[1], ks))
    return np.array(rows)


def test_moonlit_multiple_scattering_is_brighter_and_nearer_ks1991(moonlit_against_ks):
    """MS brighter than SS everywhere; for turbidity 2 nearer K&S at every point."""
    t, single, multiple, ks = moonlit_against_ks.T
    assert (multiple < single).all()
    two = t == 2
    assert (np.abs(multiple - ks)[two] < np.abs(single - ks)[two]).all()


@pytest.mark.xfail(strict=True, reason="measured MS - K&S: +0.82, +0.20, -0.33 (turbidity "
                   "1), +0.20, +0.57, +0.48, +0.23, +0.22 (2), -0.30, +0.51 mag (4) with "
                   "the default preset's tables of 2026-12-07 (12 view nodes per half, 8 x 2 "
                   "sphere directions, exponential ray quadrature; within 0.04 mag of the "
                   "tables before and of 5 radii before 2026-12-06); single "
                   "scattering -0.09 to +1.38 mag")
def test_moonlit_sky_within_ks1991_accuracy(moonlit_against_ks):
    """K&S's own accuracy, 0.2 mag (8-23 %), at every point."""
    _, _, multiple, ks = moonlit_against_ks.T
    assert (np.abs(multiple - ks) < 0.2 * MAG).all()


#: ESO SkyCalc 1.4.3 (the scattered-moonlight model of Jones et al. 2013, A&A 560, A91;
#: Noll et al. 2012, A&A 543, A92), Paranal, object at the zenith, Moon 45 deg up and 45 deg
#: from it at its mean distance, 130 sfu: V = 18.01 mag arcsec^-2 with the Sun and Moon 180
#: deg apart (full Moon), 21.83 with them 0 deg apart (no moonlight), all other components the
#: same (web outputs stored in github.com/sdss/lvmetc_lco_script, database/sky/readme_14.txt
#: and readme_0.txt, commit 70eb5a80): the scattered moonlight alone, V [mag arcsec^-2]
SKYCALC_FULL_MOON_V, SKYCALC_NEW_MOON_V = 18.01, 21.83
#: SkyCalc's inputs that skytorch can take (ESO Sky Background package 1.0.0, 2018:
#: config/skymodel_etc.par and src/sm_skyemcomp.c): observer at 2640 m, aerosol extinction
#: of Patat et al. 2011 above it, k = 0.014 mag (lambda / 1 um)^-1.38 with a 1.2 km scale
#: height, single-scattering albedo 0.97, asymmetry of its Mie table 0.68, ozone 258 DU,
#: ground of the Atacama soil (Sutter et al.) about 0.12 in its multiple-scattering table
SKYCALC_SITE_M, SKYCALC_AEROSOL_K_MAG, SKYCALC_AEROSOL_ALPHA = 2640.0, 0.014, 1.38
SKYCALC_AEROSOL_SCALE_M, SKYCALC_SSA, SKYCALC_G, SKYCALC_OZONE_DU = 1200.0, 0.97, 0.68, 258.0
SKYCALC_GROUND_ALBEDO = 0.12


def _skycalc_case_v():
    """Return the moonlit zenith V [mag arcsec^-2] of SkyCalc's full-Moon case (1, N orders)."""
    from skytorch.atmosphere import Atmosphere
    from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
    from skytorch.moon import sky

    tau_site = 0.4 * math.log(10.0) * SKYCALC_AEROSOL_K_MAG * 0.55 ** -SKYCALC_AEROSOL_ALPHA
    atmosphere = Atmosphere.earth(
        aerosol_optical_depth=tau_site / math.exp(-SKYCALC_SITE_M / SKYCALC_AEROSOL_SCALE_M),
        angstrom_alpha=SKYCALC_AEROSOL_ALPHA, ozone_du=SKYCALC_OZONE_DU,
        aerosol_scale_height_m=SKYCALC_AEROSOL_SCALE_M,
        aerosol_single_scattering_albedo=SKYCALC_SSA, aerosol_asymmetry=SKYCALC_G,
        aerosol_phase_model="henyeygreenstein1941")
    fine = torch.tensor(V_GRID_NM, dtype=torch.float64)
    nodes = torch.linspace(fine[0], fine[-1], 6, dtype=torch.float64)
    tables = precompute_scattering(atmosphere, nodes, ground_albedo=SKYCALC_GROUND_ALBEDO,
                                   scattering_orders="converged",
                                   resolution=TableResolution(**FIDELITY["default"]["ms_tables"]))
    zero, moon_zenith = (torch.tensor(x, dtype=torch.float64) for x in (0.0, 45.0 * DEGREE))
    args = (atmosphere, zero, moon_zenith, zero, zero)
    single = sky.moonlit_sky_single_scattering(*args, fine, altitude_m=SKYCALC_SITE_M)
    ratio = (sky.moonlit_sky_multiple_scattering(*args[:1], tables, *args[1:],
                                                  altitude_m=SKYCALC_SITE_M)
             / sky.moonlit_sky_single_scattering(*args, nodes, altitude_m=SKYCALC_SITE_M))
    ratio = torch.from_numpy(np.interp(fine.numpy(), nodes.numpy(), ratio.numpy()))
    return [float(sky.radiance_to_mag_arcsec2(x.reshape(1, -1), fine)[0])
            for x in (single, single * ratio)]


@pytest.mark.xfail(strict=True, reason="measured 2026-12-06 and 2026-12-07 (exponential ray "
                   "quadrature): skytorch 18.49 (18.50 with the default preset's tables of "
                   "2026-12-07 09:00 UTC; single scattering "
                   "18.83) against SkyCalc's 18.04, 0.45 mag fainter: SkyCalc's Moon at phase "
                   "angle 0 is 0.25 mag brighter (ROLO divided by 0.87 after Velikodsky et al. "
                   "2011, opposition surge extrapolated to 0 deg) and its Mie table scatters "
                   "1.91 at 45 deg against Henyey-Greenstein's 1.52 (docs/moon.md)")
def test_moonlit_sky_against_eso_skycalc():
    """Jones et al. 2013's model (ESO SkyCalc) within its own accuracy, 20 % (0.2 mag)."""
    moonlight = -2.5 * math.log10(10.0 ** (-0.4 * SKYCALC_FULL_MOON_V)
                                  - 10.0 ** (-0.4 * SKYCALC_NEW_MOON_V))
    single, multiple = _skycalc_case_v()
    assert single > multiple > moonlight  # the orders >= 2 add light; SkyCalc is brighter
    assert abs(multiple - moonlight) < 0.2 * MAG


# ------------------------------------------------------------------ twilight
def test_zenith_twilight_falls_and_multiple_scattering_dominates():
    """Zenith brightness falls with the Sun's depression; orders >= 2 dominate at -8 deg.

    At -8 deg the whole zenith sky is 5-20 times the single scattering in V, the span of
    the Monte-Carlo reference at the zenith with the Sun at 98 deg (tests/data/ms_reference/
    montecarlo_sky.nc: 6.5 / 7.6 at 550 nm, 17.1 / 17.9 at 400 nm, molecules without / with
    aerosol; Patat et al. 2006: the deep twilight is multiply scattered). Measured 8.9 with
    the default preset's tables (8 radii; above 10 with the 5 radii of before, whose
    twilight was 27-36 % off the Monte-Carlo, docs/scene.md).
    """
    from skytorch.moon.sky import radiance_to_mag_arcsec2

    wl = torch.tensor(V_GRID_NM[::2], dtype=torch.float64)
    resources = SceneResources(SceneSpec(2.0, 300.0, tuple(wl.tolist())))
    n = _converged_orders(resources)
    zenith = (torch.zeros(1, dtype=torch.float64),) * 2
    values = {}
    for orders in (None, n):
        radiance = [_lookup(sky_table(resources, types.SimpleNamespace(sun_altitude_deg=-d),
                                      _knobs(orders), wl), *zenith)
                    for d in (0.0, 2.0, 4.0, 6.0, 8.0, 10.0)]
        values[orders] = torch.cat(radiance).sum(-1)
    multiple = values[n]
    assert (torch.diff(multiple) < 0).all()
    assert 5.0 < float(multiple[4] / values[None][4]) < 20.0
    v = radiance_to_mag_arcsec2(multiple[:1, None] * torch.ones(1, wl.numel()), wl)
    assert torch.isfinite(v).all()


# ------------------------------------------------------------------ experiment
@pytest.mark.slow
def test_accuracy_cost_experiment_quick(tmp_path):
    """The experiment runs in quick mode; more wavelength nodes help the day sky."""
    import subprocess
    import sys
    from pathlib import Path

    from skytorch.dataset import open_dataset

    root = Path(__file__).resolve().parents[1]
    subprocess.run([sys.executable, str(root / "experiments" / "scene_ms_accuracy_cost.py"),
                    "--quick", "--output-dir", str(tmp_path)], check=True, cwd=root)
    ds = open_dataset(tmp_path / "scene_ms_accuracy_cost.nc")
    day = ds["max_relative_error"].sel(sun_zenith=60.0).values
    assert day[1] < day[0]
    assert (tmp_path / "scene_ms_accuracy_cost.png").stat().st_size > 10_000


# ------------------------------------------------------------------ final gather
def test_final_gather_correction_of_the_reference_preset():
    """The reference preset corrects the looked-up orders >= 2 by their final gather.

    A hazy sky (aerosol optical depth 0.6 at 550 nm, Henyey-Greenstein g 0.7), Sun at
    30 deg, the reference preset's knobs on the preset's coarse tables at two wavelengths:
    the ratio gathered / looked-up on the 12 x 13 nodes, interpolated to the sky table's
    nodes, against the gather computed at those nodes directly (views 10-80 deg from the
    zenith, 0-180 deg from the Sun): within 8 % (measured 1.8 %), where the looked-up
    orders are off by up to 63 %; and the plan records the correction.
    """
    from skytorch.atmosphere import Atmosphere
    from skytorch.atmosphere.final_gather import higher_orders_gathered
    from skytorch.scene.render import higher_orders

    atm = Atmosphere.earth(aerosol_phase_model="henyeygreenstein1941",
                           aerosol_optical_depth=0.6, aerosol_asymmetry=0.7,
                           ozone_du=OZONE_DU)
    wavelength = (450.0, 650.0)
    resources = _GivenAtmosphere(SceneSpec(2.0, OZONE_DU, wavelength), atm)
    knobs = _knobs(orders=6, fidelity="reference")
    without = Knobs({**FIDELITY["reference"], "ms_final_gather": None}, torch.float64, None,
                    0.0, 0.0, 0.0, scattering_orders=knobs.scattering_orders)
    zenith = torch.deg2rad(torch.tensor([10.0, 45.0, 80.0], dtype=torch.float64))[:, None]
    azimuth = torch.deg2rad(torch.tensor([0.0, 60.0, 120.0, 180.0], dtype=torch.float64))
    zenith, azimuth = torch.broadcast_tensors(zenith, azimuth[None, :])
    wl = torch.tensor(wavelength, dtype=torch.float64)
    sun = math.radians(30.0)
    corrected = higher_orders(resources, knobs, sun, zenith, azimuth, wl, 6)
    looked_up = higher_orders(resources, without, sun, zenith, azimuth, wl, 6)
    tables = resources.scattering_tables("converged", FIDELITY["reference"]["ms_tables"],
                                         FIDELITY["reference"]["ms_wavelength_nodes"])
    direct = higher_orders_gathered(tables, atm, torch.tensor(0.0, dtype=torch.float64),
                                    zenith, azimuth, torch.full_like(zenith, sun),
                                    scattering_orders=6)
    error = (corrected / direct - 1.0).abs()
    smear = (looked_up / direct - 1.0).abs()
    assert float(error.max()) < 0.08, error
    assert float(smear.max()) > 2.0 * float(error.max())
    plan = st.Scene(**DAY, fidelity="reference").plan()
    assert "final gather" in plan.scattering_reason
    assert "final gather" not in st.Scene(**DAY).plan().scattering_reason


# ------------------------------------------------------------------ ground albedo
#: full Moon over Paranal (2635 m) the night of 2026-01-03 (phase angle 6 deg, Moon 36 deg up)
PARANAL_MOON = {"time": "2026-01-03T04:00", "lat_deg": -24.6, "lon_deg": -70.4,
                "elevation_m": 2635.0, "size": 16}


def test_ground_albedo_is_checked_and_needs_higher_orders():
    """Out of [0, 1], with single scattering, or with a solar eclipse in sight: ValueError."""
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match="ground_albedo"):
            st.Scene(**DAY, ground_albedo=bad)
    with pytest.raises(TypeError, match="ground_albedo"):
        st.Scene(**DAY, ground_albedo="snow")
    with pytest.raises(ValueError, match="ground_albedo=0.3 needs the orders"):
        st.Scene(**DAY, ground_albedo=0.3, scattering_orders=1)
    with pytest.raises(ValueError, match="ground_albedo=0.3 needs the orders"):
        st.Scene(**DAY, ground_albedo=0.3, fidelity="fast")
    st.Scene(**DAY, ground_albedo=0.3, fidelity="fast", scattering_orders="converged")
    eclipse = st.Scene(time="2026-08-12T18:29:18", lat_deg=42.34, lon_deg=-3.70,
                       elevation_m=850.0, size=8, ground_albedo=0.3)
    with pytest.raises(ValueError, match="solar-eclipse sky"):
        eclipse.plan()


def test_white_ground_in_float32_is_finite_and_brightest():
    """Albedo 1 in a float32 day scene: finite, and brighter than albedo 0 everywhere."""
    skies = []
    for albedo in (0.0, 1.0):
        ds = st.Scene(**DAY, ground_albedo=albedo, dtype=torch.float32).render()
        sky = ds["component_radiance"].sel(component="sky").values
        skies.append(sky[np.isfinite(sky)])
    black, white = skies
    assert black.size > 0 and black.shape == white.shape
    assert np.isfinite(white).all() and (white >= black).all() and (white > black).any()


def test_ground_albedo_enters_the_sky_through_the_tables():
    """The moonlit sky over a grey ground: brighter, as the moon module's function says.

    The render's moonlit sky against ``moonlit_sky_multiple_scattering`` on tables of that
    albedo.
    """
    from skytorch.moon import sky
    from skytorch.scene.render import Knobs

    black = st.Scene(**PARANAL_MOON)
    grey = st.Scene(**PARANAL_MOON, ground_albedo=0.3)
    assert grey.resources().spec.ground_albedo == 0.3
    plan = grey.plan()
    ds_black, ds_grey = black.render(), grey.render(plan)
    assert ds_grey.attrs["parameter_ground_albedo"] == 0.3
    moon_black = ds_black["component_radiance"].sel(component="moon").values
    moon_grey = ds_grey["component_radiance"].sel(component="moon").values
    up = np.isfinite(moon_black) & (moon_black > 0)
    ratio = moon_grey[up] / moon_black[up]
    # never darker; over most of the sky a 0.3 ground adds 10-40 % at 2635 m (the orders
    # >= 2 are 10-30 % of the black ground's sky; in the aureole single scattering rules)
    assert (ratio >= 1.0).all() and (ratio < 1.6).all(), (ratio.min(), ratio.max())
    assert 1.1 < np.median(ratio) < 1.4, np.median(ratio)
    # the render's moonlit sky at the zenith node against the moon module's function on
    # tables built with the albedo (the scene's own tables, the function's own
    # single scattering and lunar irradiance)
    resources = grey.resources()
    knobs = Knobs.of(grey, plan)
    tables = resources.scattering_tables(knobs.scattering_orders["tables"], knobs["ms_tables"],
                                         knobs["ms_wavelength_nodes"])
    assert float(tables.ground_albedo.max()) == 0.3
    g = plan.geometry
    zero = torch.zeros(1, dtype=torch.float64)
    wl = tables.wavelength_nm
    expected = sky.moonlit_sky_multiple_scattering(
        resources.atmosphere, tables, torch.tensor(g.phase_angle_rad, dtype=torch.float64),
        torch.tensor(math.radians(90.0 - g.moon_altitude_deg), dtype=torch.float64), zero,
        zero, distance_m=g.moon_distance_m, altitude_m=2635.0,
        scattering_orders=plan.scattering_orders["moon"])
    got = _lookup(moon_table(resources, g, knobs, wl), zero, zero)
    assert torch.allclose(got, expected, rtol=0.02), (got / expected)


# ------------------------------------------------------------------ stratospheric layer
def test_stratospheric_layer_of_a_scene():
    """The layer asked for is the atmosphere's, recorded, and brightens the deep twilight.

    Its vertical optical depth at 550 nm is the one given (the sulfate layer's Mie optics
    are normalised there); the zenith at Paranal with the Sun 7.9 deg down is brighter
    with the quiet stratosphere's 0.0044 (measured 0.13 mag; 0.08–0.18 mag at Sun 96–99°
    in experiments/twilight_zenith_profiles.py).
    """
    twilight = {"time": "2024-04-07T23:05", "lat_deg": -24.627, "lon_deg": -70.404,
                "elevation_m": 2635.0, "view": "directions",
                "directions": {"altitude_deg": [90.0], "azimuth_deg": [0.0]}}
    clear, layered = (st.Scene(**twilight, stratospheric_aod=aod) for aod in (0.0, 0.0044))
    wavelength = torch.tensor([550.0], dtype=torch.float64)
    depth = [float(scene.resources().atmosphere.optical_depth(wavelength))
             for scene in (clear, layered)]
    assert depth[1] - depth[0] == pytest.approx(0.0044, abs=1e-6)
    skies = [scene.render() for scene in (clear, layered)]
    assert skies[1].attrs["parameter_stratospheric_aod"] == 0.0044
    zenith = [float(ds["component_v_mag_arcsec2"].sel(component="sky").values.ravel()[0])
              for ds in skies]
    assert 0.05 * MAG < zenith[0] - zenith[1] < 0.3 * MAG
    for bad in (-0.1, 2.0, float("nan")):
        with pytest.raises(ValueError, match="stratospheric_aod"):
            st.Scene(**DAY, stratospheric_aod=bad)
    with pytest.raises(TypeError, match="stratospheric_aod"):
        st.Scene(**DAY, stratospheric_aod="background")
    scene = st.Scene.from_dict({"time": DAY["time"], "view": {"size": DAY["size"]},
                                "observer": {"lat_deg": 48.85, "lon_deg": 2.35},
                                "atmosphere": {"stratospheric_aod": 0.007}})
    assert scene.stratospheric_aod == 0.007
