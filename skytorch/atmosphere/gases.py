r"""Water vapour and oxygen absorption: band model with a curve of growth, O2–O2 CIA.

Band model (ref. 1, SPECTRL2; coefficients of Leckner, ref. 2): the absorption
coefficients :math:`a_w(\lambda)` of water vapour [cm^-1, per cm of precipitable
water] and :math:`a_u(\lambda)` of the uniformly mixed gases (the O2 A band at
762.5–767.5 nm and B band at 690 nm in 242–1100 nm) [cm^-1] are shipped as
SPECTRL2's 122-point table (``data/gas_absorption_bird1986.csv``, from pvlib 0.16.1,
BSD-3) and interpolated linearly in wavelength. **Spectral resolution: that of the
table**, points 2.5–50 nm apart in 242–1100 nm (690; 757.5, 762.5, 767.5; 905–965 nm
in 5–11 nm steps): the bands are triangles between table points, so a transmittance
at a wavelength between them is an interpolation of the model, not a line-by-line
value. Valid wavelengths: :data:`GAS_RANGE_NM` = 242–1100 nm (from the onset of O2's
Herzberg continuum; both coefficients are zero in 242–300 nm, below the table, where
neither gas has bands, to the O2–O2 table's upper end); outside, ``ValueError`` naming
``wavelength_nm`` (no clamp).

Curve of growth (ref. 1, eqs. 2-8 and 2-9) of the absorber amount along the actual path:

.. math::

    \tau_w = \frac{0.2385\, a_w u_w}{(1 + 20.07\, a_w u_w/\tilde p)^{0.45}},
    \qquad
    \tau_u = \frac{1.41\, a_u u_m}{(1 + 118.93\, a_u u_m/\tilde p)^{0.45}}

* In an :class:`~skytorch.atmosphere.Atmosphere` (species ``"h2o"``, ``"o2"``) the amounts
  are **pressure-scaled** path columns, :math:`u = \int n\,(p/p_0)^m\,ds / u_{ref}`
  with :math:`m` = :data:`PRESSURE_EXPONENT` = 0.5 and :math:`\tilde p = 1`;
  :math:`u_{ref}` makes the vertical path from sea level give ref. 1's amounts:
  :math:`u_w = W M` in cm of precipitable water and :math:`u_m = M p/p_0` in standard
  vertical columns (:data:`STANDARD_AIR_COLUMN_M2`). Both are integrals along the path
  the light takes (straight, slant or limb). Why 0.5: in the scaling approximation (refs.
  3, 4, ch. 6) the weak-line (linear) limit needs the unscaled amount (:math:`m = 0`) and
  the strong-Lorentz-line limit :math:`m = 1` (line width proportional to pressure); one
  column per species allows one exponent, and 0.5 is the midpoint (its effect on limb
  paths is measured in ``experiments/gas_resolution_accuracy_cost.py``: up to 3e-3 mag in
  V grazing at 5 km). Along sea-level paths :math:`m` hardly matters (the normalisation
  absorbs it).
* :func:`curve_of_growth` also takes :math:`\tilde p = \bar p / \bar p_{ref}`, the
  absorber-weighted (Curtis–Godson) mean pressure of the path over that of the reference
  path, refs. 3, 4, for use with unscaled amounts: linear in :math:`k u` in the weak
  limit, :math:`(k u)^{0.55}\,\tilde p^{0.45}` when saturated.
* The temperature dependence of the line widths and strengths is not modelled.
* 118.93 is the published constant of ref. 1; pvlib and NREL's ``spectrl2_2.c`` use
  118.3 (0.25 % in :math:`\tau_u` at 5 air masses in the A band).

O2–O2 collision-induced absorption (HITRAN, ref. 5): :math:`\tau = k(\lambda)
\int n_{O_2}^2\,ds` with the binary coefficient :math:`k` [m^5] (used in
amagat units, :func:`o2o2_coefficient`) shipped as 1 nm bin
means (``data/o2o2_cia_hitran.csv``; bands at 344–630, 690, 760, 920, 1065 nm, each
measured at 287–296 K; no temperature dependence is applied), zero below 336 nm,
where the HITRAN files end. Resolution: 1 nm.

Water vapour profile: :func:`water_vapour_density`, an exponential with scale height
:data:`WATER_VAPOUR_SCALE_HEIGHT_M` = 2 km (the standard water vapour profile of ref. 6),
normalised so that the vertical column from the ground is the precipitable water.
Oxygen: uniformly mixed, volume mixing ratio :data:`O2_VOLUME_MIXING_RATIO` (ref. 7).

References
----------
1. Bird, R. E. & Riordan, C. 1986, "Simple solar spectral model for direct and diffuse
   irradiance on horizontal and tilted planes at the Earth's surface for cloudless
   atmospheres", J. Clim. Appl. Meteorol. 25, 87,
   doi:10.1175/1520-0450(1986)025<0087:SSSMFD>2.0.CO;2.
2. Leckner, B. 1978, "The spectral distribution of solar radiation at the earth's
   surface – elements of a model", Sol. Energy 20, 143,
   doi:10.1016/0038-092X(78)90187-1.
3. Godson, W. L. 1953, "The evaluation of infra-red radiative fluxes due to atmospheric
   water vapour", Q. J. R. Meteorol. Soc. 79, 367, doi:10.1002/qj.49707934104.
4. Goody, R. M. & Yung, Y. L. 1989, "Atmospheric Radiation: Theoretical Basis", 2nd
   ed., Oxford University Press (ch. 6, inhomogeneous paths, scaling approximations).
5. Karman, T. et al. 2019, "Update of the HITRAN collision-induced absorption section",
   Icarus 328, 160, doi:10.1016/j.icarus.2019.02.034.
6. ITU-R Recommendation P.835, "Reference standard atmospheres" (standard water vapour
   density profile, exponential with a 2 km scale height).
7. NOAA/NASA/USAF 1976, "U.S. Standard Atmosphere, 1976", NOAA-S/T 76-1562 (O2 volume
   fraction 0.20946).

Examples
--------
>>> import torch
>>> from skytorch.atmosphere.gases import (mixed_gas_optical_depth,
...                                        water_vapour_optical_depth)
>>> wl = torch.tensor([690.0, 762.5, 937.0], dtype=torch.float64)
>>> mixed_gas_optical_depth(wl, air_path=1.0).round(decimals=4)  # one standard vertical column
tensor([0.0564, 0.3516, 0.0000], dtype=torch.float64)
>>> water_vapour_optical_depth(wl, water_path_cm=1.4).round(decimals=5)   # 0.674195 at 937 nm
tensor([0.0045, 0.0000, 0.6742], dtype=torch.float64)
"""

from __future__ import annotations

import dataclasses
from functools import lru_cache

import numpy as np
import torch

from skytorch._data import data_path
from skytorch._validate import as_tensor, check_broadcastable, check_range
from skytorch.atmosphere import ozone as _ozone
from skytorch.atmosphere import profiles as _profiles
from skytorch.atmosphere.constituents import Profile, Species, SpeciesBuilder, insert_dims
from skytorch.constants import LOSCHMIDT_PER_M3

__all__ = [
    "CIA_TABLE", "GAS_RANGE_NM", "GAS_TABLE", "MIXED_GAS_CURVE", "O2_VOLUME_MIXING_RATIO",
    "PRECIPITABLE_WATER_CM_PER_M2", "PRECIPITABLE_WATER_RANGE_CM", "WATER_CURVE",
    "WATER_VAPOUR_SCALE_HEIGHT_M", "bird_coefficients", "curve_of_growth",
    "mixed_gas_optical_depth", "o2o2_coefficient", "o2o2_optical_depth",
    "water_vapour_density", "water_vapour_optical_depth",
]

#: shipped tables (``data/``)
GAS_TABLE = "gas_absorption_bird1986.csv"
CIA_TABLE = "o2o2_cia_hitran.csv"
#: wavelengths covered [nm]: down to the onset of O2's Herzberg continuum (242 nm; the
#: band coefficients are zero in 242-300 nm, below SPECTRL2's table, where neither gas
#: has bands), up to the end of the O2-O2 table (1100 nm; the 1.27 um band follows)
GAS_RANGE_NM = (242.0, 1100.0)
#: accepted precipitable water [cm] (observed columns stay below ~7 cm)
PRECIPITABLE_WATER_RANGE_CM = (0.0, 10.0)
#: default precipitable water of :meth:`skytorch.atmosphere.Atmosphere.earth` [cm]
DEFAULT_PRECIPITABLE_WATER_CM = 1.4
#: water vapour scale height [m] (ref. 6)
WATER_VAPOUR_SCALE_HEIGHT_M = 2000.0
#: O2 volume mixing ratio in dry air (U.S. Standard Atmosphere 1976, 0.20946)
O2_VOLUME_MIXING_RATIO = 0.2095
#: molecules of H2O per m^2 in 1 cm of precipitable water: 10 kg m^-2 / 18.015 g/mol
PRECIPITABLE_WATER_CM_PER_M2 = 10.0 / 18.01528e-3 * 6.02214076e23
#: (numerator, saturation, exponent) of Bird & Riordan's eq. 2-8 (water vapour)
WATER_CURVE = (0.2385, 20.07, 0.45)
#: (numerator, saturation, exponent) of Bird & Riordan's eq. 2-9 (uniformly mixed gases)
MIXED_GAS_CURVE = (1.41, 118.93, 0.45)


def _read(name: str) -> np.ndarray:
    path = data_path(name)
    with open(path, encoding="utf-8") as handle:
        header = sum(1 for line in handle if line.startswith("#"))
    return np.loadtxt(path, delimiter=",", skiprows=header + 1)


@lru_cache(maxsize=1)
def _bird_table() -> np.ndarray:
    """Rows (wavelength [nm], a_w [cm^-1], a_u [cm^-1]) of SPECTRL2's table."""
    table = _read(GAS_TABLE)
    if table.shape != (122, 4) or not np.all(np.diff(table[:, 0]) > 0):
        raise ValueError(f"{GAS_TABLE} is not SPECTRL2's 122-row table")
    return np.ascontiguousarray(table[:, :3])


@lru_cache(maxsize=1)
def _cia_table() -> np.ndarray:
    table = _read(CIA_TABLE)
    if not (np.all(np.diff(table[:, 0]) == 1.0) and table[-1, 0] == GAS_RANGE_NM[1]):
        raise ValueError(f"{CIA_TABLE} is not on a 1 nm grid ending at 1100 nm")
    return np.ascontiguousarray(table)


@lru_cache(maxsize=4)
def _tensor(name: str, dtype: torch.dtype) -> tuple[torch.Tensor, ...]:
    """Contiguous columns of a table.

    ``"bird"`` (wavelength, a_w, a_u), ``"cia"`` (wavelength, k [m^-1 amagat^-2], converted from m^5
    in float64).
    """
    if name == "bird":
        table = _bird_table()
    else:
        table = _cia_table().copy()
        table[:, 1] *= LOSCHMIDT_PER_M3 ** 2
    return tuple(torch.as_tensor(np.ascontiguousarray(column), dtype=dtype)
                 for column in table.T)


def _check_wavelength(wavelength_nm) -> torch.Tensor:
    return _ozone.check_wavelength_range(wavelength_nm, GAS_RANGE_NM,
                                         "the shipped water vapour, O2 and O2-O2 tables")


def _interp(x: torch.Tensor, xp: torch.Tensor, fp: torch.Tensor) -> torch.Tensor:
    """Piecewise-linear interpolation (``x`` inside ``xp``; differentiable in ``x``)."""
    i = torch.clamp(torch.searchsorted(xp, x.detach().contiguous(), right=True) - 1, 0,
                    xp.numel() - 2)
    x0, x1 = xp[i], xp[i + 1]
    u = (x - x0) / (x1 - x0)
    return fp[i] * (1.0 - u) + fp[i + 1] * u


def bird_coefficients(wavelength_nm) -> tuple[torch.Tensor, torch.Tensor]:
    """SPECTRL2 absorption coefficients of water vapour and the mixed gases [cm^-1].

    Parameters
    ----------
    wavelength_nm : Tensor (...)
        Wavelength [nm], in :data:`GAS_RANGE_NM` = [242, 1100] nm.

    Returns
    -------
    a_w, a_u : Tensor (...)
        Water vapour coefficient [cm^-1, per cm of precipitable water] and mixed-gas
        coefficient [cm^-1], linear between the table's points (module docstring).

    Raises
    ------
    ValueError
        A wavelength outside 242–1100 nm, NaN or inf.

    Examples
    --------
    >>> import torch
    >>> a_w, a_u = bird_coefficients(torch.tensor([762.5, 765.0]))
    >>> a_u
    tensor([4.0000, 2.1750])
    """
    wavelength = _check_wavelength(wavelength_nm)
    grid, a_w, a_u = _tensor("bird", wavelength.dtype)
    below = wavelength < grid[0]
    inside = torch.where(below, grid[0], wavelength)
    zero = torch.zeros_like(wavelength)
    return (torch.where(below, zero, _interp(inside, grid, a_w)),
            torch.where(below, zero, _interp(inside, grid, a_u)))


def o2o2_coefficient(wavelength_nm) -> torch.Tensor:
    """HITRAN O2–O2 absorption coefficient [m^-1 amagat^-2], 242–1100 nm.

    Parameters
    ----------
    wavelength_nm : Tensor (...)
        Vacuum wavelength [nm], in [242, 1100] nm.

    Returns
    -------
    Tensor (...)
        The 1 nm bin means of the binary coefficient [m^5 molecule^-2] times the
        square of the Loschmidt number :math:`L` = 2.6868e25 m^-3 (1 amagat; so that
        float32 holds it), interpolated linearly; zero below 336 nm (no HITRAN data).

    Examples
    --------
    >>> import torch
    >>> o2o2_coefficient(torch.tensor([477.0, 577.0, 1065.0]))   # [m^-1 amagat^-2]
    tensor([4.7197e-05, 8.0027e-05, 9.7923e-05])
    """
    wavelength = _check_wavelength(wavelength_nm)
    grid, k = _tensor("cia", wavelength.dtype)
    below = wavelength < grid[0]
    inside = torch.where(below, grid[0], wavelength)
    return torch.where(below, torch.zeros_like(wavelength), _interp(inside, grid, k))


def curve_of_growth(coefficient, amount, pressure_ratio=1.0, *, curve=WATER_CURVE
                    ) -> torch.Tensor:
    r"""Band optical depth :math:`A k u/(1 + C k u/\tilde p)^a` (module docstring).

    Parameters
    ----------
    coefficient : Tensor (...)
        Band coefficient :math:`k` [1 per unit of ``amount``], ``>= 0``.
    amount : float or Tensor (...)
        Absorber amount along the path :math:`u`, ``>= 0``.
    pressure_ratio : float or Tensor (...)
        Curtis–Godson mean pressure of the path over that of the reference path
        :math:`\tilde p`, ``> 0`` (1: Bird & Riordan's law).
    curve : tuple of float
        :math:`(A, C, a)`: :data:`WATER_CURVE` or :data:`MIXED_GAS_CURVE`.

    Returns
    -------
    Tensor (broadcast of the inputs)
        Optical depth [1].
    """
    k = check_range("coefficient", coefficient, low=0.0)
    u = check_range("amount", as_tensor("amount", amount, dtype=k.dtype), low=0.0)
    p = check_range("pressure_ratio", as_tensor("pressure_ratio", pressure_ratio,
                                                dtype=k.dtype), low=0.0, low_inclusive=False)
    check_broadcastable(coefficient=k, amount=u, pressure_ratio=p)
    return _curve_of_growth(k, u, p, curve)


def _curve_of_growth(k: torch.Tensor, u: torch.Tensor, p, curve) -> torch.Tensor:
    """:func:`curve_of_growth` of checked inputs (the kernel of the band species' laws)."""
    scale, saturation, exponent = curve
    x = k * u
    # the fresh temporaries updated in place (autograd keeps what the backward needs)
    base = saturation * x / p if isinstance(p, torch.Tensor) else x * (saturation / p)
    return base.add_(1.0).pow_(-exponent).mul_(x).mul_(scale)


def water_vapour_optical_depth(wavelength_nm, water_path_cm, pressure_ratio=1.0
                               ) -> torch.Tensor:
    r"""Water vapour band optical depth (Bird & Riordan eq. 2-8, Curtis–Godson).

    Parameters
    ----------
    wavelength_nm : Tensor (wavelength,) or (..., wavelength)
        Wavelength [nm], in [242, 1100] nm.
    water_path_cm : float or Tensor (...)
        Precipitable water along the path [cm] (:math:`W M`), ``>= 0``; broadcasts
        against ``wavelength_nm[..., None]``-style shapes by torch rules (give a trailing
        singleton dimension to sweep a batch against a spectrum).
    pressure_ratio : float or Tensor
        :math:`\tilde p_w` (module docstring), ``> 0``.

    Returns
    -------
    Tensor (broadcast)
        Optical depth [1].
    """
    a_w, _ = bird_coefficients(wavelength_nm)
    return curve_of_growth(a_w, water_path_cm, pressure_ratio, curve=WATER_CURVE)


def mixed_gas_optical_depth(wavelength_nm, air_path, pressure_ratio=1.0) -> torch.Tensor:
    r"""Uniformly mixed gas (O2) band optical depth (Bird & Riordan eq. 2-9, Curtis–Godson).

    Parameters
    ----------
    wavelength_nm : Tensor
        Wavelength [nm], in [242, 1100] nm.
    air_path : float or Tensor
        Air along the path in standard vertical columns (:math:`M p/p_0`), ``>= 0``.
    pressure_ratio : float or Tensor
        :math:`\tilde p_m` (module docstring), ``> 0``.

    Returns
    -------
    Tensor (broadcast)
        Optical depth [1].
    """
    _, a_u = bird_coefficients(wavelength_nm)
    return curve_of_growth(a_u, air_path, pressure_ratio, curve=MIXED_GAS_CURVE)


def o2o2_optical_depth(wavelength_nm, o2_squared_path) -> torch.Tensor:
    r"""O2–O2 collision-induced optical depth :math:`k(\lambda) \int (n_{O_2}/L)^2 ds`.

    Parameters
    ----------
    wavelength_nm : Tensor
        Wavelength [nm], in [242, 1100] nm.
    o2_squared_path : float or Tensor
        :math:`\int (n_{O_2}/L)^2\,ds` [amagat^2 m], ``>= 0`` (about 160 for the
        vertical path from sea level).

    Returns
    -------
    Tensor (broadcast)
        Optical depth [1].
    """
    k = o2o2_coefficient(wavelength_nm)
    path = check_range("o2_squared_path",
                       as_tensor("o2_squared_path", o2_squared_path, dtype=k.dtype),
                       low=0.0, unit=" amagat^2 m")
    check_broadcastable(wavelength_nm=k, o2_squared_path=path)
    return k * path


def water_vapour_density(altitude_m, scale_height_m=WATER_VAPOUR_SCALE_HEIGHT_M
                         ) -> torch.Tensor:
    r"""Relative water vapour density :math:`\exp(-h/H_w)` [1].

    Parameters
    ----------
    altitude_m : Tensor (...)
        Altitude above the ground [m].
    scale_height_m : float or Tensor
        :math:`H_w` [m] (default 2 km, ref. 6), ``> 0``.

    Returns
    -------
    Tensor (...)
        Density relative to the ground; its vertical integral from the ground is
        :math:`H_w`, so the number density is ``W * PRECIPITABLE_WATER_CM_PER_M2 / H_w``
        times it for a precipitable water ``W`` [cm].
    """
    altitude = as_tensor("altitude_m", altitude_m)
    height = check_range("scale_height_m", scale_height_m, low=0.0, low_inclusive=False,
                         unit=" m")
    return torch.exp(-altitude / height.to(altitude.dtype))


# ---------------------------------------------------------------------- Atmosphere species
# Builders of the species "h2o", "o2" and "o2o2" for skytorch.atmosphere.model
# (skytorch.atmosphere.constituents, "Adding a species"). Each species' path column is the
# integral of its profile along the path; the band laws turn it into the scaled absorber
# amount of the module docstring and apply the curve of growth.

#: names of the species defined here, in output order
GAS_SPECIES = ("h2o", "o2", "o2o2")
#: pressure-scaling exponent m of the absorber amounts u = int n (p/p0)^m ds / u_ref
PRESSURE_EXPONENT = 0.5
#: levels of the exponential quadrature pieces above a leg's lowest point, in scale heights
_LEVELS = (0.5, 1.5, 4.0, 10.0, 30.0)
#: quadrature levels of the US 1976 profile [m] (its layer bases and, below the first, the
#: levels that resolve the decay near the ground)
_US1976_LEVELS_M = (1000.0, 2000.0, 4000.0, 8000.0, *_profiles.US1976_KINK_ALTITUDES_M)
#: sea-level temperature of the U.S. Standard Atmosphere 1976 [K]
_US1976_T0_K = 288.15
#: standard vertical column of air: p0 N_A / (M g0) with 101325 Pa, Bodhaine's dry air
#: with 360 ppm CO2 (28.9649 g/mol) and g0 = 9.80616 m s^-2 [m^-2]
STANDARD_AIR_COLUMN_M2 = 101325.0 * 6.02214076e23 / (28.9649e-3 * 9.80616)


def _us1976_pressure_ratio(altitude_m: torch.Tensor) -> torch.Tensor:
    """p(h)/p(0) of the U.S. Standard Atmosphere 1976: density ratio times T/T0 [1]."""
    return _profiles.us1976(altitude_m) * _profiles.us1976_temperature(
        torch.clamp(altitude_m, min=0.0)) / _US1976_T0_K


def _exponential_water(altitude_m, scale_height_m, air_scale_height_m, exponent):
    return torch.exp(-altitude_m / scale_height_m - exponent * altitude_m / air_scale_height_m)


def _us1976_water(altitude_m, scale_height_m, exponent):
    return torch.exp(-altitude_m / scale_height_m) * _us1976_pressure_ratio(altitude_m) ** exponent


def _exponential_air(altitude_m, air_scale_height_m, power):
    return torch.exp(-power * altitude_m / air_scale_height_m)


def _us1976_air(altitude_m, exponent, power):
    return _profiles.us1976(altitude_m) ** power * _us1976_pressure_ratio(altitude_m) ** exponent


@lru_cache(maxsize=16)
def _us1976_column_height(kind: str, exponent: float, top_m: float) -> float:
    """Vertical integral [m] of a US 1976 profile from the ground to ``top_m``.

    Trapezoid, 1 m steps below 20 km, 10 m above.
    """
    low = torch.arange(0.0, min(top_m, 20e3) + 0.5, 1.0, dtype=torch.float64)
    high = torch.arange(20e3, max(top_m, 20e3) + 5.0, 10.0, dtype=torch.float64)
    total = 0.0
    for h in (low, high):
        if h.numel() < 2:
            continue
        if kind == "h2o":
            f = _us1976_water(h, WATER_VAPOUR_SCALE_HEIGHT_M, exponent)
        elif kind == "o2":
            f = _us1976_air(h, exponent, 1.0)
        else:
            f = _us1976_air(h, 0.0, 2.0)
        total += float(torch.trapezoid(f, h))
    return total


def _air_shape(atm) -> str:
    shape = atm.molecule_profile
    if shape not in ("exponential", "us1976", "sounding"):
        raise ValueError(f"the gas species support the molecule profiles 'exponential', "
                         f"'us1976' and 'sounding'; got {shape!r}")
    return shape


def _sounding_air(atm, dtype):
    """Return the sounding's air density and pressure relative to 0 m.

    As functions of altitude (log-linear between its levels, continued above with the top layer's
    scale height), and its levels inside the atmosphere.
    """
    sounding = atm.sounding
    nodes = sounding["altitude_m"].to(torch.float64)
    zero = torch.zeros((), dtype=torch.float64)
    logs = []
    for key in ("number_density_m3", "pressure_pa"):
        log_value = torch.log(sounding[key].to(torch.float64))
        logs.append((log_value - torch.log(_profiles.log_linear(zero, nodes, log_value))
                     ).to(dtype))
    nodes_d = nodes.to(dtype)
    levels = nodes_d[(nodes > 0.0) & (nodes < atm.top_altitude_m)]

    def density(altitude_m):
        return _profiles.log_linear(altitude_m, nodes_d, logs[0])

    def pressure(altitude_m):
        return _profiles.log_linear(altitude_m, nodes_d, logs[1])

    return density, pressure, levels


def _vertical_integral(function, top_m: float, dtype) -> torch.Tensor:
    r""":math:`\int_0^{top} f(h)\,dh` [m] by the trapezoid rule (1 m steps below 20 km, 10 m above).

    In float64, cast to ``dtype``.
    """
    low = torch.arange(0.0, min(top_m, 20e3) + 0.5, 1.0, dtype=torch.float64)
    pieces = [low]
    if top_m > 20e3:
        pieces.append(torch.linspace(20e3, top_m, int((top_m - 20e3) / 10.0) + 1,
                                     dtype=torch.float64))
    return sum(torch.trapezoid(function(h), h) for h in pieces).to(dtype)


def _sounding_water_profile(atm, dtype, m: float):
    """Return the h2o profile of a sounding.

    Its h2o_vmr shape (or the 2 km exponential without one) times (p/p_s)^m.
    """
    _, pressure, levels = _sounding_air(atm, torch.float64)
    given = atm.water_vapour_profile(torch.float64)
    if given is None:
        def shape(h):
            return torch.exp(-h / WATER_VAPOUR_SCALE_HEIGHT_M)
        breaks = torch.cat([levels, WATER_VAPOUR_SCALE_HEIGHT_M * torch.tensor(
            _LEVELS, dtype=torch.float64)]).sort().values
        support = False
    else:
        shape = given.function
        breaks = given.breakpoints_m.to(torch.float64)
        support = given.support

    def wide(h):
        return shape(h) * pressure(h) ** m

    column = _vertical_integral(wide, atm.top_altitude_m, dtype)

    def density(altitude_m):
        return wide(altitude_m.to(torch.float64)).to(altitude_m.dtype)

    return Profile(density, {}, column, breakpoints_m=breaks.to(dtype), support=support)


def water_vapour_profile(atm, dtype: torch.dtype, exponent: float = PRESSURE_EXPONENT):
    """:class:`~skytorch.atmosphere.constituents.Profile` of ``"h2o"``.

    The water vapour density times :math:`(p/p_s)^m` (``exponent``, default
    :data:`PRESSURE_EXPONENT`), relative to the ground.
    """
    m = float(exponent)
    height_w = torch.tensor(WATER_VAPOUR_SCALE_HEIGHT_M, dtype=dtype)
    if _air_shape(atm) == "sounding":
        return _sounding_water_profile(atm, dtype, m)
    if _air_shape(atm) == "us1976":
        # the levels of the air (the standard's layer boundaries, where (p/p_s)^m has kinks,
        # and 1, 2, 4, 8 km): integrated on the air's nodes with its state. Against
        # converged columns (50 000 random rays from 0-120 km, columns > 1 m): 8.5e-9
        # relative from below 5 km, 1.2e-6 from 5-20 km, 9.2e-6 from higher up looking
        # down; levels in water scale heights from each leg's base gave 7.1e-7, 1.3e-6
        # and 4.8e-7; the largest absolute error fell from 1.7e-2 m to 6.7e-4 m
        column = _us1976_column_height("h2o", m, atm.top_altitude_m)
        return Profile(_us1976_water, {"scale_height_m": height_w,
                                       "exponent": torch.tensor(m, dtype=dtype)},
                       torch.tensor(column, dtype=dtype),
                       breakpoints_m=torch.tensor(_US1976_LEVELS_M, dtype=dtype),
                       state=_profiles.us1976_state,
                       from_state=_profiles.us1976_water_from_state, piecewise_state=True)
    air = atm.rayleigh_scale_height_m.to(dtype)
    scale = 1.0 / (1.0 / height_w + m / air)
    return Profile(_exponential_water, {"scale_height_m": height_w + 0.0 * air,
                                        "air_scale_height_m": air,
                                        "exponent": torch.tensor(m, dtype=dtype)},
                   scale, relative_breakpoints_m=scale[..., None]
                   * torch.tensor(_LEVELS, dtype=dtype), truncate=True)


def _air_profile(atm, dtype: torch.dtype, exponent: float, power: float):
    if _air_shape(atm) == "sounding":
        density, pressure, levels = _sounding_air(atm, dtype)

        def function(altitude_m):
            return density(altitude_m) ** power * pressure(altitude_m) ** exponent

        wide_density, wide_pressure, _ = _sounding_air(atm, torch.float64)
        column = _vertical_integral(
            lambda h: wide_density(h) ** power * wide_pressure(h) ** exponent,
            atm.top_altitude_m, dtype)
        return Profile(function, {}, column, breakpoints_m=levels)
    if _air_shape(atm) == "us1976":
        kind = "o2" if power == 1.0 else "o2o2"
        column = _us1976_column_height(kind, exponent, atm.top_altitude_m)
        return Profile(_us1976_air, {"exponent": torch.tensor(exponent, dtype=dtype),
                                     "power": torch.tensor(power, dtype=dtype)},
                       torch.tensor(column, dtype=dtype),
                       breakpoints_m=torch.tensor(_US1976_LEVELS_M, dtype=dtype),
                       state=_profiles.us1976_state,
                       from_state=_profiles.us1976_air_from_state, piecewise_state=True)
    air = atm.rayleigh_scale_height_m.to(dtype)
    rate = power + exponent
    height = air / rate
    return Profile(_exponential_air, {"air_scale_height_m": air,
                                      "power": torch.tensor(rate, dtype=dtype)},
                   height, relative_breakpoints_m=height[..., None]
                   * torch.tensor(_LEVELS, dtype=dtype), truncate=True)


def oxygen_profile(atm, dtype: torch.dtype, exponent: float = PRESSURE_EXPONENT):
    """Profile of ``"o2"``: the air density times :math:`(p/p_s)^m`."""
    return _air_profile(atm, dtype, float(exponent), 1.0)


def o2o2_profile(atm, dtype: torch.dtype):
    """Profile of ``"o2o2"``: the square of the air density (relative to the ground)."""
    return _air_profile(atm, dtype, 0.0, 2.0)


def _pressure_factor(atm, dtype, exponent: float) -> torch.Tensor:
    return (atm.surface_pressure_pa.to(dtype) / 101325.0) ** exponent


def water_vapour_species(atm, wavelength_nm, dtype, profile, exponent: float = PRESSURE_EXPONENT,
                         name: str = "h2o"):
    r"""Return the species ``"h2o"``: the curve of growth of eq. 2-8.

    Of the scaled water amount :math:`u_w = W (p_s/p_0)^m \int\rho\,ds / \int\rho\,dz` [cm].
    """
    water = atm.precipitable_water_cm.to(dtype)
    if _water_absent(atm):
        a_w = torch.zeros_like(wavelength_nm)
    else:
        a_w, _ = bird_coefficients(wavelength_nm)
    per_m = water * _pressure_factor(atm, dtype, float(exponent)) / profile.column_height_m
    law, indices = _band_law(a_w, per_m, WATER_CURVE)
    return Species(name, profile, torch.zeros_like(per_m[..., None] * a_w), law=law,
                   law_indices=indices)


def oxygen_species(atm, wavelength_nm, dtype, profile, exponent: float = PRESSURE_EXPONENT,
                   name: str = "o2"):
    r"""Return the species ``"o2"``: the curve of growth of eq. 2-9.

    Of the scaled air amount :math:`u_m = (N/N_0)(p_s/p_0)^m \int\rho\,ds / \int\rho\,dz`
    [standard columns].
    """
    if _oxygen_absent(atm):
        a_u = torch.zeros_like(wavelength_nm)
    else:
        _, a_u = bird_coefficients(wavelength_nm)
    # formed in float64 and cast: p N_A / (M g) alone overflows float32 at the edge of the
    # parameter ranges (the ratio does not)
    columns = (atm.molecular_column_m2(torch.float64) / STANDARD_AIR_COLUMN_M2).to(dtype)
    per_m = columns * _pressure_factor(atm, dtype, float(exponent)) / profile.column_height_m
    law, indices = _band_law(a_u, per_m, MIXED_GAS_CURVE)
    return Species(name, profile, torch.zeros_like(per_m[..., None] * a_u), law=law,
                   law_indices=indices)


def _band_law(coefficient, per_m, curve):
    """Return the optical-depth law of a band species and its band's wavelength indices.

    The law is the curve of growth of the amount ``column * per_m``, evaluated at the
    wavelengths inside the band only (where the band coefficient is zero the optical
    depth is exactly zero); the indices are ``None`` where the band covers every
    wavelength.
    """
    inside = torch.nonzero(coefficient > 0).reshape(-1)
    everywhere = inside.numel() == coefficient.numel()
    band = coefficient if everywhere else coefficient[inside]

    def law(column, extra):
        amount = (column * insert_dims(per_m, extra, 0))[..., None]
        # amounts are path columns (>= 0 by construction), the band coefficients > 0
        return _curve_of_growth(band, amount, 1.0, curve)

    return law, None if everywhere else inside


def o2o2_species(atm, wavelength_nm, dtype, profile):
    r"""Species ``"o2o2"`` (linear).

    :math:`k\,(n_{O_2}(0)/L)^2` times the path column of the squared relative density [1/m].
    """
    wide = wavelength_nm.to(torch.float64)
    column = atm.molecular_column_m2(torch.float64)
    shape = _air_shape(atm)
    if shape == "sounding":
        height = _air_profile(atm, torch.float64, 0.0, 1.0).column_height_m
    elif shape == "us1976":
        height = torch.tensor(_us1976_column_height("o2", 0.0, atm.top_altitude_m),
                              dtype=torch.float64)
    else:
        height = atm.rayleigh_scale_height_m.to(torch.float64)
    ground = O2_VOLUME_MIXING_RATIO * column / height / LOSCHMIDT_PER_M3  # [amagat]
    k = torch.zeros_like(wide) if _oxygen_absent(atm) else o2o2_coefficient(wide)
    return Species("o2o2", profile, ((ground ** 2)[..., None] * k).to(dtype))


def _water_absent(atm) -> bool:
    water = atm.precipitable_water_cm
    return not water.requires_grad and not bool(water.detach().any())


def _oxygen_absent(atm) -> bool:
    """No O2 outside an Earth-like ("air") atmosphere."""
    return atm.gas != "air"


def species_builders(exponent: float = PRESSURE_EXPONENT, suffix: str = "") -> tuple:
    """Return the species builders of :data:`GAS_SPECIES`, in order.

    One :class:`~skytorch.atmosphere.constituents.SpeciesBuilder` per species.

    Parameters
    ----------
    exponent : float
        Pressure-scaling exponent :math:`m` of the h2o and o2 amounts (default
        :data:`PRESSURE_EXPONENT`; other values for sensitivity studies, as
        ``extra_species``).
    suffix : str
        Appended to the species names (``extra_species`` need names of their own).
    """
    m = float(exponent)

    def profile_of(function):
        return lambda atm, dtype: function(atm, dtype, m)

    def species_of(function, name):
        return lambda atm, wavelength, dtype, profile: function(atm, wavelength, dtype, profile,
                                                                m, name)

    return (SpeciesBuilder("h2o" + suffix, profile_of(water_vapour_profile),
                           species_of(water_vapour_species, "h2o" + suffix),
                           absent=_water_absent),
            SpeciesBuilder("o2" + suffix, profile_of(oxygen_profile),
                           species_of(oxygen_species, "o2" + suffix), absent=_oxygen_absent),
            SpeciesBuilder("o2o2" + suffix, o2o2_profile,
                           lambda atm, wavelength, dtype, profile: dataclasses.replace(
                               o2o2_species(atm, wavelength, dtype, profile),
                               name="o2o2" + suffix), absent=_oxygen_absent))
