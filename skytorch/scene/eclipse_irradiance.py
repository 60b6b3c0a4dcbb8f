r"""Irradiance on a horizontal surface during a solar eclipse: direct, diffuse and global.

The direct beam is the Sun's limb-darkened visible fraction at the observer times the
clear-sky beam; the diffuse part is the eclipse sky of
:mod:`skytorch.scene.solar_eclipse_sky` (orders 1 and 2, the visible fraction at every
scattering point) integrated over the upper hemisphere, :math:`\int L\cos\theta\,d\Omega`.
The same quadrature without the Moon gives the uneclipsed reference, so that the ratio
(what a pyranometer records against a clear day) carries no quadrature error of its own to
first order.

* :func:`eclipsed_horizontal_irradiance` — spectral direct and diffuse irradiance per unit
  extraterrestrial irradiance, with or without the Moon.
* :func:`solar_eclipse_irradiance` — the user path: time and place in, an
  :class:`xarray.Dataset` with the eclipsed and uneclipsed spectra and their band
  integrals out.

Notes
-----
Straight rays, black ground, orders 1 and 2 of the sky (orders :math:`\ge 3` are left
out of both the eclipsed and the uneclipsed diffuse irradiance: by day they are some
0.4–0.8 of order 2 at the zenith, so the absolute diffuse irradiance is low, while the
ratio is not affected as long as the visible fraction varies little over the air that
scatters, docs/solar_eclipse_sky.md). The Sun's linear limb darkening is
:math:`u = 0.6` at every wavelength.

References
----------
1. Koepke, P. et al. 2001, Atmos. Chem. Phys. 1, 49, doi:10.5194/acp-1-49-2001.
2. Ilić, L. et al. 2018, J. Atmos. Sol.-Terr. Phys. 171, 250,
   doi:10.1016/j.jastp.2017.10.001 (Belgrade, 2015-03-20: global radiation down 48 % at
   51 % coverage of the disc).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import torch

from skytorch._quadrature import unit_nodes
from skytorch._validate import as_tensor, check_int
from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.scattering import second_order_radiance, single_scattering_radiance
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable
from skytorch.scene.geometry import site_geometries
from skytorch.scene.solar_eclipse_sky import (
    eclipsed_second_order,
    eclipsed_single_scattering,
    sun_direction,
    visible_fraction_at,
)

__all__ = ["DEFAULT_WAVELENGTHS_NM", "HorizontalIrradiance", "eclipsed_horizontal_irradiance",
           "solar_eclipse_irradiance"]

#: lines of sight per call of the second order (as the scene's eclipse sky)
_SECOND_ORDER_CHUNK = 4


class HorizontalIrradiance(NamedTuple):
    """Irradiance on a horizontal surface per unit extraterrestrial irradiance (wl,) [1]."""

    direct: torch.Tensor
    diffuse: torch.Tensor

    @property
    def global_(self) -> torch.Tensor:
        """Direct plus diffuse (wl,) [1]."""
        return self.direct + self.diffuse


def _hemisphere(n_mu: int, n_phi: int):
    """Zenith, azimuth (n_mu, n_phi) [rad] and weights cos(theta) dOmega of the upper sky."""
    x, w = unit_nodes(n_mu)
    phi = (torch.arange(n_phi, dtype=torch.float64) + 0.5) * (2.0 * math.pi / n_phi)
    zenith = torch.acos(x)[:, None].expand(n_mu, n_phi)
    azimuth = phi[None, :].expand(n_mu, n_phi)
    weight = (w * x)[:, None].expand(n_mu, n_phi) * (2.0 * math.pi / n_phi)
    return zenith, azimuth, weight


def eclipsed_horizontal_irradiance(atmosphere, wavelength_nm, geometry,
                                   altitude_m: float = 0.0, *, moon: bool = True,
                                   n_mu: int = 6, n_phi: int = 16, n_samples: int = 48,
                                   second_order: tuple[int, int, int, int] | None
                                   = (12, 4, 12, 12),
                                   table=None, n_nodes: int = 8) -> HorizontalIrradiance:
    r"""Direct and diffuse spectral irradiance on a horizontal surface, eclipse or not.

    Parameters
    ----------
    atmosphere : Atmosphere
        Scalar parameters.
    wavelength_nm : Tensor (wavelength,)
        [nm].
    geometry : skytorch.scene.geometry.Geometry
        Sun and Moon at the observer (:func:`skytorch.scene.geometry.site_geometries`).
    altitude_m : float
        Observer's height [m].
    moon : bool
        With the Moon (True) or the same sky and Sun without it (the clear-day reference).
    n_mu, n_phi : int
        Hemisphere quadrature: Gauss–Legendre nodes in :math:`\cos\theta` on (0, 1) and
        uniform azimuths, >= 1.
    n_samples : int
        Samples along each line of sight of the single scattering, >= 2.
    second_order : tuple of int or None
        ``(n_view, n_mu, n_phi, n_samples)`` of
        :func:`skytorch.scene.solar_eclipse_sky.eclipsed_second_order`; None for single
        scattering only.
    table : TransmittanceTable, optional
        The Sun's transmittance from each scattering point (integrated when not given).
    n_nodes : int
        Quadrature nodes of the visible fraction.

    Returns
    -------
    HorizontalIrradiance
        ``direct`` :math:`f_\odot\cos z_\odot\,T(z_\odot)` and ``diffuse``
        :math:`\int_{2\pi}(L_1 + L_2)\cos\theta\,d\Omega`, each (wavelength,) per unit
        extraterrestrial irradiance normal to the beam [1] (0 with the Sun below the
        horizon for ``direct``).

    Notes
    -----
    The direct beam's transmittance is along the straight ray
    (:meth:`skytorch.atmosphere.Atmosphere.transmittance`); :math:`f_\odot` is
    :func:`~skytorch.scene.solar_eclipse_sky.visible_fraction_at` the observer (1 without
    the Moon).

    Examples
    --------
    >>> import numpy as np, torch, skytorch as st
    >>> from skytorch.scene.geometry import site_geometries
    >>> g = site_geometries(np.datetime64("2015-03-20T09:45"), [53.5], [10.1], [0.0])[0]
    >>> wl = torch.tensor([550.0], dtype=torch.float64)
    >>> atm = st.Atmosphere.earth(2.0)
    >>> e = eclipsed_horizontal_irradiance(atm, wl, g, n_mu=2, n_phi=4, n_samples=8,
    ...                                    second_order=None)
    >>> c = eclipsed_horizontal_irradiance(atm, wl, g, moon=False, n_mu=2, n_phi=4,
    ...                                    n_samples=8, second_order=None)
    >>> round(float(e.global_ / c.global_), 2)
    0.17
    """
    if not isinstance(moon, bool):
        raise TypeError(f"moon must be a bool; got {type(moon).__name__}")
    n_mu = check_int("n_mu", n_mu, 1)
    n_phi = check_int("n_phi", n_phi, 1)
    if second_order is not None:
        if len(tuple(second_order)) != 4:
            raise ValueError("second_order must be (n_view, n_mu, n_phi, n_samples) or None; "
                             f"got {second_order!r}")
        n_view, so_mu, so_phi, so_samples = (int(v) for v in second_order)
    wavelength = as_tensor("wavelength_nm", wavelength_nm).to(torch.float64)
    zenith, azimuth, weight = _hemisphere(n_mu, n_phi)
    sun_zenith, sun_azimuth = sun_direction(geometry)
    radiance = _first_order(atmosphere, wavelength, zenith, azimuth, geometry, altitude_m,
                            moon, n_samples=n_samples, table=table, n_nodes=n_nodes)
    if second_order is not None:
        z, a = zenith.reshape(-1), azimuth.reshape(-1)
        parts = [_second_order(atmosphere, wavelength, z[i:i + _SECOND_ORDER_CHUNK],
                               a[i:i + _SECOND_ORDER_CHUNK], geometry, altitude_m, moon,
                               n_view=n_view, n_mu=so_mu, n_phi=so_phi,
                               n_samples=so_samples, table=table, n_nodes=n_nodes)
                 for i in range(0, z.numel(), _SECOND_ORDER_CHUNK)]
        radiance = radiance + torch.cat(parts).reshape(radiance.shape)
    diffuse = (radiance * weight[..., None]).sum((0, 1))
    if float(sun_zenith) >= 0.5 * math.pi:
        return HorizontalIrradiance(torch.zeros_like(diffuse), diffuse)
    fraction = (visible_fraction_at(geometry, torch.zeros(3, dtype=torch.float64),
                                    n_nodes=n_nodes) if moon else 1.0)
    beam = atmosphere.transmittance(wavelength, sun_zenith, float(altitude_m))
    return HorizontalIrradiance(fraction * torch.cos(sun_zenith) * beam, diffuse)


def _first_order(atmosphere, wavelength, zenith, azimuth, geometry, altitude_m, moon, *,
                 n_samples, table, n_nodes):
    """Single-scattered radiance (..., wl) [1/sr]: the eclipse kernel or the atmosphere's."""
    if moon:
        return eclipsed_single_scattering(atmosphere, wavelength, zenith, azimuth, geometry,
                                          altitude_m, n_samples=n_samples, table=table,
                                          n_nodes=n_nodes)
    sun_zenith, sun_azimuth = sun_direction(geometry)
    return single_scattering_radiance(atmosphere, wavelength, zenith, azimuth, sun_zenith,
                                      sun_azimuth, float(altitude_m), n_samples=n_samples,
                                      table=table)


def _second_order(atmosphere, wavelength, zenith, azimuth, geometry, altitude_m, moon, *,
                  n_view, n_mu, n_phi, n_samples, table, n_nodes):
    """Second order (..., wl) [1/sr]: with the visible fraction or the atmosphere's own.

    The same quadrature either way; with the Moon, the fraction weighs every first
    scattering.
    """
    if moon:
        return eclipsed_second_order(atmosphere, wavelength, zenith, azimuth, geometry,
                                     altitude_m, n_view=n_view, n_mu=n_mu, n_phi=n_phi,
                                     n_samples=n_samples, table=table, n_nodes=n_nodes)
    sun_zenith, sun_azimuth = sun_direction(geometry)
    return second_order_radiance(atmosphere.constituents(wavelength), zenith, azimuth,
                                 sun_zenith, sun_azimuth,
                                 torch.tensor(float(altitude_m), dtype=torch.float64),
                                 n_view=n_view, n_mu=n_mu, n_phi=n_phi, n_samples=n_samples,
                                 table=table)


#: default wavelengths of :func:`solar_eclipse_irradiance` [nm]: the silicon and most of a
#: thermopile pyranometer's band (about 70 % of the clear-sky global irradiance)
DEFAULT_WAVELENGTHS_NM = tuple(float(v) for v in range(350, 1051, 50))

#: (long name, description) of the spectral variables of :func:`solar_eclipse_irradiance`
_SPECTRAL_VARIABLES = {
    "direct": ("direct horizontal irradiance during the eclipse",
               "visible fraction of the limb-darkened Sun at the observer times the clear-sky "
               "beam on a horizontal surface"),
    "diffuse": ("diffuse horizontal irradiance during the eclipse",
                "orders 1-2 of the eclipse sky (visible fraction at every scattering point) "
                "integrated over the upper hemisphere"),
    "global": ("global horizontal irradiance during the eclipse", "direct plus diffuse"),
    "direct_clear": ("direct horizontal irradiance without the Moon",
                     "the clear-sky beam on a horizontal surface"),
    "diffuse_clear": ("diffuse horizontal irradiance without the Moon",
                      "orders 1-2 of the sky with the same quadrature, without the Moon"),
    "global_clear": ("global horizontal irradiance without the Moon", "direct plus diffuse"),
}


def solar_eclipse_irradiance(time, lat_deg: float, lon_deg: float, elevation_m: float = 0.0,
                             *, atmosphere=None, wavelength_nm=DEFAULT_WAVELENGTHS_NM,
                             n_mu: int = 6, n_phi: int = 16, n_samples: int = 48,
                             second_order: tuple[int, int, int, int] | None = (12, 4, 12, 12),
                             table_size: tuple[int, int] = (128, 32)):
    r"""Direct, diffuse and global irradiance during a solar eclipse and without the Moon.

    Parameters
    ----------
    time : str or numpy.datetime64
        UTC instant (e.g. ``maximum_time`` of :func:`skytorch.eclipse.solar_eclipse_local`).
    lat_deg, lon_deg, elevation_m : float
        WGS84 latitude, east longitude [degree] and height [m] of the observer.
    atmosphere : Atmosphere, optional
        Default ``Atmosphere.earth(2.0)`` (turbidity 2: a clear day).
    wavelength_nm : sequence of float
        Spectral grid [nm] (default 350–1050 nm every 50 nm); the band integrals are
        trapezoids over it.
    n_mu, n_phi, n_samples, second_order
        Quadrature of :func:`eclipsed_horizontal_irradiance`.
    table_size : (int, int)
        ``(n_mu, n_r)`` of the transmittance table for the Sun's beam at each scattering.

    Returns
    -------
    xarray.Dataset
        Over ``wavelength``: ``direct``, ``diffuse``, ``global`` and the same with
        ``_clear`` (without the Moon) [W m-2 nm-1]; scalars ``global_ratio``,
        ``direct_ratio``, ``diffuse_ratio`` (band integrals, eclipse over clear),
        ``visible_fraction`` at the observer and ``sun_altitude`` [degree].

    Examples
    --------
    >>> ds = solar_eclipse_irradiance("2015-03-20T09:44:47", 53.52, 10.10,
    ...                               wavelength_nm=(550.0,), n_mu=2, n_phi=4,
    ...                               n_samples=8, second_order=None)
    >>> round(float(ds.global_ratio), 2)
    0.17
    """
    from skytorch.atmosphere.tables import TransmittanceTable
    from skytorch.ephemeris import parse_times
    from skytorch.spectrum import solar_irradiance

    instant = parse_times(time)
    if instant.shape != (1,):
        raise ValueError(f"time must be one instant; got {instant.shape[0]}")
    atmosphere = Atmosphere.earth(2.0) if atmosphere is None else atmosphere
    wavelength = as_tensor("wavelength_nm", wavelength_nm).to(torch.float64).reshape(-1)
    geometry = site_geometries(instant[0], [float(lat_deg)], [float(lon_deg)],
                               [float(elevation_m)])[0]
    table = TransmittanceTable.build(atmosphere, wavelength, n_mu=table_size[0],
                                     n_r=table_size[1])
    options = {"n_mu": n_mu, "n_phi": n_phi, "n_samples": n_samples,
               "second_order": second_order, "table": table}
    spectrum = solar_irradiance(wavelength)
    eclipsed = eclipsed_horizontal_irradiance(atmosphere, wavelength, geometry, elevation_m,
                                              **options)
    clear = eclipsed_horizontal_irradiance(atmosphere, wavelength, geometry, elevation_m,
                                           moon=False, **options)
    values = {"direct": eclipsed.direct, "diffuse": eclipsed.diffuse,
              "direct_clear": clear.direct, "diffuse_clear": clear.diffuse}
    values = {name: value * spectrum for name, value in values.items()}
    values["global"] = values["direct"] + values["diffuse"]
    values["global_clear"] = values["direct_clear"] + values["diffuse_clear"]

    def band(name):
        return float(torch.trapezoid(values[name], wavelength)) if wavelength.numel() > 1 \
            else float(values[name][0])

    def ratio(name):
        below = band(f"{name}_clear")
        return band(name) / below if below > 0.0 else float("nan")

    spectral = {name: variable("wavelength", values[name],
                               VariableSpec("W m-2 nm-1", *_SPECTRAL_VARIABLES[name]))
                for name in _SPECTRAL_VARIABLES}
    scalars = {f"{name}_ratio": variable((), np.float64(ratio(name)), VariableSpec(
        "1", f"{name} irradiance during the eclipse over the clear value",
        "band integrals over the wavelength grid")) for name in ("global", "direct", "diffuse")}
    fraction = float(visible_fraction_at(geometry, torch.zeros(3, dtype=torch.float64)))
    scalars["visible_fraction"] = variable((), np.float64(fraction), VariableSpec(
        "1", "visible fraction of the Sun's limb-darkened flux at the observer"))
    scalars["sun_altitude"] = variable((), np.float64(geometry.sun_altitude_deg), VariableSpec(
        "degree", "geometric altitude of the Sun's centre"))
    return build_dataset(
        {**spectral, **scalars},
        {"wavelength": coordinate("wavelength", wavelength, VariableSpec("nm", "wavelength"))},
        title="Horizontal irradiance during a solar eclipse",
        references=["Koepke, P. et al. 2001, Atmos. Chem. Phys. 1, 49, "
                    "doi:10.5194/acp-1-49-2001"],
        parameters={"time": str(instant[0]), "lat_deg": float(lat_deg),
                    "lon_deg": float(lon_deg), "elevation_m": float(elevation_m),
                    "n_mu": n_mu, "n_phi": n_phi, "n_samples": n_samples,
                    "second_order": "none" if second_order is None else list(second_order),
                    "table_size": list(table_size), "limb_darkening": 0.6,
                    "orders": "1" if second_order is None else "1-2"})
