r"""Ray-deviation and contact-radius tables (Schneegans et al. 2025, their Fig. 6).

:func:`deviation_table` tabulates the bending and the lowest point of rays from origins
inside the atmosphere, over Bruneton's transmittance-texture coordinates (eq. 2 of
Schneegans et al. 2025), with the Bouguer integrals or the RK4 tracer;
:class:`DeviationTable` and :func:`lookup_deviation` look rays up in it bilinearly.

References
----------
1. Schneegans, S., Gilg, J., Ahlers, V., Zachmann, G. & Gerndt, A. 2025, "Physically Based
   Real-Time Rendering of Eclipses", Computer Graphics Forum, doi:10.1111/cgf.70220.
2. Bruneton, E. 2017, "Precomputed Atmospheric Scattering: a New Implementation",
   https://ebruneton.github.io/precomputed_atmospheric_scattering/ (transmittance
   texture parametrisation).
"""

from __future__ import annotations

import logging
import math

import torch

from skytorch._validate import (
    broadcast_shape,
    check_choice,
    check_int,
    check_range,
    common_dtype,
    refuse_gradient,
)
from skytorch.atmosphere.bouguer import TABLE_NODES, TABLE_PANEL_NODES, _observer_bending
from skytorch.atmosphere.geometry import texture_coordinates, texture_rays
from skytorch.atmosphere.ray_geometry import (
    _batch_shape,
    _check_atmosphere,
    _check_method,
    _Geometry,
)
from skytorch.atmosphere.ray_tracer import DEFAULT_MAX_DH_M, DEFAULT_STEP_M, _trace_observer_rk4

__all__ = ["TABLE_PARAMETRISATIONS", "DeviationTable", "deviation_table", "lookup_deviation"]

logger = logging.getLogger(__name__)

#: parametrisations of the deviation table
TABLE_PARAMETRISATIONS = ("schneegans2025",)


def _table_specs():
    from skytorch.dataset import VariableSpec

    return {
        "x_r": VariableSpec("1", "altitude texture coordinate",
                            "x_r = rho / H with rho = sqrt(r^2 - R^2), H = sqrt(R_top^2 - R^2) "
                            "(Schneegans et al. 2025, eq. 2)."),
        "x_mu": VariableSpec("1", "direction texture coordinate",
                             "x_mu = (d - d_min) / (d_max - d_min), d the straight-line distance "
                             "to the top of the atmosphere (Schneegans et al. 2025, eq. 2); "
                             "0 is the zenith, 1 the ray tangent to the ground."),
        "altitude": VariableSpec("m", "ray origin altitude",
                                 "Altitude of the ray's origin above the surface.", "altitude"),
        "view_zenith_angle": VariableSpec("degree", "view zenith angle",
                                          "Zenith angle of the ray direction at its origin."),
        "deviation": VariableSpec("degree", "ray deviation",
                                  "Angle between the ray direction at its origin and where it "
                                  "leaves the atmosphere (towards the planet), i.e. the "
                                  "astronomical refraction for an observer at the origin."),
        "contact_radius": VariableSpec("m", "contact radius",
                                       "Smallest distance of the ray from the planet's centre; "
                                       "for rays hitting the ground the virtual periapsis of "
                                       "the ray continued through a planet of constant index."),
        "contact_altitude": VariableSpec("m", "contact altitude",
                                         "contact_radius minus the planet radius; negative for "
                                         "rays blocked by the planet."),
    }


def deviation_table(
    atm,
    n_altitude: int = 512,
    n_angle: int = 256,
    *,
    parametrisation: str = "schneegans2025",
    method: str = "bouguer",
    n_nodes: int | None = None,
    step_m: float = DEFAULT_STEP_M,
    max_dh_m: float = DEFAULT_MAX_DH_M,
    dtype: torch.dtype = torch.float64,
    chunk_size: int = 16384,
    progress: bool = True,
):
    r"""Ray deviation and contact radius over ray origins and directions (Fig. 6, ref. 3).

    Parameters
    ----------
    atm : Atmosphere or compatible
        Needs ``planet_radius_m``, ``top_altitude_m`` and ``refractivity``.
    n_altitude, n_angle : int
        Samples of :math:`x_r` and :math:`x_\mu` (Schneegans et al. used 512 × 256).
    parametrisation : {"schneegans2025"}
        Texture coordinates of eq. 2 of ref. 3 (Bruneton's transmittance texture without
        the half-texel offsets): grid points at ``linspace(0, 1, n)``.
    method : {"bouguer", "rk4"}
        Ray-path algorithm (``"rk4"``: Schneegans' ray marching, ``step_m`` = 10 km).
    n_nodes : int, optional
        Gauss–Legendre nodes per panel of the Bouguer integrals (default
        :data:`TABLE_NODES`, or :data:`TABLE_PANEL_NODES` when the refractivity profile
        has breakpoints, e.g. the U.S. Standard Atmosphere 1976 of ``Atmosphere.earth()``).
    step_m, max_dh_m
        Resolution, see :func:`refraction_angle`.
    dtype : torch.dtype
        Computation dtype.
    chunk_size : int
        Rays per batch (memory bound).
    progress : bool
        Show a tqdm progress bar (only on a terminal).

    Returns
    -------
    xarray.Dataset
        Dimensions ``x_r`` (n_altitude) and ``x_mu`` (n_angle); variables ``deviation``
        [degree], ``contact_radius`` and ``contact_altitude`` [m] (x_r, x_mu), coordinates
        ``altitude`` (x_r) [m] and ``view_zenith_angle`` (x_r, x_mu) [degree].

    Notes
    -----
    Every ray starts inside the atmosphere and is followed to where it leaves it; rays
    that hit the ground continue through a planet of constant refractive index (ref. 3),
    so the table is smooth and the sign of ``contact_altitude`` tells which rays the
    planet blocks. Look values up with :class:`DeviationTable` or
    :func:`lookup_deviation`.

    Examples
    --------
    >>> import torch
    >>> from skytorch.atmosphere.ray_geometry import ExponentialAir as Air
    >>> ds = deviation_table(Air(), 8, 4, progress=False)
    >>> ds.deviation.dims
    ('x_r', 'x_mu')
    """
    from skytorch.dataset import build_dataset, coordinate, variable

    check_choice("parametrisation", parametrisation, TABLE_PARAMETRISATIONS)
    _check_atmosphere(atm)
    refuse_gradient("deviation_table", atm=atm)
    if _batch_shape(atm) != ():
        raise ValueError("deviation tables need an atmosphere with scalar parameters; got "
                         f"batch shape {_batch_shape(atm)} (build one table per member)")
    if n_nodes is None:
        n_nodes = (TABLE_NODES if _Geometry(atm, dtype).breakpoints is None
                   else TABLE_PANEL_NODES)
    method, checked_nodes = _check_method(method, n_nodes)
    n_altitude = check_int("n_altitude", n_altitude, low=2)
    n_angle = check_int("n_angle", n_angle, low=2)
    chunk_size = check_int("chunk_size", chunk_size, low=1)
    radius = float(atm.planet_radius_m)
    top_radius = radius + float(atm.top_altitude_m)
    x_r = torch.linspace(0.0, 1.0, n_altitude, dtype=dtype)
    x_mu = torch.linspace(0.0, 1.0, n_angle, dtype=dtype)
    altitude, mu = texture_rays(x_r[:, None], x_mu[None, :], radius, top_radius)
    altitude = altitude.expand(n_altitude, n_angle)
    elevation = torch.asin(mu)
    deviation = torch.empty_like(mu)
    contact = torch.empty_like(mu)
    flat_h, flat_e = altitude.reshape(-1), elevation.reshape(-1)
    flat_dev, flat_contact = deviation.view(-1), contact.view(-1)
    starts = range(0, flat_h.numel(), chunk_size)
    from tqdm.auto import tqdm

    bar = tqdm(starts, desc="deviation table", disable=not progress, leave=False)
    with torch.no_grad():
        for start in bar:
            part = slice(start, start + chunk_size)
            h, e = flat_h[part], flat_e[part]
            if method == "rk4":
                out = _trace_observer_rk4(atm, e, h, dtype, step_m, max_dh_m)
                flat_dev[part] = out["deviation_rad"]
                flat_contact[part] = out["contact_radius_m"] - radius
            else:
                bending, rays, t0 = _observer_bending(atm, e, h, dtype, checked_nodes)
                flat_dev[part] = bending
                flat_contact[part] = torch.where(t0 < 0.0, rays.h_p, h)
    logger.info("deviation table %d x %d (%s) computed", n_altitude, n_angle, method)
    specs = _table_specs()
    dims = ("x_r", "x_mu")
    data = {
        "deviation": variable(dims, torch.rad2deg(deviation), specs["deviation"]),
        "contact_radius": variable(dims, contact + radius, specs["contact_radius"]),
        "contact_altitude": variable(dims, contact, specs["contact_altitude"]),
    }
    coords = {
        "x_r": coordinate("x_r", x_r, specs["x_r"]),
        "x_mu": coordinate("x_mu", x_mu, specs["x_mu"]),
        "altitude": variable(("x_r",), altitude[:, 0], specs["altitude"]),
        "view_zenith_angle": variable(dims, torch.rad2deg(torch.acos(mu)),
                                      specs["view_zenith_angle"]),
    }
    parameters = {"parametrisation": parametrisation, "method": method,
                  "n_nodes": n_nodes if method == "bouguer" else None,
                  "step_m": step_m if method == "rk4" else None,
                  "max_dh_m": max_dh_m if method == "rk4" else None,
                  "planet_radius_m": radius, "top_altitude_m": float(atm.top_altitude_m)}
    if hasattr(atm, "parameters_dict"):
        parameters["atmosphere"] = atm.parameters_dict()
    return build_dataset(
        data, coords, title="Ray deviation and contact radius of refracted rays",
        references=[
            "Schneegans, S. et al. 2025, Physically Based Real-Time Rendering of Eclipses, "
            "Computer Graphics Forum, doi:10.1111/cgf.70220",
            "Auer, L. H. & Standish, E. M. 2000, Astron. J. 119, 2472, doi:10.1086/301325",
        ],
        parameters=parameters)


class DeviationTable(torch.nn.Module):
    """Batched bilinear look-up in a :func:`deviation_table` (layer 2 of the design).

    Parameters
    ----------
    dataset : xarray.Dataset
        Output of :func:`deviation_table`.

    Examples
    --------
    >>> import torch
    >>> from skytorch.atmosphere.ray_geometry import ExponentialAir as Air
    >>> table = DeviationTable(deviation_table(Air(), 16, 16, progress=False))
    >>> out = table(torch.tensor([0.0]), torch.tensor([0.5]))
    >>> sorted(out)
    ['contact_altitude_m', 'deviation_rad', 'hits_ground']
    """

    def __init__(self, dataset):
        super().__init__()
        import xarray as xr

        if not isinstance(dataset, xr.Dataset) or "deviation" not in dataset:
            raise TypeError("dataset must be an xarray.Dataset from deviation_table; got "
                            f"{type(dataset).__name__}")
        self.planet_radius_m = float(dataset.attrs["parameter_planet_radius_m"])
        self.top_altitude_m = float(dataset.attrs["parameter_top_altitude_m"])
        self.register_buffer("deviation_rad", torch.deg2rad(
            torch.as_tensor(dataset["deviation"].values, dtype=torch.float64)))
        self.register_buffer("contact_altitude_m", torch.as_tensor(
            dataset["contact_altitude"].values, dtype=torch.float64))

    def forward(self, altitude_m, zenith_rad) -> dict[str, torch.Tensor]:
        """Deviation [rad], contact altitude [m] and the ground-hit flag (...).

        Parameters
        ----------
        altitude_m : Tensor (...)
            Ray origin altitude, in [0, top] [m].
        zenith_rad : Tensor (...)
            Ray zenith angle at the origin [rad]; rays below the geometric horizon (outside
            the table) get the values of the ray tangent to the ground and
            ``hits_ground`` True.
        """
        dtype = common_dtype(altitude_m, zenith_rad)
        top = self.top_altitude_m
        height = check_range("altitude_m", altitude_m, 0.0, top, unit=" m", dtype=dtype)
        zenith = check_range("zenith_rad", zenith_rad, 0.0, math.pi, unit=" rad", dtype=dtype)
        try:
            broadcast_shape(height.shape, zenith.shape)
        except ValueError:
            raise ValueError(f"shapes do not broadcast: altitude_m {tuple(height.shape)}, "
                             f"zenith_rad {tuple(zenith.shape)}") from None
        height, zenith = torch.broadcast_tensors(height, zenith)
        x_r, x_mu = texture_coordinates(height, torch.cos(zenith), self.planet_radius_m,
                                            self.planet_radius_m + top)
        below = x_mu > 1.0
        deviation = _bilinear(self.deviation_rad.to(dtype), x_r, x_mu)
        contact = _bilinear(self.contact_altitude_m.to(dtype), x_r, x_mu)
        return {"deviation_rad": deviation, "contact_altitude_m": contact,
                "hits_ground": below | (contact < 0.0)}


def _bilinear(grid: torch.Tensor, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    """Bilinear interpolation of ``grid`` (n_x, n_y) sampled at linspace(0, 1) (clamped)."""
    n_x, n_y = grid.shape
    fx = torch.clamp(x, 0.0, 1.0) * (n_x - 1)
    fy = torch.clamp(y, 0.0, 1.0) * (n_y - 1)
    ix = torch.clamp(fx.detach().floor().long(), 0, n_x - 2)
    iy = torch.clamp(fy.detach().floor().long(), 0, n_y - 2)
    wx, wy = fx - ix, fy - iy
    g00, g01 = grid[ix, iy], grid[ix, iy + 1]
    g10, g11 = grid[ix + 1, iy], grid[ix + 1, iy + 1]
    return (g00 * (1 - wx) * (1 - wy) + g01 * (1 - wx) * wy + g10 * wx * (1 - wy)
            + g11 * wx * wy)


def lookup_deviation(table, altitude_m, zenith_rad) -> dict[str, torch.Tensor]:
    """Look rays up in a deviation table (Dataset or :class:`DeviationTable`).

    Parameters
    ----------
    table : xarray.Dataset or DeviationTable
        From :func:`deviation_table`.
    altitude_m, zenith_rad : Tensor (...)
        Ray origins and zenith angles [m], [rad].

    Returns
    -------
    dict of Tensor (...)
        ``deviation_rad``, ``contact_altitude_m``, ``hits_ground``.
    """
    if not isinstance(table, DeviationTable):
        table = DeviationTable(table)
    return table(altitude_m, zenith_rad)
