"""Brightness of the moonlit sky: Krisciunas & Schaefer (1991) and single scattering.

Two models, compared in docs/moon.md:

``moonlit_sky_ks1991`` — the empirical baseline (Krisciunas & Schaefer 1991, eq. 15–21)::

    B_moon = f(ρ) I* 10^{−0.4 k X(Z_m)} [1 − 10^{−0.4 k X(Z)}]             [nL]
    f(ρ)   = 10^{5.36} (1.06 + cos² ρ) + 10^{6.15 − ρ/40}                (ρ ≥ 10°)
           = 10^{5.36} (1.06 + cos² ρ) + 6.2e7 ρ^{−2}                    (ρ < 10°)
    I*     = 10^{−0.4 (3.84 + 0.026 |α| + 4e-9 α⁴)}                       [foot-candles]
    X(Z)   = (1 − 0.96 sin² Z)^{−1/2}

with ρ the Moon–sky separation and α the phase angle in degrees, Z_m and Z the zenith
distances of Moon and sky point, k the V extinction coefficient [mag/airmass]. Surface
brightness in nanolamberts and V mag/arcsec² are related by their eq. 1,
``B = 34.08 exp(20.7233 − 0.92104 V)``; the dark sky by eq. 2,
``B_sky = B_zen 10^{−0.4 k (X − 1)} X``; the change in V by eq. 22.

``moonlit_sky_single_scattering`` — physics from the atmosphere module: the Moon's spectral
irradiance above the atmosphere (:func:`skytorch.moon.brightness.lunar_irradiance`)
attenuated along the slant path to each point of the line of sight, scattered once by
molecules (Rayleigh phase function) and aerosols (the atmosphere's aerosol phase
function), and attenuated back to the observer::

    L(λ) = E_moon(λ) ∫_0^{s_top} [β_R(h) P_R(θ) + β_a(h) P_a(θ)] e^{−τ_moon(s) − τ_view(s)} ds

Multiple scattering and ground reflection are neglected, so the result is a lower bound;
docs/moon.md lists the measured gap to the K&S model.

``moonlit_sky_multiple_scattering`` — single scattering as above plus the orders 2..N of
the Moon as a point source: its irradiance above the atmosphere times the sky radiance per
unit irradiance of precomputed multiple-scattering tables
(:mod:`skytorch.atmosphere.multiple_scattering`) with the Moon's zenith as the source
direction, less the tables' own first order. The lunar disc (0.5 deg) is not resolved by
those orders, whose radiance varies over tens of degrees.

References
----------
1. Krisciunas, K., Schaefer, B. E. 1991, "A model of the brightness of moonlight",
   PASP 103, 1033, doi:10.1086/132921.
2. Falchi, F. et al. 2016, "The new world atlas of artificial night sky brightness",
   Sci. Adv. 2, e1600377, doi:10.1126/sciadv.1600377 (L = 10.8e4 · 10^{−0.4 m} cd/m²).
3. Jones, A., Noll, S., Kausch, W., Szyszka, C., Kimeswenger, S. 2013, "An advanced
   scattered moonlight model for Cerro Paranal", A&A 560, A91,
   doi:10.1051/0004-6361/201322433 (a spectroscopic single + multiple scattering model).

Examples
--------
>>> import math, torch
>>> from skytorch.moon.sky import moonlit_sky_ks1991, nanolambert_to_mag_arcsec2
>>> b = moonlit_sky_ks1991(torch.tensor(0.0), torch.tensor(math.radians(60)),
...                        torch.tensor(math.radians(30)), torch.tensor(0.0))
>>> 17.0 < float(nanolambert_to_mag_arcsec2(b)) < 19.0  # full Moon, zenith
True
"""

from __future__ import annotations

import math

import torch

from skytorch._validate import as_tensor, check_broadcastable, check_int, check_range, common_dtype
from skytorch.constants import (
    ARCSECOND,
    DEGREE,
    MEAN_EARTH_MOON_DISTANCE_M,
    NATURAL_ZENITH_SKY_MAG_ARCSEC2,
)
from skytorch.moon.brightness import V_BAND_WAVELENGTHS_NM, lunar_irradiance
from skytorch.moon.geometry import angle_between

__all__ = [
    "KS1991_EXTINCTION_MAG",
    "NANOLAMBERT_CD_M2",
    "dark_sky_ks1991",
    "delta_v_ks1991",
    "extinction_coefficient_v",
    "mag_arcsec2_to_nanolambert",
    "moon_illuminance_ks1991",
    "moonlit_sky_ks1991",
    "moonlit_sky_multiple_scattering",
    "moonlit_sky_single_scattering",
    "nanolambert_to_mag_arcsec2",
    "radiance_to_mag_arcsec2",
    "scattering_function_ks1991",
    "airmass_ks1991",
]

#: V extinction coefficient of K&S's Mauna Kea data (2800 m) [mag/airmass]
KS1991_EXTINCTION_MAG = 0.172

#: one nanolambert in cd/m²: 1e-9 lambert, 1 L = 1e4/π cd/m²
NANOLAMBERT_CD_M2 = 1e-9 * 1e4 / math.pi

_MAX_ZENITH = 0.5 * math.pi


def _angle(name, value, dtype=None, high=math.pi):
    return check_range(name, as_tensor(name, value, dtype=dtype), 0.0, high, unit=" rad")


def mag_arcsec2_to_nanolambert(sky_mag_arcsec2) -> torch.Tensor:
    """Sky surface brightness V [mag arcsec⁻²] → B [nL], B = 34.08 exp(20.7233 − 0.92104 V).

    Krisciunas & Schaefer (1991, eq. 1); 22.0 mag arcsec⁻² is 54 nL.

    Parameters
    ----------
    sky_mag_arcsec2 : array_like
        ``(...)`` surface brightness in V [mag arcsec⁻²], within [−20, 40].

    Returns
    -------
    torch.Tensor
        ``(...)`` surface brightness [nL].

    Examples
    --------
    >>> round(float(mag_arcsec2_to_nanolambert(22.0)), 1)
    54.0
    """
    v = check_range("sky_mag_arcsec2", sky_mag_arcsec2, -20.0, 40.0, unit=" mag/arcsec^2")
    return 34.08 * torch.exp(20.7233 - 0.92104 * v)


def nanolambert_to_mag_arcsec2(brightness_nl) -> torch.Tensor:
    """Surface brightness in nanolamberts to V [mag/arcsec²] (inverse of K&S eq. 1)."""
    b = check_range("brightness_nl", brightness_nl, 0.0, low_inclusive=False, unit=" nL")
    return (20.7233 - torch.log(b / 34.08)) / 0.92104


def airmass_ks1991(zenith_rad, *, name: str = "zenith_rad") -> torch.Tensor:
    """K&S (1991, eq. 3) airmass X = (1 − 0.96 sin² Z)^{−1/2}, finite at the horizon (5).

    ``name`` is the parameter named in error messages.
    """
    z = _angle(name, zenith_rad, high=_MAX_ZENITH)
    return (1.0 - 0.96 * torch.sin(z) ** 2) ** -0.5


def scattering_function_ks1991(separation_rad) -> torch.Tensor:
    """K&S (1991, eq. 16–19) scattering function f(ρ) (Rayleigh + Mie terms)."""
    rho = _angle("separation_rad", separation_rad)
    rho_deg = rho / DEGREE
    rayleigh = 10.0**5.36 * (1.06 + torch.cos(rho) ** 2)
    mie_far = 10.0 ** (6.15 - rho_deg / 40.0)
    mie_near = 6.2e7 / rho_deg.clamp_min(1e-3) ** 2
    return rayleigh + torch.where(rho_deg >= 10.0, mie_far, mie_near)


def moon_illuminance_ks1991(phase_angle_rad) -> torch.Tensor:
    """Illuminance of the Moon outside the atmosphere (K&S 1991, eq. 20) [foot-candles]."""
    alpha = _angle("phase_angle_rad", as_tensor("phase_angle_rad", phase_angle_rad).abs())
    a = alpha / DEGREE
    return 10.0 ** (-0.4 * (3.84 + 0.026 * a + 4e-9 * a**4))


def moonlit_sky_ks1991(phase_angle_rad, separation_rad, moon_zenith_rad, zenith_rad,
                       extinction_mag=KS1991_EXTINCTION_MAG) -> torch.Tensor:
    """Sky brightness due to moonlight, Krisciunas & Schaefer (1991, eq. 15) [nL].

    Parameters
    ----------
    phase_angle_rad : Tensor (...)
        Lunar phase angle α [rad].
    separation_rad : Tensor (...)
        Angular distance ρ between the Moon and the sky position [rad].
    moon_zenith_rad : Tensor (...)
        Zenith distance of the Moon Z_m in [0, π/2] [rad].
    zenith_rad : Tensor (...)
        Zenith distance of the sky position Z in [0, π/2] [rad].
    extinction_mag : float or Tensor (...)
        V extinction coefficient k [mag/airmass] (0.172 for K&S's Mauna Kea data).

    Returns
    -------
    Tensor (...)
        B_moon [nL] (1 nL = 3.18e-6 cd/m²). The model was fitted for ρ ≳ 10° and
        reported accurate to 8–23 %.
    """
    dtype = common_dtype(phase_angle_rad, separation_rad, moon_zenith_rad, zenith_rad)
    k = check_range("extinction_mag", as_tensor("extinction_mag", extinction_mag, dtype=dtype),
                    0.0, unit=" mag/airmass")
    check_broadcastable(**{name: as_tensor(name, value, dtype=dtype) for name, value in (
        ("phase_angle_rad", phase_angle_rad), ("separation_rad", separation_rad),
        ("moon_zenith_rad", moon_zenith_rad), ("zenith_rad", zenith_rad),
        ("extinction_mag", k))})
    f = scattering_function_ks1991(as_tensor("separation_rad", separation_rad, dtype=dtype))
    illuminance = moon_illuminance_ks1991(as_tensor("phase_angle_rad", phase_angle_rad,
                                                    dtype=dtype))
    x_moon = airmass_ks1991(as_tensor("moon_zenith_rad", moon_zenith_rad, dtype=dtype),
                            name="moon_zenith_rad")
    x_sky = airmass_ks1991(as_tensor("zenith_rad", zenith_rad, dtype=dtype))
    return (f * illuminance * 10.0 ** (-0.4 * k * x_moon)
            * -torch.expm1(-0.4 * math.log(10.0) * k * x_sky))


def dark_sky_ks1991(zenith_rad, extinction_mag=KS1991_EXTINCTION_MAG,
                    zenith_mag_arcsec2=NATURAL_ZENITH_SKY_MAG_ARCSEC2) -> torch.Tensor:
    """Moonless sky brightness at zenith distance Z (K&S 1991, eq. 2) [nL].

    ``B_sky = B_zen 10^{−0.4 k (X − 1)} X`` with B_zen from ``zenith_mag_arcsec2``.
    """
    x = airmass_ks1991(zenith_rad)
    b_zen = mag_arcsec2_to_nanolambert(as_tensor("zenith_mag_arcsec2", zenith_mag_arcsec2,
                                                 dtype=x.dtype))
    return b_zen * 10.0 ** (-0.4 * extinction_mag * (x - 1.0)) * x


def delta_v_ks1991(moon_nl, dark_nl) -> torch.Tensor:
    """Change of the V sky brightness caused by moonlight (K&S 1991, eq. 22) [mag]."""
    moon = check_range("moon_nl", moon_nl, 0.0, unit=" nL")
    dark = check_range("dark_nl", dark_nl, 0.0, low_inclusive=False, unit=" nL")
    return -2.5 * torch.log10((moon + dark) / dark)


def radiance_to_mag_arcsec2(spectral_radiance, wavelength_nm) -> torch.Tensor:
    """Spectral radiance (..., n_wavelength) [W m^-2 sr^-1 nm^-1] to V [mag/arcsec²]."""
    from skytorch.spectrum import spectrum_to_magnitude

    radiance = as_tensor("spectral_radiance", spectral_radiance)
    return spectrum_to_magnitude(radiance * ARCSECOND**2, wavelength_nm, band="V")


def _check_atmosphere(atmosphere, methods) -> None:
    missing = [m for m in methods if not callable(getattr(atmosphere, m, None))]
    if missing or isinstance(atmosphere, (str, bytes, bool, int, float)):
        raise TypeError(f"atmosphere must be a skytorch.atmosphere.Atmosphere (with "
                        f"{', '.join(methods)}); got {type(atmosphere).__name__}: "
                        f"{atmosphere!r:.60}")


def extinction_coefficient_v(atmosphere, wavelength_nm=550.0, altitude_m=0.0) -> torch.Tensor:
    """Zenith extinction of an atmosphere at one wavelength, k = 2.5 log10(e) τ [mag/airmass]."""
    _check_atmosphere(atmosphere, ("optical_depth",))
    wl = as_tensor("wavelength_nm", wavelength_nm).reshape(-1)
    tau = atmosphere.optical_depth(wl, zenith_rad=0.0, altitude_m=altitude_m)
    return (2.5 / math.log(10.0)) * tau[..., 0]


def moonlit_sky_single_scattering(atmosphere, phase_angle_rad, moon_zenith_rad,
                                  view_zenith_rad, relative_azimuth_rad, wavelength_nm=None,
                                  *, distance_m=MEAN_EARTH_MOON_DISTANCE_M,
                                  altitude_m: float = 0.0, n_steps: int = 64,
                                  n_quadrature: int = 32) -> torch.Tensor:
    """Spectral radiance of the sky lit by the Moon, single scattering.

    Parameters
    ----------
    atmosphere : skytorch.atmosphere.Atmosphere
        Atmosphere without batch dimensions in its parameters.
    phase_angle_rad : Tensor (...)
        Lunar phase angle α [rad].
    moon_zenith_rad : Tensor (...)
        Zenith distance of the Moon at the observer, in [0, π/2) [rad].
    view_zenith_rad : Tensor (...)
        Zenith distance of the line of sight, in [0, π/2] [rad].
    relative_azimuth_rad : Tensor (...)
        Azimuth of the line of sight minus azimuth of the Moon [rad].
    wavelength_nm : Tensor (n_wavelength,), optional
        Wavelengths [nm]; default: the V-band grid of :mod:`skytorch.moon.brightness`.
    distance_m : float or Tensor (...)
        Observer–Moon distance [m].
    altitude_m : float
        Observer altitude [m].
    n_steps : int
        Samples along the line of sight (quadratically spaced, dense near the observer).
    n_quadrature : int
        Nodes of the lunar disc integral.

    Returns
    -------
    Tensor (..., n_wavelength)
        Spectral radiance [W m^-2 sr^-1 nm^-1]; :func:`radiance_to_mag_arcsec2` gives
        V mag/arcsec².
    """
    from skytorch.atmosphere.geometry import distance_to_top
    from skytorch.atmosphere.scattering import rayleigh_phase

    _check_atmosphere(atmosphere, ("optical_depth", "scattering_coefficients",
                                   "extinction_coefficient", "aerosol_phase"))
    n_steps = check_int("n_steps", n_steps, low=2, high=100_000)
    altitude_m = float(check_range("altitude_m", altitude_m, 0.0, 1e5, unit=" m"))
    dtype = common_dtype(phase_angle_rad, moon_zenith_rad, view_zenith_rad,
                         relative_azimuth_rad)
    if wavelength_nm is None:
        wavelength_nm = torch.tensor(V_BAND_WAVELENGTHS_NM, dtype=dtype)
    wl = as_tensor("wavelength_nm", wavelength_nm, dtype=dtype)
    zm = _angle("moon_zenith_rad", moon_zenith_rad, dtype, high=_MAX_ZENITH)
    zv = _angle("view_zenith_rad", view_zenith_rad, dtype, high=_MAX_ZENITH)
    daz = check_range("relative_azimuth_rad", relative_azimuth_rad, unit=" rad", dtype=dtype)
    if wl.ndim > 1:
        raise ValueError(f"wavelength_nm must have shape (n_wavelength,); got shape "
                         f"{tuple(wl.shape)}")
    check_broadcastable(phase_angle_rad=as_tensor("phase_angle_rad", phase_angle_rad),
                        moon_zenith_rad=zm, view_zenith_rad=zv, relative_azimuth_rad=daz,
                        distance_m=as_tensor("distance_m", distance_m))
    zm, zv, daz = torch.broadcast_tensors(zm, zv, daz)
    moon_dir = torch.stack([torch.sin(zm), torch.zeros_like(zm), torch.cos(zm)], dim=-1)
    view_dir = torch.stack([torch.sin(zv) * torch.cos(daz), torch.sin(zv) * torch.sin(daz),
                            torch.cos(zv)], dim=-1)
    cos_theta = (moon_dir * view_dir).sum(-1).clamp(-1.0, 1.0)

    radius0 = atmosphere.planet_radius_m + float(altitude_m)
    s_max = distance_to_top(torch.full_like(zv, radius0), torch.cos(zv),
                            atmosphere.top_radius_m)
    u = torch.linspace(0.0, 1.0, n_steps, dtype=dtype)
    s = s_max.unsqueeze(-1) * u * u  # (..., n_steps)
    origin = torch.tensor([0.0, 0.0, radius0], dtype=dtype)
    position = origin + s.unsqueeze(-1) * view_dir.unsqueeze(-2)  # (..., n_steps, 3)
    radius = position.norm(dim=-1)
    altitude = (radius - atmosphere.planet_radius_m).clamp_min(0.0)
    # local zenith angle of the Moon at each point (finite gradient with the Moon overhead)
    zenith_moon = angle_between(position, moon_dir.unsqueeze(-2).expand_as(position))

    ds = torch.diff(s, dim=-1).unsqueeze(-1)
    tau_moon = atmosphere.optical_depth(wl, zenith_rad=zenith_moon, altitude_m=altitude)
    if callable(getattr(atmosphere, "constituents", None)):
        source, tau_view = _constituent_source(atmosphere.constituents(wl), altitude, s,
                                               cos_theta)
    else:  # an object with the coefficient methods only (Rayleigh + aerosol)
        scattering = atmosphere.scattering_coefficients(altitude, wl)  # (..., n, n_wl)
        extinction = atmosphere.extinction_coefficient(altitude, wl)
        segment = 0.5 * (extinction[..., 1:, :] + extinction[..., :-1, :]) * ds
        tau_view = torch.cat([torch.zeros_like(segment[..., :1, :]), segment.cumsum(-2)],
                             dim=-2)
        phase_r = rayleigh_phase(cos_theta)[..., None, None]
        phase_a = atmosphere.aerosol_phase(cos_theta)[..., None, None]
        source = scattering["rayleigh"] * phase_r + scattering["aerosol"] * phase_a
    integrand = source * torch.exp(-(tau_view + tau_moon))
    integral = (0.5 * (integrand[..., 1:, :] + integrand[..., :-1, :]) * ds).sum(-2)
    irradiance = lunar_irradiance(phase_angle_rad, wl, distance_m=distance_m,
                                  n_quadrature=n_quadrature)
    return irradiance * integral


def moonlit_sky_multiple_scattering(atmosphere, tables, phase_angle_rad, moon_zenith_rad,
                                    view_zenith_rad, relative_azimuth_rad, *,
                                    distance_m=MEAN_EARTH_MOON_DISTANCE_M,
                                    altitude_m: float = 0.0, scattering_orders=None,
                                    n_steps: int = 64, n_quadrature: int = 32) -> torch.Tensor:
    r"""Spectral radiance of the sky lit by the Moon, orders of scattering 1..N.

    Parameters
    ----------
    atmosphere : skytorch.atmosphere.Atmosphere
        Atmosphere without batch dimensions (the one the tables were built for).
    tables : skytorch.atmosphere.multiple_scattering.ScatteringTables
        Multiple-scattering tables of ``atmosphere``; the result is at their wavelengths
        ``tables.wavelength_nm`` [nm].
    phase_angle_rad, moon_zenith_rad, view_zenith_rad, relative_azimuth_rad : Tensor (...)
        As :func:`moonlit_sky_single_scattering` [rad].
    distance_m : float or Tensor (...)
        Observer–Moon distance [m].
    altitude_m : float
        Observer altitude [m].
    scattering_orders : int or "converged", optional
        Orders 1..N (default: every order of the tables).
    n_steps, n_quadrature : int
        Line-of-sight samples of the single scattering and nodes of the lunar disc
        integral.

    Returns
    -------
    Tensor (..., n_wavelength)
        Spectral radiance [W m^-2 sr^-1 nm^-1].

    Notes
    -----
    .. math:: L = L_1 + E_{moon}(\lambda)\,[R_N(\mu_m) - R_1(\mu_m)]

    with :math:`L_1` the exact single scattering (:func:`moonlit_sky_single_scattering`:
    the aureole and the band absorbers exactly, the disc integrated),
    :math:`E_{moon}` the lunar irradiance above the atmosphere
    (:func:`skytorch.moon.brightness.lunar_irradiance`) and :math:`R_n` the tables'
    radiance per unit irradiance of orders 1..n for a point source at the Moon's zenith
    angle (Bruneton & Neyret 2008). The orders >= 2 of a source of 0.5 deg differ from
    those of a point by the variation of the diffuse field over the disc, below the
    tables' own interpolation error. The ground is the tables' (over a Lambertian ground,
    the light it reflects enters with the orders >= 2); no refraction (the tables').

    References
    ----------
    1. Bruneton, E. & Neyret, F. 2008, Computer Graphics Forum 27, 1079,
       doi:10.1111/j.1467-8659.2008.01245.x.
    2. Jones, A. et al. 2013, A&A 560, A91, doi:10.1051/0004-6361/201322433 (single and
       multiple scattering of moonlight).
    """
    required = ("radiance", "wavelength_nm", "orders_computed", "check_built_for")
    if not all(hasattr(tables, name) for name in required):
        raise TypeError("tables must be a skytorch.atmosphere.multiple_scattering."
                        f"ScatteringTables; got {type(tables).__name__}")
    tables.check_built_for(atmosphere)
    wl = tables.wavelength_nm
    dtype = common_dtype(phase_angle_rad, moon_zenith_rad, view_zenith_rad,
                         relative_azimuth_rad)
    single = moonlit_sky_single_scattering(
        atmosphere, phase_angle_rad, moon_zenith_rad, view_zenith_rad, relative_azimuth_rad,
        wl.to(dtype), distance_m=distance_m, altitude_m=altitude_m, n_steps=n_steps,
        n_quadrature=n_quadrature)
    zm = _angle("moon_zenith_rad", moon_zenith_rad, dtype, high=_MAX_ZENITH)
    zv = _angle("view_zenith_rad", view_zenith_rad, dtype, high=_MAX_ZENITH)
    daz = torch.remainder(as_tensor("relative_azimuth_rad", relative_azimuth_rad, dtype=dtype),
                          2.0 * math.pi)
    args = (altitude_m, zv, daz, zm)
    higher = (tables.radiance(*args, scattering_orders=scattering_orders)
              - tables.radiance(*args, scattering_orders=1))
    irradiance = lunar_irradiance(phase_angle_rad, wl.to(dtype), distance_m=distance_m,
                                  n_quadrature=n_quadrature)
    return single + irradiance * higher.to(dtype)


def _constituent_source(constituents, altitude, s, cos_theta):
    """Return the scattering source and the view-path optical depth of the constituents.

    The source (..., n_steps, n_wl) [m^-1 sr^-1] sums every scattering species; the optical
    depth comes from cumulative per-species path columns (through
    :meth:`~skytorch.atmosphere.constituents.Constituents.optical_depth`, so that the gas
    bands' laws apply).
    """
    from skytorch.atmosphere.constituents import insert_dims

    densities = constituents.densities(altitude)  # (..., n_steps)
    step = s[..., 1:] - s[..., :-1]
    columns = {}
    for name, density in densities.items():
        increments = 0.5 * step * (density[..., 1:] + density[..., :-1])
        columns[name] = torch.cat([torch.zeros_like(increments[..., :1]),
                                   increments.cumsum(-1)], dim=-1)
    tau_view = constituents.optical_depth(columns, extra=1)
    source = torch.zeros_like(tau_view)
    for species in constituents.scatterers():
        if species.vanishes:
            continue
        source = source + (densities[species.name][..., None]
                           * insert_dims(species.scattering, 1, 1)
                           * species.phase(cos_theta)[..., None, :])
    return source, tau_view
