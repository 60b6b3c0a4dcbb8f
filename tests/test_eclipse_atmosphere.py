"""Per-eclipse atmosphere: the stratospheric record, the climatological troposphere, clouds.

The cloud profile (``LimbCloudCover``, ``cloud_climatology``) is tested here too: against
the ISCCP amounts and the SAGE occultation statistics, the single deck, and gradients.
"""

import pytest
import torch

from skytorch.atmosphere import Atmosphere
from skytorch.eclipse import eclipse_atmosphere, eclipse_shadow, stratospheric_aod
from skytorch.eclipse.eclipse_atmosphere import (
    CLOUD_CLASS_TOPS_M,
    SAGE_CLEAR_7KM,
    cloud_climatology,
    stratospheric_model,
)
from skytorch.eclipse.shadow import LimbCloudCover, Shadow


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
    # each named as the caller gave it (not as the Atmosphere's parameter)
    with pytest.raises(ValueError, match="tropospheric_aod must be finite"):
        eclipse_atmosphere("2015-09-28", tropospheric_aod=float("nan"))
    with pytest.raises(TypeError, match="tropospheric_aod"):
        eclipse_atmosphere("2015-09-28", tropospheric_aod="0.1")
    with pytest.raises(TypeError, match="stratospheric_aod_550"):
        stratospheric_model(stratospheric_aod_550="0.1")
    # checked even where the date's record chooses the model
    with pytest.raises(ValueError, match="stratospheric_aod_550"):
        stratospheric_model("2015-09-28", stratospheric_aod_550=-1.0)
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
    assert shadow.cloud_cover.name == "rossow1999" and shadow.cloud_top_altitude_m == 0.0
    assert float(shadow.atmosphere.stratospheric_aerosol_optical_depth) == pytest.approx(
        stratospheric_aod("2015-09-28"))
    deck = eclipse_shadow("2015-09-28", clouds="deck")
    assert deck.cloud_top_altitude_m == 5000.0 and deck.cloud_fraction == 0.66
    assert deck.cloud_cover is None
    clear = eclipse_shadow("2015-09-28", clouds="none")
    assert clear.cloud_cover is None and clear.cloud_top_altitude_m == 0.0
    with pytest.raises(ValueError, match="clouds"):
        eclipse_shadow("2015-09-28", clouds="isccp")


# ---------------------------------------------------------------- the limb cloud profile
F64 = torch.float64
MOON_M = 3.844e8
WAVELENGTH = torch.tensor([450.0, 550.0, 650.0], dtype=F64)


def _shadow(**options):
    return Shadow.earth(Atmosphere.earth(), n_altitude=65, **options)


def _illuminance(shadow, offsets=(0.0, 2.5e6, 4.2e6)):
    offset = torch.tensor(offsets, dtype=F64)
    return shadow.relative_illuminance(torch.full_like(offset, MOON_M), offset, WAVELENGTH)


def test_climatology_against_isccp_and_sage():
    cover = cloud_climatology()
    tops = torch.tensor(CLOUD_CLASS_TOPS_M, dtype=F64)
    # nadir cover: the ISCCP total amount at the ground, the high-cloud amount at 440 hPa
    # (Rossow & Schiffer 1999), nothing above the highest cirrus tops (Nazaryan et al. 2008)
    nadir = cover.cover_at(tops)
    assert float(nadir[0]) == pytest.approx(0.66, abs=0.005)
    assert float(nadir[2]) == pytest.approx(0.20, abs=0.005)
    assert float(cover.clear_fraction(torch.tensor(17e3, dtype=F64))) == 1.0
    # the limb at 7 km: within the SAGE occultation range, tropics 0.30 to higher
    # latitudes 0.60 (Woodbury & McCormick 1983, 1986) ...
    at_7km = float(cover.clear_fraction(torch.tensor(7e3, dtype=F64)))
    assert SAGE_CLEAR_7KM["tropics"] <= at_7km <= SAGE_CLEAR_7KM["extratropics"]
    # ... and the occultations see more cloud than a nadir view of the same climatology
    # (1 - f(7 km) = 0.81): the limb chord meets several cloud fields, exponent > 1
    nadir_clear = 1.0 - float(cover.cover_at(torch.tensor(7e3, dtype=F64)))
    assert SAGE_CLEAR_7KM["extratropics"] < nadir_clear
    assert float(cover.limb_exponent) > 1.0
    # the clear probability only grows with the periapsis altitude
    clear = cover.clear_fraction(torch.linspace(0.0, 2e4, 201, dtype=F64))
    assert bool((torch.diff(clear) >= 0.0).all())


def test_a_step_profile_is_the_single_deck():
    # a cover of 0.66 up to 5 km and 0 above (a step 1 mm wide) is the single deck of the
    # Shadow (tops 5 km, fraction 0.66), computed by another path (a ray weight of the
    # profile instead of the deck's step)
    step = LimbCloudCover([0.0, 5000.0, 5000.001], [0.66, 0.66, 0.0])
    profile = _illuminance(_shadow(cloud_cover=step))
    deck = _illuminance(_shadow(cloud_top_altitude_m=5000.0, cloud_fraction=0.66))
    torch.testing.assert_close(profile, deck, rtol=1e-6, atol=0.0)


def test_no_cover_or_zero_exponent_is_the_clear_shadow():
    # the same integrand; the profile only adds quadrature splits at its nodes (the
    # ring integral at n_altitude=65 then moves by up to 2e-4)
    clear = _illuminance(_shadow())
    none = LimbCloudCover([0.0, 16e3], [0.0, 0.0], limb_exponent=3.0)
    zero = LimbCloudCover([0.0, 16e3], [0.66, 0.0], limb_exponent=0.0)
    for cover in (none, zero):
        torch.testing.assert_close(_illuminance(_shadow(cloud_cover=cover)), clear,
                                   rtol=1e-3, atol=0.0)


def test_cloudy_umbra_between_the_clear_fraction_bounds():
    # every ray's weight lies between the clear fraction at the ground and 1, so the
    # cloudy illuminance lies between P_clear(0) x clear and clear, at every point;
    # outside the penumbra (offset 9e6 m, the whole Sun seen) the ring adds < 1e-3
    cover = cloud_climatology()
    offsets = (0.0, 2.5e6, 4.2e6, 9.0e6)
    clear = _illuminance(_shadow(), offsets)
    cloudy = _illuminance(_shadow(cloud_cover=cover), offsets)
    lowest = float(cover.clear_fraction(torch.zeros((), dtype=F64)))
    assert bool((cloudy <= clear * (1.0 + 1e-9)).all())
    assert bool((cloudy >= lowest * clear).all())
    assert bool((cloudy[:3] < clear[:3]).all())
    assert float((cloudy[3] / clear[3] - 1.0).abs().max()) < 1e-3


def test_gradients_of_the_profile_by_finite_differences():
    # d log I / d(cloud amounts, SAGE probability) through the climatology, the ray
    # weight and the ring integral, against central differences
    def log_illuminance(amounts, clear_7km):
        cover = cloud_climatology(clear_7km, amounts=amounts)
        return torch.log(_illuminance(_shadow(cloud_cover=cover), offsets=(0.0, 3.0e6)))

    amounts = torch.tensor([0.27, 0.19, 0.20], dtype=F64, requires_grad=True)
    clear = torch.tensor(0.5, dtype=F64, requires_grad=True)
    assert torch.autograd.gradcheck(log_illuminance, (amounts, clear), eps=1e-6, atol=1e-6,
                                    rtol=1e-4)


def test_bad_profiles_raise():
    with pytest.raises(ValueError, match="altitude_m"):
        LimbCloudCover([0.0, 3000.0, 2000.0], [0.6, 0.3, 0.0])
    with pytest.raises(ValueError, match="cover"):
        LimbCloudCover([0.0, 3000.0], [0.3, 0.6])
    with pytest.raises(ValueError, match="cover"):
        LimbCloudCover([0.0, 3000.0], [1.3, 0.0])
    with pytest.raises(ValueError, match="limb_exponent"):
        LimbCloudCover([0.0, 3000.0], [0.3, 0.0], limb_exponent=-1.0)
    with pytest.raises(ValueError, match="limb_clear_7km"):
        cloud_climatology(1.0)
    with pytest.raises(ValueError, match="amounts"):
        cloud_climatology(amounts=(0.5, 0.4, 0.3))
    with pytest.raises(TypeError, match="cloud_cover"):
        Shadow.earth(cloud_cover=(0.0, 0.66))
    with pytest.raises(ValueError, match="not both"):
        Shadow.earth(cloud_top_altitude_m=5e3, cloud_cover=cloud_climatology())
    needs = cloud_climatology(torch.tensor(0.5, dtype=F64, requires_grad=True))
    scattering = Shadow.earth(cloud_cover=needs, scattering=True, n_altitude=17)
    with pytest.raises(ValueError, match="cloud_cover"):
        scattering.relative_illuminance(MOON_M, 0.0, WAVELENGTH)


def test_light_curve_gradient_with_respect_to_the_cloud_profile():
    # d V(mid-totality) / d P_clear(7 km) through the shadow table and the light curve,
    # against central differences (the profile can be a retrieval parameter); and float32
    # geometry within 1e-5 of float64
    from skytorch.eclipse import lunar_light_curve

    def faintest_v(clear_7km):
        shadow = eclipse_shadow("2015-09-28", cloud_cover=cloud_climatology(clear_7km))
        curve = lunar_light_curve("2015-09-28", shadow=shadow, n_times=9, table_n_v=64)
        return curve["v_magnitude"].max()

    clear = torch.tensor(0.516, dtype=F64, requires_grad=True)
    faintest_v(clear).backward()
    step = 1e-4
    with torch.no_grad():
        central = (faintest_v(torch.tensor(0.516 + step, dtype=F64))
                   - faintest_v(torch.tensor(0.516 - step, dtype=F64))) / (2 * step)
    assert float(clear.grad) < 0.0  # clearer limb paths: a brighter Moon
    assert float(clear.grad) == pytest.approx(float(central), rel=1e-5)
    shadow = eclipse_shadow("2015-09-28")
    offset = torch.tensor([0.0, 3e6, 4.4e6])
    single = shadow.relative_illuminance(torch.full_like(offset, MOON_M), offset, [550.0])
    double = shadow.relative_illuminance(torch.full_like(offset, MOON_M).double(),
                                         offset.double(), [550.0])
    assert single.dtype == torch.float32
    torch.testing.assert_close(single.double(), double, rtol=1e-5, atol=0.0)


def test_eclipse_shadow_refuses_cloud_settings_of_another_model():
    """A cloud setting of another cloud model is refused (it was ignored: no deck at all)."""
    from skytorch.eclipse import cloud_climatology

    with pytest.raises(ValueError, match="cloud_fraction, cloud_top_altitude_m: settings"):
        eclipse_shadow("2015-09-28", cloud_top_altitude_m=8000.0, cloud_fraction=0.2)
    with pytest.raises(ValueError, match="cloud_top_altitude_m: settings of clouds='deck'"):
        eclipse_shadow("2015-09-28", clouds="none", cloud_top_altitude_m=8000.0)
    with pytest.raises(ValueError, match="cloud_cover: the profile"):
        eclipse_shadow("2015-09-28", clouds="deck", cloud_cover=cloud_climatology())
    deck = eclipse_shadow("2015-09-28", clouds="deck", cloud_top_altitude_m=8000.0)
    assert deck.parameters_dict()["cloud_top_altitude_m"] == 8000.0
