"""Images of the lunar disc through a lunation (Müller et al. 2012, Fig. 1 style).

Spectral radiance of the disc (Hapke reflectance, Müller's albedo colour, earthshine) at
phase angles 0°–150°, computed on the "bands15" wavelength grid and converted to sRGB with
one common exposure (the full Moon's disc-centre luminance maps to 0.8), so the images show
the true brightness ratios between phases; a second row scales each phase to its own
maximum to show shading and the earthlit side (×200 gain below the sunlit maximum).

Usage: ``python experiments/moon_disc_images.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable  # noqa: E402
from skytorch.moon.datasets import moon_disc_image  # noqa: E402
from skytorch.spectrum import spectrum_to_xyz, wavelength_grid, xyz_to_srgb  # noqa: E402

PHASES_DEG = (0.0, 30.0, 60.0, 90.0, 120.0, 150.0)


def run(quick: bool = False):
    n_pixels = 48 if quick else 160
    wl = wavelength_grid("bands15")
    wl = wl[(wl >= 360.0) & (wl <= 830.0)]
    images = [moon_disc_image(phase, 270.0, n_pixels=n_pixels, wavelength_nm=wl.tolist())
              for phase in PHASES_DEG]
    radiance = torch.as_tensor(np.stack([image.radiance.values for image in images]))
    xyz = spectrum_to_xyz(radiance, wl)
    luminance = xyz[..., 1]
    exposure = 0.8 / luminance[0, n_pixels // 2, n_pixels // 2]
    common = xyz_to_srgb(xyz * exposure, clip=True)
    peak = luminance.amax(dim=(-2, -1), keepdim=True).unsqueeze(-1)
    own = xyz_to_srgb(xyz / peak, clip=True)
    dark = xyz_to_srgb(xyz / peak * 200.0, clip=True)
    own = torch.where(luminance.unsqueeze(-1) < peak[..., 0:1, :] / 200.0, dark, own)
    return build_dataset(
        {"luminance": variable(("phase_angle", "y", "x"), luminance, VariableSpec(
            "W m-2 sr-1", "CIE Y of the disc radiance",
            "CIE 1931 Y tristimulus of the spectral radiance (unnormalised, W m-2 sr-1 "
            "weighted by the y-bar colour matching function)")),
         "srgb_common": variable(("phase_angle", "y", "x", "channel"), common, VariableSpec(
             "1", "sRGB, common exposure", "gamma-encoded sRGB, one exposure for all phases")),
         "srgb_own": variable(("phase_angle", "y", "x", "channel"), own, VariableSpec(
             "1", "sRGB, per-phase exposure", "each phase scaled to its maximum; the earthlit "
                                               "part shown with a gain of 200"))},
        {"phase_angle": coordinate("phase_angle", np.array(PHASES_DEG), VariableSpec(
            "degree", "lunar phase angle", "Sun-Moon-observer angle")),
         "y": images[0].y.variable, "x": images[0].x.variable,
         "channel": coordinate("channel", np.array(["R", "G", "B"]), VariableSpec(
             "1", "sRGB channel", "red, green, blue"))},
        title="Images of the lunar disc through a lunation",
        references=["Muller, T., Engel, J., Dollner, J. 2012, Proc. VMV, "
                    "doi:10.2312/PE/VMV/VMV12/055-062"],
        parameters={"quick": quick, "n_pixels": n_pixels, "bright_limb_angle_deg": 270.0})


def figure_of(dataset):
    import matplotlib.pyplot as plt

    n = dataset.sizes["phase_angle"]
    figure, axes = plt.subplots(2, n, figsize=(1.7 * n, 3.8), facecolor="black")
    for k in range(n):
        for row, name in enumerate(("srgb_common", "srgb_own")):
            axis = axes[row, k]
            axis.imshow(dataset[name].isel(phase_angle=k).values, origin="lower")
            axis.set_axis_off()
        axes[0, k].set_title(f"α = {dataset.phase_angle.values[k]:.0f}°", color="white",
                             fontsize=9)
    figure.suptitle("Lunar disc (Hapke, Müller colour, earthshine): common exposure (top), "
                    "per-phase exposure (bottom)", color="white", fontsize=9)
    return figure


def main(argv=None) -> int:
    args = parse_arguments(__doc__.splitlines()[0], argv)
    dataset = run(quick=args.quick)
    save_outputs(dataset, figure_of(dataset), args.output_dir, "moon_disc_images")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
