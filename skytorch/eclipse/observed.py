"""Observed total lunar eclipses: Danjon L, V at mid-totality, colour, each with its source.

:func:`observed_lunar_eclipses` reads ``data/observed_lunar_eclipses.csv`` (one row per
eclipse; every value as printed in the row's source, an empty field where the source gives
none) into a Dataset over ``eclipse``, for comparisons of modelled eclipses with observed
ones (issue 15). The sources: the photometry of Hernitschek, Schmidt & Vollmer 2008
(1990-02-09, 2007-03-03) and of E. Schmidt (2011-06-15, 2014-04-15; 2022-11-08 with his
photometer),
Vital's REA reports (2004-10-28, 2008-02-21, 2010-12-21, 2015-09-28), the MBK Team's
visual estimates (2001-01-09, 2003-11-09) and a V/B photometer light curve of 2019-01-21
(Georgia Journal of Science 80(1), art. 32), and the post-Pinatubo 1992-12-09 from
Harrington's compilation (method not stated); data/README.md and the file header list them.

Not included, because their numbers could not be read in the material at hand: Keen 1983
(Science 222, 1011; 21 eclipses 1960-1982 turned into optical depths), Keen 2016 (the
2015-09-28 eclipse 33 % darker than expected), Mallama 2022 (arXiv 2112.08966; predicted,
not observed, V and colour 2000-2050) and Vital's 2019-01-21 report.

Examples
--------
>>> ds = observed_lunar_eclipses()
>>> int(ds.sizes["eclipse"]) >= 10, str(ds.v_magnitude.attrs["units"])
(True, 'mag')
"""

from __future__ import annotations

import csv
from functools import lru_cache

import numpy as np
import xarray as xr

from skytorch._data import data_path
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable

__all__ = ["OBSERVED_FILE", "METHODS", "observed_lunar_eclipses"]

#: the shipped table
OBSERVED_FILE = "observed_lunar_eclipses.csv"
#: how a magnitude was measured
METHODS = ("visual", "photometer", "camera", "not stated")

_FLOATS = ("danjon_l", "danjon_l_uncertainty", "v_magnitude", "v_uncertainty",
           "v_below_full_moon", "b_minus_v")
_TEXTS = ("method", "colour", "source", "url")

_SPECS = {
    "eclipse": VariableSpec("1", "eclipse", "UTC date of greatest eclipse"),
    "greatest_eclipse": VariableSpec("", "greatest eclipse",
                                     "UTC time of greatest eclipse where the source prints "
                                     "it (NaT otherwise)"),
    "danjon_l": VariableSpec("1", "Danjon L", "Danjon luminosity estimated by the observers "
                             "(mid-totality)"),
    "danjon_l_uncertainty": VariableSpec("1", "Danjon L uncertainty",
                                         "Uncertainty of danjon_l as printed by the source"),
    "v_magnitude": VariableSpec("mag", "V magnitude at mid-totality",
                                "Visual or Johnson V magnitude of the whole Moon at "
                                "mid-totality (photometers: the light-curve minimum)"),
    "v_uncertainty": VariableSpec("mag", "V magnitude uncertainty",
                                  "Uncertainty of v_magnitude as printed (half a printed "
                                  "range)"),
    "v_below_full_moon": VariableSpec("mag", "magnitudes below the full Moon",
                                      "Brightness at mid-totality relative to the "
                                      "uneclipsed full Moon, where only that is given"),
    "b_minus_v": VariableSpec("mag", "B - V at mid-totality", "Johnson B - V colour index"),
    "method": VariableSpec("1", "measurement method",
                           "visual (naked eye, reversed binoculars), photometer or camera"),
    "colour": VariableSpec("1", "colour", "Colour of the eclipsed Moon as described"),
    "source": VariableSpec("1", "source", "Citation of the row's values"),
    "url": VariableSpec("1", "source address", "Where the source can be read"),
}


@lru_cache(maxsize=1)
def _rows() -> tuple[dict[str, str], ...]:
    """Return the table's rows as text (read once; a pure function of the shipped file)."""
    with open(data_path(OBSERVED_FILE), newline="", encoding="utf-8") as handle:
        lines = [line for line in handle if not line.startswith("#")]
    return tuple(csv.DictReader(lines))


def _float(text: str) -> float:
    return float(text) if text.strip() else np.nan


def observed_lunar_eclipses() -> xr.Dataset:
    """Observed total lunar eclipses with the source of every row.

    Returns
    -------
    xarray.Dataset
        Dimension ``eclipse`` (coordinate: UTC date of greatest eclipse, datetime64).
        Variables (NaN / NaT / "" where the source gives nothing): ``greatest_eclipse``
        (UTC time, where the source prints it), ``danjon_l`` and ``danjon_l_uncertainty``
        [1], ``v_magnitude``, ``v_uncertainty``, ``v_below_full_moon`` and ``b_minus_v``
        [mag], ``method`` (one of :data:`METHODS`), ``colour``, ``source`` and ``url``
        (text). Global attributes: ``references`` (the distinct sources) and
        ``data_file``.

    Raises
    ------
    ValueError
        If the shipped table has a row without a source, an unknown method or a
        malformed date (a damaged installation).
    """
    rows = _rows()
    dates, greatest = [], []
    for index, row in enumerate(rows):
        if not row["source"].strip():
            raise ValueError(f"{OBSERVED_FILE}: row {index} ({row['date']}) has no source")
        if row["method"] not in METHODS:
            raise ValueError(f"{OBSERVED_FILE}: row {index} method must be one of "
                             f"{METHODS}; got {row['method']!r}")
        dates.append(np.datetime64(row["date"], "ns"))
        text = row["greatest_eclipse_utc"].strip()
        greatest.append(np.datetime64(text, "ns") if text else np.datetime64("NaT", "ns"))
    data_vars = {
        "greatest_eclipse": variable("eclipse", np.array(greatest), _SPECS["greatest_eclipse"]),
    }
    for name in _FLOATS:
        values = np.array([_float(row[name]) for row in rows], dtype=np.float64)
        data_vars[name] = variable("eclipse", values, _SPECS[name])
    for name in _TEXTS:
        data_vars[name] = variable("eclipse", np.array([row[name] for row in rows], dtype=str),
                                   _SPECS[name])
    coords = {"eclipse": coordinate("eclipse", np.array(dates), _SPECS["eclipse"])}
    references = list(dict.fromkeys(row["source"] for row in rows))
    return build_dataset(data_vars, coords, title="Observed total lunar eclipses",
                         references=references, data_file=OBSERVED_FILE)
