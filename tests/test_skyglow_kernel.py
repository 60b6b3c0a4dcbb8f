"""Single-scattering skyglow kernel: emission functions, quadrature, symmetry, Walker's law."""

from __future__ import annotations

import math

import pytest
import torch
from _conditioning import well_conditioned_lstsq
from _skyglow_standin import medium as standin_medium
from _skyglow_standin import single_torch_thread  # noqa: F401
from scipy.integrate import quad

from skytorch.constants import PERCENT
from skytorch.skyglow.kernel import (
    EMISSION_FUNCTIONS,
    GARSTANG_F,
    GARSTANG_G,
    Medium,
    converged_steps,
    emission_intensity,
    kernel_radiance,
)

#: Walker (1977): zenith skyglow ∝ d^-2.5 between 10 and 50 km; tolerance of the issue
WALKER_EXPONENT = -2.5
WALKER_TOLERANCE = 0.3


@pytest.fixture(scope="module")
def medium():
    return standin_medium()


@pytest.mark.parametrize("emission, upward", [
    ("garstang1986", GARSTANG_G * (1 - GARSTANG_F) + GARSTANG_F),
    ("lambertian", 1.0),
    ("dobashi2023", 1.0),
])
def test_emission_functions_carry_their_upward_flux(emission, upward):
    # independent reference: adaptive quadrature of I(ψ) over the upper hemisphere
    def integrand(psi):
        value = emission_intensity(torch.tensor(math.cos(psi), dtype=torch.float64), emission)
        return float(value) * 2 * math.pi * math.sin(psi)

    total, _ = quad(integrand, 0.0, math.pi / 2, limit=200)
    assert total == pytest.approx(upward, rel=1e-6)
    below = emission_intensity(torch.tensor([-0.5, 0.0]), emission)
    assert torch.all(below == 0)


def test_unknown_emission_names_the_choices(medium):
    with pytest.raises(ValueError, match="lambertian"):
        kernel_radiance(medium, 0.0, 1.0, 1e3, emission="isotropic")


def test_optical_depth_table_matches_atmosphere_column():
    from skytorch.atmosphere import Atmosphere
    from skytorch.spectrum import wavelength_grid

    atm = Atmosphere.earth(turbidity=2.0)
    wl = wavelength_grid("rgb")
    m = Medium(atm, wl)
    zenith = torch.tensor([0.0, 1.0, 1.4], dtype=torch.float64)
    reference = atm.optical_depth(wl, zenith_rad=zenith[:, None])
    ours = m.optical_depth_to_top(torch.full_like(zenith, atm.planet_radius_m), torch.cos(zenith))
    assert torch.allclose(ours, reference.reshape(ours.shape), rtol=0.2 * PERCENT)


def _flat_constant_medium(beta, top_m):
    """Flat (R = 1e9 m), non-extinguishing, constant-scattering medium, isotropic phase."""

    class Constant:
        planet_radius_m = 1e9
        top_altitude_m = top_m

        def scattering_coefficients(self, altitude_m, wavelength_nm):
            h = torch.as_tensor(altitude_m, dtype=torch.float64)[..., None]
            return {"rayleigh": beta * torch.ones(*h.shape[:-1], len(wavelength_nm),
                                                  dtype=torch.float64)}

        def extinction_coefficient(self, altitude_m, wavelength_nm):
            return 0.0 * self.scattering_coefficients(altitude_m, wavelength_nm)["rayleigh"]

    return Medium(Constant(), torch.tensor([550.0]),
                  phase_functions={"rayleigh": lambda c: torch.full_like(c, 1 / (4 * math.pi))})


@pytest.mark.parametrize("distance", [50.0, 2_000.0, 30_000.0])
def test_kernel_matches_closed_form_for_constant_medium(distance):
    # zenith view, Lambertian source at r, constant β, no extinction, isotropic phase:
    # b = β/(4π²) ∫ z / (s (s² + a²)) dz = β/(4π² a) [atan(s/a)]_{r}^{sqrt(r² + Z²)}
    beta, top, a = 1e-5, 20_000.0, 10.0
    m = _flat_constant_medium(beta, top)
    b = kernel_radiance(m, 0.0, math.pi / 2, distance, emission="lambertian", n_steps=64,
                        source_radius_m=a)
    s1 = math.sqrt(distance**2 + top**2)
    expected = beta / (4 * math.pi**2 * a) * (math.atan(s1 / a) - math.atan(distance / a))
    assert float(b) == pytest.approx(expected, rel=1e-5)


@pytest.mark.parametrize("quadrature", ["single", "split"])
def test_quadrature_converges_to_fine_reference(medium, quadrature):
    # reference: 2 x 512 nodes; 2 x 16 nodes must be within 0.2 % with either scheme
    theta = torch.tensor([0.0, 0.5, 2.0, math.pi], dtype=torch.float64)[:, None, None]
    phi = torch.tensor([0.02, 0.3, 1.2], dtype=torch.float64)[None, :, None]
    r = torch.tensor([100.0, 3e3, 2e4], dtype=torch.float64)[None, None, :]
    reference = kernel_radiance(medium, theta, phi, r, n_steps=512, quadrature="split")
    coarse = kernel_radiance(medium, theta, phi, r, n_steps=16, quadrature=quadrature)
    assert torch.all((coarse - reference).abs() <= 0.2 * PERCENT * reference)
    n, change = converged_steps(medium, 1e-2, quadrature=quadrature)
    assert n <= 32 and change <= 1e-2


def test_kernel_is_mirror_symmetric(medium):
    theta = torch.linspace(0.1, 3.0, 7, dtype=torch.float64)[:, None]
    phi = torch.tensor([0.05, 0.7], dtype=torch.float64)
    plus = kernel_radiance(medium, theta, phi, 5e3, n_steps=16)
    minus = kernel_radiance(medium, -theta, phi, 5e3, n_steps=16)
    assert torch.allclose(plus, minus, rtol=1e-12, atol=0)


def test_source_at_observer_is_finite(medium, dtype):
    # hard case r -> 0: the source radius regularises the 1/s^2 singularity
    r = torch.tensor([0.0, 1e-6, 1.0], dtype=dtype)
    b = kernel_radiance(medium, torch.zeros((), dtype=dtype), torch.full((), 0.5, dtype=dtype),
                        r, n_steps=16, source_radius_m=10.0)
    assert b.dtype == dtype
    assert torch.all(torch.isfinite(b)) and torch.all(b > 0)
    assert torch.allclose(b[0], b[1], rtol=1e-4)


def test_kernel_gradient_is_finite_and_correct(medium):
    r = torch.tensor([500.0, 8e3], dtype=torch.float64, requires_grad=True)

    def f(distance):
        return kernel_radiance(medium, 0.3, 0.2, distance, n_steps=8)[..., 1] * 1e9

    assert torch.autograd.gradcheck(f, (r,), eps=1e-3, atol=1e-7, rtol=1e-4)


def test_float32_kernel_agrees_with_float64(medium):
    args = (torch.tensor([0.0, 1.0]), torch.tensor([0.1, 1.2]), torch.tensor([300.0, 2e4]))
    b32 = kernel_radiance(medium, *args, n_steps=16)
    b64 = kernel_radiance(medium, *(a.double() for a in args), n_steps=16)
    assert b32.dtype == torch.float32
    assert torch.allclose(b32.double(), b64, rtol=1e-3)


def test_invalid_geometry_raises(medium):
    with pytest.raises(ValueError, match="distance_m"):
        kernel_radiance(medium, 0.0, 0.5, -1.0)
    with pytest.raises(ValueError, match="elevation_rad"):
        kernel_radiance(medium, 0.0, 2.0, 1e3)


@pytest.mark.parametrize("turbidity", [2.0, 3.0])
def test_walker_law_with_garstang_emission(turbidity):
    # Walker (1977): zenith skyglow ∝ d^-2.5 between 10 and 50 km from a compact city;
    # Garstang (1986) F = 0.10, G = 0.15, clear atmosphere (Preetham turbidity 2-3)
    from skytorch.atmosphere import Atmosphere
    from skytorch.spectrum import wavelength_grid

    m = Medium(Atmosphere.earth(turbidity=turbidity), wavelength_grid("rgb"))
    d = torch.linspace(10e3, 50e3, 9, dtype=torch.float64)
    b = kernel_radiance(m, 0.0, math.pi / 2, d, emission="garstang1986",
                        emission_parameters={"F": 0.10, "G": 0.15}, n_steps=32)[:, 1]
    design = torch.stack([torch.log(d / 1e3), torch.ones_like(d)], dim=1)
    slope = well_conditioned_lstsq(design.numpy(), torch.log(b).numpy())[0]
    assert abs(float(slope) - WALKER_EXPONENT) <= WALKER_TOLERANCE


def test_emission_names_tuple():
    assert set(EMISSION_FUNCTIONS) == {"garstang1986", "lambertian", "dobashi2023"}


def test_float32_kernel_with_real_atmosphere_phase_function():
    # the atmosphere's phase functions reject |cos θ| > 1: rounding in float32 must not
    # produce such cosines (forward and backward scattering directions included)
    from skytorch.atmosphere import Atmosphere

    m = Medium(Atmosphere.earth(turbidity=3.0), [550.0])
    theta = torch.linspace(0.0, math.pi, 33, dtype=torch.float32)[:, None, None]
    phi = torch.linspace(0.001, math.pi / 2, 17, dtype=torch.float32)[None, :, None]
    r = torch.tensor([0.0, 30.0, 500.0, 5e3, 4e4], dtype=torch.float32)
    b = kernel_radiance(m, theta, phi, r, n_steps=8)
    assert b.dtype == torch.float32 and bool(torch.isfinite(b).all())


def test_default_node_count_accuracy(medium):
    # the precompute default (n_steps=8, 16 nodes per view ray) against 2 x 512 nodes on
    # random geometries incl. grazing rays, stand-in atmosphere; with Atmosphere.earth
    # (turbidity 2) and 2000 geometries: 0.014 % mean, 0.36 % max (docs/skyglow.md)
    import inspect

    from skytorch.skyglow.model import SkyglowModel

    default = inspect.signature(SkyglowModel.precompute).parameters["n_steps"].default
    generator = torch.Generator().manual_seed(5)
    n = 400
    theta = torch.rand(n, generator=generator, dtype=torch.float64) * math.pi
    phi = torch.rand(n, generator=generator, dtype=torch.float64) * (math.pi / 2)
    r = 20e3 * torch.rand(n, generator=generator, dtype=torch.float64) ** 2
    h_c = 600.0 * torch.rand(n, generator=generator, dtype=torch.float64)
    reference = kernel_radiance(medium, theta, phi, r, h_c, n_steps=512)
    coarse = kernel_radiance(medium, theta, phi, r, h_c, n_steps=default)
    lit = reference > 0
    relative = (coarse - reference).abs()[lit] / reference[lit]
    assert float(relative.mean()) < 0.05 * PERCENT
    assert float(relative.max()) < 1 * PERCENT


#: float32 kernel against float64 on grazing rays: relative tolerance on every value
#: brighter than FLOAT32_FLOOR of the brightest one (25 mag fainter is far below any
#: measurable skyglow); 0.1 % is below the default quadrature's own error (0.36 % max)
FLOAT32_TOLERANCE = 0.1 * PERCENT
FLOAT32_FLOOR = 1e-10


@pytest.mark.parametrize("observer_altitude_m", [0.0, 2.0, 500.0])
def test_float32_kernel_on_grazing_rays(observer_altitude_m):
    # hard case: observer near the ground, elevation 0-2°, distant sources, sources on the
    # ground and on a hill; radii near 6.4e6 m round to 0.5 m in float32, so the kernel
    # must form altitudes and offsets without differences of radii
    from skytorch.atmosphere import Atmosphere
    from skytorch.spectrum import wavelength_grid

    m = Medium(Atmosphere.earth(turbidity=2.0), wavelength_grid("rgb"))
    theta = torch.linspace(0.0, math.pi, 9, dtype=torch.float64)[:, None, None, None]
    phi = torch.deg2rad(torch.linspace(0.0, 2.0, 9, dtype=torch.float64))[None, :, None, None]
    r = torch.tensor([100.0, 1e3, 5e3, 1e4, 2e4, 5e4], dtype=torch.float64)[None, None, :, None]
    h_c = torch.tensor([0.0, 300.0], dtype=torch.float64)
    args = (theta, phi, r, h_c, observer_altitude_m)
    b64 = kernel_radiance(m, *args, n_steps=8)
    b32 = kernel_radiance(m, *(torch.as_tensor(v).float() for v in args), n_steps=8)
    assert b32.dtype == torch.float32
    assert bool((b64 > 0).any())
    bright = b64 > FLOAT32_FLOOR * b64.max()
    relative = (b32.double() - b64).abs()[bright] / b64[bright]
    assert float(relative.max()) < FLOAT32_TOLERANCE
    faint = ~bright  # the rest stays negligible, finite and non-negative
    assert torch.all(torch.isfinite(b32)) and torch.all(b32[faint] >= 0)


def test_float32_grazing_gradient_is_finite():
    from skytorch.atmosphere import Atmosphere

    m = Medium(Atmosphere.earth(turbidity=2.0), [550.0])
    r = torch.tensor([1e3, 2e4], dtype=torch.float32, requires_grad=True)
    phi = torch.tensor([0.0, 0.01], dtype=torch.float32, requires_grad=True)
    b = kernel_radiance(m, 0.5, phi, r, n_steps=8)
    (gr, gp) = torch.autograd.grad(b.sum(), (r, phi))
    assert torch.all(torch.isfinite(gr)) and torch.all(torch.isfinite(gp))
    assert torch.all(gr < 0)  # farther sources are fainter
