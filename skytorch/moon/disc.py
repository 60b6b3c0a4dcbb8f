"""Sampling the visible lunar disc: points, normals, area weights, radiance images.

The disc frame: the observer looks along −z (the z axis points from the Moon's centre
towards the observer); on the sky, ``x`` points west (to the right for an observer facing
the Moon with north up) and ``y`` north, both in units of the lunar radius. A point
(x, y) on the visible hemisphere has the outward normal ``(x, y, √(1 − x² − y²))``, so
``μ = n_z`` is the cosine of the emission angle. The Sun direction in this frame, for a
phase angle α and a bright-limb position angle χ (from north through east), is
``s = (−sin α sin χ, sin α cos χ, cos α)``.

Integrals over the disc: the flux from the Moon is ``F = J (R/d)² ∫∫ r(μ0, μ, α) dx dy``
(J the irradiance at the Moon, r the bidirectional reflectance [1/sr]), because the
projected area of a surface element is μ dA. :func:`disc_grid` returns points with
weights ``dx dy`` that sum to π (the unit disc's area); :func:`lit_disc_quadrature`
integrates exactly over the sunlit visible part, which is bounded by the terminator, in
photometric latitude β and longitude L (μ = cos β cos L, μ0 = cos β cos(L − α),
``dx dy = cos²β cos L dβ dL``, L ∈ [α − π/2, π/2]) with Gauss–Legendre nodes: the
integrand is smooth there, so it converges spectrally, unlike grids that straddle the
terminator.

References
----------
1. Müller, T., Engel, J., Döllner, J. 2012, "Single-Pass Rendering of Day and Night Sky
   Phenomena", Proc. VMV, doi:10.2312/PE/VMV/VMV12/055-062 (Fig. 1: the shaded lunar
   disc; §2: the virtual moon-sphere with normals on a billboard).
2. Hapke, B. 2012, *Theory of Reflectance and Emittance Spectroscopy*, 2nd ed., Cambridge
   University Press, doi:10.1017/CBO9781139025683, ch. 11 (photometric coordinates and
   disc-integrated brightness).

Examples
--------
>>> from skytorch.moon.disc import disc_grid
>>> grid = disc_grid(16)
>>> round(float(grid["weight"].sum()), 6)  # area of the unit disc
3.141593
"""

from __future__ import annotations

import math

import numpy as np
import torch

from skytorch import _quadrature
from skytorch._validate import (
    as_tensor,
    check_broadcastable,
    check_choice,
    check_int,
    check_range,
    common_dtype,
)
from skytorch.constants import ASTRONOMICAL_UNIT_M, MEAN_EARTH_MOON_DISTANCE_M, MOON_RADIUS_M
from skytorch.moon.earthshine import earth_angular_radius, earthshine_irradiance_ratio
from skytorch.moon.reflectance import REFLECTANCE_MODELS, reflectance

__all__ = [
    "DISC_GRID_METHODS",
    "dark_disc_quadrature",
    "disc_grid",
    "disc_image",
    "disc_radiance",
    "disc_reflectance",
    "gauss_legendre",
    "integrate_disc",
    "lit_disc_quadrature",
    "sun_direction",
]

#: sampling schemes of :func:`disc_grid`
DISC_GRID_METHODS = ("polar", "pixels")


def _flag(name: str, value) -> bool:
    """Return a boolean option; anything else (strings such as "no", numbers) is a TypeError."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False; got {value!r}")
    return bool(value)


def gauss_legendre(n: int, low, high, dtype=torch.float64):
    """Gauss–Legendre nodes and weights on [low, high] (batched bounds).

    The package's one rule, :func:`skytorch._quadrature.gauss_legendre`, with ``n``
    checked under this function's name.

    Parameters
    ----------
    n : int
        Number of nodes, in [1, 4096] (:data:`skytorch._quadrature.MAX_NODES`).
    low, high : float or Tensor (...)
        Interval bounds; tensors broadcast and the nodes get a trailing dimension.

    Returns
    -------
    (nodes, weights) : Tensor (..., n)
    """
    return _quadrature.gauss_legendre(check_int("n", n, low=1, high=_quadrature.MAX_NODES),
                                      low, high, dtype)


def disc_grid(n: int, method: str = "polar", dtype: torch.dtype = torch.float64) -> dict:
    """Sample points on the visible lunar disc with normals and area weights.

    Parameters
    ----------
    n : int
        Resolution: radial nodes for ``"polar"`` (with 2n azimuths), pixels across the
        diameter for ``"pixels"``.
    method : {"polar", "pixels"}
        ``"polar"``: Gauss–Legendre in radius × midpoint rule in azimuth (exact area, high
        order for smooth integrands). ``"pixels"``: centres of an n × n square grid that
        fall inside the disc, each weighing one pixel area (what an image sees).
    dtype : torch.dtype
        Floating dtype of the outputs.

    Returns
    -------
    dict
        ``x``, ``y`` (n_point,) in lunar radii (x west, y north); ``normal`` (n_point, 3),
        outward unit normals with z towards the observer; ``weight`` (n_point,), projected
        area elements dx dy in lunar radii² (sum π for ``"polar"``).
    """
    n = check_int("n", n, low=1)
    check_choice("method", method, DISC_GRID_METHODS)
    if method == "polar":
        radius, radial_weight = gauss_legendre(n, 0.0, 1.0, dtype=dtype)
        n_azimuth = 2 * n
        azimuth = (torch.arange(n_azimuth, dtype=dtype) + 0.5) * (2.0 * math.pi / n_azimuth)
        r = radius[:, None].expand(n, n_azimuth)
        a = azimuth[None, :].expand(n, n_azimuth)
        x = (r * torch.cos(a)).reshape(-1)
        y = (r * torch.sin(a)).reshape(-1)
        weight = (radial_weight * radius)[:, None].expand(n, n_azimuth).reshape(-1)
        weight = weight * (2.0 * math.pi / n_azimuth)
    else:
        centres = (torch.arange(n, dtype=dtype) + 0.5) * (2.0 / n) - 1.0
        yy, xx = torch.meshgrid(centres, centres, indexing="ij")
        inside = xx * xx + yy * yy < 1.0
        x, y = xx[inside], yy[inside]
        weight = torch.full_like(x, (2.0 / n) ** 2)
    z = torch.sqrt((1.0 - x * x - y * y).clamp_min(0.0))
    return {"x": x, "y": y, "normal": torch.stack([x, y, z], dim=-1), "weight": weight}


def sun_direction(phase_angle_rad, bright_limb_angle_rad=1.5 * math.pi) -> torch.Tensor:
    """Return unit vector towards the Sun in the disc frame (…, 3).

    Parameters
    ----------
    phase_angle_rad : Tensor (...)
        Phase angle α in [0, π] [rad].
    bright_limb_angle_rad : Tensor (...)
        Position angle χ of the bright limb from north through east [rad]; the default
        270° puts the bright limb to the west (right), as for a waxing Moon.
    """
    dtype = common_dtype(phase_angle_rad, bright_limb_angle_rad)
    alpha = check_range("phase_angle_rad", as_tensor("phase_angle_rad", phase_angle_rad,
                                                     dtype=dtype), 0.0, math.pi, unit=" rad")
    chi = check_range("bright_limb_angle_rad", bright_limb_angle_rad, unit=" rad", dtype=dtype)
    check_broadcastable(phase_angle_rad=alpha, bright_limb_angle_rad=chi)
    alpha, chi = torch.broadcast_tensors(alpha, chi)
    s = torch.sin(alpha)
    return torch.stack([-s * torch.sin(chi), s * torch.cos(chi), torch.cos(alpha)], dim=-1)


def _phase_of(sun_dir: torch.Tensor) -> torch.Tensor:
    """Phase angle of a disc-frame Sun direction, with finite gradients at 0 and π."""
    tiny = torch.finfo(sun_dir.dtype).tiny
    transverse = torch.sqrt(sun_dir[..., 0] ** 2 + sun_dir[..., 1] ** 2 + tiny)
    return torch.atan2(transverse, sun_dir[..., 2])


def disc_reflectance(normal, sun_dir, model: str = "hapke2012", wavelength_nm=None,
                     parameters="helfenstein1987") -> torch.Tensor:
    """Bidirectional reflectance at disc points for given Sun directions [1/sr].

    Parameters
    ----------
    normal : Tensor (n_point, 3)
        Outward normals from :func:`disc_grid` (z towards the observer).
    sun_dir : Tensor (..., 3)
        Unit vectors towards the Sun in the disc frame (:func:`sun_direction`).
    model, wavelength_nm, parameters
        As in :func:`skytorch.moon.reflectance.reflectance` (``wavelength_nm`` [nm]).

    Returns
    -------
    Tensor (..., n_point) or (..., n_point, n_wavelength)
    """
    check_choice("model", model, REFLECTANCE_MODELS)
    dtype = common_dtype(sun_dir, normal)
    normal = as_tensor("normal", normal, dtype=dtype)
    sun_dir = as_tensor("sun_dir", sun_dir, dtype=dtype)
    mu = normal[..., 2]
    mu0 = torch.einsum("pk,...k->...p", normal, sun_dir)
    alpha = _phase_of(sun_dir).unsqueeze(-1)
    return reflectance(mu0, mu, alpha, model=model, wavelength_nm=wavelength_nm,
                       parameters=parameters)


def lit_disc_quadrature(phase_angle_rad, n: int = 48):
    """Quadrature over the sunlit part of the visible disc (photometric coordinates).

    Parameters
    ----------
    phase_angle_rad : Tensor (...)
        Phase angle α in [0, π] [rad].
    n : int
        Gauss–Legendre nodes per coordinate (n² points).

    Returns
    -------
    (mu0, mu, weight) : Tensor (..., n * n)
        Cosines of incidence and emission and projected-area weights dx dy [lunar radii²];
        ``Σ weight`` is the illuminated area of the unit disc, π (1 + cos α)/2.
    """
    alpha = as_tensor("phase_angle_rad", phase_angle_rad)
    return _photometric_quadrature(alpha, alpha - 0.5 * math.pi, 0.5 * math.pi, n,
                                   lit_by_sun=True)


def dark_disc_quadrature(phase_angle_rad, n: int = 48):
    """Quadrature over the visible disc *not* lit by the Sun (where earthshine shows).

    Same outputs as :func:`lit_disc_quadrature`, with ``mu0`` the cosine of incidence of
    light coming from the observer's direction (μ0 = μ); ``Σ weight = π (1 − cos α)/2``.
    """
    alpha = as_tensor("phase_angle_rad", phase_angle_rad)
    return _photometric_quadrature(alpha, torch.full_like(alpha, -0.5 * math.pi),
                                   alpha - 0.5 * math.pi, n, lit_by_sun=False)


def _photometric_quadrature(alpha, low, high, n, lit_by_sun):
    check_range("phase_angle_rad", alpha, 0.0, math.pi, unit=" rad")
    dtype = alpha.dtype
    longitude, w_lon = gauss_legendre(n, low, high, dtype=dtype)  # (..., n)
    latitude, w_lat = gauss_legendre(n, 0.0, 0.5 * math.pi, dtype=dtype)  # (n,)
    cos_lat = torch.cos(latitude)
    cos_lon = torch.cos(longitude)
    mu = cos_lat * cos_lon.unsqueeze(-1)  # (..., n_lon, n_lat)
    if lit_by_sun:
        mu0 = cos_lat * torch.cos(longitude - alpha.unsqueeze(-1)).unsqueeze(-1)
    else:
        mu0 = mu
    # both hemispheres of latitude: factor 2 on the weights
    weight = 2.0 * (w_lon * cos_lon).unsqueeze(-1) * (w_lat * cos_lat * cos_lat)
    shape = mu.shape[:-2] + (n * n,)
    return mu0.reshape(shape), mu.reshape(shape), weight.reshape(shape)


def disc_radiance(normal, phase_angle_rad, wavelength_nm, bright_limb_angle_rad=1.5 * math.pi,
                  *, sun_distance_m=ASTRONOMICAL_UNIT_M, distance_m=MEAN_EARTH_MOON_DISTANCE_M,
                  earthshine: bool = True, model: str = "hapke2012",
                  parameters="helfenstein1987") -> torch.Tensor:
    """Spectral radiance of the lunar surface at disc points, seen from the Earth.

    Parameters
    ----------
    normal : Tensor (n_point, 3)
        Disc normals (:func:`disc_grid`).
    phase_angle_rad : Tensor (...)
        Phase angle α [rad].
    wavelength_nm : Tensor (n_wavelength,)
        Wavelengths in [360, 830] nm.
    bright_limb_angle_rad : Tensor (...)
        Position angle of the bright limb χ [rad].
    sun_distance_m : float or Tensor (...)
        Moon–Sun distance [m] (the solar irradiance scales as (1 AU / d)²).
    distance_m : float or Tensor (...)
        Earth–Moon distance [m], for the earthshine irradiance.
    earthshine : bool
        Add the light of the sunlit Earth (:mod:`skytorch.moon.earthshine`) on the whole
        disc, reflected at the Earth's angular radius as phase angle.
    model, parameters
        Reflectance law and Hapke parameters.

    Returns
    -------
    Tensor (..., n_point, n_wavelength)
        Spectral radiance [W m^-2 sr^-1 nm^-1] above the Earth's atmosphere.
    """
    from skytorch.spectrum import solar_irradiance

    dtype = common_dtype(phase_angle_rad, normal)
    wl = as_tensor("wavelength_nm", wavelength_nm, dtype=dtype)
    if wl.ndim > 1:
        raise ValueError(f"wavelength_nm must have shape (n_wavelength,); got shape "
                         f"{tuple(wl.shape)}")
    normal = as_tensor("normal", normal, dtype=dtype)
    if normal.ndim != 2 or normal.shape[-1] != 3:
        raise ValueError(f"normal must have shape (n_point, 3); got shape "
                         f"{tuple(normal.shape)}")
    earthshine = _flag("earthshine", earthshine)
    d_sun = check_range("sun_distance_m", sun_distance_m, 0.0, low_inclusive=False,
                        unit=" m", dtype=dtype)
    sun_dir = sun_direction(phase_angle_rad, bright_limb_angle_rad).to(dtype)
    check_broadcastable(phase_angle_rad=sun_dir[..., 0], sun_distance_m=d_sun,
                        distance_m=as_tensor("distance_m", distance_m, dtype=dtype))
    r = disc_reflectance(normal, sun_dir, model=model, wavelength_nm=wl,
                         parameters=parameters)
    scale = (ASTRONOMICAL_UNIT_M / d_sun) ** 2
    irradiance = solar_irradiance(wl).to(dtype) * scale.unsqueeze(-1)  # (..., n_wl)
    if earthshine:
        alpha = _phase_of(sun_dir)
        ratio = earthshine_irradiance_ratio(alpha, distance_m=distance_m)
        g_earth = earth_angular_radius(distance_m).to(dtype)
        if g_earth.ndim:  # batched distances against the disc points
            g_earth = g_earth.unsqueeze(-1)
        mu = normal[..., 2]
        r_earth = reflectance(mu, mu, g_earth, model=model, wavelength_nm=wl,
                              parameters=parameters)  # (n_point, n_wl) or broadcast
        r = r + ratio[..., None, None] * r_earth
    return r * irradiance.unsqueeze(-2)


def integrate_disc(radiance, weight, distance_m=MEAN_EARTH_MOON_DISTANCE_M,
                   radius_m: float = MOON_RADIUS_M) -> torch.Tensor:
    """Irradiance at the observer from radiance sampled on the disc.

    Parameters
    ----------
    radiance : Tensor (..., n_point, n_wavelength)
        Spectral radiance at the points of a :func:`disc_grid` (e.g. :func:`disc_radiance`
        times a shadow's relative illuminance at each point).
    weight : Tensor (n_point,)
        The grid's projected-area weights [lunar radii²].
    distance_m : float or Tensor (...)
        Observer–Moon distance [m].
    radius_m : float
        Lunar radius [m].

    Returns
    -------
    Tensor (..., n_wavelength)
        ``E = (R/d)² Σ_p L_p w_p`` [W m^-2 nm^-1] (the solid angle of a disc element is
        w (R/d)²).
    """
    radiance = as_tensor("radiance", radiance)
    weight = as_tensor("weight", weight, dtype=radiance.dtype)
    d = check_range("distance_m", as_tensor("distance_m", distance_m, dtype=radiance.dtype),
                    radius_m, low_inclusive=False, unit=" m")
    solid_angle = (radius_m / d) ** 2
    return solid_angle.unsqueeze(-1) * torch.einsum("...pw,p->...w", radiance, weight)


def disc_image(phase_angle_rad, bright_limb_angle_rad=1.5 * math.pi, n_pixels: int = 64,
               wavelength_nm=None, *, sun_distance_m=ASTRONOMICAL_UNIT_M,
               distance_m=MEAN_EARTH_MOON_DISTANCE_M, earthshine: bool = True,
               model: str = "hapke2012", parameters="helfenstein1987") -> torch.Tensor:
    """Image of the lunar disc: spectral radiance on an n × n pixel grid (Müller Fig. 1).

    Parameters
    ----------
    phase_angle_rad, bright_limb_angle_rad : Tensor (...)
        Phase angle α and bright-limb position angle χ [rad].
    n_pixels : int
        Pixels across the lunar diameter.
    wavelength_nm : Tensor (n_wavelength,), optional
        Wavelengths [nm]; default: the RGB wavelengths (680, 550, 440).
    sun_distance_m, distance_m, earthshine, model, parameters
        As in :func:`disc_radiance`.

    Returns
    -------
    Tensor (..., y, x, n_wavelength)
        Radiance [W m^-2 sr^-1 nm^-1]; row 0 is the southern edge (y increases north),
        column 0 the eastern edge (x increases west); 0 outside the disc.
    """
    n_pixels = check_int("n_pixels", n_pixels, low=1, high=4096)
    dtype = common_dtype(phase_angle_rad, bright_limb_angle_rad)
    if wavelength_nm is None:
        wavelength_nm = torch.tensor([680.0, 550.0, 440.0], dtype=dtype)
    centres = (torch.arange(n_pixels, dtype=dtype) + 0.5) * (2.0 / n_pixels) - 1.0
    yy, xx = torch.meshgrid(centres, centres, indexing="ij")
    rr = xx * xx + yy * yy
    inside = rr < 1.0
    zz = torch.sqrt((1.0 - rr).clamp_min(0.0))
    # pixels outside the disc (masked below) get the unit normal of the nearest limb point,
    # so that every normal handed to the reflectance is a unit vector
    scale = torch.where(inside, torch.ones_like(rr), torch.rsqrt(rr.clamp_min(1e-300)))
    normal = torch.stack([xx * scale, yy * scale, zz], dim=-1).reshape(-1, 3)
    radiance = disc_radiance(normal, phase_angle_rad, wavelength_nm, bright_limb_angle_rad,
                             sun_distance_m=sun_distance_m, distance_m=distance_m,
                             earthshine=earthshine, model=model, parameters=parameters)
    radiance = radiance * inside.reshape(-1, 1).to(radiance.dtype)
    return radiance.reshape(radiance.shape[:-2] + (n_pixels, n_pixels, radiance.shape[-1]))
