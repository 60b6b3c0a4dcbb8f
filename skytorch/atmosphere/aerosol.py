r"""Aerosol optical properties.

Ångström law, Preetham turbidity, Mars dust, the stratospheric sulfate layer and named aerosol types
with Mie optics.

The aerosol optical depth follows the Ångström law
:math:`\tau_a(\lambda) = \beta (\lambda / 1\,\mu m)^{-\alpha}` (ref. 1). From
Preetham's turbidity :math:`T` (ref. 2): :math:`\beta = 0.04608 T - 0.04586`,
:math:`\alpha = 1.3`; :math:`T = 1` is (nearly) aerosol-free (:math:`\beta = 2.2\times
10^{-4}`, :math:`\tau_a(550) = 5\times10^{-4}`); :math:`\beta` is clamped at zero.

References
----------
1. Ångström, A. 1929, "On the atmospheric transmission of sun radiation and on dust in
   the air", Geogr. Ann. 11, 156, doi:10.1080/20014422.1929.11880498.
2. Preetham, A. J., Shirley, P. & Smits, B. 1999, "A practical analytic model for
   daylight", Proc. SIGGRAPH 99, 91, doi:10.1145/311535.311545.
3. Lemmon, M. T. et al. 2015, "Dust aerosol, clouds, and the atmospheric optical depth
   record over 5 Mars years of the Mars Exploration Rover mission", Icarus 251, 96,
   doi:10.1016/j.icarus.2014.03.029.
4. Tomasko, M. G. et al. 1999, "Properties of dust in the Martian atmosphere from the
   Imager on Mars Pathfinder", J. Geophys. Res. 104, 8987, doi:10.1029/1998JE900016.
5. Deshler, T. et al. 2003, "Thirty years of in situ stratospheric aerosol size
   distribution measurements from Laramie, Wyoming (41°N), using balloon-borne
   instruments", J. Geophys. Res. 108(D5), 4167, doi:10.1029/2002JD002514.
6. Palmer, K. F. & Williams, D. 1975, "Optical constants of sulfuric acid; application
   to the clouds of Venus?", Appl. Opt. 14, 208, doi:10.1364/AO.14.000208.
7. Henyey, L. G. & Greenstein, J. L. 1941, "Diffuse radiation in the Galaxy", ApJ 93,
   70, doi:10.1086/144246.
8. Hess, M., Koepke, P. & Schult, I. 1998, "Optical Properties of Aerosols and Clouds:
   The Software Package OPAC", Bull. Am. Meteorol. Soc. 79, 831,
   doi:10.1175/1520-0477(1998)079<0831:OPOAAC>2.0.CO;2.
9. Wolff, M. J. et al. 2009, "Wavelength dependence of dust aerosol single scattering
   albedo as observed by the Compact Reconnaissance Imaging Spectrometer", J. Geophys.
   Res. 114, E00D04, doi:10.1029/2009JE003350.
10. Shettle, E. P. & Fenn, R. W. 1979, "Models for the Aerosols of the Lower Atmosphere
    and the Effects of Humidity Variations on their Optical Properties", AFGL-TR-79-0214;
    the stratospheric profiles as tabulated in LOWTRAN 7: Kneizys, F. X. et al. 1988,
    "Users Guide to LOWTRAN 7", AFGL-TR-88-0177.

Stratospheric sulfate layer
---------------------------
Droplets of 75 % H2SO4 (refractive index 1.43 + 1e-8 i, ref. 6) with a lognormal size
distribution (median radius 0.08 um, geometric standard deviation 1.8; ref. 5): the
extinction relative to 550 nm, the single-scattering albedo and the asymmetry parameter
come from Mie theory, tabulated 230–1690 nm in ``data/aerosol_mie_sulfate.csv``
(generator: ``data/make_aerosol_tables.py``) and interpolated linearly; the phase
function is Henyey–Greenstein (ref. 7) with the tabulated asymmetry. The vertical profile
is a Gaussian in altitude, :func:`gaussian_layer`, whose integral from the ground to the
top of the atmosphere is :func:`gaussian_layer_column` (closed form with erf), or one of
the LOWTRAN 7 stratospheric models of ref. 10 (:func:`stratospheric_profile_shape`:
background, moderate, high and extreme volcanic, 11-30 km, spring-summer, fall-winter or
their mean), whose 550 nm extinction is tabulated in
``data/stratospheric_aerosol_lowtran7.csv``.

Aerosol types
-------------
:func:`aerosol_type_properties` gives, for a name of :data:`AEROSOL_TYPES` (aliases
``continental``, ``maritime``, ``mineral_dust``), the extinction relative to 550 nm, the
single-scattering albedo and the asymmetry from Mie theory: ``sulfate`` is the table
above, the others the OPAC types (ref. 8): continental clean / average / polluted,
urban, desert, maritime clean / polluted / tropical, arctic, antarctic — external
mixtures of OPAC's lognormal components at 80 % relative humidity with OPAC's refractive
indices, tabulated 250–2000 nm every 10 nm. The phase function to use with them is
Henyey–Greenstein with the tabulated g. The 550 nm optical depth is not part of a type.

Mars dust
---------
:func:`mars_dust_properties`: the single-scattering albedo of Martian dust falls from
0.97 in the red to 0.75 at 400 nm and 0.63 at 263 nm (spheres of the Wolff et al. 2009
refractive index, r_eff = 1.5 um, v_eff = 0.3; ref. 9).

Examples
--------
>>> from skytorch.atmosphere.aerosol import preetham_angstrom_beta
>>> round(float(preetham_angstrom_beta(2.0)), 5)
0.0463
>>> ratio, albedo, g = sulfate_mie_properties(torch.tensor([550.0, 1000.0]))
>>> [round(float(v), 3) for v in ratio]
[1.0, 0.345]
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
import torch

from skytorch._data import data_path
from skytorch._validate import as_tensor, check_range

__all__ = [
    "AEROSOL_TYPES",
    "AEROSOL_TYPE_ALIASES",
    "MARS_DUST",
    "MARS_DUST_RANGE_NM",
    "OPAC_RANGE_NM",
    "PREETHAM_ANGSTROM_ALPHA",
    "SULFATE_RANGE_NM",
    "aerosol_type_properties",
    "aerosol_type_range_nm",
    "angstrom_optical_depth",
    "gaussian_layer",
    "gaussian_layer_column",
    "mars_dust_properties",
    "preetham_angstrom_beta",
    "resolve_aerosol_type",
    "STRATOSPHERIC_MODELS",
    "STRATOSPHERIC_PROFILES",
    "stratospheric_model_optical_depth",
    "stratospheric_profile_shape",
    "sulfate_mie_properties",
    "tabulated_layer",
]

#: shipped Mie table of the stratospheric sulfate aerosol (``data/``)
SULFATE_TABLE = "aerosol_mie_sulfate.csv"
#: wavelengths the sulfate table covers [nm]
SULFATE_RANGE_NM = (230.0, 1690.0)
#: shipped LOWTRAN 7 stratospheric aerosol profiles (ref. 10, ``data/``)
STRATOSPHERIC_PROFILE_TABLE = "stratospheric_aerosol_lowtran7.csv"
#: the LOWTRAN 7 stratospheric aerosol models (ref. 10), from the quiet stratosphere to
#: the densest volcanic loading
STRATOSPHERIC_MODELS = ("background", "moderate_volcanic", "high_volcanic",
                        "extreme_volcanic")
#: seasons of the LOWTRAN 7 models; a model named without one is the mean of the two
STRATOSPHERIC_SEASONS = ("spring_summer", "fall_winter")
#: vertical profiles of the stratospheric layer: the Gaussian (peak altitude and width
#: given) and each LOWTRAN 7 model, for one season or the mean of both
STRATOSPHERIC_PROFILES = ("gaussian", *STRATOSPHERIC_MODELS,
                          *(f"{model}_{season}" for model in STRATOSPHERIC_MODELS
                            for season in STRATOSPHERIC_SEASONS))
#: where the tabulated profiles go to zero [m]: LOWTRAN's tropospheric models take over
#: below 11 km and its upper-atmosphere models above 30 km; skytorch has its own
#: tropospheric aerosol, so the layer falls linearly to 0 at 10 km and at 35 km
STRATOSPHERIC_PROFILE_ENDS_M = (10e3, 35e3)
#: named aerosol types with a shipped Mie table: the stratospheric sulfate droplets and
#: the ten OPAC types of Hess et al. 1998 (ref. 8, Table 4)
AEROSOL_TYPES = (
    "sulfate", "continental_clean", "continental_average", "continental_polluted", "urban",
    "desert", "maritime_clean", "maritime_polluted", "maritime_tropical", "arctic",
    "antarctic",
)
#: short names accepted for the OPAC types
AEROSOL_TYPE_ALIASES = {
    "continental": "continental_average", "maritime": "maritime_clean",
    "mineral_dust": "desert",
}
#: wavelengths the OPAC type tables cover [nm]
OPAC_RANGE_NM = (250.0, 2000.0)
#: shipped Mie table of Martian dust (``data/``) and the wavelengths it covers [nm]
MARS_DUST_TABLE = "aerosol_mie_mars_dust.csv"
MARS_DUST_RANGE_NM = (263.0, 1717.372)

#: Ångström exponent of Preetham's turbidity model (ref. 2)
PREETHAM_ANGSTROM_ALPHA = 1.3
#: reference wavelength of the Ångström law [nm]
ANGSTROM_REFERENCE_NM = 1000.0

#: background Martian dust: optical depth 0.5 at 880 nm (ref. 3, non-dusty season
#: typical), nearly grey in the visible (alpha ~ 0), single-scattering albedo 0.93 and
#: Henyey-Greenstein asymmetry 0.63 (ref. 4), mixed with the gas (scale height 11.1 km).
#: The wavelength-dependent albedo is :func:`mars_dust_properties` (ref. 9).
MARS_DUST = {
    "optical_depth": 0.5,
    "reference_wavelength_nm": 880.0,
    "angstrom_alpha": 0.0,
    "single_scattering_albedo": 0.93,
    "asymmetry": 0.63,
    "scale_height_m": 11_100.0,
}


def preetham_angstrom_beta(turbidity) -> torch.Tensor:
    r"""Ångström :math:`\beta` from Preetham's turbidity, :math:`0.04608 T - 0.04586`.

    Parameters
    ----------
    turbidity : Tensor (...)
        Turbidity :math:`T \ge 1` [1].

    Returns
    -------
    Tensor (...)
        :math:`\beta` [1], clamped at 0.
    """
    turbidity = as_tensor("turbidity", turbidity)
    return torch.clamp(0.04608 * turbidity - 0.04586, min=0.0)


def angstrom_optical_depth(wavelength_nm, beta, alpha) -> torch.Tensor:
    r"""Vertical aerosol optical depth :math:`\beta (\lambda/1\,\mu m)^{-\alpha}`.

    Parameters
    ----------
    wavelength_nm : Tensor (wavelength,)
        Wavelength [nm].
    beta, alpha : Tensor (...)
        Ångström turbidity coefficient and exponent [1].

    Returns
    -------
    Tensor (..., wavelength)
        Vertical optical depth [1].
    """
    wavelength_nm = as_tensor("wavelength_nm", wavelength_nm)
    beta = torch.as_tensor(beta, dtype=wavelength_nm.dtype)
    alpha = torch.as_tensor(alpha, dtype=wavelength_nm.dtype)
    return beta[..., None] * (wavelength_nm / ANGSTROM_REFERENCE_NM) ** (-alpha[..., None])


@lru_cache(maxsize=16)
def _table(filename: str, low: float, high: float) -> np.ndarray:
    """Return the rows of a shipped Mie table, checked to span [low, high] nm.

    Rows (wavelength_nm, extinction ratio, single_scattering_albedo, asymmetry), checked to
    span [low, high] nm in increasing order.
    """
    path = data_path(filename)
    with open(path, encoding="utf-8") as handle:
        header = 1 + sum(1 for line in handle if line.startswith("#"))  # + column names
    table = np.loadtxt(path, delimiter=",", comments="#", skiprows=header)
    grid = table[:, 0]
    if not (np.all(np.diff(grid) > 0.0) and abs(grid[0] - low) < 1e-6
            and abs(grid[-1] - high) < 1e-6):
        raise ValueError(f"{filename} does not span ({low}, {high}) nm in order")
    return table


@lru_cache(maxsize=64)
def _table_tensors(filename: str, low: float, high: float,
                   dtype: torch.dtype) -> torch.Tensor:
    return torch.as_tensor(np.ascontiguousarray(_table(filename, low, high).T), dtype=dtype)


def _interpolate_table(filename: str, wavelength_range, wavelength_nm, name: str):
    """Linear interpolation of the three columns of a Mie table; ValueError outside."""
    low, high = wavelength_range
    wavelength = check_range(name, wavelength_nm, low, high, unit=" nm")
    if not wavelength.is_floating_point():
        wavelength = wavelength.to(torch.get_default_dtype())
    table = _table_tensors(filename, float(low), float(high), wavelength.dtype)
    grid = table[0]
    index = torch.clamp(torch.searchsorted(grid, wavelength.detach().contiguous(),
                                           right=True) - 1, 0, grid.numel() - 2)
    weight = (wavelength - grid[index]) / (grid[index + 1] - grid[index])
    return tuple(table[c, index] + weight * (table[c, index + 1] - table[c, index])
                 for c in (1, 2, 3))


def sulfate_mie_properties(wavelength_nm):
    """Mie optical properties of the stratospheric sulfate aerosol (75 % H2SO4).

    Linear interpolation of ``data/aerosol_mie_sulfate.csv`` (lognormal size
    distribution, r_g = 0.08 um, sigma_g = 1.8, m = 1.43 + 1e-8 i; refs. 5, 6).

    Parameters
    ----------
    wavelength_nm : Tensor (...)
        Wavelength [nm], in :data:`SULFATE_RANGE_NM` = [230, 1690] nm (ValueError
        outside).

    Returns
    -------
    tuple of Tensor (...)
        Extinction relative to 550 nm [1], single-scattering albedo [1] and asymmetry
        parameter g [1].
    """
    return _interpolate_table(SULFATE_TABLE, SULFATE_RANGE_NM, wavelength_nm,
                              "wavelength_nm")


def resolve_aerosol_type(aerosol_type: str) -> str:
    """Return the canonical name of an aerosol type.

    A name of :data:`AEROSOL_TYPES`, or an alias of :data:`AEROSOL_TYPE_ALIASES`; ValueError naming
    the valid names otherwise.

    Examples
    --------
    >>> resolve_aerosol_type("maritime")
    'maritime_clean'
    """
    if not isinstance(aerosol_type, str):
        raise TypeError(f"aerosol_type must be a str, got {type(aerosol_type).__name__}")
    name = AEROSOL_TYPE_ALIASES.get(aerosol_type, aerosol_type)
    if name not in AEROSOL_TYPES:
        raise ValueError(f"aerosol_type={aerosol_type!r} is not one of "
                         f"{sorted(AEROSOL_TYPES) + sorted(AEROSOL_TYPE_ALIASES)}")
    return name


def aerosol_type_range_nm(aerosol_type: str) -> tuple[float, float]:
    """Wavelengths [nm] the table of ``aerosol_type`` covers."""
    name = resolve_aerosol_type(aerosol_type)
    return SULFATE_RANGE_NM if name == "sulfate" else OPAC_RANGE_NM


def aerosol_type_properties(aerosol_type: str, wavelength_nm):
    """Mie optical properties of a named aerosol type.

    ``"sulfate"`` is the 75 % H2SO4 droplet layer of :func:`sulfate_mie_properties`; the
    others are the OPAC types of Hess et al. (1998, ref. 8): external mixtures of
    lognormal components (water-soluble, insoluble, soot, sea salt, mineral, sulfate) at
    80 % relative humidity, Mie theory per component (``data/aerosol_mie_<type>.csv``,
    generator ``data/make_aerosol_tables.py``), interpolated linearly in wavelength.
    The phase function the kernels use with these tables is Henyey–Greenstein (ref. 7)
    with the tabulated Mie asymmetry g.

    Parameters
    ----------
    aerosol_type : str
        One of :data:`AEROSOL_TYPES` or an alias of :data:`AEROSOL_TYPE_ALIASES`.
    wavelength_nm : Tensor (...)
        Wavelength [nm], within :func:`aerosol_type_range_nm` (sulfate 230-1690 nm, OPAC
        types 250-2000 nm; ValueError outside).

    Returns
    -------
    tuple of Tensor (...)
        Extinction relative to 550 nm [1], single-scattering albedo [1] and asymmetry
        parameter g [1].

    Examples
    --------
    >>> ratio, albedo, g = aerosol_type_properties("urban", torch.tensor([550.0]))
    >>> float(ratio[0]), round(float(albedo[0]), 2), round(float(g[0]), 2)
    (1.0, 0.82, 0.69)
    """
    name = resolve_aerosol_type(aerosol_type)
    if name == "sulfate":
        return sulfate_mie_properties(wavelength_nm)
    return _interpolate_table(f"aerosol_mie_{name}.csv", OPAC_RANGE_NM, wavelength_nm,
                              "wavelength_nm")


def mars_dust_properties(wavelength_nm):
    """Mie optical properties of Martian dust, wavelength-dependent (ref. 9).

    Linear interpolation of ``data/aerosol_mie_mars_dust.csv``: spheres with the Wolff et
    al. (2009) refractive index, lognormal with effective radius 1.5 um and effective
    variance 0.3; the single-scattering albedo falls from 0.97 in the red to 0.75 at
    400 nm (absorption by ferric oxides in the blue).

    Parameters
    ----------
    wavelength_nm : Tensor (...)
        Wavelength [nm] in :data:`MARS_DUST_RANGE_NM` = [263, 1717.4] nm (ValueError
        outside).

    Returns
    -------
    tuple of Tensor (...)
        Extinction relative to 880 nm [1], single-scattering albedo [1] and asymmetry g of
        the spheres [1] (:class:`~skytorch.atmosphere.model.Atmosphere.mars` keeps the
        Henyey–Greenstein asymmetry of :data:`MARS_DUST`, fitted to the non-spherical
        grains, ref. 4).

    Examples
    --------
    >>> _, albedo, _ = mars_dust_properties(torch.tensor([450.0, 700.0]))
    >>> bool(albedo[0] < albedo[1])
    True
    """
    return _interpolate_table(MARS_DUST_TABLE, MARS_DUST_RANGE_NM, wavelength_nm,
                              "wavelength_nm")


@lru_cache(maxsize=1)
def _stratospheric_table() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Altitudes [m] and 550 nm extinction [km⁻¹] of the shipped LOWTRAN 7 profiles."""
    path = data_path(STRATOSPHERIC_PROFILE_TABLE)
    with open(path, encoding="utf-8") as handle:
        lines = [line for line in handle if not line.startswith("#")]
    names = lines[0].strip().split(",")[1:]
    table = np.loadtxt(lines[1:], delimiter=",", ndmin=2)
    return 1e3 * table[:, 0], {name: table[:, k + 1] for k, name in enumerate(names)}


def _seasonal_columns(name: str) -> tuple[np.ndarray, list[np.ndarray]]:
    """Table altitudes [m] and the extinction columns [km⁻¹] of a model's season(s).

    Both seasons for a model named without one; ValueError for a name that is not a
    tabulated profile.
    """
    if name not in STRATOSPHERIC_PROFILES or name == "gaussian":
        raise ValueError(f"name must be one of {STRATOSPHERIC_PROFILES[1:]}; got {name!r}")
    altitude, columns = _stratospheric_table()
    names = ([f"{name}_{season}" for season in STRATOSPHERIC_SEASONS]
             if name in STRATOSPHERIC_MODELS else [name])
    return altitude, [columns[n] for n in names]


def stratospheric_profile_shape(name: str) -> tuple[np.ndarray, np.ndarray]:
    """Shape of a LOWTRAN 7 stratospheric aerosol profile (ref. 10).

    Parameters
    ----------
    name : str
        A model of :data:`STRATOSPHERIC_MODELS`, optionally with a season of
        ``("spring_summer", "fall_winter")`` appended (``"high_volcanic_fall_winter"``);
        without a season the mean of the two seasons' shapes, each normalised to a unit
        column.

    Returns
    -------
    altitude_m, relative : numpy.ndarray (node,)
        Nodes [m] from 10 to 35 km and the 550 nm extinction relative to its largest
        value [1], linear between the nodes and 0 outside (0 at 10 and 35 km: the
        LOWTRAN table covers 11-30 km).

    Examples
    --------
    >>> altitude, relative = stratospheric_profile_shape("high_volcanic_spring_summer")
    >>> float(altitude[relative.argmax()]), float(relative.max())
    (19000.0, 1.0)
    """
    altitude, seasons = _seasonal_columns(name)
    low, high = STRATOSPHERIC_PROFILE_ENDS_M
    altitude = np.concatenate([[low], altitude, [high]])
    shapes = [np.concatenate([[0.0], column, [0.0]]) for column in seasons]
    values = sum(shape / np.trapezoid(shape, altitude) for shape in shapes)
    return altitude, values / values.max()


def stratospheric_model_optical_depth(name: str) -> float:
    """Vertical optical depth at 550 nm of a LOWTRAN 7 stratospheric model (ref. 10) [1].

    The column of its tabulated extinction, 11-30 km (linear between the nodes); for a
    model named without a season (:func:`stratospheric_profile_shape`) the mean of the
    two seasons'.

    Examples
    --------
    >>> [round(stratospheric_model_optical_depth(m), 4) for m in STRATOSPHERIC_MODELS]
    [0.007, 0.0268, 0.0851, 0.2707]
    """
    altitude, seasons = _seasonal_columns(name)
    return float(np.mean([np.trapezoid(column, altitude / 1e3) for column in seasons]))


def tabulated_layer(altitude_m, nodes_m: torch.Tensor, values: torch.Tensor) -> torch.Tensor:
    """Relative density linear between increasing ``nodes_m`` [m], 0 outside them.

    The first and last ``values`` should be 0 (:func:`stratospheric_profile_shape`), so
    that the layer is continuous.
    """
    altitude_m = as_tensor("altitude_m", altitude_m)
    nodes = nodes_m.to(altitude_m.dtype)
    values = values.to(altitude_m.dtype)
    i = torch.clamp(torch.searchsorted(nodes, altitude_m.detach().contiguous(), right=True) - 1,
                    0, nodes.numel() - 2)
    h0, h1 = nodes[i], nodes[i + 1]
    inside = values[i] + (values[i + 1] - values[i]) * (altitude_m - h0) / (h1 - h0)
    outside = (altitude_m < nodes[0]) | (altitude_m > nodes[-1])
    return torch.where(outside, torch.zeros_like(inside), inside)


def gaussian_layer(altitude_m, center_m, width_m) -> torch.Tensor:
    r"""Gaussian layer :math:`\exp[-(h - h_c)^2 / (2 w^2)]`, 1 at the peak.

    Parameters
    ----------
    altitude_m : Tensor (...)
        Altitude [m].
    center_m, width_m : float or Tensor (...)
        Peak altitude :math:`h_c` [m] and width :math:`w` [m] (the standard deviation).

    Returns
    -------
    Tensor (...)
        Relative density [1].
    """
    altitude_m = as_tensor("altitude_m", altitude_m)
    return torch.exp(-0.5 * ((altitude_m - center_m) / width_m) ** 2)


def gaussian_layer_column(center_m, width_m, top_m) -> torch.Tensor:
    r""":math:`\int_0^{h_{top}}` of :func:`gaussian_layer` [m], truncated at ground and top.

    :math:`w\sqrt{\pi/2}\,[\mathrm{erf}((h_{top} - h_c)/(\sqrt2 w))
    + \mathrm{erf}(h_c/(\sqrt2 w))]`.

    Parameters
    ----------
    center_m, width_m : Tensor (...)
        Peak altitude and width (standard deviation) [m].
    top_m : float
        Altitude of the top of the atmosphere [m].

    Returns
    -------
    Tensor (...)
        Column height [m].
    """
    scale = math.sqrt(2.0) * width_m
    return (width_m * math.sqrt(0.5 * math.pi)
            * (torch.erf((top_m - center_m) / scale) + torch.erf(center_m / scale)))
