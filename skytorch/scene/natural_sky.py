r"""The natural night sky per view direction: zodiacal light, airglow and starlight.

:func:`natural_component` has the signature of the renderer's components
(:mod:`skytorch.scene.render`) and returns the spectral radiance image
``(*view, wavelength)`` [W m^-2 sr^-1 nm^-1] of three sources:

* zodiacal light — :func:`skytorch.nightsky.zodiacal_spectral_radiance` at each pixel's
  helio-ecliptic longitude and ecliptic latitude for the scene's instant (Sun from the
  scene geometry; J2000 mean obliquity), above the atmosphere;
* airglow — flat in f_λ across the visible, its observed zenith V level
  :func:`skytorch.nightsky.airglow_zenith_mag` for the solar flux
  ``knobs.solar_flux_sfu`` (130 sfu when the knobs carry none), brightened towards the
  horizon by the van Rhijn factor of a layer at ``knobs.airglow_height_m``;
* integrated starlight of the Gaia catalogue stars the scene does not draw as points
  (those are the Hipparcos stars of V ≤ ``knobs.star_limit_mag``) and, beyond the
  catalogue (G > 10), the Pioneer 10/11 starlight and diffuse galactic light of Leinert et al. 1998
  Table 35 less the catalogue's share, with the solar spectral shape
  (:func:`skytorch.nightsky.catalogue_starlight_map`,
  :func:`skytorch.nightsky.faint_starlight.faint_starlight_v_radiance`).

Each is dimmed by the V-band extinction along the line of sight of a source of solar
colour (:func:`skytorch.stars.extinction` on the scene's extinction table, refracted paths
when ``knobs.refraction``): the zodiacal light and starlight by the whole extinction, the
airglow relative to the zenith, as its level is an observed one. The airglow scattered
once into the line of sight (:mod:`skytorch.nightsky.scattered_light`: the layer lights
the air over the whole sky; near the horizon this makes up for much of the extinction)
is added, the sum scaled so that the zenith keeps the observed level. The zodiacal light
and starlight scattered once into the line of sight are added as well (their radiance
above the air averaged over azimuth at each zenith angle, times the response of
:func:`skytorch.nightsky.scattered_light.scattered_zenith_response`); higher orders are not
included.

References
----------
1. Leinert, Ch. et al. 1998, A&AS 127, 1, doi:10.1051/aas:1998105.
2. Noll, S. et al. 2012, A&A 543, A92, doi:10.1051/0004-6361/201219040.
3. Garstang, R. H. 1989, PASP 101, 306, doi:10.1086/132436.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from skytorch.spectrum import interpolate_wavelength, solar_irradiance

__all__ = ["DEFAULT_SOLAR_FLUX_SFU", "ecliptic_coordinates", "natural_component",
           "view_icrs_vectors"]

#: 10.7 cm solar flux used when the knobs carry none [sfu] (the ESO sky model's reference)
DEFAULT_SOLAR_FLUX_SFU = 130.0
#: mean obliquity of the ecliptic at J2000.0 (IAU 2006) [rad]
OBLIQUITY_J2000_RAD = math.radians(23.439279444)
#: B−V of a solar-colour source for the V-band extinction
_SOLAR_BV = 0.65
#: V-band zero-magnitude flux density (Bessell et al. 1998) [W m^-2 nm^-1]
_V_ZERO_FLUX = 3.631e-11
#: one square arcsecond [sr]
_ARCSEC2_SR = (math.pi / 180.0 / 3600.0) ** 2
#: azimuths over which the zodiacal light and starlight above the air are averaged at each
#: zenith node of :data:`skytorch.scene.resources.SCATTERED_SKY_SOURCE_ZENITH_DEG`
SCATTERED_SKY_SOURCE_AZIMUTHS = 24


def ecliptic_coordinates(icrs_unit: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Ecliptic longitude and latitude [rad] of ICRS unit vectors (..., 3), J2000 ecliptic."""
    x, y, z = icrs_unit.unbind(-1)
    c, s = math.cos(OBLIQUITY_J2000_RAD), math.sin(OBLIQUITY_J2000_RAD)
    ye, ze = y * c + z * s, -y * s + z * c
    return torch.atan2(ye, x), torch.asin(ze.clamp(-1.0, 1.0))


def view_icrs_vectors(view, knobs) -> torch.Tensor:
    """ICRS unit vectors (*view, 3) of the pixel directions at the scene's instant and site."""
    return view.unit_vectors() @ view_icrs_matrix(knobs)  # u = M^T h, as rows


def _extinction_mag(resources, view, knobs) -> tuple[torch.Tensor, torch.Tensor]:
    """V extinction [mag] of a solar-colour source at each pixel and at the zenith."""
    from skytorch.stars import extinction

    table = resources.extinction_table(knobs.elevation_m, knobs.refraction)
    altitude = (0.5 * math.pi - view.zenith_rad.to(torch.float64)).reshape(1, -1)
    bv = torch.tensor([_SOLAR_BV], dtype=torch.float64)
    delta, _ = extinction(bv, torch.cat([altitude.new_full((1, 1), 0.5 * math.pi), altitude],
                                        dim=1), table)
    return delta[0, 1:].reshape(view.zenith_rad.shape), delta[0, 0]


def _v_mag(spectrum: torch.Tensor, wavelength: torch.Tensor) -> torch.Tensor:
    from skytorch.moon.sky import radiance_to_mag_arcsec2

    return radiance_to_mag_arcsec2(spectrum, wavelength)


def natural_component(resources, view, geometry, wavelength, knobs) -> torch.Tensor:
    r"""Zodiacal light, airglow and integrated starlight (*view, wl) [W m^-2 sr^-1 nm^-1].

    Parameters
    ----------
    resources : SceneResources
        Its atmosphere (planet radius) and V-band extinction table.
    view : View
        Pixel directions; pixels not ``view.valid`` are 0.
    geometry : Geometry
        The Sun's horizontal vector ``sun_horizontal_m`` at the instant.
    wavelength : Tensor (wavelength,)
        Scene wavelengths [nm].
    knobs : Knobs
        ``time``, ``lat_deg``, ``lon_deg``, ``elevation_m``, ``refraction``,
        ``star_limit_mag``, ``airglow_height_m``, ``dtype`` and ``solar_flux_sfu``.

    Returns
    -------
    Tensor (*view, wavelength)

    Notes
    -----
    .. math:: L = \bigl[L_{ZL} + L_\star\bigr] 10^{-0.4\,\Delta m(h)}
              + \sum_k \langle L_{ZL} + L_\star\rangle_k R_k(z, \lambda) + L_{AG,0}\,
              \frac{V(z)\,10^{-0.4\,\Delta m(h)} + s(z, \lambda)}
                   {10^{-0.4\,\Delta m(90°)} + s_V(0)},

    with :math:`\Delta m` the V-band extinction, :math:`V(z)` the van Rhijn factor,
    :math:`s` the singly scattered airglow per unit zenith emission, :math:`L_{AG,0}`
    the observed zenith airglow, :math:`\langle\cdot\rangle_k` the azimuthal mean above
    the air at the zenith angle of node :math:`k` and :math:`R_k` the scattered response
    to it (:meth:`SceneResources.scattered_sky_response`).
    """
    from skytorch.nightsky import (
        airglow_zenith_mag,
        van_rhijn,
    )

    wl = wavelength.to(torch.float64).reshape(-1)
    zenith = view.zenith_rad.to(torch.float64)
    icrs = view_icrs_vectors(view, knobs)
    sun_h = torch.tensor(geometry.sun_horizontal_m, dtype=torch.float64)
    sun_lon, _ = ecliptic_coordinates(
        (sun_h / torch.linalg.vector_norm(sun_h)) @ view_icrs_matrix(knobs))
    above_air = _zodiacal_and_starlight(icrs, sun_lon, wl, knobs)

    flux = knobs.solar_flux_sfu
    flat = torch.ones_like(wl)
    airglow_level = 10.0 ** (-0.4 * (airglow_zenith_mag(float(flux)) - _v_mag(flat, wl)))
    path = van_rhijn(zenith.clamp(max=0.5 * math.pi),
                     layer_height_m=float(knobs.airglow_height_m),
                     planet_radius_m=float(resources.atmosphere.planet_radius_m),
                     observer_height_m=float(knobs.elevation_m))

    delta, delta_zenith = _extinction_mag(resources, view, knobs)
    space = 10.0 ** (-0.4 * delta)
    airglow = _airglow(resources, knobs, zenith, wl, path * space, 10.0 ** (-0.4 * delta_zenith))
    scattered = _scattered_zodiacal_and_starlight(resources, knobs, zenith, sun_lon, wl)
    image = above_air * space[..., None] + scattered + airglow_level * airglow
    valid = view.valid[..., None].to(torch.float64)
    return (image * valid).to(knobs.dtype)


def _zodiacal_and_starlight(icrs, sun_lon, wavelength, knobs) -> torch.Tensor:
    """Zodiacal light and integrated starlight above the air (..., wl) [W m^-2 sr^-1 nm^-1].

    At ICRS unit vectors (..., 3); ``sun_lon`` the Sun's ecliptic longitude [rad].
    """
    from skytorch.nightsky import (
        catalogue_starlight_map,
        starlight_v_radiance,
        zodiacal_spectral_radiance,
    )
    from skytorch.nightsky.faint_starlight import (
        faint_starlight_table,
        faint_starlight_v_radiance,
    )

    lon, lat = ecliptic_coordinates(icrs)
    zodiacal = zodiacal_spectral_radiance(lon - sun_lon, lat, wavelength)
    solar = solar_irradiance(wavelength)
    solar_mag = _v_mag(solar, wavelength)
    # catalogue stars not drawn as points, then the Pioneer 10/11 starlight fainter than
    # the catalogue (G > 10 and diffuse galactic light)
    star_v = (starlight_v_radiance(icrs, catalogue_starlight_map(float(knobs.star_limit_mag)))
              + faint_starlight_v_radiance(icrs, faint_starlight_table()))
    star_mag_per_unit = -2.5 * math.log10(_ARCSEC2_SR / _V_ZERO_FLUX)  # V of 1 W m^-2 sr^-1 nm^-1
    star_scale = 10.0 ** (-0.4 * (star_mag_per_unit - solar_mag))  # solar shape at V = 1 unit
    return zodiacal + (star_v * star_scale)[..., None] * solar


def _scattered_zodiacal_and_starlight(resources, knobs, zenith, sun_lon, wavelength,
                                      source=None) -> torch.Tensor:
    r"""Zodiacal light and starlight scattered once into the lines of sight (..., wl).

    Their radiance above the air averaged over azimuth at the zenith angles of
    :data:`~skytorch.scene.resources.SCATTERED_SKY_SOURCE_ZENITH_DEG` (the sky below the
    horizon included: rays from there reach the air at altitude), times the response of
    :meth:`SceneResources.scattered_sky_response` (interpolated in zenith angle and, in
    log, in wavelength). The azimuthal structure of the sources (the Milky Way's band, the
    zodiacal cone) is averaged out of the scattered light (exact for the zenith's line of
    sight, whose scattering angles depend on the incoming zenith angle alone; near the
    horizon rings the 24 azimuths sample the Milky Way's band coarsely). ``source``
    (default :func:`_zodiacal_and_starlight`) gives the radiance above the air; the stars
    drawn as points (brighter than ``knobs.star_limit_mag``) are not in it, so their
    scattered light is left out.
    """
    source = _zodiacal_and_starlight if source is None else source
    views, node_wavelength, source_zenith, response = resources.scattered_sky_response(
        knobs.elevation_m)
    azimuth = torch.arange(SCATTERED_SKY_SOURCE_AZIMUTHS, dtype=torch.float64) * (
        2.0 * math.pi / SCATTERED_SKY_SOURCE_AZIMUTHS)
    z, a = torch.broadcast_tensors(source_zenith[:, None], azimuth[None, :])
    horizontal = torch.stack([torch.sin(z) * torch.cos(a), torch.sin(z) * torch.sin(a),
                              torch.cos(z)], dim=-1)
    incident = source(horizontal @ view_icrs_matrix(knobs), sun_lon, wavelength,
                      knobs).mean(1)  # (source node, wl)
    response = interpolate_wavelength(response, node_wavelength, wavelength)
    table = (incident[:, None, :] * response).sum(0)  # (view node, wl)
    position = torch.bucketize(zenith.clamp(max=float(views[-1])).contiguous(), views)
    upper = position.clamp(1, views.numel() - 1)
    t = ((zenith - views[upper - 1]) / (views[upper] - views[upper - 1]))[..., None]
    return (1.0 - t) * table[upper - 1] + t * table[upper]


def _airglow(resources, knobs, zenith, wavelength, direct, direct_zenith) -> torch.Tensor:
    r"""Airglow per unit observed zenith level (*view, wavelength) [1].

    Direct (van Rhijn path times extinction, ``direct``) plus the airglow scattered once
    into the line of sight (:meth:`SceneResources.scattered_airglow_table`, log-interpolated
    in wavelength and linear in zenith angle), divided by the same sum at the zenith in
    the V band, so that the zenith keeps the observed level:
    :math:`[V(z) T(z) + s(z, \lambda)] / [T(0) + s_V(0)]`.
    """
    nodes, node_wavelength, table = resources.scattered_airglow_table(
        knobs.elevation_m, knobs.airglow_height_m)
    table = interpolate_wavelength(table, node_wavelength, wavelength)  # (zenith, wl)
    position = torch.bucketize(zenith.clamp(max=float(nodes[-1])).contiguous(), nodes)
    upper = position.clamp(1, nodes.numel() - 1)
    t = ((zenith - nodes[upper - 1]) / (nodes[upper] - nodes[upper - 1]))[..., None]
    scattered = (1.0 - t) * table[upper - 1] + t * table[upper]
    flat = torch.ones_like(wavelength)
    zenith_scattered = 10.0 ** (-0.4 * (_v_mag(table[0], wavelength) - _v_mag(flat, wavelength)))
    return (direct[..., None] + scattered) / (direct_zenith + zenith_scattered)


def view_icrs_matrix(knobs) -> torch.Tensor:
    """Rotation (3, 3) from horizontal (north, east, up) rows to ICRS rows at the instant."""
    from skytorch.ephemeris import icrs_to_horizontal_matrices

    return icrs_to_horizontal_matrices(np.datetime64(knobs.time, "ns"), knobs.lat_deg,
                                       knobs.lon_deg)[0]
