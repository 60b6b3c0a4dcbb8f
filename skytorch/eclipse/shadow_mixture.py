r"""A shadow whose limb atmosphere differs along the terminator: a weighted mean of shadows.

The eclipse shadow of :class:`~skytorch.eclipse.shadow.Shadow` assumes one spherically
symmetric atmosphere. The real limb crosses every latitude, from tropical air with its
tropopause at 17 km to polar air with its tropopause at 9 km. :class:`ShadowMixture`
holds one :class:`Shadow` per class of limb atmosphere with the share of the terminator's
length each occupies, and returns the weighted mean of their illuminances:

.. math:: \frac{I}{I_\odot}(P) = \sum_k w_k \frac{I_k}{I_\odot}(P), \qquad \sum_k w_k = 1.

This is exact for the light averaged over the directions around the shadow's axis (each
direction of the limb contributes with the atmosphere of its latitude, and the ring
integral of each member is linear in the limb's radiance); at a given point it neglects
that the near limb contributes more than the far one, so it is the azimuthal mean of the
true non-axisymmetric shadow, not its value in a given direction.

With ``limb_windows`` (one window on the limb per member, e.g. the latitude bands of
:class:`~skytorch.eclipse.terminator.LimbLatitudeWindow`) the mixture is also resolved in
direction: for a point at position angle :math:`\theta_P` around the axis, each member's
ring integral keeps only the rays that left the limb inside its window (near side
:math:`\theta_P \pm \psi`, far side :math:`\theta_P + \pi \pm \psi`, with
:math:`\psi` the azimuth along the solar arc), and the direct sunlight is counted once.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere import Atmosphere
>>> from skytorch.eclipse import Shadow
>>> from skytorch.eclipse.shadow_mixture import ShadowMixture
>>> clean, hazy = (Shadow.earth(Atmosphere.earth(aerosol_optical_depth=t)) for t in (0.05, 0.5))
>>> mixture = ShadowMixture([clean, hazy], [0.25, 0.75], names=["clean", "hazy"])
>>> wl = torch.tensor([600.0], dtype=torch.float64)
>>> point = (torch.tensor(3.8e8, dtype=torch.float64), torch.tensor(3e6, dtype=torch.float64))
>>> mixed = mixture.relative_illuminance(*point, wl)
>>> parts = [s.relative_illuminance(*point, wl) for s in (clean, hazy)]
>>> bool(torch.allclose(mixed, 0.25 * parts[0] + 0.75 * parts[1]))
True
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from skytorch._validate import as_tensor, check_int, check_range
from skytorch.eclipse.shadow import Shadow

__all__ = ["DEFAULT_POSITION_ANGLES", "ShadowMixture"]

#: position angles over [0, pi] of the shadow table of a mixture resolved in direction
#: (15 deg apart)
DEFAULT_POSITION_ANGLES = 13

#: geometry every member must share [m]
_GEOMETRY = ("occluder_radius_m", "top_radius_m", "sun_distance_m", "sun_radius_m")


class ShadowMixture(nn.Module):
    """Weighted mean of shadows of the same planet: limb atmospheres along the terminator.

    Parameters
    ----------
    shadows : sequence of Shadow
        Members (at least one), of the same planet radius, top of the atmosphere, Sun
        distance and Sun radius (to 1e-9 relative); batched atmospheres must broadcast.
    weights : sequence of float or Tensor (member,)
        Share of each member [1], >= 0, summing to 1 (within 1e-9).
    names : sequence of str, optional
        Label of each member (Dataset attributes); default ``member_0``, ...
    limb_windows : sequence, optional
        The part of the limb each member's atmosphere occupies, one window per member
        with ``weight(position_angle_rad)`` (e.g.
        :class:`~skytorch.eclipse.terminator.LimbLatitudeWindow`); the windows must
        partition the limb. With them :meth:`relative_illuminance` also takes the points'
        position angles and resolves the shadow in direction (members unbatched, without
        ``scattering``).
    n_position_angle : int
        Position angles over [0, π] of its shadow table when resolved in direction
        (:meth:`ShadowTable.compute <skytorch.eclipse.shadow_table.ShadowTable.compute>`).

    Raises
    ------
    TypeError
        A member is not a :class:`Shadow`, or a name not a string.
    ValueError
        No member, weights of another count, negative or not summing to 1, or members of
        another geometry.
    """

    def __init__(self, shadows: Sequence[Shadow], weights, names: Sequence[str] | None = None,
                 limb_windows: Sequence | None = None,
                 n_position_angle: int = DEFAULT_POSITION_ANGLES):
        super().__init__()
        shadows = list(shadows)
        if not shadows:
            raise ValueError("shadows must hold at least one Shadow; got none")
        for k, shadow in enumerate(shadows):
            if not isinstance(shadow, Shadow):
                raise TypeError(f"shadows[{k}] must be a skytorch.eclipse.Shadow; got "
                                f"{type(shadow).__name__}")
        weights = check_range("weights", as_tensor("weights", weights, dtype=torch.float64),
                              0.0, 1.0)
        if weights.shape != (len(shadows),):
            raise ValueError(f"weights must hold one value per shadow ({len(shadows)}); got "
                             f"shape {tuple(weights.shape)}")
        total = float(weights.detach().sum())
        if abs(total - 1.0) > 1e-9:
            raise ValueError(f"weights must sum to 1; got {weights.detach().tolist()} (sum "
                             f"{total:.12g})")
        _check_members(shadows)
        first = shadows[0]
        names = [f"member_{k}" for k in range(len(shadows))] if names is None else list(names)
        if len(names) != len(shadows) or not all(isinstance(n, str) for n in names):
            raise TypeError(f"names must be {len(shadows)} strings; got {names!r}")
        #: the part of the limb of each member (None: azimuthal mean only)
        self.limb_windows = (None if limb_windows is None
                             else _check_windows(shadows, tuple(limb_windows)))
        self.n_position_angle = check_int("n_position_angle", n_position_angle, low=2)
        self.shadows = nn.ModuleList(shadows)
        self.register_buffer("weights", weights)
        self.names = tuple(names)
        for name in _GEOMETRY:
            setattr(self, name, getattr(first, name))
        self.name = "mixture(" + ", ".join(self.names) + ")"
        #: no single atmosphere (the members hold theirs)
        self.atmosphere = None

    def relative_illuminance(self, distance_m, offset_m, wavelength_nm,
                             sun_distance_m=None, position_angle_rad=None) -> torch.Tensor:
        """Illuminance relative to the unobstructed Sun (shapes of :class:`Shadow`'s).

        Without ``position_angle_rad``: the weighted mean of the members' illuminance
        (the azimuthal mean), ``(..., n_wavelength)``. With it (needs ``limb_windows``), a
        1-D tensor of position angles around the axis [rad] (from the direction the
        windows count from): every point at each of them, ``(..., n_angle,
        n_wavelength)``, the direct sunlight plus, from each member, the light refracted
        through its window of the limb (one ring integral per point and member; only the
        weights along the solar arc differ between the angles).
        """
        if position_angle_rad is not None:
            if self.limb_windows is None:
                raise ValueError("position_angle_rad needs a mixture with limb_windows (the "
                                 "part of the limb of each member); this one has none")
            total = None
            for k, (shadow, window) in enumerate(zip(self.shadows, self.limb_windows,
                                                     strict=True)):
                part = shadow._relative_illuminance(
                    distance_m, offset_m, wavelength_nm, sun_distance_m,
                    position_angle_rad=position_angle_rad, limb_window=window,
                    direct_light=k == 0)
                total = part if total is None else total + part
            return total
        total = None
        for weight, shadow in zip(self.weights, self.shadows, strict=True):
            part = weight * shadow.relative_illuminance(distance_m, offset_m, wavelength_nm,
                                                        sun_distance_m)
            total = part if total is None else total + part
        return total

    forward = relative_illuminance

    def parameters_dict(self) -> dict:
        """Return the members' settings and weights (for Dataset attributes)."""
        resolved = ("none" if self.limb_windows is None
                    else [repr(window) for window in self.limb_windows])
        return {"shadow": self.name, "limb_windows": resolved,
                "n_position_angle": self.n_position_angle,
                "members": [{"name": name, "weight": float(weight),
                             **shadow.parameters_dict()}
                            for name, weight, shadow in zip(self.names, self.weights.tolist(),
                                                            self.shadows, strict=True)]}

    def extra_repr(self) -> str:
        """Member names and weights."""
        return ", ".join(f"{n}={w:.3f}" for n, w in zip(self.names, self.weights.tolist(),
                                                         strict=True))


def _check_members(shadows: list[Shadow]) -> None:
    """Refuse members of another geometry or limb darkening than the first."""
    first = shadows[0]
    for k, shadow in enumerate(shadows[1:], start=1):
        for name in _GEOMETRY:
            ours, theirs = getattr(first, name), getattr(shadow, name)
            if abs(theirs - ours) > 1e-9 * abs(ours):
                raise ValueError(f"shadows[{k}] has {name} {theirs}; shadows[0] has {ours}: "
                                 "members must share it")
        if (shadow.law != first.law
                or not torch.equal(shadow.limb_darkening, first.limb_darkening)):
            raise ValueError(f"shadows[{k}] has the limb darkening {shadow.law} "
                             f"{shadow.limb_darkening.tolist()}; shadows[0] has "
                             f"{first.law} {first.limb_darkening.tolist()}")


def _check_windows(shadows: list[Shadow], windows: tuple) -> tuple:
    """Refuse windows of another count or kind, and members a window cannot resolve."""
    if len(windows) != len(shadows) or not all(
            callable(getattr(w, "weight", None)) for w in windows):
        raise TypeError(f"limb_windows must be {len(shadows)} objects with a "
                        f"weight(position_angle_rad) method; got {windows!r}")
    for k, shadow in enumerate(shadows):
        if shadow.batch_shape or shadow.scattering:
            raise ValueError(f"shadows[{k}]: a mixture resolved in direction takes unbatched "
                             "members without scattering; got batch shape "
                             f"{shadow.batch_shape}, scattering={shadow.scattering}")
    return windows
