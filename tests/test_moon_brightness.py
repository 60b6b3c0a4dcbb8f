"""Disc-integrated lunar brightness against Krisciunas & Schaefer (1991) and closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from skytorch.constants import DEGREE, MAG, MEAN_EARTH_MOON_DISTANCE_M
from skytorch.moon import brightness as br
from skytorch.moon import earthshine as es

#: K&S 1991 eq. 9 tolerance of the physical (not fitted) model, issue requirement
KS_TOLERANCE = 0.15 * MAG


def test_magnitude_against_ks1991():
    """|m − m_KS| ≤ 0.15 mag for 3° ≤ α ≤ 100° (no fitting: solar spectrum, R, d, V zero point).

    Measured differences (docs/moon.md): +0.15 mag at 20°, +0.12 at 60°–90°; outside this
    range +0.16 at 110°, +0.22 at 120° (model fainter) and −0.19 at 0° (opposition surge,
    absent from the linear K&S law). The issue asks for 0.15 mag up to 120°; that is not
    met. The roughness term and the disc integration reproduce Hapke's K(g, θ̄) table
    (test_moon_reflectance.py) and the model follows ROLO's phase curve to ≤ 0.02 mag in
    shape up to its 97° limit (test_disc_reflectance_against_rolo), so the 110°–120°
    excess is left as measured rather than tuned away.
    """
    alpha = torch.arange(3.0, 101.0, 2.0, dtype=torch.float64) * DEGREE
    difference = br.magnitude(alpha) - br.magnitude_ks1991(alpha)
    assert float(difference.abs().max()) <= KS_TOLERANCE


def test_full_moon_opposition_surge():
    """Full Moon: near −12.7; the shadow-hiding surge makes it brighter than the K&S law.

    Lommel–Seeliger without a surge is ~1 mag too faint at α = 0.
    """
    zero = torch.tensor(0.0, dtype=torch.float64)
    m_hapke = float(br.magnitude(zero))
    m_ls = float(br.magnitude(zero, model="lommel_seeliger"))
    assert -13.0 < m_hapke < -12.7
    assert m_hapke < float(br.magnitude_ks1991(zero))
    assert m_ls - float(br.magnitude_ks1991(zero)) > 0.5 * MAG


def test_quadrature_converged():
    alpha = torch.tensor([0.0, 30.0, 90.0, 150.0], dtype=torch.float64) * DEGREE
    coarse = br.magnitude(alpha, n_quadrature=48)
    fine = br.magnitude(alpha, n_quadrature=96)
    assert float((coarse - fine).abs().max()) < 1e-5 * MAG


def test_inverse_square_distance():
    alpha = torch.tensor(40.0 * DEGREE, dtype=torch.float64)
    d0 = MEAN_EARTH_MOON_DISTANCE_M
    m0 = br.magnitude(alpha, distance_m=d0, earthshine=False)
    m1 = br.magnitude(alpha, distance_m=1.1 * d0, earthshine=False)
    assert abs(float(m1 - m0) - 5 * math.log10(1.1)) < 1e-9


@pytest.mark.parametrize("phase_deg", [0.0, 180.0])
def test_magnitude_hard_cases(dtype, phase_deg):
    alpha = torch.tensor(phase_deg * DEGREE, dtype=dtype, requires_grad=True)
    m = br.magnitude(alpha)
    assert m.dtype == dtype and torch.isfinite(m)
    m.backward()
    assert torch.isfinite(alpha.grad)
    if phase_deg == 180.0:
        # new Moon: earthshine only, (2A/3)(R_E/d)^2 times the full-disc reflectance
        q_earth = br.disc_integrated_reflectance(torch.tensor(math.pi), earthshine=True)
        ratio = es.earthshine_irradiance_ratio(torch.tensor(math.pi))
        q_full = br.disc_integrated_reflectance(torch.tensor(0.0))
        expected = float(br.magnitude(torch.tensor(0.0), earthshine=False)
                         - 2.5 * torch.log10(ratio * q_earth / q_full))
        assert abs(float(m.detach()) - expected) < 0.01 * MAG
        assert float(br.magnitude(torch.tensor(math.pi), earthshine=False)) == math.inf


def test_float32_vs_float64():
    alpha = torch.linspace(0.0, math.pi, 13, dtype=torch.float64)
    m64 = br.magnitude(alpha)
    m32 = br.magnitude(alpha.float())
    assert m32.dtype == torch.float32
    assert float((m32.double() - m64).abs().max()) < 1e-3 * MAG


def test_geometric_albedo_and_lunar_irradiance_consistent():
    """The flux of the full disc is p (R/d)² times the solar irradiance (definition of p)."""
    from skytorch.spectrum import solar_irradiance

    p = br.geometric_albedo()
    assert 0.10 < float(p) < 0.16  # the Moon's V geometric albedo is about 0.12 (Allen 2000)
    wl = torch.tensor([550.0], dtype=torch.float64)
    e = br.lunar_irradiance(torch.tensor(0.0, dtype=torch.float64), wl, earthshine=False)
    expected = solar_irradiance(wl) * p * (1737400.0 / MEAN_EARTH_MOON_DISTANCE_M) ** 2
    assert torch.allclose(e, expected, rtol=1e-12)


def test_module_matches_function(dtype):
    from skytorch.moon import MoonPhotometry

    moon = MoonPhotometry()
    alpha = torch.tensor([0.0, 0.7, 2.0, math.pi], dtype=dtype)
    d = torch.tensor(4.0e8, dtype=dtype)
    tolerance = 1e-9 if dtype == torch.float64 else 1e-4
    assert torch.allclose(moon(alpha, d), br.magnitude(alpha, distance_m=d), atol=tolerance)
    assert moon(alpha).dtype == dtype
    assert "hapke2012" in repr(moon)


#: ROLO's phase-angle range (Kieffer & Stone 2005: 1.55°–97°)
ROLO_PHASES_DEG = (2.0, 5.0, 10.0, 20.0, 30.0, 45.0, 60.0, 75.0, 90.0, 97.0)
#: absolute scale: ROLO's stated absolute uncertainty is 5–10 %
ROLO_ABSOLUTE_TOLERANCE = 0.10 * MAG
#: phase-curve shape (relative to 30°): ROLO's relative precision is ~1 %
ROLO_SHAPE_TOLERANCE = 0.03 * MAG
#: ROLO A(g) at 553.8 nm at 30° and 90°, eq. 10 evaluated by hand from the Table 4 row
ROLO_A_30_90 = (0.05331, 0.01023)


def test_disc_reflectance_against_rolo():
    """The Hapke disc integral against the ROLO lunar irradiance model, 2°–97°.

    An independent, modern disc-integrated phase curve (ROLO, 1.55°–97°): measured
    difference 0.04–0.07 mag in level and ≤ 0.02 mag in shape (docs/moon.md); K&S eq. 9
    differs from ROLO by 0.23 mag in shape at 2° (no opposition surge in the linear law).
    """
    alpha_deg = torch.tensor(ROLO_PHASES_DEG, dtype=torch.float64)
    q = br.disc_integrated_reflectance(alpha_deg * DEGREE)
    rolo = br.disc_reflectance_rolo2005(alpha_deg * DEGREE)
    by_hand = br.disc_reflectance_rolo2005(torch.tensor([30.0, 90.0]) * DEGREE)
    assert torch.allclose(by_hand, torch.tensor(ROLO_A_30_90, dtype=by_hand.dtype), rtol=1e-3)
    difference = -2.5 * torch.log10(q / rolo)
    assert float(difference.abs().max()) <= ROLO_ABSOLUTE_TOLERANCE
    reference = ROLO_PHASES_DEG.index(30.0)
    shape = difference - difference[reference]
    assert float(shape.abs().max()) <= ROLO_SHAPE_TOLERANCE


def test_phase_curve_experiment_quick(tmp_path, capsys):
    import importlib
    import sys
    from pathlib import Path

    from skytorch.dataset import open_dataset

    root = Path(__file__).resolve().parents[1]
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    experiment = importlib.import_module("experiments.moon_phase_curve")
    assert experiment.main(["--quick", "--output-dir", str(tmp_path)]) == 0
    assert "model − K&S" in capsys.readouterr().out
    ds = open_dataset(tmp_path / "moon_phase_curve.nc")
    assert (tmp_path / "moon_phase_curve.png").is_file()
    # ROLO is defined only inside 1.55°–97°; the default model stays within 0.1 mag of it
    rolo = ds.magnitude_rolo2005.values
    inside = np.isfinite(rolo)
    assert inside.any() and not inside[ds.phase_angle.values > 97.0].any()
    default = ds.magnitude.sel(variant="default").values
    assert np.abs(default[inside] - rolo[inside]).max() < ROLO_ABSOLUTE_TOLERANCE
