"""Per-eclipse atmosphere: the stratospheric record, the climatological troposphere, clouds."""

import pytest
import torch

from skytorch.atmosphere import Atmosphere
from skytorch.eclipse import eclipse_atmosphere, eclipse_shadow, stratospheric_aod


def test_pinatubo_year_within_the_published_global_mean():
    # Self et al. 1996 (USGS): "globally averaged values were about 0.1 to 0.15 for 2 years"
    assert 0.10 <= stratospheric_aod("1992-12-09") <= 0.15


def test_background_years_an_order_of_magnitude_below_pinatubo():
    # Vernier et al. 2011: background reached between 1998 and 2002, "two orders of
    # magnitude" below the post-Pinatubo peak; Sato et al. 1993 quiescent ~0.005
    for date in ("1999-06-01", "2000-07-16", "2001-01-09"):
        assert 0.002 <= stratospheric_aod(date) <= 0.008
    assert stratospheric_aod("1992-06-01") > 10 * stratospheric_aod("2000-07-16")


def test_volcanic_years_above_their_neighbours():
    # El Chichon 1982 (Sato et al. 1993) and Hunga Tonga 2022 (Taha et al. 2022)
    assert stratospheric_aod("1983-06-25") > 5 * stratospheric_aod("1979-09-06")
    assert stratospheric_aod("2022-11-08") > stratospheric_aod("2021-05-26")


def test_vertical_optical_depths_are_the_ingredients():
    # total vertical optical depth at 550 nm = molecules + tropospheric + stratospheric
    # aerosol + ozone; compared with an atmosphere without aerosols
    atm = eclipse_atmosphere("1992-12-09")
    clean = Atmosphere.earth(aerosol_optical_depth=0.0, ozone_du=300.0)
    wavelength = torch.tensor([550.0], dtype=torch.float64)
    aerosols = float(atm.optical_depth(wavelength) - clean.optical_depth(wavelength))
    assert aerosols == pytest.approx(0.12 + stratospheric_aod("1992-12-09"), abs=2e-3)


def test_out_of_record_and_bad_values_raise():
    with pytest.raises(ValueError, match="date"):
        stratospheric_aod("1970-02-21")
    with pytest.raises(ValueError, match="stratospheric_aod_550"):
        eclipse_atmosphere("2015-09-28", stratospheric_aod_550=-0.1)
    # an explicit layer does not need the record
    atm = eclipse_atmosphere("1970-02-21", stratospheric_aod_550=0.02)
    assert float(atm.stratospheric_aerosol_optical_depth) == pytest.approx(0.02)


def test_stratospheric_depth_keeps_its_gradient():
    tau = torch.tensor(0.05, dtype=torch.float64, requires_grad=True)
    atm = eclipse_atmosphere("2015-09-28", stratospheric_aod_550=tau)
    atm.optical_depth(torch.tensor([550.0], dtype=torch.float64)).sum().backward()
    assert tau.grad is not None and float(tau.grad) == pytest.approx(1.0, abs=2e-3)


def test_clouds_are_shadow_options():
    shadow = eclipse_shadow("2015-09-28")
    assert shadow.cloud_top_altitude_m == 5000.0 and shadow.cloud_fraction == 0.66
    assert float(shadow.atmosphere.stratospheric_aerosol_optical_depth) == pytest.approx(
        stratospheric_aod("2015-09-28"))
