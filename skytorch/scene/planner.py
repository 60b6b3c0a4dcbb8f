"""Planner: compute only the effects that can change a scene beyond its tolerance.

The NeL/Ryzom sky (ref. 1) draws only what the time of day and the weather make
visible; Müller et al. (ref. 2, §5) switch stars and the Moon with a day–night factor.
Here the decision is quantitative: each effect's share of the image's V-band flux (the
L1 norm of the luminance over the pixels, :math:`\\sum_p Y_p\\,\\Omega_p`) is bounded
with cheap estimates, and an effect whose share is below ``scene.tolerance`` is skipped
with the reason recorded. Omitting it then changes the image by at most that share.

The Sun and Moon come from one ephemeris evaluation per instant
(:mod:`skytorch.scene.geometry`), cached per time and site and handed to the render
with the plan, so planning and rendering share it.

Vocabulary (:data:`EFFECTS`): ``sky`` (scattered sunlight and twilight), ``sun`` (the
solar disc), ``moon`` (disc and moonlit sky), ``earthshine``, ``eclipse`` (Earth's shadow
on the Moon), ``stars``, ``scintillation``, ``skyglow`` (city lights), ``refraction``
(of point sources). The natural background (airglow, zodiacal light, unresolved stars)
is always part of the image.

Estimates
---------
* natural background: the zenith value (22.0 V mag arcsec^-2) over the hemisphere (a
  lower bound: the van Rhijn gradient brightens it towards the horizon, so every share
  computed against it is an upper bound);
* sky: single-scattering radiance (:meth:`Atmosphere.sky_radiance`) at 9 directions,
  averaged and spread over the hemisphere; a function of the Sun's altitude only, so it
  is tabulated per atmosphere (every 0.25°, in 5° segments computed when first needed)
  and interpolated;
* sun, moon: their V magnitudes above the atmosphere (the Moon's interpolated in a
  table of :func:`skytorch.moon.magnitude` over phase angle and distance, built once per
  process) when their apparent upper limb is above the horizon;
* earthshine: the Moon's magnitude with minus without earthshine;
* eclipse: zero outside the penumbra (:func:`skytorch.eclipse.shadow_radii`, Danjon
  enlargement; a test of the Moon's offset from the anti-Sun axis) — an exact
  criterion. Inside it no shadow model is evaluated: the Moon's share is bounded by the
  uneclipsed Moon, the dimming by the Moon's flux times one minus the Sun's visible
  fraction past an opaque sphere the size of the top of the atmosphere at the disc's
  point nearest the axis, and the image total counts the Moon at that least
  illuminance (so every share is an upper bound);
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
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
import torch

from skytorch.constants import (
    ASTRONOMICAL_UNIT_M,
    EARTH_MEAN_RADIUS_M,
    EARTH_TOP_OF_ATMOSPHERE_M,
    MOON_RADIUS_M,
    SUN_RADIUS_M,
)
from skytorch.scene.geometry import Geometry, scene_geometry
from skytorch.scene.geometry import clear_cache as clear_geometry
from skytorch.scene.resources import cached_atmosphere, refracted_altitude

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
#: Sun-altitude step of the planner's sky-flux table [degree] (0.5 gives 4 % error in
#: deep twilight, 0.25 below 0.3 %)
SKY_TABLE_STEP_DEG = 0.25
#: ... computed in segments of this many degrees when first needed
SKY_TABLE_SEGMENT_DEG = 5.0
#: hemisphere [arcsec^2]
HEMISPHERE_ARCSEC2 = 2.0 * math.pi * (180.0 * 3600.0 / math.pi) ** 2

#: quadrature nodes of the planner's estimate of the Moon's magnitude (an estimate only)
PLANNER_MOON_QUADRATURE = 8
#: nodes of the planner's table of the Moon's flux over phase angle (2° apart) ...
MOON_TABLE_PHASES = 91
#: ... and over the observer–Moon distance
MOON_TABLE_DISTANCES = 8
#: distances of that table [m]: perigee 356 400 km less the Earth's radius to apogee
#: 406 700 km plus it, rounded outwards
MOON_TABLE_DISTANCE_RANGE_M = (3.45e8, 4.15e8)

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
        Sun and Moon at the observer (shared with the render).
    seconds : float
        Wall time of the planning [s].
    """

    computed: tuple[str, ...]
    skipped: dict[str, str]
    shares: dict[str, float] = field(default_factory=dict)
    geometry: Geometry | None = None
    seconds: float = 0.0

    def __contains__(self, effect: str) -> bool:
        return effect in self.computed

    def attrs(self) -> dict[str, str]:
        """``effects_computed`` and ``effects_skipped`` as netCDF-safe strings."""
        return {"effects_computed": ",".join(self.computed),
                "effects_skipped": "; ".join(f"{k}: {v}" for k, v in self.skipped.items())}


def _sky_flux(scene, geometry: Geometry) -> float:
    """Hemisphere V flux of single-scattered sunlight (relative to V = 0), interpolated
    log-linearly in the Sun's altitude in :func:`sky_flux_table`."""
    key = (float(scene.turbidity), float(scene.ozone_du), float(scene.elevation_m),
           tuple(scene.wavelength_nm().tolist()))
    deepest = _deepest_sunlit_deg(*key[:2])
    if geometry.sun_altitude_deg <= -deepest:
        return 0.0
    segment = min(int((geometry.sun_altitude_deg + deepest) / SKY_TABLE_SEGMENT_DEG),
                  int((90.0 + deepest) / SKY_TABLE_SEGMENT_DEG))
    altitude, log_flux = sky_flux_table(*key, segment)
    return float(np.exp(np.interp(geometry.sun_altitude_deg, altitude, log_flux)))


@lru_cache(maxsize=8)
def _deepest_sunlit_deg(turbidity: float, ozone_du: float) -> float:
    """Sun depression [degree] beyond which all the air an observer sees is in shadow.

    Every point of the atmosphere the observer can see lies within ``acos(R / R_top)`` of
    the observer's zenith (seen from the planet's centre); with the Sun deeper than
    twice that angle below the horizon all of it is in the Earth's shadow.
    """
    atm = cached_atmosphere(turbidity, ozone_du)
    return 2.0 * math.degrees(math.acos(atm.planet_radius_m / atm.top_radius_m))


@lru_cache(maxsize=256)
def sky_flux_table(turbidity: float, ozone_du: float, elevation_m: float,
                   wavelengths: tuple, segment: int) -> tuple[np.ndarray, np.ndarray]:
    """The planner's estimate of the sunlit sky's V flux against the Sun's altitude.

    Single-scattering radiance (:meth:`Atmosphere.sky_radiance`) at 9 directions (the
    zenith and 60° and 85° from it at 0°, 90°, 180°, 270° from the Sun's azimuth),
    averaged and spread over the hemisphere. It depends on the Sun's altitude only, so it
    is tabulated per atmosphere, observer height and wavelength grid every
    :data:`SKY_TABLE_STEP_DEG`, in segments of :data:`SKY_TABLE_SEGMENT_DEG` computed when
    first needed, from the depression where the whole visible atmosphere is in the
    Earth's shadow (:func:`_deepest_sunlit_deg`, flux zero) up to the zenith.

    Returns
    -------
    altitude_deg : ndarray (n,)
        Sun altitudes of the segment's nodes [degree].
    log_flux : ndarray (n,)
        Natural logarithm of the flux relative to V = 0 (the smallest positive float
        where the flux is zero).
    """
    from skytorch.moon.sky import radiance_to_mag_arcsec2

    atm = cached_atmosphere(turbidity, ozone_du)
    low = -_deepest_sunlit_deg(turbidity, ozone_du) + segment * SKY_TABLE_SEGMENT_DEG
    n = round(SKY_TABLE_SEGMENT_DEG / SKY_TABLE_STEP_DEG) + 1
    altitude = np.minimum(low + SKY_TABLE_STEP_DEG * np.arange(n), 90.0)
    wl = torch.tensor(wavelengths, dtype=torch.float64)
    zenith = torch.tensor([0.0] + [math.radians(60.0)] * 4 + [math.radians(85.0)] * 4,
                          dtype=torch.float64)
    azimuth = torch.tensor([0.0] + [k * math.pi / 2 for k in range(4)] * 2,
                           dtype=torch.float64)
    sun_zenith = torch.deg2rad(90.0 - torch.as_tensor(altitude))[:, None].expand(-1, 9)
    radiance = atm.sky_radiance(wl, zenith.expand_as(sun_zenith), azimuth.expand_as(sun_zenith),
                                sun_zenith, torch.zeros_like(sun_zenith), elevation_m,
                                solar_irradiance=True, n_samples=24)
    mags = radiance_to_mag_arcsec2(radiance.clamp(min=1e-300), wl)
    flux = torch.mean(10.0 ** (-0.4 * mags), dim=-1) * HEMISPHERE_ARCSEC2
    if segment == 0:
        flux[0] = 0.0
    return altitude, np.log(flux.clamp(min=np.finfo(np.float64).tiny).numpy())


def _moon_fluxes(geometry: Geometry) -> tuple[float, float]:
    """V flux of the Moon with earthshine and of its earthshine alone (relative to V = 0),
    interpolated in a table of :func:`skytorch.moon.magnitude` over phase angle and
    distance (:func:`moon_flux_table`)."""
    alpha, distance, table = moon_flux_table()
    u = min(max(geometry.phase_angle_rad, 0.0), math.pi) / math.pi * (alpha.size - 1)
    v = (min(max(geometry.moon_distance_m, distance[0]), distance[-1]) - distance[0]) / (
        distance[1] - distance[0])
    i, j = min(int(u), alpha.size - 2), min(int(v), distance.size - 2)
    fu, fv = u - i, v - j
    values = ((1 - fu) * (1 - fv) * table[i, j] + fu * (1 - fv) * table[i + 1, j]
              + (1 - fu) * fv * table[i, j + 1] + fu * fv * table[i + 1, j + 1])
    scale = (ASTRONOMICAL_UNIT_M / geometry.moon_sun_distance_m) ** 2
    total, sunlit = float(values[0]) * scale, float(values[1]) * scale
    return total, total - sunlit


@lru_cache(maxsize=1)
def moon_flux_table() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Moon's V flux with and without earthshine over phase angle and distance.

    Returns
    -------
    alpha_rad : ndarray (MOON_TABLE_PHASES,)
        Phase angles, uniform in [0, π].
    distance_m : ndarray (MOON_TABLE_DISTANCES,)
        Observer–Moon distances, uniform over :data:`MOON_TABLE_DISTANCE_RANGE_M`.
    flux : ndarray (phase, distance, 2)
        Flux relative to V = 0 at 1 AU from the Sun, with earthshine and without
        (:func:`skytorch.moon.magnitude`, :data:`PLANNER_MOON_QUADRATURE` nodes).
    """
    from skytorch.moon import magnitude

    alpha = torch.linspace(0.0, math.pi, MOON_TABLE_PHASES, dtype=torch.float64)
    distance = torch.linspace(*MOON_TABLE_DISTANCE_RANGE_M, MOON_TABLE_DISTANCES,
                              dtype=torch.float64)
    options = {"distance_m": distance[None, :], "n_quadrature": PLANNER_MOON_QUADRATURE}
    fluxes = [10.0 ** (-0.4 * magnitude(alpha[:, None], earthshine=earthshine, **options))
              for earthshine in (True, False)]
    return alpha.numpy(), distance.numpy(), torch.stack(fluxes, -1).numpy()


def _eclipse_bounds(geometry: Geometry) -> float:
    """Lower bound of the Moon's disc-averaged illuminance in the Earth's shadow.

    The fraction of the Sun visible past an opaque sphere as large as the top of the
    atmosphere (:func:`skytorch.eclipse.sun_visible_fraction`, limb-darkened) at the
    point of the disc nearest the shadow axis: light through the atmosphere only adds to
    it, and the visible fraction grows with the offset from the axis. Zero without
    further work when that point lies in the umbra of that sphere
    (:func:`skytorch.eclipse.shadow_radii`, no enlargement).
    """
    from skytorch.eclipse import shadow_radii, sun_visible_fraction
    from skytorch.eclipse.shadow import shadow_angles

    nearest = max(geometry.shadow_offset_m - _moon_radius(), 0.0)
    opaque = EARTH_MEAN_RADIUS_M + EARTH_TOP_OF_ATMOSPHERE_M
    distance = torch.tensor(geometry.shadow_distance_m, dtype=torch.float64)
    umbra, _ = shadow_radii(distance, geometry.sun_distance_m, SUN_RADIUS_M, opaque,
                            enlargement="none")
    if nearest < float(umbra):
        return 0.0
    angles = shadow_angles(distance,
                           torch.tensor(nearest, dtype=torch.float64),
                           geometry.sun_distance_m, SUN_RADIUS_M, opaque)
    return float(sun_visible_fraction(angles["sun_radius_rad"], angles["occluder_radius_rad"],
                                      angles["separation_rad"]))


def _above_horizon(altitude_deg: float) -> bool:
    return math.radians(altitude_deg) + SEMI_DIAMETER_RAD + HORIZON_REFRACTION_RAD > 0.0


def _pixel_moves(scene, view, altitude_deg: float, azimuth_deg: float) -> tuple[bool, float]:
    """Whether refraction moves a point to another pixel, and the shift [rad]."""
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
    lit = 1.0
    if inside and moon_up:
        # bounds, not estimates: the Moon's share is at most the uneclipsed Moon's; in the
        # total (the denominator of every share) it counts with its least illuminance
        lit = _eclipse_bounds(g)
        total = total - moon + moon_total * lit
        s = share("moon", moon_total)
        decided["moon"] = (s >= tol, f"Moon in the Earth's shadow, at most {s:.1e} of the "
                                     "image flux")
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
        s = share("eclipse", moon_total * (1.0 - lit))
        decided["eclipse"] = (s >= tol, f"the Earth's shadow dims the Moon by up to {s:.1e} "
                                        "of the image flux")
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
    result = Plan(tuple(computed), skipped, shares, g, _time.perf_counter() - start)
    logger.info("plan: computed %s; skipped %s", result.computed, result.skipped)
    return result


def clear_cache() -> None:
    """Forget the geometry cached per time and site (a planner meeting a new instant)."""
    clear_geometry()


def _moon_radius() -> float:
    return MOON_RADIUS_M
