r"""The sky during a solar eclipse: sunlight dimmed by the Moon at every scattering point.

The Moon's shadow is a three-dimensional cone: the umbra is 100–250 km across at the
ground and the penumbra some 7000 km, so the fraction of the Sun that a parcel of air
sees depends on where the parcel is. The sky radiance is therefore computed with the
Sun's visible fraction evaluated at each scattering point of each view ray
(:func:`visible_fraction_at`, :func:`eclipsed_single_scattering`); at totality the
air above the observer is dark and the light comes from the sunlit air outside the
umbra, which makes the 360° horizon glow of an eclipse sky without any special case.

* :func:`visible_fraction_at` — the limb-darkened visible fraction of the Sun
  (:func:`skytorch.eclipse.sun_visible_fraction`) seen from points near the observer,
  with the Sun and the Moon placed topocentrically for each point (the apparent vectors
  of :class:`skytorch.scene.geometry.Geometry` less the point's offset).
* :func:`eclipsed_single_scattering` — the single-scattering integral of
  :func:`skytorch.atmosphere.scattering.single_scattering_radiance` with its source term
  multiplied by that fraction at each sample.
* :func:`penumbra_touches` — the planner's geometric bound: whether the Moon's penumbra
  can reach any air the observer sees (never says no when it does).
* :func:`baumbach_corona` — the white-light corona (K + F) by Baumbach's (1937) law.

Notes
-----
Single scattering at a point :math:`\mathbf p(s)` of the view ray:

.. math::

    L = E_\odot \int_0^{L} f_\odot(\mathbf p(s)) \sum_i \beta_i(h)\,P_i(\cos\theta)\,
        T(0 \to s)\,T_\odot(s)\,ds,

:math:`f_\odot(\mathbf p)` the fraction of the limb-darkened solar flux not blocked by
the Moon as seen from :math:`\mathbf p` (linear limb darkening, :math:`u = 0.6`). The
direction of the Sun is taken as the observer's for every point (the parallax of the Sun
over 1000 km is 1.4 arcsec) while the Moon's direction and angular radius change with
the point (its parallax over 100 km is 0.9 arcmin, a quarter of the umbra's width).
The Sun's transmittance from each point is the scene's transmittance table.

The second order (:func:`eclipsed_second_order`) applies the same fraction at every
first scattering of :func:`skytorch.atmosphere.scattering.second_order_radiance`: at
totality it is most of the sky (light scattered once in the sunlit air outside the umbra
and again in the dark air the observer looks through; ``docs/solar_eclipse_sky.md``).
Orders beyond the second: :mod:`skytorch.scene.eclipse_higher_orders`.

References
----------
1. Baumbach, S. 1937, Astron. Nachr. 263, 121, doi:10.1002/asna.19372630602.
2. Allen, C. W. 1973, Astrophysical Quantities, 3rd ed., Athlone Press, §81.
3. Shaw, G. E. 1975, Appl. Opt. 14, 388, doi:10.1364/AO.14.000388 (sky brightness and
   polarisation during the 1973 African eclipse).
4. Koepke, P. et al. 2001, Atmos. Chem. Phys. 1, 49, doi:10.5194/acp-1-49-2001
   (modelling solar radiation during a total eclipse, 1999-08-11).
"""

from __future__ import annotations

import math

import torch

from skytorch._validate import as_tensor, check_int
from skytorch.atmosphere.scattering import constituent_radiance, second_order_radiance
from skytorch.constants import MOON_RADIUS_M, SUN_RADIUS_M

__all__ = ["BAUMBACH_COEFFICIENTS", "CORONA_FLUX_FRACTION", "baumbach_corona",
           "eclipsed_second_order", "eclipsed_single_scattering", "penumbra_touches",
           "sight_radius_m", "sun_direction", "visible_fraction_at"]

#: Baumbach (1937) white-light corona: :math:`I/\bar I_\odot = 10^{-6}\sum a_k\rho^{-n_k}`
#: as (a_k, n_k), ρ in solar radii from the Sun's centre (Allen 1973, §81)
BAUMBACH_COEFFICIENTS = ((0.0532, 2.5), (1.425, 7.0), (2.565, 17.0))
#: flux of that corona outside the limb relative to the Sun's:
#: :math:`2\times10^{-6}\sum a_k/(n_k - 2)` (level 1)
CORONA_FLUX_FRACTION = 2e-6 * sum(a / (n - 2.0) for a, n in BAUMBACH_COEFFICIENTS)


def visible_fraction_at(geometry, points_m, *, limb_darkening: float = 0.6,
                        n_nodes: int = 8) -> torch.Tensor:
    r"""Fraction of the Sun's limb-darkened flux not hidden by the Moon, seen from points.

    Parameters
    ----------
    geometry : skytorch.scene.geometry.Geometry
        Sun and Moon at the observer (vectors in the horizontal frame [m]).
    points_m : Tensor (..., 3)
        Points relative to the observer in the horizontal frame (north, east, up) [m].
    limb_darkening : float
        Linear limb-darkening coefficient of the Sun (0.6 in the visible).
    n_nodes : int
        Quadrature nodes of :func:`skytorch.eclipse.sun_visible_fraction`.

    Returns
    -------
    Tensor (...)
        In [0, 1]; 1 outside the penumbra, 0 in the umbra.

    Notes
    -----
    From a point :math:`\mathbf p` the Sun is at :math:`\mathbf S - \mathbf p` and the
    Moon at :math:`\mathbf M - \mathbf p` (topocentric for that point); their angular radii
    are :math:`\arcsin(R/d)` and their separation the angle between the two vectors
    (:math:`\operatorname{atan2}(|a\times b|, a\cdot b)`, accurate at small angles).

    Examples
    --------
    >>> import torch
    >>> from skytorch.scene.geometry import Geometry
    >>> g = Geometry(90.0, 0.0, 90.0, 0.0, 3.6e8, 1.496e11, math.pi, 0.0, 0.0, 0.0, 0.0,
    ...              sun_horizontal_m=(0.0, 0.0, 1.496e11),
    ...              moon_horizontal_m=(0.0, 0.0, 3.6e8))
    >>> points = torch.tensor([[0.0, 0.0, 1e4], [0.0, 5e6, 1e4]], dtype=torch.float64)
    >>> [round(v, 3) for v in visible_fraction_at(g, points).tolist()]
    [0.0, 1.0]
    """
    from skytorch.eclipse import sun_visible_fraction

    points = as_tensor("points_m", points_m)
    if points.shape[-1:] != (3,):
        raise ValueError(f"points_m must have a last dimension of 3; got shape "
                         f"{tuple(points.shape)}")
    sun = torch.tensor(geometry.sun_horizontal_m, dtype=points.dtype) - points
    moon = torch.tensor(geometry.moon_horizontal_m, dtype=points.dtype) - points
    sun_distance = torch.linalg.vector_norm(sun, dim=-1)
    moon_distance = torch.linalg.vector_norm(moon, dim=-1)
    separation = torch.atan2(torch.linalg.vector_norm(torch.linalg.cross(sun, moon), dim=-1),
                             (sun * moon).sum(-1))
    return sun_visible_fraction(torch.asin(SUN_RADIUS_M / sun_distance),
                                torch.asin(MOON_RADIUS_M / moon_distance), separation,
                                limb_darkening, n_nodes=n_nodes)


def sight_radius_m(planet_radius_m: float, top_altitude_m: float,
                   elevation_m: float) -> float:
    r"""Largest distance from the observer to air it can see [m].

    A ray grazing the ground and leaving at the top of the atmosphere:
    :math:`\sqrt{r_o^2 - R^2} + \sqrt{r_t^2 - R^2}`; every visible point of the
    atmosphere lies within this distance.
    """
    r_obs = planet_radius_m + max(float(elevation_m), 0.0)
    r_top = planet_radius_m + top_altitude_m
    return (math.sqrt(max(r_obs * r_obs - planet_radius_m ** 2, 0.0))
            + math.sqrt(r_top * r_top - planet_radius_m ** 2))


def penumbra_touches(geometry, radius_m: float) -> tuple[bool, float]:
    r"""Whether the Moon's penumbra can reach a ball of ``radius_m`` about the observer.

    Parameters
    ----------
    geometry : skytorch.scene.geometry.Geometry
        Sun and Moon at the observer.
    radius_m : float
        Radius of the ball [m] (:func:`sight_radius_m`: all the air the observer sees).

    Returns
    -------
    touches : bool
        False only when no point of the ball is in the penumbra (a bound, never wrong).
    clearance_m : float
        Distance by which the ball misses the penumbra (negative when it may touch) [m].

    Notes
    -----
    Cone frame: the axis from the Sun's centre through the Moon's; a point at distance
    :math:`x` beyond the Moon along the axis and :math:`q` from it is in the penumbra
    when :math:`q < R_☾ + x\tan f`, :math:`\sin f = (R_\odot + R_☾)/d_{\odot☾}`
    (the exterior tangents of the two spheres, to first order in the Moon's radius).
    A ball of radius :math:`D` centred at :math:`(x_0, q_0)` holds points with
    :math:`x \le x_0 + D` and :math:`q \ge q_0 - D`, so it misses the penumbra when
    :math:`q_0 - D \ge R_☾/\cos f + (x_0 + D)\tan f` (the :math:`1/\cos f` covers the
    tangent point's offset from the Moon's centre).
    """
    sun = torch.tensor(geometry.sun_horizontal_m, dtype=torch.float64)
    moon = torch.tensor(geometry.moon_horizontal_m, dtype=torch.float64)
    axis = moon - sun
    sun_moon = float(torch.linalg.vector_norm(axis))
    axis = axis / sun_moon
    x0 = float(-moon @ axis)  # observer (origin) beyond the Moon along the axis
    q0 = float(torch.linalg.vector_norm(-moon - x0 * axis))
    sin_f = (SUN_RADIUS_M + MOON_RADIUS_M) / sun_moon
    tan_f = sin_f / math.sqrt(1.0 - sin_f * sin_f)
    cos_f = math.sqrt(1.0 - sin_f * sin_f)
    if x0 + radius_m < 0.0:  # the whole ball between the Sun and the Moon's far side
        reach = MOON_RADIUS_M / cos_f
    else:
        reach = MOON_RADIUS_M / cos_f + (x0 + radius_m) * tan_f
    clearance = (q0 - radius_m) - reach
    return clearance < 0.0, clearance


def baumbach_corona(rho, level: float = 1.0) -> torch.Tensor:
    r"""White-light (K + F) coronal radiance relative to the mean radiance of the solar disc.

    Parameters
    ----------
    rho : Tensor (...)
        Distance from the Sun's centre in solar radii, >= 1.
    level : float
        Multiplier of Baumbach's law (> 0): 1 for the corona Baumbach fitted (the
        eclipses of 1905–1929, an average over the cycle); about 0.6 at solar minimum
        and 1.5 at maximum in the inner corona (Allen 1973, §81).

    Returns
    -------
    Tensor (...)
        :math:`I(\rho)/\bar I_\odot` [1].

    Notes
    -----
    .. math:: \frac{I(\rho)}{\bar I_\odot} = 10^{-6}\left(\frac{0.0532}{\rho^{2.5}}
              + \frac{1.425}{\rho^{7}} + \frac{2.565}{\rho^{17}}\right)

    (Baumbach 1937; Allen 1973, §81), :math:`\bar I_\odot` the mean radiance of the solar
    disc. Integrated over the sky outside the limb it gives
    :math:`2\times10^{-6}(0.0532/0.5 + 1.425/5 + 2.565/15) = 1.12\times10^{-6}` of the
    Sun's flux, about half the full Moon (the full Moon is 2.2e-6 of the Sun).
    The spectrum of the K and F coronae is the solar spectrum (Thomson and dust
    scattering of photospheric light).

    Examples
    --------
    >>> import torch
    >>> round(float(baumbach_corona(torch.tensor(1.0))) * 1e6, 4)
    4.0432
    """
    rho = as_tensor("rho", rho)
    if bool((rho < 1.0).any()):
        raise ValueError(f"rho must be >= 1 solar radius; got {float(rho.min())}")
    if not level > 0.0:
        raise ValueError(f"level must be > 0; got {level}")
    total = sum(a * rho ** (-n) for a, n in BAUMBACH_COEFFICIENTS)
    return 1e-6 * level * total


def sun_direction(geometry, dtype=torch.float64) -> tuple[torch.Tensor, torch.Tensor]:
    """Return the zenith angle and azimuth [rad] of the Sun's vector of ``geometry``.

    From ``geometry.sun_horizontal_m`` (north, east, up), as 0-d tensors of ``dtype``;
    the azimuth from north through east.
    """
    north, east, up = geometry.sun_horizontal_m
    return (torch.tensor(math.atan2(math.hypot(north, east), up), dtype=dtype),
            torch.tensor(math.atan2(east, north), dtype=dtype))


def eclipsed_single_scattering(atmosphere, wavelength_nm, view_zenith_rad, view_azimuth_rad,
                               geometry, altitude_m: float = 0.0, *, n_samples: int = 64,
                               table=None, n_nodes: int = 8) -> torch.Tensor:
    r"""Single-scattering sky radiance per unit solar irradiance during a solar eclipse [1/sr].

    Parameters
    ----------
    atmosphere : Atmosphere
        The atmosphere (scalar parameters).
    wavelength_nm : Tensor (wavelength,)
        [nm].
    view_zenith_rad, view_azimuth_rad : Tensor (...)
        Lines of sight [rad], azimuth from north through east (absolute: the eclipse sky
        has no symmetry about the Sun's vertical).
    geometry : skytorch.scene.geometry.Geometry
        Sun and Moon at the observer; the Sun's direction is ``sun_horizontal_m``.
    altitude_m : float
        Observer's height [m].
    n_samples : int
        Samples along each view ray (quadratically spaced from the observer), >= 2.
    table : TransmittanceTable, optional
        The Sun's transmittance from each sample (integrated when not given).
    n_nodes : int
        Quadrature nodes of the visible fraction.

    Returns
    -------
    Tensor (..., wavelength)
        :math:`L/E_\odot` [sr^-1]; multiply by the extraterrestrial irradiance.

    Notes
    -----
    The kernel of :func:`skytorch.atmosphere.scattering.constituent_radiance` (same
    sampling, trapezoid rule and transmittances), with the source term at each sample
    multiplied by :func:`visible_fraction_at` there. Far from the Moon's shadow the
    fraction is 1 and the two agree to rounding (tested).
    """
    n_samples = check_int("n_samples", n_samples, 2)
    constituents, view_zenith, view_azimuth, sun_zenith, sun_azimuth, visible = \
        _eclipse_inputs(atmosphere, wavelength_nm, view_zenith_rad, view_azimuth_rad,
                        geometry, n_nodes)
    altitude = torch.full(torch.broadcast_shapes(view_zenith.shape, view_azimuth.shape),
                          float(altitude_m), dtype=constituents.dtype)
    return constituent_radiance(constituents, view_zenith, view_azimuth, sun_zenith,
                                sun_azimuth, altitude, n_samples=n_samples, table=table,
                                source_weight=visible)


def _eclipse_inputs(atmosphere, wavelength_nm, view_zenith_rad, view_azimuth_rad, geometry,
                    n_nodes: int):
    """Constituents, view and Sun directions (their dtype) and the visible-fraction weight.

    Shared by :func:`eclipsed_single_scattering` and :func:`eclipsed_second_order`: the
    weight takes points (..., 3) from the observer and returns :func:`visible_fraction_at`.
    """
    wavelength = as_tensor("wavelength_nm", wavelength_nm).to(torch.float64)
    view_zenith = as_tensor("view_zenith_rad", view_zenith_rad).to(torch.float64)
    view_azimuth = as_tensor("view_azimuth_rad", view_azimuth_rad).to(torch.float64)
    constituents = atmosphere.constituents(wavelength)
    dtype = constituents.dtype
    sun_zenith, sun_azimuth = sun_direction(geometry, dtype)

    def visible(points):
        return visible_fraction_at(geometry, points, n_nodes=n_nodes)

    return (constituents, view_zenith.to(dtype), view_azimuth.to(dtype), sun_zenith,
            sun_azimuth, visible)


def eclipsed_second_order(atmosphere, wavelength_nm, view_zenith_rad, view_azimuth_rad,
                          geometry, altitude_m: float = 0.0, *, n_view: int = 24,
                          n_mu: int = 4, n_phi: int = 16, n_samples: int = 16, table=None,
                          n_nodes: int = 8) -> torch.Tensor:
    r"""Second order of scattering per unit solar irradiance during a solar eclipse [1/sr].

    Parameters
    ----------
    atmosphere, wavelength_nm, view_zenith_rad, view_azimuth_rad, geometry, altitude_m
        As :func:`eclipsed_single_scattering`.
    n_view, n_mu, n_phi, n_samples : int
        Quadrature of :func:`skytorch.atmosphere.scattering.second_order_radiance`.
    table : TransmittanceTable, optional
        The Sun's transmittance from each first scattering.
    n_nodes : int
        Quadrature nodes of the visible fraction.

    Returns
    -------
    Tensor (..., wavelength)
        :math:`L_2/E_\odot` [sr^-1].

    Notes
    -----
    :func:`~skytorch.atmosphere.scattering.second_order_radiance` with the Sun's visible
    fraction (:func:`visible_fraction_at`) at every first scattering: at totality the air
    around the observer is dark, and light scattered once in the sunlit air outside the
    umbra is scattered again towards the observer. Orders beyond the second:
    :func:`skytorch.scene.eclipse_higher_orders.eclipsed_higher_orders`. Without the Moon
    nearby the result is the atmosphere's second order (checked against a Monte-Carlo in
    ``tests/test_second_order.py``).
    """
    constituents, view_zenith, view_azimuth, sun_zenith, sun_azimuth, visible = \
        _eclipse_inputs(atmosphere, wavelength_nm, view_zenith_rad, view_azimuth_rad,
                        geometry, n_nodes)
    altitude = torch.tensor(float(altitude_m), dtype=constituents.dtype)
    return second_order_radiance(constituents, view_zenith, view_azimuth, sun_zenith,
                                 sun_azimuth, altitude, n_view=n_view, n_mu=n_mu,
                                 n_phi=n_phi, n_samples=n_samples, table=table,
                                 source_weight=visible)
