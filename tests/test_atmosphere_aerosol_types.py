"""Named aerosol types (OPAC, stratospheric sulfate) and the Martian dust table.

Names, ranges, and the physics the Mie tables must show (absorbing soot lowers the albedo, coarse
sea salt flattens the spectrum, Martian dust absorbs in the blue).
"""

import math

import numpy as np
import pytest
import torch

from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.aerosol import (
    AEROSOL_TYPE_ALIASES,
    AEROSOL_TYPES,
    MARS_DUST_RANGE_NM,
    OPAC_RANGE_NM,
    aerosol_type_properties,
    aerosol_type_range_nm,
    mars_dust_properties,
    resolve_aerosol_type,
    sulfate_mie_properties,
)

F64 = torch.float64


def _angstrom(name, short=440.0, long=870.0):
    ratio = aerosol_type_properties(name, torch.tensor([short, long], dtype=F64))[0]
    return -math.log(float(ratio[1] / ratio[0])) / math.log(long / short)


def test_required_types_and_aliases_exist():
    for name in ("sulfate", "continental", "maritime", "urban", "mineral_dust"):
        assert resolve_aerosol_type(name) in AEROSOL_TYPES
    assert set(AEROSOL_TYPE_ALIASES.values()) <= set(AEROSOL_TYPES)


@pytest.mark.parametrize("name", AEROSOL_TYPES)
def test_every_type_is_normalised_at_550_nm_and_physical(name):
    low, high = aerosol_type_range_nm(name)
    wavelength = torch.linspace(low, high, 57, dtype=F64)
    ratio, albedo, g = aerosol_type_properties(name, wavelength)
    at_550 = aerosol_type_properties(name, torch.tensor([550.0], dtype=F64))[0]
    assert float(at_550[0]) == pytest.approx(1.0, abs=1e-12)
    assert torch.all(ratio > 0.0)
    assert torch.all((albedo > 0.0) & (albedo <= 1.0))
    assert torch.all((g > 0.0) & (g < 1.0))


def test_sulfate_type_is_the_stratospheric_table():
    wavelength = torch.tensor([400.0, 800.0], dtype=F64)
    for a, b in zip(aerosol_type_properties("sulfate", wavelength),
                    sulfate_mie_properties(wavelength), strict=True):
        assert torch.equal(a, b)


def test_soot_lowers_the_albedo():
    """Soot orders the single-scattering albedo of the continental types at 550 nm.

    Urban (130000 soot cm^-3) < continental polluted < continental average < continental
    clean (no soot); urban below 0.85, clean above 0.95.
    """
    wavelength = torch.tensor([550.0], dtype=F64)
    albedo = [float(aerosol_type_properties(name, wavelength)[1][0]) for name in
              ("urban", "continental_polluted", "continental_average", "continental_clean")]
    assert albedo == sorted(albedo)
    assert albedo[0] < 0.85 and albedo[-1] > 0.95


def test_coarse_particles_flatten_the_spectrum():
    """Ångström exponent 440/870 nm.

    Maritime clean (sea salt) and desert (mineral) below 0.7, continental types (fine water-soluble
    particles) above 1.
    """
    assert _angstrom("maritime_clean") < 0.7
    assert _angstrom("desert") < 0.7
    assert _angstrom("continental_average") > 1.0
    assert _angstrom("urban") > 1.0


def test_mineral_dust_absorbs_more_in_the_blue():
    _, albedo, _ = aerosol_type_properties("mineral_dust",
                                           torch.tensor([400.0, 700.0], dtype=F64))
    assert float(albedo[0]) < float(albedo[1]) - 0.02


def test_unknown_type_and_wrong_kind_refused():
    with pytest.raises(ValueError, match="aerosol_type='smoke'"):
        aerosol_type_properties("smoke", torch.tensor([550.0]))
    with pytest.raises(TypeError, match="aerosol_type"):
        resolve_aerosol_type(3)


@pytest.mark.parametrize("bad", [OPAC_RANGE_NM[0] - 1.0, OPAC_RANGE_NM[1] + 1.0,
                                 float("nan")])
def test_type_wavelength_out_of_range_refused(bad):
    with pytest.raises(ValueError, match="wavelength_nm"):
        aerosol_type_properties("urban", torch.tensor([bad]))


def test_interpolation_is_differentiable_in_wavelength():
    wavelength = torch.tensor([512.3, 733.0], dtype=F64, requires_grad=True)
    ratio, _, _ = aerosol_type_properties("continental_average", wavelength)
    ratio.sum().backward()
    assert torch.all(wavelength.grad < 0.0)  # extinction falls with wavelength


def test_float32_follows_float64():
    wavelength = torch.tensor([444.4, 987.6])
    single = aerosol_type_properties("maritime_polluted", wavelength)
    double = aerosol_type_properties("maritime_polluted", wavelength.to(F64))
    for a, b in zip(single, double, strict=True):
        assert a.dtype == torch.float32
        torch.testing.assert_close(a.to(F64), b, rtol=1e-6, atol=1e-6)


def test_mars_dust_albedo_lower_in_the_blue():
    """Martian dust (Wolff et al. 2009 index).

    Albedo rises monotonically (within 0.005) from the UV to a plateau of 0.96-0.98 at 650-1717 nm;
    below 0.80 at 450 nm.
    """
    wavelength = torch.linspace(MARS_DUST_RANGE_NM[0], MARS_DUST_RANGE_NM[1], 200,
                                dtype=F64)
    _, albedo, _ = mars_dust_properties(wavelength)
    blue = wavelength < 600.0
    assert torch.all(torch.diff(albedo[blue]) > -0.005)
    red = wavelength >= 650.0
    assert torch.all((albedo[red] > 0.96) & (albedo[red] < 0.98))
    at_450 = mars_dust_properties(torch.tensor([450.0], dtype=F64))[1]
    assert float(at_450[0]) < 0.80


@pytest.mark.parametrize("bad", [MARS_DUST_RANGE_NM[0] - 1.0, MARS_DUST_RANGE_NM[1] + 1.0])
def test_mars_dust_wavelength_out_of_range_refused(bad):
    with pytest.raises(ValueError, match="wavelength_nm"):
        mars_dust_properties(torch.tensor([bad]))


# ---------------------------------------------------------------- Atmosphere wiring
WL = torch.tensor([400.0, 550.0, 870.0], dtype=F64)


def test_default_earth_keeps_the_untyped_aerosol():
    atm = Atmosphere.earth()
    assert atm.aerosol_type is None and atm.aerosol_phase_model == "cornetteshanks1992"
    assert "aerosol_type" not in atm.parameters_dict()
    albedo = atm.constituents(WL)["aerosol"].single_scattering_albedo
    assert torch.all(albedo == 0.9)


@pytest.mark.parametrize("given", [{"aerosol_optical_depth": 0.3}, {"turbidity": 4.0}])
def test_typed_aerosol_keeps_the_550_nm_depth_and_takes_the_type_spectrum(given):
    """The vertical aerosol optical depth at 550 nm of a type is the untyped one.

    Turbidity or aerosol_optical_depth, within 1e-12; at other wavelengths it follows the type's
    extinction ratio; the albedo is the type's.
    """
    plain = Atmosphere.earth(**given).optical_depth(WL, per_species=True)["aerosol"]
    typed_atm = Atmosphere.earth(**given, aerosol_type="maritime")
    typed = typed_atm.optical_depth(WL, per_species=True)["aerosol"]
    assert float(typed[1]) == pytest.approx(float(plain[1]), rel=1e-12)
    ratio, albedo, _ = aerosol_type_properties("maritime_clean", WL)
    torch.testing.assert_close(typed / typed[1], ratio, rtol=1e-12, atol=0.0)
    species = typed_atm.constituents(WL)["aerosol"]
    torch.testing.assert_close(species.single_scattering_albedo, albedo, rtol=1e-12, atol=0.0)


def test_typed_phase_is_normalised_with_the_mie_asymmetry():
    """The aerosol phase of a type integrates to 1 over 4π, with the table's g.

    Its mean cosine is the table's g at each wavelength (Gauss-Legendre, 400 nodes, within
    1e-6).
    """
    atm = Atmosphere.earth(aerosol_type="continental")
    assert atm.aerosol_phase_model == "henyeygreenstein1941"
    nodes, weights = np.polynomial.legendre.leggauss(400)
    mu = torch.tensor(nodes, dtype=F64)
    w = torch.tensor(weights, dtype=F64)
    phase = atm.constituents(WL)["aerosol"].phase(mu)  # (400, wavelength)
    norm = 2.0 * math.pi * (w[:, None] * phase).sum(0)
    mean_cos = 2.0 * math.pi * (w[:, None] * mu[:, None] * phase).sum(0)
    _, _, g = aerosol_type_properties("continental_average", WL)
    torch.testing.assert_close(norm, torch.ones_like(norm), rtol=0.0, atol=1e-6)
    torch.testing.assert_close(mean_cos, g, rtol=0.0, atol=1e-6)


def test_typed_aerosol_gradient_in_optical_depth():
    aod = torch.tensor(0.2, dtype=F64, requires_grad=True)

    def depth(value):
        atm = Atmosphere.earth(aerosol_optical_depth=value, aerosol_type="urban")
        return atm.optical_depth(WL, per_species=True)["aerosol"]

    assert torch.autograd.gradcheck(depth, (aod,))


def test_typed_aerosol_refuses_scalar_optics_and_wavelength_free_phase():
    with pytest.raises(ValueError, match="aerosol_single_scattering_albedo"):
        Atmosphere.earth(aerosol_type="urban", aerosol_single_scattering_albedo=0.8)
    with pytest.raises(ValueError, match="aerosol_type='soot'"):
        Atmosphere.earth(aerosol_type="soot")
    # the type's spectrum replaces the Angstrom exponent of a given optical depth (0.1 and 2
    # gave the same depths at every wavelength); with a turbidity it still sets the 550 nm
    # depth of Preetham's beta
    with pytest.raises(ValueError, match="angstrom_alpha would not be used"):
        Atmosphere.earth(aerosol_type="urban", aerosol_optical_depth=0.2, angstrom_alpha=2.0)
    steep, flat = (Atmosphere.earth(turbidity=3.0, aerosol_type="urban", angstrom_alpha=alpha)
                   for alpha in (2.0, 0.1))
    assert not torch.allclose(steep.optical_depth(WL), flat.optical_depth(WL))
    with pytest.raises(ValueError, match="depends on the wavelength"):
        Atmosphere.earth(aerosol_type="urban").aerosol_phase(torch.tensor([0.5]))
    with pytest.raises(ValueError, match="wavelength_nm"):
        Atmosphere.earth(aerosol_type="urban").constituents(torch.tensor([240.0]))


def test_mars_dust_albedo_depends_on_wavelength():
    """Atmosphere.mars uses the Martian dust table (lower in the blue).

    A scalar albedo passed explicitly replaces it.
    """
    atm = Atmosphere.mars()
    wavelength = torch.tensor([450.0, 700.0], dtype=F64)
    albedo = atm.constituents(wavelength)["aerosol"].single_scattering_albedo
    torch.testing.assert_close(albedo, mars_dust_properties(wavelength)[1], rtol=1e-12,
                               atol=0.0)
    assert float(albedo[0]) < float(albedo[1]) - 0.1
    scalar = Atmosphere.mars(aerosol_single_scattering_albedo=0.93)
    assert torch.all(scalar.constituents(wavelength)["aerosol"].single_scattering_albedo
                     == 0.93)
