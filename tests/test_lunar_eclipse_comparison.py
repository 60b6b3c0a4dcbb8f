"""The lunar-eclipse comparison experiment: ingredients, clouds and a published light curve."""

import numpy as np
import pytest

from experiments.lunar_eclipse_comparison import ingredients, light_curve_2019

#: the issue's accuracy goal for the modelled V at mid-totality [mag]
GOAL_RMS_MAG = 0.5


@pytest.mark.slow
def test_each_ingredient_darkens_mid_totality():
    # extinction and blocked rays only remove light: adding ozone, tropospheric and
    # stratospheric aerosol and then clouds can only make the eclipsed Moon fainter
    dataset, figure, _ = ingredients(quick=True)
    v = dataset.greatest_v_magnitude.values
    labels = list(dataset.ingredient.values)
    assert np.all(np.diff(v[:5]) > 0.0), v
    # ozone: vertical optical depth at 550 nm of 300 DU is 300 x 2.687e16 cm-2 x
    # 3.3e-21 cm2 (Chappuis band) = 0.027; a grazing ray crosses the layer on a path of
    # at least ~10 vertical columns on each side of the tangent point, so at least
    # ~0.5 in optical depth (~0.5 mag) and not the 4+ mag of 150 columns
    assert 0.3 < v[1] - v[0] < 4.0
    # the SAGE range of the cloud profile: fewer clear limb paths (tropics, 0.30 at 7 km)
    # give a fainter Moon than the terminator mean, more (0.60) a brighter one
    nominal = v[labels.index("+ clouds (ISCCP + SAGE profile)")]
    assert v[labels.index("+ clouds, SAGE tropics 0.30 at 7 km")] > nominal
    assert v[labels.index("+ clouds, SAGE extratropics 0.60 at 7 km")] < nominal


@pytest.mark.slow
def test_2019_light_curve_against_the_published_photometry():
    # the samples printed by the Georgia J. Sci. 80(1) art. 32 photometry (SSP-3, Johnson
    # B and V, three per band from second contact to after mid-totality): the model
    # with the limb cloud profile meets the 0.5 mag goal in both bands; without
    # clouds it does not in V (a check that this comparison can fail)
    dataset, figure, _ = light_curve_2019(quick=False)
    v = dataset.band.values == "V"

    def rms(residual):
        return float(np.sqrt(np.mean(residual ** 2)))

    clouds = dataset.residual_clouds.values
    assert rms(clouds[v]) <= GOAL_RMS_MAG, clouds
    assert rms(clouds[~v]) <= GOAL_RMS_MAG, clouds
    assert rms(dataset.residual_no_clouds.values[v]) > GOAL_RMS_MAG


@pytest.mark.slow
def test_terminator_bands_experiment():
    """The latitude-band experiment: the near limb's hemisphere and the ozone term.

    The limb point nearest the Moon at greatest eclipse lies in the hemisphere of the
    Moon's passage, i.e. on the side given by the sign of the canon's gamma (tested against
    the canon elsewhere), for every observed eclipse; and the bands' AFGL ozone (a
    terminator mean above 300 DU for 2015-09-28) makes the 2015 Moon fainter than the same
    bands at 300 DU.
    """
    from experiments.lunar_eclipse_comparison import terminator_comparison
    from skytorch.eclipse.lunar import nearest_eclipse

    dataset, figure, summary = terminator_comparison(quick=True)
    gamma = np.array([float(nearest_eclipse(np.datetime_as_string(day, "D")).gamma[0])
                      for day in dataset.eclipse.values])
    latitude = dataset.near_limb_latitude.values
    assert np.all(np.sign(latitude) == np.sign(gamma)), (latitude, gamma)
    v = dict(zip(dataset.variant.values, dataset.variant_v_magnitude.values, strict=True))
    assert (v["latitude bands (AFGL ozone and water, clouds by zone)"]
            > v["AFGL T and p, 300 DU and 1.4 cm, clouds by zone"])
    assert np.isfinite(summary["latitude_bands_rms_v_mag"])
