"""Tabulated stratospheric aerosol profiles (the LOWTRAN 7 models of Shettle & Fenn 1979).

References: the shipped table itself (read here with the csv module, independently of the
package's reader), integrated by scipy quad along vertical and limb paths; the models'
published peak altitudes and the published ordering of their loadings.
"""

import csv
import math

import numpy as np
import pytest
import torch
from scipy.integrate import quad

from skytorch._data import data_path
from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.aerosol import (
    STRATOSPHERIC_MODELS,
    stratospheric_model_optical_depth,
    stratospheric_profile_shape,
)
from skytorch.eclipse import (
    eclipse_atmosphere,
    eclipse_shadow,
    stratospheric_model,
    terminator_bands,
)

WL = torch.tensor([550.0], dtype=torch.float64)
AOD = 0.1


def _table():
    """Altitudes [m] and extinction [1/m] columns of the shipped LOWTRAN 7 table."""
    with open(data_path("stratospheric_aerosol_lowtran7.csv"), encoding="utf-8") as handle:
        rows = list(csv.reader(line for line in handle if not line.startswith("#")))
    names = rows[0][1:]
    values = np.array(rows[1:], dtype=float)
    return 1e3 * values[:, 0], {name: values[:, k + 1] / 1e3 for k, name in enumerate(names)}


def _extinction(name, aod):
    """Extinction [1/m] of the seasonal LOWTRAN model scaled to ``aod``: 0 at 10 and 35 km."""
    altitude, columns = _table()
    nodes = np.concatenate([[10e3], altitude, [35e3]])
    values = np.concatenate([[0.0], columns[name], [0.0]])
    scale = aod / np.trapezoid(values, nodes)
    return lambda h: scale * float(np.interp(h, nodes, values, left=0.0, right=0.0))


def test_the_table_is_the_published_models():
    """Peaks and loadings of LOWTRAN 7's models (Shettle & Fenn 1979).

    Background peaks at the bottom (11 km) in both seasons; moderate volcanic at 14-15 km;
    high volcanic spring-summer at 18-19 km; extreme volcanic at 19-20 km; each model's
    column exceeds the previous one's.
    """
    altitude, columns = _table()
    peak = {name: altitude[np.argmax(values)] for name, values in columns.items()}
    assert peak["background_spring_summer"] == peak["background_fall_winter"] == 11e3
    assert 14e3 <= peak["moderate_volcanic_spring_summer"] <= 15e3
    assert 18e3 <= peak["high_volcanic_spring_summer"] <= 19e3
    assert 19e3 <= peak["extreme_volcanic_spring_summer"] <= 20e3
    depths = [stratospheric_model_optical_depth(m) for m in STRATOSPHERIC_MODELS]
    assert all(b > 2.0 * a for a, b in zip(depths, depths[1:], strict=False))


@pytest.mark.parametrize("name", ["background_spring_summer", "high_volcanic_fall_winter",
                                  "extreme_volcanic_spring_summer"])
def test_vertical_column_is_the_requested_aod(name):
    """The vertical optical depth from the ground is the requested one (1e-6 relative)."""
    atm = Atmosphere.earth(stratospheric_aerosol_optical_depth=AOD,
                           stratospheric_aerosol_profile=name)
    tau = float(atm.optical_depth(WL, per_species=True)["stratospheric_aerosol"][0])
    assert tau == pytest.approx(AOD, rel=1e-6)


@pytest.mark.parametrize(("name", "tangent_m"), [("high_volcanic_spring_summer", 12e3),
                                                 ("high_volcanic_spring_summer", 18.5e3),
                                                 ("background_fall_winter", 14e3)])
def test_limb_chord_against_quad_of_the_table(name, tangent_m):
    """Slant optical depth along the chord through a tangent altitude: model vs quad.

    The straight chord from the top through the tangent point and back out, integrated
    by scipy quad over the shipped table's linear interpolation: within 1e-4 relative.
    """
    atm = Atmosphere.earth(stratospheric_aerosol_optical_depth=AOD,
                           stratospheric_aerosol_profile=name)
    radius, top = atm.planet_radius_m, atm.top_altitude_m
    extinction = _extinction(name, AOD)
    rt = radius + tangent_m
    half = math.sqrt((radius + top) ** 2 - rt ** 2)
    kinks = [math.sqrt((radius + h) ** 2 - rt ** 2) for h in np.arange(10e3, 35.5e3, 1e3)
             if radius + h > rt]
    reference = 2.0 * quad(lambda s: extinction(math.sqrt(rt ** 2 + s * s) - radius),
                           0.0, half, points=kinks, limit=400, epsrel=1e-10)[0]
    zenith = math.pi - math.asin(rt / (radius + top))
    model = float(atm.optical_depth(WL, torch.tensor([zenith], dtype=torch.float64),
                                    torch.tensor([top], dtype=torch.float64),
                                    per_species=True)["stratospheric_aerosol"][0, 0])
    assert reference > 1.0  # the limb enhancement of a layer tens of km thick
    assert model == pytest.approx(reference, rel=1e-4)


def test_season_mean_and_moments():
    """Without a season: the mean of the two unit-column shapes; buffers hold the moments."""
    altitude, columns = _table()
    nodes = np.concatenate([[10e3], altitude, [35e3]])
    unit = [np.concatenate([[0.0], columns[f"high_volcanic_{s}"], [0.0]]) for s in
            ("spring_summer", "fall_winter")]
    mean = sum(u / np.trapezoid(u, nodes) for u in unit)
    got_nodes, got = stratospheric_profile_shape("high_volcanic")
    np.testing.assert_allclose(got_nodes, nodes)
    np.testing.assert_allclose(got, mean / mean.max(), rtol=1e-12)
    atm = Atmosphere.earth(stratospheric_aerosol_profile="high_volcanic")
    centroid = np.trapezoid(mean * nodes, nodes) / np.trapezoid(mean, nodes)
    assert float(atm.stratospheric_aerosol_altitude_m) == pytest.approx(centroid, rel=1e-9)
    assert 16e3 < centroid < 19e3  # below the Gaussian default's 20 km peak


def test_gradient_with_respect_to_the_optical_depth():
    aod = torch.tensor(AOD, dtype=torch.float64, requires_grad=True)

    def slant(value):
        atm = Atmosphere.earth(stratospheric_aerosol_optical_depth=value,
                               stratospheric_aerosol_profile="moderate_volcanic")
        return atm.optical_depth(WL, torch.tensor([1.2], dtype=torch.float64),
                                 per_species=True)["stratospheric_aerosol"]

    assert torch.autograd.gradcheck(slant, (aod,))


def test_bad_profiles_refused_by_name():
    with pytest.raises(ValueError, match="stratospheric_aerosol_profile"):
        Atmosphere.earth(stratospheric_aerosol_profile="volcanic")
    with pytest.raises(ValueError, match="stratospheric_aerosol_altitude_m"):
        Atmosphere.earth(stratospheric_aerosol_profile="background",
                         stratospheric_aerosol_altitude_m=18e3)
    with pytest.raises(ValueError, match="stratospheric_profile"):
        eclipse_atmosphere("2015-09-28", stratospheric_profile="lowtran")
    # the profile belongs to the atmosphere: not with an atmosphere of one's own
    with pytest.raises(ValueError, match="stratospheric_profile"):
        eclipse_shadow("2015-09-28", atmosphere=Atmosphere.earth(),
                       stratospheric_profile="background")
    with pytest.raises(ValueError, match="name"):
        stratospheric_profile_shape("gaussian")
    # a table cut by the top of the atmosphere would not hold the requested column
    with pytest.raises(ValueError, match="top_altitude_m"):
        Atmosphere.earth(stratospheric_aerosol_profile="background", top_altitude_m=30e3)


def test_model_of_each_eclipse_date():
    """The nearest model in log optical depth: Pinatubo's year high, quiet years background.

    The record's 1992 value (0.11) lies between the high (0.085) and extreme (0.27) models,
    nearer the high one; the quiet years' 0.004-0.009 by the background's 0.007.
    """
    assert stratospheric_model("1992-12-09") == "high_volcanic"
    for day in ("2001-01-09", "2008-02-21", "2015-09-28", "2019-01-21"):
        assert stratospheric_model(day) == "background"
    # outside the record the given optical depth chooses; 0 is the quiet stratosphere
    assert stratospheric_model("2050-01-01", 0.3) == "extreme_volcanic"
    assert stratospheric_model(stratospheric_aod_550=0.0) == "background"
    atm = eclipse_atmosphere("1992-12-09")
    assert atm.stratospheric_aerosol_profile == "high_volcanic"
    assert eclipse_atmosphere("1992-12-09", stratospheric_profile="gaussian") \
        .stratospheric_aerosol_profile == "gaussian"
    seasons = [band.atmosphere.stratospheric_aerosol_profile
               for band in terminator_bands("1992-12-09")]
    # December: southern bands in summer, the tropics the seasons' mean, northern in winter
    assert seasons == ["high_volcanic_spring_summer"] * 2 + ["high_volcanic"] \
        + ["high_volcanic_fall_winter"] * 2


def test_batched_optical_depths_and_float32():
    """A batch of optical depths shares the table's shape; float32 keeps the column."""
    aod = torch.tensor([0.01, 0.1], dtype=torch.float64)
    atm = Atmosphere.earth(stratospheric_aerosol_optical_depth=aod,
                           stratospheric_aerosol_profile="background")
    slant = atm.optical_depth(WL, torch.tensor([1.5], dtype=torch.float64),
                              per_species=True)["stratospheric_aerosol"][:, 0]
    # one shape: the slant optical depths scale with the vertical ones
    assert float(slant[1] / slant[0]) == pytest.approx(10.0, rel=1e-9)
    assert float(slant[0]) > 5.0 * 0.01  # the air mass of a layer near 17 km at 86 deg
    single = Atmosphere.earth(stratospheric_aerosol_optical_depth=AOD,
                              stratospheric_aerosol_profile="background")
    tau32 = single.optical_depth(WL.float(), per_species=True)["stratospheric_aerosol"]
    assert tau32.dtype == torch.float32
    assert float(tau32[0]) == pytest.approx(AOD, rel=1e-5)
