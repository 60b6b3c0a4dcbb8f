r"""Light curve, colour and images of the Moon through a lunar eclipse.

:func:`lunar_eclipse` finds the eclipse nearest to a date
(:func:`skytorch.eclipse.lunar_eclipses`), follows the Moon from before P1 to after P4 and,
at each time, integrates over the visible lunar disc

.. math::

    F_\lambda(t) = \Big(\frac{R_M}{d}\Big)^2 \sum_k w_k\,
        L_\lambda(\mathbf{n}_k, \alpha, \chi)\,\frac{I}{I_\odot}(\mathbf{x}_k, \lambda),

with ``w_k`` the projected-area weights of :func:`skytorch.moon.disc.disc_grid`, ``L`` the
sunlit radiance of the surface (:func:`skytorch.moon.disc.disc_radiance`, Hapke reflectance
and lunar albedo colour) and ``I / I_sun`` the Earth's shadow
(:class:`~skytorch.eclipse.shadow.Shadow`) at the 3-D position ``x_k`` of each surface
point, expressed as (distance along the anti-Sun axis, offset from it). The shadow is
evaluated through a (u, v) table restricted to the Moon's distances during the eclipse
(:class:`~skytorch.eclipse.shadow_table.ShadowTable`, bilinear in ``log I``). From ``F``
follow the V and B magnitudes (Bessell passbands), B − V and the sRGB colour; the
magnitude at greatest eclipse gives a Danjon L estimate (:func:`danjon_l`, Vital's
correlation; NaN outside its range [-3.8, 4.2] mag).

References
----------
1. Schneegans, S. et al. 2025, "Physically Based Real-Time Rendering of Eclipses",
   Computer Graphics Forum, doi:10.1111/cgf.70220 (Fig. 11: eclipsed Moon images).
2. Müller, T., Engel, J., Döllner, J. 2012, "Single-Pass Rendering of Day and Night Sky
   Phenomena", Proc. VMV, doi:10.2312/PE/VMV/VMV12/055-062 (Fig. 3: eclipse stages).
3. Hernitschek, N., Schmidt, E., Vollmer, M. 2008, "Lunar eclipse photometry: absolute
   luminance measurements and modeling", Appl. Opt. 47, H62, doi:10.1364/AO.47.000H62
   (totality from −3.3 mag for bright eclipses).
4. Keen, R. A. 1983, "Volcanic aerosols and lunar eclipses", Science 222, 1011,
   doi:10.1126/science.222.4627.1011.
5. Danjon, A. 1921, "Relation entre l'éclairement de la Lune éclipsée et l'activité
   solaire", L'Astronomie 35, 261.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import torch
import xarray as xr

from skytorch._validate import check_choice, check_int, refuse_gradient
from skytorch.constants import EARTH_MEAN_RADIUS_M, MOON_RADIUS_M
from skytorch.dataset import (
    VariableSpec,
    batch_coordinates,
    build_dataset,
    coordinate,
    time_coordinate,
    to_numpy,
    variable,
)
from skytorch.eclipse.circumstances import _parse_one, _search_range, lunar_eclipses
from skytorch.eclipse.cone import ENLARGEMENTS
from skytorch.eclipse.danjon import (  # danjon_l and the constants are re-exported
    DANJON_ANCHORS,
    DANJON_RELATION,
    danjon_l,
)
from skytorch.eclipse.occlusion import sun_visible_fraction
from skytorch.eclipse.shadow import (
    Shadow,  # re-exported by the package
    _check_wavelength,
    shadow_angles,
)
from skytorch.eclipse.shadow_mixture import ShadowMixture
from skytorch.eclipse.shadow_table import ShadowTable
from skytorch.ephemeris import parse_times, sun_moon_vectors

__all__ = [
    "DANJON_ANCHORS",
    "DANJON_RELATION",
    "Shadow",
    "ShadowTable",
    "danjon_l",
    "lunar_eclipse",
    "lunar_light_curve",
    "plot_lunar_eclipse",
]

logger = logging.getLogger(__name__)

#: days around the given date in which the nearest eclipse is looked for
SEARCH_DAYS = 20
#: fraction of the P1–P4 duration added before P1 and after P4
MARGIN = 0.05
#: the farthest from greatest eclipse that a given light-curve time may be
TIMES_WITHIN = np.timedelta64(12, "h")
#: elements of the largest shadow look-up temporary (times x disc points x members x
#: wavelengths) in the light curve (~32 MB in float64)
_LOOKUP_ELEMENTS = 4_000_000

_REFERENCES = [
    "Schneegans, S., Gilg, J., Ahlers, V., Zachmann, G., Gerndt, A. 2025, Physically Based "
    "Real-Time Rendering of Eclipses, Computer Graphics Forum, doi:10.1111/cgf.70220",
    "Hernitschek, N., Schmidt, E., Vollmer, M. 2008, Lunar eclipse photometry: absolute "
    "luminance measurements and modeling, Appl. Opt. 47, H62, doi:10.1364/AO.47.000H62",
    "Keen, R. A. 1983, Volcanic aerosols and lunar eclipses, Science 222, 1011, "
    "doi:10.1126/science.222.4627.1011",
    "Vollmer, M., Gedzelman, S. D. 2008, Simulating irradiance and color of the eclipsed "
    "moon, Appl. Opt. 47, H52, doi:10.1364/AO.47.000H52",
]


def _frames(sun: torch.Tensor, moon: torch.Tensor):
    """Disc-frame axes (x west, y north, z towards the Earth) for each time (n, 3) each."""
    pole = torch.tensor([0.0, 0.0, 1.0], dtype=moon.dtype)
    towards_moon = moon / torch.linalg.norm(moon, dim=-1, keepdim=True)
    east = torch.linalg.cross(pole.expand_as(towards_moon), towards_moon, dim=-1)
    east = east / torch.linalg.norm(east, dim=-1, keepdim=True)
    west = -east
    z = -towards_moon
    north = torch.linalg.cross(z, west, dim=-1)
    return west, north, z


def nearest_eclipse(date, enlargement: str = "danjon"):
    """Circumstances of the lunar eclipse nearest to ``date`` (within ``SEARCH_DAYS``).

    Returns the one-eclipse :func:`skytorch.eclipse.lunar_eclipses` Dataset (dimension
    ``eclipse`` of length 1); raises ValueError when no eclipse is that near.
    """
    check_choice("enlargement", enlargement, ENLARGEMENTS)
    moment = _parse_one("time_or_date", date, parse_times)
    window = np.timedelta64(SEARCH_DAYS, "D")
    low, high = _search_range()
    if not low + window <= moment <= high - window:
        raise ValueError(
            f"time_or_date must be within {np.datetime_as_string(low + window, 'D')} .. "
            f"{np.datetime_as_string(high - window, 'D')} (the eclipses are searched "
            f"{SEARCH_DAYS} days around it in the ephemeris range); got "
            f"{np.datetime_as_string(moment, 's')}")
    table = lunar_eclipses(moment - window, moment + window, enlargement=enlargement)
    if table.sizes["eclipse"] == 0:
        raise ValueError(f"no lunar eclipse within {SEARCH_DAYS} days of time_or_date "
                         f"{np.datetime_as_string(moment, 's')}")
    index = int(np.argmin(np.abs(table.time.values - moment)))
    return table.isel(eclipse=[index])


def _eclipse_times(date, n_times: int, enlargement: str, times=None):
    """Return the times of a light curve and the eclipse's circumstances (one row).

    ``times`` given: those instants (UTC, within :data:`TIMES_WITHIN` of greatest
    eclipse), in the order given; otherwise ``n_times`` from :data:`MARGIN` of the P1–P4
    duration before P1 to as much after P4.
    """
    row = nearest_eclipse(date, enlargement).isel(eclipse=0)
    if times is not None:
        given = parse_times(times)
        offset = np.abs(given - row.time.values)
        if given.size == 0 or not (offset <= TIMES_WITHIN).all():
            hours = TIMES_WITHIN // np.timedelta64(1, "h")
            raise ValueError(
                f"times must be 1 or more instants within {hours} h of greatest eclipse "
                f"{np.datetime_as_string(row.time.values, 's')}; got {given.size} "
                f"instant(s), the farthest "
                f"{offset.max(initial=np.timedelta64(0, 'ns')) / np.timedelta64(1, 'h'):.2f} h")
        return given, row
    start, end = _grid_extent(row)
    span = (end - start).astype("timedelta64[ns]").astype(np.int64)
    offsets = np.linspace(0.0, span, n_times).astype(np.int64)
    times = start + offsets.astype("timedelta64[ns]")
    return times, row


def _grid_extent(row) -> tuple[np.datetime64, np.datetime64]:
    """Return the first and last instant of a light curve's default grid.

    P1 - MARGIN x (P4 - P1) and P4 + MARGIN x (P4 - P1).
    """
    p1, p4 = row.p1.values, row.p4.values
    margin = np.timedelta64(int(MARGIN * (p4 - p1).astype("timedelta64[ns]").astype(np.int64)),
                            "ns")
    return p1 - margin, p4 + margin


def _disc_images(shadow_fn, sun, moon, wavelength, n_pixels, sun_distance, ring_phase=True):
    """Spectral radiance images (*B, n, y, x, n_wavelength) of the lunar disc."""
    from skytorch.moon.disc import disc_radiance

    centres = (torch.arange(n_pixels, dtype=torch.float64) + 0.5) * (2.0 / n_pixels) - 1.0
    yy, xx = torch.meshgrid(centres, centres, indexing="ij")
    rr = xx * xx + yy * yy
    inside = (rr < 1.0).reshape(-1)
    zz = torch.sqrt((1.0 - rr).clamp_min(0.0))
    normal = torch.stack([xx, yy, zz], dim=-1).reshape(-1, 3)
    _, lit = _surface_radiance(shadow_fn, sun, moon, normal, wavelength, sun_distance,
                               disc_radiance, ring_phase)  # (n, p, *B, n_wl)
    batch = lit.shape[2:-1]
    lit = lit * inside.reshape(1, -1, *(1,) * (len(batch) + 1)).to(lit.dtype)
    lit = lit.movedim(1, -2).movedim(0, len(batch))  # (*B, n, p, n_wl)
    return lit.reshape(*batch, sun.shape[0], n_pixels, n_pixels, -1)


def _surface_radiance(shadow_fn, sun, moon, normal, wavelength, sun_distance, disc_radiance,
                      ring_phase: bool = True):
    """Uneclipsed and eclipsed spectral radiance of surface points.

    Returns ``(radiance, lit)``: the sunlit radiance (n_time, n_point, n_wavelength) and
    the radiance in the shadow (n_time, n_point, *B, n_wavelength). The direct sunlight
    (fraction ``f`` of the solar disc above the atmosphere) is reflected at the Sun's phase
    angle; the light refracted through the atmosphere ring, ``I / I_sun - f``, arrives from
    the ring around the Earth, which the (geocentric) observer sees at the ring's angular
    radius from the Moon, ``asin(R / d)``, so it is reflected at that phase angle (same
    bright-limb orientation; within a degree of the Sun's direction, the incidence angles
    barely change, but the opposition surge does).
    """
    west, north, z = _frames(sun, moon)
    axes = torch.stack([west, north, z], dim=-2)  # (n, 3, 3) rows: disc axes in GCRS
    moon_to_sun = sun - moon
    s = torch.einsum("nij,nj->ni", axes, moon_to_sun / torch.linalg.norm(
        moon_to_sun, dim=-1, keepdim=True))
    phase = torch.acos(torch.clamp(s[:, 2], -1.0, 1.0))
    limb = torch.atan2(-s[:, 0], s[:, 1])
    moon_distance = torch.linalg.norm(moon, dim=-1)
    radiance = disc_radiance(normal, phase, wavelength, limb,
                             sun_distance_m=torch.linalg.norm(moon_to_sun, dim=-1),
                             distance_m=moon_distance, earthshine=False)
    # 3-D positions of the surface points and their shadow coordinates
    points = moon[:, None, :] + MOON_RADIUS_M * torch.einsum("pk,nkj->npj", normal, axes)
    anti_sun = -sun / torch.linalg.norm(sun, dim=-1, keepdim=True)
    along = torch.einsum("npj,nj->np", points, anti_sun)
    across = points - along[..., None] * anti_sun[:, None, :]
    offset = torch.linalg.norm(across, dim=-1)
    # position angle around the axis from the projected celestial pole (GCRS z), in [0, pi]
    pole = torch.tensor([0.0, 0.0, 1.0], dtype=anti_sun.dtype) - anti_sun[:, 2:3] * anti_sun
    pole = pole / torch.linalg.norm(pole, dim=-1, keepdim=True)
    # (a point within 1 m of the axis gets cosine ~0: there every position angle is alike)
    cosine = torch.einsum("npj,nj->np", across, pole) / offset.clamp_min(1.0)
    angle = torch.acos(torch.clamp(cosine, -1.0, 1.0)).detach()
    illuminance, direct = shadow_fn(along, offset, angle)  # (n, p, *B, n_wl), (n, p)
    ring_radiance = radiance if not ring_phase else disc_radiance(
        normal, torch.asin(EARTH_MEAN_RADIUS_M / moon_distance), wavelength, limb,
        sun_distance_m=torch.linalg.norm(moon_to_sun, dim=-1), distance_m=moon_distance,
        earthshine=False)
    extra = illuminance.dim() - radiance.dim()  # batch dims of the atmosphere
    shape = (*radiance.shape[:2], *(1,) * extra, radiance.shape[-1])
    direct = direct.reshape(*direct.shape, *(1,) * (extra + 1))
    lit = (radiance.reshape(shape) * direct
           + ring_radiance.reshape(shape) * (illuminance - direct).clamp_min(0.0))
    return radiance, lit


def _display(xyz: torch.Tensor, dims: int) -> torch.Tensor:
    """Gamma-encoded sRGB with the brightest linear channel over the last ``dims`` dims at 1."""
    from skytorch.spectrum import xyz_to_linear_srgb, xyz_to_srgb

    linear = xyz_to_linear_srgb(xyz).clamp_min(0.0)
    peak = linear.flatten(-dims).max(dim=-1).values.clamp_min(torch.finfo(xyz.dtype).tiny)
    peak = peak.reshape(peak.shape + (1,) * dims)
    return xyz_to_srgb(xyz / peak, gamma=True, clip=True)


def _colour(flux: torch.Tensor, wavelength: torch.Tensor) -> torch.Tensor:
    """Return the sRGB of a spectrum at constant luminance, brightest channel 1 (..., 3)."""
    from skytorch.spectrum import spectrum_to_xyz

    return _display(spectrum_to_xyz(flux, wavelength), 1)


_SPECS = {
    "v_magnitude": VariableSpec("mag", "V magnitude of the Moon",
                                "Disc-integrated Johnson V magnitude above the atmosphere "
                                "(Bessell 1990 passband, Bessell 1998 zero point)"),
    "b_magnitude": VariableSpec("mag", "B magnitude of the Moon",
                                "Disc-integrated Johnson B magnitude above the atmosphere"),
    "b_minus_v": VariableSpec("mag", "B-V colour index of the Moon", "B - V"),
    "colour": VariableSpec("1", "sRGB colour of the Moon",
                           "Gamma-encoded sRGB of the disc-integrated spectrum at constant "
                           "luminance (brightest channel 1)"),
    "spectral_irradiance": VariableSpec(
        "W m-2 nm-1", "spectral irradiance from the Moon",
        "Spectral irradiance from the whole Moon at the Earth (above the atmosphere)"),
    "relative_brightness": VariableSpec(
        "1", "brightness relative to the uneclipsed Moon",
        "V-band flux divided by the flux the Moon would have without the shadow"),
    "shadow_axis_distance": VariableSpec(
        "m", "distance of the Moon's centre from the shadow axis",
        "Distance of the Moon's centre from the anti-Sun axis through the Earth's centre"),
    "image": VariableSpec("1", "sRGB image of the lunar disc",
                          "Gamma-encoded sRGB, common exposure per image (brightest pixel "
                          "of each image scaled to 1); x west, y north"),
    "image_v_magnitude": VariableSpec("mag", "V magnitude at the image times",
                                      "Disc-integrated V magnitude at the image times"),
    "greatest_v_magnitude": VariableSpec(
        "mag", "V magnitude at greatest eclipse",
        "Disc-integrated V magnitude at greatest eclipse (computed at that instant)"),
    "danjon_l": VariableSpec("1", "Danjon L estimate",
                             "Danjon luminosity L from the V magnitude at greatest eclipse "
                             "(Vital's correlation; NaN outside [-3.8, 4.2] mag; see the "
                             "danjon_l_relation attribute)"),
    "wavelength": VariableSpec("nm", "wavelength", "Vacuum wavelength",
                               standard_name="radiation_wavelength"),
    "channel": VariableSpec("1", "sRGB channel", "R, G, B"),
    "x": VariableSpec("1", "disc x (west)", "Disc coordinate in lunar radii, west positive"),
    "y": VariableSpec("1", "disc y (north)", "Disc coordinate in lunar radii, north positive"),
}


@dataclass(frozen=True)
class _Run:
    """What :func:`lunar_eclipse` needs of a light-curve run beyond the light curve.

    ``times`` (time,) datetime64, ``row`` the eclipse's circumstances (a one-eclipse row
    of :func:`lunar_eclipses`), ``sun`` and ``moon`` the GCRS vectors (time, 3) [m],
    ``sun_distance`` their mean distance [m], the ``shadow`` and its ``table``,
    ``wavelength`` [nm] and ``axis_distance`` (time,) [m] of the Moon's centre from the
    shadow axis, whose minimum is greatest eclipse (index ``greatest``).
    """

    times: np.ndarray
    row: xr.Dataset
    sun: torch.Tensor
    moon: torch.Tensor
    sun_distance: float
    shadow: Shadow
    table: ShadowTable
    wavelength: torch.Tensor
    axis_distance: torch.Tensor
    greatest: int


def _light_curve(time_or_date, atmosphere, n_times, wavelength_nm, n_disc, enlargement,
                 shadow, table_n_u, table_n_v, progress,
                 ring_phase, times=None) -> tuple[dict[str, torch.Tensor], _Run]:
    """Compute the light curve of :func:`lunar_light_curve` and the run behind it.

    Returns the dictionary :func:`lunar_light_curve` returns (batch dimensions ``B`` of the
    shadow's atmosphere leading) and the :class:`_Run` the Dataset and images of
    :func:`lunar_eclipse` are built from.
    """
    from skytorch.moon.disc import disc_grid, disc_radiance
    from skytorch.spectrum import spectrum_to_magnitude, wavelength_grid

    n_times = check_int("n_times", n_times, low=2)
    n_disc = check_int("n_disc", n_disc, low=2)
    table_n_u = check_int("table_n_u", table_n_u, low=2)
    table_n_v = check_int("table_n_v", table_n_v, low=2)
    for name, flag in (("progress", progress), ("ring_phase", ring_phase)):
        if not isinstance(flag, (bool, np.bool_)):
            raise TypeError(f"{name} must be True or False; got {flag!r}")
    if shadow is not None and not isinstance(shadow, (Shadow, ShadowMixture)):
        raise TypeError(f"shadow must be a skytorch.eclipse.Shadow, ShadowMixture or None; got "
                        f"{type(shadow).__name__}: {shadow!r:.60}")
    wavelength = (wavelength_grid("bands15") if wavelength_nm is None
                  else _check_wavelength(wavelength_nm, torch.float64))
    # the magnitudes integrate the bands where their responses exceed 10 % of the peak
    # (B 377-529 nm, V 486-636 nm): V needs a wavelength in its band; without two in B the
    # B magnitude and B - V are NaN (a grid of one red wavelength gave B - V 0.60 in the
    # umbra and V -5.27 at totality)
    def sampled(low, high):
        return int(((wavelength >= low) & (wavelength <= high)).sum())

    if sampled(486.0, 636.0) < 1:
        raise ValueError(f"wavelength_nm must hold a wavelength within the V band "
                         f"(486-636 nm); got {wavelength.tolist()!r:.80}")
    b_sampled = sampled(377.0, 529.0) >= 2
    times, row = _eclipse_times(time_or_date, n_times, enlargement, times)
    n_series = times.size
    # the greatest eclipse itself as one more instant, after the series: its V (and the
    # Danjon L from it) is that of greatest eclipse, not of the nearest sample
    computed = np.concatenate([times, np.array([row.time.values], dtype=times.dtype)])
    n_times = computed.size
    vectors = sun_moon_vectors(computed, frames=("gcrs",))
    sun, moon = vectors["sun_gcrs_m"], vectors["moon_gcrs_m"]
    # the mean over the series' times (the instant of greatest eclipse added for its V
    # does not move the shadow's Sun distance)
    sun_distance = float(torch.linalg.norm(sun[:n_series], dim=-1).mean())
    if shadow is None:
        shadow = Shadow.earth(atmosphere, sun_distance_m=sun_distance)
    # the table's range: the Moon's distances over the default grid's extent (the same
    # table for any times within it: the light curve at given times equals the grid's) and
    # at every computed instant
    extent = sun_moon_vectors(np.array(_grid_extent(row), dtype=computed.dtype),
                              frames=("gcrs",))
    distances = torch.linalg.norm(moon, dim=-1)
    spanned = torch.cat([distances, torch.linalg.norm(extent["moon_gcrs_m"], dim=-1)])
    sun_all = torch.cat([sun, extent["sun_gcrs_m"]])
    # the disc's points, by their distance along the anti-Sun axis: within a lunar radius
    # of the centre's distance, and up to distance x (1 - cos 1.5 deg) nearer for points
    # off the axis in the penumbra; each is looked up at its own Sun distance, which moves
    # its u as a change of its distance by the same fraction would (a shadow given for
    # 1 au against the Sun's 1.0026 au in September): ShadowTable.lookup refuses points
    # beyond the table's range
    table_sun = float(getattr(shadow, "sun_distance_m", sun_distance))
    shift = float((torch.linalg.norm(sun_all, dim=-1) - table_sun).abs().max()) / table_sun
    margin = 1.05 * MOON_RADIUS_M + (4e-4 + 1.5 * shift) * float(spanned.max())
    table = ShadowTable.compute(
        shadow, wavelength, n_u=table_n_u, n_v=table_n_v,
        min_distance_m=float(spanned.min()) - margin,
        max_distance_m=float(spanned.max()) + margin, progress=progress)
    grid = disc_grid(n_disc)
    solid = (MOON_RADIUS_M / distances) ** 2  # sr per unit disc area
    weight = grid["weight"] * solid[:, None]  # (n_time, n_point) [sr]
    batch = _members(table)
    # times in chunks: the look-up temporaries are (times, points, members, wavelengths)
    size = grid["weight"].numel() * math.prod(batch) * wavelength.numel()
    step = max(1, _LOOKUP_ELEMENTS // size)
    fluxes, fulls = [], []
    for start in range(0, n_times, step):
        part = slice(start, start + step)
        radiance, lit = _surface_radiance(
            _shadow_lookup(table, sun[part]), sun[part], moon[part], grid["normal"],
            wavelength, sun_distance, disc_radiance, ring_phase)
        members = lit.reshape(*lit.shape[:2], -1, lit.shape[-1])
        fluxes.append(torch.einsum("npbl,np->nbl", members, weight[part]))
        fulls.append(torch.einsum("npl,np->nl", radiance, weight[part]))
    flux = torch.cat(fluxes).reshape(n_times, *batch, -1)
    flux_full = torch.cat(fulls)
    anti_sun = -sun / torch.linalg.norm(sun, dim=-1, keepdim=True)
    along = (moon * anti_sun).sum(-1)
    axis_distance = torch.linalg.norm(moon - along[:, None] * anti_sun, dim=-1)
    flux = flux.movedim(0, len(batch))  # (*B, time, wavelength)
    v_mag = spectrum_to_magnitude(flux, wavelength, "V")
    b_mag = (spectrum_to_magnitude(flux, wavelength, "B") if b_sampled
             else torch.full_like(v_mag, math.nan))
    v_full = spectrum_to_magnitude(flux_full, wavelength, "V")
    series = slice(0, n_series)
    greatest = int(torch.argmin(axis_distance[series]))
    curve = {
        "v_magnitude": v_mag[..., series],
        "b_magnitude": b_mag[..., series],
        "b_minus_v": (b_mag - v_mag)[..., series],
        "relative_brightness": 10 ** (-0.4 * (v_mag - v_full))[..., series],
        "spectral_irradiance": flux[..., series, :],
        "greatest_v_magnitude": v_mag[..., n_series],
        "danjon_l": danjon_l(v_mag[..., n_series], outside="nan"),
    }
    return curve, _Run(times, row, sun[series], moon[series], sun_distance, shadow, table,
                       wavelength, axis_distance[series], greatest)


def lunar_light_curve(time_or_date, atmosphere=None, n_times: int | None = None, *,
                      times=None, wavelength_nm=None, n_disc: int = 12,
                      enlargement: str = "danjon", shadow=None, table_n_v: int = 384,
                      table_n_u: int = 3, progress: bool = False,
                      ring_phase: bool = True) -> dict[str, torch.Tensor]:
    """Light curve of the Moon through a lunar eclipse for a batch of atmospheres.

    The tensor form of :func:`lunar_eclipse` (same times, disc integration and shadow
    table, no images): for a batched atmosphere, e.g.
    ``Atmosphere.earth(turbidity=t[:, None], ozone_du=o[None, :])`` with batch shape
    ``B``, the rays are traced and the ring geometry evaluated once and only the
    transmittances differ per member. Batch dimensions lead, as
    :func:`skytorch.sweep` with ``backend="broadcast"`` expects.

    Parameters
    ----------
    time_or_date, atmosphere, wavelength_nm, n_disc, enlargement, shadow, table_n_v,
    table_n_u, progress, ring_phase
        As in :func:`lunar_eclipse`; ``atmosphere`` (or ``shadow``) may be batched.
    n_times : int, optional
        As in :func:`lunar_eclipse` (default 200); not together with ``times``.
    times : str, datetime, datetime64 or a list/array of them, optional
        UTC instants of the light curve instead of the ``n_times`` grid (e.g. those of an
        observed light curve), within 12 h of greatest eclipse, in the order given.

    Returns
    -------
    dict of Tensor
        ``v_magnitude``, ``b_magnitude``, ``b_minus_v``, ``relative_brightness``
        (*B, time) [mag], [mag], [mag], [1] (B and B − V NaN for a grid with fewer than
        two wavelengths in 377-529 nm); ``spectral_irradiance`` (*B, time, wavelength)
        [W m-2 nm-1]; ``greatest_v_magnitude`` and ``danjon_l`` (*B) at greatest eclipse
        (computed at that instant, whatever the times of the series). The times are those
        of ``lunar_eclipse(...).time``, or ``times``.

    Examples
    --------
    >>> import torch
    >>> from skytorch.atmosphere import Atmosphere
    >>> atm = Atmosphere.earth(turbidity=torch.tensor([[1.5], [3.0]], dtype=torch.float64),
    ...                        ozone_du=torch.tensor([[250.0, 350.0]], dtype=torch.float64))
    >>> curve = lunar_light_curve("2015-09-28", atm, n_times=8, table_n_v=96)
    >>> tuple(curve["v_magnitude"].shape), tuple(curve["danjon_l"].shape)
    ((2, 2, 8), (2, 2))
    >>> at = lunar_light_curve("2015-09-28", False, times=["2015-09-28T02:47",
    ...                        "2015-09-28T03:30"], table_n_v=32)
    >>> tuple(at["v_magnitude"].shape)
    (2,)
    """
    if times is not None and n_times is not None:
        raise ValueError(f"n_times and times cannot both be given; got n_times={n_times!r} "
                         "and times (the light curve is at the given times)")
    return _light_curve(time_or_date, atmosphere, 200 if n_times is None else n_times,
                        wavelength_nm, n_disc, enlargement, shadow, table_n_u, table_n_v,
                        progress, ring_phase, times)[0]


def lunar_eclipse(time_or_date, atmosphere=None, n_times: int = 200, *,
                  wavelength_nm=None, n_disc: int = 12, n_images: int = 9,
                  image_pixels: int = 48, enlargement: str = "danjon", shadow=None,
                  table_n_v: int = 384, table_n_u: int = 3,
                  progress: bool = False, ring_phase: bool = True,
                  batch_dims=None) -> xr.Dataset:
    """Brightness, colour and images of the Moon through the lunar eclipse nearest a date.

    Parameters
    ----------
    time_or_date : str, datetime or datetime64
        A date or time within 20 days of the eclipse (UTC).
    atmosphere : Atmosphere, optional
        The Earth's atmosphere (default ``Atmosphere.earth()``); ``False`` for none. It may
        be batched (e.g. ``Atmosphere.earth(turbidity=torch.tensor([1.5, 3.0]))``): its
        batch dimensions become Dataset dimensions, see ``batch_dims``.
    n_times : int
        Times from 5 % of the P1–P4 duration before P1 to as much after P4.
    wavelength_nm : Tensor (wavelength,), optional
        Wavelength grid (default: the 15 bands of ``wavelength_grid("bands15")``).
    n_disc : int
        Radial Gauss nodes on the lunar disc (``2 n_disc`` azimuths).
    n_images, image_pixels : int
        Number of disc images (evenly spaced in time) and their size.
    enlargement : {"danjon", "chauvenet", "none"}
        Convention for the circumstances (contacts, magnitudes).
    shadow : Shadow or ShadowMixture, optional
        A prepared shadow model (overrides ``atmosphere``; may be batched too), or a
        mixture of limb atmospheres along the terminator (:func:`eclipse_shadow` with
        ``terminator="latitude_bands"``).
    table_n_u, table_n_v : int
        Size of the (u, v) shadow table over the Moon's distances.
    progress : bool
        Progress bar for the shadow table.
    ring_phase : bool
        Reflect the light refracted through the atmosphere at the phase angle of the
        Earth's limb ring (``asin(R_earth / d)``, about 1°) instead of the Sun's (0.2–0.5°
        at mid-totality); the lunar opposition surge makes totality about 0.05 mag
        fainter (2015-09-28). ``False``: the Sun's phase angle for all light.
    batch_dims : sequence of str, optional
        Names of the Dataset dimensions of a batched atmosphere, one per batch dimension
        (default ``atmosphere_0``, ``atmosphere_1``, ...). Each gets an index coordinate,
        unless it is named after an atmosphere parameter that varies along it alone (e.g.
        ``"ozone_du"``), whose values then label it; every batched parameter is also
        stored as a coordinate over the dimensions it varies along.

    Returns
    -------
    xarray.Dataset
        Dims ``time``, ``wavelength``, ``channel``, ``image_time``, ``y``, ``x`` (and the
        batch dims ``B`` of a batched atmosphere, leading): ``v_magnitude``,
        ``b_magnitude``, ``b_minus_v``, ``relative_brightness`` (*B, time), ``colour``
        (*B, time, channel), ``spectral_irradiance`` (*B, time, wavelength),
        ``shadow_axis_distance`` (time), ``image`` (*B, image_time, y, x, channel),
        ``image_v_magnitude`` (*B, image_time); attributes: the circumstances,
        ``greatest_v_magnitude``, ``danjon_l`` and the shadow parameters. For a batched
        atmosphere ``greatest_v_magnitude`` and (for a total eclipse) ``danjon_l`` are
        also variables over ``B``.

    Examples
    --------
    >>> import torch
    >>> from skytorch.atmosphere import Atmosphere
    >>> atmosphere = Atmosphere.earth(turbidity=torch.tensor([1.5, 3.0], dtype=torch.float64))
    >>> ds = lunar_eclipse("2015-09-28", atmosphere, n_times=5, n_images=0, table_n_v=64,
    ...                    batch_dims=["turbidity_case"])
    >>> ds.v_magnitude.dims, ds.sizes["turbidity_case"]
    (('turbidity_case', 'time'), 2)
    """
    refuse_gradient("lunar_eclipse", atmosphere=atmosphere, wavelength_nm=wavelength_nm)
    from skytorch.spectrum import spectrum_to_xyz

    n_images = check_int("n_images", n_images, low=0)
    image_pixels = check_int("image_pixels", image_pixels, low=4)
    curve, run = _light_curve(time_or_date, atmosphere, n_times, wavelength_nm, n_disc,
                              enlargement, shadow, table_n_u, table_n_v, progress, ring_phase)
    times, row, shadow, wavelength = run.times, run.row, run.shadow, run.wavelength
    batch = _members(run.table)
    dims = _batch_dims(batch, batch_dims)
    flux, v_mag = curve["spectral_irradiance"], curve["v_magnitude"]  # (*B, time, ...)
    greatest_v = curve["greatest_v_magnitude"]
    image_index = (np.round(np.linspace(0, n_times - 1, n_images)).astype(int)
                   if n_images else np.zeros(0, dtype=int))
    total = str(row.kind.values) == "total"
    data_vars = {
        name: variable((*dims, "time"), to_numpy(curve[name]), _SPECS[name])
        for name in ("v_magnitude", "b_magnitude", "b_minus_v")
    }
    data_vars["colour"] = variable((*dims, "time", "channel"),
                                   to_numpy(_colour(flux, wavelength)), _SPECS["colour"])
    data_vars["relative_brightness"] = variable((*dims, "time"),
                                                to_numpy(curve["relative_brightness"]),
                                                _SPECS["relative_brightness"])
    data_vars["spectral_irradiance"] = variable((*dims, "time", "wavelength"), to_numpy(flux),
                                                _SPECS["spectral_irradiance"])
    data_vars["shadow_axis_distance"] = variable(("time",), to_numpy(run.axis_distance),
                                                 _SPECS["shadow_axis_distance"])
    coords = {
        "time": time_coordinate(times),
        "wavelength": coordinate("wavelength", to_numpy(wavelength), _SPECS["wavelength"]),
        "channel": coordinate("channel", np.array(["R", "G", "B"]), _SPECS["channel"]),
        **_batch_coordinates(shadow, batch, dims),
    }
    if batch:
        data_vars["greatest_v_magnitude"] = variable(dims, to_numpy(greatest_v),
                                                     _SPECS["greatest_v_magnitude"])
        if total:
            data_vars["danjon_l"] = variable(dims, to_numpy(curve["danjon_l"]),
                                             _SPECS["danjon_l"])
    if n_images:
        sun, moon = run.sun[image_index], run.moon[image_index]
        pixels = _disc_images(_shadow_lookup(run.table, sun), sun, moon, wavelength,
                              image_pixels, run.sun_distance, ring_phase)
        images = _display(spectrum_to_xyz(pixels, wavelength), 3)
        centres = (np.arange(image_pixels) + 0.5) * (2.0 / image_pixels) - 1.0
        data_vars["image"] = variable((*dims, "image_time", "y", "x", "channel"),
                                      to_numpy(images), _SPECS["image"])
        data_vars["image_v_magnitude"] = variable((*dims, "image_time"),
                                                  to_numpy(v_mag[..., image_index]),
                                                  _SPECS["image_v_magnitude"])
        coords["image_time"] = time_coordinate(times[image_index], dim="image_time")
        coords["x"] = coordinate("x", centres, _SPECS["x"])
        coords["y"] = coordinate("y", centres, _SPECS["y"])

    def when(name):
        value = row[name].values
        return "NaT" if np.isnat(value) else np.datetime_as_string(value, unit="s")

    def scalar_or_list(value: torch.Tensor):
        return float(value) if value.ndim == 0 else to_numpy(value).tolist()

    parameters = {
        "kind": str(row.kind.values), "umbral_magnitude": float(row.umbral_magnitude),
        "penumbral_magnitude": float(row.penumbral_magnitude), "gamma": float(row.gamma),
        "greatest_eclipse": when("time"), **{c: when(c) for c in ("p1", "u1", "u2", "u3",
                                                                  "u4", "p4")},
        "enlargement": enlargement, "greatest_v_magnitude": scalar_or_list(greatest_v),
        "greatest_time": np.datetime_as_string(run.row.time.values, unit="s"),
        "danjon_l": scalar_or_list(curve["danjon_l"]) if total else "none",
        "danjon_l_relation": DANJON_RELATION,
        "n_disc": n_disc, "table_n_u": table_n_u, "table_n_v": table_n_v,
        "ring_phase": str(bool(ring_phase)),
        "shadow": shadow.parameters_dict(),
    }
    return build_dataset(data_vars, coords, title="Lunar eclipse light curve",
                         references=_REFERENCES, parameters=parameters)


def _batch_dims(batch: tuple[int, ...], names) -> tuple[str, ...]:
    """Dataset dimension names of an atmosphere batch shape (validated)."""
    if names is None:
        return tuple(f"atmosphere_{k}" for k in range(len(batch)))
    names = tuple(str(name) for name in names)
    reserved = {"time", "wavelength", "channel", "image_time", "x", "y"}
    if (len(names) != len(batch) or len(set(names)) != len(names)
            or reserved.intersection(names)):
        raise ValueError(
            f"batch_dims must name each of the {len(batch)} atmosphere batch dimensions "
            f"(shape {batch}) once, avoiding {sorted(reserved)}; got {list(names)}")
    return names


def _batch_coordinates(shadow, batch: tuple[int, ...], dims: tuple[str, ...]) -> dict:
    """Coordinates of the atmosphere batch dimensions (:func:`batch_coordinates`).

    Every atmosphere parameter with a batch shape becomes a coordinate over the dimensions
    along which it varies; a dimension named after a parameter that varies along it alone
    takes that parameter's values, any other an index.
    """
    parameters = {}
    atmosphere = getattr(shadow, "atmosphere", None)
    if atmosphere is not None and hasattr(atmosphere, "parameters_dict"):
        for key, value in atmosphere.parameters_dict().items():
            if not isinstance(value, list):
                continue
            values = getattr(atmosphere, key).detach().to(torch.float64)
            values = values.reshape((1,) * (len(batch) - values.ndim) + tuple(values.shape))
            along = tuple(k for k, size in enumerate(values.shape) if size > 1)
            if along:
                index = tuple(slice(None) if k in along else 0 for k in range(len(batch)))
                parameters[key] = (tuple(dims[k] for k in along), values[index])
    return batch_coordinates(
        dict(zip(dims, batch, strict=True)), parameters, long_name="{label}",
        description="Atmosphere parameter {name} of the batch members",
        index_long_name="atmosphere batch index",
        index_description="Index of the atmosphere along batch dimension {axis}")


def _shadow_lookup(table, sun):
    """Shadow look-up ``(along, offset, angle) -> (I / I_sun (n, p, *B, n_wl), direct (n, p))``.

    ``direct`` is the fraction of the limb-darkened solar disc seen above the atmosphere
    (:func:`sun_visible_fraction` with the top of the atmosphere as occluder), for Sun
    vectors (n, 3). ``angle`` (n, p), the points' position angles around the axis [rad],
    is used by a table resolved in direction (linear in angle between its columns) and
    ignored otherwise.
    """
    distance = torch.linalg.norm(sun, dim=-1)

    def function(along, offset, angle):
        sun_distance = distance[:, None].expand_as(along)
        angles = shadow_angles(along, offset, sun_distance, table.sun_radius_m,
                               table.occluder_radius_m)
        direct = sun_visible_fraction(angles["sun_radius_rad"], angles["occluder_radius_rad"],
                                      angles["separation_rad"],
                                      table.attrs.get("limb_darkening", 0.6),
                                      table.attrs.get("limb_darkening_law", "linear"))
        values = table.lookup(along, offset, sun_distance_m=sun_distance)
        if table.position_angle_rad is None:
            return values, direct
        grid = table.position_angle_rad
        x = torch.clamp(angle, 0.0, math.pi) / math.pi * (grid.shape[0] - 1)
        i = torch.clamp(torch.floor(x), 0, grid.shape[0] - 2).long()
        fraction = (x - i.to(x.dtype)).unsqueeze(-1)
        pick = i[..., None, None].expand(*i.shape, 1, values.shape[-1])
        low = values.gather(-2, pick).squeeze(-2)
        high = values.gather(-2, pick + 1).squeeze(-2)
        return low + fraction * (high - low), direct

    return function


def _members(table) -> tuple[int, ...]:
    """Batch shape of the table's atmospheres (none for a table resolved in direction)."""
    return () if table.position_angle_rad is not None else tuple(table.batch_shape)


def plot_lunar_eclipse(dataset: xr.Dataset, path=None):
    """Figure: strip of disc images above the V light curve and B − V.

    Parameters
    ----------
    dataset : xarray.Dataset
        Output of :func:`lunar_eclipse`.
    path : str or Path, optional
        PNG file to write.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    extra = [dim for dim in dataset.v_magnitude.dims if dim != "time"]
    if extra:
        raise ValueError(f"plot_lunar_eclipse shows one atmosphere; select a member of the "
                         f"batch dimensions {extra}, e.g. dataset.isel({extra[0]}=0)")
    n_images = dataset.sizes.get("image_time", 0)
    figure = plt.figure(figsize=(max(8.0, 1.2 * n_images), 6.5))
    grid = figure.add_gridspec(2, max(n_images, 1), height_ratios=(1, 2.2))
    for index in range(n_images):
        axis = figure.add_subplot(grid[0, index])
        axis.imshow(dataset["image"].isel(image_time=index).values, origin="lower")
        axis.set_axis_off()
        stamp = np.datetime_as_string(dataset.image_time.values[index], unit="m")[11:]
        axis.set_title(f"{stamp}\nV {float(dataset.image_v_magnitude[index]):.1f}",
                       fontsize=8)
    axis = figure.add_subplot(grid[1, :])
    hours = (dataset.time.values - dataset.time.values[0]) / np.timedelta64(1, "h")
    axis.plot(hours, dataset.v_magnitude.values, color="k", label="V")
    axis.plot(hours, dataset.b_magnitude.values, color="tab:blue", label="B")
    axis.invert_yaxis()
    axis.set_xlabel(f"hours since {np.datetime_as_string(dataset.time.values[0], unit='m')}"
                    " UTC")
    axis.set_ylabel("magnitude")
    axis.legend(loc="upper right")
    axis.grid(alpha=0.3)
    attrs = dataset.attrs
    # a member selected from a batched Dataset carries its values as variables
    greatest = (dataset["greatest_v_magnitude"] if "greatest_v_magnitude" in dataset
                else attrs.get("parameter_greatest_v_magnitude", math.nan))
    title = (f"lunar eclipse {attrs.get('parameter_greatest_eclipse', '')}: greatest V "
             f"{float(greatest):.2f}")
    if "danjon_l" in dataset:
        title += f", Danjon L ≈ {float(dataset['danjon_l']):.1f} ± 0.4"
    elif attrs.get("parameter_danjon_l", "none") != "none":
        title += f", Danjon L ≈ {float(attrs['parameter_danjon_l']):.1f} ± 0.4"
    axis.set_title(title, fontsize=10)
    figure.tight_layout()
    if path is not None:
        figure.savefig(path, dpi=110)
    return figure
