"""The constituents interface: one value object, optical depths from path columns."""

from __future__ import annotations

import dataclasses
import math
import pathlib
import re

import pytest
import torch

from skytorch.atmosphere import SPECIES, Atmosphere
from skytorch.atmosphere.constituents import Constituents, Species, SpeciesBuilder

WAVELENGTH = torch.tensor([320.0, 450.0, 550.0, 800.0], dtype=torch.float64)
ROOT = pathlib.Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def batched():
    return Atmosphere.earth(turbidity=torch.tensor([[2.0], [5.0]], dtype=torch.float64),
                            ozone_du=torch.tensor([250.0, 400.0], dtype=torch.float64),
                            stratospheric_aerosol_optical_depth=0.1)


def test_constituents_are_immutable_and_named(batched):
    c = batched.constituents(WAVELENGTH)
    assert isinstance(c, Constituents)
    assert c.names == SPECIES
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.species = ()
    with pytest.raises(dataclasses.FrozenInstanceError):
        c["ozone"].extinction = torch.zeros(4)
    with pytest.raises(TypeError):
        c["ozone"].profile.parameters["center_m"] = torch.tensor(0.0)
    with pytest.raises(KeyError, match="no species 'o3'"):
        c["o3"]
    assert c["ozone"].phase is None and c["ozone"].scattering is None
    assert c["aerosol"].extinction.shape == (2, 1, 4)  # batched over the parameters


def test_single_scattering_albedo_per_species(batched):
    c = batched.constituents(WAVELENGTH)
    assert torch.equal(c["rayleigh"].single_scattering_albedo, torch.ones(4, dtype=torch.float64))
    assert torch.equal(c["ozone"].single_scattering_albedo,
                       torch.zeros_like(c["ozone"].extinction))
    assert torch.allclose(c["aerosol"].single_scattering_albedo,
                          torch.full((2, 1, 4), 0.9, dtype=torch.float64), rtol=1e-14)


def test_phase_functions_are_normalised(batched):
    c = batched.constituents(WAVELENGTH)
    mu = torch.linspace(-1.0, 1.0, 20001, dtype=torch.float64)
    for species in c.scatterers():
        phase = species.phase(mu)
        integral = 2.0 * math.pi * torch.trapezoid(phase, mu, dim=0)
        assert torch.allclose(integral, torch.ones_like(integral), atol=2e-3), species.name


@pytest.mark.parametrize("zenith", [0.0, 1.2, 1.5707, 1.58])  # 1.58: below the horizontal
def test_per_species_sums_to_total(batched, zenith):
    zenith = torch.tensor([zenith, 0.5], dtype=torch.float64)
    parts = batched.optical_depth(WAVELENGTH, zenith, 1000.0, per_species=True)
    total = batched.optical_depth(WAVELENGTH, zenith, 1000.0)
    assert set(parts) == set(SPECIES)
    assert all(part.shape == total.shape for part in parts.values())
    assert torch.allclose(sum(parts.values()), total, rtol=1e-14, atol=0.0)
    # the four species present here all contribute
    assert all(bool((parts[name] > 0).all()) for name in
               ("rayleigh", "aerosol", "ozone", "stratospheric_aerosol"))


def test_optical_depth_is_the_constituents_of_the_columns(batched):
    zenith = torch.tensor([0.3, 1.4], dtype=torch.float64)
    c = batched.constituents(WAVELENGTH)
    columns = c.column_integrals(batched.planet_radius_m + torch.tensor(500.0,
                                                                        dtype=torch.float64),
                                 torch.cos(zenith))
    direct = batched.optical_depth(WAVELENGTH, zenith, 500.0)
    assert torch.equal(c.optical_depth(columns), direct)
    # the columns of the public method are the same
    public = batched.column_integrals(zenith, 500.0)
    assert all(torch.equal(public[name], columns[name]) for name in SPECIES)
    with pytest.raises(ValueError, match="lack species"):
        c.optical_depth({"rayleigh": columns["rayleigh"]})


def test_nonlinear_species_uses_its_law_on_the_column():
    """A species with tau = a sqrt(u).

    Doubling the path (air mass 2 at 60 deg on a thin flat-ish layer) multiplies its optical depth
    by sqrt(2), not 2.
    """
    atm = Atmosphere.earth(ozone_du=0.0, aerosol_optical_depth=0.0)

    def build(atmosphere, wavelength, dtype, profile):
        def law(column, extra):
            return 1e-3 * torch.sqrt(column)[..., None] * torch.ones_like(wavelength)
        return Species("toy", profile, torch.zeros_like(wavelength), law=law)

    builder = SpeciesBuilder("toy", lambda a, dtype: a.profiles(dtype)["ozone"], build)
    c = atm.constituents(WAVELENGTH, extra_species=(builder,))
    mu = torch.tensor([1.0, 0.5], dtype=torch.float64)
    columns = c.column_integrals(torch.tensor(atm.planet_radius_m, dtype=torch.float64), mu)
    tau = c.optical_depth(columns, per_species=True)["toy"][:, 0]
    ratio_column = float(columns["toy"][1] / columns["toy"][0])
    assert 1.9 < ratio_column < 2.0  # a layer at 10-40 km: a little less than sec(60 deg)
    assert float(tau[1] / tau[0]) == pytest.approx(math.sqrt(ratio_column), rel=1e-12)


def test_no_kernel_reads_private_members_of_the_atmosphere():
    files = ["skytorch/atmosphere/scattering.py", "skytorch/atmosphere/tables.py",
             "skytorch/eclipse/shadow.py", "skytorch/eclipse/shadow_scattering.py",
             "skytorch/eclipse/shadow_table.py", "skytorch/skyglow/kernel.py",
             "skytorch/skyglow/model.py", "skytorch/moon/sky.py"]
    pattern = re.compile(r"\b(atmosphere|atm)\._[a-z]")
    offenders = [f"{name}:{number}" for name in files
                 for number, line in enumerate((ROOT / name).read_text().splitlines(), 1)
                 if pattern.search(line)]
    assert not offenders
