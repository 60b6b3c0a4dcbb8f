"""Star catalogue: Hipparcos 2 selection, Hp → V, epoch propagation, BSC5 reader."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from skytorch.constants import ARCSECOND, DEGREE, MAG
from skytorch.stars import bright_stars, hipparcos_to_johnson_v, propagate_space_motion, read_bsc5

DATA = Path(__file__).parent / "data"

#: Johnson V of bright, photometrically steady stars: Bright Star Catalogue 5th ed.
#: (Hoffleit & Warren 1991, field Vmag), HIP -> (name, V)
BSC5_V = {
    91262: ("Vega", 0.03), 69673: ("Arcturus", -0.04), 24608: ("Capella", 0.08),
    37279: ("Procyon", 0.38), 97649: ("Altair", 0.77), 7588: ("Achernar", 0.46),
    37826: ("Pollux", 1.14), 102098: ("Deneb", 1.25), 49669: ("Regulus", 1.35),
    113368: ("Fomalhaut", 1.16), 21421: ("Aldebaran", 0.85), 65474: ("Spica", 0.98),
}
#: SIMBAD ICRS J2000 coordinates [deg] (from the 2007 Hipparcos reduction)
SIMBAD_J2000 = {91262: (279.23473479, 38.78368896), 32349: (101.28715533, -16.71611586)}


@pytest.fixture(scope="module")
def catalog():
    return bright_stars(6.5)


def _row(ds, hip):
    return int(np.nonzero(ds.hip.values == hip)[0][0])


def test_about_nine_thousand_stars_to_6_5(catalog):
    assert 8500 < catalog.sizes["star"] < 9500
    assert float(catalog.vmag.max()) <= 6.5
    assert np.all(np.diff(catalog.vmag.values) >= 0.0)  # sorted by V
    for name in ("hip", "ra", "dec", "vmag", "bv", "pm_ra", "pm_dec", "parallax"):
        assert name in catalog and catalog[name].attrs.get("long_name")
    assert catalog.attrs["epoch"] == "J2000.0"


@pytest.mark.parametrize("hip", sorted(BSC5_V))
def test_transformed_hp_matches_published_johnson_v(catalog, hip):
    name, published = BSC5_V[hip]
    row = _row(catalog, hip)
    assert int(catalog.vmag_source[row]) == 0, f"{name} must come from the Hp transformation"
    assert abs(float(catalog.vmag[row]) - published) <= 0.05 * MAG, name


def test_named_reference_stars(catalog):
    """Vega ≈ 0.03, Sirius ≈ −1.46 (taken from BSC5: Hp saturated), Arcturus ≈ −0.05."""
    assert float(catalog.vmag[_row(catalog, 91262)]) == pytest.approx(0.03, abs=0.05)
    assert float(catalog.vmag[_row(catalog, 69673)]) == pytest.approx(-0.05, abs=0.05)
    sirius = _row(catalog, 32349)
    assert float(catalog.vmag[sirius]) == pytest.approx(-1.46, abs=0.01)
    assert int(catalog.vmag_source[sirius]) == 1
    # the Hipparcos magnitude of Sirius alone would be 0.37 mag too faint
    hp_based = float(hipparcos_to_johnson_v(float(catalog.hp[sirius]), float(catalog.bv[sirius])))
    assert hp_based - (-1.46) > 0.3


@pytest.mark.parametrize("hip", sorted(SIMBAD_J2000))
def test_j2000_positions_match_simbad(catalog, hip):
    ra, dec = SIMBAD_J2000[hip]
    row = _row(catalog, hip)
    d_ra = (float(catalog.ra[row]) - ra) * np.cos(np.deg2rad(dec)) * DEGREE
    d_dec = (float(catalog.dec[row]) - dec) * DEGREE
    assert np.hypot(d_ra, d_dec) < 0.005 * ARCSECOND


def test_empty_selection_is_an_empty_dataset():
    ds = bright_stars(limit_magnitude=-5.0)
    assert ds.sizes["star"] == 0
    assert "vmag" in ds


def test_limit_magnitude_validation():
    with pytest.raises(ValueError, match="limit_magnitude"):
        bright_stars(float("nan"))


def test_space_motion_round_trip_and_linear_limit():
    ra = torch.tensor([0.3, 4.0, 6.0])
    dec = torch.tensor([0.2, -1.2, 1.5])
    pm_ra = torch.tensor([-3678.0, 500.0, 20.0])
    pm_dec = torch.tensor([482.0, -1000.0, -7.0])
    parallax = torch.tensor([754.8, 100.0, 1.0])
    forward = propagate_space_motion(ra, dec, pm_ra, pm_dec, parallax, 100.0)
    back = propagate_space_motion(*forward, -100.0)
    # the radial component mu^2 t acquired at the new epoch is not carried: a round trip
    # of a century misses by (mu t)^2 mu t ~ 1.2 mas for alpha Cen's 3.7″/yr
    d_ra = (back[0] - ra.double()) * torch.cos(dec.double())
    d_dec = back[1] - dec.double()
    assert float(torch.hypot(d_ra, d_dec).max()) < 2e-3 * ARCSECOND
    assert torch.allclose(back[2], pm_ra.double(), atol=0.05)
    # over one year the change is the proper motion itself (first order)
    step = propagate_space_motion(ra, dec, pm_ra, pm_dec, parallax, 1.0)
    d_dec_mas = (step[1] - dec) / DEGREE * 3.6e6
    assert torch.allclose(d_dec_mas, pm_dec.double(), atol=0.01)


def test_bessell_relation_at_table_nodes():
    # Bessell (2000) Table 2: BT−VT = 0.5 → B−V = 0.465, V − Hp = −0.108
    v = hipparcos_to_johnson_v(torch.tensor([5.0]), torch.tensor([0.465]))
    assert float(v) == pytest.approx(5.0 - 0.108, abs=1e-6)


def test_bsc5_reader_matches_hipparcos(catalog):
    bsc = read_bsc5(DATA / "bsc5_sample.dat")
    assert list(bsc.hr.values) == [2491, 5340, 7001, 424, 9999]  # the removed HR 92 skipped
    assert bsc.bv_missing.values.tolist() == [False, False, False, False, True]
    for hr, hip in ((2491, 32349), (5340, 69673), (7001, 91262), (424, 11767)):
        i = int(np.nonzero(bsc.hr.values == hr)[0][0])
        j = _row(catalog, hip)
        d_ra = (float(bsc.ra[i]) - float(catalog.ra[j])) * np.cos(np.deg2rad(float(bsc.dec[i])))
        d_dec = float(bsc.dec[i]) - float(catalog.dec[j])
        # BSC5 rounds RA to 0.1 s (1.5″ cos δ) and Dec to 1″; Polaris' RA to 0.1 s is 1″ · 0.013
        assert np.hypot(d_ra, d_dec) * DEGREE < 2.0 * ARCSECOND, hr
        assert float(bsc.pm_dec[i]) == pytest.approx(float(catalog.pm_dec[j]), abs=20.0)
    assert float(bsc.vmag[0]) == -1.46
    assert float(bsc.parallax[0]) == pytest.approx(375.0)
    assert bsc.sizes["star"] == 5
    assert read_bsc5(DATA / "bsc5_sample.dat", limit_magnitude=0.0).sizes["star"] == 2


def test_bsc5_reader_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_bsc5(tmp_path / "missing.dat")
    empty = tmp_path / "empty.dat"
    empty.write_text("\n")
    with pytest.raises(ValueError, match="no BSC5 records"):
        read_bsc5(empty)
    # a malformed number: the file, the field and the record are named
    lines = (DATA / "bsc5_sample.dat").read_text().splitlines()
    vmag = slice(102, 107)
    lines[2] = lines[2][:vmag.start] + " x.3 " + lines[2][vmag.stop:]
    bad = tmp_path / "bad.dat"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"bad.dat, field 'vmag': record 3 holds 'x.3'"):
        read_bsc5(bad)


def test_tensor_layer_refuses_mismatched_shapes_and_nan():
    from skytorch.stars.gaia import gaia_g_to_johnson_v
    from skytorch.stars.visibility import count_visible

    with pytest.raises(ValueError, match=r"hp_mag \(3,\), bv_mag \(2,\)"):
        hipparcos_to_johnson_v([1.0, 2.0, 3.0], [0.5, 0.6])
    with pytest.raises(ValueError, match=r"g_mag \(3,\), bp_rp_mag \(2,\)"):
        gaia_g_to_johnson_v([1.0, 2.0, 3.0], [0.5, 0.6])
    with pytest.raises(ValueError, match="ra_rad must be finite"):
        propagate_space_motion(float("nan"), 0.0, 0.0, 0.0, 1.0, 10.0)
    with pytest.raises(ValueError, match="dt_years must be finite"):
        propagate_space_motion(0.0, 0.0, 0.0, 0.0, 1.0, float("inf"))
    magnitude, above = torch.zeros(2, 3), torch.ones(2, 3, dtype=torch.bool)
    with pytest.raises(ValueError, match="limit_mag"):
        count_visible(magnitude, above, torch.zeros(5))
    with pytest.raises(TypeError, match="above_horizon must be a bool"):
        count_visible(magnitude, torch.ones(2, 3), torch.zeros(2))
    visible, count = count_visible(np.zeros((2, 3)), np.ones((2, 3), dtype=bool),
                                   np.array([1.0, -1.0]))
    assert count.tolist() == [3, 0]
