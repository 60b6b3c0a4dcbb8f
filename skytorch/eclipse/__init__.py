"""Eclipses: occlusion of the Sun, shadow cones, lunar-eclipse circumstances.

Public names are collected from the submodules below; each submodule adds its names with
one ``from ... import`` line and one entry in ``__all__``.
"""

from skytorch.eclipse.circumstances import lunar_eclipses  # noqa: F401
from skytorch.eclipse.cone import ENLARGEMENTS, shadow_cone, shadow_radii  # noqa: F401
from skytorch.eclipse.occlusion import (  # noqa: F401
    LIMB_DARKENING_LAWS,
    limb_darkening_profile,
    sun_visible_fraction,
)

__all__ = [
    "ENLARGEMENTS",
    "LIMB_DARKENING_LAWS",
    "Shadow",
    "ShadowTable",
    "danjon_l",
    "lunar_eclipse",
    "lunar_light_curve",
    "limb_darkening_profile",
    "lunar_eclipses",
    "shadow_cone",
    "shadow_radii",
    "sun_visible_fraction",
    "volcanic_atmosphere",
]
from skytorch.eclipse.lunar import (  # noqa: E402,F401,I001
    Shadow, ShadowTable, danjon_l, lunar_eclipse, lunar_light_curve, volcanic_atmosphere)
