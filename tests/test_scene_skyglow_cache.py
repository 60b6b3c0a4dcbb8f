"""The scene's skyglow disk cache never serves a corrupted or swapped file.

Issue 12 found 4 of 13 byte corruptions of the cached model served (zenith -699.5, 19.26,
18.23 mag arcsec^-2 instead of 17.93) and the bad file left for later runs. Every cache
file now carries its SHA-256 and the parameter hash (skytorch._cache): each corruption
below must be detected, the file rebuilt and the zenith brightness equal to a fresh
build's.
"""

from __future__ import annotations

import importlib
import shutil

import numpy as np
import pytest
import torch

import skytorch as st
from skytorch import _cache
from skytorch.scene.planner import FIDELITY
from skytorch.scene.resources import SceneResources
from skytorch.skyglow import SkyglowModel
from skytorch.skyglow.citymap import synthetic_city

# the module (``skytorch.scene.render`` is also the name of the render function)
render = importlib.import_module("skytorch.scene.render")

#: identical inputs give identical models: a rebuilt file must give the same zenith to
#: floating-point noise of the PCA (far below any photometric precision)
SAME_BRIGHTNESS_MAG = 1e-9


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """Return a private cache folder, an empty in-memory cache and a count of the builds."""
    monkeypatch.setenv("SKYTORCH_CACHE_DIR", str(tmp_path))
    # a coarser model than the "fast" preset: every corruption below costs a rebuild
    monkeypatch.setitem(FIDELITY["fast"], "skyglow", {
        "n_azimuth": 16, "n_elevation": 4, "n_distance": 8, "n_components": 3,
        "max_distance_m": 20_000.0})
    builds = []
    original = SkyglowModel.precompute.__func__

    def counting(cls, *args, **kwargs):
        builds.append(kwargs.get("n_components"))
        return original(cls, *args, **kwargs)

    monkeypatch.setattr(SkyglowModel, "precompute", classmethod(counting))
    return tmp_path, builds


def _scene(turbidity=2.0):
    city = synthetic_city(extent_m=20_000.0, cell_m=2_000.0, population=1e6)
    return st.Scene(time="2015-09-13T23:00", lat_deg=52.52, lon_deg=13.40, fidelity="fast",
                    view="directions", light_map=city, turbidity=turbidity,
                    directions={"altitude_deg": [90.0], "azimuth_deg": [0.0]})


def _zenith_mag(scene) -> float:
    """V surface brightness of the skyglow alone at the zenith [mag arcsec^-2].

    Through the cache (fresh resources hold no model in memory, so the disk file is read).
    """
    from skytorch.moon.sky import radiance_to_mag_arcsec2

    resources = SceneResources.for_scene(scene)
    wavelength = scene.wavelength_nm()
    radiance = render.skyglow_component(resources, scene.make_view(), None, wavelength,
                                        render.Knobs.of(scene))
    return float(radiance_to_mag_arcsec2(radiance.to(torch.float64), wavelength)[0])


def _paths(scene):
    return SceneResources.for_scene(scene).skyglow_cache_path(
        FIDELITY[scene.fidelity]["skyglow"])


def test_corrupted_bytes_are_detected_and_rebuilt(cache):
    folder, builds = cache
    scene = _scene()
    fresh = _zenith_mag(scene)
    path, key = _paths(scene)
    assert path.parent == folder and len(builds) == 1
    assert _cache.verify(path, key) is None
    assert _zenith_mag(scene) == fresh and len(builds) == 1  # a good file is served
    original = path.read_bytes()
    # the file signature, the netCDF-4/HDF5 superblock, data and metadata, the last byte;
    # positions relative to each file's own size (rebuilt files may differ in length)
    positions = [lambda n: 0, lambda n: 9, lambda n: n // 4, lambda n: n // 2,
                 lambda n: 3 * n // 4, lambda n: n - 1]
    for count, position in enumerate(positions, start=2):
        size = len(original)
        offset = position(size)
        data = bytearray(original)
        data[offset] ^= 0xFF
        path.write_bytes(bytes(data))
        brightness = _zenith_mag(scene)
        assert len(builds) == count, f"corruption at byte {offset} of {size} was served"
        assert abs(brightness - fresh) < SAME_BRIGHTNESS_MAG, offset
        assert _cache.verify(path, key) is None  # the bad file was replaced
        original = path.read_bytes()
    # a truncated file
    path.write_bytes(original[: len(original) // 2])
    assert abs(_zenith_mag(scene) - fresh) < SAME_BRIGHTNESS_MAG
    assert _cache.verify(path, key) is None
    assert len(builds) == len(positions) + 2
    # a missing record is not trusted either
    _cache.record_path(path).unlink()
    assert abs(_zenith_mag(scene) - fresh) < SAME_BRIGHTNESS_MAG
    assert len(builds) == len(positions) + 3


def test_a_file_of_another_key_is_refused(cache):
    folder, builds = cache
    clear, hazy = _scene(2.0), _scene(6.0)
    clear_mag, hazy_mag = _zenith_mag(clear), _zenith_mag(hazy)
    assert abs(clear_mag - hazy_mag) > 0.05  # the two models are told apart
    (clear_path, clear_key), (hazy_path, hazy_key) = _paths(clear), _paths(hazy)
    assert clear_path != hazy_path and len(builds) == 2
    # the hazy file in place of the clear one, with the clear record: checksum mismatch
    shutil.copyfile(hazy_path, clear_path)
    assert abs(_zenith_mag(clear) - clear_mag) < SAME_BRIGHTNESS_MAG
    assert len(builds) == 3
    # the hazy file and its record both copied over: the record names another file and
    # another parameter hash
    shutil.copyfile(hazy_path, clear_path)
    shutil.copyfile(_cache.record_path(hazy_path), _cache.record_path(clear_path))
    assert _cache.verify(clear_path, clear_key) is not None
    assert abs(_zenith_mag(clear) - clear_mag) < SAME_BRIGHTNESS_MAG
    assert len(builds) == 4
    assert _cache.verify(clear_path, clear_key) is None
    assert _cache.verify(hazy_path, hazy_key) is None
    assert np.isfinite(clear_mag) and np.isfinite(hazy_mag)


def test_an_elevated_observer_sees_the_skyglow_of_their_height(cache):
    """From 3 km the city's zenith glow is that of a model whose observer node is at 3 km.

    It was the ground's (every height gave 18.92 mag arcsec^-2 at the zenith, measured
    with the "fast" preset). The reference: SkyglowModel with observer nodes at 0 and
    3 km, read at its 3 km node; the glow from 3 km is fainter (less air above the
    observer scatters the city's light).
    """
    from skytorch.moon.sky import radiance_to_mag_arcsec2

    ground, high = _scene(), _scene().replace(elevation_m=3000.0)
    at_ground, at_height = _zenith_mag(ground), _zenith_mag(high)
    assert at_height > at_ground + 0.5
    resources = SceneResources.for_scene(high)
    settings = {**FIDELITY["fast"]["skyglow"], "n_observer_altitude": 2,
                "observer_altitude_range_m": (0.0, 3000.0)}
    model = SkyglowModel.precompute(resources.atmosphere, wavelength_nm=resources.wavelength_nm,
                                    progress=False, **settings)
    out = model.render(high.light_map, observer_altitude_m=3000.0, as_dataset=False)
    reference = radiance_to_mag_arcsec2(out["radiance"][-1:].mean(1).to(torch.float64),
                                        resources.wavelength_nm)
    assert abs(at_height - float(reference[0])) < 0.05
