"""The lunar-eclipse comparison experiment: each extinction ingredient darkens the umbra."""

import numpy as np
import pytest

from experiments.lunar_eclipse_comparison import ingredients


@pytest.mark.slow
def test_each_ingredient_darkens_mid_totality():
    # extinction and blocked rays only remove light: adding ozone, tropospheric and
    # stratospheric aerosol and then clouds can only make the eclipsed Moon fainter
    dataset, figure, _ = ingredients(quick=True)
    v = dataset.greatest_v_magnitude.values
    assert np.all(np.diff(v) > 0.0), v
    # ozone: vertical optical depth at 550 nm of 300 DU is 300 x 2.687e16 cm-2 x
    # 3.3e-21 cm2 (Chappuis band) = 0.027; a grazing ray crosses the layer on a path of
    # at least ~10 vertical columns on each side of the tangent point, so at least
    # ~0.5 in optical depth (~0.5 mag) and not the 4+ mag of 150 columns
    assert 0.3 < v[1] - v[0] < 4.0
