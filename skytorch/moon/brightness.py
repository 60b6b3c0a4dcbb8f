"""Disc-integrated brightness of the Moon: irradiance at the Earth and V magnitude.

The magnitude is computed from first principles, not fitted to observations: the
reflectance law (:mod:`skytorch.moon.reflectance`) is integrated over the sunlit disc,
scaled by the solar spectral irradiance at 1 AU (:func:`skytorch.spectrum.solar_irradiance`),
the inverse-square laws with the lunar radius and distances, and converted to a Johnson V
magnitude with the V passband and zero point of :func:`skytorch.spectrum.spectrum_to_magnitude`.
The observed phase curve of Krisciunas & Schaefer (1991, eq. 9) is provided
(:func:`magnitude_ks1991`) only to validate it.

Notes
-----
Spectral irradiance at the top of the Earth's atmosphere::

    E_moon(λ) = E_sun(λ) (1 AU / d_S)² (R_M / d)² a(λ) [Q_sun(α) + ε(α) Q_earth(α)]

    Q_sun(α)   = ∫∫_lit  r(μ0, μ, α) dx dy                 (unit disc, r in 1/sr)
    Q_earth(α) = ∫∫_dark r(μ, μ, g_E) dx dy                 (earthshine, g_E = asin(R_E/d))

with d_S the Moon–Sun and d the Earth–Moon distance, R_M the lunar radius, a(λ) the
relative albedo spectrum and ε(α) the earthshine irradiance ratio
(:func:`skytorch.moon.earthshine.earthshine_irradiance_ratio`). Q_sun(0) is the geometric
albedo at 550 nm. Both integrals use the photometric-coordinate Gauss–Legendre quadrature
of :func:`skytorch.moon.disc.lit_disc_quadrature` (spectral convergence: 48 × 48 nodes
reach 1e-6 mag).

References
----------
1. Krisciunas, K., Schaefer, B. E. 1991, "A model of the brightness of moonlight",
   PASP 103, 1033, doi:10.1086/132921, eq. 9.
2. Hapke, B. 2012, *Theory of Reflectance and Emittance Spectroscopy*, 2nd ed., Cambridge
   University Press, doi:10.1017/CBO9781139025683, ch. 11 (integrated brightness).
3. Bessell, M. S. 1990, "UBVRI passbands", PASP 102, 1181, doi:10.1086/132749.
4. Kieffer, H. H., Stone, T. C. 2005, "The spectral irradiance of the Moon", AJ 129, 2887,
   doi:10.1086/430185 (ROLO, eq. 10 and Table 4; reference only).

Examples
--------
>>> import torch
>>> from skytorch.moon.brightness import magnitude_ks1991
>>> round(float(magnitude_ks1991(torch.tensor(0.0))), 2)
-12.73
"""

from __future__ import annotations

import math
from types import MappingProxyType

import torch

from skytorch._validate import (
    as_tensor,
    check_broadcastable,
    check_int,
    check_range,
    common_dtype,
)
from skytorch.constants import (
    ASTRONOMICAL_UNIT_M,
    DEGREE,
    MEAN_EARTH_MOON_DISTANCE_M,
    MOON_RADIUS_M,
)
from skytorch.moon.disc import _flag, dark_disc_quadrature, lit_disc_quadrature
from skytorch.moon.earthshine import earth_angular_radius, earthshine_irradiance_ratio
from skytorch.moon.reflectance import albedo, reflectance

__all__ = [
    "ROLO2005_553NM",
    "V_BAND_WAVELENGTHS_NM",
    "disc_integrated_reflectance",
    "disc_reflectance_rolo2005",
    "geometric_albedo",
    "lunar_irradiance",
    "magnitude",
    "magnitude_ks1991",
]

#: wavelength grid covering the Bessell (1990) V passband (470–700 nm), 5 nm steps [nm]
V_BAND_WAVELENGTHS_NM = tuple(float(w) for w in range(470, 705, 5))

#: Kieffer & Stone (2005), ROLO eq. 10, Table 4 row of the 553.8 nm band: a0..a3 (phase
#: polynomial, g in rad), d1..d3 (opposition terms) and the band-independent p1..p4 [deg]
ROLO2005_553NM = MappingProxyType({
    "a": (-2.12504, -1.65970, 0.38409, -0.20655),
    "d": (0.37206, -0.10745, 0.00347),
    "p_deg": (4.06054, 12.8802, -30.5858, 16.7498),
    "phase_range_deg": (1.55, 97.0),
})


#: largest number of Gauss–Legendre nodes per photometric coordinate (n² nodes per phase
#: angle; 48 already reach 1e-6 mag)
MAX_QUADRATURE = 512


def _quadrature(n_quadrature) -> int:
    return check_int("n_quadrature", n_quadrature, low=1, high=MAX_QUADRATURE)


def _phase(phase_angle_rad):
    alpha = as_tensor("phase_angle_rad", phase_angle_rad)
    # signed phase angles (waxing / waning) are symmetric; the message shows the value given
    return check_range("phase_angle_rad", alpha, -math.pi, math.pi, unit=" rad").abs()


def magnitude_ks1991(phase_angle_rad) -> torch.Tensor:
    """Observed lunar V magnitude at mean distance (Krisciunas & Schaefer 1991, eq. 9).

    ``m = −12.73 + 0.026 |α| + 4e-9 α⁴`` with α in degrees; after Allen (1976). Used as
    the reference for :func:`magnitude`, not by it.
    """
    alpha_deg = _phase(phase_angle_rad) / DEGREE
    return -12.73 + 0.026 * alpha_deg + 4e-9 * alpha_deg**4


def disc_reflectance_rolo2005(phase_angle_rad) -> torch.Tensor:
    """ROLO disc-equivalent reflectance A(g) at 553.8 nm (Kieffer & Stone 2005, eq. 10).

    The observed lunar phase curve of the USGS ROLO programme at zero libration, valid for
    1.55° ≤ |g| ≤ 97°; a reference for :func:`disc_integrated_reflectance` (ROLO defines
    I = A Ω_M E_sun / π with Ω_M = π (R/d)², so A is the disc integral Q), not used by it.
    The odd terms in the Sun's selenographic longitude (the waxing/waning asymmetry of the
    maria) are left out: they cancel in the mean of waxing and waning Moons.

    Parameters
    ----------
    phase_angle_rad : Tensor (...)
        Phase angle g [rad] (the sign is ignored).

    Returns
    -------
    Tensor (...)
        A(g), dimensionless.
    """
    g = _phase(phase_angle_rad)
    g_deg = g / DEGREE
    a0, a1, a2, a3 = ROLO2005_553NM["a"]
    d1, d2, d3 = ROLO2005_553NM["d"]
    p1, p2, p3, p4 = ROLO2005_553NM["p_deg"]
    log_a = (a0 + a1 * g + a2 * g**2 + a3 * g**3 + d1 * torch.exp(-g_deg / p1)
             + d2 * torch.exp(-g_deg / p2) + d3 * torch.cos((g_deg - p3) / p4))
    return torch.exp(log_a)


def disc_integrated_reflectance(phase_angle_rad, *, model: str = "hapke2012",
                                parameters="helfenstein1987", n_quadrature: int = 48,
                                earthshine: bool = False,
                                distance_m=MEAN_EARTH_MOON_DISTANCE_M) -> torch.Tensor:
    """Disc integral Q(α) = ∫∫ r dx dy over the unit lunar disc at 550 nm [1/sr].

    Parameters
    ----------
    phase_angle_rad : Tensor (...)
        Phase angle α [rad] (the sign is ignored).
    model, parameters
        Reflectance law and Hapke parameters (:func:`skytorch.moon.reflectance.reflectance`).
    n_quadrature : int
        Gauss–Legendre nodes per photometric coordinate, 1 … :data:`MAX_QUADRATURE`
        (n² nodes per phase angle).
    earthshine : bool
        If True return the earthshine integral Q_earth(α) over the unlit part instead.
    distance_m : float or Tensor
        Earth–Moon distance [m] (sets the earthshine phase angle, asin(R_E / d)).

    Returns
    -------
    Tensor (...)
        Q(α); Q(0) is the geometric albedo. The flux is F = J (R_M/d)² Q.
    """
    n = _quadrature(n_quadrature)
    alpha = _phase(phase_angle_rad)
    if _flag("earthshine", earthshine):
        g = earth_angular_radius(distance_m).to(alpha.dtype)
        check_broadcastable(phase_angle_rad=alpha, distance_m=g)
        mu0, mu, weight = dark_disc_quadrature(alpha, n)
        if g.ndim:
            g = g.unsqueeze(-1)
        r = reflectance(mu0, mu, g, model=model, parameters=parameters)
    else:
        mu0, mu, weight = lit_disc_quadrature(alpha, n)
        r = reflectance(mu0, mu, alpha.unsqueeze(-1), model=model, parameters=parameters)
    return (r * weight).sum(-1)


def geometric_albedo(*, model: str = "hapke2012", parameters="helfenstein1987",
                     n_quadrature: int = 48, dtype=torch.float64) -> torch.Tensor:
    """Geometric albedo of the Moon at 550 nm, p = Q(0) (dimensionless)."""
    return disc_integrated_reflectance(torch.zeros((), dtype=dtype), model=model,
                                       parameters=parameters, n_quadrature=n_quadrature)


def lunar_irradiance(phase_angle_rad, wavelength_nm, *, distance_m=MEAN_EARTH_MOON_DISTANCE_M,
                     sun_distance_m=ASTRONOMICAL_UNIT_M, earthshine: bool = True,
                     model: str = "hapke2012", parameters="helfenstein1987",
                     n_quadrature: int = 48) -> torch.Tensor:
    """Spectral irradiance from the whole Moon at the top of the Earth's atmosphere.

    Parameters
    ----------
    phase_angle_rad : Tensor (...)
        Phase angle α [rad].
    wavelength_nm : Tensor (n_wavelength,)
        Wavelengths in [360, 830] nm.
    distance_m : float or Tensor (...)
        Observer–Moon distance [m] (mean Earth–Moon distance by default).
    sun_distance_m : float or Tensor (...)
        Moon–Sun distance [m] (1 AU by default).
    earthshine : bool
        Include the earthlit part of the disc (keeps new Moon finite).
    model, parameters, n_quadrature
        As in :func:`disc_integrated_reflectance`.

    Returns
    -------
    Tensor (..., n_wavelength)
        Spectral irradiance [W m^-2 nm^-1]; ``...`` is the broadcast shape of the phase
        angle and the distances.

    Raises
    ------
    ValueError
        For out-of-range values, a bad ``n_quadrature``, or shapes that do not broadcast
        (checked before any arithmetic).
    TypeError
        For non-numeric inputs or a non-boolean ``earthshine``.
    """
    from skytorch.spectrum import solar_irradiance

    dtype = common_dtype(phase_angle_rad, distance_m, sun_distance_m)
    alpha = _phase(as_tensor("phase_angle_rad", phase_angle_rad, dtype=dtype))
    wl = as_tensor("wavelength_nm", wavelength_nm, dtype=dtype)
    d = check_range("distance_m", as_tensor("distance_m", distance_m, dtype=dtype),
                    MOON_RADIUS_M, low_inclusive=False, unit=" m")
    d_sun = check_range("sun_distance_m", as_tensor("sun_distance_m", sun_distance_m,
                                                    dtype=dtype), 0.0, low_inclusive=False,
                        unit=" m")
    check_broadcastable(phase_angle_rad=alpha, distance_m=d, sun_distance_m=d_sun)
    if wl.ndim > 1:
        raise ValueError(f"wavelength_nm must have shape (n_wavelength,); got shape "
                         f"{tuple(wl.shape)}")
    earthshine = _flag("earthshine", earthshine)
    _quadrature(n_quadrature)
    q = disc_integrated_reflectance(alpha, model=model, parameters=parameters,
                                    n_quadrature=n_quadrature)
    if earthshine:
        q_earth = disc_integrated_reflectance(alpha, model=model, parameters=parameters,
                                              n_quadrature=n_quadrature, earthshine=True,
                                              distance_m=d)
        q = q + earthshine_irradiance_ratio(alpha, distance_m=d) * q_earth
    scale = (ASTRONOMICAL_UNIT_M / d_sun) ** 2 * (MOON_RADIUS_M / d) ** 2 * q
    spectrum = solar_irradiance(wl).to(dtype) * albedo(wl)
    return scale.unsqueeze(-1) * spectrum


def magnitude(phase_angle_rad, *, distance_m=MEAN_EARTH_MOON_DISTANCE_M,
              sun_distance_m=ASTRONOMICAL_UNIT_M, earthshine: bool = True,
              model: str = "hapke2012", parameters="helfenstein1987",
              n_quadrature: int = 48) -> torch.Tensor:
    """Disc-integrated Johnson V magnitude of the Moon, from the reflectance law.

    Parameters
    ----------
    phase_angle_rad : Tensor (...)
        Phase angle α [rad]; |α| ≤ π.
    distance_m, sun_distance_m : float or Tensor (...)
        Observer–Moon and Moon–Sun distances [m]; defaults: mean Earth–Moon distance and
        1 AU, the conditions of Krisciunas & Schaefer's eq. 9.
    earthshine : bool
        Include earthshine (default): the new Moon (α = π) then has a finite magnitude
        (≈ −2.5); without it the sunlit flux vanishes there and the magnitude is +inf.
    model, parameters, n_quadrature
        As in :func:`disc_integrated_reflectance`.

    Returns
    -------
    Tensor (...)
        V magnitude [mag] above the atmosphere. About −12.9 at α = 0 with the default
        Hapke parameters (opposition surge included); see docs/moon.md for the comparison
        with Krisciunas & Schaefer (1991).

    Examples
    --------
    >>> import math, torch
    >>> from skytorch.moon import magnitude, magnitude_ks1991
    >>> alpha = torch.tensor([0.0, math.pi / 2])  # full and quarter Moon
    >>> magnitude(alpha)
    tensor([-12.9..., -10.0...])
    >>> magnitude_ks1991(alpha)  # the observed phase curve, for comparison
    tensor([-12.7300, -10.1276])
    """
    from skytorch.spectrum import spectrum_to_magnitude

    dtype = common_dtype(phase_angle_rad, distance_m, sun_distance_m)
    wl = torch.tensor(V_BAND_WAVELENGTHS_NM, dtype=dtype)
    flux = lunar_irradiance(phase_angle_rad, wl, distance_m=distance_m,
                            sun_distance_m=sun_distance_m, earthshine=earthshine,
                            model=model, parameters=parameters, n_quadrature=n_quadrature)
    return spectrum_to_magnitude(flux, wl, band="V")
