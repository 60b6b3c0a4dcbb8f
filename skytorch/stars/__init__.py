"""Stars: catalogue, apparent positions, photometry, scintillation and visibility.

* :func:`bright_stars` — the Hipparcos 2 catalogue to a V limit (J2000.0, Johnson V);
  :func:`read_bsc5` — a Yale Bright Star Catalogue file; :func:`gaia_stars` — Gaia DR3 to
  G = 10 (482 176 entries) in Johnson V;
* :func:`observe` — apparent altitude/azimuth, magnitude after extinction, air mass,
  colour, relative brightness, scintillation index and visibility over ``(time, star)``;
* tensor functions in :mod:`~skytorch.stars.positions`, :mod:`~skytorch.stars.photometry`,
  :mod:`~skytorch.stars.scintillation` and :mod:`~skytorch.stars.visibility`;
* :func:`~skytorch.stars.chart.all_sky_chart` — an all-sky chart of an observation;
* :func:`planets` — apparent places, phases and V magnitudes of the planets
  (:mod:`~skytorch.stars.planets`).
"""

from skytorch.stars.catalog import (
    bright_stars,
    hipparcos_to_johnson_v,
    propagate_space_motion,
    read_bsc5,
)
from skytorch.stars.gaia import gaia_g_to_johnson_v, gaia_stars
from skytorch.stars.observation import observe, observe_tensors, refract, refraction_table
from skytorch.stars.photometry import (
    apparent_color,
    apparent_color_table,
    bv_to_srgb,
    extinction,
    extinction_coefficient,
    extinction_table,
    relative_brightness,
)
from skytorch.stars.planets import planet_magnitude, planets
from skytorch.stars.positions import (
    apparent_altaz,
    horizontal_vectors,
    star_vectors,
    time_operators,
)
from skytorch.stars.scintillation import scintillation_index, twinkle
from skytorch.stars.visibility import (
    count_visible,
    limiting_magnitude,
    mag_arcsec2_to_nanolambert,
    muller_day_night_factor,
)

__all__ = [
    "apparent_altaz",
    "apparent_color",
    "apparent_color_table",
    "bright_stars",
    "bv_to_srgb",
    "count_visible",
    "extinction",
    "extinction_coefficient",
    "extinction_table",
    "gaia_g_to_johnson_v",
    "gaia_stars",
    "hipparcos_to_johnson_v",
    "horizontal_vectors",
    "limiting_magnitude",
    "mag_arcsec2_to_nanolambert",
    "muller_day_night_factor",
    "observe",
    "observe_tensors",
    "planet_magnitude",
    "planets",
    "propagate_space_motion",
    "read_bsc5",
    "refract",
    "refraction_table",
    "relative_brightness",
    "scintillation_index",
    "star_vectors",
    "time_operators",
    "twinkle",
]
