"""Retrieval of the atmosphere from synthetic mid-totality V and light curves.

The synthetic observations are the public light curve of known parameters plus fixed
draws of the observation error; the retrieval must recover the parameters within its own
Laplace uncertainty.
"""

import numpy as np
import pytest
import torch
import xarray as xr

from skytorch.eclipse import (
    eclipse_atmosphere,
    eclipse_shadow,
    lunar_light_curve,
    retrieve_atmosphere,
)


def _faintest_v(date, n_times, table_n_v, terminator="global", **parameters):
    """Mid-totality V [mag] of the date's eclipse for the given atmosphere parameters."""
    shadow = (eclipse_shadow(date, atmosphere=eclipse_atmosphere(date, **parameters))
              if terminator == "global" else
              eclipse_shadow(date, terminator=terminator, **parameters))
    curve = lunar_light_curve(date, shadow=shadow, n_times=n_times, table_n_v=table_n_v)
    return float(curve["v_magnitude"].max())


@pytest.mark.slow
def test_recovers_a_known_stratospheric_depth_from_noisy_v():
    date, truth = "2015-09-28", 0.05
    v_true = _faintest_v(date, 9, 64, stratospheric_aod_550=truth)
    noise, sigma = 0.04, 0.1  # a fixed draw of the observation error [mag]
    fit = retrieve_atmosphere({"v_magnitude": (v_true + noise, sigma)}, date,
                              initial={"stratospheric_aod_550": 0.01})
    best = float(fit.best_fit.sel(parameter="stratospheric_aod_550"))
    spread = float(fit.uncertainty.sel(parameter="stratospheric_aod_550"))
    assert abs(float(fit.residual.sel(observable="v_magnitude"))) < 0.01
    assert 0.0 < spread < truth
    assert abs(best - truth) < 2.0 * spread


def test_bad_observations_raise():
    with pytest.raises(ValueError, match="observations"):
        retrieve_atmosphere({"r_magnitude": (1.0, 0.1)}, "2015-09-28")
    with pytest.raises(ValueError, match="parameters"):
        retrieve_atmosphere({"v_magnitude": (-2.0, 0.1)}, "2015-09-28",
                            parameters=("turbidity",))
    for pair in (-3.0, (-3.0,), ("abc", 0.1), (True, 0.1)):
        with pytest.raises(TypeError, match="must be a pair of numbers"):
            retrieve_atmosphere({"v_magnitude": pair}, "2015-09-28")
    # 2020-01-10 is penumbral: no mid-totality to fit (it fitted chi2 8952 before)
    with pytest.raises(ValueError, match="is penumbral, without a totality"):
        retrieve_atmosphere({"v_magnitude": (-3.0, 0.1)}, "2020-01-10", max_iter=1,
                            table_n_v=16)


@pytest.mark.slow
def test_recovers_the_depth_through_the_latitude_bands():
    """The same retrieval through the bands resolved in direction (coarse model)."""
    date, truth = "2015-09-28", 0.05
    v_true = _faintest_v(date, 3, 16, "latitude_bands", stratospheric_aod_550=truth)
    fit = retrieve_atmosphere({"v_magnitude": (v_true + 0.04, 0.1)}, date,
                              initial={"stratospheric_aod_550": 0.01}, n_times=3,
                              table_n_v=16, terminator="latitude_bands")
    best = float(fit.best_fit.sel(parameter="stratospheric_aod_550"))
    spread = float(fit.uncertainty.sel(parameter="stratospheric_aod_550"))
    assert fit.attrs["terminator"] == "latitude_bands"
    assert abs(float(fit.residual.sel(observable="v_magnitude"))) < 0.01
    assert 0.0 < spread < truth and abs(best - truth) < 2.0 * spread


def test_bands_refuse_fitting_ozone_and_unknown_terminators():
    with pytest.raises(ValueError, match="ozone_du cannot be fitted"):
        retrieve_atmosphere({"v_magnitude": (-2.0, 0.1)}, "2015-09-28",
                            parameters=("ozone_du",), terminator="latitude_bands")
    with pytest.raises(ValueError, match="terminator"):
        retrieve_atmosphere({"v_magnitude": (-2.0, 0.1)}, "2015-09-28", terminator="zonal")


#: eight instants through the 2019-01-21 eclipse: partial phases and totality
_TIMES_2019 = np.array(["2019-01-21T04:05", "2019-01-21T04:25", "2019-01-21T04:45",
                        "2019-01-21T05:00", "2019-01-21T05:12", "2019-01-21T05:25",
                        "2019-01-21T05:40", "2019-01-21T06:00"], dtype="datetime64[ns]")


def _light_curve_dataset(times, bands, magnitude, uncertainty):
    return xr.Dataset({"time": ("sample", times), "band": ("sample", bands),
                       "magnitude": ("sample", magnitude),
                       "uncertainty": ("sample", uncertainty)})


@pytest.mark.slow
def test_recovers_three_parameters_from_a_noisy_v_and_b_light_curve():
    """Stratospheric and tropospheric AOD and ozone from 8 V and 8 B samples (σ 0.03 mag).

    Measured (table_n_v 32, 19 s): 0.0299 ± 0.0003, 0.24 ± 0.15 and 329 ± 12 DU against
    0.03, 0.2 and 330 DU; the tropospheric depth is the least constrained (the clouds
    block most of the limb rays below them).
    """
    date, n_v, sigma = "2019-01-21", 32, 0.03
    truth = {"stratospheric_aod_550": 0.03, "tropospheric_aod": 0.2, "ozone_du": 330.0}
    with torch.no_grad():
        curve = lunar_light_curve(date, shadow=eclipse_shadow(
            date, atmosphere=eclipse_atmosphere(date, **truth)), times=_TIMES_2019,
            table_n_v=n_v)
    noise = np.random.default_rng(1).normal(0.0, sigma, (2, _TIMES_2019.size))
    observed = _light_curve_dataset(
        np.concatenate([_TIMES_2019, _TIMES_2019]), ["V"] * 8 + ["B"] * 8,
        np.concatenate([curve["v_magnitude"].numpy(), curve["b_magnitude"].numpy()])
        + noise.reshape(-1), np.full(16, sigma))
    fit = retrieve_atmosphere(observed, date, parameters=tuple(truth), table_n_v=n_v,
                              max_iter=30)
    assert fit.residual.dims == ("sample",)
    assert (fit.band.values == observed.band.values).all()
    assert float(np.abs(fit.residual).max()) < 3.0 * sigma
    for name, value in truth.items():
        best = float(fit.best_fit.sel(parameter=name))
        spread = float(fit.uncertainty.sel(parameter=name))
        assert 0.0 < spread < value and abs(best - value) < 2.0 * spread, (name, best, spread)


def test_bad_light_curves_raise():
    good = {"times": _TIMES_2019[:2], "bands": ["V", "B"], "magnitude": [-2.0, -0.5],
            "uncertainty": [0.1, 0.1]}
    with pytest.raises(ValueError, match="band"):
        retrieve_atmosphere(_light_curve_dataset(**{**good, "bands": ["V", "R"]}),
                            "2019-01-21")
    with pytest.raises(ValueError, match="uncertainties > 0"):
        retrieve_atmosphere(_light_curve_dataset(**{**good, "uncertainty": [0.1, 0.0]}),
                            "2019-01-21")
    with pytest.raises(ValueError, match="within 12 h of greatest eclipse"):
        retrieve_atmosphere(_light_curve_dataset(**{**good, "times": np.array(
            ["2019-01-21T05:00", "2019-01-23T05:00"], dtype="datetime64[ns]")}), "2019-01-21")
    with pytest.raises(ValueError, match="'sample'"):
        retrieve_atmosphere(_light_curve_dataset(**good).drop_vars("uncertainty"),
                            "2019-01-21")


def test_light_curve_at_given_times_matches_the_grid():
    """Times given explicitly reproduce the n_times grid's values at the same instants."""
    grid = lunar_light_curve("2019-01-21", False, n_times=5, table_n_v=16)
    from skytorch.eclipse import lunar_eclipse

    times = lunar_eclipse("2019-01-21", False, n_times=5, n_images=0, table_n_v=16).time.values
    at = lunar_light_curve("2019-01-21", False, times=times[[3, 1]], table_n_v=16)
    for name in ("v_magnitude", "b_minus_v"):
        assert torch.allclose(at[name], grid[name][[3, 1]], rtol=0.0, atol=1e-9), name
    with pytest.raises(ValueError, match="n_times and times"):
        lunar_light_curve("2019-01-21", False, n_times=5, times=times)


def test_initial_values_outside_the_bounds_raise():
    from skytorch.eclipse.retrieval import PARAMETER_BOUNDS

    low, high = PARAMETER_BOUNDS["ozone_du"]
    for value in (low, high * 2.0):
        with pytest.raises(ValueError, match="initial\\['ozone_du'\\] must be in"):
            retrieve_atmosphere({"v_magnitude": (-2.0, 0.1)}, "2015-09-28",
                                parameters=("ozone_du",), initial={"ozone_du": value})


@pytest.mark.slow
def test_a_parameter_driven_to_its_bound_is_flagged():
    """An observed Moon far brighter than any stratospheric layer allows: AOD at 1e-7."""
    fit = retrieve_atmosphere({"v_magnitude": (-6.0, 0.1)}, "2015-09-28", n_times=3,
                              table_n_v=16)
    assert bool(fit.at_bound.sel(parameter="stratospheric_aod_550"))
    assert float(fit.best_fit[0]) < 2e-7 and np.isnan(float(fit.uncertainty[0]))
    assert "at a bound" in fit.attrs["note"]


def test_the_limb_clear_probability_is_refused_with_bands():
    with pytest.raises(ValueError, match="limb_clear_7km cannot be fitted"):
        retrieve_atmosphere({"v_magnitude": (-2.0, 0.1)}, "2015-09-28",
                            parameters=("limb_clear_7km",), terminator="latitude_bands")


@pytest.mark.slow
def test_recovers_the_limb_clear_probability_from_v_and_b():
    """The limb's clear probability at 7 km with the stratospheric AOD (σ 0.03 mag).

    Measured (table_n_v 32): 0.0150 ± 0.0004 and 0.399 ± 0.021 against 0.015 and 0.40.
    """
    from skytorch.eclipse import cloud_climatology

    date, n_v, sigma = "2019-01-21", 32, 0.03
    with torch.no_grad():
        curve = lunar_light_curve(date, shadow=eclipse_shadow(
            date, atmosphere=eclipse_atmosphere(date, stratospheric_aod_550=0.015),
            cloud_cover=cloud_climatology(0.40)), times=_TIMES_2019, table_n_v=n_v)
    noise = np.random.default_rng(2).normal(0.0, sigma, (2, _TIMES_2019.size))
    observed = _light_curve_dataset(
        np.concatenate([_TIMES_2019, _TIMES_2019]), ["V"] * 8 + ["B"] * 8,
        np.concatenate([curve["v_magnitude"].numpy(), curve["b_magnitude"].numpy()])
        + noise.reshape(-1), np.full(16, sigma))
    truth = {"stratospheric_aod_550": 0.015, "limb_clear_7km": 0.40}
    fit = retrieve_atmosphere(observed, date, parameters=tuple(truth), table_n_v=n_v,
                              max_iter=30)
    for name, value in truth.items():
        best = float(fit.best_fit.sel(parameter=name))
        spread = float(fit.uncertainty.sel(parameter=name))
        assert 0.0 < spread < value and abs(best - value) < 2.0 * spread, (name, best, spread)


def test_retrieval_shadow_refuses_unknown_and_band_parameters():
    from skytorch.eclipse import retrieval_shadow

    with pytest.raises(ValueError, match="turbidity"):
        retrieval_shadow("2015-09-28", {"turbidity": 2.0})
    with pytest.raises(ValueError, match="limb_clear_7km cannot be fitted"):
        retrieval_shadow("2015-09-28", {"limb_clear_7km": 0.5}, "latitude_bands")
