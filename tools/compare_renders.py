"""Render a fixed set of small scenes and compare two such runs bit for bit.

The scenes cover every component of the renderer: a day (sky and Sun), a civil/nautical
twilight (panorama), a moonlit night with stars, the 2015-09-28 lunar eclipse (an
all-sky view and a telescope view that resolves the eclipsed disc), a city with skyglow,
and a moonlit night seen by two observers at once (one ephemeris evaluation for both).
Every data variable, coordinate and attribute of each Dataset (except the wall times
``seconds_*`` and the creation time in ``history``) is saved to one ``.npz`` file.

Usage::

    python tools/compare_renders.py --save renders.npz        # render and save
    python tools/compare_renders.py --compare A.npz B.npz     # max |A - B| per variable

``--compare`` prints the largest absolute difference of every entry and exits with
status 1 unless both files hold the same entries, with the same dtypes, shapes and
bytes (NaN patterns included). The renders use a private, empty cache folder
(``SKYTORCH_CACHE_DIR``) unless ``--cache-dir`` is given, so every table is built by the
code under test rather than read from an earlier run.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: the scenes (name -> keyword arguments of skytorch.Scene, with "city" for a light map)
SCENES = {
    "day": {"time": "2015-06-21T12:00", "lat_deg": 48.85, "lon_deg": 2.35, "size": 24,
            "fidelity": "fast"},
    "twilight": {"time": "2015-06-21T20:50", "lat_deg": 48.85, "lon_deg": 2.35,
                 "view": "panorama", "size": 12, "fidelity": "fast"},
    "moonlit": {"time": "2015-08-29T23:00", "lat_deg": 52.52, "lon_deg": 13.40,
                "elevation_m": 34.0, "size": 24, "fidelity": "fast", "star_limit_mag": 4.0},
    "eclipse": {"time": "2015-09-28T02:47", "lat_deg": 52.52, "lon_deg": 13.40,
                "elevation_m": 34.0, "size": 24, "fidelity": "fast", "star_limit_mag": 4.0},
    "eclipse_camera": {"time": "2015-09-28T02:47", "lat_deg": 52.52, "lon_deg": 13.40,
                       "elevation_m": 34.0, "view": "camera", "size": 24,
                       "camera": {"fov_deg": 0.8, "target": "moon"}, "fidelity": "fast",
                       "turbidity": 3.0},
    "city": {"time": "2015-09-13T23:00", "lat_deg": 52.52, "lon_deg": 13.40,
             "elevation_m": 34.0, "size": 16, "fidelity": "fast", "city": True,
             "star_limit_mag": 3.0},
    "observers": {"time": "2015-08-29T23:00", "lat_deg": [52.52, 40.0],
                  "lon_deg": [13.40, -3.7], "elevation_m": [34.0, 650.0], "size": 12,
                  "fidelity": "fast", "star_limit_mag": 3.0, "dtype": "float32"},
}


def make_scene(name: str):
    """Return the :class:`skytorch.Scene` called ``name`` in :data:`SCENES`."""
    import torch

    import skytorch as st

    options = dict(SCENES[name])
    if options.pop("city", False):
        from skytorch.skyglow.citymap import synthetic_city

        options["light_map"] = synthetic_city(extent_m=40_000.0, cell_m=2_000.0,
                                              population=1e6, scale_length_m=4_000.0,
                                              centre_xy=(8_000.0, -9_000.0))
    if options.get("dtype") == "float32":
        options["dtype"] = torch.float32
    return st.Scene(**options)


def flatten(name: str, dataset) -> dict[str, np.ndarray]:
    """Return the variables, coordinates and attributes of a rendered Dataset.

    As ``{"<scene>/<kind>/<name>": array}``; wall times and creation time left out.
    """
    out = {}
    for key, value in dataset.data_vars.items():
        out[f"{name}/var/{key}"] = np.asarray(value.values)
    for key, value in dataset.coords.items():
        out[f"{name}/coord/{key}"] = np.asarray(value.values)
    for key, value in dataset.attrs.items():
        if key == "history" or "seconds_" in key:
            continue  # creation time and wall times
        if key == "parameters":
            value = json.dumps({k: v for k, v in json.loads(value).items()
                                if not k.startswith("seconds_")}, sort_keys=True)
        out[f"{name}/attr/{key}"] = np.asarray(repr(value))
    return out


def render_all(names=None, resources=None) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """Render the scenes (all of :data:`SCENES` by default); arrays and seconds each."""
    arrays, seconds = {}, {}
    for name in names or SCENES:
        scene = make_scene(name)
        start = time.perf_counter()
        dataset = scene.render() if resources is None else scene.render(resources=resources)
        seconds[name] = time.perf_counter() - start
        arrays.update(flatten(name, dataset))
    return arrays, seconds


def _identical(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def _max_difference(a: np.ndarray, b: np.ndarray) -> str:
    if a.shape != b.shape:
        return f"shapes {a.shape} / {b.shape}"
    if a.dtype.kind in "fc" and b.dtype.kind in "fc":
        nan_a, nan_b = np.isnan(a), np.isnan(b)
        if (nan_a != nan_b).any():
            return f"NaN at {int((nan_a != nan_b).sum())} different places"
        if a.size == 0:
            return "0"
        diff = np.abs(a.astype(np.float64) - b.astype(np.float64))[~nan_a]
        return f"{float(diff.max()) if diff.size else 0.0:.3e}"
    return "equal" if np.array_equal(a, b) else "differ"


def compare(first: dict, second: dict) -> tuple[bool, list[str]]:
    """Whether two flattened runs are bit-identical, and one report line per entry."""
    lines, same = [], True
    for key in sorted(set(first) | set(second)):
        if key not in first or key not in second:
            lines.append(f"{key}: only in {'first' if key in first else 'second'}")
            same = False
            continue
        a, b = first[key], second[key]
        identical = _identical(a, b)
        same &= identical
        status = "identical" if identical else "DIFFERENT"
        lines.append(f"{key}: {status}, max |diff| {_max_difference(a, b)}")
    return same, lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--save", type=Path, help="render the scenes and save them here")
    group.add_argument("--compare", nargs=2, type=Path, metavar=("A", "B"),
                       help="compare two saved runs")
    parser.add_argument("--cache-dir", type=Path, default=None,
                        help="cache folder (default: a new empty temporary folder)")
    args = parser.parse_args(argv)
    if args.compare:
        with np.load(args.compare[0]) as a, np.load(args.compare[1]) as b:
            same, lines = compare(dict(a), dict(b))
        print("\n".join(lines))
        print("bit-identical" if same else "NOT bit-identical")
        return 0 if same else 1
    with tempfile.TemporaryDirectory() as folder:
        os.environ["SKYTORCH_CACHE_DIR"] = str(args.cache_dir or folder)
        arrays, seconds = render_all()
    np.savez(args.save, **arrays)
    for name, value in seconds.items():
        print(f"{name}: {value:.2f} s")
    print(f"saved {len(arrays)} entries to {args.save}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
