r"""Tone mapping of sky images: exposure, night vision (Purkinje shift), sRGB PNG.

Absolute luminances span 1e-4 cd m^-2 (dark sky) to 1e9 cd m^-2 (the solar disc); a
display shows [0, 1]. The mapping is

1. exposure: :math:`Y \to k\,Y` with ``exposure`` [cd^-1 m^2], or automatically
   :math:`k = a / \bar Y_{log}` with the log-average luminance of the sky pixels and key
   :math:`a = 0.18` (Reinhard et al. 2002, eq. 1–2);
2. night vision (optional): below the photopic range the eye loses colour and shifts
   towards blue. The scotopic luminance :math:`Y_s = Y\,[1.33\,(1 + (Y+Z)/X) - 1.68]`
   (Larson et al. 1997, eq. 7) is mixed in with weight :math:`s` falling linearly in
   :math:`\log_{10} Y` from 1 at 0.01 cd m^-2 to 0 at 3 cd m^-2 (the mesopic range),
   rendered in the bluish grey of chromaticity (0.25, 0.25) used for night scenes by
   Jensen et al. (2001);
3. the global Reinhard operator :math:`Y/(1+Y)` on the luminance, keeping chromaticity;
4. sRGB primaries and transfer curve (:func:`skytorch.spectrum.xyz_to_srgb`).

References
----------
1. Reinhard, E., Stark, M., Shirley, P. & Ferwerda, J. 2002, "Photographic tone
   reproduction for digital images", ACM TOG 21, 267, doi:10.1145/566654.566575.
2. Larson, G. W., Rushmeier, H. & Piatko, C. 1997, "A visibility matching tone
   reproduction operator for high dynamic range scenes", IEEE TVCG 3, 291,
   doi:10.1109/2945.646233.
3. Jensen, H. W. et al. 2001, "A physically-based night sky model", SIGGRAPH 2001,
   doi:10.1145/383259.383306.

Examples
--------
>>> import torch
>>> rgb, k = tonemap(torch.tensor([[[0.95, 1.0, 1.09]]]))
>>> bool(((rgb >= 0) & (rgb <= 1)).all())
True
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import torch

from skytorch._validate import check_flag, check_positive

#: Reinhard's middle-grey key
KEY = 0.18
#: mesopic range of the night-vision blend [cd m^-2] (scotopic below, photopic above)
MESOPIC_RANGE_CD_M2 = (0.01, 3.0)
#: chromaticity of the night-vision tint (Jensen et al. 2001)
NIGHT_CHROMATICITY = (0.25, 0.25)


def auto_exposure(luminance: torch.Tensor, valid: torch.Tensor | None = None) -> float:
    r"""Reinhard's exposure :math:`a / \exp(\overline{\ln(\delta + Y)})` [cd^-1 m^2]."""
    values = luminance.reshape(-1) if valid is None else luminance[valid]
    values = values.to(torch.float64).clamp(min=0.0)
    if values.numel() == 0:
        return 1.0
    log_mean = float(torch.log(1e-9 + values).mean())
    return KEY / math.exp(log_mean)


def night_vision(xyz: torch.Tensor) -> torch.Tensor:
    """Blend absolute XYZ [cd m^-2] towards a blue-grey scotopic rendering (Purkinje)."""
    x, y, z = xyz.unbind(-1)
    safe_x = x.clamp(min=1e-30)
    scotopic = (y * (1.33 * (1.0 + (y + z) / safe_x) - 1.68)).clamp(min=0.0)
    low, high = (math.log10(v) for v in MESOPIC_RANGE_CD_M2)
    weight = ((high - torch.log10(y.clamp(min=1e-30))) / (high - low)).clamp(0.0, 1.0)
    cx, cy = NIGHT_CHROMATICITY
    # scotopic luminance shown with the luminance of its photopic equivalent
    grey = torch.stack([cx / cy * scotopic, scotopic, (1.0 - cx - cy) / cy * scotopic], -1)
    grey = grey * (y / scotopic.clamp(min=1e-30)).clamp(max=1.0)[..., None]
    return (1.0 - weight[..., None]) * xyz + weight[..., None] * grey


def tonemap(xyz: torch.Tensor, valid: torch.Tensor | None = None, *, exposure=None,
            night: bool = False) -> tuple[torch.Tensor, float]:
    """Display sRGB (..., 3) in [0, 1] from absolute XYZ (..., 3) [cd m^-2].

    Parameters
    ----------
    xyz : Tensor (..., 3)
        Tristimulus values with Y the luminance [cd m^-2].
    valid : Tensor (...) bool, optional
        Pixels that show the sky (others are black and ignored by the auto exposure).
    exposure : float, optional
        Scale [cd^-1 m^2]; default automatic (module notes).
    night : bool
        Apply the night-vision blend first.

    Returns
    -------
    (Tensor (..., 3), float)
        sRGB values and the exposure used.
    """
    from skytorch.spectrum import xyz_to_srgb

    xyz = xyz.to(torch.float64).clamp(min=0.0)
    if check_flag("night", night):
        xyz = night_vision(xyz)
    if exposure is not None:
        exposure = float(check_positive("exposure", exposure))
    k = auto_exposure(xyz[..., 1], valid) if exposure is None else exposure
    scaled = xyz * k
    y = scaled[..., 1:2]
    mapped = scaled * (1.0 / (1.0 + y))
    rgb = xyz_to_srgb(mapped, gamma=True, clip=True)
    if valid is not None:
        rgb = rgb * valid[..., None].to(rgb.dtype)
    return rgb, k


def save_png(rgb, path, *, title: str | None = None) -> Path:
    """Write an sRGB image (rows, columns, 3) in [0, 1] to a PNG file."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    array = np.asarray(rgb.detach() if torch.is_tensor(rgb) else rgb, dtype=float)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if title is None:
        plt.imsave(path, np.clip(array, 0.0, 1.0))
        return path
    figure, axes = plt.subplots(figsize=(5, 5.3))
    axes.imshow(np.clip(array, 0.0, 1.0), interpolation="nearest")
    axes.set_title(title, fontsize=9)
    axes.set_axis_off()
    figure.savefig(path, dpi=120, bbox_inches="tight", facecolor="black")
    plt.close(figure)
    return path


def scene_png(dataset, path, *, exposure=None, night: bool = False,
              title: str | None = None) -> Path:
    """Tone-map a rendered scene Dataset (``xyz``) and write it as a PNG."""
    missing = [name for name in ("xyz", "solid_angle") if name not in dataset]
    if missing:
        raise ValueError(f"dataset lacks {missing}: scene_png needs a render with 'xyz' among "
                         "the Scene's outputs")
    xyz = torch.as_tensor(dataset["xyz"].values)
    valid = torch.as_tensor(dataset["solid_angle"].values > 0)
    if xyz.ndim != 3:
        raise ValueError("scene_png needs an image view (fisheye or panorama); got dims "
                         f"{dataset['xyz'].dims}")
    rgb, _ = tonemap(xyz, valid, exposure=exposure, night=night)
    if dataset["xyz"].dims[0] == "elevation":
        rgb = torch.flip(rgb, dims=(0,))  # horizon at the bottom
    return save_png(rgb, path, title=title)
