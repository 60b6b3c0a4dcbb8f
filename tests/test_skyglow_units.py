"""Astronomers' units, lamp spectra and synthetic city maps for skyglow."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from _skyglow_standin import single_torch_thread  # noqa: F401

from skytorch.constants import MAG, PERCENT
from skytorch.skyglow import lamps, units
from skytorch.skyglow.citymap import point_sources, synthetic_city

#: lamp CCT tolerance of the fitted spectral models [K]
CCT_TOLERANCE_K = 100.0


def test_falchi_luminance_magnitude_relation():
    # Falchi et al. 2016: L = 10.8e4 * 10^(-0.4 m) cd/m^2; 22.0 mag/arcsec^2 -> 1.71e-4
    assert float(units.mag_arcsec2_to_luminance(22.0)) == pytest.approx(
        10.8e4 * 10 ** (-8.8), rel=1e-12)
    assert float(units.natural_luminance()) == pytest.approx(1.711e-4, rel=0.1 * PERCENT)
    m = torch.tensor([16.0, 19.5, 21.9], dtype=torch.float64)
    back = units.luminance_to_mag_arcsec2(units.mag_arcsec2_to_luminance(m))
    assert torch.allclose(back, m, atol=1e-9 * MAG)
    with pytest.raises(ValueError, match="luminance_cd_m2"):
        units.luminance_to_mag_arcsec2(0.0)


def test_nanolambert_and_ratio():
    # 1 lambert = 1e4/pi cd/m^2, so 1 cd/m^2 = pi * 1e5 nL
    assert float(units.luminance_to_nanolambert(1.0)) == pytest.approx(math.pi * 1e5,
                                                                        rel=1e-12)
    assert float(units.nanolambert_to_luminance(math.pi * 1e5)) == pytest.approx(1.0)
    natural = units.natural_luminance()
    assert float(units.artificial_to_natural_ratio(natural)) == pytest.approx(1.0)
    # doubling the natural sky brightens it by 2.5 log10(2) = 0.753 mag
    assert float(units.total_mag_arcsec2(natural)) == pytest.approx(22.0 - 2.5 * math.log10(2))


def test_bortle_classes():
    m = torch.tensor([22.0, 21.7, 21.4, 21.0, 20.0, 19.0, 18.2, 17.7, 16.0])
    assert units.bortle_class(m).tolist() == [1, 2, 3, 4, 5, 6, 7, 8, 9]


@pytest.mark.parametrize("lamp, cct", [("led3000k", 3000.0), ("led4000k", 4000.0),
                                       ("hps", 2030.0), ("incandescent", 2856.0)])
def test_lamp_colour_temperatures(lamp, cct):
    from skytorch.spectrum import wavelength_grid

    wl = wavelength_grid("cie1")
    assert lamps.cct_mccamy(lamps.lamp_spectrum(lamp, wl), wl) == pytest.approx(
        cct, abs=CCT_TOLERANCE_K)


@pytest.mark.parametrize("lamp", lamps.LAMPS)
def test_per_lumen_spectra_emit_one_lumen(lamp):
    from skytorch.spectrum import photopic_luminous_efficiency, wavelength_grid

    wl = wavelength_grid("cie1")
    s = lamps.per_lumen(lamp)
    lumens = 683.002 * float(torch.trapezoid(s * photopic_luminous_efficiency(wl), wl))
    assert lumens == pytest.approx(1.0, rel=1e-9)
    weights, power = lamps.luminance_weights(lamp, torch.tensor([680.0, 550.0, 440.0]))
    assert float(weights.sum()) == pytest.approx(1.0, rel=1e-9)
    assert torch.all(power >= 0)
    with pytest.raises(ValueError, match="lamp"):
        lamps.lamp_spectrum("mercury", wl)


def test_custom_lamp_spectrum_carries_its_gradient():
    """A sampled lamp spectrum's values are differentiated (they were detached silently)."""
    wavelength = torch.linspace(380.0, 780.0, 9, dtype=torch.float64)
    spectrum = torch.linspace(1.0, 2.0, 9, dtype=torch.float64).requires_grad_(True)
    at = torch.tensor([450.0, 555.0, 650.0], dtype=torch.float64)
    assert torch.autograd.gradcheck(
        lambda values: lamps.per_lumen((wavelength, values), at), (spectrum,))
    with pytest.raises(ValueError, match="lamp_wavelength_nm"):
        lamps.per_lumen((wavelength.clone().requires_grad_(True), spectrum.detach()), at)


def test_synthetic_city_conserves_flux():
    city = synthetic_city(20_000.0, 500.0, population=5e4, lumens_per_capita=800.0,
                          n_towns=3, town_population=1e3, terrain_amplitude_m=300.0)
    assert float(city["flux"].sum()) == pytest.approx(800.0 * (5e4 + 3e3), rel=1e-9)
    assert city["flux"].dims == ("y", "x") and city["x"].attrs["units"] == "m"
    # a centre off the map put the whole city into the edge column (or, past ~1 500 km,
    # an empty map): refused
    for centre in ((10_001.0, 0.0), (0.0, -1e6)):
        with pytest.raises(ValueError, match="centre_xy"):
            synthetic_city(20_000.0, 500.0, centre_xy=centre)
    assert 0.0 <= float(city["altitude"].min()) and float(city["altitude"].max()) <= 300.0
    cells = point_sources(16, 10_000.0, 500.0, exclude_radius_m=1000.0)
    lit = cells["flux"].values > 0
    assert lit.sum() == 16
    xx, yy = np.meshgrid(cells["x"].values, cells["y"].values)
    assert np.all(np.hypot(xx, yy)[lit] >= 1000.0)


def test_star_overlay_counts():
    # Allen's Astrophysical Quantities: about 4800 stars brighter than V = 6.0 on the sky
    whole = float(units.visible_star_count(6.0, hemisphere=False))
    assert whole == pytest.approx(4800.0, rel=10 * PERCENT)
    limits = units.naked_eye_limiting_magnitude(torch.tensor([22.0, 20.0, 18.0]))
    counts = units.visible_star_count(limits)
    assert bool((torch.diff(limits) < 0).all()) and bool((torch.diff(counts) < 0).all())


@pytest.mark.parametrize("natural", [8.0, 30.0, math.nan])
def test_natural_sky_outside_the_range_of_the_renders_is_refused(natural):
    """The units take the natural sky of the scene and the skyglow render: 14–26."""
    for function in (units.natural_luminance,
                     lambda n: units.total_mag_arcsec2(torch.zeros(2), n),
                     lambda n: units.artificial_to_natural_ratio(torch.zeros(2), n)):
        with pytest.raises(ValueError, match="natural_mag_arcsec2"):
            function(natural)
