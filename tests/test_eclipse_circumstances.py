"""Lunar-eclipse circumstances and shadow cones against published values.

References: rows of the Five Millennium Canon of Lunar Eclipses (Espenak & Meeus 2009,
NASA/TP-2009-214172; catalogue page https://eclipse.gsfc.nasa.gov/LEcat5/LE2001-2100.html),
Espenak's statement of the Danjon vs Chauvenet magnitude offsets
(https://eclipsewise.com/oh/oh-help/LEshadow.html), the classical parallax forms of the
shadow radii (https://eclipse.gsfc.nasa.gov/LEcat5/shadow.html) and Müller et al. 2012
eq. (5)-(6). See tests/data/README.md.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from skytorch.constants import ARCSECOND, ASTRONOMICAL_UNIT_M, EARTH_EQUATORIAL_RADIUS_M
from skytorch.eclipse import lunar_eclipses, shadow_cone, shadow_radii, sun_visible_fraction
from skytorch.eclipse.cone import (
    MULLER_EARTH_RADIUS_M,
    MULLER_MOON_RADIUS_M,
    MULLER_SUN_RADIUS_M,
    muller_shadow_radii,
)

MINUTE = np.timedelta64(60, "s")
MAGNITUDE_TOLERANCE = 0.005  # eclipse magnitude (fraction of the Moon's diameter)
DURATION_TOLERANCE_MIN = 1.0
SUN_RADIUS_M = 6.957e8

# Five Millennium Canon, LE2001-2100: date, TD of greatest eclipse, type, gamma,
# penumbral magnitude, umbral magnitude, durations (penumbral, partial, total) [min]
CANON = [
    ("2013-04-25T20:08:38", "partial", -1.0121, 0.9866, 0.0148, 247.7, 27.0, None),
    ("2015-04-04T12:01:24", "total", 0.4460, 2.0792, 1.0008, 357.5, 209.0, 4.7),
    ("2018-07-27T20:22:54", "total", 0.1168, 2.6792, 1.6087, 373.8, 234.5, 103.0),
    ("2019-01-21T05:13:27", "total", 0.3684, 2.1684, 1.1953, 311.5, 196.8, 62.0),
    ("2021-05-26T11:19:53", "total", 0.4774, 1.9540, 1.0095, 302.0, 187.4, 14.5),
    ("2022-05-16T04:12:42", "total", -0.2532, 2.3726, 1.4137, 318.7, 207.2, 84.9),
    ("2023-05-05T17:24:05", "penumbral", -1.0349, 0.9636, -0.0457, 257.5, None, None),
    ("2024-09-18T02:45:25", "partial", -0.9792, 1.0372, 0.0848, 246.3, 62.8, None),
    ("2025-03-14T06:59:56", "total", 0.3484, 2.2595, 1.1784, 362.6, 218.3, 65.4),
    ("2025-09-07T18:12:58", "total", -0.2752, 2.3440, 1.3619, 326.7, 209.4, 82.1),
    ("2028-12-31T16:53:15", "total", 0.3258, 2.2742, 1.2463, 336.2, 208.8, 71.3),
    ("2029-06-26T03:23:22", "total", 0.0124, 2.8266, 1.8436, 335.1, 219.5, 101.9),
]
# greatest eclipse (TD) of two more canon eclipses
CANON_GREATEST_TD = ["2022-11-08T11:00:22", "2023-10-28T20:15:18"]
# every lunar eclipse 2020-2029 in the canon (date of greatest eclipse, type)
CANON_2020S = [
    ("2020-01-10", "penumbral"), ("2020-06-05", "penumbral"), ("2020-07-05", "penumbral"),
    ("2020-11-30", "penumbral"), ("2021-05-26", "total"), ("2021-11-19", "partial"),
    ("2022-05-16", "total"), ("2022-11-08", "total"), ("2023-05-05", "penumbral"),
    ("2023-10-28", "partial"), ("2024-03-25", "penumbral"), ("2024-09-18", "partial"),
    ("2025-03-14", "total"), ("2025-09-07", "total"), ("2026-03-03", "total"),
    ("2026-08-28", "partial"), ("2027-02-20", "penumbral"), ("2027-07-18", "penumbral"),
    ("2027-08-17", "penumbral"), ("2028-01-12", "partial"), ("2028-07-06", "partial"),
    ("2028-12-31", "total"), ("2029-06-26", "total"), ("2029-12-20", "total"),
]


@pytest.fixture(scope="module")
def danjon():
    return lunar_eclipses("2013-01-01", "2030-01-01")


@pytest.fixture(scope="module")
def chauvenet():
    return lunar_eclipses("2020-01-01", "2030-01-01", enlargement="chauvenet")


def _td(dataset):
    return dataset.time.values + (dataset.delta_t.values * 1e9).astype("timedelta64[ns]")


def _find(dataset, td_string):
    td = _td(dataset)
    index = int(np.argmin(np.abs(td - np.datetime64(td_string))))
    assert abs(td[index] - np.datetime64(td_string)) < 60 * MINUTE, td_string
    return dataset.isel(eclipse=index), td[index]


@pytest.mark.parametrize("row", CANON, ids=[row[0][:10] for row in CANON])
def test_circumstances_match_the_canon(danjon, row):
    greatest, kind, gamma, penumbral, umbral, pen_min, par_min, tot_min = row
    eclipse, td = _find(danjon, greatest)
    assert abs(td - np.datetime64(greatest)) <= MINUTE
    assert str(eclipse.kind.values) == kind
    assert float(eclipse.gamma) == pytest.approx(gamma, abs=1e-3)
    assert float(eclipse.penumbral_magnitude) == pytest.approx(penumbral, abs=MAGNITUDE_TOLERANCE)
    assert float(eclipse.umbral_magnitude) == pytest.approx(umbral, abs=MAGNITUDE_TOLERANCE)
    for name, published in (("penumbral_duration", pen_min), ("partial_duration", par_min),
                            ("total_duration", tot_min)):
        value = float(eclipse[name])
        if published is None:
            assert math.isnan(value)
        else:
            assert value == pytest.approx(published, abs=DURATION_TOLERANCE_MIN)


def test_contacts_are_ordered_and_symmetric_with_the_durations(danjon):
    eclipse, _ = _find(danjon, "2018-07-27T20:22:54")
    contacts = [eclipse[name].values for name in ("p1", "u1", "u2", "time", "u3", "u4", "p4")]
    assert all(a < b for a, b in zip(contacts[:-1], contacts[1:], strict=True))
    # contacts from the canon's durations, centred on greatest eclipse (motion nearly uniform)
    for first, last, minutes in (("p1", "p4", 373.8), ("u1", "u4", 234.5), ("u2", "u3", 103.0)):
        half = np.timedelta64(int(minutes * 30), "s")
        assert abs(eclipse[first].values - (eclipse.time.values - half)) <= MINUTE
        assert abs(eclipse[last].values - (eclipse.time.values + half)) <= MINUTE
    penumbral, _ = _find(danjon, "2023-05-05T17:24:05")
    for name in ("u1", "u2", "u3", "u4"):
        assert np.isnat(penumbral[name].values)


@pytest.mark.parametrize("greatest", CANON_GREATEST_TD)
def test_greatest_eclipse_times(danjon, greatest):
    _, td = _find(danjon, greatest)
    assert abs(td - np.datetime64(greatest)) <= MINUTE


def test_all_eclipses_of_the_2020s(danjon):
    decade = danjon.sel(eclipse=danjon.time.values >= np.datetime64("2020-01-01"))
    found = [(str(t)[:10], str(k)) for t, k in zip(decade.time.values, decade.kind.values, strict=True)]
    assert found == CANON_2020S


def test_danjon_vs_chauvenet_offsets(danjon, chauvenet):
    # Espenak: Danjon magnitudes are smaller by about 0.005 (umbral) and 0.026 (penumbral)
    decade = danjon.sel(eclipse=danjon.time.values >= np.datetime64("2020-01-01"))
    assert decade.sizes["eclipse"] == chauvenet.sizes["eclipse"]
    umbral = float((chauvenet.umbral_magnitude.values - decade.umbral_magnitude.values).mean())
    penumbral = float(
        (chauvenet.penumbral_magnitude.values - decade.penumbral_magnitude.values).mean())
    assert umbral == pytest.approx(0.005, abs=0.002)
    assert penumbral == pytest.approx(0.026, abs=0.003)


def test_dataset_metadata_and_netcdf_round_trip(danjon, tmp_path):
    from skytorch.dataset import open_dataset, to_netcdf

    assert danjon.attrs["enlargement"] == "danjon"
    for name, data in danjon.data_vars.items():
        assert "long_name" in data.attrs and "description" in data.attrs, name
    back = open_dataset(to_netcdf(danjon, tmp_path / "eclipses.nc"))
    assert np.array_equal(back.time.values, danjon.time.values)
    assert np.array_equal(np.isnat(back.u2.values), np.isnat(danjon.u2.values))
    assert list(back.kind.values) == list(danjon.kind.values)


def test_invalid_ranges():
    with pytest.raises(ValueError, match="enlargement"):
        lunar_eclipses("2020-01-01", "2021-01-01", enlargement="lahire")
    with pytest.raises(ValueError, match="after"):
        lunar_eclipses("2021-01-01", "2020-01-01")
    with pytest.raises(ValueError, match="DE421"):
        lunar_eclipses("2050-01-01", "2060-01-01")


# --- shadow cones ---------------------------------------------------------------------------


def test_muller_coefficients_from_the_cone_geometry():
    moon_distance = torch.linspace(356e6, 407e6, 11, dtype=torch.float64)
    sun_distance = torch.linspace(1.471e11, 1.521e11, 11, dtype=torch.float64)[:, None]
    umbra, penumbra = shadow_radii(moon_distance, sun_distance, MULLER_SUN_RADIUS_M,
                                   MULLER_EARTH_RADIUS_M, enlargement="none")
    eps_u, eps_p = muller_shadow_radii(moon_distance, sun_distance)
    # exact cones vs Müller's first-order coefficients: < 2e-4 Moon radii (350 m)
    assert torch.allclose(umbra / MULLER_MOON_RADIUS_M, eps_u, atol=2e-4)
    assert torch.allclose(penumbra / MULLER_MOON_RADIUS_M, eps_p, atol=2e-4)


@pytest.mark.parametrize(
    ("enlargement", "factor", "oblateness"),
    [("danjon", 1.0, 1.01), ("chauvenet", 1.02, 0.998340), ("none", 1.0, 1.0)])
def test_classical_parallax_forms(enlargement, factor, oblateness):
    # Espenak & Meeus (shadow.html, eq. 1-3 to 1-6): radii seen from Earth's centre
    moon_distance, sun_distance = 370e6, 1.0 * ASTRONOMICAL_UNIT_M
    sun_radius = ASTRONOMICAL_UNIT_M * math.tan(959.63 * ARCSECOND)
    umbra, penumbra = shadow_radii(moon_distance, sun_distance, sun_radius,
                                   EARTH_EQUATORIAL_RADIUS_M, enlargement)
    moon_parallax = math.asin(EARTH_EQUATORIAL_RADIUS_M / moon_distance)
    sun_parallax = math.asin(EARTH_EQUATORIAL_RADIUS_M / sun_distance)
    sun_semidiameter = math.asin(sun_radius / sun_distance)
    expected_umbra = factor * (oblateness * moon_parallax - sun_semidiameter + sun_parallax)
    expected_penumbra = factor * (oblateness * moon_parallax + sun_semidiameter + sun_parallax)
    # the published forms add angles to first order: they use asin(R/x) where the cone's
    # cross-section has R/x (third-order term 0.18 arcsec), and leave the solar parallax
    # (8.8 arcsec) unenlarged (0.09 arcsec): 0.5 arcsec is 3e-4 in eclipse magnitude
    assert abs(float(umbra) / moon_distance - expected_umbra) < 0.5 * ARCSECOND
    assert abs(float(penumbra) / moon_distance - expected_penumbra) < 0.5 * ARCSECOND


@pytest.mark.parametrize("edge", ["umbra", "penumbra"])
def test_cone_edges_are_occlusion_tangencies(edge, dtype):
    # at the cone's edge the Sun seen from that point touches the occluder's limb
    x, sun_distance, radius = 1.2e9, ASTRONOMICAL_UNIT_M, 6.371e6
    umbra, penumbra = shadow_radii(torch.tensor(x, dtype=dtype), sun_distance, SUN_RADIUS_M,
                                   radius, enlargement="none")
    offset = float(umbra if edge == "umbra" else penumbra)
    point = np.array([x, offset])  # along the anti-Sun axis, and across it
    to_occluder, to_sun = -point, np.array([-sun_distance, 0.0]) - point
    rho_o = math.asin(radius / np.linalg.norm(to_occluder))
    rho_s = math.asin(SUN_RADIUS_M / np.linalg.norm(to_sun))
    separation = math.acos(to_occluder @ to_sun
                           / (np.linalg.norm(to_occluder) * np.linalg.norm(to_sun)))
    tangency = rho_o - rho_s if edge == "umbra" else rho_o + rho_s
    assert abs(separation - tangency) < 1e-4 * rho_s
    fraction = sun_visible_fraction(rho_s, rho_o, separation).item()
    assert fraction == pytest.approx(0.0 if edge == "umbra" else 1.0, abs=1e-6)


def test_umbra_apex_and_antumbra_of_phobos():
    # Phobos over Mars: the umbra ends at R D / (R_s - R), short of the surface
    radius, sun_distance = 11_080.0, 2.28e11
    apex = radius * sun_distance / (SUN_RADIUS_M - radius)
    cone = shadow_cone(torch.tensor([0.5 * apex, apex, 5_986e3], dtype=torch.float64),
                       sun_distance, SUN_RADIUS_M, radius, enlargement="none")
    assert float(cone["apex_distance_m"][0]) == pytest.approx(apex, rel=1e-9)
    assert float(cone["umbra_radius_m"][1]) == pytest.approx(0.0, abs=1e-6)
    assert float(cone["umbra_radius_m"][0]) > 0 and float(cone["antumbra_radius_m"][0]) == 0
    # beyond the apex the antumbra grows linearly: (x - apex) tan f_u
    tan_f = (SUN_RADIUS_M - radius) / math.sqrt(sun_distance**2 - (SUN_RADIUS_M - radius)**2)
    assert float(cone["antumbra_radius_m"][2]) == pytest.approx((5_986e3 - apex) * tan_f,
                                                                rel=1e-9)


def test_cone_gradients_and_errors():
    distance = torch.tensor(384e6, dtype=torch.float64, requires_grad=True)
    umbra, penumbra = shadow_radii(distance, ASTRONOMICAL_UNIT_M, SUN_RADIUS_M, 6.378e6)
    (umbra + penumbra).backward()
    assert torch.isfinite(distance.grad)
    with pytest.raises(ValueError, match="enlargement"):
        shadow_radii(384e6, ASTRONOMICAL_UNIT_M, SUN_RADIUS_M, 6.378e6, enlargement="lahire")
    with pytest.raises(ValueError, match="smaller than the Sun"):
        shadow_radii(384e6, ASTRONOMICAL_UNIT_M, 1e6, 6.378e6)
    # the message names the first offending values of a batch
    with pytest.raises(ValueError, match=r"occluder_radius_m=7e\+08, sun_radius_m=6\.96e\+08"):
        shadow_radii(384e6, ASTRONOMICAL_UNIT_M, 6.96e8, torch.tensor([6.378e6, 7e8]))


# 2015-09-28 contacts (UTC) as listed for NASA's predictions in the Wikipedia infobox
# "September 2015 lunar eclipse" (Espenak's eclipse page LE2015Sep28T)
CONTACTS_2015_09_28 = {"p1": "2015-09-28T00:11:47", "u1": "2015-09-28T01:07:11",
                       "u2": "2015-09-28T02:11:10", "time": "2015-09-28T02:47:08",
                       "u3": "2015-09-28T03:23:05", "u4": "2015-09-28T04:27:03",
                       "p4": "2015-09-28T05:22:27"}


def test_contacts_of_2015_09_28(danjon):
    eclipse, _ = _find(danjon, "2015-09-28T02:48:17")
    for name, published in CONTACTS_2015_09_28.items():
        assert abs(eclipse[name].values - np.datetime64(published)) <= MINUTE, name


# --- command line ------------------------------------------------------------------------------


def test_cli_table(tmp_path, capsys):
    from skytorch.cli import main
    from skytorch.dataset import open_dataset

    path = tmp_path / "table.nc"
    assert main(["eclipse", "--from", "2022-01-01", "--to", "2024-01-01", "-o", str(path)]) == 0
    out = capsys.readouterr().out
    assert "4 lunar eclipses" in out and "2022-11-08 10:59" in out and "penumbral" in out
    assert open_dataset(path).sizes["eclipse"] == 4


def test_cli_single_date_circumstances(tmp_path, capsys, monkeypatch):
    from skytorch.cli import main
    from skytorch.commands import eclipse as command

    monkeypatch.setattr(command, "_light_curve_model", lambda: None)
    assert main(["eclipse", "2018-07-27", "-o", str(tmp_path / "one.nc")]) == 0
    out = capsys.readouterr().out
    assert "U2        2018-07-27T19:30" in out and "total" in out
    assert main(["eclipse", "2018-07-27", "--from", "2018-01-01"]) == 2
