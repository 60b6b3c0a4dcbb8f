"""Lunar-eclipse light curve: uneclipsed limit, totality range, colour, convergence, CLI.

References: the uneclipsed Moon from skytorch.moon.brightness.magnitude (a different
quadrature: photometric coordinates over the lit disc); the totality range V = -3.3 ... +2
(Hernitschek et al. 2008, Appl. Opt. 47, H62; Keen 1983, Science 222, 1011); the greatest
eclipse time from the circumstances (Five Millennium Canon validated); a converged
high-resolution disc sampling for the 0.01 mag requirement.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import torch

from skytorch.constants import MAG
from skytorch.eclipse.lunar import lunar_eclipse, plot_lunar_eclipse

DATE = "2015-09-28"


@pytest.fixture(scope="module")
def shadow():
    from skytorch.eclipse.shadow import Shadow

    return Shadow.earth()


@pytest.fixture(scope="module")
def curve(shadow):
    return lunar_eclipse(DATE, n_times=41, n_images=3, image_pixels=16, n_disc=8,
                         shadow=shadow)


def test_uneclipsed_matches_moon_magnitude(curve):
    from skytorch.ephemeris import sun_moon_vectors
    from skytorch.moon.brightness import magnitude

    times = curve.time.values[[0, -1]]
    vectors = sun_moon_vectors(times)
    sun, moon = vectors["sun_gcrs_m"], vectors["moon_gcrs_m"]
    to_sun = sun - moon
    phase = torch.acos((to_sun * -moon).sum(-1) / (to_sun.norm(dim=-1) * moon.norm(dim=-1)))
    expected = magnitude(phase, distance_m=moon.norm(dim=-1), sun_distance_m=to_sun.norm(dim=-1),
                         earthshine=False)
    value = curve.v_magnitude.values[[0, -1]]
    assert np.abs(value - expected.numpy()).max() < 0.02 * MAG
    assert curve.relative_brightness.values[[0, -1]].min() > 0.999


def test_totality_in_published_range_and_red(curve):
    greatest = float(curve.attrs["parameter_greatest_v_magnitude"])
    assert -3.3 < greatest < 2.0
    bv = curve.b_minus_v.values
    assert bv.max() > bv[0] + 0.5 * MAG  # reddened in the umbra
    colour = curve.colour.values[int(np.argmax(curve.v_magnitude.values))]
    assert colour[0] > colour[1] > colour[2]  # R > G > B at the darkest
    assert 0.0 <= float(curve.attrs["parameter_danjon_l"]) <= 4.0


def test_darkest_near_greatest_eclipse(curve):
    darkest = curve.time.values[int(np.argmax(curve.v_magnitude.values))]
    greatest = np.datetime64(curve.attrs["parameter_greatest_eclipse"])
    step = curve.time.values[1] - curve.time.values[0]
    assert abs(darkest - greatest) <= 2 * step


def test_disc_sampling_converged(shadow):
    """0.01 mag at mid-eclipse: default disc and table sampling vs finer ones."""
    coarse = lunar_eclipse(DATE, n_times=3, n_images=0, shadow=shadow)
    fine = lunar_eclipse(DATE, n_times=3, n_images=0, n_disc=32, shadow=shadow,
                         table_n_v=512)
    difference = np.abs(coarse.v_magnitude.values - fine.v_magnitude.values).max()
    assert difference < 0.01 * MAG


def test_dataset_and_figure(curve, tmp_path):
    from skytorch.dataset import open_dataset, to_netcdf

    assert curve.image.dims == ("image_time", "y", "x", "channel")
    assert float(curve.image.min()) >= 0.0 and float(curve.image.max()) <= 1.0
    for name in curve.data_vars:
        assert {"units", "long_name", "description"} <= set(curve[name].attrs)
    restored = open_dataset(to_netcdf(curve, tmp_path / "curve.nc"))
    np.testing.assert_allclose(restored.v_magnitude.values, curve.v_magnitude.values)
    plot_lunar_eclipse(curve, tmp_path / "curve.png")
    assert (tmp_path / "curve.png").stat().st_size > 10_000


def test_no_eclipse_raises():
    with pytest.raises(ValueError, match="no lunar eclipse"):
        lunar_eclipse("2016-01-01", n_times=3, n_images=0)


def test_cli_single_date(tmp_path, capsys, monkeypatch, shadow):
    from skytorch.cli import main
    from skytorch.commands import eclipse as command
    from skytorch.dataset import open_dataset

    model = functools.partial(lunar_eclipse, n_times=9, n_images=2, image_pixels=12,
                              n_disc=6, shadow=shadow)
    monkeypatch.setattr(command, "_light_curve_model", lambda: model)
    nc, png = tmp_path / "eclipse.nc", tmp_path / "eclipse.png"
    assert main(["eclipse", DATE, "-o", str(nc), "--png", str(png)]) == 0
    out = capsys.readouterr().out
    assert "2015-09-28T02:47" in out and "Danjon" in out
    assert open_dataset(nc).sizes["time"] == 9 and png.stat().st_size > 10_000


#: the shadow weights the disc non-uniformly, so the disc-integrated phase curve predicts
#: the ring-phase dimming only to a few mmag
RING_PHASE_TOLERANCE = 0.01 * MAG


def test_ring_phase_dims_totality_like_the_phase_curve():
    """Reflect the refracted light at the ring's phase angle.

    The change at greatest eclipse equals the lunar phase curve (skytorch.moon.magnitude,
    an independent disc integration) between the Sun's and the ring's phase angles; no
    change outside.
    """
    import math

    import numpy as np

    from skytorch.constants import EARTH_MEAN_RADIUS_M
    from skytorch.ephemeris import sun_moon_vectors
    from skytorch.moon import magnitude

    kwargs = {"n_times": 31, "table_n_v": 128, "n_images": 0}
    ring = lunar_eclipse("2015-09-28", **kwargs)
    sun_only = lunar_eclipse("2015-09-28", ring_phase=False, **kwargs)
    g = int(np.argmin(ring.shadow_axis_distance.values))
    vectors = sun_moon_vectors(ring.time.values[g:g + 1])
    sun, moon = vectors["sun_gcrs_m"][0], vectors["moon_gcrs_m"][0]
    alpha_sun = torch.acos(torch.dot(sun - moon, -moon) / torch.linalg.norm(sun - moon)
                           / torch.linalg.norm(moon))
    alpha_ring = torch.tensor(math.asin(EARTH_MEAN_RADIUS_M / float(torch.linalg.norm(moon))),
                              dtype=torch.float64)
    expected = float(magnitude(alpha_ring) - magnitude(alpha_sun))
    change = float(ring.v_magnitude[g] - sun_only.v_magnitude[g])
    assert expected > 0.03 * MAG
    assert abs(change - expected) < RING_PHASE_TOLERANCE
    assert float(abs(ring.v_magnitude[0] - sun_only.v_magnitude[0])) < 1e-9 * MAG


#: batched and single-member shadow tables differ only by floating-point rounding
BATCH_TOLERANCE = 1e-9 * MAG


def test_batched_atmosphere_equals_member_loop():
    """Batch an atmosphere (turbidity x ozone) into Dataset dims.

    Its members equal lunar_eclipse run member by member (reference: the unbatched code
    path).
    """
    from skytorch.atmosphere import Atmosphere

    turbidity = torch.tensor([[1.5], [3.0]], dtype=torch.float64)
    ozone = torch.tensor([[250.0, 350.0]], dtype=torch.float64)
    kwargs = {"n_times": 7, "n_images": 2, "image_pixels": 8, "n_disc": 6, "table_n_v": 64}
    batched = lunar_eclipse(DATE, Atmosphere.earth(turbidity=turbidity, ozone_du=ozone),
                            batch_dims=["haze", "ozone_du"], **kwargs)
    assert batched.v_magnitude.dims == ("haze", "ozone_du", "time")
    assert batched.image.dims == ("haze", "ozone_du", "image_time", "y", "x", "channel")
    np.testing.assert_allclose(batched.ozone_du.values, [250.0, 350.0])
    assert batched.angstrom_beta.dims == ("haze",)
    assert list(batched.haze.values) == [0, 1]
    for i in range(2):
        for j in range(2):
            single = lunar_eclipse(DATE, Atmosphere.earth(turbidity=float(turbidity[i, 0]),
                                                          ozone_du=float(ozone[0, j])),
                                   **kwargs)
            member = batched.isel(haze=i, ozone_du=j)
            for name in ("v_magnitude", "b_magnitude", "image_v_magnitude"):
                np.testing.assert_allclose(member[name].values, single[name].values, rtol=0,
                                           atol=BATCH_TOLERANCE)
            np.testing.assert_allclose(member.image.values, single.image.values, atol=1e-9)
            np.testing.assert_allclose(member.spectral_irradiance.values,
                                       single.spectral_irradiance.values, rtol=1e-9)
            assert float(member.greatest_v_magnitude) == pytest.approx(
                float(single.attrs["parameter_greatest_v_magnitude"]), abs=BATCH_TOLERANCE)
            assert float(member.danjon_l) == pytest.approx(
                float(single.attrs["parameter_danjon_l"]), abs=1e-9)
    # more aerosol, darker totality
    greatest = batched.greatest_v_magnitude.values
    assert (greatest[1] > greatest[0]).all()


def test_batched_dataset_round_trip_and_dimension_names(tmp_path):
    from skytorch.atmosphere import Atmosphere
    from skytorch.dataset import open_dataset, to_netcdf

    atmosphere = Atmosphere.earth(turbidity=torch.tensor([1.5, 3.0], dtype=torch.float64))
    curve = lunar_eclipse(DATE, atmosphere, n_times=4, n_images=0, n_disc=4, table_n_v=48)
    assert curve.v_magnitude.dims == ("atmosphere_0", "time")
    restored = open_dataset(to_netcdf(curve, tmp_path / "batched.nc"))
    np.testing.assert_allclose(restored.v_magnitude.values, curve.v_magnitude.values)
    with pytest.raises(ValueError, match="select a member"):
        plot_lunar_eclipse(curve)
    plot_lunar_eclipse(curve.isel(atmosphere_0=1), tmp_path / "member.png")
    with pytest.raises(ValueError, match="batch_dims"):
        lunar_eclipse(DATE, atmosphere, n_times=3, n_images=0, table_n_v=32,
                      batch_dims=["time"])


def test_greatest_magnitude_is_at_greatest_eclipse_whatever_the_samples():
    """The 'greatest V' of a series is the light curve's value at greatest eclipse.

    From a single sample 2 h 17 min before greatest eclipse it was that sample's (-12.93).
    """
    from skytorch.eclipse import lunar_light_curve

    options = {"n_disc": 4, "table_n_v": 32}
    early = lunar_light_curve(DATE, times=["2015-09-28T00:30"], **options)
    at_greatest = lunar_light_curve(DATE, times=["2015-09-28T02:47:08"], **options)
    assert float(early["v_magnitude"][0]) < -12.0                     # the uneclipsed Moon
    assert float(early["greatest_v_magnitude"]) == pytest.approx(
        float(at_greatest["v_magnitude"][0]), abs=0.01 * MAG)
    assert float(early["greatest_v_magnitude"]) > -3.3


def test_a_grid_that_misses_the_bands_gives_no_false_colour():
    """A grid without a wavelength in V is refused; without two in B, B and B - V are NaN.

    One red wavelength gave V -5.27 at totality and B - V 0.60 in the umbra.
    """
    from skytorch.eclipse import lunar_light_curve

    options = {"n_times": 3, "n_disc": 3, "table_n_v": 16}
    with pytest.raises(ValueError, match="within the V band"):
        lunar_light_curve(DATE, wavelength_nm=[700.0], **options)
    curve = lunar_light_curve(DATE, wavelength_nm=[550.0, 650.0], **options)
    assert bool(torch.isnan(curve["b_minus_v"]).all())
    assert bool(torch.isfinite(curve["v_magnitude"]).all())
