"""The natural night sky: zodiacal light, airglow and the integrated light of stars.

* :mod:`~skytorch.nightsky.zodiacal` — Leinert et al. 1998 Table 17 and its colour;
* :mod:`~skytorch.nightsky.airglow` — van Rhijn layer, zenith level and solar cycle;
* :mod:`~skytorch.nightsky.starlight` — Gaia catalogue stars fainter than a limit, as a
  surface-brightness map (the Milky Way of the catalogue);
* :mod:`~skytorch.nightsky.faint_starlight` — the Pioneer 10/11 starlight (Leinert et al.
  1998 Table 35) fainter than the catalogue;
* :mod:`~skytorch.nightsky.scattered_light` — light of a source above the air (the
  airglow layer) scattered once into the line of sight.

The per-direction sum for a scene is :func:`skytorch.scene.natural_sky.natural_component`.
"""

from skytorch.nightsky.airglow import (
    AIRGLOW_HEIGHT_M,
    AIRGLOW_ZENITH_V_130SFU,
    airglow_solar_factor,
    airglow_zenith_mag,
    layer_path_factor,
    van_rhijn,
)
from skytorch.nightsky.faint_starlight import (
    faint_starlight_table,
    faint_starlight_v_radiance,
)
from skytorch.nightsky.scattered_light import scattered_diffuse_radiance
from skytorch.nightsky.starlight import (
    catalogue_starlight_map,
    galactic_coordinates,
    starlight_v_radiance,
)
from skytorch.nightsky.zodiacal import (
    S10_W_M2_SR_NM,
    zodiacal_brightness_500,
    zodiacal_colour,
    zodiacal_spectral_radiance,
)

__all__ = [
    "AIRGLOW_HEIGHT_M",
    "AIRGLOW_ZENITH_V_130SFU",
    "S10_W_M2_SR_NM",
    "airglow_solar_factor",
    "airglow_zenith_mag",
    "catalogue_starlight_map",
    "faint_starlight_table",
    "faint_starlight_v_radiance",
    "galactic_coordinates",
    "layer_path_factor",
    "scattered_diffuse_radiance",
    "starlight_v_radiance",
    "van_rhijn",
    "zodiacal_brightness_500",
    "zodiacal_colour",
    "zodiacal_spectral_radiance",
]
