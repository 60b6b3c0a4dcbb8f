"""The star tables' in-memory caches: keyed by the atmosphere's values, bounded, thread-safe.

refraction_table, extinction_table and apparent_color_table keep recent tables in a
skytorch._cache.MemoryCache keyed by the atmosphere's parameters_dict() values (not by the
object's id, which Python reuses once an object is freed). Each test starts from empty
caches; the references are tables computed with the cache bypassed.
"""

from __future__ import annotations

import gc
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import torch

from skytorch._cache import MemoryCache, atmosphere_key
from skytorch.atmosphere import Atmosphere
from skytorch.stars import bright_stars, observe
from skytorch.stars import observation as observation_module
from skytorch.stars import photometry as photometry_module
from skytorch.stars.observation import _trace_refraction_table, refraction_table
from skytorch.stars.photometry import apparent_color_table, extinction_table


@pytest.fixture(autouse=True)
def empty_caches():
    observation_module._REFRACTION_TABLES.clear()
    photometry_module._TABLES.clear()
    yield
    observation_module._REFRACTION_TABLES.clear()
    photometry_module._TABLES.clear()


def _equal(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def test_equal_atmospheres_share_a_refraction_table():
    cache = observation_module._REFRACTION_TABLES
    first = refraction_table(Atmosphere.earth(), 0.0, 64)
    second = refraction_table(Atmosphere.earth(), 0.0, 64)  # another object, same values
    assert cache.cache_info()["misses"] == 1 and cache.cache_info()["hits"] == 1
    assert _equal(first, second)
    assert atmosphere_key(Atmosphere.earth()) == atmosphere_key(Atmosphere.earth())


def test_different_atmospheres_do_not_collide():
    cache = observation_module._REFRACTION_TABLES
    low = Atmosphere.earth(surface_pressure_pa=70_000.0)
    tables = {}
    for pressure in (101_325.0, 70_000.0):
        atmosphere = Atmosphere.earth(surface_pressure_pa=pressure)
        tables[pressure] = refraction_table(atmosphere, 0.0, 64)
        del atmosphere
        gc.collect()  # the next atmosphere may take the freed object's id
    assert cache.cache_info()["misses"] == 2 and cache.cache_info()["hits"] == 0
    assert atmosphere_key(low) != atmosphere_key(Atmosphere.earth())
    # lower pressure, less refraction: about 70/101 of the sea-level table at the zenith side
    assert float(tables[70_000.0]["refraction_rad"][-2]) < float(
        tables[101_325.0]["refraction_rad"][-2])
    assert _equal(tables[70_000.0], _trace_refraction_table(low, 0.0, 64))
    other_altitude = refraction_table(low, 1000.0, 64)
    assert not torch.equal(other_altitude["refraction_rad"], tables[70_000.0]["refraction_rad"])


def test_turbidity_changes_the_extinction_key():
    clear = extinction_table(Atmosphere.earth(turbidity=2.0), n_nodes=16)
    hazy = extinction_table(Atmosphere.earth(turbidity=4.0), n_nodes=16)
    assert photometry_module._TABLES.cache_info()["misses"] == 2
    # zenith extinction grows with the aerosol optical depth
    assert float(hazy["offset"][-1]) > float(clear["offset"][-1]) + 0.05
    again = extinction_table(Atmosphere.earth(turbidity=2.0), n_nodes=16)
    assert photometry_module._TABLES.cache_info()["hits"] == 1
    assert _equal(again, clear)
    assert _equal(clear, extinction_table(Atmosphere.earth(turbidity=2.0), n_nodes=16,
                                          cache=False))


def test_a_caller_modifying_its_table_does_not_change_the_cache():
    table = apparent_color_table(Atmosphere.earth(), n_nodes=8)
    reference = {k: v.clone() for k, v in table.items()}
    table["linear_srgb"].zero_()
    assert _equal(apparent_color_table(Atmosphere.earth(), n_nodes=8), reference)


def test_an_atmosphere_without_parameters_is_not_cached():
    class Plain:  # a duck-typed model: refraction only, no parameters_dict
        def __init__(self, scale):
            self.scale = scale

        def refraction(self, apparent_altitude_rad, altitude_m):
            return self.scale * 1e-4 / torch.tan(apparent_altitude_rad + 0.05)

    small = refraction_table(Plain(1.0), 0.0, 16)
    large = refraction_table(Plain(2.0), 0.0, 16)
    info = observation_module._REFRACTION_TABLES.cache_info()
    assert info["uncached"] == 2 and info["size"] == 0
    np.testing.assert_allclose(large["refraction_rad"][-1], 2 * small["refraction_rad"][-1],
                               rtol=1e-3)


def test_memory_cache_is_bounded_and_least_recently_used():
    cache = MemoryCache(2)
    for key in ("a", "b", "a", "c"):  # "b" is the least recently used when "c" arrives
        cache.get(key, lambda key=key: key.upper())
    assert cache.cache_info()["size"] == 2
    assert cache.get("b", lambda: "recomputed") == "recomputed"
    with pytest.raises(ValueError, match="maxsize"):
        MemoryCache(0)


def test_tables_from_a_thread_pool_match_uncached_ones():
    # eight threads, four different atmospheres twice each, from cold caches
    pressures = (101_325.0, 90_000.0, 80_000.0, 70_000.0)
    turbidities = (2.0, 2.5, 3.0, 4.0)

    def tables(k):
        atmosphere = Atmosphere.earth(turbidity=turbidities[k % 4],
                                      surface_pressure_pa=pressures[k % 4])
        return (refraction_table(atmosphere, 0.0, 16),
                extinction_table(atmosphere, n_nodes=16, refraction=False))

    with ThreadPoolExecutor(max_workers=8) as pool:
        pooled = list(pool.map(tables, range(8)))
    # Concurrent LAPACK calls (the least-squares colour fit) differ from serial ones at the
    # rounding level, ~1e-14 mag; a table of another atmosphere would differ by > 0.01 mag
    # (checked below), so 1e-12 separates a collision from rounding by ten decades.
    references = []
    for k, (refraction, extinction) in enumerate(pooled):
        atmosphere = Atmosphere.earth(turbidity=turbidities[k % 4],
                                      surface_pressure_pa=pressures[k % 4])
        expected = (_trace_refraction_table(atmosphere, 0.0, 16),
                    extinction_table(atmosphere, n_nodes=16, refraction=False, cache=False))
        references.append(expected)
        for got, want in zip((refraction, extinction), expected, strict=True):
            assert got.keys() == want.keys()
            for name in want:  # [rad] or [mag], [mag/mag], [1]
                torch.testing.assert_close(got[name], want[name], rtol=0, atol=1e-12)
    for k in range(1, 4):  # the four atmospheres are far apart on this scale
        assert float((references[k][1]["offset"] - references[0][1]["offset"]).abs().max()) > 0.01
        assert float((references[k][0]["refraction_rad"]
                      - references[0][0]["refraction_rad"]).abs().max()) > 1e-5
    assert observation_module._REFRACTION_TABLES.cache_info()["size"] == 4
    assert photometry_module._TABLES.cache_info()["size"] == 4


def test_observe_from_a_thread_pool_matches_serial():
    catalog = bright_stars(1.5)

    def run(atmosphere):
        ds = observe(catalog, ["2025-09-07T20:00", "2025-09-08T02:00"], 52.5, 13.4,
                     atmosphere=atmosphere, reddening=False)
        return ds.magnitude.values, ds.altitude.values, ds.airmass.values

    serial = run(Atmosphere.earth())
    observation_module._REFRACTION_TABLES.clear()
    photometry_module._TABLES.clear()
    # two threads with equal atmospheres (distinct objects) miss the cold caches together
    with ThreadPoolExecutor(max_workers=2) as pool:
        pooled = list(pool.map(run, [Atmosphere.earth() for _ in range(2)]))
    for result in pooled:
        np.testing.assert_allclose(result[0], serial[0], rtol=0, atol=1e-9)  # [mag]
        np.testing.assert_allclose(result[1], serial[1], rtol=0, atol=1e-9)  # [degree]
        np.testing.assert_allclose(result[2], serial[2], rtol=1e-12)
    assert observation_module._REFRACTION_TABLES.cache_info()["size"] == 1
    assert photometry_module._TABLES.cache_info()["size"] == 1
