r"""Retrieval of the atmosphere of an eclipse from the Moon's observed brightness and colour.

:func:`retrieve_atmosphere` fits parameters of :func:`~skytorch.eclipse.eclipse_atmosphere`
(stratospheric and tropospheric aerosol optical depth at 550 nm, ozone column) and of the
limb cloud profile (:func:`~skytorch.eclipse.cloud_climatology`: the clear-line-of-sight
probability at 7 km) to the observed V magnitude and B − V at mid-totality, or to a light
curve, by minimising

.. math::

    \chi^2(\mathbf{x}) = \sum_j \Big(\frac{m_j(\mathbf{x}) - o_j}{\sigma_j}\Big)^2,
    \qquad \mathbf{x} = \log \mathbf{p},

with L-BFGS (strong Wolfe line search) on the autograd gradient of the modelled light
curve (:func:`~skytorch.eclipse.lunar_light_curve`, the shadow carries gradients with
respect to these parameters). Each parameter is kept within its range
:math:`[p_{lo}, p_{hi}]` (:data:`PARAMETER_BOUNDS`) by a logistic map of log space,
:math:`\log p = \log p_{lo} + (\log p_{hi} - \log p_{lo})\,s(z)` with :math:`s` the
logistic function and z unconstrained (without it a line search along a poorly
constrained direction steps to optical depths of 1e7); a parameter whose s lies within
0.01 of 0 or 1 (1 % of its log range from a bound) is reported ``at_bound``. The
uncertainties are the Laplace approximation with the Gauss–Newton Hessian
:math:`H = 2 J^\top W J` (J the Jacobian of the modelled observables in z, W the inverse
variances): :math:`\sigma_{z_i} = \sqrt{(2 H^{-1})_{ii}}`
and :math:`\sigma_{p_i} = |\mathrm{d}p_i/\mathrm{d}z_i|\,\sigma_{z_i}` to first order
(the same as in log space away from the bounds; NaN at a bound, where it means nothing).
With fewer observables than parameters the Hessian is singular and the uncertainties are
infinite (reported as inf, with a note in the Dataset's attributes), not regularised.

The modelled value at mid-totality is the faintest V sample of the light curve (and the
B − V at that sample). A light curve (an :class:`xarray.Dataset` of V and B samples at
given times, ``observations`` in its second form) is modelled at its own times
(``lunar_light_curve(..., times=...)``), each sample in its band.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
import xarray as xr

from skytorch._validate import check_choice, check_int
from skytorch.eclipse.eclipse_atmosphere import (
    LIMB_CLEAR_7KM,
    TERMINATOR_MODELS,
    cloud_climatology,
    eclipse_atmosphere,
    eclipse_shadow,
)
from skytorch.eclipse.lunar import lunar_light_curve, nearest_eclipse
from skytorch.ephemeris import parse_times

__all__ = ["LIGHT_CURVE_BANDS", "LIGHT_CURVE_VARIABLES", "OBSERVABLES", "PARAMETERS",
           "PARAMETER_BOUNDS", "retrieval_shadow", "retrieve_atmosphere"]

#: the parameters that can be fitted: those of :func:`~skytorch.eclipse.eclipse_atmosphere`
#: and the limb cloud profile's clear-line-of-sight probability at 7 km
#: (:func:`~skytorch.eclipse.cloud_climatology`)
PARAMETERS = ("stratospheric_aod_550", "tropospheric_aod", "ozone_du", "limb_clear_7km")
#: the observables at mid-totality [mag]
OBSERVABLES = ("v_magnitude", "b_minus_v")
#: the bands of a light curve's samples (Johnson V and B, Bessell passbands)
LIGHT_CURVE_BANDS = ("V", "B")
#: the variables of a light curve Dataset over its ``sample`` dimension
LIGHT_CURVE_VARIABLES = ("time", "band", "magnitude", "uncertainty")
_INITIAL = {"stratospheric_aod_550": 0.01, "tropospheric_aod": 0.12, "ozone_du": 300.0,
            "limb_clear_7km": LIMB_CLEAR_7KM}
#: the range each fitted parameter is kept in [1, 1, DU, 1]: optical depths from none that
#: matters to beyond any eruption of the record (El Chichón and Pinatubo: 0.1-0.2), ozone
#: beyond the extremes of the total column (about 100-600 DU), the limb's clear
#: probability at 7 km within (0, 1) (SAGE measured 0.30-0.60)
PARAMETER_BOUNDS = {"stratospheric_aod_550": (1e-7, 1.0), "tropospheric_aod": (1e-4, 3.0),
                    "ozone_du": (50.0, 800.0), "limb_clear_7km": (0.01, 0.99)}
#: distance of the logistic map from 0 or 1 within which a parameter is at its bound
_AT_BOUND = 1e-2


@dataclass(frozen=True)
class _Observed:
    """What is fitted: values, uncertainties, and how the model selects its values.

    ``dim`` and ``coords`` label the observed values in the result; ``times`` are the light
    curve's instants (None: the model's default grid, mid-totality observables);
    ``select`` maps the modelled light curve to the observed quantities.
    """

    target: torch.Tensor
    sigma: torch.Tensor
    dim: str
    coords: dict
    times: np.ndarray | None
    select: Callable[[dict], torch.Tensor]


def _check_light_curve(observations: xr.Dataset) -> _Observed:
    missing = [name for name in LIGHT_CURVE_VARIABLES if name not in observations.variables]
    if missing or any(observations[name].dims != ("sample",) for name in LIGHT_CURVE_VARIABLES):
        raise ValueError(f"observations (a light curve) must have the variables "
                         f"{LIGHT_CURVE_VARIABLES} over one dimension 'sample'; missing "
                         f"{missing}, dimensions "
                         f"{ {n: observations[n].dims for n in observations.variables} }")
    bands = [str(b) for b in observations["band"].values]
    unknown = sorted(set(bands) - set(LIGHT_CURVE_BANDS))
    if unknown:
        raise ValueError(f"observations['band'] must hold bands from {LIGHT_CURVE_BANDS}; "
                         f"got {unknown}")
    magnitude = np.asarray(observations["magnitude"].values, dtype=np.float64)
    sigma = np.asarray(observations["uncertainty"].values, dtype=np.float64)
    if not np.isfinite(magnitude).all() or not (np.isfinite(sigma) & (sigma > 0)).all():
        raise ValueError("observations (a light curve) must have finite magnitudes and "
                         f"uncertainties > 0 [mag]; got magnitude {magnitude}, uncertainty "
                         f"{sigma}")
    times, time_index = np.unique(parse_times(observations["time"].values),
                                  return_inverse=True)
    band_index = torch.tensor([LIGHT_CURVE_BANDS.index(b) for b in bands])
    time_index = torch.as_tensor(time_index.reshape(-1))

    def select(curve):
        return torch.stack([curve["v_magnitude"], curve["b_magnitude"]])[band_index,
                                                                          time_index]

    return _Observed(torch.as_tensor(magnitude), torch.as_tensor(sigma), "sample",
                     {"time": ("sample", observations["time"].values),
                      "band": ("sample", np.array(bands))}, times, select)


def _check_observations(observations) -> _Observed:
    if isinstance(observations, xr.Dataset):
        return _check_light_curve(observations)
    if not isinstance(observations, dict) or not observations:
        raise TypeError("observations must be a non-empty dict {name: (value, uncertainty)} "
                        f"with names in {OBSERVABLES}, or a light curve (xarray.Dataset); "
                        f"got {observations!r:.80}")
    checked = {}
    for name, pair in observations.items():
        if name not in OBSERVABLES:
            raise ValueError(f"observations key must be one of {OBSERVABLES}; got {name!r}")
        if (not isinstance(pair, (tuple, list)) or len(pair) != 2
                or not all(isinstance(v, (int, float, np.number))
                           and not isinstance(v, (bool, np.bool_)) for v in pair)):
            raise TypeError(f"observations[{name!r}] must be a pair of numbers (value, "
                            f"uncertainty) [mag]; got {pair!r:.60}")
        value, sigma = (float(v) for v in pair)
        if not np.isfinite(value) or not (np.isfinite(sigma) and sigma > 0):
            raise ValueError(f"observations[{name!r}] must be a finite value and an "
                             f"uncertainty > 0 [mag]; got {pair!r}")
        checked[name] = (value, sigma)
    rows = [OBSERVABLES.index(name) for name in checked]

    def select(curve):
        k = int(torch.argmax(curve["v_magnitude"].detach()))  # mid-totality: the faintest
        return torch.stack([curve["v_magnitude"][k], curve["b_minus_v"][k]])[rows]

    return _Observed(torch.tensor([v for v, _ in checked.values()], dtype=torch.float64),
                     torch.tensor([u for _, u in checked.values()], dtype=torch.float64),
                     "observable", {"observable": list(checked)}, None, select)


def _log_bounds(names) -> tuple[torch.Tensor, torch.Tensor]:
    low, high = (torch.tensor([np.log(PARAMETER_BOUNDS[n][k]) for n in names],
                              dtype=torch.float64) for k in (0, 1))
    return low, high - low


def _values(names, z) -> torch.Tensor:
    """Parameters (in ``names`` order) from the unconstrained ``z`` (logistic log map)."""
    low, span = _log_bounds(names)
    return torch.exp(low + span * torch.sigmoid(z))


def _check_band_parameters(names, terminator: str) -> None:
    """Refuse the parameters that the latitude bands take from their own climatology."""
    taken = {"ozone_du": "AFGL ozone column",
             "limb_clear_7km": "SAGE clear probability (tropics or higher latitudes)"}
    for name, what in taken.items():
        if terminator != "global" and name in names:
            raise ValueError(f"terminator={terminator!r} takes each band's {what}: {name} "
                             "cannot be fitted there; fit it with terminator='global'")


def retrieval_shadow(date, parameters: dict, terminator: str = "global"):
    """Return the shadow that :func:`retrieve_atmosphere` models for given parameter values.

    Parameters
    ----------
    date : str, datetime or datetime64
        Date of the eclipse (UTC).
    parameters : dict
        Values of some of :data:`PARAMETERS` (floats or tensors); the others keep the
        defaults of :func:`~skytorch.eclipse.eclipse_atmosphere` and
        :func:`~skytorch.eclipse.cloud_climatology`.
    terminator : {"global", "latitude_bands", "latitude_bands_mean"}
        As in :func:`retrieve_atmosphere` (the bands take neither ``ozone_du`` nor
        ``limb_clear_7km``).

    Returns
    -------
    skytorch.eclipse.shadow.Shadow or skytorch.eclipse.shadow_mixture.ShadowMixture
        ``eclipse_shadow(date, ...)`` with the limb cloud profile.
    """
    values = dict(parameters)
    unknown = sorted(set(values) - set(PARAMETERS))
    if unknown:
        raise ValueError(f"parameters must be names from {PARAMETERS}; got {unknown}")
    _check_band_parameters(values, terminator)
    clear = values.pop("limb_clear_7km", None)
    if terminator == "global":
        # the date's shadow: the clouds block the lowest limb rays as in the comparison
        cover = None if clear is None else cloud_climatology(clear)
        return eclipse_shadow(date, atmosphere=eclipse_atmosphere(date, **values),
                              cloud_cover=cover)
    # the aerosol optical depths are those of every band
    return eclipse_shadow(date, terminator=terminator, **values)


def _model(date, names, z, observed, n_times, table_n_v, terminator="global"):
    """Modelled observed quantities for the unconstrained parameters ``z``."""
    shadow = retrieval_shadow(date, dict(zip(names, _values(names, z), strict=True)),
                              terminator)
    grid = ({"n_times": n_times} if observed.times is None else {"times": observed.times})
    return observed.select(lunar_light_curve(date, shadow=shadow, table_n_v=table_n_v, **grid))


def retrieve_atmosphere(observations, date, parameters=("stratospheric_aod_550",), *,  # noqa: C901 (argument checks)
                        initial=None, n_times: int = 9, table_n_v: int = 64,
                        max_iter: int = 20, terminator: str = "global") -> xr.Dataset:
    """Fit atmosphere parameters to the observed mid-totality V (and B − V) of an eclipse.

    Parameters
    ----------
    observations : dict or xarray.Dataset
        Mid-totality: ``{"v_magnitude": (value, uncertainty), "b_minus_v": (value,
        uncertainty)}`` [mag] (either or both). A light curve: a Dataset over ``sample``
        with ``time`` (UTC, within 12 h of greatest eclipse), ``band`` (``"V"`` or
        ``"B"``), ``magnitude`` and ``uncertainty`` [mag] (:data:`LIGHT_CURVE_VARIABLES`),
        each sample modelled at its own time and in its band.
    date : str, datetime or datetime64
        Date of the eclipse (UTC).
    parameters : sequence of str
        Names among :data:`PARAMETERS` to fit; the others keep the defaults of
        :func:`~skytorch.eclipse.eclipse_atmosphere` and
        :func:`~skytorch.eclipse.cloud_climatology`.
    initial : dict, optional
        Starting values per fitted parameter, inside :data:`PARAMETER_BOUNDS`; default
        0.01, 0.12, 300 DU and the terminator's SAGE mean 0.516.
    n_times, table_n_v : int
        Light-curve samples (mid-totality observations only) and shadow-table rows of the
        model.
    max_iter : int
        L-BFGS iterations.
    terminator : {"global", "latitude_bands", "latitude_bands_mean"}
        The limb atmosphere of :func:`~skytorch.eclipse.eclipse_shadow`; with the latitude
        bands the aerosol optical depths are fitted for every band at once, the ozone is
        each band's AFGL column and the clouds each band's SAGE zone (``"ozone_du"`` and
        ``"limb_clear_7km"`` cannot be fitted: ``ValueError``).

    Returns
    -------
    xarray.Dataset
        ``best_fit`` and ``uncertainty`` over ``parameter`` [1, 1, DU] (with ``at_bound``,
        ``lower_bound`` and ``upper_bound``); ``observed``,
        ``observed_uncertainty``, ``model`` and ``residual`` (model − observed) over
        ``observable`` [mag] (over ``sample``, with its ``time`` and ``band``, for a light
        curve); attribute ``chi2``.

    Examples
    --------
    >>> import numpy as np, xarray as xr
    >>> from skytorch.eclipse import retrieve_atmosphere
    >>> curve = xr.Dataset({
    ...     "time": ("sample", np.array(["2019-01-21T04:43", "2019-01-21T05:13:30"],
    ...                                 dtype="datetime64[ns]")),
    ...     "band": ("sample", ["V", "V"]), "magnitude": ("sample", [-3.18, -2.04]),
    ...     "uncertainty": ("sample", [0.3, 0.3])})
    >>> fit = retrieve_atmosphere(curve, "2019-01-21", table_n_v=16, max_iter=2)
    >>> fit.residual.dims, fit.band.values.tolist()
    (('sample',), ['V', 'V'])
    """
    observed = _check_observations(observations)
    eclipse = nearest_eclipse(date)
    if str(eclipse["kind"].values[0]) != "total":
        raise ValueError(f"date: the lunar eclipse nearest it "
                         f"({np.datetime_as_string(eclipse.time.values[0], 'm')}) is "
                         f"{eclipse['kind'].values[0]}, without a totality; the observables "
                         "are those of mid-totality")
    names = tuple(parameters)
    if not names or any(name not in PARAMETERS for name in names) or len(set(names)) != len(
            names):
        raise ValueError(f"parameters must be distinct names from {PARAMETERS}; got "
                         f"{parameters!r}")
    check_choice("terminator", terminator, TERMINATOR_MODELS)
    _check_band_parameters(names, terminator)
    n_times = check_int("n_times", n_times, low=3)
    table_n_v = check_int("table_n_v", table_n_v, low=16)
    max_iter = check_int("max_iter", max_iter, low=1)
    start = dict(_INITIAL)
    for name, value in (initial or {}).items():
        if name not in names:
            raise ValueError(f"initial must map fitted parameters {names} to values; got "
                             f"{name!r}: {value!r}")
        low, high = PARAMETER_BOUNDS[name]
        if not low < float(value) < high:
            raise ValueError(f"initial[{name!r}] must be in ({low}, {high}) "
                             f"(PARAMETER_BOUNDS); got {value!r}")
        start[name] = float(value)
    target, sigma = observed.target, observed.sigma
    low, span = _log_bounds(names)
    fraction = (torch.tensor([np.log(start[n]) for n in names], dtype=torch.float64)
                - low) / span
    x = torch.logit(fraction).requires_grad_(True)
    optimiser = torch.optim.LBFGS([x], lr=1.0, max_iter=max_iter,
                                  line_search_fn="strong_wolfe")

    def closure():
        optimiser.zero_grad()
        model = _model(date, names, x, observed, n_times, table_n_v, terminator)
        chi2 = (((model - target) / sigma) ** 2).sum()
        chi2.backward()
        return chi2

    optimiser.step(closure)
    best = x.detach().clone()
    jacobian = torch.autograd.functional.jacobian(
        lambda y: _model(date, names, y, observed, n_times, table_n_v, terminator), best)
    with torch.no_grad():  # the fit is done: values only from here
        model = _model(date, names, best, observed, n_times, table_n_v, terminator)
        weighted = jacobian / sigma[:, None]
        hessian = 2.0 * weighted.T @ weighted
        notes = []
        if torch.linalg.matrix_rank(hessian) < len(names):
            sigma_z = torch.full((len(names),), float("inf"), dtype=torch.float64)
            notes.append("singular Hessian (fewer constraints than parameters): "
                         "uncertainty inf")
        else:
            sigma_z = torch.sqrt(torch.diagonal(2.0 * torch.linalg.inv(hessian)))
        values = _values(names, best)
        s = torch.sigmoid(best)
        at_bound = (s < _AT_BOUND) | (s > 1.0 - _AT_BOUND)
        spread = torch.where(at_bound, float("nan"), values * span * s * (1.0 - s) * sigma_z)
        if at_bound.any():
            notes.append("at a bound of PARAMETER_BOUNDS (uncertainty NaN): "
                         + ", ".join(n for n, b in zip(names, at_bound.tolist(), strict=True)
                                     if b))
        note = "; ".join(notes)
        chi2 = float((((model - target) / sigma) ** 2).sum())
    return xr.Dataset(
        {"best_fit": (("parameter",), values.numpy()),
         "uncertainty": (("parameter",), spread.numpy()),
         "at_bound": (("parameter",), at_bound.numpy()),
         "lower_bound": (("parameter",), [PARAMETER_BOUNDS[n][0] for n in names]),
         "upper_bound": (("parameter",), [PARAMETER_BOUNDS[n][1] for n in names]),
         "observed": ((observed.dim,), target.numpy(), {"units": "mag"}),
         "observed_uncertainty": ((observed.dim,), sigma.numpy(), {"units": "mag"}),
         "model": ((observed.dim,), model.numpy(), {"units": "mag"}),
         "residual": ((observed.dim,), (model - target).numpy(), {"units": "mag"})},
        coords={"parameter": list(names), **observed.coords},
        attrs={"title": "Atmosphere retrieved from a lunar eclipse", "chi2": chi2,
               "terminator": terminator,
               "date": str(np.datetime64(date, "D")) if isinstance(date, str) else str(date),
               "note": note, "table_n_v": table_n_v,
               **({"n_times": n_times} if observed.times is None else {})})
