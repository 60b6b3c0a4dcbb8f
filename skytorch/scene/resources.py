"""Physical resources shared by the scenes with the same parameters.

The scene's atmosphere and the star-site tables (refraction and extinction at the
observer) are built once per set of physical parameters and reused by the planner, the
renderer and :class:`~skytorch.scene.Scene`; they sit here, below all three, so that
none of them imports another to reach them.

The physics packages (:mod:`skytorch.atmosphere`, :mod:`skytorch.stars`) are imported
when a resource is first built, not when :mod:`skytorch.scene` is imported.
"""

from __future__ import annotations

import math
from functools import lru_cache

import torch

__all__ = ["cached_atmosphere", "refracted_altitude"]


@lru_cache(maxsize=8)
def cached_atmosphere(turbidity: float, ozone_du: float):
    """``Atmosphere.earth(turbidity, ozone_du)``, shared by scenes with those parameters."""
    from skytorch.atmosphere import Atmosphere

    return Atmosphere.earth(turbidity=turbidity, ozone_du=ozone_du)


@lru_cache(maxsize=8)
def _star_site_tables(turbidity: float, ozone_du: float, elevation_m: float,
                      refraction: bool):
    from skytorch.stars import extinction_table, refraction_table

    atm = cached_atmosphere(turbidity, ozone_du)
    return (refraction_table(atm, elevation_m) if refraction else None,
            extinction_table(atm, elevation_m, refraction=refraction))


def refracted_altitude(scene, true_altitude_rad: float) -> float:
    """Apparent altitude [rad] from a cached refraction table of the scene's site
    (:func:`skytorch.stars.refraction_table`, ray-traced refraction of the atmosphere)."""
    from skytorch.stars import refract

    table, _ = _star_site_tables(float(scene.turbidity), float(scene.ozone_du),
                                 float(scene.elevation_m), True)
    true = torch.tensor([max(true_altitude_rad, math.radians(-1.0))], dtype=torch.float64)
    return float(refract(true, table)[0])
