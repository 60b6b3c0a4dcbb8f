"""Limiting magnitude (Schaefer 1990), Müller's day–night factor, scintillation (Young 1967)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from skytorch.constants import CANDELA_PER_M2_AT_ZERO_MAG_ARCSEC2, MAG, PERCENT
from skytorch.stars import (
    bright_stars,
    limiting_magnitude,
    mag_arcsec2_to_nanolambert,
    muller_day_night_factor,
    observe,
    scintillation_index,
    twinkle,
)

#: 1 nanolambert = 1e-9 * 1e4/pi cd/m² (definition of the lambert)
NANOLAMBERT_CD_M2 = 1e-9 * 1e4 / math.pi


def test_nanolambert_conversion_matches_candela_scale():
    """Krisciunas & Schaefer's nL formula vs Falchi et al.'s 10.8e4·10^(−0.4 m) cd/m²."""
    sky = torch.tensor([16.0, 19.0, 22.0], dtype=torch.float64)
    candela = CANDELA_PER_M2_AT_ZERO_MAG_ARCSEC2 * 10.0 ** (-0.4 * sky)
    assert torch.allclose(mag_arcsec2_to_nanolambert(sky) * NANOLAMBERT_CD_M2, candela,
                          rtol=1.0 * PERCENT)


def test_limiting_magnitude_dark_sky_and_zero_background():
    # Schaefer (1990): with no background the threshold c1 = 10^-9.8 ft-cd is m = 7.93
    assert float(limiting_magnitude(40.0)) == pytest.approx(-16.57 + 2.5 * 9.8, abs=0.02)
    # the classical naked-eye limit at a dark site (22 mag/arcsec², 54 nL) is about 6.5
    assert float(limiting_magnitude(22.0)) == pytest.approx(6.5, abs=0.2)
    # a smaller pupil sees fainter stars less well: (7/5)² in flux = 0.73 mag
    shift = float(limiting_magnitude(22.0) - limiting_magnitude(22.0, pupil_diameter_mm=5.0))
    assert shift == pytest.approx(5.0 * math.log10(7.0 / 5.0), abs=1e-9)


def test_limiting_magnitude_monotonic_and_nearly_continuous_at_branch_switch():
    sky = torch.linspace(4.0, 24.0, 401, dtype=torch.float64)
    limit = limiting_magnitude(sky)
    assert torch.isfinite(limit).all()
    steps = torch.diff(limit)
    # rod/cone switch at 1500 nL (~18.0 mag/arcsec²): a jump below 0.1 mag
    assert float(steps.max()) < 0.1 * MAG
    assert float(steps.min()) > -1e-12  # brighter sky never lets fainter stars through
    # daylight sky (~4 mag/arcsec²): only the brightest objects (Venus, −4) remain
    assert float(limit[0]) < -2.0


def test_muller_day_night_factor():
    """(1 + (s_z + 1.14)^32)^(−1/2) (Müller et al. 2012, §5)."""
    altitude = torch.asin(torch.tensor([-1.0, -0.3, -0.14, 0.0, 0.1, 0.5],
                                       dtype=torch.float64))
    factor = muller_day_night_factor(altitude)
    assert float(factor[0]) == pytest.approx(1.0, abs=1e-12)
    assert float(factor[1]) > 0.99  # full visibility at night
    assert float(factor[2]) == pytest.approx(1.0 / math.sqrt(2.0), rel=1e-12)
    assert float(factor[3]) == pytest.approx((1.0 + 1.14**32) ** -0.5, rel=1e-12)
    assert float(factor[5]) < 1e-3  # zero visibility in daylight
    assert torch.all(torch.diff(factor) < 0.0)


def test_visible_star_count_dark_site():
    """Under a dark sky a few thousand stars are above the horizon and visible at once."""
    ds = observe(bright_stars(6.5), "2025-09-07T22:00", 52.5, 13.4)
    count = int(ds.n_visible[0])
    assert 1500 < count < 3500
    assert count == int(ds.visible.values.sum())
    brighter = observe(bright_stars(6.5), "2025-09-07T22:00", 52.5, 13.4,
                       sky_brightness_mag_arcsec2=18.0)
    assert int(brighter.n_visible[0]) < count / 2


def test_muller_visibility_option_daytime_hides_stars():
    ds = observe(bright_stars(2.0), ["2025-06-21T00:00", "2025-06-21T12:00"], 48.0, 11.0,
                 visibility="muller2012")
    assert "day_night_factor" in ds
    assert float(ds.day_night_factor[1]) < 1e-3
    assert int(ds.n_visible[1]) == 0 < int(ds.n_visible[0])


# --- scintillation -------------------------------------------------------------------------

def test_young_index_value_and_scaling():
    """Young (1967): σ = 0.09 D_cm^(−2/3) X^1.75 e^(−h/8 km) (2t)^(−1/2)."""
    sigma2 = scintillation_index(1.0, aperture_m=1.0, exposure_s=1.0, altitude_m=0.0)
    assert float(sigma2) == pytest.approx(0.09**2 * 100.0 ** (-4.0 / 3.0) / 2.0, rel=1e-12)
    base = float(scintillation_index(1.0, 0.5, 0.1, 2000.0))
    assert float(scintillation_index(2.0, 0.5, 0.1, 2000.0)) == pytest.approx(
        base * 2.0**3.5, rel=1e-12)
    assert float(scintillation_index(1.0, 1.0, 0.1, 2000.0)) == pytest.approx(
        base * 2.0 ** (-4.0 / 3.0), rel=1e-12)
    assert float(scintillation_index(1.0, 0.5, 0.2, 2000.0)) == pytest.approx(base / 2.0,
                                                                             rel=1e-12)
    assert float(scintillation_index(1.0, 0.5, 0.1, 0.0)) == pytest.approx(
        base * math.exp(0.5), rel=1e-12)


def test_osborn_form_close_to_young_at_zenith():
    young = float(scintillation_index(1.0, 1.0, 1.0, model="young1967"))
    osborn = float(scintillation_index(1.0, 1.0, 1.0, model="osborn2015", site_factor=1.0))
    assert osborn == pytest.approx(young, rel=15.0 * PERCENT)  # 1.0e-5 vs 0.87e-5
    assert float(scintillation_index(2.0, 1.0, 1.0, model="osborn2015")) == pytest.approx(
        8.0 * 1.5**2 * 1e-5, rel=1e-12)
    with pytest.raises(ValueError, match="model"):
        scintillation_index(1.0, model="tatarskii")


def test_twinkle_statistics_and_seed():
    variance = torch.tensor([0.01, 0.25], dtype=torch.float64)
    samples = twinkle(variance, 40000, sample_interval_s=0.01, correlation_time_s=0.02,
                      seed=7)
    assert samples.shape == (2, 40000)
    assert (samples > 0).all()
    rho = math.exp(-0.5)
    n_eff = 40000 * (1 - rho) / (1 + rho)
    assert torch.allclose(samples.mean(-1), torch.ones(2, dtype=torch.float64),
                          atol=float(4 * variance.sqrt().max() / math.sqrt(n_eff)))
    assert torch.allclose(samples.var(-1), variance, rtol=0.15)
    log = torch.log(samples[0])
    log = (log - log.mean()) / log.std()
    assert float((log[1:] * log[:-1]).mean()) == pytest.approx(rho, abs=0.03)
    again = twinkle(variance, 40000, sample_interval_s=0.01, correlation_time_s=0.02, seed=7)
    assert torch.equal(samples, again)
    other = twinkle(variance, 40000, sample_interval_s=0.01, correlation_time_s=0.02, seed=8)
    assert not torch.equal(samples, other)
    white = twinkle(torch.tensor(0.0), 5, seed=1)
    assert torch.allclose(white, torch.ones(5, dtype=white.dtype))


def test_observed_scintillation_grows_towards_horizon():
    ds = observe(bright_stars(3.0), "2025-09-07T22:00", 52.5, 13.4)
    above = ds.above_horizon.values[0]
    index = ds.scintillation_index.values[0][above]
    altitude = ds.altitude.values[0][above]
    assert np.isfinite(ds.scintillation_index.values).all()
    assert index[np.argmin(altitude)] > 10.0 * index[np.argmax(altitude)]


def test_observe_twinkle_on_request_is_seeded():
    first = observe(bright_stars(1.0), "2025-09-07T22:00", 52.5, 13.4, twinkle_samples=64,
                    seed=3)
    again = observe(bright_stars(1.0), "2025-09-07T22:00", 52.5, 13.4, twinkle_samples=64,
                    seed=3)
    assert first.twinkle.dims == ("time", "star", "sample")
    assert np.array_equal(first.twinkle.values, again.twinkle.values)
    assert (first.twinkle.values > 0).all()
    assert "twinkle" not in observe(bright_stars(1.0), "2025-09-07T22:00", 52.5, 13.4)


def test_count_true_matches_a_plain_count_and_refuses_other_dtypes():
    """The byte-wise count equals Python's count of True per row; non-bool input raises."""
    from skytorch.stars.visibility import count_true

    flags = torch.rand(7, 1001, generator=torch.Generator().manual_seed(5)) < 0.3
    expected = [sum(bool(v) for v in row) for row in flags.tolist()]
    counted = count_true(flags)
    assert counted.dtype == torch.int64 and counted.tolist() == expected
    assert count_true(flags[:, ::2]).tolist() == [sum(row[::2]) for row in flags.tolist()]
    for bad in (flags.double(), torch.tensor(True), [True, False]):
        with pytest.raises(TypeError, match="flags must be a bool tensor"):
            count_true(bad)
