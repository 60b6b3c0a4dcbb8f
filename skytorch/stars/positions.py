"""Apparent topocentric positions of catalogue stars, thousands at a time.

Every star is described by eight numbers — its unit vector ``u`` at the catalogue epoch,
its proper-motion vector ``mu`` [rad/yr], its parallax [rad] and a constant 1 — and every
instant by one 3 × 8 matrix that combines the ICRS → horizontal rotation ``M``
(precession–nutation and Earth rotation, :func:`skytorch.ephemeris.icrs_to_horizontal_
matrices`), the time since the catalogue epoch and Earth's barycentric position. One
batched matmul per time gives the horizontal vectors of all stars
(:func:`horizontal_vectors`, with :func:`skytorch.ephemeris.aberrate` for annual and
diurnal aberration). Because relativistic aberration is an affine map of the direction
(up to a scale that ``atan2`` ignores), :func:`aberration_operators` folds it into the
matrix, so that the fast path (:func:`horizontal_planes`) is a single GEMM.

References
----------
1. ESA 1997, "The Hipparcos and Tycho Catalogues", ESA SP-1200, Vol. 1, §1.2.8 and §1.5.5
   (space motion, parallax).
2. Urban, S. E., Seidelmann, P. K. (eds.) 2013, "Explanatory Supplement to the
   Astronomical Almanac", 3rd ed., ch. 7 (aberration).
3. Müller, S., Engel, J., Döllner, J. 2012, "Single-Pass Rendering of Day and Night Sky
   Phenomena", Proc. VMV 2012, eq. 7 (one rotation per time for all stars).

Examples
--------
>>> import torch
>>> from skytorch.stars.positions import star_vectors
>>> star_vectors(torch.tensor([0.0]), torch.tensor([90.0]), torch.zeros(1), torch.zeros(1),
...              torch.zeros(1)).shape
torch.Size([1, 8])
"""

from __future__ import annotations

import math

import numpy as np
import torch

from skytorch._validate import check_broadcastable, check_finite, check_range
from skytorch.constants import ASTRONOMICAL_UNIT_M, DEGREE
from skytorch.ephemeris import (
    TIME_MAX,
    TIME_MIN,
    aberrate,
    aberration_matrix,
    altaz_from_horizontal,
    icrs_to_horizontal_matrices,
    load_ephemeris,
    observer_gcrs_velocity,
    parse_times,
    skyfield_time,
)
from skytorch.stars.catalog import direction_and_tangents

__all__ = [
    "J2000_UTC",
    "apparent_altaz",
    "epoch_years",
    "aberration_operators",
    "horizontal_planes",
    "horizontal_vectors",
    "star_vectors",
    "time_operators",
]

#: J2000.0 = 2000-01-01T12:00 TT expressed in UTC (TT − UTC = 64.184 s then)
J2000_UTC = np.datetime64("2000-01-01T11:58:55.816", "ns")
#: Julian year [s]
JULIAN_YEAR_S = 365.25 * 86400.0
#: milliarcsecond [rad]
MAS_RAD = DEGREE / 3.6e6


def epoch_years(times, epoch_jyear: float = 2000.0) -> torch.Tensor:
    """Julian years from ``epoch_jyear`` to each UTC time, float64 of shape (time,).

    The 69 s between UTC and TT are ignored (a proper motion of 10″/yr moves a star by
    20 µas in that time).
    """
    values = parse_times(times)
    seconds = (values - J2000_UTC).astype("timedelta64[ns]").astype(np.float64) * 1e-9
    return torch.from_numpy(seconds / JULIAN_YEAR_S - (epoch_jyear - 2000.0))


def star_vectors(ra_deg, dec_deg, pm_ra_mas_yr, pm_dec_mas_yr, parallax_mas,
                 dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """Per-star vectors ``[u, mu, parallax, 1]`` for :func:`horizontal_vectors`.

    Parameters
    ----------
    ra_deg, dec_deg : array_like, shape (star,)
        ICRS right ascension and declination at the catalogue epoch [deg].
    pm_ra_mas_yr, pm_dec_mas_yr : array_like, shape (star,)
        Proper motion mu_alpha cos(delta) and mu_delta [mas/yr].
    parallax_mas : array_like, shape (star,)
        Parallax [mas]; negative catalogue values (measurement noise) count as 0.
    dtype : torch.dtype
        Output dtype.

    Returns
    -------
    torch.Tensor, shape (star, 8)
        Unit vector u (ICRS axes), proper-motion vector mu = mu_alpha* p + mu_delta q
        [rad/yr] with p, q the local east and north unit vectors, parallax [rad] and 1.
    """
    if dtype not in (torch.float64, torch.float32):
        raise TypeError(f"dtype must be torch.float64 or torch.float32; got {dtype!r:.60}")
    ra = torch.deg2rad(check_range("ra_deg", ra_deg, -360.0, 720.0, unit=" deg",
                                   dtype=torch.float64).to(torch.float64))
    dec = torch.deg2rad(check_range("dec_deg", dec_deg, -90.0, 90.0, unit=" deg",
                                    dtype=torch.float64).to(torch.float64))
    pm_ra = check_finite("pm_ra_mas_yr", pm_ra_mas_yr, dtype=torch.float64).to(torch.float64)
    pm_dec = check_finite("pm_dec_mas_yr", pm_dec_mas_yr, dtype=torch.float64).to(torch.float64)
    parallax = check_finite("parallax_mas", parallax_mas,
                            dtype=torch.float64).to(torch.float64).clamp_min(0.0)
    named = {"ra_deg": ra, "dec_deg": dec, "pm_ra_mas_yr": pm_ra, "pm_dec_mas_yr": pm_dec,
             "parallax_mas": parallax}
    if any(v.ndim > 1 for v in named.values()):
        raise ValueError("star columns must be 1-d (star,); got shapes " + ", ".join(
            f"{k} {tuple(v.shape)}" for k, v in named.items()))
    shape = check_broadcastable(**named)
    ra, dec, pm_ra, pm_dec, parallax = (v.reshape(-1).expand(shape if len(shape) else (1,))
                                        for v in named.values())
    unit, east, north = direction_and_tangents(ra, dec)
    motion = (pm_ra[:, None] * east + pm_dec[:, None] * north) * MAS_RAD
    return torch.cat([unit, motion, (parallax * MAS_RAD)[:, None], torch.ones_like(ra)[:, None]],
                     dim=-1).to(dtype)


#: Earth's rotation angle rate per UT1 day [rad/day] (IERS Conventions 2010, eq. 5.15)
EARTH_ROTATION_RAD_PER_UT1_DAY = 2.0 * math.pi * 1.00273781191135448
#: default spacing of the instants at which precession-nutation is evaluated [minutes]
ANCHOR_MINUTES = 30.0


def _rotation_matrices(times, lat_deg, lon_deg, elevation_m, anchor_minutes):
    """ICRS → horizontal matrices, with precession–nutation evaluated at anchor instants.

    Every time is assigned the centre of its ``anchor_minutes`` UTC bin;
    :func:`skytorch.ephemeris.icrs_to_horizontal_matrices` runs once per occupied bin,
    and the Earth rotation between the anchor and the time is applied about the
    celestial pole, M(t) = R_pole(ERA rate · ΔUT1) M(anchor). ΔUT1 comes from skyfield's
    UT1 of both instants, so leap seconds are honoured. Precession and nutation change by
    < 3 mas within ±15 minutes (precession 50″/yr; nutation rate < 0.1″/day).
    """
    values = parse_times(times)
    if anchor_minutes is None:
        return icrs_to_horizontal_matrices(values, lat_deg, lon_deg, elevation_m)
    step = np.timedelta64(int(round(float(anchor_minutes) * 60e9)), "ns")
    epoch = np.datetime64("2000-01-01T00:00", "ns")
    bins = (values - epoch) // step
    unique, inverse = np.unique(bins, return_inverse=True)
    # bin centres clipped to the ephemeris range: a time at TIME_MAX would otherwise be
    # anchored a quarter of an hour beyond it (the clipped anchor is never further away)
    centres = np.clip(epoch + unique * step + step // 2, TIME_MIN, TIME_MAX)
    anchors = icrs_to_horizontal_matrices(centres, lat_deg, lon_deg, elevation_m)[inverse]
    ut1 = np.asarray(skyfield_time(values).ut1, np.float64).reshape(-1)
    ut1_centres = np.asarray(skyfield_time(centres).ut1, np.float64).reshape(-1)[inverse]
    angle = torch.from_numpy((ut1 - ut1_centres) * EARTH_ROTATION_RAD_PER_UT1_DAY)
    # the celestial pole in (north, east, up) axes and the rotation of the sky about it
    lat = math.radians(float(lat_deg))
    pole = torch.tensor([math.cos(lat), 0.0, math.sin(lat)], dtype=torch.float64)
    cross = torch.tensor([[0.0, -pole[2], pole[1]], [pole[2], 0.0, -pole[0]],
                          [-pole[1], pole[0], 0.0]], dtype=torch.float64)
    outer = pole[:, None] * pole[None, :]
    cos, sin = torch.cos(angle)[:, None, None], torch.sin(angle)[:, None, None]
    rotation = cos * torch.eye(3, dtype=torch.float64) + (1.0 - cos) * outer + sin * cross
    return rotation @ anchors


def time_operators(times, lat_deg: float, lon_deg: float, elevation_m: float = 0.0, *,
                   epoch_jyear: float = 2000.0, aberration: bool = True,
                   parallax: bool = True, anchor_minutes: float | None = ANCHOR_MINUTES
                   ) -> tuple[torch.Tensor, torch.Tensor | None]:
    """Per-time 3 × 8 operators and observer velocities for :func:`horizontal_vectors`.

    Parameters
    ----------
    times : str, datetime, datetime64 or a list/array of them
        UTC instants (dimension ``time``).
    lat_deg, lon_deg : float
        Geodetic latitude and east longitude of the observer [deg].
    elevation_m : float
        Height above the WGS84 ellipsoid [m].
    epoch_jyear : float
        Epoch of the catalogue positions [Julian year].
    aberration : bool
        Return the observer's velocity for annual + diurnal aberration (else ``None``).
    parallax : bool
        Include annual parallax (Earth's barycentric position from DE421).
    anchor_minutes : float or None
        Evaluate precession–nutation (the IAU 2000A series, most of the cost) once per
        bin of this many minutes and rotate about the pole in between (< 3 mas);
        ``None`` evaluates :func:`skytorch.ephemeris.icrs_to_horizontal_matrices` at
        every time.

    Returns
    -------
    operators : torch.Tensor, float64, shape (time, 3, 8)
        ``K = [M, dt M, −M e, 0]`` with ``M`` the ICRS → (north, east, up) rotation,
        ``dt`` the Julian years since the epoch and ``e`` Earth's barycentric position
        [au].
    velocity : torch.Tensor or None, float64, shape (time, 3)
        Observer's barycentric velocity [m/s] in horizontal axes: Earth's barycentric
        velocity (DE421, as :func:`skytorch.ephemeris.earth_barycentric_velocity`) rotated
        by ``M``, plus the diurnal velocity, due east in these axes with the speed of
        :func:`skytorch.ephemeris.observer_gcrs_velocity`.
    """
    matrices = _rotation_matrices(times, lat_deg, lon_deg, elevation_m, anchor_minutes)
    dt = epoch_years(times, epoch_jyear)
    earth = load_ephemeris()["earth"].at(skyfield_time(times))
    columns = [matrices, dt[:, None, None] * matrices]
    if parallax:
        earth_au = torch.from_numpy(np.asarray(earth.position.m, np.float64).T
                                    / ASTRONOMICAL_UNIT_M)
        columns.append(-(matrices @ earth_au.unsqueeze(-1)))
    else:
        columns.append(torch.zeros(matrices.shape[0], 3, 1, dtype=torch.float64))
    columns.append(torch.zeros(matrices.shape[0], 3, 1, dtype=torch.float64))
    operators = torch.cat(columns, dim=-1)
    velocity = None
    if aberration:
        annual = torch.from_numpy(np.ascontiguousarray(
            np.asarray(earth.velocity.m_per_s, np.float64).T))
        velocity = (matrices @ annual.unsqueeze(-1)).squeeze(-1)
        # the diurnal velocity points due east with a constant speed omega * rho
        speed = torch.linalg.vector_norm(
            observer_gcrs_velocity(parse_times(times)[:1], lat_deg, lon_deg, elevation_m)[0])
        velocity[:, 1] += speed
    return operators, velocity


def horizontal_vectors(stars: torch.Tensor, operators: torch.Tensor,
                       velocity_m_s: torch.Tensor | None = None) -> torch.Tensor:
    """Apparent (north, east, up) unit vectors of all stars at all times.

    Parameters
    ----------
    stars : torch.Tensor, shape (star, 8)
        From :func:`star_vectors`; its dtype sets the computation dtype.
    operators : torch.Tensor, shape (time, 3, 8)
        From :func:`time_operators` (cast to the dtype of ``stars``).
    velocity_m_s : torch.Tensor, shape (time, 3), optional
        Observer's barycentric velocity in horizontal axes [m/s]; ``None`` skips
        aberration.

    Returns
    -------
    torch.Tensor, shape (time, star, 3)
        Unit vectors in horizontal axes (north, east, up), before refraction.

    Notes
    -----
    ``h = K s = M (u + mu dt − ϖ e)`` is the direction from the observer to the star's
    linearly moving barycentric position (in units of its distance), one batched matmul
    ``(time, 3, 8) × (8, star)``; then ``u' ∝ γ⁻¹ h + (1 + h·β/(1 + γ⁻¹)) β`` with
    ``β = v/c`` (relativistic aberration, :func:`skytorch.ephemeris.aberrate`). The
    first-order formula ``u + β − (u·β) u`` would differ by up to β² ≈ 1e-8 rad (2 mas).
    """
    horizontal = torch.matmul(stars, operators.to(stars.dtype).transpose(-1, -2))
    if velocity_m_s is None:
        return horizontal / torch.linalg.vector_norm(horizontal, dim=-1, keepdim=True)
    return aberrate(horizontal, velocity_m_s.to(stars.dtype).unsqueeze(-2))


def aberration_operators(operators: torch.Tensor, velocity_m_s: torch.Tensor) -> torch.Tensor:
    """Fold relativistic aberration into the per-time operators.

    Parameters
    ----------
    operators : torch.Tensor, shape (time, 3, 8)
        From :func:`time_operators`.
    velocity_m_s : torch.Tensor, shape (time, 3)
        Observer's barycentric velocity in the same (horizontal) axes [m/s].

    Returns
    -------
    torch.Tensor, float64, shape (time, 3, 8)
        ``A K + β e_8ᵀ`` with ``A = γ⁻¹ I + β βᵀ/(1 + γ⁻¹)``: applied to a star vector it
        gives ``γ⁻¹ h + (h·β) β/(1 + γ⁻¹) + β``, the aberrated direction of
        :func:`skytorch.ephemeris.aberrate` before its normalisation.

    Notes
    -----
    Exact for |h| = 1; proper motion and parallax make |h| − 1 ≲ 2e-6 (4″/yr over a
    century), which changes the aberration by < 1e-9 rad (0.1 mas).
    """
    matrix, beta = aberration_matrix(velocity_m_s.to(torch.float64))
    folded = matrix @ operators.to(torch.float64)
    folded[:, :, 7] += beta
    return folded


def horizontal_planes(stars_t: torch.Tensor, operators: torch.Tensor,
                      out: torch.Tensor | None = None
                      ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Fast path of :func:`horizontal_vectors`: (north, east, up) as three contiguous planes.

    Parameters
    ----------
    stars_t : torch.Tensor, shape (8, star)
        Transposed (contiguous) :func:`star_vectors`; sets the dtype.
    operators : torch.Tensor, shape (time, 3, 8)
        :func:`time_operators`, or :func:`aberration_operators` to include aberration.
    out : torch.Tensor, optional
        Contiguous (time · 3, star) buffer that receives the product (not while gradients
        are recorded).

    Returns
    -------
    north, east, up : torch.Tensor, each (time, star)
        Directions, not normalised (|v| = 1 + O(1e-4)): use them through ``atan2`` as
        :func:`skytorch.ephemeris.altaz_from_horizontal` does.

    Notes
    -----
    One GEMM ``(time·3, 8) × (8, star)``; the planes are contiguous, where elementwise
    work on the strided components of ``(time, star, 3)`` is 5–50× slower. Tests assert
    agreement with :func:`horizontal_vectors` to 1e-12.
    """
    n_time = operators.shape[0]
    planes = torch.mm(operators.to(stars_t.dtype).reshape(n_time * 3, -1), stars_t, out=out)
    planes = planes.view(n_time, 3, -1)
    return planes[:, 0], planes[:, 1], planes[:, 2]


def apparent_altaz(stars: torch.Tensor, operators: torch.Tensor,
                   velocity_m_s: torch.Tensor | None = None
                   ) -> tuple[torch.Tensor, torch.Tensor]:
    """Geometric (unrefracted) apparent altitude and azimuth [rad], each (time, star).

    Azimuth is measured from north through east in [0, 2π).
    """
    return altaz_from_horizontal(horizontal_vectors(stars, operators, velocity_m_s))
