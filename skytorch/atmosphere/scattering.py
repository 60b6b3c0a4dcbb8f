"""Phase functions and single-scattering sky radiance.

Phase functions are normalised over the sphere, :math:`\\int P\\,d\\Omega = 1` [1/sr].

References
----------
1. Chandrasekhar, S. 1950, *Radiative Transfer*, Oxford (Rayleigh phase function).
2. Henyey, L. G. & Greenstein, J. L. 1941, "Diffuse radiation in the Galaxy",
   ApJ 93, 70, doi:10.1086/144246.
3. Cornette, W. M. & Shanks, J. G. 1992, "Physically reasonable analytic expression for
   the single-scattering phase function", Appl. Opt. 31, 3152,
   doi:10.1364/AO.31.003152.
4. Bruneton, E. & Neyret, F. 2008, "Precomputed Atmospheric Scattering", Computer
   Graphics Forum 27, 1079, doi:10.1111/j.1467-8659.2008.01245.x.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere.scattering import rayleigh_phase
>>> round(float(rayleigh_phase(torch.tensor(1.0))) * 4 * 3.141592653589793, 3)
1.5
"""

from __future__ import annotations

import math

import torch

from skytorch._validate import as_tensor, check_choice

__all__ = [
    "PHASE_FUNCTIONS",
    "cornette_shanks",
    "henyey_greenstein",
    "phase_function",
    "rayleigh_phase",
]

#: aerosol phase-function models
PHASE_FUNCTIONS = ("cornetteshanks1992", "henyeygreenstein1941")


def rayleigh_phase(cos_theta) -> torch.Tensor:
    """Rayleigh phase function :math:`\\frac{3}{16\\pi}(1 + \\cos^2\\theta)` [1/sr] (ref. 1).

    Parameters
    ----------
    cos_theta : Tensor (...)
        Cosine of the scattering angle [1].
    """
    cos_theta = as_tensor("cos_theta", cos_theta)
    return 3.0 / (16.0 * math.pi) * (1.0 + cos_theta * cos_theta)


def henyey_greenstein(cos_theta, g) -> torch.Tensor:
    """Henyey–Greenstein phase function [1/sr] (ref. 2).

    :math:`P = \\frac{1}{4\\pi}\\frac{1 - g^2}{(1 + g^2 - 2 g \\cos\\theta)^{3/2}}`.

    Parameters
    ----------
    cos_theta : Tensor (...)
        Cosine of the scattering angle [1].
    g : float or Tensor (...)
        Asymmetry parameter, -1 < g < 1 [1].
    """
    cos_theta = as_tensor("cos_theta", cos_theta)
    g = torch.as_tensor(g, dtype=cos_theta.dtype)
    return (1.0 - g * g) / (4.0 * math.pi * (1.0 + g * g - 2.0 * g * cos_theta) ** 1.5)


def cornette_shanks(cos_theta, g) -> torch.Tensor:
    """Cornette–Shanks phase function [1/sr] (ref. 3, as used in ref. 4).

    :math:`P = \\frac{3}{8\\pi}\\frac{(1 - g^2)(1 + \\cos^2\\theta)}
    {(2 + g^2)(1 + g^2 - 2 g\\cos\\theta)^{3/2}}`.
    """
    cos_theta = as_tensor("cos_theta", cos_theta)
    g = torch.as_tensor(g, dtype=cos_theta.dtype)
    return (3.0 / (8.0 * math.pi) * (1.0 - g * g) * (1.0 + cos_theta * cos_theta)
            / ((2.0 + g * g) * (1.0 + g * g - 2.0 * g * cos_theta) ** 1.5))


def phase_function(cos_theta, g, model: str = "cornetteshanks1992") -> torch.Tensor:
    """Aerosol phase function by model keyword (``PHASE_FUNCTIONS``) [1/sr]."""
    check_choice("model", model, PHASE_FUNCTIONS)
    if model == "cornetteshanks1992":
        return cornette_shanks(cos_theta, g)
    return henyey_greenstein(cos_theta, g)
