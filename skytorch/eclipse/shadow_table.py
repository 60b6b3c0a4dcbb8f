r"""Eclipse-shadow look-up table over the (u, v) parametrisation of Schneegans et al.

A point in the shadow cone is described by the angular radii of the Sun ``phi_s`` and of
the occluder (top of its atmosphere) ``phi_o`` seen from it and the angular distance
``delta`` between their centres (Schneegans et al. 2022, 2025, eq. 3–4):

.. math::

    u = \frac{1}{\varphi_o/\varphi_s + 1}, \qquad v = \frac{\delta}{\varphi_o + \varphi_s}.

``u`` grows from ~0 at the occluder to ``R_s / (R_s + R_o)`` infinitely far away (0.5 at
the end of the umbra); ``v`` runs from 0 on the shadow axis to 1 at the outer edge of the
penumbra, beyond which the Sun is unobstructed.

The inverse mapping (eq. 5–6) has no closed form: starting from ``d_s = D`` (Sun–occluder
distance) it iterates

.. math::

    \varphi_s = \arcsin\frac{R_s}{d_s},\quad \varphi_o = \varphi_s\Big(\frac1u - 1\Big),\quad
    \delta = v(\varphi_o + \varphi_s),\quad d_o = \frac{R_o}{\sin\varphi_o},\quad
    d_s = d_o\cos\delta + \sqrt{D^2 - d_o^2\sin^2\delta} ,

a contraction with factor about ``d_o / d_s``; it is run to a relative change below 1e-15
(converged to 1e-9 in (u, v) far faster than that, tested). The point then lies at
``d_o`` from the occluder's centre, at angle ``delta + asin(d_o sin(delta) / D)`` from
the anti-Sun axis (exterior angle of the triangle Sun–occluder–point).

:class:`ShadowTable` stores ``I / I_sun`` on a regular (u, v) grid for a set of
wavelengths, as a Dataset, and looks points up by bilinear interpolation of
``log(I / I_sun)`` (the umbra spans many decades).

References
----------
1. Schneegans, S., Gilg, J., Ahlers, V., Zachmann, G., Gerndt, A. 2025, "Physically
   Based Real-Time Rendering of Eclipses", Computer Graphics Forum,
   doi:10.1111/cgf.70220, §5.1 (eq. 3–6).
2. Schneegans, S., Gilg, J., Ahlers, V., Gerndt, A. 2022, "Real-Time Rendering of Eclipses
   without Incorporation of Atmospheric Effects", Computer Graphics Forum 41, 279,
   doi:10.1111/cgf.14676 (the shadow look-up parametrisation).

Examples
--------
>>> import torch
>>> from skytorch.eclipse.shadow_table import shadow_uv, shadow_uv_inverse
>>> p = shadow_uv_inverse(torch.tensor(0.25), torch.tensor(0.5), 1.496e11, 6.957e8, 6.471e6)
>>> u, v = shadow_uv(p["sun_radius_rad"], p["occluder_radius_rad"], p["separation_rad"])
>>> round(float(u), 12), round(float(v), 12)
(0.25, 0.5)
"""

from __future__ import annotations

import hashlib
import json
import logging
import math

import numpy as np
import torch
import xarray as xr
from torch import nn

from skytorch._validate import (
    as_tensor,
    check_broadcastable,
    check_choice,
    check_finite,
    check_flag,
    check_int,
    check_positive,
    check_range,
    common_dtype,
)
from skytorch.dataset import VariableSpec, build_dataset, coordinate, to_numpy, variable
from skytorch.eclipse.shadow import (
    Shadow,
    _check_wavelength,
    shadow_angles,
)
from skytorch.eclipse.shadow_mixture import DEFAULT_POSITION_ANGLES, ShadowMixture

__all__ = [
    "INTERPOLATIONS",
    "ShadowTable",
    "shadow_uv",
    "shadow_uv_inverse",
]

logger = logging.getLogger(__name__)

#: look-up interpolation: bilinear in log(I / I_sun) or in I / I_sun
INTERPOLATIONS = ("log", "linear")

#: relative change of the Sun's distance at which the inverse mapping stops
INVERSE_TOLERANCE = 1e-15
#: iteration limit of the inverse mapping
INVERSE_MAX_ITERATIONS = 200
#: smallest tabulated value (log interpolation floor)
_FLOOR = 1e-300

_REFERENCES = [
    "Schneegans, S., Gilg, J., Ahlers, V., Zachmann, G., Gerndt, A. 2025, Physically Based "
    "Real-Time Rendering of Eclipses, Computer Graphics Forum, doi:10.1111/cgf.70220",
]


def shadow_uv(sun_radius_rad, occluder_radius_rad, separation_rad):
    """Table coordinates of a point from the angles seen from it (eq. 4).

    Parameters
    ----------
    sun_radius_rad, occluder_radius_rad, separation_rad : Tensor (...)
        ``phi_s``, ``phi_o`` (top of the atmosphere) and ``delta`` [rad].

    Returns
    -------
    (u, v) : Tensor (...)
        ``u = 1 / (phi_o / phi_s + 1)`` and ``v = delta / (phi_o + phi_s)`` [1].
    """
    phi_s, phi_o, delta = sun_radius_rad, occluder_radius_rad, separation_rad
    return phi_s / (phi_o + phi_s), delta / (phi_o + phi_s)


def shadow_uv_inverse(u, v, sun_distance_m, sun_radius_m, occluder_radius_m, *,
                      tolerance: float = INVERSE_TOLERANCE,
                      max_iterations: int = INVERSE_MAX_ITERATIONS) -> dict[str, torch.Tensor]:
    """Position in space of the table coordinates ``(u, v)`` (iterative, eq. 5–6).

    Parameters
    ----------
    u, v : Tensor (...)
        Table coordinates; ``u`` must correspond to a point outside the occluder
        (``phi_o < pi/2``) and below ``R_s / (R_s + R_o)``; ``v >= 0``.
    sun_distance_m, sun_radius_m, occluder_radius_m : float
        Sun–occluder distance ``D``, solar radius ``R_s`` and occluder radius ``R_o``
        (top of the atmosphere) [m].
    tolerance : float
        Stop when the relative change of the Sun's distance is below this.
    max_iterations : int
        Iteration limit (a ``ValueError`` is raised if it is reached).

    Returns
    -------
    dict of Tensor (...)
        ``distance_m`` (along the anti-Sun axis) and ``offset_m`` (from it) [m];
        ``centre_distance_m`` ``d_o`` and ``sun_range_m`` ``d_s`` [m];
        ``sun_radius_rad``, ``occluder_radius_rad``, ``separation_rad`` [rad];
        ``iterations`` (int).
    """
    dtype = common_dtype(u, v)
    u = check_range("u", u, 0.0, 1.0, low_inclusive=False, high_inclusive=False, dtype=dtype)
    v = check_range("v", v, 0.0, dtype=dtype)
    big_d, r_s, r_o = (float(check_positive(name, value, unit=" m")) for name, value in (
        ("sun_distance_m", sun_distance_m), ("sun_radius_m", sun_radius_m),
        ("occluder_radius_m", occluder_radius_m)))
    if not big_d > r_s + r_o:
        raise ValueError(f"sun_distance_m must exceed sun_radius_m + occluder_radius_m = "
                         f"{r_s + r_o:.6g} m; got {big_d:.6g} m")
    check_broadcastable(u=u, v=v)
    max_iterations = check_int("max_iterations", max_iterations, low=1)
    tolerance = float(check_positive("tolerance", tolerance))
    far = r_s / (r_s + r_o)
    with torch.no_grad():
        if bool((u >= far).any()):
            raise ValueError(f"u must be < R_s / (R_s + R_o) = {far:.9g} (a point at finite "
                             f"distance); got max u = {float(u.max()):.9g}")
    def update(d_s):
        """One step of eq. 5-6: the Sun's distance implied by the current guess."""
        phi_s = torch.asin(r_s / d_s)
        phi_o = phi_s / u - phi_s
        with torch.no_grad():
            if bool((phi_o >= 0.5 * math.pi).any()):
                raise ValueError("u is too small: the point would lie inside the occluder "
                                 f"(phi_o >= 90 deg); got min u = {float(u.min()):.6g}")
        delta = v * (phi_o + phi_s)
        d_o = r_o / torch.sin(phi_o)
        return d_o * torch.cos(delta) + torch.sqrt(big_d**2 - (d_o * torch.sin(delta)) ** 2)

    # fixed-point iteration of eq. 6 (Schneegans et al.), accelerated by the secant method
    # on the residual F(d) - d: the plain iteration contracts by ~d_o/d_s only, slow for
    # points far beyond the umbra
    previous = torch.full_like(u, big_d)
    previous_residual = update(previous) - previous
    d_s = previous + previous_residual
    iterations = 1
    tolerance = max(float(tolerance), 4.0 * torch.finfo(dtype).eps)
    while True:
        residual = update(d_s) - d_s
        iterations += 1
        change = float((residual.abs() / d_s).max().detach()) if d_s.numel() else 0.0
        if change <= tolerance:
            break
        if iterations >= max_iterations:
            raise ValueError(f"inverse (u, v) mapping did not converge in {max_iterations} "
                             f"iterations (relative change {change:.3g})")
        slope = (residual - previous_residual) / (d_s - previous)
        secant = d_s - residual / slope
        step = torch.where(torch.isfinite(secant) & (slope < 0) & (d_s != previous),
                           secant, d_s + residual)
        previous, previous_residual = d_s, residual
        d_s = step
    phi_s = torch.asin(r_s / d_s)
    phi_o = phi_s / u - phi_s
    delta = v * (phi_o + phi_s)
    d_o = r_o / torch.sin(phi_o)
    axis_angle = delta + torch.asin(d_o * torch.sin(delta) / big_d)
    return {
        "distance_m": d_o * torch.cos(axis_angle),
        "offset_m": d_o * torch.sin(axis_angle),
        "centre_distance_m": d_o,
        "sun_range_m": d_s,
        "sun_radius_rad": phi_s,
        "occluder_radius_rad": phi_o,
        "separation_rad": delta,
        "iterations": iterations,
    }


def _u_at_distance(distance_m: float, sun_distance_m: float, sun_radius_m: float,
                   occluder_radius_m: float) -> float:
    """``u`` of a point on the shadow axis at ``distance_m`` behind the occluder."""
    phi_s = math.asin(sun_radius_m / (sun_distance_m + distance_m))
    phi_o = math.asin(occluder_radius_m / distance_m)
    return phi_s / (phi_o + phi_s)


_SPECS = {
    "relative_illuminance": VariableSpec(
        "1", "relative illuminance", "Illuminance relative to the unobstructed Sun, I/I_sun, "
        "direct light above the atmosphere plus light refracted through the atmosphere ring"),
    "distance": VariableSpec("m", "distance along the anti-Sun axis",
                             "Distance behind the occluder's centre along the anti-Sun axis"),
    "offset": VariableSpec("m", "distance from the shadow axis",
                           "Distance of the point from the anti-Sun axis"),
    "u": VariableSpec("1", "shadow table coordinate u",
                      "u = 1 / (phi_occ / phi_sun + 1) (Schneegans et al. 2025, eq. 4)"),
    "v": VariableSpec("1", "shadow table coordinate v",
                      "v = delta / (phi_occ + phi_sun) (Schneegans et al. 2025, eq. 4)"),
    "wavelength": VariableSpec("nm", "wavelength", "Vacuum wavelength",
                               standard_name="radiation_wavelength"),
}


class ShadowTable(nn.Module):
    """``I / I_sun`` tabulated over Schneegans' (u, v) for a set of wavelengths.

    Build it with :meth:`compute`; save with :meth:`to_dataset` and restore with
    :meth:`from_dataset`.

    Parameters
    ----------
    u, v : Tensor (u,), (v,)
        Uniform grids of the table coordinates.
    wavelength_nm : Tensor (wavelength,)
        Wavelengths [nm].
    values : Tensor (u, v, wavelength) or (u, v, *B, wavelength)
        ``I / I_sun``, optionally for a batch (shape ``B``) of atmospheres; look-ups then
        return ``(..., *B, wavelength)``.
    sun_distance_m, sun_radius_m, occluder_radius_m : float
        Geometry of the table (``occluder_radius_m`` is the top of the atmosphere) [m].
    interpolation : {"log", "linear"}
        Bilinear interpolation of ``log(I / I_sun)`` or of ``I / I_sun``.
    attrs : dict, optional
        Parameters stored with the Dataset.
    """

    def __init__(self, u, v, wavelength_nm, values, *, sun_distance_m: float,
                 sun_radius_m: float, occluder_radius_m: float, interpolation: str = "log",
                 attrs: dict | None = None, provenance: dict | None = None):
        super().__init__()
        self.interpolation = check_choice("interpolation", interpolation, INTERPOLATIONS)
        u = _uniform_grid("u", u, 0.0, 1.0)
        v = _uniform_grid("v", v, 0.0, 1.0)
        if float(v[0]) != 0.0 or abs(float(v[-1]) - 1.0) > 1e-12:
            raise ValueError(f"v must run from 0 to 1; got {float(v[0])} .. {float(v[-1])}")
        wavelength = check_range("wavelength_nm", wavelength_nm, 0.0, low_inclusive=False,
                                 unit=" nm", dtype=torch.float64)
        if wavelength.ndim != 1 or wavelength.numel() == 0:
            raise ValueError("wavelength_nm must be a non-empty 1-D array; got shape "
                             f"{tuple(wavelength.shape)}")
        values = as_tensor("values", values, dtype=torch.float64)
        if (values.ndim < 3 or values.shape[0] != u.shape[0] or values.shape[1] != v.shape[0]
                or values.shape[-1] != wavelength.shape[0]):
            raise ValueError(
                "values must have shape (u, v, [batch ...,] wavelength) = "
                f"({u.shape[0]}, {v.shape[0]}, ..., {wavelength.shape[0]}); got "
                f"{tuple(values.shape)}")
        check_range("values", values, 0.0)
        self.register_buffer("u", u)
        self.register_buffer("v", v)
        self.register_buffer("wavelength_nm", wavelength)
        self.register_buffer("values", values)
        self.batch_shape = tuple(self.values.shape[2:-1])
        self.sun_distance_m = float(check_positive("sun_distance_m", sun_distance_m, unit=" m"))
        self.sun_radius_m = float(check_positive("sun_radius_m", sun_radius_m, unit=" m"))
        self.occluder_radius_m = float(check_positive("occluder_radius_m", occluder_radius_m,
                                                      unit=" m"))
        if attrs is not None and not isinstance(attrs, dict):
            raise TypeError(f"attrs must be a dict or None; got {type(attrs).__name__}")
        self.attrs = dict(attrs or {})
        if provenance is not None and not isinstance(provenance, dict):
            raise TypeError(f"provenance must be a dict or None; got {type(provenance).__name__}")
        #: position angles around the axis [rad] of a table resolved in direction (its
        #: one batch dimension; ``attrs["position_angle_rad"]``), None otherwise
        self.position_angle_rad = (
            None if "position_angle_rad" not in self.attrs
            else torch.tensor(self.attrs["position_angle_rad"], dtype=torch.float64))
        if (self.position_angle_rad is not None
                and self.batch_shape != tuple(self.position_angle_rad.shape)):
            raise ValueError("a table resolved in direction has its position angles as its "
                             f"one batch dimension: {self.position_angle_rad.shape[0]} "
                             f"angles, batch shape {self.batch_shape}")
        #: what the table was built for: ``shadow_sha256`` (every setting of the shadow
        #: model, its atmosphere included), ``atmosphere_sha256``, ``n_u``, ``n_v`` (set by
        #: :meth:`compute`; see :meth:`check_compatible`)
        self.provenance = dict(provenance or {})

    # ------------------------------------------------------------------ build
    @classmethod
    def compute(cls, shadow, wavelength_nm, *, n_u: int = 256, n_v: int = 256,  # noqa: C901 (checks, two kinds of shadow)
                min_distance_m: float | None = None, max_distance_m: float | None = None,
                interpolation: str = "log", progress: bool = True,
                dtype: torch.dtype = torch.float64,
                n_position_angle: int | None = None) -> ShadowTable:
        """Evaluate ``shadow.relative_illuminance`` on the (u, v) grid.

        Parameters
        ----------
        shadow : Shadow or ShadowMixture
            The shadow model (its default Sun distance is used). A mixture with
            ``limb_windows`` is resolved in direction: its table has the position angle
            around the axis (``n_position_angle`` values over [0, π]) as its one batch
            dimension (:attr:`position_angle_rad`); a mixture without them is the
            weighted mean of its members' tables.
        wavelength_nm : Tensor (wavelength,)
            Wavelengths [nm].
        n_u, n_v : int
            Grid size; ``v`` runs over [0, 1] and ``u`` over the range of axis points
            between ``min_distance_m`` and ``max_distance_m`` behind the occluder.
        min_distance_m, max_distance_m : float, optional
            Defaults: 1.02 times the top radius, and ten times the length of the umbra
            of the top of the atmosphere.
        interpolation : {"log", "linear"}
            Look-up interpolation.
        progress : bool
            Show a progress bar (only on a terminal).
        dtype : torch.dtype
            Precision of the evaluation.
        n_position_angle : int, optional
            Position angles of a mixture resolved in direction (>= 2); default the
            mixture's ``n_position_angle``.

        Notes
        -----
        The table's ``values`` keep the graph of the shadow's parameters that require a
        gradient (the atmosphere's extinction parameters, a cloud-top tensor; see
        :class:`~skytorch.eclipse.shadow.Shadow`), so :meth:`lookup` and the light curves
        built on it are differentiable with respect to them; the ring table is then built
        once per call. The graph holds the ring integral's temporaries of every row: keep
        such tables small (a light curve uses a few ``u`` rows). :meth:`to_dataset` writes
        the values only.
        """
        from tqdm.auto import tqdm

        resolved = isinstance(shadow, ShadowMixture) and shadow.limb_windows is not None
        if isinstance(shadow, ShadowMixture) and not resolved:
            return cls._compute_mixture(shadow, wavelength_nm, n_u=n_u, n_v=n_v,
                                        min_distance_m=min_distance_m,
                                        max_distance_m=max_distance_m,
                                        interpolation=interpolation, progress=progress,
                                        dtype=dtype)
        if not isinstance(shadow, (Shadow, ShadowMixture)):
            raise TypeError(f"shadow must be a skytorch.eclipse.Shadow or ShadowMixture; got "
                            f"{type(shadow).__name__}: {shadow!r:.60}")
        n_u = check_int("n_u", n_u, low=2)
        n_v = check_int("n_v", n_v, low=2)
        progress = check_flag("progress", progress)
        if n_position_angle is None:
            n_position_angle = getattr(shadow, "n_position_angle", DEFAULT_POSITION_ANGLES)
        n_position_angle = check_int("n_position_angle", n_position_angle, low=2)
        check_choice("interpolation", interpolation, INTERPOLATIONS)
        if not isinstance(dtype, torch.dtype) or not dtype.is_floating_point:
            raise TypeError(f"dtype must be a floating torch.dtype; got {dtype!r}")
        for name, value in (("min_distance_m", min_distance_m),
                            ("max_distance_m", max_distance_m)):
            if value is not None:
                check_positive(name, value, unit=" m")
        big_d, r_s, r_o = shadow.sun_distance_m, shadow.sun_radius_m, shadow.top_radius_m
        umbra_length = r_o * big_d / (r_s - r_o) if r_s > r_o else 1e3 * big_d
        low = 1.02 * r_o if min_distance_m is None else float(min_distance_m)
        high = 10.0 * umbra_length if max_distance_m is None else float(max_distance_m)
        if not r_o < low < high:
            raise ValueError(f"need top radius {r_o:.6g} m < min_distance_m {low:.6g} m < "
                             f"max_distance_m {high:.6g} m")
        u_low = _u_at_distance(low, big_d, r_s, r_o)
        u_high = _u_at_distance(high, big_d, r_s, r_o)
        # grid and positions in float64 (the inverse mapping converges to 1e-15); the
        # illuminance is evaluated in ``dtype``
        u = torch.linspace(u_low, u_high, n_u, dtype=torch.float64)
        v = torch.linspace(0.0, 1.0, n_v, dtype=torch.float64)
        wavelength = _check_wavelength(wavelength_nm, dtype)
        position = shadow_uv_inverse(u[:, None].expand(n_u, n_v), v[None, :].expand(n_u, n_v),
                                     big_d, r_s, r_o)
        attrs = {"min_distance_m": low, "max_distance_m": high, "n_u": n_u, "n_v": n_v,
                 "dtype": str(dtype).replace("torch.", "")}
        if resolved:
            # a shadow resolved in direction: the position angles around the axis are the
            # table's one batch dimension (the latitude on the limb depends on cos only)
            angles = torch.linspace(0.0, math.pi, n_position_angle, dtype=dtype)
            attrs["position_angle_rad"] = angles.tolist()
            batch = (n_position_angle,)

            def evaluate(distance, offset):
                return shadow.relative_illuminance(distance, offset, wavelength,
                                                   position_angle_rad=angles)
        else:
            # one ring table for every row (with parameters that require a gradient it is
            # rebuilt on every call of relative_illuminance, so build it here once)
            profile = shadow.ring_profile(wavelength)
            batch = tuple(getattr(shadow, "batch_shape", ()))

            def evaluate(distance, offset):
                return shadow._relative_illuminance(distance, offset, wavelength,
                                                    profile=profile)
        rows = []
        show = progress and _is_terminal()
        step = max(1, 4096 // n_v)
        ones = () if resolved else (1,) * len(batch)
        # no torch.no_grad: the values keep the graph of atmosphere parameters (and a
        # cloud-top tensor) that require a gradient, for lookups that carry it
        for start in tqdm(range(0, n_u, step), desc="shadow table", disable=not show):
            distance = position["distance_m"][start:start + step].to(dtype)
            offset = position["offset_m"][start:start + step].to(dtype)
            rows.append(evaluate(distance.reshape(*distance.shape, *ones),
                                 offset.reshape(*offset.shape, *ones)))
        values = torch.cat(rows).to(torch.float64)
        if hasattr(shadow, "parameters_dict"):
            attrs.update(shadow.parameters_dict())
        table = cls(u, v, wavelength, values, sun_distance_m=big_d, sun_radius_m=r_s,
                    occluder_radius_m=r_o, interpolation=interpolation, attrs=attrs,
                    provenance=_provenance(shadow, n_u, n_v))
        table._positions = position
        return table

    @classmethod
    def _compute_mixture(cls, mixture: ShadowMixture, wavelength_nm, **options) -> ShadowTable:
        """Table of a :class:`ShadowMixture`: its members' tables, weighted (same grid)."""
        tables = [cls.compute(shadow, wavelength_nm, **options) for shadow in mixture.shadows]
        try:
            values = sum(weight * table.values
                         for weight, table in zip(mixture.weights, tables, strict=True))
        except RuntimeError as error:
            raise ValueError("the mixture's members have batch shapes that do not broadcast: "
                             f"{[t.batch_shape for t in tables]}") from error
        first = tables[0]
        attrs = {key: value for key, value in first.attrs.items()
                 if key in ("min_distance_m", "max_distance_m", "n_u", "n_v", "dtype",
                            "limb_darkening", "limb_darkening_law")}
        attrs.update(mixture.parameters_dict())
        table = cls(first.u, first.v, first.wavelength_nm, values,
                    sun_distance_m=first.sun_distance_m, sun_radius_m=first.sun_radius_m,
                    occluder_radius_m=first.occluder_radius_m,
                    interpolation=first.interpolation, attrs=attrs,
                    provenance=_provenance(mixture, first.attrs["n_u"], first.attrs["n_v"]))
        table._positions = first._positions
        return table

    # ------------------------------------------------------------------ look-up
    def lookup_uv(self, u, v, *, wavelength_nm=None) -> torch.Tensor:
        """Bilinear look-up at table coordinates -> (..., *B, wavelength).

        ``u`` in [0, 1] (clamped to the grid) and ``v >= 0``; ``v >= 1`` gives exactly 1
        (outside the penumbra). ``wavelength_nm``, if given, must be the table's
        (:meth:`check_compatible`).
        """
        dtype = common_dtype(u, v)
        u = check_range("u", u, 0.0, 1.0, dtype=dtype)
        v = check_range("v", v, 0.0, dtype=dtype)
        if wavelength_nm is not None:
            self.check_compatible(wavelength_nm=wavelength_nm)
        check_broadcastable(u=u, v=v)
        u, v = torch.broadcast_tensors(u, v)
        grid_u, grid_v = self.u.to(dtype), self.v.to(dtype)
        raw = values = self.values.to(dtype)
        if self.interpolation == "log":
            values = torch.log(torch.clamp(values, min=_FLOOR if dtype == torch.float64
                                           else torch.finfo(dtype).tiny))
        n_u, n_v = grid_u.shape[0], grid_v.shape[0]
        x = (torch.clamp(u, grid_u[0], grid_u[-1]) - grid_u[0]) / (grid_u[-1] - grid_u[0]) * (
            n_u - 1)
        y = torch.clamp(v, 0.0, 1.0) * (n_v - 1)
        i = torch.clamp(torch.floor(x.detach()), 0, n_u - 2).long()
        j = torch.clamp(torch.floor(y.detach()), 0, n_v - 2).long()
        trailing = (1,) * (len(self.batch_shape) + 1)  # batch members, wavelength
        fx = (x - i.to(dtype)).reshape(*x.shape, *trailing)
        fy = (y - j.to(dtype)).reshape(*y.shape, *trailing)
        def bilinear(table):
            return ((1 - fx) * (1 - fy) * table[i, j] + fx * (1 - fy) * table[i + 1, j]
                    + (1 - fx) * fy * table[i, j + 1] + fx * fy * table[i + 1, j + 1])

        result = bilinear(values)
        if self.interpolation == "log":
            # linear where a corner holds no light (a dark umbra): 0 stays 0, where the
            # logarithm's floor gave 1e-300 (V = 737 mag for a Moon in a black umbra)
            dark = torch.minimum(torch.minimum(raw[i, j], raw[i + 1, j]),
                                 torch.minimum(raw[i, j + 1], raw[i + 1, j + 1])) <= 0.0
            result = torch.where(dark, bilinear(raw), torch.exp(result))
        return torch.where((v >= 1.0).reshape(*v.shape, *trailing), torch.ones_like(result),
                           result)

    def lookup(self, distance_m, offset_m, sun_distance_m=None, *,
               wavelength_nm=None) -> torch.Tensor:
        """``I / I_sun`` at points given along and across the anti-Sun axis [m].

        Validates like :meth:`Shadow.relative_illuminance`.

        Parameters
        ----------
        distance_m, offset_m : Tensor (...)
            Position behind the occluder [m] (see ``Shadow.relative_illuminance``).
        sun_distance_m : float or Tensor (...), optional
            Sun–occluder distance [m] (> 0; default: the table's).
        wavelength_nm : Tensor (wavelength,), optional
            If given, must be the table's wavelengths (``ValueError`` otherwise).

        Returns
        -------
        Tensor (..., wavelength) or (..., *B, wavelength) for a batched table
        """
        dtype = common_dtype(distance_m, offset_m)
        distance = check_range("distance_m", distance_m, unit=" m", dtype=dtype)
        offset = check_range("offset_m", offset_m, 0.0, unit=" m", dtype=dtype)
        big_d = self.sun_distance_m if sun_distance_m is None else check_positive(
            "sun_distance_m", sun_distance_m, unit=" m", dtype=dtype)
        shapes = {"distance_m": distance, "offset_m": offset}
        if sun_distance_m is not None:
            shapes["sun_distance_m"] = big_d
        check_broadcastable(**shapes)
        if wavelength_nm is not None:
            self.check_compatible(wavelength_nm=wavelength_nm)
        angles = shadow_angles(distance, offset, big_d, self.sun_radius_m,
                               self.occluder_radius_m)
        with torch.no_grad():
            if bool((angles["centre_distance_m"] <= self.occluder_radius_m).any()):
                raise ValueError("point (distance_m, offset_m) inside the occluder or its "
                                 f"atmosphere (radius {self.occluder_radius_m:.6g} m); valid: "
                                 "farther from the centre")
        u, v = shadow_uv(angles["sun_radius_rad"], angles["occluder_radius_rad"],
                         angles["separation_rad"])
        # the table answers within the distances it was built for (u grows with the
        # distance), not beyond them: there its edge values would be returned. The slack,
        # 1e-4 of u, is what a lookup's own Sun distance moves u by against the table's
        # during an eclipse (parts in 1e5), not a distance beyond the table's
        low, high = float(self.u[0]), float(self.u[-1])
        with torch.no_grad():
            outside = (u < low * (1.0 - 1e-4)) | (u > high * (1.0 + 1e-4))
        if bool(outside.any()):
            span = (f"{self.attrs['min_distance_m']:.6g}..{self.attrs['max_distance_m']:.6g} m"
                    if "min_distance_m" in self.attrs else f"u {low:.6g}..{high:.6g}")
            first = outside.reshape(-1).nonzero()[0]
            got = float(torch.broadcast_to(distance, outside.shape).detach().reshape(-1)[first])
            raise ValueError(f"distance_m: a point lies outside the distances the table was "
                             f"built for ({span} behind the occluder; got {got:.6g} m): "
                             "compute a table for it, or use Shadow.relative_illuminance")
        return self.lookup_uv(u, v)

    forward = lookup

    def check_compatible(self, shadow=None, wavelength_nm=None) -> None:
        """Refuse (``ValueError``) a use the table was not built for.

        Parameters
        ----------
        shadow : Shadow, optional
            Must have the table's geometry (Sun distance and radius, top radius) and, when
            the table records one, the same settings and atmosphere
            (``provenance["shadow_sha256"]``).
        wavelength_nm : Tensor (wavelength,), optional
            Must equal the table's wavelengths (same count, equal to 1e-9 nm).
        """
        if wavelength_nm is not None:
            wavelength = check_finite("wavelength_nm", wavelength_nm,
                                      dtype=torch.float64).detach().reshape(-1)
            ours = self.wavelength_nm
            if wavelength.shape != ours.shape or not bool(
                    ((wavelength - ours).abs() <= 1e-9).all()):
                raise ValueError(
                    f"wavelength_nm: the table was built for {ours.tolist()} nm; got "
                    f"{wavelength.tolist()} nm (build a table for these wavelengths)")
        if shadow is not None:
            if not isinstance(shadow, (Shadow, ShadowMixture)):
                raise TypeError(f"shadow must be a skytorch.eclipse.Shadow or ShadowMixture; "
                                f"got {type(shadow).__name__}")
            geometry = {"sun_distance_m": (shadow.sun_distance_m, self.sun_distance_m),
                        "sun_radius_m": (shadow.sun_radius_m, self.sun_radius_m),
                        "top_radius_m": (shadow.top_radius_m, self.occluder_radius_m)}
            for name, (theirs, ours) in geometry.items():
                if abs(theirs - ours) > 1e-9 * abs(ours):
                    raise ValueError(f"shadow: the table was built for {name} {ours} m; "
                                     f"the shadow has {theirs} m")
            recorded = self.provenance.get("shadow_sha256")
            if recorded is not None and recorded != _shadow_hash(shadow):
                raise ValueError(
                    "shadow: the table was built for another shadow model or atmosphere "
                    f"(parameter hash {recorded[:12]}..., this one "
                    f"{_shadow_hash(shadow)[:12]}...): build a table for it")

    # ------------------------------------------------------------------ Dataset
    def to_dataset(self) -> xr.Dataset:
        """Return the table as a CF Dataset (dims u, v, [atmosphere_k ...,] wavelength).

        A table resolved in direction has the dimension ``position_angle`` [rad] instead.
        """
        resolved = self.position_angle_rad is not None
        batch_dims = (("position_angle",) if resolved
                      else tuple(f"atmosphere_{k}" for k in range(len(self.batch_shape))))
        data_vars = {"relative_illuminance": variable(("u", "v", *batch_dims, "wavelength"),
                                                      to_numpy(self.values),
                                                      _SPECS["relative_illuminance"])}
        positions = getattr(self, "_positions", None)
        if positions is not None:
            data_vars["distance"] = variable(("u", "v"), to_numpy(positions["distance_m"]),
                                             _SPECS["distance"])
            data_vars["offset"] = variable(("u", "v"), to_numpy(positions["offset_m"]),
                                           _SPECS["offset"])
        coords = {"u": coordinate("u", to_numpy(self.u), _SPECS["u"]),
                  "v": coordinate("v", to_numpy(self.v), _SPECS["v"]),
                  "wavelength": coordinate("wavelength", to_numpy(self.wavelength_nm),
                                           _SPECS["wavelength"])}
        if resolved:
            coords["position_angle"] = coordinate(
                "position_angle", to_numpy(self.position_angle_rad), VariableSpec(
                    "rad", "position angle around the shadow's axis",
                    "From the projection of the celestial pole; the limb's latitude depends "
                    "on its cosine only"))
        else:
            for dim, size in zip(batch_dims, self.batch_shape, strict=True):
                coords[dim] = coordinate(dim, np.arange(size), VariableSpec(
                    "1", "atmosphere batch index", f"Index of the atmosphere along {dim}"))
        parameters = dict(self.attrs)
        parameters.update({f"provenance_{key}": value for key, value in self.provenance.items()})
        parameters.update({"table_sun_distance_m": self.sun_distance_m,
                           "table_sun_radius_m": self.sun_radius_m,
                           "table_occluder_radius_m": self.occluder_radius_m,
                           "interpolation": self.interpolation})
        return build_dataset(data_vars, coords, title="Eclipse shadow look-up table",
                             references=_REFERENCES, parameters=parameters)

    @classmethod
    def from_dataset(cls, dataset: xr.Dataset) -> ShadowTable:  # noqa: C901 (flat checks)
        """Rebuild a table written by :meth:`to_dataset`."""
        if not isinstance(dataset, xr.Dataset):
            raise TypeError(f"dataset must be an xarray.Dataset; got {type(dataset).__name__}")
        attrs = dict(dataset.attrs)

        def number(key):
            for name in (key, f"parameter_{key}"):
                if name in attrs:
                    return float(attrs[name])
            raise ValueError(f"dataset lacks the attribute {key!r}")

        for name in ("u", "v", "wavelength", "relative_illuminance"):
            if name not in dataset.variables:
                raise ValueError(f"dataset lacks the variable {name!r} (not a shadow table)")
        interpolation = str(attrs.get("interpolation", attrs.get("parameter_interpolation",
                                                                 "log")))
        provenance = {}
        for key, value in attrs.items():
            for prefix in ("provenance_", "parameter_provenance_"):
                if key.startswith(prefix):
                    provenance[key[len(prefix):]] = value
        for key in ("n_u", "n_v"):
            if key in provenance:
                provenance[key] = int(provenance[key])
        # the table's settings (limb darkening and its law, distances, the shadow's), as
        # written in the "parameters" attribute: the look-ups and the light curves read them
        try:
            written = json.loads(attrs.get("parameters", "{}"))
        except (TypeError, ValueError):
            raise ValueError("dataset's 'parameters' attribute is not the JSON that "
                             "to_dataset writes") from None
        table_attrs = {key: value for key, value in written.items()
                       if not key.startswith(("provenance_", "table_"))
                       and key != "interpolation"}
        if "position_angle" in dataset.dims:
            table_attrs["position_angle_rad"] = dataset["position_angle"].values.tolist()
        return cls(np.array(dataset["u"].values), np.array(dataset["v"].values),
                   np.array(dataset["wavelength"].values),
                   np.array(dataset["relative_illuminance"].values),
                   sun_distance_m=number("table_sun_distance_m"),
                   sun_radius_m=number("table_sun_radius_m"),
                   occluder_radius_m=number("table_occluder_radius_m"),
                   interpolation=interpolation, provenance=provenance,
                   attrs=table_attrs or None)


def _is_terminal() -> bool:
    import sys

    return bool(getattr(sys.stderr, "isatty", lambda: False)())


def _uniform_grid(name: str, value, low: float, high: float) -> torch.Tensor:
    """Return a 1-D, uniform, increasing grid of at least two nodes within [low, high]."""
    grid = check_range(name, value, low, high, dtype=torch.float64)
    if grid.ndim != 1 or grid.shape[0] < 2:
        raise ValueError(f"{name} must be a 1-D grid of at least 2 nodes; got shape "
                         f"{tuple(grid.shape)}")
    step = grid[1:] - grid[:-1]
    if not bool((step > 0).all()) or float((step - step.mean()).abs().max()) > 1e-9 * float(
            grid[-1] - grid[0]):
        raise ValueError(f"{name} must be uniform and increasing (the look-up assumes equal "
                         "steps)")
    return grid


def _shadow_hash(shadow) -> str:
    """SHA-256 of every setting of a shadow model (its atmosphere's parameters included)."""
    text = json.dumps(shadow.parameters_dict(), sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def _provenance(shadow, n_u: int, n_v: int) -> dict:
    """Return what :meth:`ShadowTable.compute` built a table for."""
    record = {"shadow_sha256": _shadow_hash(shadow), "n_u": n_u, "n_v": n_v}
    if getattr(shadow, "atmosphere", None) is not None:
        from skytorch.atmosphere.tables import atmosphere_hash

        record["atmosphere_sha256"] = atmosphere_hash(shadow.atmosphere)
    return record
