"""Aerosol optical properties: Ångström law, Preetham turbidity, Mars dust.

The aerosol optical depth follows the Ångström law
:math:`\\tau_a(\\lambda) = \\beta (\\lambda / 1\\,\\mu m)^{-\\alpha}` (ref. 1). From
Preetham's turbidity :math:`T` (ref. 2): :math:`\\beta = 0.04608 T - 0.04586`,
:math:`\\alpha = 1.3`; :math:`T = 1` is (nearly) aerosol-free (:math:`\\beta = 2.2\\times
10^{-4}`, :math:`\\tau_a(550) = 5\\times10^{-4}`); :math:`\\beta` is clamped at zero.

References
----------
1. Ångström, A. 1929, "On the atmospheric transmission of sun radiation and on dust in
   the air", Geogr. Ann. 11, 156, doi:10.1080/20014422.1929.11880498.
2. Preetham, A. J., Shirley, P. & Smits, B. 1999, "A practical analytic model for
   daylight", Proc. SIGGRAPH 99, 91, doi:10.1145/311535.311545.
3. Lemmon, M. T. et al. 2015, "Dust aerosol, clouds, and the atmospheric optical depth
   record over 5 Mars years of the Mars Exploration Rover mission", Icarus 251, 96,
   doi:10.1016/j.icarus.2014.03.029.
4. Tomasko, M. G. et al. 1999, "Properties of dust in the Martian atmosphere from the
   Imager on Mars Pathfinder", J. Geophys. Res. 104, 8987, doi:10.1029/1998JE900016.

Examples
--------
>>> from skytorch.atmosphere.aerosol import preetham_angstrom_beta
>>> round(float(preetham_angstrom_beta(2.0)), 5)
0.0463
"""

from __future__ import annotations

import torch

from skytorch._validate import as_tensor

__all__ = [
    "MARS_DUST",
    "PREETHAM_ANGSTROM_ALPHA",
    "angstrom_optical_depth",
    "preetham_angstrom_beta",
]

#: Ångström exponent of Preetham's turbidity model (ref. 2)
PREETHAM_ANGSTROM_ALPHA = 1.3
#: reference wavelength of the Ångström law [nm]
ANGSTROM_REFERENCE_NM = 1000.0

#: background Martian dust: optical depth 0.5 at 880 nm (ref. 3, non-dusty season
#: typical), nearly grey in the visible (alpha ~ 0), single-scattering albedo 0.93 and
#: Henyey-Greenstein asymmetry 0.63 (ref. 4), mixed with the gas (scale height 11.1 km).
MARS_DUST = {
    "optical_depth": 0.5,
    "reference_wavelength_nm": 880.0,
    "angstrom_alpha": 0.0,
    "single_scattering_albedo": 0.93,
    "asymmetry": 0.63,
    "scale_height_m": 11_100.0,
}


def preetham_angstrom_beta(turbidity) -> torch.Tensor:
    """Ångström :math:`\\beta` from Preetham's turbidity, :math:`0.04608 T - 0.04586`.

    Parameters
    ----------
    turbidity : Tensor (...)
        Turbidity :math:`T \\ge 1` [1].

    Returns
    -------
    Tensor (...)
        :math:`\\beta` [1], clamped at 0.
    """
    turbidity = as_tensor("turbidity", turbidity)
    return torch.clamp(0.04608 * turbidity - 0.04586, min=0.0)


def angstrom_optical_depth(wavelength_nm, beta, alpha) -> torch.Tensor:
    """Vertical aerosol optical depth :math:`\\beta (\\lambda/1\\,\\mu m)^{-\\alpha}`.

    Parameters
    ----------
    wavelength_nm : Tensor (wavelength,)
        Wavelength [nm].
    beta, alpha : Tensor (...)
        Ångström turbidity coefficient and exponent [1].

    Returns
    -------
    Tensor (..., wavelength)
        Vertical optical depth [1].
    """
    wavelength_nm = as_tensor("wavelength_nm", wavelength_nm)
    beta = torch.as_tensor(beta, dtype=wavelength_nm.dtype)
    alpha = torch.as_tensor(alpha, dtype=wavelength_nm.dtype)
    return beta[..., None] * (wavelength_nm / ANGSTROM_REFERENCE_NM) ** (-alpha[..., None])
