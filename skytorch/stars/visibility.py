"""Which stars the eye can see: Schaefer's threshold model and Müller's day–night factor.

Two models side by side, as the sky phenomena literature uses them:

* the physical contrast model — Schaefer's (1990) fit to Hecht's (1934) threshold data:
  the faintest point source the eye detects against a sky background B gives the
  limiting magnitude (:func:`limiting_magnitude`); a star is visible where its magnitude
  after extinction is brighter than that (:func:`count_visible`);
* Müller et al.'s (2012, §5) rendering factor that fades stars between night and day
  from the Sun's altitude alone (:func:`muller_day_night_factor`).

References
----------
1. Schaefer, B. E. 1990, "Telescopic limiting magnitudes", PASP 102, 212,
   doi:10.1086/132629 (eqs. 2–3 and the nanolambert conversion).
2. Schaefer, B. E. 1998, "To the visual limits", Sky & Telescope 95 (5), 57.
3. Krisciunas, K., Schaefer, B. E. 1991, "A model of the brightness of moonlight", PASP
   103, 1033, doi:10.1086/132921 (eq. 1: B [nL] = 34.08 exp(20.7233 − 0.92104 V)).
4. Müller, S., Engel, J., Döllner, J. 2012, "Single-Pass Rendering of Day and Night Sky
   Phenomena", Proc. VMV 2012, §5.

Examples
--------
>>> round(float(limiting_magnitude(22.0)), 2)
6.62
"""

from __future__ import annotations

import math

import torch

from skytorch._validate import as_tensor, check_choice, check_range, refuse_gradient
from skytorch.moon.sky import mag_arcsec2_to_nanolambert  # K&S 1991 eq. 1, shared

__all__ = [
    "VISIBILITY_MODELS",
    "count_true",
    "count_visible",
    "limiting_magnitude",
    "mag_arcsec2_to_nanolambert",
    "muller_day_night_factor",
]

#: models of star visibility: Schaefer's threshold contrast or Müller's rendering factor
VISIBILITY_MODELS = ("schaefer1990", "muller2012")
#: Schaefer (1990) threshold constants (c1 [foot-candle], c2 [1/nL]) for night and day
SCHAEFER_NIGHT = (10.0**-9.80, 10.0**-1.90)
SCHAEFER_DAY = (10.0**-8.35, 10.0**-5.90)
#: sky brightness separating the scotopic and photopic branches [nL]
SCHAEFER_SWITCH_NL = 1500.0
#: magnitude of a source giving 1 foot-candle: m = −16.57 − 2.5 log10(I) (Schaefer 1990)
SCHAEFER_ZERO_POINT_MAG = -16.57
#: pupil diameter of the dark-adapted eye in Schaefer's calibration [mm]
REFERENCE_PUPIL_MM = 7.0


def limiting_magnitude(sky_mag_arcsec2, *, pupil_diameter_mm: float = REFERENCE_PUPIL_MM,
                       acuity_factor: float = 1.0) -> torch.Tensor:
    """Naked-eye limiting magnitude of a point source against a sky background.

    Parameters
    ----------
    sky_mag_arcsec2 : array_like
        ``(...)`` sky surface brightness in V [mag arcsec⁻²] (22: dark site; 17: city;
        about 4 in daylight).
    pupil_diameter_mm : float
        Pupil diameter [mm]; the threshold scales with the collecting area relative to
        Schaefer's 7 mm.
    acuity_factor : float
        Schaefer's observer factor F_s (> 1 for a less sensitive observer).

    Returns
    -------
    torch.Tensor
        ``(...)`` limiting V magnitude [mag] of a star *as seen* (apply extinction to the
        star, not to the threshold).

    Notes
    -----
    Schaefer (1990, eqs. 2–3), fitted to Hecht's (1934) thresholds: the threshold
    illuminance I = c1 (1 + √(c2 B))² [foot-candle] with B in nanolamberts, (c1, c2) =
    (10^−9.8, 10^−1.9) for B < 1500 nL (rods) and (10^−8.35, 10^−5.9) above (cones); the
    limiting magnitude is m = −16.57 − 2.5 log10(I F), F = F_s (7 mm / pupil)². Without
    any background m → 7.93.
    """
    brightness = mag_arcsec2_to_nanolambert(sky_mag_arcsec2)
    refuse_gradient("limiting_magnitude", why="the observer's pupil and acuity are numbers of "
                    "the observer, not of the sky", pupil_diameter_mm=pupil_diameter_mm,
                    acuity_factor=acuity_factor)
    pupil = float(check_range("pupil_diameter_mm", pupil_diameter_mm, 1.0, 10.0, unit=" mm"))
    acuity = float(check_range("acuity_factor", acuity_factor, 0.01, 100.0))
    night = brightness < SCHAEFER_SWITCH_NL
    c1 = torch.where(night, SCHAEFER_NIGHT[0], SCHAEFER_DAY[0]).to(brightness.dtype)
    c2 = torch.where(night, SCHAEFER_NIGHT[1], SCHAEFER_DAY[1]).to(brightness.dtype)
    threshold = c1 * (1.0 + torch.sqrt(c2 * brightness)) ** 2
    factor = acuity * (REFERENCE_PUPIL_MM / pupil) ** 2
    return SCHAEFER_ZERO_POINT_MAG - 2.5 * torch.log10(threshold * factor)


def muller_day_night_factor(sun_altitude_rad) -> torch.Tensor:
    """Müller et al.'s (2012, §5) star intensity factor between night and day.

    Parameters
    ----------
    sun_altitude_rad : array_like
        ``(time,)`` altitude of the Sun [rad].

    Returns
    -------
    torch.Tensor
        ``(time,)`` factor in (0, 1]: (1 + (s_z + 1.14)³²)^(−1/2) with s_z = sin(altitude),
        the z component of the unit vector to the Sun. 1/√2 at s_z = −0.14 (Sun 8° below
        the horizon), 0.12 at sunrise, 0.03 at 5.7° altitude.
    """
    altitude = check_range("sun_altitude_rad", sun_altitude_rad, -math.pi / 2, math.pi / 2,
                           unit=" rad")
    s_z = torch.sin(altitude)
    return torch.rsqrt(1.0 + (s_z + 1.14) ** 32)


def count_visible(magnitude: torch.Tensor, above_horizon: torch.Tensor,
                  limit_mag: torch.Tensor, model: str = "schaefer1990",
                  day_night_factor: torch.Tensor | None = None
                  ) -> tuple[torch.Tensor, torch.Tensor]:
    """Visibility flags and the number of visible stars per time.

    Parameters
    ----------
    magnitude : torch.Tensor, shape (time, star)
        Magnitude after extinction [mag].
    above_horizon : torch.Tensor (bool), shape (time, star)
    limit_mag : torch.Tensor, shape (time,) or ()
        Limiting magnitude [mag] (:func:`limiting_magnitude`).
    model : {"schaefer1990", "muller2012"}
        ``"schaefer1990"``: visible where m ≤ limit. ``"muller2012"``: the limit is
        shifted by the day–night factor f, m ≤ limit + 2.5 log10 f (a star rendered with
        intensity f·10^(−0.4 m) must still reach the threshold).
    day_night_factor : torch.Tensor, shape (time,), optional
        Required for ``"muller2012"``.

    Returns
    -------
    visible : torch.Tensor (bool), shape (time, star)
    count : torch.Tensor (int64), shape (time,)
    """
    check_choice("model", model, VISIBILITY_MODELS)
    magnitude = as_tensor("magnitude", magnitude)
    limit_mag = as_tensor("limit_mag", limit_mag, dtype=magnitude.dtype)
    above_horizon = torch.as_tensor(above_horizon)
    if above_horizon.dtype != torch.bool:
        raise TypeError(f"above_horizon must be a bool tensor (time, star); got dtype "
                        f"{above_horizon.dtype}")
    if magnitude.ndim != 2 or above_horizon.shape != magnitude.shape or limit_mag.ndim > 1 \
            or limit_mag.numel() not in (1, magnitude.shape[0]):
        raise ValueError(f"magnitude and above_horizon must have one shape (time, star) and "
                         f"limit_mag () or (time,); got {tuple(magnitude.shape)}, "
                         f"{tuple(above_horizon.shape)} and {tuple(limit_mag.shape)}")
    limit = limit_mag.to(magnitude.dtype).reshape(-1, 1) if limit_mag.ndim else limit_mag
    if model == "muller2012":
        if day_night_factor is None:
            raise ValueError("day_night_factor is required for model 'muller2012'")
        limit = limit + 2.5 * torch.log10(day_night_factor.to(magnitude.dtype)).reshape(-1, 1)
    visible = torch.le(magnitude, limit).logical_and_(above_horizon)
    return visible, count_true(visible)


def count_true(flags: torch.Tensor) -> torch.Tensor:
    """Count the True values of a bool tensor along its last dimension (int64).

    Summed as bytes into int32, twice as fast as ``flags.sum(-1)`` (which widens every
    value to int64).

    Examples
    --------
    >>> count_true(torch.tensor([[True, False, True], [False, False, False]]))
    tensor([2, 0])
    """
    if not isinstance(flags, torch.Tensor) or flags.dtype != torch.bool or flags.ndim == 0:
        raise TypeError(f"flags must be a bool tensor of at least one dimension; got "
                        f"{getattr(flags, 'dtype', type(flags).__name__)} with shape "
                        f"{tuple(getattr(flags, 'shape', ()))}")
    if flags.shape[-1] >= 2**31:
        return flags.sum(-1)
    return flags.view(torch.uint8).sum(-1, dtype=torch.int32).long()
