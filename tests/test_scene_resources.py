"""A scene's resources are explicit state: renders depend on the scene and the spec only.

* five small scenes (day, twilight, moonlit night, lunar eclipse, city) rendered with a
  fresh :class:`SceneResources` each and with one object reused for all of them in
  another order are bit-identical (no hidden state carried from one render to the next);
* threads rendering a time series with one shared object give the renders of one thread;
* resources of another spec are refused; copies of a scene share its resources only when
  their spec is the same;
* no module-level caches are left in ``skytorch/scene`` (read from the source);
* a Scene checks its atmosphere with Atmosphere.earth's own rules and refuses a tensor of
  more than one element for every one-number parameter, naming it.
"""

from __future__ import annotations

import ast
import pickle
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
import torch

import skytorch as st
from skytorch.atmosphere import Atmosphere
from skytorch.scene.presets import FIDELITY
from skytorch.scene.resources import SceneResources, SceneSpec
from skytorch.skyglow.citymap import synthetic_city

SCENE_DIR = Path(__file__).resolve().parents[1] / "skytorch" / "scene"

BERLIN = {"lat_deg": 52.52, "lon_deg": 13.40, "elevation_m": 34.0}
#: the scenes (all of one spec: turbidity 2, ozone 300 DU, RGB)
SCENES = {
    "day": {"time": "2015-06-21T12:00", "lat_deg": 48.85, "lon_deg": 2.35, "size": 12},
    "twilight": {"time": "2015-06-21T20:50", "lat_deg": 48.85, "lon_deg": 2.35,
                 "view": "panorama", "size": 6},
    "moonlit": {"time": "2015-08-29T23:00", **BERLIN, "size": 12, "star_limit_mag": 3.0},
    "eclipse": {"time": "2015-09-28T02:47", **BERLIN, "size": 12, "star_limit_mag": 3.0},
    "city": {"time": "2015-09-13T23:00", **BERLIN, "size": 8, "star_limit_mag": 2.0,
             "city": True},
}
#: the effects each scene must exercise (so that the comparison covers them)
EXPECTED = {"day": {"sky", "sun"}, "twilight": {"sky"}, "moonlit": {"moon"},
            "eclipse": {"moon", "eclipse", "stars"}, "city": {"skyglow", "stars"}}


@pytest.fixture(autouse=True)
def _small_private_cache(tmp_path, monkeypatch):
    """Return an empty cache folder, and a skyglow model coarser than the "fast" preset."""
    monkeypatch.setenv("SKYTORCH_CACHE_DIR", str(tmp_path))
    monkeypatch.setitem(FIDELITY["fast"], "skyglow", {
        "n_azimuth": 16, "n_elevation": 4, "n_distance": 8, "n_components": 3,
        "max_distance_m": 20_000.0})


def _scene(name: str, **changes) -> st.Scene:
    options = {"fidelity": "fast", **SCENES[name], **changes}
    if options.pop("city", False):
        options["light_map"] = synthetic_city(extent_m=20_000.0, cell_m=2_000.0,
                                              population=1e6, centre_xy=(8_000.0, -9_000.0))
    return st.Scene(**options)


def _arrays(dataset) -> dict[str, np.ndarray]:
    out = {f"var/{k}": np.asarray(v.values) for k, v in dataset.data_vars.items()}
    out.update({f"coord/{k}": np.asarray(v.values) for k, v in dataset.coords.items()})
    out.update({f"attr/{k}": np.asarray(repr(v)) for k, v in dataset.attrs.items()
                if k not in ("history", "parameters") and "seconds_" not in k})
    return out


def _assert_identical(first: dict, second: dict, label: str) -> None:
    assert first.keys() == second.keys(), label
    for key in first:
        a, b = first[key], second[key]
        assert a.dtype == b.dtype and a.shape == b.shape, (label, key)
        assert a.tobytes() == b.tobytes(), (label, key)  # bits, NaN patterns included


def test_fresh_and_reused_resources_render_bit_identical():
    # the skyglow model read from the disk cache differs in the last bits from the one
    # built in memory (netCDF round trip): both passes below read it from disk
    city = _scene("city")
    city.render(resources=SceneResources.for_scene(city))
    fresh = {}
    for name in SCENES:
        scene = _scene(name)
        ds = scene.render(resources=SceneResources.for_scene(scene))
        assert EXPECTED[name] <= set(ds.attrs["effects_computed"].split(",")), name
        fresh[name] = _arrays(ds)
    shared = SceneResources.for_scene(_scene("day"))
    for name in ("city", "eclipse", "day", "moonlit", "twilight"):
        _assert_identical(fresh[name], _arrays(_scene(name).render(resources=shared)), name)
    assert {"atmosphere", "shadow"} <= set(shared.built())
    assert ("catalogue", 2.0) in shared.built() and ("catalogue", 3.0) in shared.built()


def test_threads_sharing_resources_render_as_one_thread():
    base = _scene("eclipse", size=8, outputs=("spectral",))
    times = [f"2015-09-28T0{h}:47" for h in range(1, 5)]
    alone = [_arrays(base.replace(time=t).render(resources=SceneResources.for_scene(base)))
             for t in times]
    shared = SceneResources.for_scene(base)
    with ThreadPoolExecutor(max_workers=4) as pool:
        together = list(pool.map(lambda t: _arrays(base.replace(time=t).render(
            resources=shared)), times))
    for time, a, b in zip(times, alone, together, strict=True):
        _assert_identical(a, b, time)
    # each table was built once (a second build would replace the first object)
    assert len(shared.built()) == len(set(shared.built()))


def test_resources_of_another_spec_are_refused():
    scene = _scene("day")
    with pytest.raises(ValueError, match="turbidity 3.0"):
        scene.replace(turbidity=3.0).render(resources=scene.resources())
    with pytest.raises(ValueError, match="wavelengths"):
        scene.replace(wavelengths="bands15").plan(resources=scene.resources())
    with pytest.raises(TypeError, match="resources"):
        scene.render(resources={"atmosphere": None})


def test_copies_share_resources_only_with_the_same_spec():
    scene = _scene("day")
    resources = scene.resources()
    assert scene.replace(time="2015-06-21T13:00").resources() is resources
    assert scene.replace(size=16, fidelity="default").resources() is resources
    other = scene.replace(ozone_du=250.0)
    assert other.resources() is not resources
    assert other.resources().spec == SceneSpec(2.0, 250.0, resources.spec.wavelengths)
    assert other.atmosphere() is not scene.atmosphere()
    # two scenes built apart share nothing
    assert _scene("day").atmosphere() is not scene.atmosphere()


def test_a_time_series_reuses_the_tables():
    scene = _scene("day")
    resources = scene.resources()
    scene.render()
    atmosphere, built = resources.atmosphere, resources.built()
    scene.replace(time="2015-06-21T12:01").render()
    assert resources.atmosphere is atmosphere
    assert resources.built() == built  # the same tables served, none rebuilt


def test_pickled_resources_keep_the_spec_and_rebuild():
    scene = _scene("day")
    scene.atmosphere()
    copy = pickle.loads(pickle.dumps(scene))
    assert copy == scene and copy.resources().spec == scene.resources().spec
    assert copy.resources().built() == ()


def test_spec_is_checked():
    with pytest.raises(TypeError, match="turbidity"):
        SceneSpec("2", 300.0, (550.0,))
    with pytest.raises(TypeError, match="wavelengths"):
        SceneSpec(2.0, 300.0, ())
    with pytest.raises(TypeError, match="spec"):
        SceneResources({"turbidity": 2.0})


def _module_level_caches(path: Path) -> list[str]:
    """Cache decorators and module-level names that look like caches in a module."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for decorator in node.decorator_list:
                target = decorator.func if isinstance(decorator, ast.Call) else decorator
                name = getattr(target, "attr", getattr(target, "id", ""))
                if name in ("lru_cache", "cache", "cached_property"):
                    found.append(f"{path.name}:{node.lineno} @{name} {node.name}")
    for node in tree.body:
        targets = node.targets if isinstance(node, ast.Assign) else (
            [node.target] if isinstance(node, ast.AnnAssign) else [])
        for target in targets:
            name = getattr(target, "id", "")
            if "cache" in name.lower() or name.endswith("_models"):
                found.append(f"{path.name}:{node.lineno} {name}")
    return found


def test_no_module_level_caches_in_the_scene_package():
    found = [hit for path in sorted(SCENE_DIR.glob("*.py")) for hit in _module_level_caches(path)]
    assert not found, "module-level caches in skytorch/scene:\n" + "\n".join(found)


def test_the_cache_finder_finds_caches(tmp_path):
    path = tmp_path / "m.py"
    path.write_text("from functools import lru_cache\n_cache = {}\n"
                    "@lru_cache(maxsize=2)\ndef f(x):\n    return x\n")
    assert len(_module_level_caches(path)) == 2


@pytest.mark.parametrize("parameters", [{"turbidity": 0.5}, {"turbidity": 65.0},
                                        {"ozone_du": -1.0}])
def test_the_atmosphere_is_checked_as_atmosphere_earth_checks_it(parameters):
    with pytest.raises(ValueError) as theirs:
        Atmosphere.earth(**parameters)
    with pytest.raises(ValueError) as ours:
        st.Scene(size=8, **parameters)
    assert str(ours.value) == str(theirs.value)


ONE_NUMBER = {"turbidity": (2.0, 3.0), "ozone_du": (300.0, 250.0), "tolerance": (0.01, 0.1),
              "star_limit_mag": (6.5, 4.0), "natural_mag_arcsec2": (22.0, 21.0),
              "airglow_fraction": (0.6, 0.5), "airglow_height_m": (90_000.0, 95_000.0)}


@pytest.mark.parametrize("name", sorted(ONE_NUMBER))
def test_a_tensor_of_several_values_is_refused_naming_the_parameter(name):
    st.Scene(size=8, **{name: torch.tensor(ONE_NUMBER[name][:1])})  # one element: accepted
    with pytest.raises(ValueError, match=rf"^{name} must be one number per scene; got shape "
                                         r"\(2,\)"):
        st.Scene(size=8, **{name: torch.tensor(ONE_NUMBER[name])})


@pytest.mark.parametrize("name", ["lat_deg", "lon_deg", "elevation_m"])
def test_observer_coordinates_batch_over_observers_only(name):
    values = {"lat_deg": [52.0, 40.0], "lon_deg": [13.0, -3.0], "elevation_m": [0.0, 600.0]}
    scene = st.Scene(size=8, **{name: torch.tensor(values[name])})
    assert scene.n_observers == 2  # a sequence gives observers (dimension "observer")
    with pytest.raises(ValueError, match=name):
        st.Scene(size=8, **{name: torch.tensor([values[name]] * 2)})


def test_camera_and_size_refuse_several_values():
    with pytest.raises(ValueError, match="camera fov_deg must be one number"):
        st.Scene(size=8, view="camera", camera={"fov_deg": torch.tensor([1.0, 2.0]),
                                                "target": "moon"})
    with pytest.raises((TypeError, ValueError), match="size"):
        st.Scene(size=torch.tensor([8, 9]))
