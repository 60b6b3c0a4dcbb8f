r"""Composition of a scene's components into spectral radiance images.

Every component is a spectral radiance image ``(*view, wavelength)``
[W m^-2 sr^-1 nm^-1]; the image is their sum (Müller et al. 2012, §5: atmosphere,
then stars, Moon and Sun added as light sources; stars behind the Moon's disc are
occulted):

* ``natural`` — airglow, zodiacal light and unresolved stars: ``scene.natural_mag_arcsec2``
  at the zenith (22.0 V mag arcsec^-2, Falchi et al. 2016) with the solar spectral shape
  (zodiacal light is scattered sunlight); the airglow share brightens towards the
  horizon by the van Rhijn factor (:func:`natural_gradient`, Garstang 1989) and the whole
  is dimmed by the V-band extinction relative to the zenith (:func:`natural_extinction`).
* ``sky`` — single-scattered sunlight (:meth:`Atmosphere.sky_radiance`), tabulated on a
  (view zenith, relative azimuth) grid for the scene's Sun and interpolated bilinearly;
  the zenith nodes are denser towards the horizon (:math:`z = \tfrac{\pi}{2}\sin
  \tfrac{\pi u}{2}`) and the azimuth nodes towards the Sun (:math:`\phi = \pi u^2`).
  With the planner's orders of scattering above 1 the orders 2..N of the resources'
  multiple-scattering tables are added on the same nodes (:func:`higher_orders`: coarse
  tables at a few wavelength nodes, interpolated in log radiance; the exact single
  scattering keeps the aureole and the band absorbers).
* ``moon`` — the disc's irradiance (:func:`skytorch.moon.lunar_irradiance`) times the
  transmittance along the line of sight, spread over the pixel that holds it, plus the
  moonlit sky (:func:`skytorch.moon.sky.moonlit_sky_single_scattering`, plus the orders
  2..N of the Moon as a point source) tabulated like the sky; during an eclipse each
  pixel of the disc is multiplied by the relative
  illuminance of the Earth's shadow (:meth:`skytorch.eclipse.Shadow.relative_illuminance`)
  at the lunar surface point its centre sees (a disc smaller than a pixel, and the
  moonlit sky, by the shadow averaged over the disc), so a resolved disc shows the
  umbra's edge.
* ``sun`` — the solar irradiance times the transmittance, spread over its pixel.
* ``stars`` — catalogue stars (:func:`skytorch.stars.observe`, magnitudes after
  extinction) with black-body spectra of their B−V temperature
  (:func:`skytorch.spectrum.bv_to_temperature`) scaled to their V magnitudes.
* ``skyglow`` — :meth:`skytorch.skyglow.SkyglowModel.render` panorama interpolated to
  the view (model cached on disk, keyed by the atmosphere, wavelengths, settings and a
  hash of the skyglow and atmosphere sources; each file verified by its checksum and
  parameter hash on load, :mod:`skytorch._cache`).
"""

from __future__ import annotations

import logging
import math
import time as _time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import torch

from skytorch._angles import wrap_to_turn
from skytorch._validate import as_tensor
from skytorch.constants import ASTRONOMICAL_UNIT_M, MOON_RADIUS_M, SUN_RADIUS_M
from skytorch.dataset import VariableSpec, coordinate, time_coordinate, variable
from skytorch.scene.dataset import scene_dataset, stack_frames
from skytorch.scene.planner import Plan, scene_key
from skytorch.scene.planner import plan as make_plan
from skytorch.scene.presets import FIDELITY, HORIZON_REFRACTION_RAD, RESOLVED_DISC_PIXELS
from skytorch.scene.resources import SceneResources

logger = logging.getLogger(__name__)

#: components of an image, in composition order
COMPONENTS = ("natural", "sky", "skyglow", "stars", "moon", "sun")
#: largest view zenith angle of the moonlit-sky table [rad] (its valid range is < 90°)
_MAX_MOONLIT_ZENITH = math.radians(89.9)


@dataclass(frozen=True, eq=False)
class Knobs:
    """What a renderer reads besides its resources, view, geometry and wavelengths.

    ``knobs[name]`` reads the fidelity preset (:data:`skytorch.scene.presets.FIDELITY`);
    the attributes are the scene's settings of one observer and instant and the planner's
    decisions that change how a component is drawn.

    Attributes
    ----------
    fidelity : mapping
        The modules' knobs of the scene's fidelity preset.
    dtype : torch.dtype
        Floating type of the images.
    time : numpy.datetime64
        UTC instant.
    lat_deg, lon_deg, elevation_m : float
        The observer [degree, degree, m].
    refraction, earthshine, eclipse, solar_eclipse : bool
        Effects the planner computes.
    star_limit_mag, natural_mag_arcsec2, natural_model, airglow_fraction
        The scene's settings of the stars and the natural background.
    airglow_height_m, solar_flux_sfu : float
        The airglow layer's height [m] and the 10.7 cm solar flux setting its level [sfu].
    light_map, observer_xy, lamp
        The scene's city lights.
    scattering_orders : dict
        The planner's orders of scattering (:attr:`skytorch.scene.planner.Plan.
        scattering_orders`): ``"sky"``, ``"moon"`` and the orders of the tables
        (``"tables"``).
    """

    fidelity: Mapping
    dtype: torch.dtype
    time: object
    lat_deg: float
    lon_deg: float
    elevation_m: float
    refraction: bool = False
    earthshine: bool = False
    eclipse: bool = False
    solar_eclipse: bool = False
    star_limit_mag: float = 6.5
    natural_mag_arcsec2: float = 22.0
    natural_model: str = "garstang1989"
    airglow_fraction: float = 0.6
    airglow_height_m: float = 90_000.0
    solar_flux_sfu: float = 130.0
    light_map: object = None
    observer_xy: tuple = (0.0, 0.0)
    lamp: str = "white"
    scattering_orders: Mapping = None

    def __getitem__(self, name: str):
        """Return the fidelity knob ``name``."""
        return self.fidelity[name]

    @classmethod
    def of(cls, scene, plan: Plan | None = None) -> Knobs:
        """Return the knobs of a one-observer scene and its plan (no effect flags without one)."""
        computed = () if plan is None else plan.computed
        return cls(FIDELITY[scene.fidelity], scene.dtype, scene.time, float(scene.lat_deg),
                   float(scene.lon_deg), float(scene.elevation_m),
                   refraction="refraction" in computed, earthshine="earthshine" in computed,
                   eclipse="eclipse" in computed,
                   solar_eclipse="solar_eclipse" in computed, star_limit_mag=scene.star_limit_mag,
                   natural_mag_arcsec2=scene.natural_mag_arcsec2,
                   natural_model=scene.natural_model, airglow_fraction=scene.airglow_fraction,
                   airglow_height_m=scene.airglow_height_m,
                   solar_flux_sfu=scene.solar_flux_sfu, light_map=scene.light_map,
                   observer_xy=tuple(scene.observer_xy), lamp=scene.lamp,
                   scattering_orders=(None if plan is None
                                      else dict(plan.scattering_orders)))

    def orders(self, source: str) -> int:
        """Orders of scattering of the ``"sky"`` or the ``"moon"`` (1 without a plan)."""
        return 1 if self.scattering_orders is None else int(self.scattering_orders[source])


def _zenith_nodes(n: int, dtype) -> torch.Tensor:
    u = torch.linspace(0.0, 1.0, n, dtype=dtype)
    return 0.5 * math.pi * torch.sin(0.5 * math.pi * u)


def _zenith_coordinate(zenith: torch.Tensor) -> torch.Tensor:
    """Inverse of :func:`_zenith_nodes` in [0, 1]."""
    return (2.0 / math.pi) * torch.asin((zenith / (0.5 * math.pi)).clamp(0.0, 1.0))


def _azimuth_nodes(n: int, dtype) -> torch.Tensor:
    """|Relative azimuth| nodes in [0, π], denser towards the source (φ = π u²)."""
    u = torch.linspace(0.0, 1.0, n, dtype=dtype)
    return math.pi * u * u


def _lookup(table: torch.Tensor, zenith: torch.Tensor, relative_azimuth: torch.Tensor):
    """Bilinear look-up of a (zenith node, |relative azimuth| node, wl) table."""
    n_z, n_a, n_wl = table.shape
    u = _zenith_coordinate(zenith.reshape(-1)) * 2.0 - 1.0
    phi = torch.remainder(relative_azimuth.reshape(-1) + math.pi, 2 * math.pi) - math.pi
    v = torch.sqrt(phi.abs() / math.pi) * 2.0 - 1.0
    grid = torch.stack([v, u], dim=-1).to(table.dtype)[None, None]  # (1, 1, P, 2)
    image = table.permute(2, 0, 1)[None]  # (1, wl, z, a)
    out = torch.nn.functional.grid_sample(image, grid, mode="bilinear",
                                          padding_mode="border", align_corners=True)
    return out[0, :, 0, :].T.reshape(*zenith.shape, n_wl)


def higher_orders(resources, knobs, source_zenith_rad: float, zenith, relative_azimuth,
                  wavelength, orders: int) -> torch.Tensor:
    r"""Orders 2..N of the sky per unit irradiance of a point source (..., wl) [sr^-1].

    From the resources' multiple-scattering tables
    (:meth:`~skytorch.scene.resources.SceneResources.scattering_tables`, resolution and
    wavelength nodes of the fidelity preset): ``radiance(N) - radiance(1)`` at the
    view zenith angles and azimuths relative to the source, for a source at
    ``source_zenith_rad``, interpolated from the nodes to ``wavelength`` in log radiance
    (:func:`skytorch.spectrum.interpolate_wavelength`).
    """
    tables = resources.scattering_tables(knobs.scattering_orders["tables"],
                                         knobs["ms_tables"], knobs["ms_wavelength_nodes"])
    source = torch.full_like(zenith, source_zenith_rad)
    args = (knobs.elevation_m, zenith, torch.remainder(relative_azimuth, 2.0 * math.pi),
            source)
    higher = (tables.radiance(*args, scattering_orders=orders)
              - tables.radiance(*args, scattering_orders=1))
    correction = final_gather_correction(resources, knobs, tables, source_zenith_rad, orders)
    if correction is not None:
        higher = higher * _lookup(correction, zenith, relative_azimuth)
    from skytorch.spectrum import interpolate_wavelength

    return interpolate_wavelength(higher, tables.wavelength_nm, wavelength)


def final_gather_correction(resources, knobs, tables, source_zenith_rad: float, orders: int):
    """Gathered over looked-up orders 2..N on the preset's coarse sky grid, or ``None``.

    With the fidelity knob ``ms_final_gather`` (``{"lut": (n_z, n_a), "quadrature":
    (n_view, n_mu, n_phi)}``), the ratio of
    :func:`skytorch.atmosphere.final_gather.higher_orders_gathered` to the tables' look-up
    at ``n_z`` zenith x ``n_a`` relative-azimuth nodes (those of the sky table), shape
    (n_z, n_a, table wavelengths): it removes most of what is left of the tables'
    interpolation error in a forward-peaked aerosol's orders >= 2
    (docs/multiple_scattering_validation.md) at the cost of ``n_z n_a`` gathered lines of
    sight per source.
    """
    setting = knobs["ms_final_gather"]
    if setting is None or orders < 2:
        return None
    from skytorch.atmosphere.final_gather import higher_orders_gathered

    n_view, n_mu, n_phi = setting["quadrature"]
    zenith = _zenith_nodes(setting["lut"][0], torch.float64)
    azimuth = _azimuth_nodes(setting["lut"][1], torch.float64)
    z, a = torch.meshgrid(zenith, azimuth, indexing="ij")
    source = torch.full_like(z, source_zenith_rad)
    altitude = torch.tensor(float(knobs.elevation_m), dtype=torch.float64)
    looked_up = (tables.radiance(altitude, z, a, source, scattering_orders=orders)
                 - tables.radiance(altitude, z, a, source, scattering_orders=1))
    gathered = higher_orders_gathered(tables, resources.atmosphere, altitude, z, a, source,
                                      scattering_orders=orders, n_view=n_view, n_mu=n_mu,
                                      n_phi=n_phi)
    return gathered / looked_up


def sky_table(resources, geometry, knobs, wavelength):
    """Sunlit-sky spectral radiance on the (zenith, relative azimuth) grid (z, a, wl).

    Single scattering (:meth:`Atmosphere.sky_radiance`) plus, when the planner keeps
    ``knobs.orders("sky") > 1``, the orders 2..N of :func:`higher_orders` times the
    extraterrestrial solar spectrum.
    """
    atm = resources.atmosphere
    n_z, n_a = knobs["sky_lut"]
    zenith = _zenith_nodes(n_z, torch.float64)
    azimuth = _azimuth_nodes(n_a, torch.float64)
    z, a = torch.meshgrid(zenith, azimuth, indexing="ij")
    sun_zenith = math.radians(90.0 - geometry.sun_altitude_deg)
    table = resources.transmittance_table(*knobs["transmittance"])
    wl = wavelength.to(torch.float64)
    single = atm.sky_radiance(wl, z, a, torch.full_like(z, sun_zenith),
                              torch.zeros_like(z), knobs.elevation_m, solar_irradiance=True,
                              n_samples=knobs["sky_samples"], table=table, scattering_orders=1)
    if knobs.orders("sky") == 1:
        return single
    from skytorch.spectrum import solar_irradiance

    return single + solar_irradiance(wl) * higher_orders(
        resources, knobs, sun_zenith, z, a, wl, knobs.orders("sky"))


def moon_table(resources, geometry, knobs, wavelength):
    """Moonlit-sky spectral radiance on the (zenith, relative azimuth) grid (z, a, wl).

    Single scattering (:func:`skytorch.moon.sky.moonlit_sky_single_scattering`) plus,
    when the planner keeps ``knobs.orders("moon") > 1``, the orders 2..N of the Moon as a
    point source: the Moon's irradiance above the atmosphere
    (:func:`skytorch.moon.lunar_irradiance`) times :func:`higher_orders` for the Moon's
    zenith angle, as :func:`skytorch.moon.sky.moonlit_sky_multiple_scattering`.
    """
    from skytorch.moon import lunar_irradiance
    from skytorch.moon.sky import moonlit_sky_single_scattering

    n_z, n_a = knobs["moon_lut"]
    zenith = _zenith_nodes(n_z, torch.float64).clamp(max=_MAX_MOONLIT_ZENITH)
    azimuth = _azimuth_nodes(n_a, torch.float64)
    z, a = torch.meshgrid(zenith, azimuth, indexing="ij")
    moon_zenith = min(math.radians(90.0 - geometry.moon_altitude_deg), _MAX_MOONLIT_ZENITH)
    phase = torch.tensor(geometry.phase_angle_rad, dtype=torch.float64)
    wl = wavelength.to(torch.float64)
    single = moonlit_sky_single_scattering(
        resources.atmosphere, phase, torch.tensor(moon_zenith, dtype=torch.float64), z, a,
        wavelength_nm=wl, distance_m=geometry.moon_distance_m,
        altitude_m=knobs.elevation_m, n_steps=knobs["moon_steps"],
        n_quadrature=knobs["moon_quadrature"])
    if knobs.orders("moon") == 1:
        return single
    higher = higher_orders(resources, knobs, moon_zenith, z, a, wl, knobs.orders("moon"))
    return single + lunar_irradiance(phase, wl, distance_m=geometry.moon_distance_m,
                                     n_quadrature=knobs["moon_quadrature"]) * higher


def shadow_illuminance(resources, geometry, points_m: torch.Tensor, wavelength) -> torch.Tensor:
    """Relative illuminance of the Earth's shadow (n, wl) at points (n, 3) [m].

    The points are given from the observer in the horizontal frame (north, east, up);
    their distance along the anti-Sun axis and their offset from it are measured from the
    Earth's centre (:meth:`skytorch.eclipse.Shadow.relative_illuminance`).
    """
    observer = torch.tensor(geometry.observer_horizontal_m, dtype=torch.float64)
    sun = torch.tensor(geometry.sun_horizontal_m, dtype=torch.float64) + observer
    sun_distance = torch.linalg.vector_norm(sun)
    axis = sun / sun_distance
    geocentric = points_m.to(torch.float64) + observer
    along = -(geocentric @ axis)
    offset = torch.linalg.vector_norm(geocentric + along[..., None] * axis, dim=-1)
    return resources.shadow.relative_illuminance(along, offset, wavelength.to(torch.float64),
                                       sun_distance_m=sun_distance)


def moon_surface_points(geometry, directions: torch.Tensor) -> torch.Tensor:
    """Where lines of sight (n, 3) (unit, horizontal frame) meet the Moon's near side [m].

    A line that misses the sphere gives its point of closest approach to the centre.
    """
    centre = torch.tensor(geometry.moon_horizontal_m, dtype=torch.float64)
    along = directions @ centre
    discriminant = along * along - centre @ centre + MOON_RADIUS_M ** 2
    depth = along - torch.sqrt(discriminant.clamp(min=0.0))
    return depth[..., None] * directions


def _rotation(source: torch.Tensor, target: torch.Tensor):
    """Return the rotation taking the unit vector ``source`` to ``target`` (Rodrigues).

    As a function of vectors (..., 3).
    """
    axis = torch.linalg.cross(source, target)
    cosine = float(source @ target)

    def rotate(vectors):
        once = torch.linalg.cross(axis.expand_as(vectors), vectors)
        twice = torch.linalg.cross(axis.expand_as(vectors), once)
        return vectors + once + twice / (1.0 + cosine)

    return rotate


class MoonDisc:
    r"""The Moon's visible disc as the observer sees it, pixel by pixel.

    For a line of sight through the disc: the lunar surface point it meets (after rotation
    by the refraction of the Moon's centre), that point's normal, its radiance by the lunar
    reflectance law (:func:`skytorch.moon.disc_radiance`, with earthshine on the whole disc
    when ``earthshine``) and, with ``eclipse``, the relative illuminance of the Earth's
    shadow there (:func:`shadow_illuminance`).

    Parameters
    ----------
    resources : SceneResources
        The scene's tables (its shadow).
    geometry : Geometry
        Sun and Moon at the observer (:mod:`skytorch.scene.geometry`).
    wavelength : Tensor (wavelength,)
        [nm].
    apparent_altitude_rad : float
        Altitude of the Moon's apparent (refracted) centre [rad].
    earthshine, eclipse : bool
        Effects the planner computes.

    Notes
    -----
    Disc frame (as in :mod:`skytorch.moon.disc`, with the vertical in place of north):
    :math:`\hat z` from the Moon's centre towards the observer, :math:`\hat y` the
    zenith's direction projected on the disc (north when the Moon is at the zenith) and
    :math:`\hat x = \hat z \times \hat y` to the right of an observer facing the Moon. The
    unit vector :math:`s` from the Moon to the Sun in that frame gives the topocentric
    phase angle :math:`\alpha = \angle(s, \hat z)` and the position angle of the bright
    limb from the vertical through the left, :math:`\chi = \operatorname{atan2}(-s_x,
    s_y)` (the bright-limb angle of Meeus eq. 48.5 less the parallactic angle), so that
    :func:`skytorch.moon.sun_direction` :math:`(\alpha, \chi) = s`. Radiances follow the
    distances Moon–Sun and Moon–observer of the scene's geometry.
    """

    def __init__(self, resources, geometry, wavelength, apparent_altitude_rad: float, *,
                 earthshine: bool, eclipse: bool):
        self.resources, self.geometry, self.wavelength = resources, geometry, wavelength
        self.earthshine, self.eclipse = earthshine, eclipse
        self.centre = torch.tensor(geometry.moon_horizontal_m, dtype=torch.float64)
        line = self.centre / torch.linalg.vector_norm(self.centre)
        azimuth = math.radians(geometry.moon_azimuth_deg)
        self.apparent = torch.tensor([math.cos(apparent_altitude_rad) * math.cos(azimuth),
                                      math.cos(apparent_altitude_rad) * math.sin(azimuth),
                                      math.sin(apparent_altitude_rad)], dtype=torch.float64)
        self.rotate = _rotation(self.apparent, line)
        z_axis = -line
        vertical = torch.tensor([0.0, 0.0, 1.0] if abs(float(line[2])) < 0.999999
                                else [1.0, 0.0, 0.0], dtype=torch.float64)
        y_axis = vertical - (vertical @ z_axis) * z_axis
        y_axis = y_axis / torch.linalg.vector_norm(y_axis)
        self.axes = torch.stack([torch.linalg.cross(z_axis, y_axis), y_axis, z_axis])  # rows
        to_sun = torch.tensor(geometry.sun_horizontal_m, dtype=torch.float64) - self.centre
        s = self.axes @ (to_sun / torch.linalg.vector_norm(to_sun))
        self.phase_angle_rad = torch.atan2(torch.linalg.vector_norm(s[:2]), s[2])
        self.bright_limb_rad = torch.atan2(-s[0], s[1])
        self.mean_shadow = eclipse_factor(resources, geometry, wavelength, disc=self) \
            if eclipse else None

    def normals(self, directions: torch.Tensor) -> torch.Tensor:
        """Disc-frame normals (n, 3) of the surface points seen along directions (n, 3).

        The apparent directions are unit vectors in the horizontal frame; a line that misses the
        sphere takes its point of closest approach (a limb normal).
        """
        outward = moon_surface_points(self.geometry, self.rotate(directions)) - self.centre
        outward = outward / torch.linalg.vector_norm(outward, dim=-1, keepdim=True)
        return outward @ self.axes.T

    def radiance(self, normals: torch.Tensor) -> torch.Tensor:
        """Spectral radiance (n, wl) [W m^-2 sr^-1 nm^-1] above the atmosphere, uneclipsed.

        At disc-frame normals (n, 3), by :func:`skytorch.moon.disc_radiance`.
        """
        from skytorch.moon.disc import disc_radiance

        g = self.geometry
        return disc_radiance(normals, self.phase_angle_rad, self.wavelength.to(torch.float64),
                             self.bright_limb_rad, sun_distance_m=g.moon_sun_distance_m,
                             distance_m=g.moon_distance_m, earthshine=self.earthshine)

    def points(self, normals: torch.Tensor) -> torch.Tensor:
        """Lunar surface points (n, 3) [m] at disc-frame normals (n, 3).

        From the observer, in the horizontal frame.
        """
        return self.centre + MOON_RADIUS_M * (normals @ self.axes)

    def __call__(self, directions):
        """Relative radiance (n, wl) and shadow factor (n, wl) of pixels.

        Of pixels with apparent directions (n, 3); the factor is ``None`` without eclipse. For
        ``None``, the factor (wl,) of a disc smaller than a pixel (the disc-averaged shadow) or
        ``None``.
        """
        if directions is None:
            return self.mean_shadow
        normals = self.normals(directions)
        shadow = (shadow_illuminance(self.resources, self.geometry, self.points(normals),
                                     self.wavelength) if self.eclipse else None)
        return self.radiance(normals), shadow

    def bright_point(self) -> tuple[float, float]:
        r"""Apparent altitude and azimuth [rad] of the centroid of the sunlit part of the disc.

        :math:`\tfrac{4}{3\pi}(1 - \cos\alpha)` lunar radii from the centre towards the bright limb
        (where a crescent narrower than the pixels is drawn).
        """
        offset = 4.0 / (3.0 * math.pi) * (1.0 - math.cos(float(self.phase_angle_rad)))
        angle = offset * self.geometry.moon_radius_rad
        chi = float(self.bright_limb_rad)
        towards = -math.sin(chi) * self.axes[0] + math.cos(chi) * self.axes[1]
        towards = towards - (towards @ self.apparent) * self.apparent
        towards = towards / torch.linalg.vector_norm(towards)
        point = math.cos(angle) * self.apparent + math.sin(angle) * towards
        return math.asin(float(point[2])), math.atan2(float(point[1]), float(point[0]))


def eclipse_factor(resources, geometry, wavelength, n_disc: int = 8, disc=None) -> torch.Tensor:
    """Relative illuminance (n_wavelength,) of the Earth's shadow over the Moon's disc.

    Averaged over the Moon's visible disc, weighted by the uneclipsed radiance of the disc (the
    flux-weighted mean over :func:`skytorch.moon.disc_grid` points, 8 × 16 polar nodes by default).

    ``disc`` is the scene's :class:`MoonDisc` (its phase and earthshine set the weights);
    without it the disc is weighted by area.
    """
    from skytorch.moon.disc import disc_grid

    grid = disc_grid(n_disc, dtype=torch.float64)
    if disc is None:
        disc = MoonDisc(resources, geometry, wavelength,
                        math.radians(geometry.moon_altitude_deg),
                        earthshine=False, eclipse=False)
        weight = grid["weight"][:, None]
    else:
        weight = grid["weight"][:, None] * disc.radiance(grid["normal"])
    factor = shadow_illuminance(resources, geometry, disc.points(grid["normal"]), wavelength)
    total = weight.sum(0)
    return torch.where(total > 0, (weight * factor).sum(0) / total.clamp(min=1e-300),
                       factor.mean(0))


def _splat(view, altitude_rad, azimuth_rad, flux, n_wavelength, dtype) -> torch.Tensor:
    """Spread point fluxes (n, wl) [W m^-2 nm^-1] over their pixels as radiance."""
    image = torch.zeros(math.prod(view.shape), n_wavelength, dtype=dtype)
    index = view.pixel_index(altitude_rad, azimuth_rad)
    keep = index >= 0
    if bool(keep.any()):
        image.index_add_(0, index[keep], flux[keep].to(dtype))
    solid = view.solid_angle_sr.reshape(-1, 1).to(dtype)
    image = torch.where(solid > 0, image / solid.clamp(min=1e-300), torch.zeros_like(image))
    return image.reshape(*view.shape, n_wavelength)


def _disc(view, altitude_rad: float, azimuth_rad: float, radius_rad: float, flux,
          dtype, pattern=None) -> torch.Tensor:
    """Return a disc of angular radius ``radius_rad`` and total flux (wl,) as radiance.

    Without ``pattern`` the pixels whose centres lie within the radius share the flux in
    proportion to their solid angle (a uniformly bright disc). ``pattern`` (a
    :class:`MoonDisc`) shapes a disc over at least :data:`RESOLVED_DISC_PIXELS` pixels:
    each pixel's radiance is proportional to the pattern's relative radiance at its centre,
    normalised so that the pixels carry ``flux``, and then multiplied by the pattern's
    shadow factor; when no pixel centre falls on a lit part (a crescent narrower than the
    pixels) the flux goes to the pixel of the pattern's ``bright_point``. A smaller disc
    (whose few pixel centres would sample it too coarsely), or one smaller than a pixel,
    is uniform (or falls in the pixel that holds its centre) times ``pattern(None)``, the
    disc-averaged factor.
    """
    n_wavelength = flux.shape[-1]
    if view.kind == "directions" or altitude_rad + radius_rad < 0.0:
        return torch.zeros(*view.shape, n_wavelength, dtype=dtype)
    mean = pattern(None) if pattern is not None else None
    scaled = flux if mean is None else flux * mean
    point = torch.tensor([math.cos(altitude_rad) * math.cos(azimuth_rad),
                          math.cos(altitude_rad) * math.sin(azimuth_rad),
                          math.sin(altitude_rad)], dtype=torch.float64)
    cos_distance = view.unit_vectors() @ point
    inside = (cos_distance >= math.cos(radius_rad)) & (view.solid_angle_sr > 0)
    if not bool(inside.any()):
        return _splat(view, torch.tensor([altitude_rad]), torch.tensor([azimuth_rad]),
                      scaled[None], n_wavelength, dtype)
    solid = view.solid_angle_sr.to(torch.float64)
    if pattern is None or int(inside.sum()) < RESOLVED_DISC_PIXELS:
        weight = inside.to(torch.float64)
        return (weight[..., None] * (scaled.to(torch.float64)
                                     / float((weight * solid).sum()))).to(dtype)
    brightness, shadow = pattern(view.unit_vectors()[inside].to(torch.float64))
    norm = (brightness * solid[inside][:, None]).sum(0)
    if not bool((norm > 0).all()):  # no lit pixel centre: a crescent below a pixel
        altitude, azimuth = pattern.bright_point()
        return _splat(view, torch.tensor([altitude]), torch.tensor([azimuth]), scaled[None],
                      n_wavelength, dtype)
    radiance = flux.to(torch.float64) * brightness / norm
    if shadow is not None:
        radiance = radiance * shadow
    image = torch.zeros(*view.shape, n_wavelength, dtype=torch.float64)
    image[inside] = radiance
    return image.to(dtype)


def _apparent(resources, knobs, altitude_deg: float) -> float:
    true = math.radians(altitude_deg)
    return (resources.refracted_altitude(knobs.elevation_m, true) if knobs.refraction
            else true)


def _point_transmittance(resources, knobs, altitude_rad: float, wavelength) -> torch.Tensor:
    """Transmittance (wl,) towards a point source at apparent altitude [rad].

    Along the refracted ray when ``knobs.refraction`` (straight otherwise), from the
    observer's height; below the apparent horizon (0 at sea level, minus the dip for an
    elevated observer) the ray that grazes the ground.
    """
    low = resources.apparent_horizon(knobs.elevation_m, knobs.refraction)
    zenith = 0.5 * math.pi - max(altitude_rad, low)
    return resources.atmosphere.transmittance(wavelength.to(torch.float64),
                                              torch.tensor(zenith, dtype=torch.float64),
                                              knobs.elevation_m, refraction=knobs.refraction)


def natural_gradient(zenith_rad, airglow_fraction: float = 0.6,
                     airglow_height_m: float = 90_000.0, planet_radius_m: float = 6_371_000.0,
                     observer_height_m: float = 0.0):
    r"""Natural background relative to the zenith: :math:`(1 - f) + f\,V(z)`.

    Parameters
    ----------
    zenith_rad : Tensor (...)
        Zenith distance of the line of sight [rad], in [0, π/2].
    airglow_fraction : float
        Share :math:`f` of the zenith background emitted by the airglow layer.
    airglow_height_m, planet_radius_m, observer_height_m : float
        Height of the thin emitting layer, the planet's radius and the observer's height
        [m].

    Returns
    -------
    Tensor (...)
        1 at the zenith, growing towards the horizon (4.01 there for the defaults).

    Notes
    -----
    A thin layer of uniform emission at height :math:`h` is crossed by a line of sight at
    zenith distance :math:`z` over a path longer than the vertical one by the van Rhijn
    (1921) factor

    .. math:: V(z) = \left[1 - \left(\frac{R + h_o}{R + h}\right)^2 \sin^2 z
              \right]^{-1/2},

    the rest of the background (zodiacal light, starlight) does not depend on the
    path (Garstang 1989, eq. 29; Patat 2003, eq. C.1, with :math:`f = 0.6`).
    Extinction along the line of sight is applied separately
    (:func:`natural_extinction`, ``natural_model="garstang1989"``).

    References
    ----------
    1. van Rhijn, P. J. 1921, Publ. Astron. Lab. Groningen 31, 1.
    2. Garstang, R. H. 1989, PASP 101, 306, doi:10.1086/132436.
    3. Leinert, Ch. et al. 1998, A&AS 127, 1, doi:10.1051/aas:1998105.
    4. Patat, F. 2003, A&A 400, 1183, doi:10.1051/0004-6361:20030015.

    Examples
    --------
    >>> import math, torch
    >>> round(float(natural_gradient(torch.tensor(math.pi / 2))), 2)
    4.01
    """
    zenith_rad = as_tensor("zenith_rad", zenith_rad)
    if not 0.0 <= observer_height_m < airglow_height_m:
        raise ValueError(f"observer_height_m must be in [0, airglow_height_m = "
                         f"{airglow_height_m} m); got {observer_height_m} m")
    ratio = (planet_radius_m + observer_height_m) / (planet_radius_m + airglow_height_m)
    sine = torch.sin(zenith_rad)
    van_rhijn = torch.rsqrt(1.0 - ratio * ratio * sine * sine)
    return (1.0 - airglow_fraction) + airglow_fraction * van_rhijn


#: B−V of the natural background's spectrum, the solar colour (Holmberg et al. 2006:
#: 0.64 ± 0.02), for its V-band extinction
NATURAL_BACKGROUND_BV = 0.65


def natural_extinction(resources, view, knobs) -> torch.Tensor:
    r"""Extinction of the natural background relative to the zenith (*view) [1].

    :math:`10^{-0.4\,[\Delta m(h) - \Delta m(90°)]}`, with :math:`\Delta m(h)` the V-band
    extinction of a source of solar colour (B−V = :data:`NATURAL_BACKGROUND_BV`) seen at
    apparent altitude :math:`h` through the scene's atmosphere
    (:func:`skytorch.stars.extinction_table`: the V-band optical depth along the path,
    refracted when ``knobs.refraction``; the zenith extinction coefficient :math:`k` times the
    air mass :math:`X`, with the curvature of the band at large air mass). Relative to the
    zenith because the zenith value ``knobs.natural_mag_arcsec2`` is an observed one,
    extinction included.
    """
    from skytorch.stars import extinction

    table = resources.extinction_table(knobs.elevation_m, knobs.refraction)
    altitude = (0.5 * math.pi - view.zenith_rad.to(torch.float64)).reshape(1, -1)
    bv = torch.tensor([NATURAL_BACKGROUND_BV], dtype=torch.float64)
    delta, _ = extinction(bv, torch.cat([altitude.new_full((1, 1), 0.5 * math.pi), altitude],
                                        dim=1), table)
    return (10.0 ** (-0.4 * (delta[0, 1:] - delta[0, 0]))).reshape(view.zenith_rad.shape)


def natural_component(resources, view, geometry, wavelength, knobs) -> torch.Tensor:
    r"""Natural background (*view, wl) [W m^-2 sr^-1 nm^-1].

    ``knobs.natural_mag_arcsec2`` at the zenith with the solar spectral shape (zodiacal light is
    scattered sunlight).

    By ``knobs.natural_model``: ``"garstang1989"`` multiplies it by
    :func:`natural_gradient` and :func:`natural_extinction` (refracted paths when
    ``knobs.refraction``), ``"vanrhijn1921"`` by the gradient alone, ``"constant"`` by 1
    (``geometry`` is not used: the background does not depend on the Sun and Moon);
    ``"leinert1998"`` builds the sky per direction from zodiacal light, airglow and faint
    starlight (:func:`skytorch.scene.natural_sky.natural_component`).

    Notes
    -----
    Garstang (1989, eq. 29), Krisciunas & Schaefer (1991, eq. 2), Patat (2003, eq. C.1):

    .. math:: b(z) = b_0 \left[(1 - f) + f\,V(z)\right] 10^{-0.4\,k\,(X(z) - 1)},

    with :math:`b_0` the observed zenith value (22.0 V mag arcsec⁻², Falchi et al. 2016),
    :math:`V(z)` the van Rhijn factor of the airglow layer and :math:`k\,X` the V-band
    extinction along the line of sight. The zenith keeps its value; with the defaults
    (turbidity 2, k = 0.25 mag per air mass) the background is brightest near 20° altitude
    (21.72 mag arcsec⁻², against 21.52 without extinction at 30°) and fades below.
    Light of the glowing sky scattered into the line of sight, which partly makes up for
    the extinction near the horizon (Garstang 1989), is not included.

    References
    ----------
    1. Garstang, R. H. 1989, PASP 101, 306, doi:10.1086/132436.
    2. Krisciunas, K. & Schaefer, B. E. 1991, PASP 103, 1033, doi:10.1086/132921.
    3. Patat, F. 2003, A&A 400, 1183, doi:10.1051/0004-6361:20030015.
    """
    if knobs.natural_model == "leinert1998":
        from skytorch.scene import natural_sky

        return natural_sky.natural_component(resources, view, geometry, wavelength, knobs)
    from skytorch.moon.sky import radiance_to_mag_arcsec2
    from skytorch.spectrum import solar_irradiance

    shape = solar_irradiance(wavelength.to(torch.float64))
    mag = float(radiance_to_mag_arcsec2(shape, wavelength.to(torch.float64)))
    spectrum = shape * 10.0 ** (-0.4 * (knobs.natural_mag_arcsec2 - mag))
    valid = view.valid[..., None].to(knobs.dtype)
    image = valid * spectrum.to(knobs.dtype)
    if knobs.natural_model == "constant":
        return image
    factor = natural_gradient(view.zenith_rad.to(torch.float64), knobs.airglow_fraction,
                              knobs.airglow_height_m, resources.atmosphere.planet_radius_m,
                              float(knobs.elevation_m))
    if knobs.natural_model == "garstang1989":
        factor = factor * natural_extinction(resources, view, knobs)
    return image * factor[..., None].to(knobs.dtype)


def sun_component(resources, view, geometry, wavelength, knobs) -> torch.Tensor:
    """Return the solar disc (*view, wl) [W m^-2 sr^-1 nm^-1].

    Extraterrestrial irradiance times the transmittance at its (refracted) altitude, spread over its
    pixels.
    """
    from skytorch.spectrum import solar_irradiance

    altitude = _apparent(resources, knobs, geometry.sun_altitude_deg)
    flux = (solar_irradiance(wavelength.to(torch.float64))
            * _point_transmittance(resources, knobs, altitude, wavelength))
    flux = flux * (ASTRONOMICAL_UNIT_M / geometry.sun_distance_m) ** 2
    radius = math.asin(SUN_RADIUS_M / geometry.sun_distance_m)
    azimuth = math.radians(geometry.sun_azimuth_deg)
    if not knobs.solar_eclipse:
        return _disc(view, altitude, azimuth, radius, flux, knobs.dtype)
    pattern = EclipsedSun(geometry, altitude, radius)
    disc = _disc(view, altitude, azimuth, radius, flux, knobs.dtype, pattern)
    if view.kind == "directions" or altitude + 10.0 * radius < 0.0:
        return disc
    return disc + pattern.corona(view, flux, wavelength.numel(), knobs.dtype)


class EclipsedSun:
    r"""The Sun's disc behind the Moon, limb-darkened, and the corona, as the observer sees them.

    Parameters
    ----------
    geometry : Geometry
        Sun and Moon at the observer.
    apparent_altitude_rad : float
        Altitude of the Sun's apparent centre [rad]; the Moon is moved by the same
        refraction (their differential refraction, under 1 % of a radius above 10°, is
        neglected).
    radius_rad : float
        Angular radius of the Sun [rad].
    limb_darkening : float
        Linear coefficient :math:`u` (0.6), as :func:`skytorch.eclipse.sun_visible_fraction`.

    Notes
    -----
    ``pattern(None)`` is the visible fraction at the observer (the disc's total flux
    factor); ``pattern(directions)`` gives the limb-darkened relative radiance
    :math:`1 - u(1 - \mu)` at pixel centres and a 0/1 mask of the Moon's disc, as
    :func:`_disc` expects. :meth:`corona` spreads Baumbach's corona over the pixels from a
    polar grid of 48 × 64 cells between 1 and 8 solar radii, the cells behind the Moon
    removed.
    """

    def __init__(self, geometry, apparent_altitude_rad: float, radius_rad: float,
                 limb_darkening: float = 0.6):
        from skytorch.scene.solar_eclipse_sky import visible_fraction_at

        self.radius_rad, self.limb_darkening = radius_rad, limb_darkening
        self.moon_radius_rad = geometry.moon_radius_rad
        sun = torch.tensor(geometry.sun_horizontal_m, dtype=torch.float64)
        moon = torch.tensor(geometry.moon_horizontal_m, dtype=torch.float64)
        sun, moon = sun / torch.linalg.vector_norm(sun), moon / torch.linalg.vector_norm(moon)
        azimuth = math.radians(geometry.sun_azimuth_deg)
        self.centre = torch.tensor([math.cos(apparent_altitude_rad) * math.cos(azimuth),
                                    math.cos(apparent_altitude_rad) * math.sin(azimuth),
                                    math.sin(apparent_altitude_rad)], dtype=torch.float64)
        self.moon = _rotation(sun, self.centre)(moon[None])[0]
        self.fraction = visible_fraction_at(geometry, torch.zeros(1, 3, dtype=torch.float64),
                                            limb_darkening=limb_darkening)

    def _behind_moon(self, directions):
        return directions @ self.moon > math.cos(self.moon_radius_rad)

    def __call__(self, directions):
        """Visible fraction (1,) for ``None``; else relative radiance (n, 1) and mask (n, 1)."""
        if directions is None:
            return self.fraction
        rho = torch.acos((directions @ self.centre).clamp(-1.0, 1.0)) / self.radius_rad
        mu = torch.sqrt((1.0 - rho * rho).clamp(min=0.0))
        brightness = 1.0 - self.limb_darkening * (1.0 - mu)
        mask = (~self._behind_moon(directions)).to(torch.float64)
        return brightness[:, None], mask[:, None]

    def corona(self, view, flux, n_wavelength: int, dtype, level: float = 1.0):
        """Baumbach's corona (*view, wl) [W m^-2 sr^-1 nm^-1] for a Sun of total ``flux`` (wl,)."""
        from skytorch.scene.solar_eclipse_sky import baumbach_corona

        edges = torch.logspace(0.0, math.log10(8.0), 49, dtype=torch.float64)
        rho = torch.sqrt(edges[1:] * edges[:-1])
        angle = (torch.arange(64, dtype=torch.float64) + 0.5) * (2.0 * math.pi / 64)
        # the mean radiance of the disc times the cells' solid angles (small-angle)
        cell = (baumbach_corona(rho, level) * rho * (edges[1:] - edges[:-1])
                * (2.0 * math.pi / 64) / math.pi)  # relative to the disc's flux
        up = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)
        east = torch.linalg.cross(up, self.centre)
        if float(torch.linalg.vector_norm(east)) < 1e-9:
            east = torch.tensor([0.0, 1.0, 0.0], dtype=torch.float64)
        east = east / torch.linalg.vector_norm(east)
        north = torch.linalg.cross(self.centre, east)
        offset = (rho[:, None] * self.radius_rad)[..., None]
        d = (torch.cos(offset) * self.centre + torch.sin(offset)
             * (torch.cos(angle)[None, :, None] * north + torch.sin(angle)[None, :, None]
                * east)).reshape(-1, 3)
        weight = cell[:, None].expand(-1, angle.numel()).reshape(-1)
        weight = weight * (~self._behind_moon(d)).to(torch.float64)
        keep = (weight > 0) & (d[:, 2] > 0)
        altitude = torch.asin(d[keep, 2])
        azimuth = torch.atan2(d[keep, 1], d[keep, 0])
        cell_flux = weight[keep][:, None] * flux.to(torch.float64)[None]
        return _splat(view, altitude, azimuth, cell_flux, n_wavelength, dtype)


def moon_component(resources, view, geometry, wavelength, knobs) -> torch.Tensor:
    """Return the Moon (*view, wl) [W m^-2 sr^-1 nm^-1].

    Its disc (irradiance times transmittance, shaded pixel by pixel by the lunar reflectance law for
    the topocentric Sun–Moon–observer geometry and, with ``knobs.eclipse``, by the Earth's shadow at
    the lunar surface each pixel sees: :class:`MoonDisc`) plus the moonlit sky (times the
    disc-averaged shadow).
    """
    from skytorch.moon import lunar_irradiance

    wl = wavelength.to(torch.float64)
    earthshine, eclipse = knobs.earthshine, knobs.eclipse
    altitude = _apparent(resources, knobs, geometry.moon_altitude_deg)
    irradiance = lunar_irradiance(torch.tensor(geometry.phase_angle_rad, dtype=torch.float64),
                                  wl, distance_m=geometry.moon_distance_m,
                                  sun_distance_m=geometry.moon_sun_distance_m,
                                  earthshine=earthshine,
                                  n_quadrature=knobs["moon_disc_quadrature"])
    flux = irradiance * _point_transmittance(resources, knobs, altitude, wavelength)
    pattern = MoonDisc(resources, geometry, wavelength, altitude, earthshine=earthshine,
                       eclipse=eclipse)
    disc = _disc(view, altitude, math.radians(geometry.moon_azimuth_deg),
                 geometry.moon_radius_rad, flux, knobs.dtype, pattern)
    if altitude < 0.0:  # below the horizon: single scattering of a set Moon is omitted
        return disc
    table = moon_table(resources, geometry, knobs, wavelength)
    if eclipse:
        table = table * pattern.mean_shadow
    relative = view.azimuth_rad.to(torch.float64) - math.radians(geometry.moon_azimuth_deg)
    sky = _lookup(table, view.zenith_rad.to(torch.float64).clamp(max=_MAX_MOONLIT_ZENITH),
                  relative)
    return disc + sky.to(knobs.dtype) * view.valid[..., None].to(knobs.dtype)


def _full_circle_grid(n_z: int, n_a: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Return (zenith, absolute azimuth) nodes (n_z, n_a) [rad], the azimuths uniform."""
    zenith = _zenith_nodes(n_z, torch.float64)
    azimuth = torch.linspace(0.0, 2.0 * math.pi, n_a + 1, dtype=torch.float64)[:-1]
    return torch.meshgrid(zenith, azimuth, indexing="ij")


def eclipse_sky_table(resources, geometry, knobs, wavelength):
    """Sky during a solar eclipse on the (zenith, absolute azimuth) grid (z, a + 1, wl).

    :func:`skytorch.scene.solar_eclipse_sky.eclipsed_single_scattering` times the
    extraterrestrial spectrum on ``knobs["eclipse_sky_lut"]`` nodes (zenith as
    :func:`_zenith_nodes`, azimuth uniform over the full circle, the first column repeated
    after the last) [W m^-2 sr^-1 nm^-1]; with ``knobs.orders("sky") >= 2`` plus the
    second order of :func:`eclipse_second_order_table`, interpolated to those nodes in
    log radiance, and with ``knobs.orders("sky") >= 3`` the orders 3..N of
    :func:`eclipse_higher_orders_table` likewise.
    """
    from skytorch.scene.solar_eclipse_sky import eclipsed_single_scattering
    from skytorch.spectrum import solar_irradiance

    z, a = _full_circle_grid(*knobs["eclipse_sky_lut"])
    wl = wavelength.to(torch.float64)
    table = resources.transmittance_table(*knobs["transmittance"])
    radiance = eclipsed_single_scattering(resources.atmosphere, wl, z, a, geometry,
                                          knobs.elevation_m, n_samples=knobs["eclipse_samples"],
                                          table=table) * solar_irradiance(wl)
    if knobs.orders("sky") >= 2:
        # in log radiance: the second order grows steeply towards the horizon (halves the
        # look-up error of linear interpolation, docs/solar_eclipse_sky.md)
        second = eclipse_second_order_table(resources, geometry, knobs, wl)
        tiny = torch.finfo(second.dtype).tiny
        radiance = radiance + torch.exp(_lookup_full(torch.log(second.clamp(min=tiny)), z, a))
    if knobs.orders("sky") >= 3:
        higher = eclipse_higher_orders_table(resources, geometry, knobs, wl)
        tiny = torch.finfo(higher.dtype).tiny
        radiance = radiance + torch.exp(_lookup_full(torch.log(higher.clamp(min=tiny)), z, a))
    return torch.cat([radiance, radiance[:, :1]], dim=1)


def eclipse_higher_orders_table(resources, geometry, knobs, wavelength):
    """Orders 3..N of the eclipse sky on the ``knobs["eclipse_higher"]["lut"]`` nodes.

    :func:`skytorch.scene.eclipse_higher_orders.eclipsed_higher_orders` on the resources'
    multiple-scattering tables (their wavelength nodes, then interpolated to ``wavelength``
    in log radiance) with the quadrature ``knobs["eclipse_higher"]["quadrature"]``, times
    the extraterrestrial spectrum, laid out as :func:`eclipse_sky_table` (z, a + 1, wl)
    [W m^-2 sr^-1 nm^-1]; the zenith row is one line of sight.
    """
    from skytorch.scene.eclipse_higher_orders import eclipsed_higher_orders
    from skytorch.spectrum import interpolate_wavelength, solar_irradiance

    setting = knobs["eclipse_higher"]
    if setting is None:
        raise ValueError("the orders >= 3 of the eclipse sky need the fidelity knob "
                         "'eclipse_higher' (the 'reference' preset has it)")
    tables = resources.scattering_tables(knobs.scattering_orders["tables"], knobs["ms_tables"],
                                         knobs["ms_wavelength_nodes"])
    n_z, n_a = setting["lut"]
    n_view, n_mu, n_phi = setting["quadrature"]
    z, a = _full_circle_grid(n_z, n_a)
    # the zenith row (z = 0) is one direction: computed once
    zenith = torch.cat([z[:1, 0], z[1:].reshape(-1)])
    azimuth = torch.cat([a[:1, 0], a[1:].reshape(-1)])
    higher = eclipsed_higher_orders(resources.atmosphere, tables.wavelength_nm, zenith, azimuth,
                                    geometry, knobs.elevation_m, tables=tables,
                                    scattering_orders=knobs.orders("sky"), n_view=n_view,
                                    n_mu=n_mu, n_phi=n_phi)
    wl = wavelength.to(torch.float64)
    higher = interpolate_wavelength(higher.to(torch.float64), tables.wavelength_nm, wl)
    higher = higher * solar_irradiance(wl)
    table = torch.cat([higher[:1].expand(n_a, -1), higher[1:]]).reshape(n_z, n_a, wl.numel())
    return torch.cat([table, table[:, :1]], dim=1)


#: lines of sight per call of the eclipse sky's second order (memory stays in cache)
_ECLIPSE_MS_CHUNK = 2


def eclipse_second_order_table(resources, geometry, knobs, wavelength):
    """Second order of the eclipse sky on the coarser ``knobs["eclipse_ms_lut"]`` nodes.

    :func:`skytorch.scene.solar_eclipse_sky.eclipsed_second_order` (quadrature
    ``knobs["eclipse_ms"]``: samples along the line of sight, direction cosines per
    hemisphere, azimuths, samples per ray) times the extraterrestrial spectrum, laid out
    as :func:`eclipse_sky_table` (z, a + 1, wl) [W m^-2 sr^-1 nm^-1].
    """
    from skytorch.scene.solar_eclipse_sky import eclipsed_second_order
    from skytorch.spectrum import solar_irradiance

    n_z, n_a = knobs["eclipse_ms_lut"]
    n_view, n_mu, n_phi, n_samples = knobs["eclipse_ms"]
    z, a = _full_circle_grid(n_z, n_a)
    wl = wavelength.to(torch.float64)
    table = resources.transmittance_table(*knobs["transmittance"])
    z, a = z.reshape(-1), a.reshape(-1)
    # a few lines of sight at a time: each holds n_view x 2 n_mu x n_phi x n_samples points
    parts = [eclipsed_second_order(resources.atmosphere, wl, z[i:i + _ECLIPSE_MS_CHUNK],
                                   a[i:i + _ECLIPSE_MS_CHUNK], geometry, knobs.elevation_m,
                                   n_view=n_view, n_mu=n_mu, n_phi=n_phi,
                                   n_samples=n_samples, table=table)
             for i in range(0, z.numel(), _ECLIPSE_MS_CHUNK)]
    second = (torch.cat(parts) * solar_irradiance(wl)).reshape(n_z, n_a, wl.numel())
    return torch.cat([second, second[:, :1]], dim=1)


def _lookup_full(table: torch.Tensor, zenith: torch.Tensor, azimuth: torch.Tensor):
    """Bilinear look-up of a (zenith node, periodic azimuth node, wl) table."""
    n_z, n_a, n_wl = table.shape
    u = _zenith_coordinate(zenith.reshape(-1)) * 2.0 - 1.0
    v = wrap_to_turn(azimuth.reshape(-1), 2 * math.pi) / math.pi - 1.0
    grid = torch.stack([v, u], dim=-1).to(table.dtype)[None, None]
    image = table.permute(2, 0, 1)[None]
    out = torch.nn.functional.grid_sample(image, grid, mode="bilinear",
                                          padding_mode="border", align_corners=True)
    return out[0, :, 0, :].T.reshape(*zenith.shape, n_wl)


def sky_component(resources, view, geometry, wavelength, knobs) -> torch.Tensor:
    """Single-scattered sunlight (*view, wl) [W m^-2 sr^-1 nm^-1] from the sky table.

    With ``knobs.solar_eclipse`` the table holds the sky with the Sun's visible fraction at
    every scattering point (:func:`eclipse_sky_table`).
    """
    if knobs.solar_eclipse:
        table = eclipse_sky_table(resources, geometry, knobs, wavelength)
        sky = _lookup_full(table, view.zenith_rad.to(torch.float64),
                           view.azimuth_rad.to(torch.float64))
        return sky.to(knobs.dtype) * view.valid[..., None].to(knobs.dtype)
    table = sky_table(resources, geometry, knobs, wavelength)
    relative = view.azimuth_rad.to(torch.float64) - math.radians(geometry.sun_azimuth_deg)
    sky = _lookup(table, view.zenith_rad.to(torch.float64), relative)
    return sky.to(knobs.dtype) * view.valid[..., None].to(knobs.dtype)


def star_spectra(vmag: torch.Tensor, bv: torch.Tensor, wavelength) -> torch.Tensor:
    """Black-body spectral irradiance (star, wl) [W m^-2 nm^-1] with V magnitudes ``vmag``."""
    from skytorch.spectrum import blackbody_radiance, bv_to_temperature, spectrum_to_magnitude

    wl = wavelength.to(torch.float64)
    temperature = bv_to_temperature(bv.clamp(-0.4, 2.0))
    shape = blackbody_radiance(wl, temperature[:, None])
    mag = spectrum_to_magnitude(shape, wl, band="V")
    return shape * (10.0 ** (-0.4 * (vmag - mag)))[:, None]


def stars_component(resources, view, geometry, wavelength, knobs) -> torch.Tensor:
    """Catalogue stars and the planets at their apparent places with extincted magnitudes.

    The tensor layer of :func:`skytorch.stars.observe` (positions, refraction and extinction tables
    from the resources) for the catalogue and the planets to the scene's V limit
    (:meth:`~skytorch.scene.resources.SceneResources.planet_sources`: Mallama & Hilton 2018
    magnitudes, black bodies of the planets' B−V); stars and planets behind the Moon's disc
    (:func:`occulted`) are left out.
    """
    from skytorch.ephemeris import parse_times
    from skytorch.stars import observe_tensors, time_operators

    vectors, vmag, bv, epoch = resources.star_vectors(knobs.star_limit_mag)
    planets = resources.planet_sources(knobs.time)
    bright = planets["vmag"] <= knobs.star_limit_mag
    operators, velocity = time_operators(parse_times([knobs.time]), float(knobs.lat_deg),
                                         float(knobs.lon_deg), float(knobs.elevation_m),
                                         epoch_jyear=epoch)
    refraction_tab, extinction_tab = resources.star_site_tables(knobs.elevation_m,
                                                                knobs.refraction)
    result = observe_tensors(torch.cat([vectors, planets["vectors"][bright]]),
                             torch.cat([vmag, planets["vmag"][bright]]),
                             torch.cat([bv, planets["bv"][bright]]), operators, velocity,
                             refraction_tab, extinction_tab)
    altitude, azimuth = result["altitude"][0], result["azimuth"][0]
    up = (altitude > 0) & ~occulted(resources, geometry, altitude, azimuth, knobs)
    mag = result["magnitude"][0][up]
    planet_bv = planets["bv"][bright]
    unit = torch.cat([resources.catalogue_spectra(knobs.star_limit_mag, star_spectra),
                      star_spectra(torch.zeros_like(planet_bv), planet_bv,
                                   wavelength)])[up]
    flux = unit * (10.0 ** (-0.4 * mag))[:, None]
    return _splat(view, altitude[up], azimuth[up], flux, wavelength.numel(), knobs.dtype)


def occulted(resources, geometry, altitude_rad, azimuth_rad, knobs) -> torch.Tensor:
    """Whether points (star,) at apparent altitude and azimuth [rad] lie behind the Moon.

    A point is occulted when its angular distance from the Moon's apparent (refracted when
    ``knobs.refraction``) centre is less than the Moon's topocentric angular radius. Both places
    are refracted alike, so the small flattening of the disc by differential refraction
    (under 1 % of its radius above 10° altitude) is neglected.
    """
    if (math.radians(geometry.moon_altitude_deg) + geometry.moon_radius_rad
            + HORIZON_REFRACTION_RAD < 0.0):  # below the horizon even when refracted
        return torch.zeros(altitude_rad.shape, dtype=torch.bool)
    moon = _apparent(resources, knobs, geometry.moon_altitude_deg)
    moon_azimuth = math.radians(geometry.moon_azimuth_deg)
    altitude = altitude_rad.to(torch.float64)
    azimuth = azimuth_rad.to(torch.float64)
    cosine = (torch.sin(altitude) * math.sin(moon) + torch.cos(altitude) * math.cos(moon)
              * torch.cos(azimuth - moon_azimuth))
    return cosine > math.cos(geometry.moon_radius_rad)


def skyglow_component(resources, view, geometry, wavelength, knobs) -> torch.Tensor:
    """City skyglow (*view, wl) [W m^-2 sr^-1 nm^-1] from the resources' skyglow model.

    :meth:`~skytorch.scene.resources.SceneResources.skyglow_model`, cached on disk; ``geometry`` is
    not used.
    """
    settings = dict(knobs["skyglow"])
    height = float(knobs.elevation_m)
    if height > 0.0:
        # the observer's own height: a model with its one observer node there (the
        # preset's models have theirs at the ground; the sky seen from a mountain is
        # darker by ~0.9 mag from 3 km)
        settings.update(n_observer_altitude=1, observer_altitude_range_m=(height, height))
    model = resources.skyglow_model(settings)
    out = model.render(knobs.light_map, observer_xy=tuple(knobs.observer_xy),
                       observer_altitude_m=height, lamp=knobs.lamp, as_dataset=False)
    panorama = out["radiance"].to(torch.float64)  # (elevation, azimuth, wl)
    elevation = model.elevation_rad.to(torch.float64)
    azimuth = model.azimuth_rad.to(torch.float64)
    # periodic in azimuth: append the first column after the last
    panorama = torch.cat([panorama, panorama[:, :1]], dim=1)
    azimuth = torch.cat([azimuth, azimuth[:1] + 2 * math.pi])
    alt = (0.5 * math.pi - view.zenith_rad.to(torch.float64)).reshape(-1)
    az = torch.remainder(view.azimuth_rad.to(torch.float64).reshape(-1) - azimuth[0],
                         2 * math.pi) + azimuth[0]
    u = _fractional(elevation, alt)
    v = _fractional(azimuth, az)
    grid = torch.stack([v, u], -1)[None, None]
    image = panorama.permute(2, 0, 1)[None]
    sampled = torch.nn.functional.grid_sample(image, grid, mode="bilinear",
                                              padding_mode="border", align_corners=True)
    sampled = sampled[0, :, 0, :].T.reshape(*view.shape, -1)
    return sampled.to(knobs.dtype) * view.valid[..., None].to(knobs.dtype)


def _fractional(nodes: torch.Tensor, values: torch.Tensor) -> torch.Tensor:
    """Normalised [-1, 1] grid coordinate of values on increasing nodes (linear inside)."""
    index = torch.searchsorted(nodes, values.contiguous()).clamp(1, nodes.numel() - 1)
    left, right = nodes[index - 1], nodes[index]
    position = (index - 1) + ((values - left) / (right - left)).clamp(0.0, 1.0)
    position = torch.where(values < nodes[0], torch.zeros_like(position), position)
    return position / (nodes.numel() - 1) * 2.0 - 1.0


def render_components(resources: SceneResources, plan: Plan, view, wavelength,
                      knobs: Knobs) -> tuple[dict, dict]:
    """Spectral radiance of each component (*view, wl) and the seconds each took.

    Every component renderer takes ``(resources, view, geometry, wavelength, knobs)``; the
    planner's decisions arrive as ``plan.computed`` and the flags of ``knobs``.
    """
    g = plan.geometry
    components, seconds = {}, {}

    def timed(name, fn):
        start = _time.perf_counter()
        components[name] = fn()
        seconds[name] = _time.perf_counter() - start

    timed("natural", lambda: natural_component(resources, view, g, wavelength, knobs))
    if "sky" in plan.computed:
        timed("sky", lambda: sky_component(resources, view, g, wavelength, knobs))
    if "skyglow" in plan.computed:
        timed("skyglow", lambda: skyglow_component(resources, view, g, wavelength, knobs))
    if "stars" in plan.computed:
        timed("stars", lambda: stars_component(resources, view, g, wavelength, knobs))
    if "moon" in plan.computed:
        timed("moon", lambda: moon_component(resources, view, g, wavelength, knobs))
    if "sun" in plan.computed:
        timed("sun", lambda: sun_component(resources, view, g, wavelength, knobs))
    return components, seconds


#: the interface of :class:`skytorch.scene.Scene` the renderers use (checked by interface:
#: this module sits below ``scene.py``, whose ``Scene.render`` calls it)
_SCENE_METHODS = ("resources", "plan", "make_view", "replace")


def _check_scene(scene) -> None:
    """Raise TypeError unless ``scene`` has the interface of a :class:`skytorch.Scene`."""
    if not all(callable(getattr(scene, name, None)) for name in _SCENE_METHODS):
        raise TypeError(f"scene must be a skytorch.Scene; got {type(scene).__name__}")


def _resources(scene, resources) -> SceneResources:
    """Return the resources of a render: the scene's own, or the given ones (checked)."""
    if resources is None:
        return scene.resources()
    if not isinstance(resources, SceneResources):
        raise TypeError("resources must be a skytorch.scene.SceneResources (Scene.resources()) "
                        f"or None; got {type(resources).__name__}")
    resources.check(scene)
    return resources


def render(scene, plan=None, resources=None):
    """Render ``scene`` to a Dataset (see :func:`skytorch.scene.dataset.scene_dataset`).

    A scene with several observers goes to :func:`render_observers`.

    Parameters
    ----------
    scene : Scene
    plan : Plan, optional
        The planner's decision (:meth:`Scene.plan`; a list of them for several observers).
    resources : SceneResources, optional
        Tables of the scene's spec (default: ``scene.resources()``); a time series keeps
        one and passes it to every render. ``ValueError`` when its spec is not the
        scene's.
    """
    _check_scene(scene)
    resources = _resources(scene, resources)
    if scene.several_observers:
        return render_observers(scene, plan, resources=resources)
    if plan is not None and not isinstance(plan, Plan):
        raise TypeError(f"plan must be a skytorch.scene.Plan (Scene.plan()) or None; got "
                        f"{type(plan).__name__}")
    if plan is not None and plan.made_for and plan.made_for != scene_key(scene):
        raise ValueError("plan was made for another scene (its time, site, light map or "
                         "settings differ): pass this scene's own Scene.plan(), or None")
    view = scene.make_view(resources)
    plan = make_plan(scene, view, resources) if plan is None else plan
    start = _time.perf_counter()
    wavelength = scene.wavelength_nm()
    components, seconds = render_components(resources, plan, view, wavelength,
                                            Knobs.of(scene, plan))
    total = sum(components.values())
    seconds["total"] = _time.perf_counter() - start
    return scene_dataset(scene, view, plan, components, total, seconds)


def render_observers(scene, plans=None, resources=None):
    """Render a scene with several observers, stacked along a dimension ``observer``.

    The Sun and Moon of all observers come from one ephemeris evaluation
    (:meth:`skytorch.scene.resources.SceneResources.geometries`); each observer is planned
    on its own (the Moon may be up for one and set for another) and its decisions are kept
    as the string variables ``effects_computed`` and ``effects_skipped`` over
    ``observer``; the Dataset attributes list the union of the computed effects.
    Coordinates ``latitude``, ``longitude`` and ``elevation`` over ``observer`` give the
    sites.

    Parameters
    ----------
    scene : Scene
        With sequences ``lat_deg``, ``lon_deg``, ``elevation_m`` (``n_observers``).
    plans : list of Plan, optional
        One per observer (:meth:`Scene.plan`).
    resources : SceneResources, optional
        Shared by all the observers (default: ``scene.resources()``).

    Returns
    -------
    xarray.Dataset
    """
    _check_scene(scene)
    resources = _resources(scene, resources)
    singles = scene.observers()
    plans = scene.plan(resources=resources) if plans is None else plans
    if isinstance(plans, Plan) and len(singles) == 1:
        plans = [plans]
    if not isinstance(plans, (list, tuple)) or not all(isinstance(p, Plan) for p in plans):
        raise TypeError("plans must be a list of skytorch.scene.Plan, one per observer; got "
                        f"{type(plans).__name__}")
    if len(plans) != len(singles):
        raise ValueError(f"plans: one per observer ({len(singles)}); got {len(plans)}")
    frames = [render(single, plan, resources)
              for single, plan in zip(singles, plans, strict=True)]
    index = coordinate("observer", np.arange(len(singles)), VariableSpec(
        "1", "observer index", "Index of the observer."))
    stacked = stack_frames(frames, "observer", index,
                           f"Sky scene at {len(singles)} observers")
    for name, values, spec in (
            ("latitude", scene.lat_deg, VariableSpec(
                "degree_north", "latitude", "WGS84 geodetic latitude of the observer.",
                "latitude")),
            ("longitude", scene.lon_deg, VariableSpec(
                "degree_east", "longitude", "East longitude of the observer.", "longitude")),
            ("elevation", scene.elevation_m, VariableSpec(
                "m", "observer height", "Height above the WGS84 ellipsoid.",
                "height_above_reference_ellipsoid"))):
        stacked = stacked.assign_coords({name: variable(("observer",), np.asarray(values),
                                                        spec)})
    return stacked


def render_times(scene, times, resources=None):
    """Render ``scene`` at several instants, stacked along a ``time`` dimension.

    Each instant is planned on its own (the Sun and Moon move); the per-instant decisions
    are kept as the string variables ``effects_computed`` and ``effects_skipped`` over
    ``time``, and the Dataset attributes list the union of the computed effects. All the
    instants share one :class:`~skytorch.scene.resources.SceneResources`.

    Parameters
    ----------
    scene : Scene
        The scene; its ``time`` is replaced by each of ``times``.
    times : sequence of str, datetime or datetime64
        UTC instants (dimension ``time``).
    resources : SceneResources, optional
        Default: ``scene.resources()``.

    Returns
    -------
    xarray.Dataset
    """
    from skytorch.ephemeris import parse_times

    _check_scene(scene)
    resources = _resources(scene, resources)
    values = parse_times(times)
    frames = [render(scene.replace(time=str(t)), resources=resources) for t in values]
    return stack_frames(frames, "time", time_coordinate(values),
                        f"Sky scene at {len(values)} times")
