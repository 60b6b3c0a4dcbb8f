"""Scene renders: energy, colour of the day and sunset sky, the natural night background.

References: CIE D65 white point (0.3127, 0.3290) (CIE 15:2004); clear-sky zenith
chromaticities measured bluer than D65 (Hernández-Andrés, Romero & Lee 2001, JOSA A 18,
412, doi:10.1364/JOSAA.18.000412: x ≈ 0.25–0.30); the sunset sky towards the Sun is red
near the horizon; natural zenith background 22.0 V mag arcsec^-2 (Falchi et al. 2016,
doi:10.1126/sciadv.1600377).
"""

import numpy as np
import pytest
import torch

import skytorch as st
from skytorch.constants import MAG

D65 = (0.3127, 0.3290)
#: largest clear-sky zenith x measured by Hernández-Andrés et al. (2001)
CLEAR_SKY_ZENITH_MAX_X = 0.30
NATURAL_ZENITH_MAG = 22.0
PARIS = {"lat_deg": 48.85, "lon_deg": 2.35}
ALTITUDES = [90.0, 45.0, 20.0, 10.0, 5.0, 2.0, 0.5]


def chromaticity(ds):
    xyz = ds["xyz"].values
    return xyz[..., :2] / xyz.sum(-1, keepdims=True)


def towards_sun(time, dtype=torch.float64):
    base = st.Scene(time=time, **PARIS, view="directions", fidelity="fast", dtype=dtype,
                    directions={"altitude_deg": [90.0], "azimuth_deg": [0.0]})
    azimuth = base.plan().geometry.sun_azimuth_deg
    return base.replace(directions={"altitude_deg": ALTITUDES,
                                    "azimuth_deg": [azimuth] * len(ALTITUDES)})


def test_day_sky_is_blue_at_the_zenith():
    ds = towards_sun("2015-06-21T12:00").render()
    x, y = chromaticity(ds)[0]
    assert x < D65[0] and y < D65[1]
    assert x < CLEAR_SKY_ZENITH_MAX_X


def test_sunset_sky_reddens_towards_the_horizon():
    scene = towards_sun("2015-06-21T19:45")  # Sun 0.8 deg above the horizon
    assert 0.0 < scene.plan().geometry.sun_altitude_deg < 2.0
    xy = chromaticity(scene.render())
    assert np.all(np.diff(xy[:, 0]) > 0.0)  # x grows from the zenith to the horizon
    assert xy[0, 0] < D65[0] < xy[-1, 0]  # bluish zenith, reddish horizon
    assert xy[-1, 0] > 0.5


def _dark_night(**kwargs):
    return st.Scene(time="2015-09-13T23:00", lat_deg=52.52, lon_deg=13.40,
                    view="directions", fidelity="fast",
                    directions={"altitude_deg": ALTITUDES, "azimuth_deg": [0.0] * 7},
                    **kwargs)


def test_night_sky_without_lights_reaches_the_natural_background():
    ds = _dark_night(natural_model="constant").render()
    assert ds.attrs["effects_computed"] == ""
    np.testing.assert_allclose(ds["v_mag_arcsec2"].values, NATURAL_ZENITH_MAG,
                               atol=0.01 * MAG)
    np.testing.assert_allclose(ds["component_v_mag_arcsec2"].sel(component="natural").values,
                               NATURAL_ZENITH_MAG, atol=0.01 * MAG)


@pytest.mark.parametrize(("fraction", "height_m"), [(0.6, 90e3), (1.0, 130e3)])
def test_natural_background_follows_van_rhijn(fraction, height_m):
    """Garstang (1989, eq. 29) / Patat (2003, eq. C.1).

    b(z) = b0 [(1 - f) + f X] with the van Rhijn (1921) path factor X = (1 - (R / (R + h))^2 sin^2
    z)^(-1/2); Garstang's 0.96 is h = 130 km.
    """
    ds = _dark_night(natural_model="vanrhijn1921", airglow_fraction=fraction,
                     airglow_height_m=height_m).render()
    zenith = np.radians(90.0 - np.asarray(ALTITUDES))
    ratio2 = 0.96 if height_m == 130e3 else (6_371e3 / (6_371e3 + height_m)) ** 2
    closed_form = (1.0 - fraction) + fraction / np.sqrt(1.0 - ratio2 * np.sin(zenith) ** 2)
    expected = NATURAL_ZENITH_MAG - 2.5 * np.log10(closed_form)
    # Garstang's rounded 0.96 against (6371 / 6501)^2 = 0.9604: within 0.01 mag
    np.testing.assert_allclose(ds["v_mag_arcsec2"].values, expected, atol=0.01 * MAG)
    assert ds["v_mag_arcsec2"].values[0] == pytest.approx(NATURAL_ZENITH_MAG, abs=0.01 * MAG)
    assert np.all(np.diff(ds["v_mag_arcsec2"].values) < 0.0)  # brighter towards the horizon


#: Kasten & Young's air mass against the model atmosphere's (straight rays: -0.64 % at
#: z = 80°, i.e. 0.009 mag of k X = 1.4 mag) and the V band's curvature of k X
NATURAL_EXTINCTION_TOLERANCE = 0.02 * MAG
#: the direct V-band path integral against the interpolated extinction table near the
#: horizon (tens of magnitudes of optical depth in some channels)
NATURAL_HORIZON_TOLERANCE = 0.02 * MAG


@pytest.mark.parametrize("turbidity", [2.0, 3.0])
def test_natural_background_is_dimmed_by_extinction(turbidity, dtype):
    """Garstang (1989) / Krisciunas & Schaefer (1991, eq. 2) / Patat (2003).

    b(z) = b0 [(1 - f) + f V(z)] 10^(-0.4 k (X - 1)) with the observed zenith value b0 = 22.0
    mag/arcsec^2, k the atmosphere's V-band zenith extinction (st.stars.extinction_coefficient) and
    X Kasten & Young's (1989) air mass, down to 10° altitude; near the horizon, where Kasten &
    Young's air mass no longer fits the aerosol's thin layer, the V-band magnitude loss of a solar
    spectrum along the straight path through the atmosphere (Atmosphere.transmittance) instead.
    """
    from skytorch.atmosphere.optical_depth import kasten_young_air_mass
    from skytorch.moon.brightness import V_BAND_WAVELENGTHS_NM
    from skytorch.spectrum import solar_irradiance, spectrum_to_magnitude

    scene = _dark_night(turbidity=turbidity, dtype=dtype)
    ds = scene.render()
    assert "refraction" not in ds.attrs["effects_computed"]  # straight rays
    measured = ds["v_mag_arcsec2"].values.astype(np.float64)
    zenith = np.radians(90.0 - np.asarray(ALTITUDES))
    ratio2 = (6_371e3 / (6_371e3 + 90e3)) ** 2
    gradient = 0.4 + 0.6 / np.sqrt(1.0 - ratio2 * np.sin(zenith) ** 2)
    k = float(st.stars.extinction_coefficient(scene.atmosphere(), 0.0, bv=0.65))
    air_mass = kasten_young_air_mass(torch.tensor(zenith)).numpy()
    closed_form = NATURAL_ZENITH_MAG - 2.5 * np.log10(gradient) + k * (air_mass - 1.0)
    high = np.asarray(ALTITUDES) >= 10.0
    np.testing.assert_allclose(measured[high], closed_form[high],
                               atol=NATURAL_EXTINCTION_TOLERANCE)
    assert measured[0] == pytest.approx(NATURAL_ZENITH_MAG, abs=0.01 * MAG)
    # near the horizon: a solar spectrum through the straight path, in V
    wavelength = torch.tensor(V_BAND_WAVELENGTHS_NM, dtype=torch.float64)
    transmittance = scene.atmosphere().transmittance(
        wavelength, torch.tensor(np.append(zenith, 0.0))[:, None], 0.0)
    spectra = solar_irradiance(wavelength) * transmittance
    loss = spectrum_to_magnitude(spectra, wavelength).numpy().reshape(-1)
    path = NATURAL_ZENITH_MAG - 2.5 * np.log10(gradient) + loss[:-1] - loss[-1]
    np.testing.assert_allclose(measured, path, atol=NATURAL_HORIZON_TOLERANCE)


@pytest.mark.parametrize("time", ["2015-06-21T12:00", "2015-09-28T02:47"])
def test_energy_is_finite_and_non_negative(time, dtype):
    ds = st.Scene(time=time, lat_deg=52.52, lon_deg=13.40, size=24, fidelity="fast",
                  dtype=dtype, star_limit_mag=4.0).render()
    radiance = ds["component_radiance"].values
    assert np.isfinite(radiance).all() and (radiance >= 0.0).all()
    assert ds["radiance"].dtype == (np.float64 if dtype == torch.float64 else np.float32)
    srgb = ds["srgb"].values
    assert (srgb >= 0.0).all() and (srgb <= 1.0).all()
    # the components add up to the total
    np.testing.assert_allclose(radiance.sum(0), ds["radiance"].values, rtol=1e-5)


def test_point_sources_keep_their_flux():
    """The Sun's disc integrates back to the solar spectrum times the transmittance."""
    from skytorch.spectrum import solar_irradiance

    scene = st.Scene(time="2015-06-21T12:00", **PARIS, size=64, fidelity="fast")
    ds = scene.render()
    sun = ds["component_radiance"].sel(component="sun").values
    flux = (sun * ds["solid_angle"].values[..., None]).sum((0, 1))
    g = scene.plan().geometry
    zenith = torch.tensor(np.radians(90.0 - g.sun_altitude_deg), dtype=torch.float64)
    wl = scene.wavelength_nm()
    expected = (solar_irradiance(wl) * scene.atmosphere().transmittance(wl, zenith)
                * (1.495978707e11 / g.sun_distance_m) ** 2)
    np.testing.assert_allclose(flux, expected.numpy(), rtol=1e-3)


def test_panorama_and_png(tmp_path):
    ds = st.Scene(time="2015-06-21T19:45", **PARIS, view="panorama", size=12,
                  fidelity="fast").render()
    assert ds["radiance"].dims == ("elevation", "azimuth", "wavelength")
    # a panorama's solid angles cover the hemisphere
    np.testing.assert_allclose(ds["solid_angle"].values.sum(), 2 * np.pi, rtol=1e-3)
    path = st.scene.scene_png(ds, tmp_path / "pano.png", night=True)
    assert path.stat().st_size > 200


def test_fisheye_solid_angles_cover_the_hemisphere():
    from skytorch.scene.scene import fisheye_view

    view = fisheye_view(256)
    # pixelisation of the rim: error ~ perimeter/area of the disc in pixels
    np.testing.assert_allclose(float(view.solid_angle_sr.sum()), 2 * np.pi, rtol=1e-2)


def test_night_vision_desaturates_dark_skies():
    from skytorch.scene.tonemap import night_vision

    dark = torch.tensor([0.8e-3, 1.0e-3, 0.3e-3], dtype=torch.float64)  # reddish, dim
    bright = dark * 1e5
    out_dark, out_bright = night_vision(dark), night_vision(bright)
    torch.testing.assert_close(out_bright, bright)  # photopic: unchanged
    xy = out_dark[:2] / out_dark.sum()
    torch.testing.assert_close(xy, torch.tensor([0.25, 0.25], dtype=torch.float64))


def test_render_times_stacks_instants(tmp_path):
    from skytorch.dataset import open_dataset, to_netcdf

    scene = st.Scene(time="2015-06-21T12:00", **PARIS, view="directions", fidelity="fast",
                     directions={"altitude_deg": [90.0], "azimuth_deg": [0.0]})
    ds = st.scene.render_times(scene, ["2015-06-21T12:00", "2015-06-21T20:30",
                                       "2015-06-21T23:30"])
    assert ds["v_mag_arcsec2"].dims == ("time", "direction")
    assert list(ds["effects_computed"].values) == ["sky", "sky", ""]
    mags = ds["v_mag_arcsec2"].values[:, 0]
    assert mags[0] < mags[1] < mags[2]  # day, civil twilight, night
    np.testing.assert_allclose(mags[2], NATURAL_ZENITH_MAG, atol=0.01 * MAG)
    # the sky component is absent at night: zero radiance there, not missing
    night_sky = ds["component_radiance"].sel(component="sky").values[2]
    assert (night_sky == 0.0).all()
    again = open_dataset(to_netcdf(ds, tmp_path / "series.nc"))
    np.testing.assert_array_equal(again["radiance"].values, ds["radiance"].values)


def test_render_times_keeps_the_orders_of_scattering_per_frame():
    """A day and a night frame: the orders of scattering differ and stay per frame."""
    scene = st.Scene(time="2015-06-21T12:00", **PARIS, view="directions",
                     directions={"altitude_deg": [90.0], "azimuth_deg": [0.0]})
    frames = [scene.replace(time=t).render() for t in ("2015-06-21T12:00", "2015-06-21T23:30")]
    assert frames[0].attrs["sky_scattering_orders"] != frames[1].attrs["sky_scattering_orders"]
    ds = st.scene.render_times(scene, ["2015-06-21T12:00", "2015-06-21T23:30"])
    assert ds["sky_scattering_orders"].dims == ("time",)
    assert list(ds["sky_scattering_orders"].values) == [
        str(f.attrs["sky_scattering_orders"]) for f in frames]


def test_scene_png_refuses_what_it_cannot_draw(tmp_path):
    """No xyz among the outputs, a non-positive or NaN exposure, a night flag 'yes'."""
    from skytorch.scene import scene_png

    scene = st.Scene(time="2015-06-21T19:45", lat_deg=48.85, lon_deg=2.35, size=8,
                     fidelity="fast")
    ds = scene.render()
    for exposure, message in ((-1.0, "exposure must be > 0"), (0.0, "exposure must be > 0"),
                              (float("nan"), "exposure must be finite")):
        with pytest.raises(ValueError, match=message):
            scene_png(ds, tmp_path / "x.png", exposure=exposure)
    with pytest.raises(TypeError, match="night must be True or False"):
        scene_png(ds, tmp_path / "x.png", night="yes")
    with pytest.raises(ValueError, match=r"lacks \['xyz'\]"):
        scene_png(scene.replace(outputs=("v_mag",)).render(), tmp_path / "x.png")
    assert scene_png(ds, tmp_path / "x.png", exposure=2.0).stat().st_size > 0
