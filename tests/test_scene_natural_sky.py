"""Scenes with the natural sky built from its parts (natural_model="leinert1998")."""

import pytest

from skytorch.scene import Scene

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
    # magnitude (Leinert et al. 1998, Table 17); measured here 21.80 and 21.30, i.e. 0.20
    # and 0.30 mag brighter than Patat's means
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
