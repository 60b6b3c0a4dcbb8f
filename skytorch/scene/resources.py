"""Physical resources of a scene: one explicit object that the planner and renderers share.

A :class:`SceneResources` is built from a frozen :class:`SceneSpec` (the physical
parameters its tables depend on: turbidity, ozone column and wavelength grid) and holds,
each built on first use and kept on the instance,

* the atmosphere (:meth:`skytorch.atmosphere.Atmosphere.earth`) and the Earth's shadow
  (:meth:`skytorch.eclipse.Shadow.earth`);
* transmittance tables (:class:`skytorch.atmosphere.tables.TransmittanceTable`, also
  cached on disk), per table resolution;
* the star-site tables (refraction and extinction at an observer height,
  :func:`skytorch.stars.refraction_table`, :func:`skytorch.stars.extinction_table`, each
  built only when asked for: the planner's refraction test needs no extinction table) and
  the planner's sky-flux table, per observer height;
* the planner's table of the Moon's flux, the star catalogue and its spectra and
  vectors, per faintest magnitude;
* skyglow models (:class:`skytorch.skyglow.SkyglowModel`, also cached on disk with
  :mod:`skytorch._cache`), per model setting;
* multiple-scattering tables (:func:`skytorch.atmosphere.multiple_scattering.
  precompute_scattering`, black ground) at a few wavelength nodes spanning the spec's
  grid, per (orders, table resolution, number of nodes); one table serves every point
  source (Sun and Moon), since it is per unit irradiance and the source direction is an
  argument of its look-up;
* the fisheye and panorama views (pixel directions and solid angles) per size and dtype;
* the Sun and Moon per (instant, site) (:func:`skytorch.scene.geometry.site_geometries`,
  the last :data:`SceneResources.GEOMETRIES_KEPT`), so that planning and rendering, and
  the observers of one instant, share one ephemeris evaluation.

Nothing is held in module globals: two resources objects share nothing, and a render is
a function of its scene and the spec of its resources only (tested: renders with fresh
and with reused resources are bit-identical). A user who renders a time series keeps one
object (``Scene.resources()``, passed as ``render(..., resources=r)``); a scene whose
parameters do not match the spec is refused with ``ValueError``.

Threads: every build runs under a lock of the instance (re-entrant, since tables build on
the atmosphere), so threads rendering with one shared object build each table once and
then read it concurrently; the tables are never modified after they are built.

The physics packages (:mod:`skytorch.atmosphere`, :mod:`skytorch.stars`, ...) are
imported when a resource is first built, not when :mod:`skytorch.scene` is imported
(measured start-up cost; see ``tests/test_import_graph.py``).

Examples
--------
>>> from skytorch.scene.resources import SceneResources, SceneSpec
>>> resources = SceneResources(SceneSpec(turbidity=2.0, ozone_du=300.0,
...                                      wavelengths=(450.0, 550.0, 650.0)))
>>> resources.built()
()
>>> round(resources.atmosphere.top_altitude_m)
100000
>>> resources.built()
('atmosphere',)
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, fields, replace

import numpy as np
import torch

from skytorch.constants import ASTRONOMICAL_UNIT_M
from skytorch.scene.geometry import Geometry, site_geometries
from skytorch.scene.presets import (
    HEMISPHERE_ARCSEC2,
    HORIZON_REFRACTION_RAD,
    MOON_TABLE_DISTANCE_RANGE_M,
    MOON_TABLE_DISTANCES,
    MOON_TABLE_PHASES,
    PLANNER_MOON_QUADRATURE,
    SKY_TABLE_SEGMENT_DEG,
    SKY_TABLE_STEP_DEG,
)

__all__ = ["SceneResources", "SceneSpec"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class SceneSpec:
    """The physical parameters a scene's tables depend on (frozen, hashable).

    Parameters
    ----------
    turbidity, ozone_du : float
        Atmosphere parameters (:meth:`skytorch.atmosphere.Atmosphere.earth` checks them
        when the atmosphere is built).
    wavelengths : tuple of float
        The wavelength grid [nm] of the renders (the values of
        :meth:`skytorch.scene.Scene.wavelength_nm`).
    ground_albedo : float
        Lambertian albedo of the ground under the multiple-scattering tables, in [0, 1]
        (default 0, a black ground).
    stratospheric_aod : float
        Vertical optical depth at 550 nm of the stratospheric sulfate layer (LOWTRAN 7's
        background profile) [1]; default 0, no layer.
    """

    turbidity: float
    ozone_du: float
    wavelengths: tuple[float, ...]
    ground_albedo: float = 0.0
    stratospheric_aod: float = 0.0

    def __post_init__(self):
        """Check the spec's fields and store them as floats (TypeError for non-numbers)."""
        for name in ("turbidity", "ozone_du", "ground_albedo", "stratospheric_aod"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f"SceneSpec.{name} must be a number; got {value!r}")
            object.__setattr__(self, name, float(value))
        if (not isinstance(self.wavelengths, tuple) or not self.wavelengths
                or not all(isinstance(v, (int, float)) for v in self.wavelengths)):
            raise TypeError("SceneSpec.wavelengths must be a non-empty tuple of numbers [nm]; "
                            f"got {self.wavelengths!r}")
        object.__setattr__(self, "wavelengths", tuple(float(v) for v in self.wavelengths))
        if not 0.0 <= self.ground_albedo <= 1.0:
            raise ValueError(f"SceneSpec.ground_albedo must be in [0, 1]; got "
                             f"{self.ground_albedo}")

    @classmethod
    def of(cls, scene) -> SceneSpec:
        """Return the spec of a :class:`skytorch.scene.Scene`."""
        return cls(float(scene.turbidity), float(scene.ozone_du),
                   tuple(scene.wavelength_nm().tolist()), float(scene.ground_albedo),
                   float(scene.stratospheric_aod))


#: vertical profile of a scene's stratospheric sulfate layer (LOWTRAN 7's background,
#: :data:`skytorch.atmosphere.aerosol.STRATOSPHERIC_PROFILES`)
STRATOSPHERIC_PROFILE = "background"
#: view zenith nodes of :meth:`SceneResources.scattered_airglow_table` [degree]
SCATTERED_AIRGLOW_ZENITH_DEG = (0.0, 20.0, 40.0, 55.0, 65.0, 72.0, 78.0, 82.0, 85.0, 87.0,
                                88.5, 90.0)
#: wavelength nodes of that table [nm] (log-interpolated between them; clear of the O2
#: A and B and the strongest water bands), with the scene's shortest and longest added
SCATTERED_AIRGLOW_WAVELENGTH_NM = (380.0, 440.0, 500.0, 560.0, 620.0, 660.0, 800.0, 870.0,
                                   1000.0)
#: zenith angles [deg] between which the zodiacal light and starlight arriving at the
#: scattering points is interpolated (azimuthal means; rays from up to ~10° below the
#: horizontal still reach the air above the ground's horizon)
SCATTERED_SKY_SOURCE_ZENITH_DEG = (0.0, 15.0, 30.0, 45.0, 60.0, 70.0, 80.0, 85.0, 90.0, 95.0,
                                   100.0, 105.0)

class SceneResources:
    """Tables shared by the planner and renderers of scenes with one :class:`SceneSpec`.

    Parameters
    ----------
    spec : SceneSpec

    Notes
    -----
    Every resource is built on first use under the instance's lock and kept;
    :meth:`built` lists what has been built. Resources depending on more than the spec
    (observer height, table resolution, faintest star, skyglow settings) are kept per
    value of those arguments.
    """

    #: (instant, site) geometries kept (the oldest are forgotten first)
    GEOMETRIES_KEPT = 256

    def __init__(self, spec: SceneSpec):
        if not isinstance(spec, SceneSpec):
            raise TypeError(f"spec must be a skytorch.scene.resources.SceneSpec; got "
                            f"{type(spec).__name__}")
        self.spec = spec
        self._lock = threading.RLock()
        self._built: dict = {}
        self._geometries: OrderedDict = OrderedDict()
        self._planets: OrderedDict = OrderedDict()

    @classmethod
    def for_scene(cls, scene) -> SceneResources:
        """Return new (empty) resources for the spec of ``scene``."""
        return cls(SceneSpec.of(scene))

    def __repr__(self) -> str:
        """Show the spec and the names of the resources built so far."""
        return f"SceneResources({self.spec!r}, built={list(self.built())})"

    # pickling (process pools) and copies: the spec travels, the tables are rebuilt
    def __getstate__(self) -> dict:
        """Pickle the spec only."""
        return {"spec": self.spec}

    def __setstate__(self, state: dict) -> None:
        """Rebuild empty resources for the pickled spec."""
        self.__init__(state["spec"])

    def check(self, scene) -> None:
        """Raise ``ValueError`` unless ``scene`` has this object's spec."""
        theirs = SceneSpec.of(scene)
        if theirs != self.spec:
            differ = [f"{f.name} {getattr(theirs, f.name)!r} (resources: "
                      f"{getattr(self.spec, f.name)!r})" for f in fields(SceneSpec)
                      if getattr(theirs, f.name) != getattr(self.spec, f.name)]
            raise ValueError("resources: built for another scene spec; the scene has "
                             + "; ".join(differ))

    def _get(self, key, build: Callable):
        with self._lock:
            if key not in self._built:
                self._built[key] = build()
            return self._built[key]

    def built(self) -> tuple:
        """Keys of the resources built so far, in the order they were built."""
        with self._lock:
            return tuple(self._built)

    # ------------------------------------------------------------------ atmosphere
    @property
    def wavelength_nm(self) -> torch.Tensor:
        """The spec's wavelengths (n_wavelength,) [nm], float64."""
        return torch.tensor(self.spec.wavelengths, dtype=torch.float64)

    @property
    def atmosphere(self):
        """``Atmosphere.earth(turbidity, ozone_du)`` of the spec.

        With a stratospheric layer (``spec.stratospheric_aod`` > 0) in LOWTRAN 7's
        background profile.
        """
        def build():
            from skytorch.atmosphere import Atmosphere

            layer = {} if not self.spec.stratospheric_aod else {
                "stratospheric_aerosol_optical_depth": self.spec.stratospheric_aod,
                "stratospheric_aerosol_profile": STRATOSPHERIC_PROFILE}
            return Atmosphere.earth(turbidity=self.spec.turbidity, ozone_du=self.spec.ozone_du,
                                    **layer)

        return self._get("atmosphere", build)

    @property
    def shadow(self):
        """The Earth's shadow (:meth:`skytorch.eclipse.Shadow.earth`) of the atmosphere.

        Its ring table is traced once per wavelength grid and kept on it.
        """
        def build():
            from skytorch.eclipse import Shadow

            return Shadow.earth(self.atmosphere)

        return self._get("shadow", build)

    def transmittance_table(self, n_mu: int, n_r: int):
        """Transmittance table of the atmosphere at the spec's wavelengths.

        ``n_mu × n_r`` nodes; :class:`skytorch.atmosphere.tables.TransmittanceTable`, disk cache.
        """
        def build():
            from skytorch.atmosphere.tables import TransmittanceTable

            return TransmittanceTable.build(self.atmosphere, self.wavelength_nm, cache=True,
                                            n_mu=n_mu, n_r=n_r)

        return self._get(("transmittance", int(n_mu), int(n_r)), build)

    # ------------------------------------------------------------------ site tables
    def refraction_table(self, elevation_m: float):
        """Ray-traced refraction of the atmosphere at an observer height [m].

        :func:`skytorch.stars.refraction_table`.
        """
        elevation_m = float(elevation_m)

        def build():
            from skytorch.stars import refraction_table

            return refraction_table(self.atmosphere, elevation_m)

        return self._get(("refraction", elevation_m), build)

    def extinction_table(self, elevation_m: float, refraction: bool):
        """V-band extinction of the atmosphere at an observer height [m].

        Along refracted paths when ``refraction`` (:func:`skytorch.stars.extinction_table`).
        """
        elevation_m, refraction = float(elevation_m), bool(refraction)

        def build():
            from skytorch.stars import extinction_table

            return extinction_table(self.atmosphere, elevation_m, refraction=refraction)

        return self._get(("extinction", elevation_m, refraction), build)

    def scattered_airglow_table(self, elevation_m: float, layer_height_m: float):
        """Airglow scattered once into lines of sight, per unit zenith emission (cached).

        :func:`skytorch.nightsky.scattered_light.scattered_diffuse_radiance` of a thin
        layer at ``layer_height_m`` (van Rhijn brightening of each incoming ray, zero at
        points above the layer) on :data:`SCATTERED_AIRGLOW_ZENITH_DEG` × the nodes of
        :data:`SCATTERED_AIRGLOW_WAVELENGTH_NM` inside the scene's wavelength range plus
        its two ends; returns ``(zenith_rad, wavelength_nm, radiance)`` with radiance
        (zenith, wavelength) [1] in units of the layer's zenith radiance.
        """
        elevation_m, layer_height_m = float(elevation_m), float(layer_height_m)
        low, high = min(self.spec.wavelengths), max(self.spec.wavelengths)
        nodes = sorted({low, high, *(x for x in SCATTERED_AIRGLOW_WAVELENGTH_NM
                                     if low < x < high)})

        def build():
            from skytorch.nightsky.airglow import layer_path_factor
            from skytorch.nightsky.scattered_light import scattered_diffuse_radiance

            planet = float(self.atmosphere.planet_radius_m)

            def incident(mu, altitude):
                return layer_path_factor(mu, altitude, layer_height_m=layer_height_m,
                                         planet_radius_m=planet)[..., None]

            zenith = torch.deg2rad(torch.tensor(SCATTERED_AIRGLOW_ZENITH_DEG,
                                                dtype=torch.float64))
            wavelength = torch.tensor(nodes, dtype=torch.float64)
            radiance = scattered_diffuse_radiance(self.atmosphere, zenith, wavelength,
                                                  incident, altitude_m=elevation_m)
            return zenith, wavelength, radiance

        return self._get(("scattered_airglow", elevation_m, layer_height_m, low, high), build)

    def scattered_sky_response(self, elevation_m: float):
        """Sky light scattered once into lines of sight, per unit incident radiance (cached).

        :func:`skytorch.nightsky.scattered_light.scattered_zenith_response` on
        :data:`SCATTERED_AIRGLOW_ZENITH_DEG` lines of sight and the wavelength nodes of
        :meth:`scattered_airglow_table`, for an incident radiance interpolated linearly in
        zenith angle between :data:`SCATTERED_SKY_SOURCE_ZENITH_DEG`; returns
        ``(view_zenith_rad, wavelength_nm, source_zenith_rad, response)`` with response
        (source node, view, wavelength) [1].
        """
        elevation_m = float(elevation_m)
        low, high = min(self.spec.wavelengths), max(self.spec.wavelengths)
        nodes = sorted({low, high, *(x for x in SCATTERED_AIRGLOW_WAVELENGTH_NM
                                     if low < x < high)})

        def build():
            from skytorch.nightsky.scattered_light import scattered_zenith_response

            zenith = torch.deg2rad(torch.tensor(SCATTERED_AIRGLOW_ZENITH_DEG,
                                                dtype=torch.float64))
            source = torch.deg2rad(torch.tensor(SCATTERED_SKY_SOURCE_ZENITH_DEG,
                                                dtype=torch.float64))
            wavelength = torch.tensor(nodes, dtype=torch.float64)
            response = scattered_zenith_response(self.atmosphere, zenith, wavelength, source,
                                                 altitude_m=elevation_m)
            return zenith, wavelength, source, response

        return self._get(("scattered_sky", elevation_m, low, high), build)

    def star_site_tables(self, elevation_m: float, refraction: bool):
        """Return the refraction and extinction tables at an observer height [m].

        The refraction table is ``None`` without refraction (:meth:`refraction_table`,
        :meth:`extinction_table`).
        """
        return (self.refraction_table(elevation_m) if refraction else None,
                self.extinction_table(elevation_m, refraction))

    def refracted_altitude(self, elevation_m: float, true_altitude_rad: float) -> float:
        """Apparent altitude [rad] of a true altitude [rad] at an observer height [m].

        From the refraction table (ray-traced refraction), which starts at the apparent
        horizon: an elevated observer sees the Sun and Moon below the astronomical
        horizon, down to the true altitude of the apparent horizon (−2.47° from 3 km).
        Below −1° or that true altitude, whichever is lower, taken there.
        """
        from skytorch.stars import refract

        table = self.refraction_table(elevation_m)
        lowest = min(math.radians(-1.0), float(table["low_rad"]))
        true = torch.tensor([max(true_altitude_rad, lowest)], dtype=torch.float64)
        return float(refract(true, table)[0])

    def apparent_horizon(self, elevation_m: float, refraction: bool) -> float:
        """Apparent altitude [rad] of the horizon (the ground) at an observer height [m].

        0 at sea level; minus the refracted (``refraction``) or geometric dip for an
        elevated observer (:func:`skytorch.stars.photometry.apparent_horizon`).
        """
        elevation_m, refraction = float(elevation_m), bool(refraction)

        def build():
            from skytorch.stars.photometry import apparent_horizon

            return apparent_horizon(self.atmosphere, elevation_m, refraction)

        return self._get(("apparent_horizon", elevation_m, refraction), build)

    @property
    def deepest_sunlit_deg(self) -> float:
        """Sun depression [degree] beyond which all the air an observer sees is in shadow.

        Every point of the atmosphere the observer can see lies within ``acos(R / R_top)``
        of the observer's zenith (seen from the planet's centre); with the Sun deeper than
        twice that angle below the horizon all of it is in the Earth's shadow.
        """
        def build():
            atm = self.atmosphere
            return 2.0 * math.degrees(math.acos(atm.planet_radius_m / atm.top_radius_m))

        return self._get("deepest_sunlit_deg", build)

    def sky_flux_table(self, elevation_m: float, segment: int
                       ) -> tuple[np.ndarray, np.ndarray]:
        """Return the planner's estimate of the sunlit sky's V flux against the Sun's altitude.

        Single-scattering radiance (:meth:`Atmosphere.sky_radiance`) at 9 directions (the
        zenith and 60° and 85° from it at 0°, 90°, 180°, 270° from the Sun's azimuth),
        averaged and spread over the hemisphere. It depends on the Sun's altitude only, so
        it is tabulated per observer height every :data:`SKY_TABLE_STEP_DEG`, in segments
        of :data:`SKY_TABLE_SEGMENT_DEG` computed when first needed, from the depression
        where the whole visible atmosphere is in the Earth's shadow
        (:attr:`deepest_sunlit_deg`, flux zero) up to the zenith.

        Returns
        -------
        altitude_deg : ndarray (n,)
            Sun altitudes of the segment's nodes [degree].
        log_flux : ndarray (n,)
            Natural logarithm of the flux relative to V = 0 (the smallest positive float
            where the flux is zero).
        log_darkest : ndarray (n,)
            Natural logarithm of the darkest of the 9 directions' surface brightness, V
            flux per arcsec² relative to V = 0 (the planner's contrast of point sources).
        """
        elevation_m, segment = float(elevation_m), int(segment)

        def build():
            from skytorch.moon.sky import radiance_to_mag_arcsec2

            atm = self.atmosphere
            low = -self.deepest_sunlit_deg + segment * SKY_TABLE_SEGMENT_DEG
            n = round(SKY_TABLE_SEGMENT_DEG / SKY_TABLE_STEP_DEG) + 1
            altitude = np.minimum(low + SKY_TABLE_STEP_DEG * np.arange(n), 90.0)
            wl = self.wavelength_nm
            zenith = torch.tensor([0.0] + [math.radians(60.0)] * 4 + [math.radians(85.0)] * 4,
                                  dtype=torch.float64)
            azimuth = torch.tensor([0.0] + [k * math.pi / 2 for k in range(4)] * 2,
                                   dtype=torch.float64)
            sun_zenith = torch.deg2rad(90.0 - torch.as_tensor(altitude))[:, None].expand(-1, 9)
            radiance = atm.sky_radiance(wl, zenith.expand_as(sun_zenith),
                                        azimuth.expand_as(sun_zenith), sun_zenith,
                                        torch.zeros_like(sun_zenith), elevation_m,
                                        solar_irradiance=True, n_samples=24, scattering_orders=1)
            mags = radiance_to_mag_arcsec2(radiance.clamp(min=1e-300), wl)
            surface = 10.0 ** (-0.4 * mags)  # (altitude, direction) per arcsec²
            flux = torch.mean(surface, dim=-1) * HEMISPHERE_ARCSEC2
            darkest = surface.amin(dim=-1)
            if segment == 0:
                flux[0] = darkest[0] = 0.0
            tiny = np.finfo(np.float64).tiny
            return (altitude, np.log(flux.clamp(min=tiny).numpy()),
                    np.log(darkest.clamp(min=tiny).numpy()))

        return self._get(("sky_flux", elevation_m, segment), build)

    # ------------------------------------------------------------------ Moon and stars
    def moon_flux_table(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the Moon's V flux with and without earthshine over phase angle and distance.

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
        def build():
            from skytorch.moon import magnitude

            alpha = torch.linspace(0.0, math.pi, MOON_TABLE_PHASES, dtype=torch.float64)
            distance = torch.linspace(*MOON_TABLE_DISTANCE_RANGE_M, MOON_TABLE_DISTANCES,
                                      dtype=torch.float64)
            options = {"distance_m": distance[None, :], "n_quadrature": PLANNER_MOON_QUADRATURE}
            fluxes = [10.0 ** (-0.4 * magnitude(alpha[:, None], earthshine=earthshine,
                                                **options))
                      for earthshine in (True, False)]
            return alpha.numpy(), distance.numpy(), torch.stack(fluxes, -1).numpy()

        return self._get("moon_flux", build)

    def moon_fluxes(self, geometry: Geometry) -> tuple[float, float]:
        """V flux of the Moon with earthshine and of its earthshine alone (relative to V = 0).

        Interpolated bilinearly in :meth:`moon_flux_table`.
        """
        alpha, distance, table = self.moon_flux_table()
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

    def catalogue(self, limit_magnitude: float):
        """Return the star catalogue to a V limit (:func:`skytorch.stars.bright_stars`)."""
        limit_magnitude = float(limit_magnitude)

        def build():
            from skytorch.stars import bright_stars

            return bright_stars(limit_magnitude)

        return self._get(("catalogue", limit_magnitude), build)

    def integrated_starlight(self, limit_magnitude: float) -> float:
        """Total V flux of the catalogue's stars (relative to magnitude 0), whole sky."""
        limit_magnitude = float(limit_magnitude)
        return self._get(("integrated_starlight", limit_magnitude), lambda: float(np.sum(
            10.0 ** (-0.4 * self.catalogue(limit_magnitude)["vmag"].values))))

    def star_vectors(self, limit_magnitude: float):
        """Return the catalogue vectors, V, B−V and epoch [Julian year] to a V limit.

        Vectors of :func:`skytorch.stars.star_vectors`, for the catalogue to a V limit.
        """
        limit_magnitude = float(limit_magnitude)

        def build():
            from skytorch.stars import star_vectors

            cat = self.catalogue(limit_magnitude)
            vectors = star_vectors(cat["ra"].values, cat["dec"].values, cat["pm_ra"].values,
                                   cat["pm_dec"].values, cat["parallax"].values,
                                   dtype=torch.float64)
            return (vectors, torch.as_tensor(cat["vmag"].values, dtype=torch.float64),
                    torch.as_tensor(cat["bv"].values, dtype=torch.float64),
                    float(cat.attrs.get("epoch_jyear", 2000.0)))

        return self._get(("star_vectors", limit_magnitude), build)

    def planet_sources(self, time) -> dict:
        """Return the planets at one UTC instant as catalogue entries at rest.

        Kept per instant, like the geometries (the last :data:`GEOMETRIES_KEPT`); none
        before :data:`skytorch.stars.planets.PLANET_TIME_MIN` (logged).

        Their astrometric geocentric ICRS directions (:func:`skytorch.stars.planets.planets`)
        as :func:`skytorch.stars.star_vectors` without proper motion or parallax, so that
        :func:`skytorch.stars.observe_tensors` adds aberration, refraction and extinction
        as for the stars; the topocentric parallax (at most 35″, Venus at inferior
        conjunction) is neglected.

        Returns
        -------
        dict
            ``"planet"`` (names), ``"vectors"`` (planet, 8), ``"vmag"``, ``"bv"``
            (planet,) [mag], float64.
        """
        time = np.datetime64(time, "ns")

        def build():
            from skytorch.stars import star_vectors
            from skytorch.stars.planets import PLANET_TIME_MIN, planets

            if time < PLANET_TIME_MIN:
                logger.warning("planets are not drawn before %s: their light left them "
                               "before the DE421 ephemeris begins", PLANET_TIME_MIN)
                empty = torch.zeros(0, dtype=torch.float64)
                return {"planet": (), "vectors": torch.zeros(0, 8, dtype=torch.float64),
                        "vmag": empty, "bv": empty}
            ds = planets(time).isel(time=0)
            zeros = np.zeros(ds.sizes["planet"])
            vectors = star_vectors(ds["astrometric_ra"].values, ds["astrometric_dec"].values,
                                   zeros, zeros, zeros, dtype=torch.float64)
            return {"planet": tuple(str(p) for p in ds["planet"].values), "vectors": vectors,
                    "vmag": torch.as_tensor(ds["magnitude"].values, dtype=torch.float64),
                    "bv": torch.as_tensor(ds["bv"].values, dtype=torch.float64)}

        with self._lock:
            if time not in self._planets:
                self._planets[time] = build()
            self._planets.move_to_end(time)
            while len(self._planets) > self.GEOMETRIES_KEPT:
                self._planets.popitem(last=False)
            return self._planets[time]

    def planet_flux(self, time, lat_deg: float, lon_deg: float, limit_magnitude: float
                    ) -> float:
        """V flux (relative to magnitude 0) of the planets to a V limit that can be up.

        Above the atmosphere; a planet counts when its geometric altitude is above −0.8°
        (refraction at the horizon plus a margin, :func:`_can_be_up`): a bound for the
        planner.
        """
        sources = self.planet_sources(time)
        vmag = sources["vmag"][_can_be_up(sources["vectors"], time, lat_deg, lon_deg)]
        return float((10.0 ** (-0.4 * vmag[vmag <= float(limit_magnitude)])).sum())

    def brightest_point_flux(self, time, lat_deg: float, lon_deg: float,
                             limit_magnitude: float) -> float:
        """V flux (relative to magnitude 0) of the brightest star or planet that can be up.

        The catalogue's stars and the planets to a V limit, above the atmosphere, that
        stand above −0.8° geometric altitude at ``time`` (as :meth:`planet_flux`); 0 when
        none does.
        """
        limit = float(limit_magnitude)
        vectors, vmag, _, _ = self.star_vectors(limit)
        peaks = [vmag[_can_be_up(vectors, time, lat_deg, lon_deg)]]
        planets = self.planet_sources(time)
        peaks.append(planets["vmag"][_can_be_up(planets["vectors"], time, lat_deg, lon_deg)])
        vmag = torch.cat([p.to(torch.float64) for p in peaks])
        vmag = vmag[vmag <= limit]
        return float(10.0 ** (-0.4 * vmag.min())) if vmag.numel() else 0.0

    def catalogue_spectra(self, limit_magnitude: float, spectra: Callable) -> torch.Tensor:
        """Return spectra of V = 0 (star, wl) of the catalogue stars to a V limit.

        Every catalogue star to the limit, at the spec's wavelengths:
        ``spectra(vmag, bv, wavelength)`` (the renderer's black bodies), B−V
        missing taken as the solar 0.65.
        """
        limit_magnitude = float(limit_magnitude)

        def build():
            bv = torch.as_tensor(self.catalogue(limit_magnitude)["bv"].values,
                                 dtype=torch.float64)
            bv = torch.nan_to_num(bv, nan=0.65)  # stars without B-V: solar colour
            return spectra(torch.zeros_like(bv), bv, self.wavelength_nm)

        return self._get(("catalogue_spectra", limit_magnitude), build)

    # ------------------------------------------------------------------ skyglow
    def _skyglow_code_hash(self) -> str:
        """Hash of the skyglow and atmosphere sources: a changed model rebuilds cached tables."""
        def build():
            from pathlib import Path

            import skytorch.atmosphere
            import skytorch.skyglow

            digest = hashlib.sha256()
            for package in (skytorch.skyglow, skytorch.atmosphere):
                for path in sorted(Path(package.__file__).parent.glob("*.py")):
                    digest.update(path.read_bytes())
            return digest.hexdigest()

        return self._get("skyglow_code_hash", build)

    def skyglow_key(self, settings: dict) -> str:
        """SHA-256 (hex) of everything a skyglow model depends on.

        The atmosphere, the wavelengths, the model's settings and the skyglow and atmosphere
        sources.
        """
        text = json.dumps({"turbidity": self.spec.turbidity, "ozone_du": self.spec.ozone_du,
                           "stratospheric_aod": self.spec.stratospheric_aod,
                           "wavelength": list(self.spec.wavelengths),
                           "settings": settings, "code": self._skyglow_code_hash(),
                           "format": 1}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()

    def skyglow_cache_path(self, settings: dict):
        """Return the skyglow model's cache file for ``settings`` and the hash it must carry."""
        from skytorch.atmosphere.tables import cache_directory

        key = self.skyglow_key(settings)
        return cache_directory() / f"skyglow_{key[:16]}.nc", key

    def skyglow_model(self, settings: dict):
        """Return the skyglow model of the atmosphere with ``settings``.

        ``settings`` are keywords of :meth:`skytorch.skyglow.SkyglowModel.precompute`; the model is
        cached on disk and kept here.

        The file is written with :func:`skytorch._cache.write_verified` (a record of its
        SHA-256 and of the parameter hash beside it) and read with
        :func:`skytorch._cache.read_verified`: a corrupted, truncated or swapped file, or one
        built for other parameters, is deleted and rebuilt, never served.
        """
        def build():
            from skytorch._cache import read_verified, write_verified
            from skytorch.skyglow import SkyglowModel

            path, key = self.skyglow_cache_path(settings)
            model = read_verified(path, key, SkyglowModel.load)
            if model is None:
                model = SkyglowModel.precompute(self.atmosphere, wavelength_nm=self.wavelength_nm,
                                                progress=False, **settings)
                try:
                    write_verified(path, key, model.save)
                except OSError as error:
                    logger.warning("could not cache the skyglow model at %s: %s", path, error)
            return model

        return self._get(("skyglow", json.dumps(settings, sort_keys=True)), build)

    # ------------------------------------------------------------------ multiple scattering
    def scattering_nodes(self, n_nodes: int) -> torch.Tensor:
        """Wavelength nodes (n,) [nm] of the multiple-scattering tables, increasing.

        The spec's wavelengths themselves (sorted) when there are at most ``n_nodes`` of
        them, else ``n_nodes`` nodes uniform from the shortest to the longest.
        """
        n_nodes = int(n_nodes)
        if n_nodes < 2:
            raise ValueError(f"n_nodes must be an integer >= 2; got {n_nodes}")
        grid = sorted(self.spec.wavelengths)
        if len(grid) <= n_nodes:
            return torch.tensor(grid, dtype=torch.float64)
        return torch.linspace(grid[0], grid[-1], n_nodes, dtype=torch.float64)

    def scattering_tables(self, scattering_orders, resolution: dict, n_nodes: int):
        """Multiple-scattering tables of the atmosphere at :meth:`scattering_nodes`.

        :func:`skytorch.atmosphere.multiple_scattering.precompute_scattering` with
        ``scattering_orders`` (an integer >= 1 or ``"converged"``), the
        :class:`~skytorch.atmosphere.multiple_scattering.TableResolution` of the fields
        ``resolution`` (a mapping) and the spec's Lambertian ``ground_albedo``; built once
        per (orders, resolution, nodes) and kept. The tables give the radiance per unit
        irradiance of a point source in any direction, so the Sun and the Moon share them.
        """
        if isinstance(scattering_orders, bool) or not (
                scattering_orders == "converged"
                or (isinstance(scattering_orders, int) and scattering_orders >= 1)):
            raise ValueError("scattering_orders must be an integer >= 1 or 'converged'; "
                             f"got {scattering_orders!r}")
        # the fields as given (sizes, weights, the ray quadrature's name): the key of the build
        settings = tuple(sorted((str(k), v) for k, v in dict(resolution).items()))
        nodes = self.scattering_nodes(n_nodes)

        def build():
            from skytorch.atmosphere.multiple_scattering import (
                TableResolution,
                precompute_scattering,
            )

            return precompute_scattering(self.atmosphere, nodes,
                                         ground_albedo=self.spec.ground_albedo,
                                         scattering_orders=scattering_orders,
                                         resolution=TableResolution(**dict(settings)))

        return self._get(("scattering", scattering_orders, settings, int(n_nodes)), build)

    # ------------------------------------------------------------------ views
    def view(self, kind: str, size: int, dtype, build: Callable):
        """Return a fisheye or panorama :class:`~skytorch.scene.scene.View` of ``size`` pixels.

        ``build()`` on first use and kept (shared by the renders: do not modify its tensors).
        """
        return self._get(("view", kind, int(size), str(dtype)), build)

    # ------------------------------------------------------------------ geometry
    def geometries(self, time, lat_deg, lon_deg, elevation_m) -> list[Geometry]:
        """:func:`skytorch.scene.geometry.site_geometries` kept per (time, site).

        Observers already seen at this instant are not recomputed; the others share one ephemeris
        evaluation. Fresh copies (the caller may modify them).
        """
        time = np.datetime64(time, "ns")
        keys = [(time, a, b, c) for a, b, c in zip(_floats(lat_deg), _floats(lon_deg),
                                                   _floats(elevation_m), strict=True)]
        with self._lock:
            missing = [k for k in keys if k not in self._geometries]
            if missing:
                computed = site_geometries(time, [k[1] for k in missing],
                                           [k[2] for k in missing], [k[3] for k in missing])
                for key, value in zip(missing, computed, strict=True):
                    self._geometries[key] = value
            result = []
            for key in keys:
                self._geometries.move_to_end(key)
                result.append(replace(self._geometries[key]))
            while len(self._geometries) > self.GEOMETRIES_KEPT:
                self._geometries.popitem(last=False)
        return result

    def geometry(self, scene) -> Geometry:
        """Geometry of a one-observer scene (a fresh copy)."""
        return self.geometries(scene.time, scene.lat_deg, scene.lon_deg, scene.elevation_m)[0]

    def clear(self) -> None:
        """Forget everything built (the next use rebuilds it)."""
        with self._lock:
            self._built.clear()
            self._geometries.clear()
            self._planets.clear()


def _floats(values) -> list[float]:
    return [float(v) for v in np.asarray(values, float).reshape(-1)]


def _can_be_up(vectors: torch.Tensor, time, lat_deg: float, lon_deg: float) -> torch.Tensor:
    """Whether sources (ICRS unit vectors in the first three columns) can be in the sky.

    Geometric altitude at ``time`` above −(refraction at the horizon + 0.2°): the 0.2°
    covers aberration (20″), parallax and the proper motion of the fastest catalogue star
    brighter than V = 6.5 (61 Cygni, 5.3″/yr: 0.15° over the century from J2000 that the
    ephemeris spans).
    """
    from skytorch.ephemeris import icrs_to_horizontal_matrices

    rotation = icrs_to_horizontal_matrices([time], float(lat_deg), float(lon_deg))[0]
    up = (vectors[:, :3].to(rotation.dtype) @ rotation.T)[:, 2]
    return torch.asin(up.clamp(-1.0, 1.0)) > -(HORIZON_REFRACTION_RAD + math.radians(0.2))
