"""Batched atmospheres (turbidity x ozone grids) in the Earth's shadow and the light curve.

Reference: the same model evaluated member by member (a plain loop over unbatched
atmospheres); the batched path shares the ray geometry and must agree to rounding.
"""

import pytest
import torch

from skytorch.atmosphere import Atmosphere
from skytorch.constants import MAG, MEAN_EARTH_MOON_DISTANCE_M
from skytorch.eclipse.lunar import lunar_light_curve
from skytorch.eclipse.shadow import Shadow
from skytorch.eclipse.shadow_table import ShadowTable

RGB = torch.tensor([680.0, 550.0, 440.0], dtype=torch.float64)
TURBIDITY = torch.tensor([1.0, 3.0], dtype=torch.float64)
OZONE = torch.tensor([0.0, 300.0, 450.0], dtype=torch.float64)
#: batched and looped evaluations differ by rounding only
ROUNDING = 1e-10
#: light-curve agreement [mag]
CURVE_TOLERANCE = 1e-9 * MAG


def _grid_atmosphere():
    return Atmosphere.earth(turbidity=TURBIDITY[:, None], ozone_du=OZONE[None, :])


def _member(i, j):
    return Atmosphere.earth(turbidity=float(TURBIDITY[i]), ozone_du=float(OZONE[j]))


def test_batched_shadow_equals_loop():
    distance = torch.full((6,), MEAN_EARTH_MOON_DISTANCE_M, dtype=torch.float64)
    offset = torch.linspace(0.0, 8.0e6, 6, dtype=torch.float64)
    batched = Shadow.earth(_grid_atmosphere(), n_altitude=101).relative_illuminance(
        distance[:, None, None], offset[:, None, None], RGB)
    assert batched.shape == (6, 2, 3, 3)
    for i in range(2):
        for j in range(3):
            single = Shadow.earth(_member(i, j), n_altitude=101).relative_illuminance(
                distance, offset, RGB)
            torch.testing.assert_close(batched[:, i, j], single, rtol=ROUNDING, atol=0.0)
    # ozone darkens the umbra centre in the green (Chappuis band)
    assert bool((batched[0, :, 2, 1] < batched[0, :, 0, 1]).all())


def test_batched_shadow_broadcasts_like_torch():
    shadow = Shadow.earth(_grid_atmosphere(), n_altitude=101)
    distance = torch.tensor([[3.7e8], [4.0e8]], dtype=torch.float64)  # (2, 1) with B (2, 3)
    offset = torch.tensor([[1.0e6], [5.0e6]], dtype=torch.float64)
    paired = shadow.relative_illuminance(distance, offset, RGB)
    outer = shadow.relative_illuminance(distance[..., None], offset[..., None], RGB)
    assert paired.shape == (2, 3, 3) and outer.shape == (2, 2, 3, 3)
    # torch pairs point i with the members of turbidity row i
    torch.testing.assert_close(paired, torch.stack([outer[0, 0], outer[1, 1]]),
                               rtol=ROUNDING, atol=0.0)


def test_batched_table_lookup_and_dataset():
    shadow = Shadow.earth(_grid_atmosphere(), n_altitude=101)
    table = ShadowTable.compute(shadow, RGB, n_u=3, n_v=16, min_distance_m=3.6e8,
                                max_distance_m=4.1e8, progress=False)
    assert table.values.shape == (3, 16, 2, 3, 3)
    single = ShadowTable.compute(Shadow.earth(_member(1, 2), n_altitude=101), RGB, n_u=3,
                                 n_v=16, min_distance_m=3.6e8, max_distance_m=4.1e8,
                                 progress=False)
    distance = torch.tensor([3.8e8, 3.9e8], dtype=torch.float64)
    offset = torch.tensor([2.0e6, 6.0e6], dtype=torch.float64)
    torch.testing.assert_close(table.lookup(distance, offset)[:, 1, 2],
                               single.lookup(distance, offset), rtol=ROUNDING, atol=0.0)
    restored = ShadowTable.from_dataset(table.to_dataset())
    torch.testing.assert_close(restored.lookup(distance, offset), table.lookup(distance, offset))


def test_batched_light_curve_equals_loop():
    kwargs = {"n_times": 6, "table_n_v": 64}
    atmosphere = Atmosphere.earth(turbidity=TURBIDITY[:, None],
                                  ozone_du=OZONE[None, 1:2])
    curve = lunar_light_curve("2015-09-28", shadow=Shadow.earth(atmosphere, n_altitude=101),
                              **kwargs)
    assert curve["v_magnitude"].shape == (2, 1, 6)
    for i in range(2):
        single = lunar_light_curve("2015-09-28", shadow=Shadow.earth(_member(i, 1),
                                                                     n_altitude=101), **kwargs)
        torch.testing.assert_close(curve["v_magnitude"][i, 0], single["v_magnitude"],
                                   rtol=0.0, atol=CURVE_TOLERANCE)
    # more aerosol, darker totality
    assert float(curve["greatest_v_magnitude"][1, 0]) > float(curve["greatest_v_magnitude"][0, 0])


def test_limb_view_rejects_batched_atmosphere():
    with pytest.raises(ValueError, match="unbatched"):
        Shadow.earth(_grid_atmosphere(), n_altitude=101).limb_view(3.8e8, 0.0, RGB)


def test_batched_atmosphere_that_bends_differently_raises():
    """Members with different refractivity (surface pressure) need one Shadow each.

    The members of a turbidity x ozone grid bend alike up to the batched trace's rounding
    (1 ulp, which differs between CPUs' vector lanes: compared with a tolerance); a
    pressure change of 11 % is far outside it.
    """
    atm = Atmosphere.earth(surface_pressure_pa=torch.tensor([101325.0, 90000.0],
                                                            dtype=torch.float64))
    with pytest.raises(ValueError, match="bend light differently"):
        Shadow.earth(atm, n_altitude=101).relative_illuminance(
            torch.tensor(MEAN_EARTH_MOON_DISTANCE_M, dtype=torch.float64),
            torch.tensor(1.0e6, dtype=torch.float64), RGB)
