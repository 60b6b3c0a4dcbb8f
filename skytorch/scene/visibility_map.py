"""Which stars the eye sees in each direction: limiting magnitude maps and visible counts.

:func:`limiting_magnitude_map` applies Schaefer's (1990) threshold model
(:func:`skytorch.stars.visibility.limiting_magnitude`) to every pixel's sky surface
brightness; :func:`visible_star_count` counts the catalogue stars above the horizon whose
magnitude after extinction is brighter than the limit of the pixel that holds them.

References
----------
1. Schaefer, B. E. 1990, PASP 102, 212, doi:10.1086/132629.

Examples
--------
>>> import torch
>>> [round(v, 2) for v in limiting_magnitude_map(torch.tensor([22.0, 18.0])).tolist()]
[6.62, 4.19]
"""

from __future__ import annotations

import torch

from skytorch._validate import check_finite, check_range
from skytorch.moon.sky import radiance_to_mag_arcsec2
from skytorch.stars.visibility import REFERENCE_PUPIL_MM, limiting_magnitude

__all__ = ["limiting_magnitude_map", "sky_mag_from_radiance", "visible_star_count"]


def sky_mag_from_radiance(spectral_radiance, wavelength_nm) -> torch.Tensor:
    """V surface brightness [mag arcsec^-2] of a radiance image (*view, wavelength).

    Pixels without light (radiance 0) come out as +inf magnitudes would: they are set to
    40 mag arcsec^-2, the upper end of :func:`limiting_magnitude`'s range, where the
    limit is that of a black background (7.93 mag).
    """
    radiance = check_range("spectral_radiance", spectral_radiance, low=0.0,
                           unit=" W m^-2 sr^-1 nm^-1")
    dark = radiance.sum(-1) == 0.0
    safe = torch.where(dark[..., None], torch.ones_like(radiance), radiance)
    mag = radiance_to_mag_arcsec2(safe, wavelength_nm)
    return torch.where(dark, torch.full_like(mag, 40.0), mag.clamp(max=40.0))


def limiting_magnitude_map(sky_mag_arcsec2, *, pupil_diameter_mm: float = REFERENCE_PUPIL_MM,
                           acuity_factor: float = 1.0) -> torch.Tensor:
    """Naked-eye limiting magnitude per pixel from the sky's V surface brightness.

    Parameters
    ----------
    sky_mag_arcsec2 : array_like
        ``(*view)`` V surface brightness of the sky in each pixel [mag arcsec^-2], within
        [−20, 40] (:func:`sky_mag_from_radiance` of the rendered image).
    pupil_diameter_mm, acuity_factor : float
        The observer (Schaefer's defaults: 7 mm, F_s = 1).

    Returns
    -------
    torch.Tensor
        ``(*view)`` faintest V magnitude seen, to compare with a star's magnitude after
        extinction [mag].
    """
    return limiting_magnitude(sky_mag_arcsec2, pupil_diameter_mm=pupil_diameter_mm,
                              acuity_factor=acuity_factor)


def visible_star_count(magnitude, pixel_index, limit_map) -> tuple[torch.Tensor, torch.Tensor]:
    """Stars brighter than the limiting magnitude of their pixel, and how many.

    Parameters
    ----------
    magnitude : array_like
        ``(star,)`` magnitude after extinction [mag].
    pixel_index : array_like (int)
        ``(star,)`` flat index of the pixel holding each star, −1 for stars outside the
        view or below the horizon (:meth:`skytorch.scene.scene.View.pixel_index`).
    limit_map : array_like
        ``(*view)`` limiting magnitude (:func:`limiting_magnitude_map`).

    Returns
    -------
    visible : torch.Tensor (bool), shape (star,)
    count : torch.Tensor (int64), shape ()
    """
    mag = check_finite("magnitude", magnitude)
    index = torch.as_tensor(pixel_index)
    if index.dtype == torch.bool:
        raise TypeError("pixel_index must hold integer pixel indices; got booleans")
    if index.dtype.is_floating_point or index.shape != mag.shape:
        raise ValueError(f"pixel_index must be an integer tensor of the magnitudes' shape "
                         f"{tuple(mag.shape)}; got {index.dtype} {tuple(index.shape)}")
    limits = check_finite("limit_map", limit_map).reshape(-1)
    if bool((index >= limits.numel()).any()) or bool((index < -1).any()):
        raise ValueError(f"pixel_index must be in [-1, {limits.numel() - 1}]")
    inside = index >= 0
    limit = limits.to(mag.dtype)[index.clamp(min=0)]
    visible = inside & (mag <= limit)
    return visible, visible.sum()
