"""Limiting magnitude per direction and visible star counts (skytorch.scene.visibility_map).

References: Schaefer 1990 (PASP 102, 212) threshold model with its default observer, the
dark zenith 6.3-7.0 mag of the issue (Schaefer 1998, Sky & Telescope 95 (5), 57: 6.5 or so
for a typical observer at a dark site); a hemisphere holds half of the stars of an
all-sky catalogue (8916 Hipparcos stars to 6.5 mag: about 4 500 above the horizon).
"""

import importlib
import math

import numpy as np
import pytest
import torch

import skytorch as st
from skytorch.moon.sky import radiance_to_mag_arcsec2
from skytorch.nightsky import airglow_zenith_mag, zodiacal_spectral_radiance
from skytorch.scene.visibility_map import (
    limiting_magnitude_map,
    sky_mag_from_radiance,
    visible_star_count,
)

MAG = 1.0
FINE = torch.arange(380.0, 781.0, 2.0, dtype=torch.float64)


def _dark_zenith(flux_sfu):
    zl = zodiacal_spectral_radiance(torch.tensor(math.radians(120.0), dtype=torch.float64),
                                    torch.tensor(math.radians(30.0), dtype=torch.float64), FINE)
    zl_v = float(radiance_to_mag_arcsec2(zl, FINE))
    ag_v = float(airglow_zenith_mag(flux_sfu))
    return -2.5 * math.log10(10 ** (-0.4 * zl_v) + 10 ** (-0.4 * ag_v))


@pytest.mark.parametrize("flux_sfu", [70.0, 200.0])
def test_dark_zenith_limiting_magnitude_in_band(flux_sfu):
    limit = float(limiting_magnitude_map(torch.tensor([_dark_zenith(flux_sfu)]))[0])
    assert 6.3 <= limit <= 7.0


def test_sky_mag_of_dark_pixels_is_black_background():
    image = torch.zeros(2, 3, dtype=torch.float64)
    mag = sky_mag_from_radiance(image, torch.tensor([680.0, 550.0, 440.0], dtype=torch.float64))
    assert torch.all(mag == 40.0)
    assert float(limiting_magnitude_map(mag)[0]) == pytest.approx(7.93, abs=0.01)


def _hemisphere_index(catalog):
    scene = st.Scene(time="2024-03-10T02:00", lat_deg=-24.6, lon_deg=-70.4, view="fisheye",
                     size=64, fidelity="fast")
    view = scene.make_view()
    obs = st.stars.observe(catalog, np.datetime64("2024-03-10T02:00"), -24.6, -70.4,
                           refraction=False)
    alt = torch.deg2rad(torch.as_tensor(obs["altitude"].values[0]))
    az = torch.deg2rad(torch.as_tensor(obs["azimuth"].values[0]))
    return view, view.pixel_index(alt, az)


def test_count_above_horizon_is_half_the_catalogue():
    catalog = st.stars.bright_stars(6.5)
    view, index = _hemisphere_index(catalog)
    vmag = torch.as_tensor(catalog["vmag"].values)
    _, count = visible_star_count(vmag, index, torch.full(view.shape, 6.5, dtype=torch.float64))
    half = catalog.sizes["star"] / 2
    assert abs(int(count) - half) < 0.1 * half


def test_visible_count_rejects_bad_index():
    with pytest.raises(ValueError, match="pixel_index"):
        visible_star_count(torch.zeros(3), torch.tensor([0, 1, 99]), torch.zeros(2, 2))


def _natural(altitudes):
    render = importlib.import_module("skytorch.scene.render")
    from skytorch.scene.geometry import site_geometries
    from skytorch.scene.natural_sky import natural_component
    from skytorch.scene.resources import SceneResources

    scene = st.Scene(time="2024-03-10T02:00", lat_deg=-24.6, lon_deg=-70.4, elevation_m=2600.0,
                     fidelity="fast", view="directions",
                     directions={"altitude_deg": altitudes, "azimuth_deg": [0.0] * len(altitudes)})
    geometry = site_geometries(np.datetime64("2024-03-10T02:00"), [-24.6], [-70.4], [2600.0])[0]
    wl = scene.wavelength_nm()
    image = natural_component(SceneResources.for_scene(scene), scene.make_view(), geometry, wl,
                              render.Knobs.of(scene))
    return radiance_to_mag_arcsec2(image.to(torch.float64), wl)


def test_natural_component_dark_site_levels():
    """Zenith within the published dark-sky range; brighter towards the horizon (van Rhijn)."""
    mags = _natural([90.0, 30.0, 10.0])
    assert 21.2 < float(mags[0]) < 22.2
    assert float(mags[1]) < float(mags[0]) and float(mags[2]) < float(mags[0])


def test_visibility_helpers_refuse_what_they_cannot_mean():
    """Input the visibility helpers cannot mean is refused.

    Booleans as pixel indices (True was pixel 1), NaN magnitudes and limits (counted as not
    visible), negative radiance (a black 40 mag sky).
    """
    from skytorch.scene.visibility_map import sky_mag_from_radiance, visible_star_count

    limits = torch.tensor([6.0, 6.5, 7.0], dtype=torch.float64)
    with pytest.raises(TypeError, match="pixel_index"):
        visible_star_count(torch.tensor([1.0, 2.0]), torch.tensor([True, False]), limits)
    with pytest.raises(ValueError, match="magnitude must be finite"):
        visible_star_count(torch.tensor([1.0, float("nan")]), torch.tensor([0, 1]), limits)
    with pytest.raises(ValueError, match="limit_map must be finite"):
        visible_star_count(torch.tensor([1.0, 2.0]), torch.tensor([0, 1]),
                           torch.tensor([6.0, float("nan"), 7.0]))
    wavelength = torch.tensor([500.0, 550.0, 600.0], dtype=torch.float64)
    with pytest.raises(ValueError, match="spectral_radiance"):
        sky_mag_from_radiance(torch.tensor([1e-9, -5e-9, 1e-9], dtype=torch.float64),
                              wavelength)
    assert float(sky_mag_from_radiance(torch.zeros(3, dtype=torch.float64), wavelength)) == 40.0


def test_galactic_coordinates_and_van_rhijn_check_their_inputs():
    """Galactic coordinates take unit vectors; van Rhijn's law finite inputs.

    Vectors of length 5 gave another latitude, a (2, 2) input a raw RuntimeError;
    van_rhijn(nan) and a negative planet radius passed.
    """
    import math

    from skytorch.nightsky.airglow import van_rhijn
    from skytorch.nightsky.starlight import galactic_coordinates

    with pytest.raises(ValueError, match="unit vectors"):
        galactic_coordinates(torch.tensor([[0.0, 0.0, 5.0]], dtype=torch.float64))
    with pytest.raises(ValueError, match="last dimension of 3"):
        galactic_coordinates(torch.ones(2, 2, dtype=torch.float64))
    with pytest.raises(ValueError, match="zenith_rad must be finite"):
        van_rhijn(float("nan"))
    with pytest.raises(ValueError, match="planet_radius_m"):
        van_rhijn(0.5, planet_radius_m=-1.0)
    assert float(van_rhijn(math.pi / 2)) == pytest.approx(6.01, abs=0.005)
