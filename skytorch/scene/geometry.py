r"""Sun and Moon at the observers of a scene, from one ephemeris evaluation per instant.

The planner and the render share these numbers (kept per instant and site by
:meth:`skytorch.scene.resources.SceneResources.geometries`): :func:`site_geometries` reads the
barycentric positions and velocities of the Earth, the Sun and the Moon from DE421 once
per instant (three ``at()`` calls of skyfield's SPICE kernel), applies light time and
annual aberration, and rotates the apparent geocentric vectors to the horizontal frame
of every observer (``icrs_to_horizontal`` rotation: precession–nutation, sidereal time).

Notes
-----
Light time: the body's barycentric position is moved back along its velocity by
:math:`\tau = |r|/c`, iterated twice (the quadratic term of the Moon's motion over
1.3 s is millimetres, the Sun's over 499 s metres). Annual aberration: the relativistic
formula of :func:`skytorch.ephemeris.aberrate` with the Earth's barycentric velocity.
Gravitational deflection is omitted: for the Sun itself it vanishes, for the Moon it is
:math:`0.004'' \cot(\psi/2)` (:math:`\psi` the Moon's elongation), milliarcseconds
except near new Moon. The topocentric vectors are the apparent geocentric vectors less
the observer's geocentric position (WGS84); the observer's diurnal aberration (at most
0.32 arcsec) is omitted. The result agrees with skyfield's full
``observe().apparent().altaz()`` to well below an arcsecond (tested).

References
----------
1. Urban, S. E. & Seidelmann, P. K. (eds.) 2013, Explanatory Supplement to the
   Astronomical Almanac, 3rd ed., University Science Books, ch. 7 (light time,
   aberration).
2. Folkner, W. M. et al. 2008, The Planetary and Lunar Ephemeris DE 421, JPL IOM
   343R-08-003.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from skytorch.constants import (
    EARTH_MEAN_RADIUS_M,
    MOON_RADIUS_M,
    SPEED_OF_LIGHT_M_S,
    SUN_RADIUS_M,
)


@dataclass
class Geometry:
    """Sun and Moon at one observer and instant (degrees, metres, radians).

    The vectors are tuples of floats in the observer's horizontal frame (north, east, up)
    [m]: ``sun_horizontal_m`` and ``moon_horizontal_m`` from the observer to the apparent
    Sun and Moon, ``observer_horizontal_m`` from the Earth's centre to the observer.
    ``phase_angle_rad`` is the topocentric Sun–Moon–observer angle (it differs from the
    geocentric one by up to the Moon's horizontal parallax, ~1°).
    """

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
    sun_horizontal_m: tuple = (0.0, 0.0, 0.0)
    moon_horizontal_m: tuple = (0.0, 0.0, 0.0)
    observer_horizontal_m: tuple = (0.0, 0.0, 0.0)

    @property
    def moon_radius_rad(self) -> float:
        """Apparent (topocentric) angular radius of the Moon [rad]."""
        return math.asin(MOON_RADIUS_M / self.moon_distance_m)

    @property
    def moon_sun_distance_m(self) -> float:
        """Distance from the Moon to the Sun [m].

        The Earth–Sun distance when the vectors are not given.
        """
        distance = math.dist(self.sun_horizontal_m, self.moon_horizontal_m)
        return distance if distance > 0.0 else self.sun_distance_m


def _light_time(body, earth_position: np.ndarray) -> np.ndarray:
    """Geocentric vector (3,) [m] of a body seen with light time, from barycentric states."""
    position = np.asarray(body.position.m, np.float64).reshape(3)
    velocity = np.asarray(body.velocity.m_per_s, np.float64).reshape(3)
    relative = position - earth_position
    for _ in range(2):
        relative = position - velocity * (np.linalg.norm(relative) / SPEED_OF_LIGHT_M_S) \
            - earth_position
    return relative


def apparent_geocentric(time) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Apparent geocentric Sun and Moon vectors and the ICRS -> Earth-fixed rotation.

    Parameters
    ----------
    time : numpy.datetime64
        One UTC instant.

    Returns
    -------
    sun_m, moon_m : Tensor (3,) float64
        GCRS axes, light-time distances [m], aberrated directions.
    rotation : Tensor (3, 3) float64
        ICRS -> Earth-fixed (true equator of date rotated by the apparent sidereal time).
    """
    from skytorch.ephemeris import aberrate, earth_rotation, skyfield_time

    t = skyfield_time([time])
    earth_body, *bodies = _bodies()
    earth = earth_body.at(t)
    earth_position = np.asarray(earth.position.m, np.float64).reshape(3)
    earth_velocity = torch.from_numpy(np.asarray(earth.velocity.m_per_s, np.float64).reshape(3))
    relative = torch.from_numpy(np.stack([_light_time(body.at(t), earth_position)
                                          for body in bodies]))  # (2, 3): Sun, Moon
    distance = torch.linalg.vector_norm(relative, dim=-1, keepdim=True)
    vectors = distance * aberrate(relative / distance, earth_velocity)
    return vectors[0], vectors[1], earth_rotation(t)[0]


def _bodies():
    """Return the Earth, Sun and Moon of DE421 (skyfield vector sums of the loaded kernel)."""
    from skytorch.ephemeris import load_ephemeris

    kernel = load_ephemeris()
    return kernel["earth"], kernel["sun"], kernel["moon"]


def site_geometries(time, lat_deg, lon_deg, elevation_m) -> list[Geometry]:
    """Sun and Moon at several observers for one instant (one ephemeris evaluation).

    Parameters
    ----------
    time : numpy.datetime64
        UTC instant.
    lat_deg, lon_deg, elevation_m : sequence of float (observer,)
        WGS84 latitude, east longitude [degree] and height above the ellipsoid [m].

    Returns
    -------
    list of Geometry
        One per observer.
    """
    from skytorch.eclipse import shadow_radii
    from skytorch.ephemeris import altaz_from_horizontal, geodetic_to_itrs, horizontal_rows
    from skytorch.moon.geometry import phase_angle

    sun, moon, rotation = apparent_geocentric(time)
    lat = torch.deg2rad(torch.as_tensor(np.asarray(lat_deg, float).reshape(-1)))
    lon = torch.deg2rad(torch.as_tensor(np.asarray(lon_deg, float).reshape(-1)))
    height = torch.as_tensor(np.asarray(elevation_m, float).reshape(-1))
    rows = horizontal_rows(lat, lon)  # (observer, 3, 3) Earth-fixed -> horizontal
    # a few 3-vectors per observer: numpy from here (cheaper than torch for tiny arrays)
    observer = np.einsum("oij,oj->oi", rows.numpy(), geodetic_to_itrs(lat, lon, height).numpy())
    to_horizontal = rows.numpy() @ rotation.numpy()
    sun_h = to_horizontal @ sun.numpy() - observer
    moon_h = to_horizontal @ moon.numpy() - observer
    sun_alt, sun_az = (v.numpy() for v in altaz_from_horizontal(torch.from_numpy(sun_h)))
    moon_alt, moon_az = (v.numpy() for v in altaz_from_horizontal(torch.from_numpy(moon_h)))
    moon_range = np.linalg.norm(moon_h, axis=-1)

    sun_distance = float(torch.linalg.vector_norm(sun))
    sun_hat = sun / sun_distance
    along = -float(moon @ sun_hat)
    offset = float(torch.linalg.vector_norm(moon + along * sun_hat))
    umbra, penumbra = shadow_radii(torch.tensor(max(along, 1.0), dtype=torch.float64),
                                   sun_distance, SUN_RADIUS_M, EARTH_MEAN_RADIUS_M,
                                   enlargement="danjon")
    phase = phase_angle(torch.from_numpy(sun_h), torch.from_numpy(moon_h),
                        torch.zeros(3, dtype=torch.float64)).numpy()  # topocentric
    shared = {"sun_distance_m": sun_distance,
              "shadow_distance_m": along, "shadow_offset_m": offset,
              "penumbra_radius_m": float(penumbra), "umbra_radius_m": float(umbra)}
    return [Geometry(sun_altitude_deg=math.degrees(sun_alt[i]),
                     sun_azimuth_deg=math.degrees(sun_az[i]),
                     moon_altitude_deg=math.degrees(moon_alt[i]),
                     moon_azimuth_deg=math.degrees(moon_az[i]),
                     moon_distance_m=float(moon_range[i]),
                     phase_angle_rad=float(phase[i]),
                     sun_horizontal_m=tuple(sun_h[i].tolist()),
                     moon_horizontal_m=tuple(moon_h[i].tolist()),
                     observer_horizontal_m=tuple(observer[i].tolist()), **shared)
            for i in range(len(observer))]
