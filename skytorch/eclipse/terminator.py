r"""Latitudes along the Earth's limb seen from the shadow, and the share of each band.

During a lunar eclipse the sunlight reaching the umbra grazes the Earth along the
terminator, the great circle perpendicular to the Sun's direction. A limb point at
position angle :math:`\psi` in the shadow plane (from the projection of the celestial
north pole, the Earth's axis tilted by the Sun's declination :math:`\delta_\odot` out of
that plane) lies at the geocentric latitude

.. math:: \sin\varphi = \cos\psi\,\cos\delta_\odot ,

so, with :math:`\psi` uniform along the limb, the share of the terminator's length
between latitudes :math:`\varphi_a < \varphi_b` is

.. math:: s = \frac{1}{\pi}\left[\arccos x_a - \arccos x_b\right], \qquad
          x = \mathrm{clip}\left(\frac{\sin\varphi}{\cos\delta_\odot}, -1, 1\right).

At the equinoxes the terminator passes through the poles and every latitude has the same
share (the tropics within 30° of the equator: 1/3); at the solstices the polar caps
beyond :math:`90° - |\delta_\odot|` are not on it at all.

Examples
--------
>>> import math, torch
>>> from skytorch.eclipse.terminator import terminator_band_shares
>>> shares = terminator_band_shares(torch.tensor(0.0), (-52.5, -30.0, 30.0, 52.5))
>>> [round(v, 4) for v in shares.tolist()]
[0.2083, 0.125, 0.3333, 0.125, 0.2083]
>>> solstice = terminator_band_shares(torch.tensor(math.radians(23.44)), (-30.0, 30.0))
>>> round(float(solstice[1]), 4)
0.3669
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

from skytorch._validate import as_tensor, check_range

__all__ = ["LimbLatitudeWindow", "terminator_band_shares", "terminator_latitude"]


def terminator_latitude(position_angle_rad, solar_declination_rad) -> torch.Tensor:
    r"""Geocentric latitude of the limb point at a position angle in the shadow plane [rad].

    Parameters
    ----------
    position_angle_rad : float or Tensor (...)
        Position angle of the limb point from the projected celestial north pole [rad].
    solar_declination_rad : float or Tensor (...)
        Declination of the Sun [rad], in [-π/2, π/2].

    Returns
    -------
    Tensor (...)
        :math:`\arcsin(\cos\psi \cos\delta_\odot)` [rad].
    """
    psi = as_tensor("position_angle_rad", position_angle_rad, dtype=torch.float64)
    delta = check_range("solar_declination_rad", solar_declination_rad, -0.5 * math.pi,
                        0.5 * math.pi, dtype=torch.float64)
    return torch.asin(torch.cos(psi) * torch.cos(delta))


def terminator_band_shares(solar_declination_rad,
                           boundaries_deg: Sequence[float]) -> torch.Tensor:
    """Share of the terminator's length in each latitude band [1].

    Parameters
    ----------
    solar_declination_rad : float or Tensor (...)
        Declination of the Sun [rad], in (-π/2, π/2).
    boundaries_deg : sequence of float
        Latitudes separating the bands [deg], strictly increasing, inside (-90, 90): ``n``
        boundaries give ``n + 1`` bands from the south pole to the north pole.

    Returns
    -------
    Tensor (..., n + 1)
        Shares summing to 1 (differentiable in the declination).

    Raises
    ------
    ValueError
        Boundaries not increasing or outside (-90, 90) deg, declination out of range.
    """
    delta = check_range("solar_declination_rad", solar_declination_rad, -0.5 * math.pi,
                        0.5 * math.pi, low_inclusive=False, high_inclusive=False,
                        dtype=torch.float64)
    bounds = check_range("boundaries_deg", boundaries_deg, -90.0, 90.0, low_inclusive=False,
                         high_inclusive=False, dtype=torch.float64)
    if bounds.ndim != 1 or bounds.numel() == 0 or not bool((bounds.diff() > 0).all()):
        raise ValueError("boundaries_deg must be a non-empty, strictly increasing sequence of "
                         f"latitudes in (-90, 90) deg; got {bounds.tolist()}")
    x = torch.sin(torch.deg2rad(bounds)) / torch.cos(delta)[..., None]
    angle = torch.acos(torch.clamp(x, -1.0, 1.0))  # (..., n): position angles of the bounds
    pad = torch.zeros_like(angle[..., :1])
    edges = torch.cat([pad + math.pi, angle, pad], dim=-1)  # south pole .. north pole
    return (edges[..., :-1] - edges[..., 1:]) / math.pi


class LimbLatitudeWindow:
    r"""The part of the limb between two latitudes, by position angle around the axis.

    ``weight(theta)`` is 1 where the limb point at position angle ``theta`` from the
    projected celestial north pole lies at a latitude in ``[low, high)`` and 0 elsewhere
    (:func:`terminator_latitude`; the latitude depends on :math:`\cos\theta` only, so the
    sense in which ``theta`` is counted does not matter). Windows with shared boundaries
    partition the limb: their weights sum to 1 at every position angle.

    Parameters
    ----------
    low_deg, high_deg : float
        Latitude bounds [deg], ``-90 <= low < high <= 90`` (-90 / 90 for the polar caps).
    solar_declination_rad : float
        Declination of the Sun [rad], in (-π/2, π/2).
    """

    def __init__(self, low_deg: float, high_deg: float, solar_declination_rad: float):
        low = float(check_range("low_deg", low_deg, -90.0, 90.0, high_inclusive=False))
        high = float(check_range("high_deg", high_deg, -90.0, 90.0, low_inclusive=False))
        if not low < high:
            raise ValueError(f"low_deg must be below high_deg; got {low} and {high}")
        delta = float(check_range("solar_declination_rad", solar_declination_rad,
                                  -0.5 * math.pi, 0.5 * math.pi, low_inclusive=False,
                                  high_inclusive=False))
        self.low_deg, self.high_deg = low, high
        self.solar_declination_rad = delta
        # bounds on sin(latitude) / cos(delta) = cos(theta): the caps reach +-1
        scale = math.cos(delta)
        self._low = -math.inf if low <= -90.0 else math.sin(math.radians(low)) / scale
        self._high = math.inf if high >= 90.0 else math.sin(math.radians(high)) / scale

    def weight(self, position_angle_rad: torch.Tensor) -> torch.Tensor:
        """Return 1 inside the window and 0 outside, at limb position angles [rad]."""
        cosine = torch.cos(position_angle_rad)
        return ((cosine >= self._low) & (cosine < self._high)).to(position_angle_rad.dtype)

    def __repr__(self) -> str:
        """Bounds and declination."""
        return (f"LimbLatitudeWindow({self.low_deg:g}..{self.high_deg:g} deg, declination "
                f"{math.degrees(self.solar_declination_rad):.2f} deg)")
