"""Eclipses: occlusion of the Sun, shadow cones, lunar-eclipse circumstances.

Public names are collected from the submodules below; each submodule adds its names with
one ``from ... import`` line and one entry in ``__all__``.

Differentiability: :func:`sun_visible_fraction` carries exact gradients with respect to
its geometry and limb darkening (at tangency and containment too);
:meth:`Shadow.relative_illuminance` carries gradients with respect to the points'
geometry and to the atmosphere's extinction parameters (turbidity, ozone, ...: the
optical depths of the ring keep their graph; the bending places the quadrature nodes and
carries none); :class:`ShadowTable` and the lunar-eclipse light curves built on it keep
that graph (so :func:`retrieve_atmosphere` fits the atmosphere to observed eclipses). The
scattered light (``scattering=True``) is tabulated without gradients: it raises
``ValueError`` for an atmosphere whose parameters require a gradient rather than detach
them.

Examples
--------
>>> import torch
>>> from skytorch.eclipse import sun_visible_fraction
>>> separation = torch.tensor(2.0e-3, dtype=torch.float64, requires_grad=True)
>>> fraction = sun_visible_fraction(4.65e-3, 2.5e-3, separation)
>>> fraction.backward()
>>> round(fraction.item(), 4), round(separation.grad.item(), 1)
(0.6817, 30.7)
"""

from skytorch.eclipse.circumstances import lunar_eclipses  # noqa: F401
from skytorch.eclipse.cone import ENLARGEMENTS, shadow_cone, shadow_radii  # noqa: F401
from skytorch.eclipse.danjon import danjon_class_l, danjon_l_linear  # noqa: F401
from skytorch.eclipse.eclipse_atmosphere import (  # noqa: F401
    cloud_climatology,
    eclipse_atmosphere,
    eclipse_shadow,
    stratospheric_aod,
    stratospheric_model,
    terminator_bands,
)
from skytorch.eclipse.observed import observed_lunar_eclipses  # noqa: F401
from skytorch.eclipse.occlusion import (  # noqa: F401
    LIMB_DARKENING_LAWS,
    limb_darkening_profile,
    sun_visible_fraction,
)
from skytorch.eclipse.retrieval import retrieval_shadow, retrieve_atmosphere  # noqa: F401
from skytorch.eclipse.shadow import LimbCloudCover  # noqa: F401
from skytorch.eclipse.shadow_mixture import ShadowMixture  # noqa: F401
from skytorch.eclipse.solar import solar_eclipses  # noqa: F401
from skytorch.eclipse.solar_local import solar_eclipse_local  # noqa: F401
from skytorch.eclipse.solar_path import obscuration_map, solar_eclipse_path  # noqa: F401

__all__ = [
    "ENLARGEMENTS",
    "LIMB_DARKENING_LAWS",
    "LimbCloudCover",
    "Shadow",
    "ShadowMixture",
    "ShadowTable",
    "cloud_climatology",
    "danjon_class_l",
    "danjon_l",
    "danjon_l_linear",
    "eclipse_atmosphere",
    "eclipse_shadow",
    "lunar_eclipse",
    "lunar_light_curve",
    "limb_darkening_profile",
    "lunar_eclipses",
    "observed_lunar_eclipses",
    "obscuration_map",
    "retrieval_shadow",
    "retrieve_atmosphere",
    "shadow_cone",
    "shadow_radii",
    "solar_eclipse_local",
    "solar_eclipse_path",
    "solar_eclipses",
    "stratospheric_aod",
    "stratospheric_model",
    "sun_visible_fraction",
    "terminator_bands",
]
from skytorch.eclipse.lunar import (  # noqa: E402,F401,I001
    Shadow, ShadowTable, danjon_l, lunar_eclipse, lunar_light_curve)
