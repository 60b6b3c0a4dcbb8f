"""Molecular (Rayleigh) scattering and the refractive index of air, from first principles.

The Rayleigh scattering cross-section per molecule follows from the refractivity of the
gas, its number density and the King correction factor for depolarisation (ref. 1,
eq. 2). For air the refractivity is that of Peck & Reeder (ref. 2) corrected for the CO2
concentration (ref. 1, eq. 19) and the King factor is the weighted mean of those of N2,
O2, Ar and CO2 (ref. 1, eqs. 22-23, after Bates 1984). The vertical Rayleigh optical
depth follows from the column number density of a hydrostatic atmosphere,
:math:`N = p N_A / (m_a g)` (ref. 1, eq. 29).

Model keywords (``RAYLEIGH_GASES``): ``"air"`` (Earth) and ``"co2"`` (Mars).

References
----------
1. Bodhaine, B. A., Wood, N. B., Dutton, E. G. & Slusser, J. R. 1999, "On Rayleigh
   optical depth calculations", J. Atmos. Oceanic Technol. 16, 1854,
   doi:10.1175/1520-0426(1999)016<1854:ORODC>2.0.CO;2.
2. Peck, E. R. & Reeder, K. 1972, "Dispersion of air", J. Opt. Soc. Am. 62, 958,
   doi:10.1364/JOSA.62.000958.
3. Sneep, M. & Ubachs, W. 2005, "Direct measurement of the Rayleigh scattering cross
   section in various gases", JQSRT 92, 293, doi:10.1016/j.jqsrt.2004.07.025.
4. Schneegans, S. et al. 2025, "Physically Based Real-Time Rendering of Eclipses",
   Computer Graphics Forum (n - 1 = 2.77e-4 on Earth, 3.38e-6 on Mars at 610 Pa, 215 K).

Examples
--------
>>> import torch
>>> from skytorch.atmosphere.rayleigh import rayleigh_cross_section
>>> sigma = rayleigh_cross_section(torch.tensor([550.0]))
>>> round(float(sigma[0]) * 1e31, 2)   # [m^2], Bodhaine 1999 Table 3: 4.51e-31
4.51
"""

from __future__ import annotations

import math

import torch

from skytorch._validate import check_choice, check_positive, check_range
from skytorch.constants import (
    AVOGADRO_PER_MOL,
    BOLTZMANN_J_K,
    MARS_REFRACTIVITY_SURFACE,
    MARS_SURFACE_PRESSURE_PA,
    MARS_SURFACE_TEMPERATURE_K,
)

__all__ = [
    "RAYLEIGH_GASES",
    "WAVELENGTH_RANGE_NM",
    "STANDARD_AIR_NUMBER_DENSITY_M3",
    "air_king_factor",
    "air_molar_mass",
    "air_refractivity",
    "column_number_density",
    "rayleigh_cross_section",
    "refractivity_dispersion",
]

#: wavelengths covered by the Peck & Reeder (1972) dispersion formula [nm] (their
#: measurements span 230.2-1690.3 nm; the formula has poles at 87 and 159 nm)
WAVELENGTH_RANGE_NM = (230.0, 1690.0)


def _check_wavelength(wavelength_nm):
    """Wavelength [nm] as a floating tensor inside :data:`WAVELENGTH_RANGE_NM`."""
    low, high = WAVELENGTH_RANGE_NM
    return check_range("wavelength_nm", wavelength_nm, low, high, unit=" nm")


#: gases with a Rayleigh model
RAYLEIGH_GASES = ("air", "co2")

#: N_s: molecules per m^3 at 288.15 K and 1013.25 hPa (ref. 1, below eq. 2)
STANDARD_AIR_NUMBER_DENSITY_M3 = 2.546899e25
#: Bodhaine's standard CO2 concentration [parts per volume] (ref. 1)
DEFAULT_CO2_PPV = 360e-6
#: King factor of CO2 (ref. 1, Table 1; ref. 3 measures 1.14-1.15 in the visible)
CO2_KING_FACTOR = 1.15
#: molar mass of the Martian atmosphere (95.1 % CO2, 2.8 % N2, 2.1 % Ar; ref. 4) [kg/mol]
MARS_MOLAR_MASS_KG_MOL = 0.951 * 44.0095e-3 + 0.028 * 28.0134e-3 + 0.021 * 39.948e-3
#: wavelength at which the constant refractivities of ref. 4 are taken to apply [nm]
REFRACTIVITY_REFERENCE_WAVELENGTH_NM = 589.3


def air_refractivity(wavelength_nm, co2_ppv: float = DEFAULT_CO2_PPV) -> torch.Tensor:
    r"""Refractivity :math:`n_s - 1` of dry air at 288.15 K, 1013.25 hPa.

    Parameters
    ----------
    wavelength_nm : Tensor (...)
        Vacuum wavelength [nm].
    co2_ppv : float
        CO2 volume mixing ratio [1] (default 360e-6 as in ref. 1).

    Returns
    -------
    Tensor (...)
        :math:`n_s - 1` [1].

    Notes
    -----
    Ref. 2 (ref. 1 eq. 18), with :math:`\lambda` in micrometres:
    :math:`10^8 (n_{300} - 1) = 8060.51 + 2480990/(132.274 - \lambda^{-2})
    + 17455.7/(39.32957 - \lambda^{-2})`, and ref. 1 eq. 19:
    :math:`(n - 1) = (n_{300} - 1)[1 + 0.54 (C - 0.0003)]`.
    """
    lam = _check_wavelength(wavelength_nm) * 1e-3
    inv2 = lam ** -2
    n300 = 1e-8 * (8060.51 + 2480990.0 / (132.274 - inv2) + 17455.7 / (39.32957 - inv2))
    return n300 * (1.0 + 0.54 * (co2_ppv - 0.0003))


def refractivity_dispersion(wavelength_nm) -> torch.Tensor:
    r"""Spectral shape of refractivity relative to its value at 589.3 nm [1].

    Used to give a constant refractivity (ref. 4) a wavelength dependence:
    :math:`(n-1)(\lambda) = (n-1)_{589.3} \, f(\lambda)/f(589.3)` with :math:`f` the
    Peck–Reeder dispersion of air (an approximation for CO2).
    """
    reference = air_refractivity(torch.tensor(REFRACTIVITY_REFERENCE_WAVELENGTH_NM,
                                              dtype=torch.float64))
    return air_refractivity(wavelength_nm) / reference.item()


def air_king_factor(wavelength_nm, co2_ppv: float = DEFAULT_CO2_PPV) -> torch.Tensor:
    r"""King correction factor :math:`F_{air}(\lambda)` (ref. 1, eqs. 22-23).

    Notes
    -----
    :math:`F(N_2) = 1.034 + 3.17\times10^{-4}\lambda^{-2}`,
    :math:`F(O_2) = 1.096 + 1.385\times10^{-3}\lambda^{-2} + 1.448\times10^{-4}\lambda^{-4}`,
    :math:`F(Ar) = 1`, :math:`F(CO_2) = 1.15`, weighted by volume percentages
    78.084, 20.946, 0.934 and :math:`100\,C`.
    """
    lam = _check_wavelength(wavelength_nm) * 1e-3
    inv2 = lam ** -2
    f_n2 = 1.034 + 3.17e-4 * inv2
    f_o2 = 1.096 + 1.385e-3 * inv2 + 1.448e-4 * inv2 * inv2
    co2 = 100.0 * co2_ppv
    return (78.084 * f_n2 + 20.946 * f_o2 + 0.934 * 1.0 + co2 * CO2_KING_FACTOR) / (
        78.084 + 20.946 + 0.934 + co2
    )


def air_molar_mass(co2_ppv: float = DEFAULT_CO2_PPV) -> float:
    """Mean molar mass of dry air [kg/mol] (ref. 1, eq. 17)."""
    return (15.0556 * co2_ppv + 28.9595) * 1e-3


def _lorentz_lorenz_cross_section(wavelength_nm, refractivity, number_density_m3, king_factor):
    r""":math:`\sigma = 24\pi^3 (n^2-1)^2 / (\lambda^4 N^2 (n^2+2)^2) F_K` [m^2]."""
    lam_m = wavelength_nm * 1e-9
    n2 = (1.0 + refractivity) ** 2
    ratio = (n2 - 1.0) / (n2 + 2.0)
    return 24.0 * math.pi ** 3 * ratio * ratio / (lam_m ** 4 * number_density_m3 ** 2) * king_factor


def rayleigh_cross_section(wavelength_nm, gas: str = "air", *, co2_ppv: float = DEFAULT_CO2_PPV,
                           reference_refractivity: float | None = None,
                           reference_number_density_m3: float | None = None) -> torch.Tensor:
    r"""Rayleigh scattering cross-section per molecule [m^2].

    Parameters
    ----------
    wavelength_nm : Tensor (wavelength,)
        Vacuum wavelength [nm] (any shape).
    gas : {"air", "co2"}
        ``"air"``: Peck–Reeder refractivity and Bates King factor (ref. 1).
        ``"co2"``: refractivity ``reference_refractivity`` (default 3.38e-6, ref. 4) at
        ``reference_number_density_m3`` (default 610 Pa, 215 K), dispersion of air,
        King factor 1.15 (refs. 1, 3).
    co2_ppv : float
        CO2 mixing ratio for ``"air"`` [1].
    reference_refractivity, reference_number_density_m3 : float, optional
        Refractivity and the number density [m^-3] at which it holds (``"co2"``).

    Returns
    -------
    Tensor (...)
        Cross-section [m^2], same shape as ``wavelength_nm``.

    Notes
    -----
    :math:`\sigma(\lambda) = \frac{24\pi^3 (n^2-1)^2}{\lambda^4 N^2 (n^2+2)^2} F_K(\lambda)`
    (ref. 1, eq. 2), independent of the density at which :math:`n` and :math:`N` are
    taken as long as :math:`n - 1 \propto N`.
    """
    check_choice("gas", gas, RAYLEIGH_GASES)
    check_range("co2_ppv", co2_ppv, 0.0, 1.0)
    wavelength_nm = _check_wavelength(wavelength_nm)
    dtype = wavelength_nm.dtype
    # lambda^4 N^2 overflows float32: evaluate in float64 and cast back
    wavelength_nm = wavelength_nm.to(torch.float64)
    if gas == "air":
        return _lorentz_lorenz_cross_section(
            wavelength_nm, air_refractivity(wavelength_nm, co2_ppv),
            STANDARD_AIR_NUMBER_DENSITY_M3, air_king_factor(wavelength_nm, co2_ppv)).to(dtype)
    refractivity = MARS_REFRACTIVITY_SURFACE if reference_refractivity is None \
        else reference_refractivity
    density = (MARS_SURFACE_PRESSURE_PA / (BOLTZMANN_J_K * MARS_SURFACE_TEMPERATURE_K)
               if reference_number_density_m3 is None else reference_number_density_m3)
    return _lorentz_lorenz_cross_section(
        wavelength_nm, refractivity * refractivity_dispersion(wavelength_nm), density,
        CO2_KING_FACTOR).to(dtype)


def column_number_density(pressure_pa, gravity_m_s2, molar_mass_kg_mol) -> torch.Tensor:
    """Vertical column of molecules of a hydrostatic atmosphere [m^-2].

    :math:`N_{col} = p N_A / (m_a g)` (ref. 1, eq. 29 with :math:`A = N_A`).
    """
    pressure = check_positive("pressure_pa", pressure_pa, allow_zero=True, unit=" Pa")
    gravity = check_positive("gravity_m_s2", gravity_m_s2, unit=" m s^-2")
    molar_mass = check_positive("molar_mass_kg_mol", molar_mass_kg_mol, unit=" kg/mol")
    return pressure * AVOGADRO_PER_MOL / (molar_mass * gravity)
