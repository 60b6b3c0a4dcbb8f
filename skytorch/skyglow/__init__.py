"""Artificial skyglow from city lights (Dobashi, Ishikawa & Iwasaki 2023).

Single-scattering kernel of one ground source (:mod:`.kernel`), PCA basis
(:mod:`.basis`), the precomputed model with azimuthal FFT convolution (:mod:`.model`),
the naive reference (:mod:`.naive`), inverse tools (:mod:`.inverse`), astronomers' units
(:mod:`.units`), lamp spectra (:mod:`.lamps`) and synthetic city maps (:mod:`.citymap`).
"""

from skytorch.skyglow.kernel import EMISSION_FUNCTIONS, Medium, emission_intensity, kernel_radiance
from skytorch.skyglow.model import SkyglowModel
from skytorch.skyglow.naive import render_naive

__all__ = [
    "EMISSION_FUNCTIONS",
    "Medium",
    "SkyglowModel",
    "emission_intensity",
    "kernel_radiance",
    "render_naive",
]
