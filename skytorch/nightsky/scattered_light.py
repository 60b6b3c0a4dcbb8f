r"""Light of the glowing night sky scattered once into the line of sight.

The airglow layer (near 90 km), the zodiacal light and the starlight arrive from above
the scattering atmosphere over the whole upper sky. Besides being extinguished along the
line of sight, they are scattered into it by the air and aerosols below: near the horizon
this diffuse light makes up part of the extinction loss (Garstang 1989 §3; Kocifaj 2007).
For a source whose radiance at the top of the atmosphere depends only on the local zenith
angle of the ray (azimuthally uniform: the airglow layer's van Rhijn brightening, a
uniform background), the single-scattered radiance of a line of sight from an observer at
height :math:`h_o`, view zenith :math:`z`, is

.. math::

    L_{sca}(z) = \int_0^{s_{max}} e^{-\tau_{view}(s)} \sum_i \beta_i(h(s))
        \int_{\mu_{hor}(h)}^{1} 2\pi\,\bar P_i(\mu_v, \mu')\,
        L_{top}(\mu', h)\,e^{-\tau(h, \mu')}\,d\mu'\,ds ,

with :math:`\mu_v` the local zenith cosine of the line of sight at the scattering point
(spherical geometry), :math:`\mu'` that of the incoming light's direction (back along the
ray; rays below the local horizon :math:`\mu_{hor} = -\sqrt{1 - (R/r)^2}` meet the
ground), :math:`\tau(h, \mu')` the optical depth of that ray to the top of the atmosphere
(every species, :meth:`~skytorch.atmosphere.constituents.Constituents.column_integrals`),
and :math:`\bar P_i` the species' phase function averaged over the relative azimuth
(Gauss–Legendre nodes on :math:`[0, \pi]`). The :math:`\mu'` nodes are Gauss–Legendre in
:math:`x` with :math:`\mu' = \mu_{hor} + (1 - \mu_{hor}) x^2`, dense towards the horizon
where the transmittance falls fastest; the path uses the trapezoid rule on
:math:`s = s_{max} u^2`. Ground reflection and higher orders are not included.

References
----------
1. Garstang, R. H. 1989, PASP 101, 306, doi:10.1086/132436.
2. Kocifaj, M. 2007, Appl. Opt. 46, 3013, doi:10.1364/AO.46.003013.
3. Chandrasekhar, S. 1950, *Radiative Transfer*, Oxford (Rayleigh phase function).

Examples
--------
>>> import torch
>>> from skytorch.atmosphere import Atmosphere
>>> atm = Atmosphere.earth()
>>> uniform = lambda mu, h: torch.ones_like(mu)[..., None]
>>> value = scattered_diffuse_radiance(atm, torch.tensor([0.0, 1.4]), torch.tensor([550.0]),
...                                    uniform)
>>> bool((value[1] > value[0]).all())   # brighter towards the horizon
True
"""

from __future__ import annotations

import math

import torch

from skytorch._quadrature import unit_nodes
from skytorch._validate import as_tensor, check_int, check_range
from skytorch.atmosphere.constituents import insert_dims
from skytorch.atmosphere.geometry import distance_to_top, safe_sqrt
from skytorch.atmosphere.scattering import cumulative_columns

__all__ = ["scattered_diffuse_radiance", "scattered_zenith_response", "zenith_hat_weights"]

#: view rays per chunk (bounds the (view, path, mu', phi) temporaries)
_VIEW_CHUNK = 16


def scattered_diffuse_radiance(atmosphere, view_zenith_rad, wavelength_nm, incident, *,
                               altitude_m: float = 0.0, n_steps: int = 96, n_mu: int = 16,
                               n_azimuth: int = 8) -> torch.Tensor:
    """Single-scattered radiance of lines of sight lit by a diffuse source above the air.

    Parameters
    ----------
    atmosphere : skytorch.atmosphere.Atmosphere
        Atmosphere without batch dimensions in its parameters.
    view_zenith_rad : Tensor (n_view,)
        Zenith angles of the lines of sight, in [0, π/2] [rad].
    wavelength_nm : Tensor (n_wavelength,)
        Wavelengths [nm].
    incident : callable
        ``incident(cos_zenith, altitude_m)``: the source's radiance arriving at the top of
        the atmosphere along the ray that reaches altitude ``altitude_m`` [m] from local
        zenith cosine ``cos_zenith`` (both (...)), before extinction in the atmosphere;
        shape (..., n_wavelength) or (..., 1) [any radiance unit].
    altitude_m : float
        Observer height [m].
    n_steps, n_mu, n_azimuth : int
        Nodes along the line of sight, in the incoming zenith cosine and in the relative
        azimuth (module docstring).

    Returns
    -------
    Tensor (n_view, n_wavelength)
        Scattered radiance, in the unit of ``incident``; computed and returned in
        float64 (a one-off table, where the long slant columns near the horizon need
        the precision), differentiable with respect to ``view_zenith_rad``.
    """
    if not callable(incident):
        raise TypeError(f"incident must be a callable (cos_zenith, altitude_m); got "
                        f"{type(incident).__name__}")
    if tuple(getattr(atmosphere, "batch_shape", ())):
        raise ValueError(f"atmosphere must have no batch dimensions; got batch shape "
                         f"{tuple(atmosphere.batch_shape)}")
    n_steps = check_int("n_steps", n_steps, low=2, high=100_000)
    n_mu = check_int("n_mu", n_mu, low=1, high=10_000)
    n_azimuth = check_int("n_azimuth", n_azimuth, low=1, high=10_000)
    dtype = torch.float64
    zenith = check_range("view_zenith_rad", view_zenith_rad, 0.0, 0.5 * math.pi, unit=" rad",
                         dtype=dtype)
    if zenith.ndim != 1:
        raise ValueError(f"view_zenith_rad must have shape (n_view,); got shape "
                         f"{tuple(zenith.shape)}")
    wl = as_tensor("wavelength_nm", wavelength_nm, dtype=dtype).reshape(-1)
    altitude_m = float(check_range("altitude_m", altitude_m, 0.0,
                                   float(atmosphere.top_altitude_m), unit=" m"))
    constituents = atmosphere.constituents(wl, dtype)
    pieces = [_chunk(constituents, zenith[i:i + _VIEW_CHUNK], incident, altitude_m, n_steps,
                     n_mu, n_azimuth) for i in range(0, zenith.shape[0], _VIEW_CHUNK)]
    return torch.cat(pieces) if pieces else torch.zeros(0, wl.shape[0], dtype=dtype)


def _chunk(constituents, zenith, incident, altitude_m, n_steps, n_mu, n_azimuth):
    """:func:`scattered_diffuse_radiance` for a few view rays (n_view, n_wavelength)."""
    dtype = zenith.dtype
    planet, top = constituents.planet_radius_m, constituents.top_radius_m
    r0 = planet + altitude_m
    mu_view = torch.cos(zenith)
    length = distance_to_top(torch.full_like(zenith, r0), mu_view, top)
    s = length[:, None] * torch.linspace(0.0, 1.0, n_steps, dtype=dtype) ** 2  # (v, n)
    r = torch.sqrt(r0 * r0 + s * s + 2.0 * r0 * s * mu_view[:, None]).clamp(max=top)
    height = (r - planet).clamp(min=0.0)
    mu_local = ((r0 * mu_view[:, None] + s) / r).clamp(-1.0, 1.0)  # line of sight at s
    # incoming directions: Gauss nodes in x, mu' = mu_hor + (1 - mu_hor) x^2
    x, wx = unit_nodes(n_mu, dtype)
    mu_hor = -safe_sqrt(1.0 - (planet / r) ** 2)  # (v, n); 0 at the ground, finite gradient
    mu_in = mu_hor[..., None] + (1.0 - mu_hor[..., None]) * x * x  # (v, n, m)
    weight_mu = (1.0 - mu_hor[..., None]) * 2.0 * x * wx
    columns = constituents.column_integrals(r[..., None].expand_as(mu_in), mu_in, extra=3)
    transmittance = torch.exp(-constituents.optical_depth(columns, extra=3))  # (v, n, m, wl)
    source_top = incident(mu_in, height[..., None].expand_as(mu_in))
    radiance_in = transmittance * source_top * weight_mu[..., None]  # (v, n, m, wl)
    # azimuth-averaged phase function between the incoming and the viewing directions
    phi, wphi = unit_nodes(n_azimuth, dtype)
    sin_v = safe_sqrt(1.0 - mu_local * mu_local)[..., None, None]
    sin_in = safe_sqrt(1.0 - mu_in * mu_in)[..., None]
    cos_theta = (mu_local[..., None, None] * mu_in[..., None]
                 + sin_v * sin_in * torch.cos(math.pi * phi)).clamp(-1.0, 1.0)  # (v, n, m, p)
    densities = constituents.densities(height)
    source = 0.0
    for species in constituents.scatterers():
        if species.vanishes:
            continue
        phase = (species.phase(cos_theta, extra=4) * wphi[:, None]).sum(-2)  # (v, n, m, wl?)
        in_scattered = 2.0 * math.pi * (phase * radiance_in).sum(-2)  # (v, n, wl)
        source = source + (densities[species.name][..., None]
                           * insert_dims(species.scattering, 2, 1) * in_scattered)
    step = s[:, 1:] - s[:, :-1]
    tau_view = constituents.optical_depth(cumulative_columns(densities, step), extra=2)
    integrand = source * torch.exp(-tau_view)
    return (0.5 * (integrand[:, 1:] + integrand[:, :-1]) * step[..., None]).sum(1)


def zenith_hat_weights(nodes_rad: torch.Tensor, zenith_rad: torch.Tensor) -> torch.Tensor:
    """Weights (..., node) of linear interpolation in zenith angle between ``nodes_rad``.

    The hat functions of the increasing nodes: they sum to 1 between the first and the last
    node and are held at the end nodes beyond them.
    """
    n = nodes_rad.numel()
    z = zenith_rad.clamp(float(nodes_rad[0]), float(nodes_rad[-1]))
    upper = torch.bucketize(z.contiguous(), nodes_rad).clamp(1, n - 1)
    t = (z - nodes_rad[upper - 1]) / (nodes_rad[upper] - nodes_rad[upper - 1])
    weights = torch.zeros(*z.shape, n, dtype=z.dtype)
    weights.scatter_(-1, (upper - 1)[..., None], (1.0 - t)[..., None])
    weights.scatter_add_(-1, upper[..., None], t[..., None])
    return weights


def scattered_zenith_response(atmosphere, view_zenith_rad, wavelength_nm, source_zenith_rad,
                              *, altitude_m: float = 0.0, n_steps: int = 96, n_mu: int = 16,
                              n_azimuth: int = 8) -> torch.Tensor:
    r"""Scattered radiance per unit incident radiance at each of a set of zenith nodes.

    A source above the atmosphere whose radiance depends on the zenith angle alone,
    :math:`L_{top}(z) = \sum_k L_k\, H_k(z)` with the hat functions :math:`H_k` of
    ``source_zenith_rad`` (:func:`zenith_hat_weights`), scatters
    :math:`\sum_k L_k\, R_k(z_v, \lambda)` into a line of sight of zenith :math:`z_v`: this
    returns :math:`R_k`, each the :func:`scattered_diffuse_radiance` of one hat, all in one
    pass (the hats ride along as copies of the wavelengths). The incoming rays' zenith
    angles are those at the scattering point; for a source fixed on the sky (zodiacal
    light, starlight) they differ from the observer's by the angle between the two
    verticals (under 1° within 110 km of the observer).

    Parameters
    ----------
    atmosphere, view_zenith_rad, wavelength_nm, altitude_m, n_steps, n_mu, n_azimuth
        As for :func:`scattered_diffuse_radiance`.
    source_zenith_rad : Tensor (node,)
        Increasing zenith angles of the incident radiance's nodes [rad], in [0, π]; the
        incoming rays reach up to the ground's horizon at the scattering point (below the
        horizontal at altitude), so the nodes should reach ~100°.

    Returns
    -------
    Tensor (node, n_view, n_wavelength)
        Scattered radiance per unit incident radiance at each node [1].
    """
    nodes = check_range("source_zenith_rad", source_zenith_rad, 0.0, math.pi, unit=" rad",
                        dtype=torch.float64).reshape(-1)
    if nodes.numel() < 2 or not bool((nodes[1:] > nodes[:-1]).all()):
        raise ValueError(f"source_zenith_rad must hold at least two increasing angles; got "
                         f"{nodes.tolist()}")
    wl = as_tensor("wavelength_nm", wavelength_nm, dtype=torch.float64).reshape(-1)
    n_wl, n_nodes = wl.numel(), nodes.numel()

    def incident(mu, altitude):
        hats = zenith_hat_weights(nodes, torch.acos(mu.clamp(-1.0, 1.0)))
        return hats.repeat_interleave(n_wl, dim=-1)  # node-major copies of the wavelengths

    radiance = scattered_diffuse_radiance(atmosphere, view_zenith_rad, wl.repeat(n_nodes),
                                          incident, altitude_m=altitude_m, n_steps=n_steps,
                                          n_mu=n_mu, n_azimuth=n_azimuth)
    return radiance.reshape(-1, n_nodes, n_wl).permute(1, 0, 2)
