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

from skytorch._validate import as_tensor, check_range
from skytorch.eclipse.shadow import Shadow

__all__ = ["ShadowMixture"]

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

    Raises
    ------
    TypeError
        A member is not a :class:`Shadow`, or a name not a string.
    ValueError
        No member, weights of another count, negative or not summing to 1, or members of
        another geometry.
    """

    def __init__(self, shadows: Sequence[Shadow], weights, names: Sequence[str] | None = None):
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
        self.shadows = nn.ModuleList(shadows)
        self.register_buffer("weights", weights)
        self.names = tuple(names)
        for name in _GEOMETRY:
            setattr(self, name, getattr(first, name))
        self.name = "mixture(" + ", ".join(self.names) + ")"
        #: no single atmosphere (the members hold theirs)
        self.atmosphere = None

    def relative_illuminance(self, distance_m, offset_m, wavelength_nm,
                             sun_distance_m=None) -> torch.Tensor:
        """Weighted mean of the members' :meth:`Shadow.relative_illuminance` (same shapes)."""
        total = None
        for weight, shadow in zip(self.weights, self.shadows, strict=True):
            part = weight * shadow.relative_illuminance(distance_m, offset_m, wavelength_nm,
                                                        sun_distance_m)
            total = part if total is None else total + part
        return total

    forward = relative_illuminance

    def parameters_dict(self) -> dict:
        """Return the members' settings and weights (for Dataset attributes)."""
        return {"shadow": self.name,
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
