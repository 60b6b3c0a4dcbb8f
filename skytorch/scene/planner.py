"""Planner: compute only the effects that can change a scene beyond its tolerance.

The NeL/Ryzom sky (ref. 1) draws only what the time of day and the weather make
visible; Müller et al. (ref. 2, §5) switch stars and the Moon with a day–night factor.
Here the decision is quantitative: each effect's share of the image's V-band flux (the
L1 norm of the luminance over the pixels, :math:`\\sum_p Y_p\\,\\Omega_p`) is bounded
with cheap estimates, and an effect whose share is below ``scene.tolerance`` is skipped
with the reason recorded. Omitting it then changes the image by at most that share.

Vocabulary (:data:`EFFECTS`): ``sky`` (scattered sunlight and twilight), ``sun`` (the
solar disc), ``moon`` (disc and moonlit sky), ``earthshine``, ``eclipse`` (Earth's shadow
on the Moon), ``stars``, ``scintillation``, ``skyglow`` (city lights), ``refraction``
(of point sources). The natural background (airglow, zodiacal light, unresolved stars)
is always part of the image.

Estimates
---------
* natural background: the zenith value (22.0 V mag arcsec^-2) over the hemisphere;
* sky: single-scattering radiance (:meth:`Atmosphere.sky_radiance`) at 9 directions,
  averaged and spread over the hemisphere;
* sun, moon: their V magnitudes above the atmosphere (the Moon's from
  :func:`skytorch.moon.magnitude`) when their apparent upper limb is above the horizon;
* earthshine: the Moon's magnitude with minus without earthshine;
* eclipse: zero outside the penumbra (:func:`skytorch.eclipse.shadow_radii`, Danjon
  enlargement) — an exact criterion; inside it the Moon's whole share;
* stars: half the integrated V flux of the catalogue above ``star_limit_mag``;
* skyglow: the brightest sky measured by Falchi et al. (2016), 14.0 V mag arcsec^-2,
  over the hemisphere (a bound, since the planner cannot afford the skyglow model);
* refraction: the Sun's and Moon's pixels with and without refraction (table of
  :func:`skytorch.stars.refraction_table`); with stars in a
  fisheye or panorama, stars near the horizon always move by more than a pixel;
* scintillation: a still image records the mean flux of a twinkling star, so it is
  always skipped (twinkling sequences: ``skytorch.stars.observe(..., twinkle_samples=n)``).

:data:`FIDELITY` maps the presets "fast", "default", "reference" to the modules' knobs;
their measured error and cost are in ``docs/scene.md``.

References
----------
1. Ryzom/NeL sky post-mortem (2005), "Drawing the sky in Ryzom", Nevrax.
2. Müller, Engel & Döllner 2012, "Single-Pass Rendering of Day and Night Sky Phenomena",
   VMV 2012, doi:10.2312/PE/VMV/VMV12/055-062.
3. Falchi, F. et al. 2016, "The new world atlas of artificial night sky brightness",
   Science Advances 2, e1600377, doi:10.1126/sciadv.1600377.
"""

from __future__ import annotations

import logging
import math
import time as _time
from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np
import torch

logger = logging.getLogger(__name__)

#: the planner's vocabulary of effects, in composition order
EFFECTS = ("sky", "sun", "moon", "earthshine", "eclipse", "stars", "scintillation",
           "skyglow", "refraction")

#: V magnitude of the Sun above the atmosphere (Willmer 2018, ApJS 236, 47,
#: doi:10.3847/1538-4365/aabfdf)
SUN_V_MAG = -26.76
#: brightest artificial sky in the world atlas [V mag arcsec^-2] (Falchi et al. 2016)
BRIGHTEST_SKYGLOW_MAG_ARCSEC2 = 14.0
#: apparent semi-diameter of the Sun and Moon used for "above the horizon" [rad]
SEMI_DIAMETER_RAD = math.radians(0.27)
#: refraction at the horizon (standard atmosphere) bounding the upper-limb test [rad]
HORIZON_REFRACTION_RAD = math.radians(0.6)
#: hemisphere [arcsec^2]
HEMISPHERE_ARCSEC2 = 2.0 * math.pi * (180.0 * 3600.0 / math.pi) ** 2

#: quadrature nodes of the planner's estimate of the Moon's magnitude (an estimate only)
PLANNER_MOON_QUADRATURE = 8

#: module knobs per fidelity preset (measured error and cost in docs/scene.md)
FIDELITY = {
    "fast": {
        "sky_lut": (12, 13), "sky_samples": 24, "transmittance": (64, 16),
        "moon_lut": (8, 9), "moon_steps": 16, "moon_quadrature": 8,
        "moon_disc_quadrature": 12,
        "skyglow": {"n_azimuth": 32, "n_elevation": 8, "n_distance": 16, "n_components": 4,
                    "max_distance_m": 30_000.0}},
    "default": {
        "sky_lut": (24, 25), "sky_samples": 48, "transmittance": (128, 32),
        "moon_lut": (12, 13), "moon_steps": 32, "moon_quadrature": 16,
        "moon_disc_quadrature": 24,
        "skyglow": {"n_azimuth": 64, "n_elevation": 16, "n_distance": 32, "n_components": 8,
                    "max_distance_m": 40_000.0}},
    "reference": {
        "sky_lut": (48, 49), "sky_samples": 128, "transmittance": (256, 64),
        "moon_lut": (24, 25), "moon_steps": 64, "moon_quadrature": 32,
        "moon_disc_quadrature": 48,
        "skyglow": {"n_azimuth": 128, "n_elevation": 32, "n_distance": 64,
                    "n_components": 16, "max_distance_m": 40_000.0}},
}


def _flux(magnitude: float) -> float:
    """V flux relative to magnitude 0."""
    return 10.0 ** (-0.4 * magnitude)


def _surface_flux(mag_arcsec2: float, area_arcsec2: float = HEMISPHERE_ARCSEC2) -> float:
    return _flux(mag_arcsec2) * area_arcsec2


@lru_cache(maxsize=4)
def catalogue(limit_magnitude: float):
    """The star catalogue to a V limit (cached)."""
    from skytorch.stars import bright_stars

    return bright_stars(limit_magnitude)


@lru_cache(maxsize=4)
def integrated_starlight(limit_magnitude: float) -> float:
    """Total V flux of the catalogue's stars (relative to magnitude 0), whole sky."""
    return float(np.sum(10.0 ** (-0.4 * catalogue(limit_magnitude)["vmag"].values)))


@dataclass
class Geometry:
    """Sun and Moon at the observer for one scene (degrees, metres, radians)."""

    sun_altitude_deg: float
    sun_azimuth_deg: float
    moon_altitude_deg: float
    moon_azimuth_deg: float
    moon_distance_m: float
    sun_distance_m: float
    phase_angle_rad: float
    shadow_distance_m: float
    shadow_offset_m: float
    penumbra_radius_m: float
    umbra_radius_m: float


def scene_geometry(scene) -> Geometry:
    """Topocentric Sun and Moon and the Moon's place in the Earth's shadow.

    Cached per (time, site): the render and later plans of the same instant and place
    reuse it (a fresh copy each call, so callers may modify it).
    """
    return replace(_site_geometry(np.datetime64(scene.time, "ns"), float(scene.lat_deg),
                                  float(scene.lon_deg), float(scene.elevation_m)))


@lru_cache(maxsize=64)
def _site_geometry(time, lat_deg: float, lon_deg: float, elevation_m: float) -> Geometry:
    from skytorch.constants import SUN_RADIUS_M
    from skytorch.eclipse import shadow_radii
    from skytorch.ephemeris import sun_moon, sun_moon_vectors
    from skytorch.moon.geometry import phase_angle

    ds = sun_moon([time], lat_deg, lon_deg, elevation_m)
    vectors = sun_moon_vectors([time])
    sun = vectors["sun_gcrs_m"][0]
    moon = vectors["moon_gcrs_m"][0]
    sun_hat = sun / torch.linalg.norm(sun)
    along = -float(moon @ sun_hat)
    offset = float(torch.linalg.norm(moon + along * sun_hat))
    sun_distance = float(torch.linalg.norm(sun))
    umbra, penumbra = shadow_radii(torch.tensor(max(along, 1.0), dtype=torch.float64),
                                   sun_distance, SUN_RADIUS_M,
                                   _earth_radius(), enlargement="danjon")
    return Geometry(
        sun_altitude_deg=float(ds["sun_altitude"][0]), sun_azimuth_deg=float(ds["sun_azimuth"][0]),
        moon_altitude_deg=float(ds["moon_altitude"][0]),
        moon_azimuth_deg=float(ds["moon_azimuth"][0]),
        moon_distance_m=_topocentric_distance(ds, elevation_m),
        sun_distance_m=sun_distance,
        phase_angle_rad=float(phase_angle(sun, moon)),
        shadow_distance_m=along, shadow_offset_m=offset,
        penumbra_radius_m=float(penumbra), umbra_radius_m=float(umbra))


def _earth_radius() -> float:
    from skytorch.constants import EARTH_MEAN_RADIUS_M

    return EARTH_MEAN_RADIUS_M


def _topocentric_distance(ds, elevation_m: float) -> float:
    """Observer–Moon distance [m] (geocentric minus the observer's height projection)."""
    geocentric = float(ds["moon_distance"][0])
    altitude = math.radians(float(ds["moon_altitude"][0]))
    return geocentric - (_earth_radius() + elevation_m) * math.sin(altitude)


@dataclass
class Plan:
    """The planner's decision for one scene.

    Attributes
    ----------
    computed : tuple of str
        Effects to compute, in :data:`EFFECTS` order.
    skipped : dict
        Skipped effect -> reason.
    shares : dict
        Estimated share of the image's V flux per effect (bounds; see module notes).
    geometry : Geometry
    seconds : float
        Wall time of the planning [s].
    eclipse_factor : Tensor (n_wavelength,) or None
        Relative illuminance of the Earth's shadow at the Moon (reused by the render).
    """

    computed: tuple[str, ...]
    skipped: dict[str, str]
    shares: dict[str, float] = field(default_factory=dict)
    geometry: Geometry | None = None
    seconds: float = 0.0
    eclipse_factor: torch.Tensor | None = None

    def __contains__(self, effect: str) -> bool:
        return effect in self.computed

    def attrs(self) -> dict[str, str]:
        """``effects_computed`` and ``effects_skipped`` as netCDF-safe strings."""
        return {"effects_computed": ",".join(self.computed),
                "effects_skipped": "; ".join(f"{k}: {v}" for k, v in self.skipped.items())}


def _sky_flux(scene, geometry: Geometry) -> float:
    """Hemisphere V flux of single-scattered sunlight from 9 sample directions."""
    from skytorch.moon.sky import radiance_to_mag_arcsec2

    atm = scene.atmosphere()
    # every point of the atmosphere the observer can see lies within the angle
    # acos(R / R_top) of the observer's zenith (seen from the planet's centre); with the
    # Sun deeper than twice that angle below the horizon all of it is in the shadow
    visible = math.acos(atm.planet_radius_m / atm.top_radius_m)
    if -math.radians(geometry.sun_altitude_deg) > 2.0 * visible:
        return 0.0
    wl = scene.wavelength_nm().to(torch.float64)
    sun_zenith = math.radians(90.0 - geometry.sun_altitude_deg)
    sun_azimuth = math.radians(geometry.sun_azimuth_deg)
    zenith = torch.tensor([0.0] + [math.radians(60.0)] * 4 + [math.radians(85.0)] * 4,
                          dtype=torch.float64)
    azimuth = torch.tensor([0.0] + [sun_azimuth + k * math.pi / 2 for k in range(4)]
                           + [sun_azimuth + k * math.pi / 2 for k in range(4)],
                           dtype=torch.float64)
    radiance = atm.sky_radiance(wl, zenith, azimuth, torch.full_like(zenith, sun_zenith),
                                torch.full_like(zenith, sun_azimuth), scene.elevation_m,
                                solar_irradiance=True, n_samples=24)
    mags = radiance_to_mag_arcsec2(radiance.clamp(min=1e-300), wl)
    return float(torch.mean(10.0 ** (-0.4 * mags))) * HEMISPHERE_ARCSEC2


def _moon_fluxes(geometry: Geometry) -> tuple[float, float]:
    """V flux of the Moon with earthshine and of its earthshine alone."""
    return _moon_fluxes_cached(geometry.phase_angle_rad, geometry.moon_distance_m,
                               geometry.sun_distance_m)


@lru_cache(maxsize=64)
def _moon_fluxes_cached(phase_angle_rad: float, moon_distance_m: float,
                        sun_distance_m: float) -> tuple[float, float]:
    from skytorch.moon import magnitude

    alpha = torch.tensor(phase_angle_rad, dtype=torch.float64)
    options = {"distance_m": moon_distance_m,
               "sun_distance_m": sun_distance_m,
               "n_quadrature": PLANNER_MOON_QUADRATURE}
    with_es = float(magnitude(alpha, earthshine=True, **options))
    without = float(magnitude(alpha, earthshine=False, **options))
    total = _flux(with_es)
    return total, total - (_flux(without) if math.isfinite(without) else 0.0)


def _above_horizon(altitude_deg: float) -> bool:
    return math.radians(altitude_deg) + SEMI_DIAMETER_RAD + HORIZON_REFRACTION_RAD > 0.0


def _pixel_moves(scene, view, altitude_deg: float, azimuth_deg: float) -> tuple[bool, float]:
    """Whether refraction moves a point to another pixel, and the shift [rad]."""
    from skytorch.scene.render import refracted_altitude

    true = torch.tensor([math.radians(altitude_deg)], dtype=torch.float64)
    apparent = torch.tensor([refracted_altitude(scene, math.radians(altitude_deg))],
                            dtype=torch.float64)
    azimuth = torch.tensor([math.radians(azimuth_deg)], dtype=torch.float64)
    before = view.pixel_index(true, azimuth)
    after = view.pixel_index(apparent, azimuth)
    return bool((before != after).any()), float((apparent - true).abs().max())


def plan(scene, view=None) -> Plan:
    """Decide which effects of ``scene`` to compute.

    Parameters
    ----------
    scene : skytorch.scene.Scene
    view : skytorch.scene.scene.View, optional
        The scene's view (built when not given).

    Returns
    -------
    Plan
        ``computed`` and ``skipped`` (with reasons), estimated flux shares, geometry.
    """
    start = _time.perf_counter()
    view = scene.make_view() if view is None else view
    g = scene_geometry(scene)
    tol = scene.tolerance
    decided: dict[str, tuple[bool, str]] = {}
    shares: dict[str, float] = {}
    points = view.kind != "directions"

    natural = _surface_flux(scene.natural_mag_arcsec2)
    sky = _sky_flux(scene, g)
    sun_up = _above_horizon(g.sun_altitude_deg)
    moon_up = _above_horizon(g.moon_altitude_deg)
    sun = _flux(SUN_V_MAG) if sun_up and points else 0.0
    moon_total, earthshine = _moon_fluxes(g)
    moon = moon_total if moon_up else 0.0
    star_flux = 0.5 * integrated_starlight(float(scene.star_limit_mag)) if points else 0.0
    total = natural + sky + sun + moon + star_flux

    def share(name, value):
        shares[name] = value / total
        return shares[name]

    s = share("sky", sky)
    decided["sky"] = (s >= tol, f"sunlit sky {s:.1e} of the image flux (Sun at "
                                f"{g.sun_altitude_deg:.1f} deg)")
    if not points:
        decided["sun"] = (False, "a directions view holds no point sources")
    elif not sun_up:
        decided["sun"] = (False, f"below the horizon (altitude {g.sun_altitude_deg:.1f} deg)")
    else:
        decided["sun"] = (share("sun", sun) >= tol, "above the horizon")
    if not moon_up:
        decided["moon"] = (False, f"below the horizon (altitude {g.moon_altitude_deg:.1f} deg)")
    else:
        s = share("moon", moon_total)
        decided["moon"] = (s >= tol, f"Moon {s:.1e} of the image flux")
    reach = g.penumbra_radius_m + _moon_radius()
    inside = g.shadow_distance_m > 0.0 and g.shadow_offset_m < reach
    eclipse = None
    if inside and moon_up and "eclipse" not in scene.exclude:
        eclipse = _eclipse_factor(scene, g)
        dimmed = moon_total * float(eclipse.mean())
        total = total - moon + dimmed
        moon = dimmed
        s = share("moon", moon)
        decided["moon"] = (s >= tol, f"eclipsed Moon {s:.1e} of the image flux")
    moon_on = decided["moon"][0] or "moon" in scene.force
    s = share("earthshine", earthshine if moon_on else 0.0)
    decided["earthshine"] = (moon_on and s >= tol,
                             f"earthshine {s:.1e} of the image flux" if moon_on
                             else "no Moon in the image")
    if not moon_on:
        decided["eclipse"] = (False, "no Moon in the image")
    elif not inside:
        decided["eclipse"] = (False, f"Moon outside the penumbra (axis offset "
                                     f"{g.shadow_offset_m / 1e3:.0f} km > "
                                     f"{reach / 1e3:.0f} km)")
    else:
        s = share("eclipse", moon_total * float((1.0 - eclipse).max()) if eclipse is not None
                  else moon_total)
        decided["eclipse"] = (s >= tol, f"the Earth's shadow dims the Moon by {s:.1e} of the "
                                        "image flux")
    if not points:
        decided["stars"] = (False, "a directions view holds no point sources")
    else:
        s = share("stars", star_flux)
        decided["stars"] = (s >= tol, f"starlight {s:.1e} of the image flux")
    stars_on = decided["stars"][0] or "stars" in scene.force
    decided["scintillation"] = (False, "a still image records the mean flux of a twinkling "
                                       "star" if stars_on else "no stars in the image")
    if scene.light_map is None:
        decided["skyglow"] = (False, "no light map")
    else:
        s = share("skyglow", _surface_flux(BRIGHTEST_SKYGLOW_MAG_ARCSEC2))
        decided["skyglow"] = (s >= tol, f"even the brightest city sky (Falchi 2016) is "
                                        f"{s:.1e} of the image flux")
    moved = []
    if points:
        if decided["sun"][0] or "sun" in scene.force:
            moves, shift = _pixel_moves(scene, view, g.sun_altitude_deg, g.sun_azimuth_deg)
            moved.append(("Sun", moves, shift))
        if moon_on:
            moves, shift = _pixel_moves(scene, view, g.moon_altitude_deg, g.moon_azimuth_deg)
            moved.append(("Moon", moves, shift))
    if stars_on:
        decided["refraction"] = (True, "stars near the horizon move by more than a pixel")
    elif any(m for _, m, _ in moved):
        names = ", ".join(n for n, m, _ in moved if m)
        decided["refraction"] = (True, f"moves the {names} to another pixel")
    elif moved:
        text = ", ".join(f"{n} by {math.degrees(s) * 60:.1f} arcmin" for n, _, s in moved)
        decided["refraction"] = (False, f"shifts the {text}, within its pixel "
                                        f"({math.degrees(view.pixel_rad) * 60:.0f} arcmin)")
    else:
        decided["refraction"] = (False, "no point sources in the image")

    computed, skipped = [], {}
    for name in EFFECTS:
        on, reason = decided[name]
        if name in scene.exclude:
            skipped[name] = "excluded by the user"
        elif name == "skyglow" and scene.light_map is None:
            skipped[name] = reason
        elif name == "scintillation":
            # a still image holds the time-averaged flux; twinkling needs a time axis
            # (skytorch.stars.observe(..., twinkle_samples=n) gives the sequences)
            skipped[name] = reason + (" (cannot be forced)" if name in scene.force else "")
        elif name in scene.force:
            computed.append(name)
        elif on:
            computed.append(name)
        else:
            skipped[name] = reason
    result = Plan(tuple(computed), skipped, shares, g, _time.perf_counter() - start,
                  eclipse_factor=eclipse)
    logger.info("plan: computed %s; skipped %s", result.computed, result.skipped)
    return result


def _eclipse_factor(scene, geometry: Geometry) -> torch.Tensor:
    """:func:`skytorch.scene.render.eclipse_factor`, cached per atmosphere, geometry and
    wavelength grid (a fresh copy each call)."""
    wavelength = scene.wavelength_nm().to(torch.float64)
    key = (float(scene.turbidity), float(scene.ozone_du), geometry.sun_distance_m,
           geometry.shadow_distance_m, geometry.shadow_offset_m,
           tuple(wavelength.tolist()))
    return _eclipse_factor_cached(key).clone()


@lru_cache(maxsize=64)
def _eclipse_factor_cached(key) -> torch.Tensor:
    from skytorch.scene.render import eclipse_factor

    turbidity, ozone_du, sun_distance_m, shadow_distance_m, shadow_offset_m, wavelength = key
    scene = _AtmosphereKey(turbidity, ozone_du)
    geometry = _ShadowKey(sun_distance_m, shadow_distance_m, shadow_offset_m)
    return eclipse_factor(scene, geometry, torch.tensor(wavelength, dtype=torch.float64))


@dataclass(frozen=True)
class _AtmosphereKey:
    turbidity: float
    ozone_du: float

    def atmosphere(self):
        from skytorch.scene.render import cached_atmosphere

        return cached_atmosphere(self.turbidity, self.ozone_du)


@dataclass(frozen=True)
class _ShadowKey:
    sun_distance_m: float
    shadow_distance_m: float
    shadow_offset_m: float


def clear_cache() -> None:
    """Forget the cached geometry, Moon fluxes and eclipse factors (a cold planner)."""
    _site_geometry.cache_clear()
    _moon_fluxes_cached.cache_clear()
    _eclipse_factor_cached.cache_clear()


def _moon_radius() -> float:
    from skytorch.constants import MOON_RADIUS_M

    return MOON_RADIUS_M
