"""Retrieval of the stratospheric optical depth from a synthetic mid-totality V."""

import math

import pytest
import torch

from skytorch.eclipse.retrieval import _model, retrieve_atmosphere


@pytest.mark.slow
def test_recovers_a_known_stratospheric_depth_from_noisy_v():
    date, truth = "2015-09-28", 0.05
    x = torch.tensor([math.log(truth)], dtype=torch.float64)
    v_true = float(_model(date, ("stratospheric_aod_550",), x, 9, 64)[0])
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


@pytest.mark.slow
def test_recovers_the_depth_through_the_latitude_bands():
    """The same retrieval through the bands resolved in direction (coarse model)."""
    date, truth = "2015-09-28", 0.05
    x = torch.tensor([math.log(truth)], dtype=torch.float64)
    v_true = float(_model(date, ("stratospheric_aod_550",), x, 3, 16, "latitude_bands")[0])
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
