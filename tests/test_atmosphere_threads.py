"""One batched Atmosphere shared by a thread pool gives the serial results (shape and value).

Before the constituents interface, a module-level mode flag set while single scattering
ran made 2,269 of 3,000 concurrent ``optical_depth`` calls return the wrong shape.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import pytest
import torch

from skytorch.atmosphere import Atmosphere

WAVELENGTH = torch.tensor([450.0, 550.0, 700.0], dtype=torch.float64)


def _tasks():
    """Return calls of mixed geometry shapes and kinds.

    Shapes: scalars, vectors, grids broadcasting with the parameters' batch shape (2, 2); kinds:
    straight optical depth, sky radiance.
    """
    zenith = torch.linspace(0.1, 1.5, 5, dtype=torch.float64)
    return [
        ("optical_depth", (WAVELENGTH, 0.3), {}),
        ("optical_depth", (WAVELENGTH, zenith[:2]), {}),
        ("optical_depth", (WAVELENGTH, zenith[:, None, None], torch.tensor([0.0, 1500.0],
                                                                          dtype=torch.float64)), {}),
        ("optical_depth", (WAVELENGTH[:1], zenith[:3, None, None]), {"per_species": True}),
        ("optical_depth", (WAVELENGTH, torch.tensor(1.7, dtype=torch.float64), 2000.0), {}),
        ("sky_radiance", (WAVELENGTH, zenith[:2], 0.0, 0.4, 1.0), {"n_samples": 8, "scattering_orders": 1}),
        ("sky_radiance", (WAVELENGTH[1:], torch.tensor(0.2, dtype=torch.float64), 0.5, 1.2,
                          0.0), {"n_samples": 8, "scattering_orders": 1}),
        ("sky_radiance", (WAVELENGTH, zenith[:3, None, None], zenith[None, :2, None], 0.3,
                          0.0), {"n_samples": 6, "scattering_orders": 1}),
    ]


def _run(atmosphere, task):
    name, args, options = task
    return getattr(atmosphere, name)(*args, **options)


def _same(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return a.shape == b.shape and bool(torch.equal(a, b))


@pytest.mark.slow  # 3000 calls of ~5-15 ms each (Python-bound: the threads share the GIL)
def test_shared_batched_atmosphere_is_thread_safe():
    atmosphere = Atmosphere.earth(
        turbidity=torch.tensor([[2.0], [4.0]], dtype=torch.float64),
        ozone_du=torch.tensor([250.0, 350.0], dtype=torch.float64),
        aerosol_scale_height_m=torch.tensor([[1000.0], [1500.0]], dtype=torch.float64),
        stratospheric_aerosol_optical_depth=0.05)
    tasks = _tasks()
    serial = [_run(atmosphere, task) for task in tasks]
    n_calls = 3000
    order = [i % len(tasks) for i in range(n_calls)]
    with ThreadPoolExecutor(max_workers=8) as pool:
        results = list(pool.map(lambda i: _run(atmosphere, tasks[i]), order))
    wrong = sum(not _same(result, serial[i]) for result, i in zip(results, order, strict=True))
    assert wrong == 0, f"{wrong} of {n_calls} concurrent calls differ from the serial result"
    # the shapes themselves are those of the broadcast rules (not merely self-consistent)
    assert serial[1].shape == (2, 2, 3)
    assert serial[2].shape == (5, 2, 2, 3)
    assert serial[3]["ozone"].shape == (3, 2, 2, 1)  # each species at the full shape
    assert serial[7].shape == (3, 2, 2, 3)
