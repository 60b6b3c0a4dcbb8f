r"""The last scattering into the line of sight gathered from the tables' radiance field.

The tables of :mod:`skytorch.atmosphere.multiple_scattering` store each order over a
fixed grid of (r, mu, mu_s, phi); their order 1 keeps the phase function out of the grid
and applies it exactly at look-up, and the orders >= 2 of a forward-peaked aerosol, whose
peak around the Sun moves across the grid's nodes, are interpolated with the shape of
that peak factored out (``forward_peak="factored"``); what is left of the look-up's
error is a few % at an aerosol optical depth of 1 (docs/multiple_scattering_validation.md).

:func:`higher_orders_gathered` does the last scattering along the observer's own line of
sight instead of looking it up (a *final gather*, as in the source-function integration
of discrete-ordinate codes):

.. math::

    L_{2..N}(\mathbf x, \hat v) = \int_0^{L} T(\mathbf x \to \mathbf p)
        \sum_i \beta_i(\mathbf p) \int_{4\pi} P_i(\hat\omega\cdot\hat v)\,
        L_{1..N-1}(\mathbf p, \hat\omega)\,d\Omega\,ds
        \;+\; T(\mathbf x \to \mathbf g)\,\frac{\alpha}{\pi}\,E_{1..N-1}(\mathbf g),

where :math:`L_{1..N-1}` is the tables' radiance (order 1 with its exact phase, orders
>= 2 interpolated) arriving at each sample :math:`\mathbf p` of the line of sight, the
inner integral a product quadrature over the sphere with each species' exact phase, and
the last term, for lines of sight that end on a Lambertian ground :math:`\mathbf g`, the
ground's reflection of the tables' diffuse irradiance there. The tables' interpolation
error then enters one scattering earlier, where the phase integral averages it: against
DISORT (plane-parallel limit, aerosol optical depth 0.05, 0.3 and 1, Sun at 30 / 60 deg),
the sky seen from the ground is within 0.77 / 0.88 %, 0.44 / 0.48 % and 1.3 / 2.4 % on
the default tables, against 0.94 / 0.97 %, 0.68 / 1.09 % and 1.7 / 2.3 % for the tables
alone (on the former default tables, 16 x 64 x 24 x 8 with 48 samples per ray: 1.0 / 0.9,
0.8 / 0.9 and 1.9 / 3.2 % gathered, 1.6 / 1.3, 1.9 / 2.3 and 4.5 / 5.0 % alone; 17.9 % and
43.5 % at 0.3 and 1 before the forward peak was factored out of them; docs/accuracy.md,
"The final gather", and docs/multiple_scattering_validation.md, "Default tables of
2026-12-05").

Approximations: the tables' radiance where the Sun is more than 18 deg below the local
horizon (outside the tables, :data:`~skytorch.atmosphere.multiple_scattering.MU_S_MIN`)
is taken as zero; straight rays; scalar radiative transfer.

Cost: ``n_view * 2 * n_mu * n_phi`` table look-ups per line of sight (65 536 at the
defaults: 20-45 ms per line of sight on 2 cores with 2-3 wavelengths, 650-900 times a
look-up of the tables; ``benchmarks/bench_final_gather.py``): for validation, irradiances
and a few directions, not for every pixel of an image.

Also against sasktran2 in spherical geometry (coarse tables, Sun 30 and 60 deg): the day
sky within 1.9 %, against 8.5 % for the tables alone.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere import Atmosphere
>>> from skytorch.atmosphere.final_gather import higher_orders_gathered
>>> from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
>>> atm = Atmosphere.earth(turbidity=2.0)
>>> tables = precompute_scattering(atm, torch.tensor([550.0]), scattering_orders=3,
...                                resolution=TableResolution.tiny())
>>> zenith = torch.tensor(0.0, dtype=torch.float64)
>>> sun = torch.tensor(1.0, dtype=torch.float64)
>>> higher = higher_orders_gathered(tables, atm, zenith, zenith, zenith, sun, n_view=8,
...                                 n_mu=4, n_phi=8)
>>> higher.shape, bool((higher > 0).all())
(torch.Size([1]), True)
"""

from __future__ import annotations

import math

import torch

from skytorch._validate import check_int, check_range
from skytorch.atmosphere.multiple_scattering import MU_S_MIN, ScatteringTables
from skytorch.atmosphere.scattering import gather_on_line_of_sight

__all__ = ["LINES_PER_CALL", "higher_orders_gathered"]

#: the tables' largest Sun zenith angle [rad] (the Sun 18 deg below the horizon)
_SUN_ZENITH_MAX = math.acos(MU_S_MIN)
#: lines of sight gathered per pass: one line is 65 536 table look-ups at the default
#: quadrature, already past the caches (3 wavelengths: 33 ms per line one at a time, 40 ms
#: four at a time, 89 ms sixty-four at a time)
LINES_PER_CALL = 1


def higher_orders_gathered(tables, atmosphere, altitude_m, view_zenith_rad,
                           view_azimuth_rad, sun_zenith_rad, sun_azimuth_rad=0.0, *,
                           scattering_orders="converged", n_view: int = 32, n_mu: int = 16,
                           n_phi: int = 64) -> torch.Tensor:
    """Orders 2..N of the radiance, the last scattering gathered (..., wavelength) [sr^-1].

    Per unit extraterrestrial solar irradiance normal to the beam; add order 1 (the
    tables' ``radiance(..., scattering_orders=1)`` or a ray-marched single scattering)
    for the sky.

    Parameters
    ----------
    tables : ScatteringTables
        Built for ``atmosphere`` (scalar parameters: no batch) at the wavelengths of the
        result, with at least N - 1 orders.
    atmosphere : Atmosphere
        The atmosphere of the tables.
    altitude_m : Tensor (...)
        Observer altitude [m], from the ground to the top of the atmosphere.
    view_zenith_rad, view_azimuth_rad : Tensor (...)
        Direction of the line of sight [rad] (zenith in [0, pi], azimuth from north
        through east).
    sun_zenith_rad, sun_azimuth_rad : Tensor (...)
        Direction of the Sun [rad]; zenith in [0, pi] (the field is zero at the samples
        where the Sun is more than 18 deg below the local horizon).
    scattering_orders : int or "converged"
        N >= 2: the tables' orders 1..N-1 are gathered ("converged": every order of the
        tables).
    n_view : int
        Samples along the line of sight, >= 2.
    n_mu, n_phi : int
        Gauss-Legendre nodes per hemisphere and azimuths of the sphere of directions at
        each sample, >= 1.

    Returns
    -------
    Tensor (..., wavelength)
    """
    if not isinstance(tables, ScatteringTables):
        raise TypeError(f"tables must be a ScatteringTables; got {type(tables).__name__}")
    if len(tables.batch_shape):
        raise ValueError("higher_orders_gathered takes tables of an atmosphere with scalar "
                         f"parameters; got batch shape {tuple(tables.batch_shape)}")
    tables.check_built_for(atmosphere)
    if scattering_orders == "converged":
        incoming_orders = "converged"
    else:
        n = check_int("scattering_orders", scattering_orders, 2, tables.orders_computed + 1)
        incoming_orders = n - 1
    n_view = check_int("n_view", n_view, 2)
    n_mu = check_int("n_mu", n_mu, 1)
    n_phi = check_int("n_phi", n_phi, 1)
    dtype = tables.wavelength_nm.dtype
    altitude = check_range("altitude_m", altitude_m, 0.0, tables.top_altitude_m, unit=" m",
                           dtype=dtype)
    view_zenith = check_range("view_zenith_rad", view_zenith_rad, 0.0, math.pi, dtype=dtype)
    view_azimuth = check_range("view_azimuth_rad", view_azimuth_rad, dtype=dtype)
    # any Sun: the samples of the line of sight look the tables up where their own Sun is
    # within the tables' 108 deg (the eclipse shadow's points lie far beyond it)
    sun_zenith = check_range("sun_zenith_rad", sun_zenith_rad, 0.0, math.pi, dtype=dtype)
    sun_azimuth = check_range("sun_azimuth_rad", sun_azimuth_rad, dtype=dtype)
    constituents = atmosphere.constituents(tables.wavelength_nm)
    if len(constituents.batch_shape):
        raise ValueError("higher_orders_gathered takes an atmosphere with scalar parameters; "
                         f"got batch shape {tuple(constituents.batch_shape)}")

    def incoming(zenith, azimuth, sun_zenith_local, sun_azimuth_local, height, _to_observer):
        inside = sun_zenith_local <= _SUN_ZENITH_MAX
        sun_inside = torch.where(inside, sun_zenith_local, torch.zeros_like(sun_zenith_local))
        field = tables.radiance(height, zenith, azimuth, sun_inside, sun_azimuth_local,
                                scattering_orders=incoming_orders)
        return torch.where(inside[..., None], field, torch.zeros_like(field))

    try:
        shape = torch.broadcast_shapes(altitude.shape, view_zenith.shape, view_azimuth.shape,
                                       sun_zenith.shape, sun_azimuth.shape)
    except RuntimeError:
        raise ValueError(
            f"shapes do not broadcast: altitude_m {tuple(altitude.shape)}, view_zenith_rad "
            f"{tuple(view_zenith.shape)}, view_azimuth_rad {tuple(view_azimuth.shape)}, "
            f"sun_zenith_rad {tuple(sun_zenith.shape)}, sun_azimuth_rad "
            f"{tuple(sun_azimuth.shape)}") from None
    flat = [t.expand(shape).reshape(-1) for t in (altitude, view_zenith, view_azimuth,
                                                  sun_zenith, sun_azimuth)]
    parts = [_gathered_lines(tables, constituents, incoming, incoming_orders,
                             *(t[first:first + LINES_PER_CALL] for t in flat),
                             n_view=n_view, n_mu=n_mu, n_phi=n_phi)
             for first in range(0, flat[0].shape[0], LINES_PER_CALL)]
    return torch.cat(parts).reshape(*shape, -1)


def _gathered_lines(tables, constituents, incoming, incoming_orders, altitude, view_zenith,
                    view_azimuth, sun_zenith, sun_azimuth, *, n_view, n_mu, n_phi):
    """Gather flat lines of sight (n,) for :func:`higher_orders_gathered` -> (n, wavelength)."""
    line = gather_on_line_of_sight(constituents, view_zenith, view_azimuth, sun_zenith,
                                   sun_azimuth, altitude, incoming, n_view=n_view,
                                   n_mu=n_mu, n_phi=n_phi)
    radiance = line.radiance
    albedo = tables.ground_albedo
    if bool(line.ends_on_ground.any()) and bool((albedo != 0).any()):
        end_sun = line.end_sun_zenith
        inside = line.ends_on_ground & (end_sun <= _SUN_ZENITH_MAX)
        ground = torch.zeros_like(altitude)
        irradiance = tables.diffuse_irradiance(
            ground, torch.where(inside, end_sun, torch.zeros_like(end_sun)),
            scattering_orders=incoming_orders)
        reflected = line.transmittance * albedo / math.pi * irradiance
        radiance = radiance + torch.where(inside[..., None], reflected,
                                          torch.zeros_like(reflected))
    return radiance
