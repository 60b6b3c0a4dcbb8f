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
    "single_scattering_radiance",
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


def _direction(zenith, azimuth):
    """Unit vectors (..., 3) in the observer's (north, east, up) frame."""
    zenith, azimuth = torch.broadcast_tensors(zenith, azimuth)
    sin_z = torch.sin(zenith)
    return torch.stack([sin_z * torch.cos(azimuth), sin_z * torch.sin(azimuth),
                        torch.cos(zenith)], dim=-1)


def single_scattering_radiance(atmosphere, wavelength_nm, view_zenith_rad,
                               view_azimuth_rad=0.0, sun_zenith_rad=0.0,
                               sun_azimuth_rad=0.0, altitude_m=0.0, *, n_samples: int = 128,
                               table=None, sun_steps: int | None = None) -> torch.Tensor:
    """Single-scattering sky radiance per unit extraterrestrial solar irradiance [1/sr].

    Parameters
    ----------
    atmosphere : Atmosphere
        The atmosphere (its parameters broadcast with the angles).
    wavelength_nm : Tensor (wavelength,)
        Wavelengths [nm].
    view_zenith_rad, view_azimuth_rad : Tensor (...)
        Viewing direction at the observer [rad] (azimuth from north through east).
    sun_zenith_rad, sun_azimuth_rad : Tensor (...)
        Direction of the Sun [rad]; zenith angles beyond 90° (twilight) are allowed.
    altitude_m : Tensor (...)
        Observer altitude [m].
    n_samples : int
        Samples along the view ray (quadratically spaced from the observer).
    table : TransmittanceTable, optional
        Look up the Sun's transmittance instead of integrating it (faster).
    sun_steps : int, optional
        Gauss–Legendre nodes per piece for the Sun's transmittance.

    Returns
    -------
    Tensor (..., wavelength)
        :math:`L/E_\\odot` [sr^-1].

    Notes
    -----
    .. math::

        \\frac{L}{E_\\odot} = \\int_0^{L} \\sum_{i} \\beta_i(h(s))\\,P_i(\\cos\\theta)\\,
        T(0 \\to s)\\,T_\\odot(s)\\,ds,\\qquad \\cos\\theta = \\hat v\\cdot\\hat s,

    over Rayleigh and aerosol scattering (ref. 4, eq. 1 without multiple scattering),
    with the view ray ending at the top of the atmosphere or the ground,
    :math:`T(0 \\to s)` integrated along the view ray (trapezoid on the samples) and
    :math:`T_\\odot(s) = 0` where the ray to the Sun meets the planet (its shadow).
    """
    from skytorch._validate import check_finite, check_int, common_dtype
    from skytorch.atmosphere.geometry import distance_to_ground, distance_to_top, ray_hits_ground

    n_samples = check_int("n_samples", n_samples, 2)
    dtype = common_dtype(wavelength_nm, view_zenith_rad, view_azimuth_rad, sun_zenith_rad,
                         sun_azimuth_rad, altitude_m)
    wavelength = atmosphere._wavelength(wavelength_nm, dtype)
    view_zenith = check_finite("view_zenith_rad", view_zenith_rad, dtype=dtype)
    view_azimuth = check_finite("view_azimuth_rad", view_azimuth_rad, dtype=dtype)
    sun_zenith = check_finite("sun_zenith_rad", sun_zenith_rad, dtype=dtype)
    sun_azimuth = check_finite("sun_azimuth_rad", sun_azimuth_rad, dtype=dtype)
    altitude = atmosphere._altitude(altitude_m, dtype)
    planet = atmosphere.planet_radius_m
    top = atmosphere.top_radius_m
    if bool((altitude > atmosphere.top_altitude_m).any()):
        raise ValueError("altitude_m must be inside the atmosphere (<= "
                         f"{atmosphere.top_altitude_m} m) for sky radiance")
    view = _direction(view_zenith, view_azimuth)
    sun = _direction(sun_zenith, sun_azimuth)
    cos_theta = (view * sun).sum(-1)
    r0 = planet + altitude
    mu_v = view[..., 2]
    hits = ray_hits_ground(r0, mu_v, planet)
    length = torch.where(hits, distance_to_ground(r0, mu_v, planet),
                         distance_to_top(r0, mu_v, top))
    fraction = torch.linspace(0.0, 1.0, n_samples, dtype=dtype) ** 2
    s = length[..., None] * fraction  # (..., n)
    # sample positions relative to the planet centre: observer at (0, 0, r0)
    r0_ = r0[..., None]
    r_sq = r0_ * r0_ + s * s + 2.0 * r0_ * s * mu_v[..., None]
    r = torch.sqrt(r_sq)
    height = torch.clamp(((r_sq - planet ** 2) / (r + planet)), min=0.0)
    # cosine of the Sun's zenith angle at each sample: (p . sun) / r
    p_dot_sun = r0_ * sun[..., 2:3] + s * cos_theta[..., None]
    mu_sun = torch.clamp(p_dot_sun / r, -1.0, 1.0)
    sun_zenith_local = torch.acos(mu_sun)
    # parameters broadcast against the geometry (...) with one extra sample dim (n)
    with atmosphere._extra_geometry_dims(1):
        # local coefficients of each species along the ray (..., n, wavelength)
        coefficients = atmosphere.reference_extinction(wavelength)
        local = {name: atmosphere._density(name, dtype)(height)[..., None]
                 * coefficients[name] for name in coefficients}
        # transmittance towards the Sun from each sample (zero in the planet's shadow)
        if table is not None:
            tau_sun = table.optical_depth(sun_zenith_local, height)
        else:
            tau_sun = atmosphere.optical_depth(wavelength, sun_zenith_local, height,
                                               n_steps=sun_steps)
    extinction = local["rayleigh"] + local["aerosol"] + local["ozone"]
    step = (s[..., 1:] - s[..., :-1])[..., None]
    increments = 0.5 * step * (extinction[..., 1:, :] + extinction[..., :-1, :])
    tau_view = torch.cat([torch.zeros_like(increments[..., :1, :]),
                          torch.cumsum(increments, dim=-2)], dim=-2)
    shadow = ray_hits_ground(r, mu_sun, planet)[..., None]
    sun_transmittance = torch.where(shadow, torch.zeros_like(tau_sun), torch.exp(-tau_sun))
    albedo = atmosphere._p("aerosol_single_scattering_albedo", dtype, 2)
    phase_r = rayleigh_phase(cos_theta)[..., None, None]
    phase_a = phase_function(cos_theta, atmosphere._p("aerosol_asymmetry", dtype),
                             atmosphere.aerosol_phase_model)[..., None, None]
    source = (local["rayleigh"] * phase_r + albedo * local["aerosol"] * phase_a)
    integrand = source * torch.exp(-tau_view) * sun_transmittance
    return (0.5 * step * (integrand[..., 1:, :] + integrand[..., :-1, :])).sum(-2)
