"""Planetary atmospheres: constituents, ray geometry, optical depth, scattering, tables.

Submodules
----------
profiles
    Vertical density profiles (exponential, U.S. Standard Atmosphere 1976, ozone tent).
rayleigh, aerosol, ozone
    Spectral cross-sections and coefficients of the three constituents.
geometry
    Ray–sphere intersections stable near the horizon and on boundaries.
optical_depth
    Path integrals of density profiles (Gauss–Legendre, trapezoid, adaptive), the
    Chapman function, the Kasten–Young air mass.
scattering
    Phase functions and single-scattering sky radiance.
tables
    Transmittance look-up table (Bruneton parametrisation) with a disk cache.
model
    :class:`Atmosphere`, the ``torch.nn.Module`` tying them together.
refraction
    Refracted rays (imported on use: ``from skytorch.atmosphere import refraction``).

Examples
--------
>>> import torch
>>> from skytorch.atmosphere import Atmosphere
>>> atm = Atmosphere.earth(turbidity=2.0, ozone_du=300.0)
>>> bool(atm.transmittance(torch.tensor([550.0]), zenith_rad=0.5)[0] < 1.0)
True
"""

from __future__ import annotations

from skytorch.atmosphere.model import SPECIES, Atmosphere

__all__ = ["SPECIES", "Atmosphere"]
