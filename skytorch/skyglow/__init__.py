"""Artificial skyglow from city lights (Dobashi, Ishikawa & Iwasaki 2023).

Single-scattering kernel of one ground source (:mod:`.kernel`), PCA basis
(:mod:`.basis`), the precomputed model with azimuthal FFT convolution (:mod:`.model`),
the naive reference (:mod:`.naive`), inverse tools (:mod:`.inverse`), astronomers' units
(:mod:`.units`), lamp spectra (:mod:`.lamps`) and synthetic city maps (:mod:`.citymap`).
See ``docs/skyglow.md``.
"""

from skytorch.skyglow import lamps, units
from skytorch.skyglow.citymap import point_sources, synthetic_city
from skytorch.skyglow.inverse import (
    apply_reduction,
    minimal_reduction,
    pollution_influence,
    reduction_factors,
    sky_region,
    skyglow_influence,
)
from skytorch.skyglow.kernel import EMISSION_FUNCTIONS, Medium, emission_intensity, kernel_radiance
from skytorch.skyglow.model import SkyglowModel, SplatPlan, light_map_arrays
from skytorch.skyglow.naive import render_naive

__all__ = [
    "EMISSION_FUNCTIONS",
    "Medium",
    "SkyglowModel",
    "SplatPlan",
    "apply_reduction",
    "emission_intensity",
    "kernel_radiance",
    "lamps",
    "light_map_arrays",
    "minimal_reduction",
    "point_sources",
    "pollution_influence",
    "reduction_factors",
    "render_naive",
    "sky_region",
    "skyglow_influence",
    "synthetic_city",
    "units",
]
