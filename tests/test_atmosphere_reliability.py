"""Reliability of the atmosphere package.

Batched atmospheres on every path, thread safety, gradients at hard cases against finite
differences, table provenance checks, the verified disk cache, the ozone range and the docstring
examples.
"""

from __future__ import annotations

import doctest
import importlib
import math
import pkgutil
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import torch
from torch.autograd import gradcheck

import skytorch.atmosphere
from skytorch._cache import record_path, verify
from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere import refraction as refraction_module
from skytorch.atmosphere.ozone import OZONE_RANGE_NM, ozone_cross_section
from skytorch.atmosphere.tables import (
    TransmittanceTable,
    cached_transmittance_table,
    table_key,
)
from skytorch.constants import PERCENT
from skytorch.dataset import open_dataset, to_netcdf

WAVELENGTH = torch.tensor([440.0, 550.0, 680.0], dtype=torch.float64)
DEGREE = math.pi / 180.0
ARCSECOND = DEGREE / 3600.0


def _f64(*values):
    return torch.tensor(values, dtype=torch.float64)


# --- batched atmospheres on every path --------------------------------------------------------


@pytest.mark.parametrize("method", ["gauss", "rk4"])
def test_refracted_optical_depth_of_a_batched_atmosphere_matches_each_member(method):
    # a turbidity x ozone sweep with refraction: every member equals its own unbatched
    # atmosphere (independent evaluation), for a scalar ray and for rays of another shape
    turbidity = _f64(2.0, 4.0)[:, None]
    ozone = _f64(250.0, 350.0)[None, :]
    batched = Atmosphere.earth(turbidity=turbidity, ozone_du=ozone)
    zenith = _f64(60.0, 88.0) * DEGREE
    # (coarse RK4 steps: the comparison is member against member, not against truth)
    options = {"step_m": 30e3, "max_dh_m": 5e3} if method == "rk4" else {}
    for rays in (zenith[1], zenith[:, None, None]):
        tau = batched.optical_depth(WAVELENGTH, rays, 500.0, refraction=True, method=method,
                                    **options)
        shape = torch.broadcast_shapes(rays.shape, (2, 2))
        assert tau.shape == shape + (3,)
        for i in range(2):
            for j in range(2):
                member = Atmosphere.earth(turbidity=float(turbidity[i, 0]),
                                          ozone_du=float(ozone[0, j]))
                expected = member.optical_depth(WAVELENGTH, rays, 500.0, refraction=True,
                                                method=method, **options)
                got = tau[..., i, j, :]
                assert torch.allclose(got.reshape(-1, 3), expected.reshape(-1, 3),
                                      rtol=1e-12, atol=0.0)


def test_batched_refraction_angle_and_grazing_rays():
    pressure = _f64(90_000.0, 101_325.0)
    batched = Atmosphere.earth(surface_pressure_pa=pressure)
    elevation = _f64(0.0, 10.0) * DEGREE
    for method in ("bouguer", "rk4"):
        angle = batched.refraction(elevation[:, None], method=method)
        assert angle.shape == (2, 2)
        for k in range(2):
            member = Atmosphere.earth(surface_pressure_pa=float(pressure[k]))
            expected = member.refraction(elevation, method=method)
            assert torch.allclose(angle[:, k], expected, rtol=1e-12, atol=0.0)
    rays = refraction_module.trace_grazing_rays(batched, impact_altitude_m=_f64(5e3),
                                                wavelength_nm=WAVELENGTH)
    assert rays["optical_depth"].shape == (2, 3)


def test_batched_sky_radiance_matches_each_member():
    turbidity = _f64(2.0, 5.0)
    batched = Atmosphere.earth(turbidity=turbidity)
    view = _f64(10.0, 80.0)[:, None] * DEGREE
    radiance = batched.sky_radiance(WAVELENGTH, view, 0.0, 40.0 * DEGREE, 1.0, n_samples=32, scattering_orders=1)
    assert radiance.shape == (2, 2, 3)
    for k in range(2):
        member = Atmosphere.earth(turbidity=float(turbidity[k]))
        expected = member.sky_radiance(WAVELENGTH, view[:, 0], 0.0, 40.0 * DEGREE, 1.0,
                                       n_samples=32, scattering_orders=1)
        assert torch.allclose(radiance[:, k], expected, rtol=1e-12, atol=0.0)


# --- thread safety -------------------------------------------------------------------------


def test_batched_atmosphere_shared_by_threads():
    # 4 threads x 200 calls on one batched Atmosphere, optical depths of rays of different
    # shapes mixed with sky radiances (which once switched a module-level mode flag of the
    # shared object): every call returns the serial result, shape and values
    atm = Atmosphere.earth(turbidity=_f64(2.0, 3.0, 4.0), ozone_du=300.0)
    shapes = [(), (3,), (5, 1), (2, 3), (4, 1, 1)]
    generator = torch.Generator().manual_seed(12)
    cases = []
    for k in range(40):
        shape = shapes[k % len(shapes)]
        zenith = torch.rand(shape, generator=generator, dtype=torch.float64) * 1.5
        cases.append(("tau", zenith))
        if k % 8 == 0:
            cases.append(("sky", zenith))

    def evaluate(case):
        kind, zenith = case
        if kind == "tau":
            return atm.optical_depth(WAVELENGTH, zenith, 100.0)
        return atm.sky_radiance(WAVELENGTH, zenith[..., None] if zenith.ndim else zenith,
                                0.0, 0.5, 0.0, n_samples=8, scattering_orders=1)

    expected = [evaluate(case) for case in cases]
    jobs = [k % len(cases) for k in range(800)]
    with ThreadPoolExecutor(max_workers=4) as pool:
        results = list(pool.map(lambda k: (k, evaluate(cases[k])), jobs))
    wrong = [k for k, value in results
             if value.shape != expected[k].shape or not torch.equal(value, expected[k])]
    assert wrong == []
    assert not hasattr(atm, "_extra_dims")


# --- gradients at hard cases against finite differences ------------------------------------------


def test_gradient_of_horizontal_straight_ray():
    # rays through the horizontal at 1 km (grazing the air below the observer) and just
    # above the horizontal at the ground: d tau / d zenith by autograd against gradcheck's
    # central differences, float64
    atm = Atmosphere.earth()
    wl = _f64(550.0)
    for altitude, zenith in ((1000.0, 90.0 * DEGREE), (1000.0, 90.5 * DEGREE),
                             (0.0, 89.99 * DEGREE)):
        z = torch.tensor(zenith, dtype=torch.float64, requires_grad=True)
        assert gradcheck(lambda z, h=altitude: atm.optical_depth(wl, z, h), (z,),
                         eps=1e-7, atol=1e-6, rtol=1e-4)


def test_gradient_of_refracted_horizon_rays():
    atm = Atmosphere.earth()
    wl = _f64(550.0)
    # refraction at the apparent horizon and at a ray that dips below the horizontal
    for elevation in (0.0, -0.3 * DEGREE):
        e = torch.tensor(elevation, dtype=torch.float64, requires_grad=True)
        assert gradcheck(lambda e: atm.refraction(e, 1000.0), (e,), eps=1e-7, atol=1e-9,
                         rtol=1e-4)
    # optical depth along the bent ray grazing below a 1 km observer's horizontal
    z = torch.tensor(90.5 * DEGREE, dtype=torch.float64, requires_grad=True)
    assert gradcheck(lambda z: atm.optical_depth(wl, z, 1000.0, refraction=True), (z,),
                     eps=1e-7, atol=1e-6, rtol=1e-4)


def test_huge_optical_depth_transmittance_is_zero_with_finite_gradient():
    # a dense aerosol layer (vertical optical depth 50 at 550 nm) seen at the horizon:
    # tau ~ 1e4, so exp(-tau) underflows to exactly 0; the gradient of the transmittance
    # is 0 (finite) and that of tau itself matches finite differences
    aod = torch.tensor(50.0, dtype=torch.float64, requires_grad=True)

    def tau(aod):
        return Atmosphere.earth(aerosol_optical_depth=aod).optical_depth(
            _f64(550.0), 90.0 * DEGREE, 0.0)

    value = tau(aod)
    assert float(value.detach()) > 1e3
    transmittance = torch.exp(-value)
    assert float(transmittance.detach()) == 0.0
    (grad,) = torch.autograd.grad(transmittance.sum(), aod)
    assert torch.isfinite(grad) and float(grad) == 0.0
    assert gradcheck(tau, (aod,), eps=1e-6, atol=1e-6, rtol=1e-6)


def test_gradients_with_respect_to_turbidity_and_ozone():
    turbidity = torch.tensor(3.0, dtype=torch.float64, requires_grad=True)
    ozone = torch.tensor(300.0, dtype=torch.float64, requires_grad=True)
    zenith = _f64(0.0, 70.0, 89.0) * DEGREE

    def straight(t, o):
        return Atmosphere.earth(turbidity=t, ozone_du=o).optical_depth(WAVELENGTH, zenith)

    def refracted(t, o):
        return Atmosphere.earth(turbidity=t, ozone_du=o).optical_depth(
            WAVELENGTH, zenith, refraction=True)

    def sky(t, o):
        return Atmosphere.earth(turbidity=t, ozone_du=o).sky_radiance(
            WAVELENGTH, zenith, 0.0, 60.0 * DEGREE, 0.0, n_samples=16, sun_steps=4, scattering_orders=1)

    # eps 1e-4: tau is linear in ozone_du, and at 89 deg (tau = 18) a 1e-6 step leaves a
    # float64 rounding error of 2e-9 in the central difference
    for function in (straight, refracted, sky):
        assert gradcheck(function, (turbidity, ozone), eps=1e-4, atol=1e-9, rtol=1e-5)


def test_rk4_backward_matches_finite_differences():
    # every method="rk4" path has a working backward pass, and its gradient is that of
    # the discrete scheme (central differences of the same scheme; coarse steps keep the
    # test short, the scheme stays smooth in its inputs)
    atm = Atmosphere.earth(refractivity_profile="exponential")
    coarse = {"method": "rk4", "step_m": 20e3, "max_dh_m": 4e3}
    e = torch.tensor([2.0 * DEGREE, 20.0 * DEGREE], dtype=torch.float64, requires_grad=True)
    assert gradcheck(lambda e: atm.refraction(e, **coarse), (e,), eps=1e-6,
                     atol=1e-10, rtol=1e-4)
    turbidity = torch.tensor(3.0, dtype=torch.float64, requires_grad=True)
    zenith = _f64(60.0, 85.0) * DEGREE

    def tau(t):
        return Atmosphere.earth(turbidity=t).optical_depth(
            _f64(550.0), zenith, refraction=True, **coarse)

    assert gradcheck(tau, (turbidity,), eps=1e-6, atol=1e-8, rtol=1e-5)
    # gradient w.r.t. the ray direction too (the step lengths depend on it)
    z = torch.tensor(80.0 * DEGREE, dtype=torch.float64, requires_grad=True)
    assert gradcheck(lambda z: atm.optical_depth(_f64(550.0), z, refraction=True, **coarse),
                     (z,), eps=1e-6, atol=1e-6, rtol=1e-4)


# --- tables: provenance and look-ups ---------------------------------------------------------------


@pytest.fixture(scope="module")
def earth():
    return Atmosphere.earth(turbidity=2.0, ozone_du=300.0)


@pytest.fixture(scope="module")
def small_table(earth):
    return TransmittanceTable.build(earth, WAVELENGTH, n_mu=32, n_r=16)


def test_table_records_what_it_was_built_for(earth, small_table):
    assert small_table.wavelength_nm.tolist() == WAVELENGTH.tolist()
    assert small_table.n_mu == 32 and small_table.x_r.shape == (16,)
    assert isinstance(small_table.atmosphere_sha256, str)
    assert len(small_table.atmosphere_sha256) == 64
    small_table.check_compatible(earth, WAVELENGTH)  # the right use passes


def test_sky_radiance_refuses_a_table_built_for_other_wavelengths(earth, small_table):
    view = _f64(20.0, 70.0) * DEGREE
    direct = earth.sky_radiance(WAVELENGTH, view, 0.0, 50.0 * DEGREE, 0.0, n_samples=32, scattering_orders=1)
    looked_up = earth.sky_radiance(WAVELENGTH, view, 0.0, 50.0 * DEGREE, 0.0, n_samples=32,
                                   table=small_table, scattering_orders=1)
    # the right table agrees with the direct integration (table interpolation, 32 x 16)
    assert float(((looked_up - direct).abs() / direct).max()) <= 2 * PERCENT
    for other in (_f64(400.0, 500.0, 600.0), _f64(440.0, 550.0), _f64(440.0, 550.0, 680.0, 700.0)):
        with pytest.raises(ValueError, match="table was built for wavelength_nm"):
            earth.sky_radiance(other, view, 0.0, 50.0 * DEGREE, 0.0, table=small_table, scattering_orders=1)


def test_sky_radiance_refuses_a_table_of_another_atmosphere(small_table):
    hazier = Atmosphere.earth(turbidity=3.0, ozone_du=300.0)
    with pytest.raises(ValueError, match="another atmosphere"):
        hazier.sky_radiance(WAVELENGTH, 0.5, 0.0, 0.5, 0.0, table=small_table, scattering_orders=1)
    with pytest.raises(TypeError, match="table"):
        hazier.sky_radiance(WAVELENGTH, 0.5, 0.0, 0.5, 0.0, table="table", scattering_orders=1)


@pytest.mark.parametrize("altitude", [-1.0, -1e-9, 100_001.0, math.nan, math.inf])
def test_table_lookups_refuse_altitudes_outside_the_table(small_table, altitude):
    with pytest.raises(ValueError, match="altitude_m"):
        small_table.optical_depth(0.5, altitude)


def test_table_lookup_shapes_checked(small_table):
    with pytest.raises(ValueError, match=r"zenith_rad \(3,\), altitude_m \(2,\)"):
        small_table.optical_depth(torch.zeros(3), torch.zeros(2))
    with pytest.raises(ValueError, match="table was built for wavelength_nm"):
        small_table.optical_depth(0.5, 0.0, wavelength_nm=_f64(500.0, 550.0, 680.0))
    # integer tensors are promoted
    value = small_table.optical_depth(torch.tensor([0, 1]), torch.tensor(0))
    assert value.dtype == torch.float64 and value.shape == (2, 3)


# --- the verified disk cache --------------------------------------------------------------------


def test_cache_never_serves_a_file_with_doubled_optical_depths(earth, tmp_path):
    good = cached_transmittance_table(earth, WAVELENGTH, n_mu=16, n_r=8, cache_dir=tmp_path)
    (path,) = tmp_path.glob("transmittance_*.nc")
    assert record_path(path).is_file()
    doubled = good.copy(deep=True)
    doubled["optical_depth"].values[:] *= 2.0  # same key, shapes and attributes
    to_netcdf(doubled, path)
    served = cached_transmittance_table(earth, WAVELENGTH, n_mu=16, n_r=8, cache_dir=tmp_path)
    assert np.array_equal(served["optical_depth"].values, good["optical_depth"].values)
    # the bad file was replaced by a verified one
    key = table_key(earth, WAVELENGTH, 16, 8, "gauss", None)
    assert verify(path, key) is None
    assert np.array_equal(open_dataset(path)["optical_depth"].values,
                          good["optical_depth"].values)


def test_cache_never_serves_a_byte_corrupted_file(earth, tmp_path):
    good = cached_transmittance_table(earth, WAVELENGTH, n_mu=16, n_r=8, cache_dir=tmp_path)
    (path,) = tmp_path.glob("transmittance_*.nc")
    original = path.read_bytes()
    key = table_key(earth, WAVELENGTH, 16, 8, "gauss", None)
    for fraction in (0.1, 0.3, 0.5, 0.7, 0.9, 0.99):
        data = bytearray(original)
        offset = int(fraction * (len(data) - 1))
        data[offset] ^= 0x01
        path.write_bytes(bytes(data))
        served = cached_transmittance_table(earth, WAVELENGTH, n_mu=16, n_r=8,
                                            cache_dir=tmp_path)
        assert np.array_equal(served["optical_depth"].values, good["optical_depth"].values)
        assert verify(path, key) is None  # replaced, verified
        original = path.read_bytes()


def test_cache_without_record_is_rebuilt(earth, tmp_path):
    cached_transmittance_table(earth, WAVELENGTH, n_mu=16, n_r=8, cache_dir=tmp_path)
    (path,) = tmp_path.glob("transmittance_*.nc")
    record_path(path).unlink()
    cached_transmittance_table(earth, WAVELENGTH, n_mu=16, n_r=8, cache_dir=tmp_path)
    assert record_path(path).is_file()


# --- ozone outside its table ---------------------------------------------------------------------


@pytest.mark.parametrize("wavelength", [200.0, 213.9, 1100.1, 1200.0])
def test_ozone_outside_its_table_is_refused(wavelength):
    with pytest.raises(ValueError, match=r"wavelength_nm must be in \[214.0, 1100.0\] nm") as info:
        ozone_cross_section(_f64(wavelength))
    assert str(wavelength) in str(info.value)
    with pytest.raises(ValueError, match="wavelength_nm"):
        Atmosphere.earth(ozone_du=300.0).optical_depth(_f64(550.0, wavelength))


def test_ozone_table_edges_and_ozone_free_atmospheres():
    low, high = OZONE_RANGE_NM
    assert torch.isfinite(ozone_cross_section(_f64(low, high))).all()
    # without ozone the cross-section is not needed: exactly zero absorption at 300 nm
    tau = Atmosphere.earth(ozone_du=0.0).optical_depth(_f64(300.0, 900.0), per_species=True)
    assert float(tau["ozone"].abs().max()) == 0.0
    assert bool((tau["rayleigh"] > 0).all())
    # (Rayleigh ~ lambda^-4: 300 nm is about (550/300)^4 = 11 times 550 nm)
    ratio = float(Atmosphere.earth(ozone_du=0.0).optical_depth(_f64(300.0), per_species=True)
                  ["rayleigh"] / Atmosphere.earth(ozone_du=0.0).optical_depth(
                      _f64(550.0), per_species=True)["rayleigh"])
    assert 11.3 * (1 - 5 * PERCENT) <= ratio <= 11.3 * (1 + 15 * PERCENT)
    assert torch.isfinite(Atmosphere.mars().optical_depth(_f64(900.0))).all()


# --- Atmosphere.earth turbidity, keywords ----------------------------------------------------------


@pytest.mark.parametrize("turbidity", [0.5, 0.999, 64.5, 1e6, 1e308, -2.0, math.nan, math.inf,
                                       torch.tensor([2.0, math.nan]),
                                       torch.tensor(1e30, dtype=torch.float32)])
def test_every_bad_turbidity_is_refused_by_name(turbidity):
    with pytest.raises(ValueError, match="turbidity") as info:
        Atmosphere.earth(turbidity=turbidity)
    assert "angstrom_beta" not in str(info.value)


@pytest.mark.parametrize("turbidity", ["2", None, True, [2.0, "x"], object()])
def test_non_numeric_turbidity_is_a_type_error(turbidity):
    if turbidity is None:  # None is the default (2) unless an aerosol depth is given
        assert float(Atmosphere.earth(turbidity=None).angstrom_beta) == pytest.approx(
            0.04608 * 2 - 0.04586)
        return
    with pytest.raises(TypeError, match="turbidity"):
        Atmosphere.earth(turbidity=turbidity)


def test_unknown_keywords_are_rejected():
    atm = Atmosphere.earth()
    with pytest.raises(TypeError, match="turbidty"):
        Atmosphere.earth(turbidty=3.0)
    with pytest.raises(TypeError, match="dust_depth"):
        Atmosphere.mars(dust_depth=0.3)
    with pytest.raises(TypeError, match="methd"):
        atm.optical_depth(WAVELENGTH, methd="gauss")
    with pytest.raises(TypeError, match="step_m"):
        atm.optical_depth(WAVELENGTH, step_m=1e3)  # straight rays have no RK4 step
    with pytest.raises(TypeError, match="n_sample"):
        atm.sky_radiance(WAVELENGTH, 0.5, n_sample=8, scattering_orders=1)
    with pytest.raises(TypeError, match="nodes"):
        atm.apparent_altitude(0.1, nodes=8)
    with pytest.raises(ValueError, match="turbidity or aerosol_optical_depth"):
        Atmosphere.earth(turbidity=3.0, aerosol_optical_depth=0.1)


@pytest.mark.parametrize("rtol", [-1e-9, 0.0, math.nan, math.inf, 2.0])
def test_bad_rtol_refused(rtol):
    with pytest.raises(ValueError, match="rtol"):
        Atmosphere.earth().optical_depth(WAVELENGTH, 0.5, method="adaptive", rtol=rtol)
    with pytest.raises(ValueError, match="rtol"):
        Atmosphere.earth().optical_depth(WAVELENGTH, 0.5, refraction=True, rtol=rtol)


def test_integer_tensors_are_promoted():
    atm = Atmosphere.earth()
    tau = atm.optical_depth(torch.tensor([440, 550]), torch.tensor(1), torch.tensor(100))
    reference = atm.optical_depth(_f64(440.0, 550.0), _f64(1.0)[0], 100.0)
    assert tau.dtype.is_floating_point and torch.allclose(tau.double(), reference)
    angle = atm.refraction(torch.tensor(0), torch.tensor(0))
    assert torch.isfinite(angle)
    assert torch.isfinite(atm.sky_radiance(torch.tensor([550]), torch.tensor(1),
                                           n_samples=8, scattering_orders=1)).all()


def test_shape_mismatches_name_the_parameters():
    atm = Atmosphere.earth(turbidity=_f64(2.0, 3.0))
    with pytest.raises(ValueError, match=r"zenith_rad \(3,\).*parameters \(2,\)"):
        atm.optical_depth(WAVELENGTH, torch.zeros(3))
    with pytest.raises(ValueError, match=r"zenith_rad \(3,\).*parameters \(2,\)"):
        atm.optical_depth(WAVELENGTH, torch.zeros(3), refraction=True)
    with pytest.raises(ValueError, match=r"apparent_altitude_rad \(3,\)"):
        atm.refraction(torch.zeros(3))
    with pytest.raises(ValueError, match=r"view_zenith_rad \(3,\)"):
        atm.sky_radiance(WAVELENGTH, torch.zeros(3), torch.zeros(4), scattering_orders=1)
    with pytest.raises(ValueError, match=r"true_altitude_rad \(4,\)"):
        atm.apparent_altitude(torch.zeros(4))


def test_wrong_object_where_an_atmosphere_is_expected():
    from skytorch.atmosphere.scattering import single_scattering_radiance
    from skytorch.atmosphere.tables import transmittance_table

    for thing in ("earth", 3.0, None, object()):
        with pytest.raises(TypeError, match="atmosphere"):
            single_scattering_radiance(thing, WAVELENGTH, 0.5)
        with pytest.raises(TypeError, match="atmosphere"):
            transmittance_table(thing, WAVELENGTH, n_mu=4, n_r=4)
        with pytest.raises(TypeError, match="atm"):
            refraction_module.refraction_angle(thing, 0.1)


# --- finite optical depths for every accepted input --------------------------------------------------


def test_extreme_accepted_parameters_give_finite_optical_depths():
    # the edges of PARAMETER_RANGES: every optical depth is a finite number (an inf once
    # came from a coefficient k = tau_vertical / H overflowing for a tiny scale height or
    # a huge column)
    from skytorch.atmosphere.model import PARAMETER_RANGES

    zenith = _f64(0.0, 89.9 * DEGREE, 90.0 * DEGREE, 91.0 * DEGREE)
    for key in ("surface_pressure_pa", "gravity_m_s2", "molar_mass_kg_mol",
                "rayleigh_scale_height_m", "aerosol_scale_height_m", "ozone_du",
                "ozone_half_width_m", "angstrom_beta"):
        low, high, inclusive, _ = PARAMETER_RANGES[key]
        for value in (low if inclusive else low * (1 + 1e-9) + 1e-300, high):
            # (ozone_temperature_k given: its default, the US 1976 temperature over the
            # tent, is outside the cross-sections' 203-293 K for a 1e7 m half width)
            atm = Atmosphere.earth(**{key: value}, ozone_temperature_k=223.0) if (
                key != "angstrom_beta") else Atmosphere(
                planet_radius_m=6.371e6, top_altitude_m=1e5, angstrom_beta=value)
            for dtype in (torch.float64, torch.float32):
                tau = atm.optical_depth(WAVELENGTH.to(dtype), zenith.to(dtype), 10.0)
                assert torch.isfinite(tau).all(), (key, value, dtype)
    # all three column parameters at their edges: p N_A / (m g) = 6e38 m^-2 exceeds the
    # float32 range, the optical depths do not
    dense = Atmosphere.earth(surface_pressure_pa=1e8, gravity_m_s2=1e-3, molar_mass_kg_mol=1e-4)
    for dtype in (torch.float64, torch.float32):
        tau = dense.optical_depth(WAVELENGTH.to(dtype), zenith.to(dtype), 10.0)
        assert torch.isfinite(tau).all(), dtype


# --- docstring examples ------------------------------------------------------------------------------


def _atmosphere_modules():
    names = ["skytorch.atmosphere"]
    names += [info.name for info in pkgutil.walk_packages(skytorch.atmosphere.__path__,
                                                            "skytorch.atmosphere.")]
    return names


@pytest.mark.parametrize("name", _atmosphere_modules())
def test_docstring_examples_run(name):
    module = importlib.import_module(name)
    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS)
    tests = finder.find(module, name)
    for test in tests:
        runner.run(test)
    assert runner.failures == 0, f"{runner.failures} failing example(s) in {name}"
    assert sum(len(test.examples) for test in tests) > 0


def test_texture_rays_tangent_ray_is_exact():
    # the ray tangent to the ground at x_mu = 1 has mu = -rho/r exactly (0 on the ground;
    # the old formula gave -1e-8 in float32, printed as -0.0)
    from skytorch.atmosphere.geometry import texture_rays

    for dtype in (torch.float32, torch.float64):
        x_r = torch.tensor([0.0, 0.3, 1.0], dtype=dtype)
        h, mu = texture_rays(x_r, torch.ones(3, dtype=dtype), 6.371e6, 6.471e6)
        r = 6.371e6 + h.double()
        expected = -torch.sqrt(1.0 - (6.371e6 / r) ** 2)
        assert float(mu[0]) == 0.0 and not math.copysign(1.0, float(mu[0])) < 0
        assert torch.allclose(mu.double(), expected, rtol=1e-5 if dtype == torch.float32
                              else 1e-12, atol=0.0)


def test_deviation_table_lookups_validate():
    from skytorch.atmosphere.refraction import DeviationTable, deviation_table, lookup_deviation

    table = DeviationTable(deviation_table(Atmosphere.earth(), 8, 8, progress=False))
    with pytest.raises(ValueError, match=r"altitude_m \(3,\), zenith_rad \(2,\)"):
        table(torch.zeros(3), torch.zeros(2))
    with pytest.raises(ValueError, match="altitude_m"):
        table(-1.0, 0.5)
    with pytest.raises(TypeError, match="dataset"):
        lookup_deviation("table", 0.0, 0.5)
    with pytest.raises(ValueError, match="scalar parameters"):
        deviation_table(Atmosphere.earth(turbidity=_f64(2.0, 3.0)), 4, 4, progress=False)
