r"""Planner: compute only the effects that can change a scene beyond its tolerance.

The NeL/Ryzom sky (ref. 1) draws only what the time of day and the weather make
visible; Müller et al. (ref. 2, §5) switch stars and the Moon with a day–night factor.
Here the decision is quantitative: each effect's share of the image's V-band flux (the
L1 norm of the luminance over the pixels, :math:`\sum_p Y_p\,\Omega_p`) is bounded
with cheap estimates, and an effect whose share is below ``scene.tolerance`` is skipped
with the reason recorded. Omitting it then changes the image by at most that share; each
effect is judged alone, so the skipped effects together change it by at most the sum of
their shares (recorded in the reasons), which a large tolerance lets exceed the tolerance
itself (0.9 skips a noon sky of share 0.12 and a Sun of 0.88).

The Sun and Moon come from one ephemeris evaluation per instant
(:mod:`skytorch.scene.geometry`), kept per time and site by the scene's
:class:`~skytorch.scene.resources.SceneResources` and handed to the render
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
  resources object) when their apparent upper limb is above the horizon;
* earthshine: the Moon's magnitude with minus without earthshine;
* eclipse: zero outside the penumbra (:func:`skytorch.eclipse.shadow_radii`, Danjon
  enlargement; a test of the Moon's offset from the anti-Sun axis) — an exact
  criterion. Inside it no shadow model is evaluated: the Moon's share is bounded by the
  uneclipsed Moon, the dimming by the Moon's flux times one minus the Sun's visible
  fraction past an opaque sphere the size of the top of the atmosphere at the disc's
  point nearest the axis, and the image total counts the Moon at that least
  illuminance (so every share is an upper bound);
* solar_eclipse: zero unless the Moon's penumbra reaches a ball holding all the air the
  observer sees (:func:`skytorch.scene.solar_eclipse_sky.penumbra_touches`, a geometric
  bound). When it does, the Sun counts at its visible fraction at the observer plus the
  corona (Baumbach's law, 1.1e-6 of the Sun), and the sky counts as zero in the image
  total (it may be dark throughout), so every share stays an upper bound;
* stars: half the integrated V flux of the catalogue above ``star_limit_mag``; and,
  since a point source changes its own pixel however small its share of the image, the
  brightest star or planet that can be up (:meth:`SceneResources.brightest_point_flux`)
  against the darkest sky its pixel can hold: the natural background plus the darkest
  of the sky estimate's 9 directions (none while the Moon's penumbra reaches the air in
  sight). Stars are drawn when either is at least ``scene.tolerance`` (at totality the
  corona dominates the image flux, yet Venus and the brightest stars stand out of the
  dark sky);
* skyglow: the brightest sky measured by Falchi et al. (2016), 14.0 V mag arcsec^-2,
  over the hemisphere (a bound, since the planner cannot afford the skyglow model);
* refraction: the Sun's and Moon's pixels with and without refraction (table of
  :func:`skytorch.stars.refraction_table`); with stars in a
  fisheye or panorama, stars near the horizon always move by more than a pixel;
* scintillation: a still image records the mean flux of a twinkling star, so it is
  always skipped (twinkling sequences: ``skytorch.stars.observe(..., twinkle_samples=n)``).

Orders of scattering (``Scene.scattering_orders``; ``"auto"`` is the fidelity preset's
``scattering_orders``): with 1 the sky and the moonlit sky are single-scattered. With
``"converged"`` the multiple-scattering tables of the resources
(:meth:`~skytorch.scene.resources.SceneResources.scattering_tables`, all orders to
convergence) give each order's hemisphere flux for the Sun's (Moon's) zenith angle (the
9 directions of the sky estimate, at the table wavelength nearest 550 nm, times the
source's V flux above the atmosphere); the sky's estimate above is raised by the orders
>= 2, and the planner keeps the fewest orders ``n`` whose omitted orders ``> n`` are
below ``scene.tolerance`` of that sky's own flux (a stricter test than a share of the
image flux, which the Sun's disc dominates by day) (:attr:`Plan.scattering_orders`, the
attributes ``sky_scattering_orders``, ``moon_scattering_orders`` and
``scattering_orders_reason`` of the render). An integer ``N`` is used as given. The
tables reach the Sun 18 deg below the horizon: deeper, and during a solar eclipse (whose
sky is a single-scattering march with the Sun's visible fraction), the sky is
single-scattered, with the reason recorded.

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

import json
import logging
import math
import time as _time
from dataclasses import dataclass, field

import numpy as np
import torch

from skytorch.constants import (
    EARTH_MEAN_RADIUS_M,
    EARTH_TOP_OF_ATMOSPHERE_M,
    MOON_RADIUS_M,
    SUN_RADIUS_M,
)
from skytorch.scene.geometry import Geometry
from skytorch.scene.presets import (  # noqa: F401 (the planner's constants, re-exported)
    BRIGHTEST_SKYGLOW_MAG_ARCSEC2,
    EFFECTS,
    FIDELITY,
    HEMISPHERE_ARCSEC2,
    HORIZON_REFRACTION_RAD,
    MOON_TABLE_DISTANCE_RANGE_M,
    MOON_TABLE_DISTANCES,
    MOON_TABLE_PHASES,
    PLANNER_MOON_QUADRATURE,
    SEMI_DIAMETER_RAD,
    SKY_TABLE_SEGMENT_DEG,
    SKY_TABLE_STEP_DEG,
    SUN_V_MAG,
)
from skytorch.scene.resources import SceneResources

logger = logging.getLogger(__name__)


def _flux(magnitude: float) -> float:
    """V flux relative to magnitude 0."""
    return 10.0 ** (-0.4 * magnitude)


def scene_key(scene) -> tuple:
    """Return what a plan depends on: the scene's parameters, its light map (identity)."""
    return (json.dumps(scene.parameters(), sort_keys=True, default=str), id(scene.light_map))


def _surface_flux(mag_arcsec2: float, area_arcsec2: float = HEMISPHERE_ARCSEC2) -> float:
    return _flux(mag_arcsec2) * area_arcsec2


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
    scattering_orders : dict
        Orders of scattering of the sunlit sky and of the moonlit sky (``"sky"``,
        ``"moon"``; 1 = single scattering) and the orders the tables were built with
        (``"tables"``: an integer or ``"converged"``; 1 when none were needed).
    scattering_reason : str
        Why those orders (the estimated share of the omitted orders).
    made_for : tuple
        :func:`scene_key` of the scene it was made for (empty for a plan built by hand);
        a render refuses it for another scene.
    """

    computed: tuple[str, ...]
    skipped: dict[str, str]
    shares: dict[str, float] = field(default_factory=dict)
    geometry: Geometry | None = None
    seconds: float = 0.0
    scattering_orders: dict = field(default_factory=lambda: {"sky": 1, "moon": 1,
                                                             "tables": 1})
    scattering_reason: str = "single scattering"
    made_for: tuple = ()

    def __contains__(self, effect: str) -> bool:
        """Whether ``effect`` is among the computed effects."""
        return effect in self.computed

    def attrs(self) -> dict:
        """Return the decisions as netCDF-safe attributes.

        ``effects_computed`` and ``effects_skipped`` (strings), ``sky_scattering_orders``
        and ``moon_scattering_orders`` (integers) and ``scattering_orders_reason``.
        """
        return {"effects_computed": ",".join(self.computed),
                "effects_skipped": "; ".join(f"{k}: {v}" for k, v in self.skipped.items()),
                "sky_scattering_orders": int(self.scattering_orders["sky"]),
                "moon_scattering_orders": int(self.scattering_orders["moon"]),
                "scattering_orders_reason": self.scattering_reason}


def requested_orders(scene):
    """Orders of scattering a scene asks for: 1, an integer N or ``"converged"``.

    ``scene.scattering_orders``, with ``"auto"`` replaced by its fidelity preset's
    ``scattering_orders`` (:data:`FIDELITY`).
    """
    value = scene.scattering_orders
    return FIDELITY[scene.fidelity]["scattering_orders"] if value == "auto" else value


#: largest source zenith angle of the multiple-scattering tables [rad] (18 deg below the
#: horizon, :data:`skytorch.atmosphere.multiple_scattering.MU_S_MIN`)
MS_MAX_SOURCE_ZENITH_RAD = math.radians(108.0)


def scattering_tables(scene, resources: SceneResources):
    """Return the multiple-scattering tables of a scene's fidelity and orders (None for 1)."""
    orders = requested_orders(scene)
    if orders == 1:
        return None
    knobs = FIDELITY[scene.fidelity]
    return resources.scattering_tables(orders, knobs["ms_tables"], knobs["ms_wavelength_nodes"])


def order_fluxes(tables, source_zenith_rad: float, elevation_m: float) -> np.ndarray:
    """Hemisphere flux of each order of scattering per unit source flux (orders,) [1].

    The tables' radiance at the 9 directions of the sky estimate (the zenith, 60 and 85
    deg from it at 0, 90, 180, 270 deg from the source's azimuth), averaged and times
    2 pi sr, at the table wavelength nearest 550 nm; order ``k`` is the sum of orders
    ``1..k`` less that of ``1..k-1``. Tables with an extrapolated remainder
    (:attr:`~skytorch.atmosphere.multiple_scattering.ScatteringTables.remainder_extrapolated`)
    give it as one more entry (orders_computed + 1,): the orders beyond the last computed.
    """
    zenith = torch.tensor([0.0] + [math.radians(60.0)] * 4 + [math.radians(85.0)] * 4,
                          dtype=torch.float64)
    azimuth = torch.tensor([0.0] + [k * math.pi / 2 for k in range(4)] * 2,
                           dtype=torch.float64)
    band = int(torch.argmin((tables.wavelength_nm - 550.0).abs()))
    source = torch.full_like(zenith, source_zenith_rad)
    levels = list(range(1, tables.orders_computed + 1))
    if tables.remainder_extrapolated:
        levels.append("converged")
    cumulative = np.array([float(tables.radiance(elevation_m, zenith, azimuth, source,
                                                 scattering_orders=k)[..., band].mean())
                           for k in levels])
    return 2.0 * math.pi * np.diff(cumulative, prepend=0.0)


def orders_needed(fluxes: np.ndarray, total: float, tolerance: float,
                  beyond: float = 0.0) -> tuple[int, float]:
    """Fewest orders ``n`` whose omitted orders (``> n``) are below ``tolerance`` of ``total``.

    ``fluxes`` (orders,) are the orders' fluxes, in the unit of ``total``, ``beyond`` the
    flux of the orders after them (which every ``n`` omits); returns ``n`` (at most the
    number of orders listed) and the omitted share.
    """
    tail = np.cumsum(fluxes[::-1])[::-1] + beyond  # tail[k]: the orders k+1, k+2, ...
    for n in range(1, fluxes.size):
        if tail[n] / total < tolerance:
            return n, float(tail[n] / total)
    return int(fluxes.size), beyond / total


def _sky_flux(resources: SceneResources, elevation_m: float, geometry: Geometry) -> float:
    """Hemisphere V flux of single-scattered sunlight (relative to V = 0).

    Interpolated log-linearly in the Sun's altitude in
    :meth:`~skytorch.scene.resources.SceneResources.sky_flux_table`.
    """
    return _sky_table_value(resources, elevation_m, geometry, 1)


def _darkest_sky(resources: SceneResources, elevation_m: float, geometry: Geometry) -> float:
    """V surface brightness (flux per arcsec², relative to V = 0) of the darkest direction.

    The darkest of the 9 directions of
    :meth:`~skytorch.scene.resources.SceneResources.sky_flux_table`, single-scattered
    sunlight only (the orders >= 2 and the moonlit sky only add to it).
    """
    return _sky_table_value(resources, elevation_m, geometry, 2)


def _sky_table_value(resources: SceneResources, elevation_m: float, geometry: Geometry,
                     column: int) -> float:
    """Interpolate a column of the planner's sky table log-linearly in the Sun's altitude."""
    deepest = resources.deepest_sunlit_deg
    if geometry.sun_altitude_deg <= -deepest:
        return 0.0
    segment = min(int((geometry.sun_altitude_deg + deepest) / SKY_TABLE_SEGMENT_DEG),
                  int((90.0 + deepest) / SKY_TABLE_SEGMENT_DEG))
    table = resources.sky_flux_table(elevation_m, segment)
    return float(np.exp(np.interp(geometry.sun_altitude_deg, table[0], table[column])))


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


def _solar_eclipse_bound(geometry: Geometry, atmosphere, elevation_m: float,
                         sun_drawn: bool) -> tuple[bool, float, float, float]:
    """Bound the solar eclipse's effect on a scene.

    Returns whether the Moon's penumbra can touch the air in sight, its clearance [m], the
    Sun's visible fraction at the observer and the corona's flux bound (0 unless drawn).
    """
    # imported here: the eclipse sky (and the atmosphere it loads) only when a plan is made
    from skytorch.scene.solar_eclipse_sky import (
        CORONA_FLUX_FRACTION,
        penumbra_touches,
        sight_radius_m,
        visible_fraction_at,
    )

    touches, clearance = penumbra_touches(geometry, sight_radius_m(
        atmosphere.planet_radius_m, atmosphere.top_altitude_m, elevation_m))
    if not touches:
        return False, clearance, 1.0, 0.0
    sun_seen = float(visible_fraction_at(geometry, torch.zeros(3, dtype=torch.float64)))
    corona = _flux(SUN_V_MAG) * CORONA_FLUX_FRACTION if sun_drawn else 0.0
    return True, clearance, sun_seen, corona


def _above_horizon(altitude_deg: float) -> bool:
    """Whether a disc at true altitude [degree] can reach into the image.

    Views end at apparent altitude 0, where refraction is largest for an observer on the
    ground (0.55° in the standard atmosphere, less from higher up), so the 0.6° bound
    holds at every height.
    """
    return math.radians(altitude_deg) + SEMI_DIAMETER_RAD + HORIZON_REFRACTION_RAD > 0.0


def _pixel_moves(resources: SceneResources, elevation_m: float, view, altitude_deg: float,
                 azimuth_deg: float) -> tuple[bool, float]:
    """Whether refraction moves a point to another pixel, and the shift [rad]."""
    true = torch.tensor([math.radians(altitude_deg)], dtype=torch.float64)
    apparent = torch.tensor([resources.refracted_altitude(elevation_m,
                                                          math.radians(altitude_deg))],
                            dtype=torch.float64)
    azimuth = torch.tensor([math.radians(azimuth_deg)], dtype=torch.float64)
    before = view.pixel_index(true, azimuth)
    after = view.pixel_index(apparent, azimuth)
    return bool((before != after).any()), float((apparent - true).abs().max())


def plan(scene, view=None, resources: SceneResources | None = None,  # noqa: C901 (rule table)
         geometry: Geometry | None = None) -> Plan:
    """Decide which effects of ``scene`` to compute.

    Parameters
    ----------
    scene : skytorch.scene.Scene
        One observer.
    view : skytorch.scene.scene.View, optional
        The scene's view (built when not given).
    resources : SceneResources, optional
        Tables of the scene's spec (default: ``scene.resources()``).
    geometry : Geometry, optional
        The Sun and Moon at the scene's observer and instant (default: from
        ``resources``).

    Returns
    -------
    Plan
        ``computed`` and ``skipped`` (with reasons), estimated flux shares, geometry.
    """
    start = _time.perf_counter()
    resources = scene.resources() if resources is None else resources
    resources.check(scene)
    view = scene.make_view(resources) if view is None else view
    g = resources.geometry(scene) if geometry is None else geometry
    elevation = float(scene.elevation_m)
    tol = scene.tolerance
    decided: dict[str, tuple[bool, str]] = {}
    shares: dict[str, float] = {}
    points = view.kind != "directions"

    natural = _surface_flux(scene.natural_mag_arcsec2)
    sky = _sky_flux(resources, elevation, g)
    orders = _OrderEstimate(scene, resources, g, elevation)
    sky = sky + orders.sky_higher()
    sun_up = _above_horizon(g.sun_altitude_deg)
    moon_up = _above_horizon(g.moon_altitude_deg)
    sun = _flux(SUN_V_MAG) if sun_up and points else 0.0
    moon_total, earthshine = resources.moon_fluxes(g)
    moon = moon_total if moon_up else 0.0
    star_flux = (0.5 * resources.integrated_starlight(scene.star_limit_mag)
                 + resources.planet_flux(scene.time, scene.lat_deg, scene.lon_deg,
                                         scene.star_limit_mag)) if points else 0.0
    atm = resources.atmosphere
    touches, clearance, sun_seen, corona = _solar_eclipse_bound(
        g, atm, elevation, sun_up and points)
    if touches:
        # bounds: the Sun at its visible fraction at the observer plus the corona; the sky
        # counts as zero in the total (it may be dark throughout), so every share is an
        # upper bound
        total = natural + sun * sun_seen + corona + moon + star_flux
        sun = sun * sun_seen + corona
    else:
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
        s = share("sun", sun)
        decided["sun"] = (s >= tol, f"Sun {s:.1e} of the image flux")
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
    if not touches:
        decided["solar_eclipse"] = (False, "the Moon's penumbra misses the air in sight "
                                           f"by {clearance / 1e3:.0f} km")
    else:
        s = share("solar_eclipse", sky + _flux(SUN_V_MAG) * (1.0 - sun_seen)
                  * (sun_up and points))
        decided["solar_eclipse"] = (s >= tol, f"the Moon's penumbra reaches the air in sight "
                                              f"(Sun {sun_seen:.3g} visible here); it dims "
                                              f"up to {s:.1e} of the image flux")
    if not points:
        decided["stars"] = (False, "a directions view holds no point sources")
    else:
        s = share("stars", star_flux)
        # a point source changes its own pixel: its flux against the darkest sky a pixel
        # can hold (the natural background, plus the sunlit sky unless the Moon's
        # penumbra reaches the air in sight, where the sky may be dark throughout)
        darkest = _flux(scene.natural_mag_arcsec2) + (
            0.0 if touches else _darkest_sky(resources, elevation, g))
        peak = resources.brightest_point_flux(scene.time, scene.lat_deg, scene.lon_deg,
                                              scene.star_limit_mag)
        contrast = peak / (darkest * (math.degrees(view.pixel_rad) * 3600.0) ** 2)
        decided["stars"] = (s >= tol or contrast >= tol,
                            f"starlight {s:.1e} of the image flux; the brightest point "
                            f"source {contrast:.1e} of the darkest sky in its pixel")
    stars_on = decided["stars"][0] or "stars" in scene.force
    decided["scintillation"] = (False, "a still image records the mean flux of a twinkling "
                                       "star" if stars_on else "no stars in the image")
    if scene.light_map is None:
        decided["skyglow"] = (False, "no light map")
    elif not bool((scene.light_map["flux"] != 0).any()):
        decided["skyglow"] = (False, "the light map emits no light")
    else:
        s = share("skyglow", _surface_flux(BRIGHTEST_SKYGLOW_MAG_ARCSEC2))
        decided["skyglow"] = (s >= tol, f"even the brightest city sky (Falchi 2016) is "
                                        f"{s:.1e} of the image flux")
    moved = []
    if points:
        if decided["sun"][0] or "sun" in scene.force:
            moves, shift = _pixel_moves(resources, elevation, view,
                                         g.sun_altitude_deg, g.sun_azimuth_deg)
            moved.append(("Sun", moves, shift))
        if moon_on:
            moves, shift = _pixel_moves(resources, elevation, view,
                                         g.moon_altitude_deg, g.moon_azimuth_deg)
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
    decision, reason = orders.decide(computed, tol, moon_total)
    gather = FIDELITY[scene.fidelity].get("ms_final_gather")
    gathered_sky = decision["sky"] > 1 and "solar_eclipse" not in computed
    if gather is not None and (gathered_sky or decision["moon"] > 1):
        reason += ("; orders >= 2 corrected by their final gather on {} x {} sky nodes "
                   "(quadrature {} x {} x {})".format(*gather["lut"], gather["quadrature"][0],
                                                       2 * gather["quadrature"][1],
                                                       gather["quadrature"][2]))
    result = Plan(tuple(computed), skipped, shares, g, _time.perf_counter() - start,
                  decision, reason, scene_key(scene))
    logger.info("plan: computed %s; skipped %s", result.computed, result.skipped)
    return result


class _OrderEstimate:
    """The planner's multiple-scattering estimates for one scene (module notes)."""

    def __init__(self, scene, resources, geometry, elevation_m):
        self.requested = requested_orders(scene)
        self.ground_albedo = scene.ground_albedo
        self.eclipse_higher = FIDELITY[scene.fidelity].get("eclipse_higher")
        self.geometry, self.elevation_m = geometry, elevation_m
        self.sun_zenith = math.radians(90.0 - geometry.sun_altitude_deg)
        self.sun_in_tables = self.sun_zenith <= MS_MAX_SOURCE_ZENITH_RAD
        needed = self.requested != 1 and (self.sun_in_tables
                                          or _above_horizon(geometry.moon_altitude_deg))
        self.tables = scattering_tables(scene, resources) if needed else None
        self.sun = (order_fluxes(self.tables, self.sun_zenith, elevation_m) * _flux(SUN_V_MAG)
                    if self.tables is not None and self.sun_in_tables else None)

    def sky_higher(self) -> float:
        """V flux of the sunlit sky's orders >= 2 (0 without tables)."""
        return 0.0 if self.sun is None else float(self.sun[1:].sum())

    def _one(self, fluxes, tol) -> tuple[int, str]:
        if self.requested != "converged":
            return int(self.requested), f"{self.requested} orders as requested"
        computed = self.tables.orders_computed
        n, omitted = orders_needed(fluxes[:computed], float(fluxes.sum()), tol,
                                   beyond=float(fluxes[computed:].sum()))
        return n, (f"{n} of {computed} orders (omitted {omitted:.1e} of its flux; "
                   f"tables {'converged' if self.tables.converged else 'not converged'})")

    def decide(self, computed, tol, moon_flux) -> tuple[dict, str]:
        """Orders of the sky and the moonlit sky, and the reason."""
        tables = 1 if self.tables is None else self.requested
        result, reasons = {"sky": 1, "moon": 1, "tables": tables}, []
        if self.requested == 1:
            return result, "single scattering (scattering_orders 1)"
        if "sky" in computed and "solar_eclipse" in computed and self.ground_albedo > 0.0:
            raise ValueError(
                f"ground_albedo={self.ground_albedo}: the solar-eclipse sky's orders 1 and 2 "
                "are a direct quadrature over a black ground, which has no ground reflection; "
                "render scenes with a solar eclipse in sight with ground_albedo=0")
        if "sky" not in computed:
            reasons.append("sky: not computed")
        elif "solar_eclipse" in computed and (
                self.eclipse_higher is None or self.tables is None
                or (self.requested != "converged" and int(self.requested) < 3)):
            # the eclipse sky's orders 1 and 2 come from a direct quadrature
            result["sky"] = 2
            reasons.append("sky: 2 orders (the solar-eclipse sky: single and second order "
                           "with the Sun's visible fraction at every scattering; orders >= 3 "
                           "are not computed: 0.5-2.8 times order 2 at the zenith at "
                           "totality; the 'reference' preset computes them)")
        elif "solar_eclipse" in computed:
            last = (self.tables.orders_computed + 1 if self.requested == "converged"
                    else int(self.requested))
            result["sky"] = last
            lut, quadrature = self.eclipse_higher["lut"], self.eclipse_higher["quadrature"]
            reasons.append(
                f"sky: {last} orders (the solar-eclipse sky: single and second order with the "
                "Sun's visible fraction at every scattering; orders 3.." + str(last)
                + " from the clear sky's tables dimmed by one step of diffusion into the "
                f"umbra on {lut[0]} x {lut[1]} sky nodes, quadrature {quadrature[0]} x "
                f"{2 * quadrature[1]} x {quadrature[2]})")
        elif not self.sun_in_tables:
            reasons.append("sky: single scattering (Sun below the tables' 18 deg depression)")
        else:
            result["sky"], text = self._one(self.sun, tol)
            reasons.append(f"sky: {text}")
        moon_zenith = math.radians(90.0 - self.geometry.moon_altitude_deg)
        if "moon" not in computed or self.tables is None or moon_zenith > 0.5 * math.pi:
            reasons.append("moonlit sky: not computed")
        else:
            fluxes = order_fluxes(self.tables, moon_zenith, self.elevation_m) * moon_flux
            result["moon"], text = self._one(fluxes, tol)
            reasons.append(f"moonlit sky: {text}")
        return result, "; ".join(reasons)


def _moon_radius() -> float:
    return MOON_RADIUS_M
