"""Fuzz the public entry points of skytorch against the input contract.

Each entry point has a valid baseline call. Every parameter of it is then replaced, one at
a time, by inputs from three pools:

* **bad** -- values no parameter accepts (``None``, a string, an object, NaN, +-inf, a
  tensor whose shape does not broadcast with the others) and a misspelled keyword;
* **out of range** -- values outside the documented range of that parameter;
* **valid variants** -- integer tensors and other spellings that must be accepted.

Each call is classified:

=================  ================================================================
``ok``             a valid input returned an all-finite result
``clean``          a bad input raised ValueError/TypeError naming the parameter
``vague``          a bad input raised ValueError/TypeError naming no parameter
``crash``          any other exception type (RuntimeError, IndexError, ...)
``silent``         a bad or out-of-range input was accepted
``nonfinite``      a valid input returned NaN or inf
``rejected``       a valid input was refused
=================  ================================================================

Run ``python tools/fuzz_entry_points.py`` (about a minute); it prints a table per entry
point and the totals, and exits non-zero if anything but ``ok`` and ``clean`` occurred.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import traceback
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
import xarray as xr

BAD = {"None": None, "str": "x", "object": object(), "nan": math.nan, "inf": math.inf,
       "-inf": -math.inf}


@dataclass
class EntryPoint:
    """A public callable, a valid baseline and the parameters to mutate."""

    name: str
    call: Callable[..., object]
    baseline: dict
    #: parameter -> list of out-of-range values
    out_of_range: dict = field(default_factory=dict)
    #: parameters that are tensors of the common batch shape (for shape mismatches)
    batched: tuple = ()
    #: parameters whose integer spelling must be accepted
    integer_ok: tuple = ()
    #: parameters not to mutate with the BAD pool (e.g. optional objects where None is valid)
    skip_bad: tuple = ()
    #: the baseline itself is invalid and must be refused
    expect_error: bool = False
    #: parameters for which None is a valid value (the documented default)
    none_ok: tuple = ()


def _finite(value) -> bool:
    if isinstance(value, torch.Tensor):
        return not value.is_floating_point() or bool(torch.isfinite(value.detach()).all())
    if isinstance(value, np.ndarray):
        return not np.issubdtype(value.dtype, np.floating) or bool(np.isfinite(value).all())
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, xr.Dataset):
        return all(_finite(np.asarray(v.values)) for v in value.data_vars.values())
    if isinstance(value, xr.DataArray):
        return _finite(np.asarray(value.values))
    if isinstance(value, dict):
        return all(_finite(v) for v in value.values())
    if isinstance(value, (tuple, list)):
        return all(_finite(v) for v in value)
    return True


def classify(entry: EntryPoint, arguments: dict, parameter: str, valid: bool) -> tuple[str, str]:
    try:
        result = entry.call(**arguments)
    except (ValueError, TypeError) as error:
        if valid:
            return "rejected", f"{type(error).__name__}: {error}"
        named = parameter in str(error) or parameter in ("<keyword>", "<baseline>")
        return ("clean" if named else "vague"), f"{type(error).__name__}: {error}"
    except Exception as error:  # noqa: BLE001 - the classification itself
        return "crash", f"{type(error).__name__}: {error}".splitlines()[0][:200] + (
            "\n" + "".join(traceback.format_tb(error.__traceback__)[-2:]))
    if not valid:
        return "silent", "accepted"
    return ("ok", "") if _finite(result) else ("nonfinite", "non-finite result")


def mutations(entry: EntryPoint):
    """(parameter, arguments, valid, label) for every mutation of the baseline."""
    yield "<baseline>", dict(entry.baseline), not entry.expect_error, "baseline"
    for parameter, value in entry.baseline.items():
        if parameter not in entry.skip_bad:
            for label, bad in BAD.items():
                valid = bad is None and parameter in entry.none_ok
                yield parameter, {**entry.baseline, parameter: bad}, valid, label
        for bad in entry.out_of_range.get(parameter, ()):
            yield parameter, {**entry.baseline, parameter: bad}, False, f"range {bad!r}"
        if parameter in entry.batched:
            mismatch = torch.ones(7, dtype=torch.float64) * torch.as_tensor(value).reshape(-1)[0]
            yield parameter, {**entry.baseline, parameter: mismatch}, False, "shape (7,)"
        if parameter in entry.integer_ok:
            integer = torch.as_tensor(value).round().to(torch.int64)
            yield parameter, {**entry.baseline, parameter: integer}, True, "integer tensor"
    yield "<keyword>", {**entry.baseline, "no_such_keyword": 1.0}, False, "unknown keyword"


def entry_points() -> list[EntryPoint]:
    """Return the fuzzed entry points (phase angles are signed: [-pi, pi] is valid)."""
    import skytorch as st
    from skytorch.atmosphere import Atmosphere
    from skytorch.eclipse import danjon_l, shadow_radii, sun_visible_fraction
    from skytorch.moon import illuminated_fraction, magnitude, moonlit_sky_ks1991, phase_angle
    from skytorch.stars import limiting_magnitude, scintillation_index

    atmosphere = Atmosphere.earth()
    atmosphere_batch = Atmosphere.earth(turbidity=torch.tensor([2.0, 3.0], dtype=torch.float64))
    heights = torch.tensor([0.0, 100.0, 2000.0], dtype=torch.float64)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from _skyglow_standin import cached_model

    skyglow = cached_model()
    city = st.skyglow.synthetic_city(extent_m=8000.0, cell_m=1000.0)
    catalog = st.stars.bright_stars(3.0)
    shadow = st.eclipse.Shadow(occluder_radius_m=6.371e6, sun_distance_m=1.496e11,
                               atmosphere=atmosphere, n_altitude=41, trace_nodes=16)
    dataset = st.ephemeris.sun_moon(["2015-09-28T02:47Z"])
    three = torch.tensor([400.0, 550.0, 700.0], dtype=torch.float64)
    zen = torch.tensor([0.0, 1.0, 1.5], dtype=torch.float64)
    return [
        EntryPoint("Atmosphere.earth", Atmosphere.earth,
                   {"turbidity": 2.0, "ozone_du": 300.0},
                   out_of_range={"turbidity": [0.5, -1.0], "ozone_du": [-10.0]},
                   none_ok=("turbidity",)),
        EntryPoint("Atmosphere.optical_depth", atmosphere.optical_depth,
                   {"wavelength_nm": three, "zenith_rad": zen, "altitude_m": heights,
                    "rtol": 1e-9},
                   out_of_range={"wavelength_nm": [-500.0, 0.0], "altitude_m": [-1e3],
                                 "zenith_rad": [4.0], "rtol": [-1e-3, 0.0]},
                   batched=("zenith_rad", "altitude_m"),
                   integer_ok=("wavelength_nm", "altitude_m")),
        EntryPoint("Atmosphere.optical_depth(refraction)", atmosphere_batch.optical_depth,
                   {"wavelength_nm": three, "zenith_rad": zen[:, None],
                    "altitude_m": heights[:, None], "refraction": True},
                   out_of_range={"zenith_rad": [4.0]}, batched=("zenith_rad", "altitude_m")),
        EntryPoint("Atmosphere.transmittance", atmosphere.transmittance,
                   {"wavelength_nm": three, "zenith_rad": zen, "altitude_m": heights},
                   out_of_range={"wavelength_nm": [-500.0], "altitude_m": [-1e3]},
                   batched=("zenith_rad", "altitude_m"), integer_ok=("wavelength_nm",)),
        EntryPoint("Atmosphere.sky_radiance", atmosphere.sky_radiance,
                   {"wavelength_nm": three, "view_zenith_rad": zen, "sun_zenith_rad": zen / 2},
                   out_of_range={"wavelength_nm": [-500.0]},
                   batched=("view_zenith_rad", "sun_zenith_rad"),
                   integer_ok=("wavelength_nm",)),
        EntryPoint("Atmosphere.apparent_altitude", atmosphere.apparent_altitude,
                   {"true_altitude_rad": torch.tensor([0.0, 0.1, 0.5], dtype=torch.float64),
                    "altitude_m": heights},
                   out_of_range={"true_altitude_rad": [3.0], "altitude_m": [-1e4]},
                   batched=("true_altitude_rad", "altitude_m")),
        EntryPoint("eclipse.sun_visible_fraction", sun_visible_fraction,
                   {"sun_radius_rad": torch.full((3,), 4.65e-3, dtype=torch.float64),
                    "occluder_radius_rad": torch.full((3,), 4.7e-3, dtype=torch.float64),
                    "separation_rad": torch.tensor([0.0, 3e-3, 2e-2], dtype=torch.float64)},
                   out_of_range={"sun_radius_rad": [-1e-3, 0.0], "separation_rad": [-1.0],
                                 "limb_darkening": [2.0, -0.5]},
                   batched=("sun_radius_rad", "separation_rad")),
        EntryPoint("eclipse.shadow_radii", shadow_radii,
                   {"distance_m": 3.844e8, "sun_distance_m": 1.496e11,
                    "sun_radius_m": 6.957e8, "occluder_radius_m": 6.371e6},
                   out_of_range={"distance_m": [-1.0], "sun_distance_m": [0.0, -1.0],
                                 "sun_radius_m": [0.0], "occluder_radius_m": [-1.0]},
                   integer_ok=("distance_m",)),
        EntryPoint("eclipse.danjon_l", danjon_l, {"v_magnitude": -2.0},
                   integer_ok=("v_magnitude",)),
        EntryPoint("eclipse.lunar_eclipses", st.eclipse.lunar_eclipses,
                   {"start": "2015-01-01", "end": "2016-01-01"},
                   skip_bad=()),
        EntryPoint("moon.magnitude", magnitude,
                   {"phase_angle_rad": torch.tensor([0.0, 1.0, 3.0], dtype=torch.float64),
                    "distance_m": torch.full((3,), 3.844e8, dtype=torch.float64),
                    "n_quadrature": 16},
                   out_of_range={"phase_angle_rad": [-4.0, 4.0], "n_quadrature": [0, -3, 2.5],
                                 "distance_m": [0.0, -1.0]},
                   batched=("phase_angle_rad", "distance_m")),
        EntryPoint("moon.phase_angle", phase_angle,
                   {"sun_vec": torch.tensor([[1.5e11, 0.0, 0.0]], dtype=torch.float64),
                    "moon_vec": torch.tensor([[0.0, 3.8e8, 0.0], [3.8e8, 1e7, 0.0]],
                                             dtype=torch.float64)},
                   skip_bad=()),
        EntryPoint("moon.phase_angle(mismatch)", phase_angle,
                   {"sun_vec": torch.ones(2, 3, dtype=torch.float64) * 1.5e11,
                    "moon_vec": torch.ones(3, 3, dtype=torch.float64) * 3.8e8},
                   skip_bad=("sun_vec", "moon_vec"), expect_error=True),
        EntryPoint("moon.illuminated_fraction", illuminated_fraction,
                   {"phase_angle_rad": torch.tensor([0.0, 1.0, 3.1], dtype=torch.float64)},
                   out_of_range={"phase_angle_rad": [-4.0, 4.0]},
                   integer_ok=("phase_angle_rad",)),
        EntryPoint("moon.moonlit_sky_ks1991", moonlit_sky_ks1991,
                   {"phase_angle_rad": 1.0, "separation_rad": zen[1:] + 0.2,
                    "moon_zenith_rad": 0.8, "zenith_rad": zen[1:]},
                   out_of_range={"phase_angle_rad": [-4.0], "extinction_mag": [-0.1]},
                   batched=("separation_rad", "zenith_rad")),
        EntryPoint("stars.limiting_magnitude", limiting_magnitude,
                   {"sky_mag_arcsec2": torch.tensor([18.0, 21.0, 22.0], dtype=torch.float64)},
                   out_of_range={"pupil_diameter_mm": [0.0, -1.0]},
                   integer_ok=("sky_mag_arcsec2",)),
        EntryPoint("stars.scintillation_index", scintillation_index,
                   {"airmass": torch.tensor([1.0, 2.0, 5.0], dtype=torch.float64)},
                   out_of_range={"airmass": [0.5, -1.0], "aperture_m": [0.0, -1.0],
                                 "exposure_s": [0.0]},
                   integer_ok=("airmass",)),
        EntryPoint("ephemeris.sun_moon", st.ephemeris.sun_moon,
                   {"times": ["2015-09-28T02:47Z"], "lat_deg": 52.5, "lon_deg": 13.4},
                   out_of_range={"lat_deg": [91.0, -100.0], "lon_deg": [400.0],
                                 "elevation_m": [-1e5]},
                   skip_bad=()),
        EntryPoint("Scene", st.Scene,
                   {"time": "2015-09-28T02:47:00", "lat_deg": 52.5, "lon_deg": 13.4,
                    "turbidity": 2.0, "size": 16},
                   out_of_range={"lat_deg": [91.0], "turbidity": [0.5], "size": [0, -4],
                                 "elevation_m": [-1e3], "natural_mag_arcsec2": [-5.0, 60.0],
                                 "ozone_du": [-1.0]}),
        EntryPoint("stars.observe", st.stars.observe,
                   {"catalog": catalog, "times": "2015-09-28T02:47Z", "lat_deg": 52.5,
                    "lon_deg": 13.4, "twinkle_samples": 0},
                   out_of_range={"lat_deg": [95.0], "elevation_m": [-1e5],
                                 "aperture_m": [0.0, -1.0], "twinkle_samples": [-1]}),
        EntryPoint("SkyglowModel.render", skyglow.render,
                   {"light_map": city, "observer_xy": (0.0, 0.0), "observer_altitude_m": 0.0},
                   out_of_range={"observer_altitude_m": [-10.0, 1e6],
                                 "observer_xy": [(math.nan, 0.0), (0.0, 0.0, 0.0)]}),
        EntryPoint("skyglow.render_naive", st.skyglow.render_naive,
                   {"model": skyglow, "light_map": city, "observer_xy": (0.0, 0.0)},
                   out_of_range={"observer_xy": [(math.inf, 0.0)]}),
        EntryPoint("Shadow.relative_illuminance", shadow.relative_illuminance,
                   {"distance_m": 3.844e8, "offset_m": torch.tensor([0.0, 3e6, 6e6]),
                    "wavelength_nm": three},
                   out_of_range={"distance_m": [-1.0], "offset_m": [-1.0],
                                 "wavelength_nm": [-5.0, 0.0], "sun_distance_m": [0.0, -1.0]},
                   integer_ok=("offset_m",), skip_bad=("sun_distance_m",)),
        EntryPoint("to_netcdf", lambda dataset, path: st.to_netcdf(dataset, path),
                   {"dataset": dataset, "path": str(Path(tempfile.mkdtemp()) / "f.nc")},
                   skip_bad=("path",)),
        EntryPoint("sweep", lambda **kw: st.sweep(progress=False, **kw),
                   {"fn": lambda turbidity: {"t": turbidity * 2.0},
                    "turbidity": [2.0, 3.0], "units": {"turbidity": "1"}},
                   out_of_range={"units": [{"turbidity": 3}, ["turbidity"], {"nope": "1"}],
                                 "turbidity": [[]]},
                   skip_bad=("fn",), none_ok=("units",)),
        EntryPoint("skyglow.synthetic_city", st.skyglow.synthetic_city,
                   {"extent_m": 4000.0, "cell_m": 500.0},
                   out_of_range={"extent_m": [0.0, -1.0], "cell_m": [0.0, -5.0],
                                 "population": [-1.0]}),
    ]


def run(selected: list[str] | None = None, verbose: bool = False) -> Counter:
    totals: Counter = Counter()
    for entry in entry_points():
        if selected and entry.name not in selected:
            continue
        counts: Counter = Counter()
        for parameter, arguments, valid, label in mutations(entry):
            outcome, detail = classify(entry, arguments, parameter, valid)
            counts[outcome] += 1
            if outcome not in ("ok", "clean") and verbose:
                print(f"  {entry.name} {parameter}={label}: {outcome}: {detail}")
        totals.update(counts)
        print(f"{entry.name:32s} " + " ".join(f"{k}={v}" for k, v in sorted(counts.items())))
    print("TOTAL " + " ".join(f"{k}={v}" for k, v in sorted(totals.items())))
    return totals


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("entry", nargs="*", help="entry point names (default all)")
    parser.add_argument("-v", "--verbose", action="store_true", help="print every failure")
    args = parser.parse_args(argv)
    totals = run(args.entry or None, verbose=args.verbose)
    return 0 if set(totals) <= {"ok", "clean"} else 1


if __name__ == "__main__":
    sys.exit(main())
