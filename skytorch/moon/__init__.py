"""The Moon: geometry, reflectance, disc images, magnitude, earthshine, moonlit sky.

Tensor functions (batched, differentiable, dtype following the inputs):

* :mod:`~skytorch.moon.geometry` — phase angle, illuminated fraction, bright-limb position
  angle, optical libration, parallactic angle, apparent diameter (Meeus 1998).
* :mod:`~skytorch.moon.reflectance` — Hapke (2012) and Lommel–Seeliger reflectance with
  published lunar parameters; the reddish albedo spectrum (Müller et al. 2012). The
  module is callable as its function: ``skytorch.moon.reflectance(mu0, mu, g)``.
* :mod:`~skytorch.moon.disc` — sample points on the visible disc, exact quadrature of the
  sunlit part, radiance images (reused by the eclipse light curve).
* :mod:`~skytorch.moon.brightness` — disc-integrated irradiance and V magnitude from
  first principles; the observed phase curves of Krisciunas & Schaefer (1991) and ROLO
  (Kieffer & Stone 2005) for validation.
* :mod:`~skytorch.moon.earthshine` — Müller's eq. 4 and a physical earthshine model.
* :mod:`~skytorch.moon.sky` — moonlit sky brightness: Krisciunas & Schaefer (1991) and
  single scattering through :class:`skytorch.atmosphere.Atmosphere`.

Module: :class:`MoonPhotometry` (reflectance law and parameters fixed, reference magnitude
as a buffer). Dataset builders: :func:`moon_geometry` (over time, from the ephemeris),
:func:`moon_disc_image` and :func:`moon_disc_images`.

Examples
--------
>>> import math, torch
>>> import skytorch as st
>>> m = st.moon.magnitude(torch.tensor(math.radians(90.0)))  # quarter Moon
>>> -10.3 < float(m) < -9.7
True
"""

from __future__ import annotations

# the submodule, callable as its function ``reflectance(mu0, mu, phase_angle_rad, ...)``
# (skytorch._modules), so that neither hides the other
from skytorch.moon import reflectance
from skytorch.moon.brightness import (
    disc_integrated_reflectance,
    disc_reflectance_rolo2005,
    geometric_albedo,
    lunar_irradiance,
    magnitude,
    magnitude_ks1991,
)
from skytorch.moon.datasets import moon_disc_image, moon_disc_images, moon_geometry
from skytorch.moon.disc import (
    dark_disc_quadrature,
    disc_grid,
    disc_image,
    disc_radiance,
    disc_reflectance,
    integrate_disc,
    lit_disc_quadrature,
    sun_direction,
)
from skytorch.moon.earthshine import (
    earthshine_irradiance_ratio,
    earthshine_muller2012,
    lambert_phase_function,
)
from skytorch.moon.geometry import (
    apparent_diameter,
    axis_position_angle,
    bright_limb_position_angle,
    illuminated_fraction,
    libration,
    optical_libration,
    orientation_matrix,
    parallactic_angle,
    phase_angle,
    phase_angle_from_radec,
    physical_libration,
    physical_libration_angles,
)
from skytorch.moon.module import MoonPhotometry
from skytorch.moon.reflectance import (
    HAPKE_PARAMETERS,
    REFLECTANCE_MODELS,
    albedo,
    lommel_seeliger,
)
from skytorch.moon.sky import (
    moonlit_sky_ks1991,
    moonlit_sky_single_scattering,
    nanolambert_to_mag_arcsec2,
    radiance_to_mag_arcsec2,
)

__all__ = [
    "HAPKE_PARAMETERS",
    "MoonPhotometry",
    "REFLECTANCE_MODELS",
    "albedo",
    "apparent_diameter",
    "axis_position_angle",
    "bright_limb_position_angle",
    "dark_disc_quadrature",
    "disc_grid",
    "disc_image",
    "disc_integrated_reflectance",
    "disc_radiance",
    "disc_reflectance_rolo2005",
    "disc_reflectance",
    "earthshine_irradiance_ratio",
    "earthshine_muller2012",
    "geometric_albedo",
    "illuminated_fraction",
    "integrate_disc",
    "lambert_phase_function",
    "libration",
    "lit_disc_quadrature",
    "lommel_seeliger",
    "lunar_irradiance",
    "magnitude",
    "magnitude_ks1991",
    "moon_disc_image",
    "moon_disc_images",
    "moon_geometry",
    "moonlit_sky_ks1991",
    "moonlit_sky_single_scattering",
    "nanolambert_to_mag_arcsec2",
    "optical_libration",
    "orientation_matrix",
    "parallactic_angle",
    "phase_angle",
    "phase_angle_from_radec",
    "physical_libration",
    "physical_libration_angles",
    "radiance_to_mag_arcsec2",
    "reflectance",
    "sun_direction",
]
