"""units_from_name and batch_coordinates: the one suffix table and batch-coordinate helper.

Both sweep() and lunar_eclipse() label their batch dimensions through these two functions;
the tests check the documented rules directly and through the two callers.
"""

import numpy as np
import pytest
import torch

import skytorch as st
from skytorch.dataset import UNIT_SUFFIXES, batch_coordinates, units_from_name


@pytest.mark.parametrize(("name", "expected"), [
    ("ozone_du", "DU"), ("surface_pressure_pa", "Pa"), ("pressure_hpa", "hPa"),
    ("gravity_m_s2", "m s-2"), ("molar_mass_kg_mol", "kg mol-1"), ("altitude_m", "m"),
    ("distance_km", "km"), ("wavelength_nm", "nm"), ("temperature_k", "K"),
    ("zenith_deg", "degree"), ("angle_rad", "rad"), ("exposure_s", "s"),
    ("limit_mag", "mag"), ("Wavelength_NM", "nm"), ("turbidity", "1"), ("angstrom_alpha", "1"),
])
def test_units_from_name_suffixes(name, expected):
    assert units_from_name(name) == expected


def test_units_from_name_explicit_units_win():
    assert units_from_name("ozone_du", {"ozone_du": "1e-5 m"}) == "1e-5 m"
    assert units_from_name("ozone_du", {"other": "K"}) == "DU"


def test_unit_suffixes_are_valid_udunits():
    pytest.importorskip("cf_xarray")
    pytest.importorskip("pint")
    from cf_xarray.units import units as udunits

    if "DU" not in udunits:  # UDUNITS-2 defines it (udunits2-common.xml); cf_xarray lacks it
        udunits.define("dobson = 446.2e-6 * mole / meter ** 2 = DU")
    # "mag" is no UDUNITS unit; it is the project's convention for magnitudes everywhere
    for _, unit in UNIT_SUFFIXES:
        if "mag" not in unit.split():
            udunits.parse_units(unit)


def test_batch_coordinates_labels_and_indices():
    ozone = torch.tensor([250.0, 350.0], dtype=torch.float64)
    turbidity = torch.tensor([[1.5, 2.0], [3.0, 4.0]], dtype=torch.float64)
    coords = batch_coordinates({"ozone_du": 2, "case": 2, "extra": 3},
                               {"ozone_du": (("ozone_du",), ozone),
                                "turbidity": (("ozone_du", "case"), turbidity)})
    assert list(coords) == ["ozone_du", "turbidity", "case", "extra"]
    assert coords["ozone_du"].dims == ("ozone_du",)
    assert coords["ozone_du"].values.tolist() == [250.0, 350.0]
    assert coords["ozone_du"].attrs["units"] == "DU"
    assert coords["ozone_du"].attrs["long_name"] == "ozone du"
    assert coords["turbidity"].dims == ("ozone_du", "case")
    assert coords["case"].values.tolist() == [0, 1]
    assert coords["extra"].values.tolist() == [0, 1, 2]
    assert coords["extra"].attrs["units"] == "1"


def test_batch_coordinates_templates():
    coords = batch_coordinates({"a": 2}, {"b_k": ("a", np.array([1.0, 2.0]))},
                               long_name="swept {name}", description="{label} values",
                               index_long_name="{dim} #{axis}", index_description="i")
    assert coords["b_k"].attrs == {"units": "K", "long_name": "swept b_k",
                                   "description": "b k values"}
    assert coords["a"].attrs["long_name"] == "a #0"


def test_batch_coordinates_rejects_bad_input():
    with pytest.raises(ValueError, match="shape"):
        batch_coordinates({"a": 2}, {"p": (("a",), np.zeros(3))})
    with pytest.raises(ValueError, match="shape"):
        batch_coordinates({"a": 2}, {"p": (("b",), np.zeros(2))})
    with pytest.raises(ValueError, match="named after a parameter"):
        batch_coordinates({"a": 2, "b": 2}, {"a": (("a", "b"), np.zeros((2, 2)))})


def test_sweep_coordinates_use_the_shared_table():
    ds = st.sweep(lambda gravity_m_s2, molar_mass_kg_mol: gravity_m_s2 * molar_mass_kg_mol,
                  gravity_m_s2=[9.8, 3.7], molar_mass_kg_mol=[0.029], progress=False)
    assert ds.gravity_m_s2.attrs["units"] == "m s-2"
    assert ds.molar_mass_kg_mol.attrs["units"] == "kg mol-1"
