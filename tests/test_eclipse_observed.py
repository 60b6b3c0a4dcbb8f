"""The observed-eclipse table: parses, every row sourced, physical values, real eclipses.

Independent references: the eclipse dates and (where printed) greatest-eclipse times come
from the observers' pages, checked here against skytorch's canon (``lunar_eclipses``, itself
tested against the NASA Five Millennium Canon); the L-V pairs are held against Vital's
correlation (``danjon_l``), whose coefficients come from his reports, not from this table.
"""

from __future__ import annotations

import numpy as np
import pytest

from skytorch.dataset import open_dataset, to_netcdf
from skytorch.eclipse import danjon_l, lunar_eclipses, observed_lunar_eclipses
from skytorch.eclipse.danjon import DANJON_L_UNCERTAINTY
from skytorch.eclipse.observed import METHODS


@pytest.fixture(scope="module")
def observed():
    return observed_lunar_eclipses()


def test_parses_with_metadata(observed, tmp_path):
    assert observed.sizes["eclipse"] >= 10
    assert int(np.isfinite(observed.v_magnitude).sum()) >= 9
    for name in ("v_magnitude", "v_uncertainty", "v_below_full_moon", "b_minus_v"):
        assert observed[name].attrs["units"] == "mag"
        assert observed[name].attrs["long_name"]
    assert observed.danjon_l.attrs["units"] == "1"
    assert observed.attrs["Conventions"].startswith("CF")
    restored = open_dataset(to_netcdf(observed, tmp_path / "observed.nc"))
    np.testing.assert_array_equal(restored.v_magnitude.values, observed.v_magnitude.values)
    assert list(restored.source.values) == list(observed.source.values)


def test_every_row_has_a_source(observed):
    sources = [str(s) for s in observed.source.values]
    urls = [str(u) for u in observed.url.values]
    assert all(len(s) > 20 for s in sources)
    assert all(u.startswith("http") for u in urls)
    # every row carries at least one observed quantity
    values = np.stack([observed[n].values for n in ("danjon_l", "v_magnitude",
                                                    "v_below_full_moon")])
    assert np.isfinite(values).any(axis=0).all()
    references = observed.attrs["references"].split("\n")
    assert set(sources) == set(references)


def test_values_in_physical_ranges(observed):
    v = observed.v_magnitude.values[np.isfinite(observed.v_magnitude.values)]
    # totality: fainter than the uneclipsed full Moon (-12.7) by > 8 mag, and never fainter
    # than the darkest eclipses (V about +4, Keen 1983)
    assert ((v > -5.0) & (v < 5.0)).all()
    level = observed.danjon_l.values[np.isfinite(observed.danjon_l.values)]
    assert ((level >= 0.0) & (level <= 4.0)).all()
    for name in ("v_uncertainty", "danjon_l_uncertainty"):
        sigma = observed[name].values[np.isfinite(observed[name].values)]
        assert ((sigma > 0.0) & (sigma <= 1.0)).all()
    below = observed.v_below_full_moon.values[np.isfinite(observed.v_below_full_moon.values)]
    assert ((below > 8.0) & (below < 17.0)).all()
    bv = observed.b_minus_v.values[np.isfinite(observed.b_minus_v.values)]
    assert ((bv > 0.92) & (bv < 3.0)).all()  # redder than the uneclipsed Moon
    assert set(str(m) for m in observed.method.values) <= set(METHODS)


def test_dates_are_total_lunar_eclipses(observed):
    one_day = np.timedelta64(1, "D")
    pairs = zip(observed.eclipse.values, observed.greatest_eclipse.values, strict=True)
    for date, greatest in pairs:
        day = np.datetime64(date, "D")
        canon = lunar_eclipses(str(day - one_day), str(day + 2 * one_day))
        assert canon.sizes["eclipse"] == 1, day
        assert str(canon.kind.values[0]) == "total", day
        when = canon.time.values[0]
        assert np.datetime64(when, "D") == day  # UTC date of greatest eclipse
        if not np.isnat(greatest):
            # printed to the second or minute: within a few minutes of the canon
            assert abs(when - greatest) <= np.timedelta64(3, "m"), (day, when, greatest)


def test_vital_pairs_agree_with_his_correlation(observed):
    # REA (Vital) rows with both an observed L and an observed V: within the +-0.4 he quotes
    rows = [i for i, s in enumerate(observed.source.values) if str(s).startswith("Vital")
            and np.isfinite(observed.danjon_l.values[i])
            and np.isfinite(observed.v_magnitude.values[i])]
    assert rows  # 2008-02-21: L 3.0, V -2.8 -> 3.17
    for i in rows:
        predicted = float(danjon_l(float(observed.v_magnitude.values[i])))
        assert abs(predicted - observed.danjon_l.values[i]) <= DANJON_L_UNCERTAINTY


def test_other_pairs_within_combined_uncertainty(observed):
    # other observers' L against Vital's correlation: the correlation's +-0.4 and an
    # L estimate's +-0.4 (Vital's figure) combine to 0.57 (MBK 2001: 0.51, 2003: 0.53)
    both = np.isfinite(observed.danjon_l.values) & np.isfinite(observed.v_magnitude.values)
    assert int(both.sum()) >= 3
    predicted = danjon_l(observed.v_magnitude.values[both]).numpy()
    combined = np.hypot(DANJON_L_UNCERTAINTY, DANJON_L_UNCERTAINTY)
    assert np.abs(predicted - observed.danjon_l.values[both]).max() <= combined
