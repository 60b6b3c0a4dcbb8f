"""Scenes with the natural sky built from its parts (natural_model="leinert1998")."""

import math

import numpy as np
import pytest
import torch

from skytorch.scene import Scene
from skytorch.stars.visibility import limiting_magnitude

# Paranal (Patat 2008, A&A 481, 575: dark-time zenith V 22.0 near solar minimum and 21.6
# near maximum, nightly values scattered by about 0.2 mag)
PARANAL = dict(lat_deg=-24.63, lon_deg=-70.40, elevation_m=2635.0)
NIGHT = "2026-03-20T04:00:00"  # Sun 40 deg below the horizon, Moon down
# Patat's skies are measured on CCD frames between the resolved stars, so they hold
# little of the integrated starlight that the natural component includes (stars fainter
# than the point-star limit and the Pioneer 10/11 starlight); the comparison is made
# with the south galactic pole near the zenith (new Moon, Sun 70 deg down), where that
# starlight adds about 0.07 mag (docs/nightsky.md); at NIGHT (b = +33 deg) it adds 0.15
PATAT_NIGHT = "2026-09-11T04:45:00"


def _zenith(flux_sfu: float, time: str = PATAT_NIGHT) -> float:
    scene = Scene(time=time, size=32, natural_model="leinert1998", solar_flux_sfu=flux_sfu,
                  exclude=("stars",), **PARANAL)
    image = scene.render().component_v_mag_arcsec2.sel(component="natural")
    return float(image.isel(y=16, x=16))


@pytest.mark.parametrize("flux_sfu, patat", [(70.0, 22.0), (200.0, 21.6)])
def test_dark_zenith_against_patat_2008(flux_sfu, patat):
    # 0.35 mag: Patat's values are means over fields at all ecliptic latitudes, while the
    # zodiacal light at one zenith differs from its sky mean by a few tenths of a
    # magnitude (Leinert et al. 1998, Table 17); measured here 21.77 and 21.28, i.e. 0.23
    # and 0.32 mag brighter than Patat's means
    assert abs(_zenith(flux_sfu) - patat) < 0.35


def test_solar_cycle_change_against_patat_2008():
    """Patat 2008: the dark zenith is about 0.4 mag brighter at solar maximum."""
    assert abs((_zenith(70.0) - _zenith(200.0)) - 0.4) < 0.15


def test_solar_flux_out_of_range_is_refused():
    with pytest.raises(ValueError, match="solar_flux_sfu"):
        Scene(time=NIGHT, size=8, natural_model="leinert1998", solar_flux_sfu=10.0, **PARANAL)


def test_every_render_has_a_limiting_magnitude_map():
    """Dark zenith 6.3-7.0 with Schaefer's default observer (issue 17); none by day."""
    night = Scene(time=NIGHT, size=32, natural_model="leinert1998", solar_flux_sfu=70.0,
                  exclude=("stars",), **PARANAL).render()
    limit = night.limiting_magnitude
    assert limit.dims == night.v_mag_arcsec2.dims
    assert 6.3 <= float(limit.isel(y=16, x=16)) <= 7.0
    day = Scene(time="2026-03-20T16:00:00", size=32, **PARANAL).render()
    assert float(day.limiting_magnitude.isel(y=16, x=16)) < 0.0


def test_limiting_magnitude_map_leaves_out_the_stars_drawn():
    """A star does not hide itself: the map is that of the sky without the stars drawn.

    Schaefer's threshold is for a point source against its background; with the stars'
    light in the background a 0-mag star's pixel fell from a limit of 6.1 to 4.1. At night
    with the Moon down the background is the natural component alone.
    """
    night = Scene(time=NIGHT, size=64, natural_model="leinert1998", solar_flux_sfu=70.0,
                  star_limit_mag=6.0, **PARANAL).render()
    assert night.attrs["effects_computed"] == "stars,refraction"
    stars = night.component_radiance.sel(component="stars").sum("wavelength").values
    assert (stars > 0).sum() > 100                                 # pixels that hold a star
    natural = night.component_v_mag_arcsec2.sel(component="natural").values
    valid = ~np.isnan(natural)
    expected = limiting_magnitude(torch.tensor(natural[valid], dtype=torch.float64)).numpy()
    np.testing.assert_allclose(night.limiting_magnitude.values[valid], expected, rtol=1e-12)
    # with the stars in the background, a star's pixel would be brighter than its sky
    assert (night.v_mag_arcsec2.values[stars > 0] < natural[stars > 0]).all()


@pytest.mark.parametrize("turbidity", [4.0, 10.0])
def test_dark_night_renders_in_hazy_air(turbidity):
    """A dark night in hazy air renders; where the sky is black the limit is a black sky's.

    The horizon's natural sky is darker than 40 mag arcsec^-2 in hazy air (Garstang's
    extinction over the long horizontal path).

    Before 2026-12-07 such a pixel stopped the render (ValueError from Schaefer's range).
    """
    ds = Scene(time="2015-09-13T23:00", lat_deg=52.52, lon_deg=13.40, size=32,
               turbidity=turbidity).render()
    limit = ds.limiting_magnitude.values
    valid = ~np.isnan(ds.v_mag_arcsec2.values)
    assert np.isfinite(limit[valid]).all()
    # Schaefer's limit against a black background (40 mag arcsec^-2) is the largest
    black = float(limiting_magnitude(torch.tensor(40.0, dtype=torch.float64)))
    assert limit[valid].max() <= black + 1e-9


def test_scattered_airglow_brightens_the_horizon_not_the_zenith(monkeypatch):
    """The airglow scattered into the line of sight: zenith level kept, horizon brighter.

    Against the same render with the scattered-airglow table set to zero (direct airglow
    only). Measured at Paranal: zenith unchanged, 0.1 mag or more within ~5° of the
    horizon (docs/nightsky.md).
    """
    from skytorch.scene.resources import SceneResources

    def row(scattered):
        original = SceneResources.scattered_airglow_table

        def table(self, elevation_m, layer_height_m):
            zenith, wavelength, radiance = original(self, elevation_m, layer_height_m)
            return zenith, wavelength, radiance if scattered else 0.0 * radiance

        monkeypatch.setattr(SceneResources, "scattered_airglow_table", table)
        scene = Scene(time=PATAT_NIGHT, size=32, natural_model="leinert1998",
                      solar_flux_sfu=70.0, exclude=("stars",), **PARANAL)
        image = scene.render().component_v_mag_arcsec2.sel(component="natural")
        return image.isel(y=16).values[16:]

    with_light, direct_only = row(True), row(False)
    assert abs(with_light[0] - direct_only[0]) < 0.01  # zenith [mag]
    assert direct_only[-1] - with_light[-1] > 0.1  # lowest pixel [mag]
    assert bool((with_light <= direct_only + 1e-9).all())


#: dates (Paranal, Sun and Moon down) with the zodiacal light at the zenith from 94 to
#: 204 (10^-8 W m^-2 sr^-1 µm^-1 at 500 nm)
SCATTERED_ZL_NIGHTS = ("2026-09-11T04:45:00", "2026-03-20T23:30:00", "2026-06-21T04:00:00",
                       "2026-12-21T03:00:00")


def _eso_scattered_zodiacal_fraction(brightness_500, tau_rayleigh, tau_aerosol):
    """Scattered zodiacal light at the zenith over its brightness above the air, ESO model.

    The Cerro Paranal sky model (Noll et al. 2012, §3.3, eqs. 19-20, as in its released
    code ``sm_skyemcomp.c``, ``sm_comp_zodskybright``) extinguishes the zodiacal light of
    brightness I0 [10^-8 W m^-2 sr^-1 µm^-1, 500 nm] with effective optical depths f_R
    tau_R and f_M tau_M, the factors parametrised from three-dimensional scattering
    calculations of extended emission; the scattered part is what that adds to the point
    source's exp(-tau).
    """
    lg = math.log10(brightness_500)
    f_r = 1.4072 * lg - 2.6916 if lg <= 2.2444 else 0.5267 * lg - 0.7152
    f_m = 1.3088 * lg - 2.5976 if lg <= 2.2546 else 0.4683 * lg - 0.7025
    return (math.exp(-(f_r * tau_rayleigh + f_m * tau_aerosol))
            - math.exp(-(tau_rayleigh + tau_aerosol)))


@pytest.mark.parametrize("time", SCATTERED_ZL_NIGHTS)
def test_scattered_zodiacal_light_at_the_zenith_against_the_eso_sky_model(monkeypatch, time):
    """Zodiacal light scattered into the zenith at 550 nm, against the ESO sky model's recipe.

    Ours (single scattering of the azimuthal means above the air) over the ESO model's
    (the scene atmosphere's Rayleigh and aerosol optical depths at the site, 0.070 and
    0.011): measured 0.69, 1.12, 0.66 and 0.72 on these nights (0.026-0.081 of the
    zodiacal light above the air against 0.040-0.073). The ESO factors include light
    arriving after more than one scattering and depend on the line of sight's own
    brightness only; allowed: 0.4-1.25.
    """
    import torch

    import skytorch.scene.natural_sky as natural
    from skytorch.nightsky import zodiacal_brightness_500, zodiacal_spectral_radiance

    def zodiacal_only(icrs, sun_lon, wavelength, knobs):
        lon, lat = natural.ecliptic_coordinates(icrs)
        return zodiacal_spectral_radiance(lon - sun_lon, lat, wavelength)

    measured = {}
    scattered = natural._scattered_zodiacal_and_starlight

    def capture(resources, knobs, zenith, sun_lon, wavelength, source=None):
        up = torch.zeros(1, dtype=torch.float64)
        value = scattered(resources, knobs, up, sun_lon, wavelength, zodiacal_only)[0]
        icrs = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64) @ natural.view_icrs_matrix(
            knobs)
        lon, lat = natural.ecliptic_coordinates(icrs)
        index = int(torch.argmin((wavelength - 550.0).abs()))
        above = zodiacal_spectral_radiance(lon - sun_lon, lat, wavelength)[index]
        measured.update(fraction=float(value[index] / above),
                        brightness=float(zodiacal_brightness_500(lon - sun_lon, lat)) * 1e11,
                        wavelength=float(wavelength[index]))
        optical = resources.atmosphere.optical_depth(
            wavelength[index:index + 1], 0.0, knobs.elevation_m, per_species=True)
        measured.update(rayleigh=float(optical["rayleigh"][0]),
                        aerosol=float(optical["aerosol"][0]
                                      + optical["stratospheric_aerosol"][0]))
        return scattered(resources, knobs, zenith, sun_lon, wavelength, source)

    monkeypatch.setattr(natural, "_scattered_zodiacal_and_starlight", capture)
    Scene(time=time, size=8, natural_model="leinert1998", exclude=("stars",),
          **PARANAL).render()
    assert abs(measured["wavelength"] - 550.0) < 30.0
    eso = _eso_scattered_zodiacal_fraction(measured["brightness"], measured["rayleigh"],
                                           measured["aerosol"])
    assert 0.4 * eso <= measured["fraction"] <= 1.25 * eso, (measured, eso)


def test_leinert_settings_are_checked_when_the_scene_is_made():
    """The leinert1998 settings are checked when the scene is made.

    A limit outside the catalogue map failed at render() naming fainter_than; the zenith
    value and the airglow share, unused by this model, changed the planner's decisions.
    """
    for settings, name in (({"star_limit_mag": 11.0}, "star_limit_mag"),
                           ({"star_limit_mag": -2.5}, "star_limit_mag"),
                           ({"natural_mag_arcsec2": 14.0}, "natural_mag_arcsec2"),
                           ({"airglow_fraction": 0.3}, "airglow_fraction")):
        with pytest.raises(ValueError, match=name):
            Scene(time=NIGHT, size=8, natural_model="leinert1998", **settings, **PARANAL)
