r"""Umbra, penumbra and antumbra of a spherical occluder lit by a spherical Sun.

Similar triangles give the shadow cones exactly. With the Sun (radius ``R_s``) at distance
``D`` from the occluder's centre (radius ``R``), the umbral cone is bounded by the external
common tangents of the two spheres and the penumbral cone by the internal ones, with
half-angles

.. math::

    \sin f_u = \frac{R_s - R}{D}, \qquad \sin f_p = \frac{R_s + R}{D} .

A tangent line at distance ``R`` from the occluder's centre crosses the plane
perpendicular to the axis at distance ``x`` behind the centre at radius

.. math::

    r_u(x) = \frac{R}{\cos f_u} - x \tan f_u , \qquad
    r_p(x) = \frac{R}{\cos f_p} + x \tan f_p

(the Besselian ``l_1``, ``l_2`` of solar eclipses). The umbra ends at the apex
``x_a = R / \sin f_u``; beyond it ``r_u < 0`` and ``|r_u|`` is the radius of the antumbra
(annular zone). Seen from the occluder's centre, to first order in the small angles,
``r_u / x = \pi - s + \pi_\odot`` and ``r_p / x = \pi + s + \pi_\odot`` with the occluder's
parallax ``\pi = R / x``, the Sun's semi-diameter ``s = R_s / D`` and its parallax
``\pi_\odot = R / D`` — the classical lunar-eclipse formulas.

Shadow enlargement by Earth's atmosphere (Espenak & Meeus 2009, sect. 1.3):

* ``"chauvenet"`` (Chauvenet 1891; Astronomical Almanac): both radii ``x 1.02``, with the
  Earth's radius scaled by 0.998340 for the mean radius at latitude 45 degrees:
  ``R_p = 1.02 (0.998340 P_m + S_s + P_s)``, ``R_u = 1.02 (0.998340 P_m - S_s + P_s)``.
* ``"danjon"`` (Danjon 1951; Connaissance des Temps; used by the Five Millennium Canon):
  the Earth's radius is enlarged by 1/85 and reduced by 1/594 for the oblateness,
  ``R_p = 1.01 P_m + S_s + P_s``, ``R_u = 1.01 P_m - S_s + P_s`` (1.01 ~ 1 + 1/85 - 1/594).
* ``"none"``: the geometric cones.

Here the enlargement is applied to the occluder radius in the exact cone formulas
(``R -> 1.01 R`` for Danjon, ``R -> 0.998340 R`` and then both radii ``x 1.02`` for
Chauvenet). That also scales the solar parallax term ``P_s`` (8.8 arcsec) by the same
factor, a difference of 0.09 arcsec from the published forms, i.e. 3e-5 in eclipse
magnitude.

References
----------
1. Espenak, F., Meeus, J. 2009, "Five Millennium Canon of Lunar Eclipses: -1999 to +3000",
   NASA/TP-2009-214172, sect. 1.3 "Enlargement of Earth's shadows"; also
   https://eclipse.gsfc.nasa.gov/LEcat5/shadow.html (equations 1-3 to 1-6).
2. Danjon, A. 1951, "Les éclipses de Lune par la pénombre en 1951", L'Astronomie 65, 51.
3. Chauvenet, W. 1891, "A Manual of Spherical and Practical Astronomy", vol. 1, 5th ed.,
   Lippincott, Philadelphia, p. 542.
4. Müller, M., Engel, J., Döllner, J. 2012, "Single-Pass Rendering of Day and Night Sky
   Phenomena", Proc. Vision, Modeling and Visualization, eq. (5)-(6),
   doi:10.2312/PE/VMV/VMV12/055-062.
5. Meeus, J. 1998, "Astronomical Algorithms", 2nd ed., Willmann-Bell, ch. 54.
"""

from __future__ import annotations

import torch

from skytorch._validate import check_broadcastable, check_choice, check_range, common_dtype

__all__ = [
    "CHAUVENET_ENLARGEMENT",
    "CHAUVENET_OBLATENESS",
    "DANJON_ENLARGEMENT",
    "ENLARGEMENTS",
    "MULLER_EARTH_RADIUS_M",
    "MULLER_MOON_RADIUS_M",
    "MULLER_SUN_RADIUS_M",
    "muller_shadow_radii",
    "shadow_cone",
    "shadow_radii",
]

#: shadow enlargement conventions understood by :func:`shadow_radii`
ENLARGEMENTS = ("danjon", "chauvenet", "none")
#: Danjon: Earth's radius x (1 + 1/85 - 1/594), rounded to 1.01 as in the canon (ref. 1)
DANJON_ENLARGEMENT = 1.01
#: Chauvenet: both shadow radii x (1 + 1/50) (ref. 1, 3)
CHAUVENET_ENLARGEMENT = 1.02
#: Chauvenet: Earth's mean radius at latitude 45 degrees over the equatorial one (ref. 1)
CHAUVENET_OBLATENESS = 0.998340

#: radii implied by Müller et al.'s coefficients 3.6676, 397.0001 and 404.3354: the sums
#: give R_sun / R_moon = 400.668 and R_earth / R_moon = 3.6677, i.e. these radii [m]
MULLER_SUN_RADIUS_M = 696_000e3
MULLER_EARTH_RADIUS_M = 6_371e3
MULLER_MOON_RADIUS_M = 1_737.1e3


def _occluder_factors(enlargement: str) -> tuple[float, float]:
    """(factor on the occluder radius, factor on both shadow radii)."""
    check_choice("enlargement", enlargement, ENLARGEMENTS)
    if enlargement == "danjon":
        return DANJON_ENLARGEMENT, 1.0
    if enlargement == "chauvenet":
        return CHAUVENET_OBLATENESS, CHAUVENET_ENLARGEMENT
    return 1.0, 1.0


def _cone(x, sun_distance, sun_radius, radius, enlargement: str):
    """Cone radii without input checks: (umbra, penumbra, sin f_u, sin f_p, radius used)."""
    radius_factor, shadow_factor = _occluder_factors(enlargement)
    radius = radius * radius_factor
    sin_u = (sun_radius - radius) / sun_distance
    sin_p = (sun_radius + radius) / sun_distance
    cos_u = torch.sqrt((1.0 - sin_u) * (1.0 + sin_u))
    cos_p = torch.sqrt((1.0 - sin_p) * (1.0 + sin_p))
    umbra = shadow_factor * (radius / cos_u - x * sin_u / cos_u)
    penumbra = shadow_factor * (radius / cos_p + x * sin_p / cos_p)
    return umbra, penumbra, sin_u, sin_p, radius


def shadow_cone(
    distance_m,
    sun_distance_m,
    sun_radius_m,
    occluder_radius_m,
    enlargement: str = "danjon",
) -> dict[str, torch.Tensor]:
    """Umbra, penumbra and antumbra of a spherical occluder at a distance behind it.

    Parameters
    ----------
    distance_m : array_like
        Distance ``x`` from the occluder's centre along the anti-Sun axis [m], >= 0.
    sun_distance_m : array_like
        Distance ``D`` between the centres of the Sun and the occluder [m].
    sun_radius_m : array_like
        Radius of the Sun ``R_s`` [m].
    occluder_radius_m : array_like
        Radius of the occluder ``R`` [m] (for Earth: the equatorial radius, as in the
        parallax-based conventions), smaller than ``R_s``.
    enlargement : {"danjon", "chauvenet", "none"}
        Atmospheric enlargement convention (see the module docstring).

    Returns
    -------
    dict of str to torch.Tensor
        Broadcast shape of the inputs:
        ``umbra_radius_m`` (signed: negative beyond the umbra's apex),
        ``antumbra_radius_m`` (``max(-r_u, 0)``), ``penumbra_radius_m``,
        ``apex_distance_m`` (length of the umbral cone), ``umbra_half_angle_rad``,
        ``penumbra_half_angle_rad``.

    Examples
    --------
    >>> cone = shadow_cone(384_400e3, 1.496e11, 6.957e8, 6_378_137.0, enlargement="none")
    >>> round(float(cone["umbra_radius_m"]) / 1e3), round(float(cone["penumbra_radius_m"]) / 1e3)
    (4607, 8182)
    """
    dtype = common_dtype(distance_m, sun_distance_m, sun_radius_m, occluder_radius_m)
    x = check_range("distance_m", distance_m, 0.0, unit=" m", dtype=dtype)
    sun_distance = check_range("sun_distance_m", sun_distance_m, 0.0, low_inclusive=False,
                               unit=" m", dtype=dtype)
    sun_radius = check_range("sun_radius_m", sun_radius_m, 0.0, low_inclusive=False,
                             unit=" m", dtype=dtype)
    radius = check_range("occluder_radius_m", occluder_radius_m, 0.0, low_inclusive=False,
                         unit=" m", dtype=dtype)
    check_choice("enlargement", enlargement, ENLARGEMENTS)
    check_broadcastable(distance_m=x, sun_distance_m=sun_distance, sun_radius_m=sun_radius,
                        occluder_radius_m=radius)
    with torch.no_grad():
        effective = radius * _occluder_factors(enlargement)[0]
        bad = (sun_radius + effective >= sun_distance) | (effective >= sun_radius)
        if bool(bad.any()):
            first = tuple(bad.nonzero()[0].tolist())
            values = torch.broadcast_tensors(radius, sun_radius, sun_distance, bad)[:3]
            occluder, sun, distance = (float(v[first]) for v in values)
            raise ValueError(
                "shadow cones need an occluder smaller than the Sun and both well separated "
                "(occluder_radius_m < sun_radius_m and their sum < sun_distance_m); got "
                f"occluder_radius_m={occluder:g}, sun_radius_m={sun:g}, "
                f"sun_distance_m={distance:g} (enlargement {enlargement!r})"
            )
    umbra, penumbra, sin_u, sin_p, radius = _cone(x, sun_distance, sun_radius, radius,
                                                  enlargement)
    return {
        "umbra_radius_m": umbra,
        "antumbra_radius_m": torch.clamp(-umbra, min=0.0),
        "penumbra_radius_m": penumbra,
        "apex_distance_m": (radius / sin_u).expand_as(umbra),
        "umbra_half_angle_rad": torch.asin(sin_u).expand_as(umbra),
        "penumbra_half_angle_rad": torch.asin(sin_p).expand_as(umbra),
    }


def shadow_radii(
    distance_m,
    sun_distance_m,
    sun_radius_m,
    occluder_radius_m,
    enlargement: str = "danjon",
) -> tuple[torch.Tensor, torch.Tensor]:
    """Umbral and penumbral radii at ``distance_m`` behind the occluder [m].

    Same parameters as :func:`shadow_cone`. Returns ``(umbra_radius_m, penumbra_radius_m)``;
    the umbral radius is negative beyond the apex of the umbra, where its magnitude is the
    radius of the antumbra.

    Examples
    --------
    >>> umbra, penumbra = shadow_radii(384_400e3, 1.496e11, 6.957e8, 6_378_137.0)
    >>> round(float(umbra) / 1e3), round(float(penumbra) / 1e3)
    (4671, 8246)
    """
    cone = shadow_cone(distance_m, sun_distance_m, sun_radius_m, occluder_radius_m,
                       enlargement)
    return cone["umbra_radius_m"], cone["penumbra_radius_m"]


def muller_shadow_radii(moon_distance_m, sun_distance_m) -> tuple[torch.Tensor, torch.Tensor]:
    """Müller et al. (2012) eq. (5)-(6): umbral and penumbral radii in Moon radii.

    ``eps_u = 3.6676 - 397.0001 d_M / d_S``, ``eps_p = 3.6676 + 404.3354 d_M / d_S`` with the
    Earth–Moon and Earth–Sun distances ``d_M``, ``d_S`` [m]. These are the first-order
    (small-angle) cone radii of :func:`shadow_cone` with ``enlargement="none"`` and the
    radii :data:`MULLER_SUN_RADIUS_M`, :data:`MULLER_EARTH_RADIUS_M`,
    :data:`MULLER_MOON_RADIUS_M`.

    Examples
    --------
    >>> eps_u, eps_p = muller_shadow_radii(384_400e3, 1.496e11)
    >>> round(float(eps_u), 3), round(float(eps_p), 3)
    (2.648, 4.707)
    """
    dtype = common_dtype(moon_distance_m, sun_distance_m)
    moon = check_range("moon_distance_m", moon_distance_m, 0.0, dtype=dtype)
    sun = check_range("sun_distance_m", sun_distance_m, 0.0, low_inclusive=False, dtype=dtype)
    check_broadcastable(moon_distance_m=moon, sun_distance_m=sun)
    ratio = moon / sun
    return 3.6676 - 397.0001 * ratio, 3.6676 + 404.3354 * ratio
