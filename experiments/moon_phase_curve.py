"""The lunar phase curve: Hapke model against Krisciunas & Schaefer (1991) and ROLO.

V magnitude at mean distance from :func:`skytorch.moon.magnitude` (Hapke law, Helfenstein
& Veverka 1987 parameters, nothing fitted) and for single-parameter variants within the
published ranges (roughness θ̄, asymmetry ξ, opposition width h_S, albedo w), against the
K&S eq. 9 curve and the ROLO disc reflectance of Kieffer & Stone (2005, 553.8 nm),
converted to V by the model's own colour (m_ROLO = m_model − 2.5 log10(A_ROLO / Q_model)).

Usage: ``python experiments/moon_phase_curve.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402
from skytorch.constants import DEGREE  # noqa: E402
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable  # noqa: E402
from skytorch.moon.brightness import (  # noqa: E402
    ROLO2005_553NM,
    disc_integrated_reflectance,
    disc_reflectance_rolo2005,
    magnitude,
    magnitude_ks1991,
)

#: single-parameter variants of the default "helfenstein1987" set
VARIANTS = {
    "default": {},
    "roughness 15 deg": {"roughness_rad": 15.0 * DEGREE},
    "roughness 25 deg": {"roughness_rad": 25.0 * DEGREE},
    "asymmetry -0.15": {"asymmetry": -0.15},
    "asymmetry -0.21": {"asymmetry": -0.21},
    "shoe width 0.10": {"shoe_width": 0.10},
    "albedo w 0.23": {"single_scattering_albedo": 0.23},
}
#: the issue's tolerance against K&S [mag]
KS_TOLERANCE_MAG = 0.15


def run(quick: bool = False):
    step = 15.0 if quick else 1.0
    n_quadrature = 8 if quick else 48
    alpha_deg = np.arange(2.0, 150.0 + step / 2, step)
    alpha = torch.tensor(alpha_deg * DEGREE, dtype=torch.float64)
    model = torch.stack([magnitude(alpha, parameters=p, n_quadrature=n_quadrature)
                         for p in VARIANTS.values()])
    ks = magnitude_ks1991(alpha)
    low, high = ROLO2005_553NM["phase_range_deg"]
    in_range = torch.as_tensor((alpha_deg >= low) & (alpha_deg <= high))
    q = disc_integrated_reflectance(alpha, n_quadrature=n_quadrature)
    rolo = model[0] - 2.5 * torch.log10(disc_reflectance_rolo2005(alpha) / q)
    rolo = torch.where(in_range, rolo, torch.full_like(rolo, float("nan")))
    mag = VariableSpec("mag", "V magnitude of the Moon at mean distance",
                       "Disc-integrated V magnitude above the atmosphere, 384 400 km, 1 au.")
    return build_dataset(
        {"magnitude": variable(("variant", "phase_angle"), model, mag),
         "magnitude_ks1991": variable("phase_angle", ks, VariableSpec(
             "mag", "V magnitude, Krisciunas & Schaefer 1991 eq. 9",
             "-12.73 + 0.026 |a| + 4e-9 a^4 (a in degrees), after Allen 1976.")),
         "magnitude_rolo2005": variable("phase_angle", rolo, VariableSpec(
             "mag", "V magnitude from the ROLO disc reflectance",
             "Kieffer & Stone 2005 eq. 10 at 553.8 nm (zero libration) converted to V with "
             "the default model's colour; NaN outside ROLO's 1.55-97 degree range."))},
        {"variant": coordinate("variant", np.array(list(VARIANTS)), VariableSpec(
            "1", "Hapke parameter variant", "Default set or one parameter changed.")),
         "phase_angle": coordinate("phase_angle", alpha_deg, VariableSpec(
             "degree", "lunar phase angle", "Sun-Moon-observer angle."))},
        title="Lunar phase curve: Hapke model, Krisciunas & Schaefer 1991 and ROLO",
        references=["Krisciunas, K., Schaefer, B. E. 1991, PASP 103, 1033, "
                    "doi:10.1086/132921",
                    "Kieffer, H. H., Stone, T. C. 2005, AJ 129, 2887, doi:10.1086/430185",
                    "Helfenstein, P., Veverka, J. 1987, Icarus 72, 342, "
                    "doi:10.1016/0019-1035(87)90179-5"],
        parameters={"quick": quick, "n_quadrature": n_quadrature, "step_deg": step})


def figure_of(dataset):
    import matplotlib.pyplot as plt

    alpha = dataset.phase_angle.values
    ks = dataset.magnitude_ks1991.values
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(7.0, 7.0), sharex=True)
    top.plot(alpha, ks, "k--", label="K&S 1991 eq. 9")
    top.plot(alpha, dataset.magnitude_rolo2005.values, "k:", lw=2.5, label="ROLO (K&S 2005)")
    for index, name in enumerate(dataset.variant.values):
        style = {"lw": 2.0, "color": "C3"} if index == 0 else {"lw": 0.8, "alpha": 0.8}
        curve = dataset.magnitude.values[index]
        top.plot(alpha, curve, label=f"Hapke, {name}", **style)
        bottom.plot(alpha, curve - ks, **style)
    bottom.plot(alpha, dataset.magnitude_rolo2005.values - ks, "k:", lw=2.5)
    for sign in (-1.0, 1.0):
        bottom.axhline(sign * KS_TOLERANCE_MAG, color="0.5", lw=0.8)
    top.invert_yaxis()
    top.set_ylabel("V [mag]")
    top.legend(fontsize=7)
    bottom.set_ylim(-0.4, 0.6)
    bottom.set_xlabel("phase angle [°]")
    bottom.set_ylabel("minus K&S [mag]")
    top.set_title("Lunar phase curve (no fitting); band: ±0.15 mag", fontsize=10)
    for axes in (top, bottom):
        axes.grid(alpha=0.3)
    return figure


def main(argv=None) -> int:
    args = parse_arguments(__doc__.splitlines()[0], argv)
    dataset = run(quick=args.quick)
    save_outputs(dataset, figure_of(dataset), args.output_dir, "moon_phase_curve")
    alpha = dataset.phase_angle.values
    difference = dataset.magnitude.sel(variant="default").values - dataset.magnitude_ks1991.values
    for target in (30.0, 90.0, 110.0, 120.0):
        index = int(np.argmin(np.abs(alpha - target)))
        print(f"| {alpha[index]:.0f}° | model − K&S {difference[index]:+.3f} mag |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
