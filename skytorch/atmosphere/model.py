r"""The :class:`Atmosphere` module: constituents, their profiles and spectral coefficients.

An atmosphere is a spherical shell between ``planet_radius_m`` and ``top_radius_m``
holding three constituents, each a dimensionless density profile :math:`\rho_s(h)`
times a spectral extinction coefficient at the reference level :math:`k_s(\lambda)`:

* molecules (Rayleigh scattering; :mod:`skytorch.atmosphere.rayleigh`), exponential or
  U.S. Standard Atmosphere 1976 profile; the column of molecules is that of a
  hydrostatic atmosphere with the given surface pressure,
  :math:`N_{col} = p N_A/(m g)`, so the vertical Rayleigh optical depth scales with
  pressure whatever the profile shape;
* aerosols (Ångström law from Preetham turbidity or an optical depth at 550 nm;
  :mod:`skytorch.atmosphere.aerosol`), exponential profile, single-scattering albedo
  and Cornette–Shanks or Henyey–Greenstein phase function;
* ozone (absorbing only; :mod:`skytorch.atmosphere.ozone`, 214–1100 nm at the layer's
  temperature ``ozone_temperature_k``), tent profile with the
  column given in Dobson units.

The refractivity :math:`n - 1` is proportional to the gas density,
:math:`(n-1)(h) = (n-1)_{ref}\,(p/p_{ref})(T_{ref}/T)\,\rho(h)` (2.77e-4 at
1013.25 hPa, 288.15 K on Earth; 3.38e-6 at 610 Pa, 215 K on Mars, ref. 1), with
:math:`\rho` the molecular profile or, with ``refractivity_profile="us1976"`` (the
default of :meth:`Atmosphere.earth`), the U.S. Standard Atmosphere 1976 density (a
realistic lapse rate for refraction near the horizon, while optical depths keep the
molecular profile).

Every physical parameter may be a tensor with batch dimensions; parameters and ray
geometry broadcast together by torch rules and spectral outputs have shape
``(*broadcast, n_wavelength)``. Parameters are stored as float64 buffers and cast to the
dtype of the inputs at use.

References
----------
1. Schneegans, S. et al. 2025, "Physically Based Real-Time Rendering of Eclipses",
   Computer Graphics Forum.
2. Bruneton, E. 2017, "A qualitative and quantitative evaluation of 8 clear sky models",
   IEEE TVCG 24, 2641, doi:10.1109/TVCG.2016.2622272.
3. Preetham, A. J., Shirley, P. & Smits, B. 1999, "A practical analytic model for
   daylight", Proc. SIGGRAPH 99, 91, doi:10.1145/311535.311545.

Examples
--------
>>> import torch
>>> from skytorch.atmosphere import Atmosphere
>>> atm = Atmosphere.earth(turbidity=torch.tensor([[1.5], [3.0]]),
...                        ozone_du=torch.tensor([[0.0, 300.0]]))
>>> atm.optical_depth(torch.tensor([550.0])).shape   # 2 x 2 sweep, one wavelength
torch.Size([2, 2, 1])
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import json
import math
from functools import lru_cache
from types import MappingProxyType

import torch
from torch import nn

from skytorch._validate import (
    as_tensor,
    broadcast_shape,
    check_choice,
    check_flag,
    check_int,
    check_range,
    check_zenith,
    common_dtype,
)
from skytorch.atmosphere import aerosol as _aerosol
from skytorch.atmosphere import constituents as _constituents
from skytorch.atmosphere import gases as _gases
from skytorch.atmosphere import optical_depth as _od
from skytorch.atmosphere import ozone as _ozone
from skytorch.atmosphere import profiles as _profiles
from skytorch.atmosphere import rayleigh as _rayleigh
from skytorch.atmosphere.constituents import Constituents, Profile, Species, SpeciesBuilder
from skytorch.atmosphere.inputs import altitude_tensor, wavelength_tensor
from skytorch.atmosphere.ozone import ozone_cross_section
from skytorch.atmosphere.scattering import PHASE_FUNCTIONS, phase_function, rayleigh_phase
from skytorch.constants import (
    AVOGADRO_PER_MOL,
    DOBSON_UNIT_PER_M2,
    EARTH_AEROSOL_SCALE_HEIGHT_M,
    EARTH_MEAN_RADIUS_M,
    EARTH_RAYLEIGH_SCALE_HEIGHT_M,
    EARTH_REFRACTIVITY_SEA_LEVEL,
    EARTH_TOP_OF_ATMOSPHERE_M,
    MARS_MEAN_RADIUS_M,
    MARS_REFRACTIVITY_SURFACE,
    MARS_SCALE_HEIGHT_M,
    MARS_SURFACE_PRESSURE_PA,
    MARS_SURFACE_TEMPERATURE_K,
    MARS_TOP_OF_ATMOSPHERE_M,
    STANDARD_PRESSURE_PA,
    STANDARD_TEMPERATURE_K,
)

__all__ = ["SPECIES", "SPECIES_BUILDERS", "Atmosphere", "altitude_tensor", "wavelength_tensor"]

#: straight rays integrated together by :meth:`Atmosphere.optical_depth` when there are
#: more than twice as many (scalar parameters, fixed quadrature)
RAY_CHUNK = 16_384
#: constituents, in the order of ``per_species`` outputs
SPECIES = ("rayleigh", "aerosol", "ozone", "stratospheric_aerosol", *_gases.GAS_SPECIES)

#: gravity at sea level, latitude 45° (Bodhaine et al. 1999, eq. 11) [m s^-2]
EARTH_GRAVITY_M_S2 = 9.80616
#: Mars surface gravity [m s^-2] (IAU/NASA fact sheet value)
MARS_GRAVITY_M_S2 = 3.711
#: Bruneton's (2017) demo aerosol: single-scattering albedo and asymmetry
EARTH_AEROSOL_SINGLE_SCATTERING_ALBEDO = 0.9
EARTH_AEROSOL_ASYMMETRY = 0.8
#: breakpoints of exponential profiles above the lowest point of a leg, in scale heights;
#: the last one ends the integration (exp(-30) = 9e-14 of the leg's peak density)
_EXPONENTIAL_LEVELS = (0.5, 1.5, 4.0, 10.0, 30.0)
#: quadrature levels of the US 1976 profile [m]: its layer bases (kinks) and, below the
#: first, levels that resolve the exponential-like decay near the ground
_US1976_BREAKS_M = (1000.0, 2000.0, 4000.0, 8000.0, *_profiles.US1976_KINK_ALTITUDES_M)

_PARAMETERS = (
    "surface_pressure_pa", "surface_temperature_k", "gravity_m_s2", "molar_mass_kg_mol",
    "rayleigh_scale_height_m", "angstrom_beta", "angstrom_alpha", "aerosol_scale_height_m",
    "aerosol_single_scattering_albedo", "aerosol_asymmetry", "ozone_du",
    "ozone_peak_altitude_m", "ozone_half_width_m", "ozone_temperature_k",
    "reference_refractivity", "reference_pressure_pa", "reference_temperature_k",
    "stratospheric_aerosol_optical_depth", "stratospheric_aerosol_altitude_m",
    "stratospheric_aerosol_width_m",
    "precipitable_water_cm",  # gases (skytorch.atmosphere.gases)
)
#: levels of the stratospheric Gaussian layer's quadrature, in widths about its peak
_GAUSSIAN_LEVELS = (-8.0, -5.0, -3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0, 5.0, 8.0)

#: accepted range of every constructor parameter: (low, high, low inclusive, unit). The
#: bounds are wide (Venus' 9.2 MPa surface, scale heights from 1 m, a Preetham turbidity
#: of 64 is beta = 2.9) but finite, so that every optical depth and coefficient the model
#: forms from them is a finite float64 number.
PARAMETER_RANGES = {
    "planet_radius_m": (0.0, 1e9, False, " m"),
    "top_altitude_m": (0.0, 1e8, False, " m"),
    "surface_pressure_pa": (0.0, 1e8, True, " Pa"),
    "surface_temperature_k": (1.0, 1e4, True, " K"),
    "gravity_m_s2": (1e-3, 1e3, True, " m s^-2"),
    "molar_mass_kg_mol": (1e-4, 1.0, True, " kg/mol"),
    "rayleigh_scale_height_m": (1.0, 1e7, True, " m"),
    "angstrom_beta": (0.0, 100.0, True, ""),
    "angstrom_alpha": (-1.0, 4.0, True, ""),
    "aerosol_scale_height_m": (1.0, 1e7, True, " m"),
    "aerosol_single_scattering_albedo": (0.0, 1.0, True, ""),
    "aerosol_asymmetry": (-0.99, 0.99, True, ""),
    "ozone_du": (0.0, 1e5, True, " DU"),
    "ozone_peak_altitude_m": (0.0, 1e7, False, " m"),
    "ozone_half_width_m": (1.0, 1e7, True, " m"),
    "ozone_temperature_k": (*_ozone.OZONE_TEMPERATURE_RANGE_K, True, " K"),
    "reference_refractivity": (0.0, 1e-2, True, ""),
    "reference_pressure_pa": (0.0, 1e8, False, " Pa"),
    "reference_temperature_k": (1.0, 1e4, True, " K"),
    "stratospheric_aerosol_optical_depth": (0.0, 100.0, True, ""),
    "stratospheric_aerosol_altitude_m": (0.0, 1e7, True, " m"),
    "stratospheric_aerosol_width_m": (1.0, 1e7, True, " m"),
    # gases: observed columns stay below ~7 cm (skytorch.atmosphere.gases)
    "precipitable_water_cm": (*_gases.PRECIPITABLE_WATER_RANGE_CM, True, " cm"),
}
#: default peak altitude and half width of the ozone tent [m]
OZONE_PEAK_ALTITUDE_M = 25_000.0
OZONE_HALF_WIDTH_M = 15_000.0
#: Preetham turbidity accepted by :meth:`Atmosphere.earth`: 1 (aerosol-free) to 64
#: (beta = 2.9, a vertical aerosol optical depth of 6.3 at 550 nm: thick fog)
TURBIDITY_RANGE = (1.0, 64.0)
#: wavelength-dependent aerosol albedos (``aerosol_albedo_spectrum``)
AEROSOL_ALBEDO_SPECTRA = ("mars_dust",)
#: vertical aerosol optical depth at 550 nm accepted by :meth:`Atmosphere.earth`
AEROSOL_OPTICAL_DEPTH_RANGE = (0.0, 100.0)
#: wavelengths the molecular model covers [nm]: the range of the Peck & Reeder (1972)
#: dispersion formula behind the Rayleigh cross-section and the refractivity (its poles
#: lie at 87 and 159 nm)
WAVELENGTH_RANGE_NM = _rayleigh.WAVELENGTH_RANGE_NM


class _FromProfile:
    """Default of a keyword taken from the sounding when one is given.

    Otherwise the documented standard value; ``None`` stays an invalid value.
    """

    def __repr__(self) -> str:
        return "<standard value, or the sounding's>"


#: default of surface_pressure_pa, surface_temperature_k and ozone_du
FROM_PROFILE = _FromProfile()


def _check_parameter(name: str, value, *, low=None, high=None, low_inclusive=None,
                     unit=None) -> torch.Tensor:
    """Return a constructor parameter as a float64 tensor, within :data:`PARAMETER_RANGES`.

    Booleans are refused (``True`` is not a pressure); integer tensors are promoted.
    """
    if isinstance(value, bool) or (isinstance(value, torch.Tensor)
                                   and value.dtype == torch.bool):
        raise TypeError(f"{name} must be a number or a tensor of numbers; got {value!r}")
    default = PARAMETER_RANGES.get(name, (None, None, True, ""))
    low = default[0] if low is None else low
    high = default[1] if high is None else high
    low_inclusive = default[2] if low_inclusive is None else low_inclusive
    unit = default[3] if unit is None else unit
    tensor = as_tensor(name, value)
    if tensor.is_floating_point() and tensor.dtype != torch.float64:
        tensor = tensor.to(torch.float64)  # float16/float32 values are exact in float64
    return check_range(name, tensor, low, high, low_inclusive=low_inclusive, unit=unit)


#: keywords of the constructor (checked by the presets before forwarding)
_CONSTRUCTOR_KEYWORDS = (
    "planet_radius_m", "top_altitude_m", "gas", "molecule_profile", "refractivity_profile",
    "profile",
    "aerosol_phase_model", "aerosol_type", "aerosol_albedo_spectrum", "name",
    "stratospheric_aerosol_profile", *_PARAMETERS,
)


def _check_type_options(where: str, options: dict) -> None:
    """ValueError for scalar aerosol optics that a named type or albedo spectrum replaces."""
    replaced = ()
    if options.get("aerosol_type") is not None:
        replaced = ("aerosol_single_scattering_albedo", "aerosol_asymmetry")
    elif options.get("aerosol_albedo_spectrum") is not None:
        replaced = ("aerosol_single_scattering_albedo",)
    unused = [key for key in replaced if key in options]
    if unused:
        raise ValueError(f"{where}(): {unused} would not be used with aerosol_type="
                         f"{options.get('aerosol_type')!r}, aerosol_albedo_spectrum="
                         f"{options.get('aerosol_albedo_spectrum')!r} (the Mie tables give "
                         "them)")


def _check_options(where: str, options: dict, exclude: tuple[str, ...] = ()) -> None:
    """TypeError for keywords that are not constructor arguments (typos are not ignored)."""
    valid = [key for key in _CONSTRUCTOR_KEYWORDS if key not in exclude]
    unknown = sorted(key for key in options if key not in valid)
    if unknown:
        raise TypeError(f"{where}() got unexpected keyword argument(s) {unknown}; valid "
                        f"keywords: {', '.join(valid)}")


def _parameter_batch_shape(values: dict) -> torch.Size:
    """Broadcast shape of the parameters, or ValueError naming each one's shape."""
    try:
        return broadcast_shape(*(v.shape for v in values.values()))
    except ValueError:
        listing = ", ".join(f"{key}{_FROM_PRESET.get(key, '')} {tuple(v.shape)}"
                            for key, v in values.items() if v.ndim > 0)
        raise ValueError(f"Atmosphere parameters do not broadcast: {listing}") from None


#: parameters that the presets derive from another keyword (named in shape errors)
_FROM_PRESET = {"angstrom_beta": " (from turbidity or aerosol_optical_depth)"}


@lru_cache(maxsize=1)
def _us1976_column_height_m() -> float:
    r""":math:`\int_0^\infty \rho_{US1976}(h)\,dh` [m] by fine trapezoid (0–200 km)."""
    altitude = torch.linspace(0.0, 200e3, 200_001, dtype=torch.float64)
    return float(torch.trapezoid(_profiles.us1976(altitude), altitude))


class Atmosphere(nn.Module):
    """A spherically symmetric planetary atmosphere with batched parameters.

    Parameters
    ----------
    planet_radius_m, top_altitude_m : float
        Planet radius and altitude of the top of the atmosphere [m].
    surface_pressure_pa, surface_temperature_k : float or Tensor, optional
        Surface pressure [Pa] (sets the column of molecules) and temperature [K] (with
        the pressure, sets the surface density used for the refractivity); default
        1013.25 hPa and 288.15 K, or the sounding's values at 0 m.
    gravity_m_s2, molar_mass_kg_mol : float or Tensor
        Gravity [m s^-2] and mean molar mass [kg/mol] for the hydrostatic column.
    gas : {"air", "co2"}
        Rayleigh model (:data:`skytorch.atmosphere.rayleigh.RAYLEIGH_GASES`).
    molecule_profile : {"exponential", "us1976", "sounding"}, optional
        Shape of the molecular density (optical depths, scattering and, by default,
        refraction); default ``"exponential"`` (:meth:`earth`: ``"us1976"``), or
        ``"sounding"`` with a ``profile``.
    refractivity_profile : {"exponential", "us1976"}, optional
        Shape of the refractivity :math:`n - 1` with altitude (refraction); default: the
        ``molecule_profile`` (:meth:`earth`: ``"us1976"``). The refraction near the
        horizon depends on the density gradient in the lowest kilometres, which the
        isothermal 8 km exponential overstates (horizon refraction 37.3' instead of
        Bennett's 34.0' at 1013.25 hPa, 15 degC; US 1976: 32.9'; see
        ``docs/refraction.md``).
    rayleigh_scale_height_m : float or Tensor
        Scale height of the exponential molecular profile [m].
    angstrom_beta, angstrom_alpha : float or Tensor
        Ångström coefficient and exponent of the aerosol optical depth [1].
    aerosol_scale_height_m : float or Tensor
        Aerosol scale height [m].
    aerosol_single_scattering_albedo, aerosol_asymmetry : float or Tensor
        Aerosol single-scattering albedo and phase-function asymmetry [1].
    aerosol_phase_model : {"cornetteshanks1992", "henyeygreenstein1941"}, optional
        Aerosol phase function; default Cornette-Shanks, or Henyey-Greenstein with an
        ``aerosol_type``.
    aerosol_type : str, optional
        A named tropospheric aerosol type with Mie optics
        (:data:`skytorch.atmosphere.aerosol.AEROSOL_TYPES`: ``"sulfate"`` and the OPAC
        types ``"continental_average"`` (alias ``"continental"``), ``"maritime_clean"``
        (``"maritime"``), ``"urban"``, ``"desert"`` (``"mineral_dust"``), ...). The
        optical depth at 550 nm stays that of the Ångström law (``angstrom_beta``,
        ``angstrom_alpha``: turbidity or ``aerosol_optical_depth`` in :meth:`earth`); the
        spectrum relative to 550 nm, the single-scattering albedo and the asymmetry g per
        wavelength come from the type's Mie table
        (:func:`skytorch.atmosphere.aerosol.aerosol_type_properties`, 250-2000 nm; 230-1690
        nm for ``"sulfate"``), and ``aerosol_phase_model`` is used with that g (default
        Henyey-Greenstein); ``aerosol_single_scattering_albedo`` and ``aerosol_asymmetry``
        are then not used. Default None: Ångström spectrum, scalar albedo and asymmetry
        (the behaviour without types).
    aerosol_albedo_spectrum : {"mars_dust"}, optional
        Wavelength-dependent single-scattering albedo of the aerosol, replacing
        ``aerosol_single_scattering_albedo``: ``"mars_dust"``
        (:func:`skytorch.atmosphere.aerosol.mars_dust_properties`, 263-1717 nm; the
        default of :meth:`mars`). Not with ``aerosol_type``.
    ozone_du : float or Tensor, optional
        Ozone column [DU]; default 0, or the column of the sounding's
        ``ozone_number_density``. Given with a sounding that has ozone, it scales the
        sounding's ozone shape to this column (the knob of a sweep).
    ozone_peak_altitude_m, ozone_half_width_m : float or Tensor, optional
        Altitude of the ozone peak and half width of the tent [m]; default 25 km and
        15 km. The tent holds ``ozone_du`` between the ground and the top, however cut
        by either. A sounding that gives the ozone replaces the tent (giving either
        raises ValueError).
    ozone_temperature_k : float or Tensor, optional
        Temperature of the ozone cross-sections [K], in [203, 293] K; default: the
        tent-weighted mean U.S. Standard Atmosphere 1976 temperature over the layer
        (:func:`skytorch.atmosphere.ozone.ozone_effective_temperature`; 222.9 K for the
        default tent 10–40 km), or the sounding's ozone-weighted temperature. It does not
        follow ``surface_temperature_k``, which scales :meth:`temperature_k` (T_s/288.15):
        pass the layer's temperature for a colder or warmer stratosphere.
    reference_refractivity, reference_pressure_pa, reference_temperature_k : float
        :math:`n - 1` at 589.3 nm and the pressure [Pa] and temperature [K] it refers to.
    stratospheric_aerosol_optical_depth : float or Tensor
        Vertical optical depth at 550 nm of the stratospheric sulfate layer (species
        ``"stratospheric_aerosol"``), in [0, 100]; default 0 (no layer).
    stratospheric_aerosol_altitude_m, stratospheric_aerosol_width_m : float or Tensor, optional
        Peak altitude [m] and width [m] of the ``"gaussian"`` layer (default 20 km and
        3 km): a Gaussian in altitude whose width is its standard deviation, normalised so
        that its column from the ground to ``top_altitude_m`` (truncation included) is the
        given optical depth. Not with a tabulated ``stratospheric_aerosol_profile`` (giving
        them raises ValueError); the buffers then hold that profile's centroid and rms
        width. Spectrum, single-scattering albedo and Henyey-Greenstein asymmetry from Mie
        theory for 75 % H2SO4 droplets
        (:func:`skytorch.atmosphere.aerosol.sulfate_mie_properties`).
    stratospheric_aerosol_profile : str
        Vertical profile of the layer: ``"gaussian"`` (default) or a LOWTRAN 7 model of
        :data:`skytorch.atmosphere.aerosol.STRATOSPHERIC_PROFILES` (Shettle & Fenn 1979:
        ``"background"``, ``"moderate_volcanic"``, ``"high_volcanic"``,
        ``"extreme_volcanic"``, with ``"_spring_summer"`` or ``"_fall_winter"`` or, without,
        the mean of both), tabulated 11-30 km
        (:func:`skytorch.atmosphere.aerosol.stratospheric_profile_shape`) and scaled to
        ``stratospheric_aerosol_optical_depth``.
    precipitable_water_cm : float or Tensor
        Vertical column of water vapour from the ground [cm of precipitable water], in
        [0, 10]; default 0 (:meth:`earth`: 1.4). Species ``"h2o"``, ``"o2"`` and ``"o2o2"``
        (O2 follows the molecules, volume mixing ratio 0.2095, only with ``gas="air"``):
        band model with a curve of growth of the pressure-scaled path amount and O2-O2
        collision-induced absorption, 242-1100 nm (:mod:`skytorch.atmosphere.gases`).
    profile : xarray.Dataset, optional
        A user sounding (:func:`skytorch.atmosphere.profiles.check_sounding`):
        ``altitude`` [m], ``pressure`` [Pa], ``temperature`` [K], optionally
        ``ozone_number_density`` [m-3] and ``h2o_vmr`` [1]. The molecular shape is the
        number density :math:`p/(kT)` relative to its value at 0 m, interpolated
        log-linearly between levels (exact for isothermal layers) and continued above
        the top level with the scale height of the top layer; the column of molecules
        stays :math:`p_s N_A/(m g)` (hydrostatic, so that the Rayleigh optical depth
        scales with surface pressure as in Bodhaine et al. 1999). Ozone and water vapour
        are interpolated linearly and are zero above the top level. Refraction follows
        the same profile.
    name : str
        Label stored in Datasets.

    Notes
    -----
    Parameters given as tensors that require gradients stay differentiable (buffers are
    not detached), e.g. to fit a turbidity to observed extinction. The conversion from
    the given parameters (e.g. turbidity to Ångström β) is part of the autograd graph:
    rebuild the module for every optimisation step (or backward with
    ``retain_graph=True``).

    Examples
    --------
    >>> import torch
    >>> atm = Atmosphere.earth(turbidity=2.0, ozone_du=300.0)
    >>> tau = atm.optical_depth(torch.tensor([440.0, 550.0, 680.0]))
    >>> tau.shape
    torch.Size([3])
    """

    def __init__(self, *, planet_radius_m: float, top_altitude_m: float,  # noqa: C901 (parameter checks and defaults)
                 surface_pressure_pa=FROM_PROFILE,
                 surface_temperature_k=FROM_PROFILE,
                 gravity_m_s2=EARTH_GRAVITY_M_S2,
                 molar_mass_kg_mol=None, gas: str = "air",
                 molecule_profile: str | None = None,
                 refractivity_profile: str | None = None,
                 rayleigh_scale_height_m=EARTH_RAYLEIGH_SCALE_HEIGHT_M,
                 angstrom_beta=0.0, angstrom_alpha=_aerosol.PREETHAM_ANGSTROM_ALPHA,
                 aerosol_scale_height_m=EARTH_AEROSOL_SCALE_HEIGHT_M,
                 aerosol_single_scattering_albedo=EARTH_AEROSOL_SINGLE_SCATTERING_ALBEDO,
                 aerosol_asymmetry=EARTH_AEROSOL_ASYMMETRY,
                 aerosol_phase_model: str | None = None,
                 aerosol_type: str | None = None,
                 aerosol_albedo_spectrum: str | None = None,
                 ozone_du=FROM_PROFILE, ozone_peak_altitude_m=None, ozone_half_width_m=None,
                 ozone_temperature_k=None,
                 reference_refractivity: float = EARTH_REFRACTIVITY_SEA_LEVEL,
                 reference_pressure_pa: float = STANDARD_PRESSURE_PA,
                 reference_temperature_k: float = STANDARD_TEMPERATURE_K,
                 stratospheric_aerosol_optical_depth=0.0,
                 stratospheric_aerosol_altitude_m=None,
                 stratospheric_aerosol_width_m=None,
                 stratospheric_aerosol_profile: str = "gaussian",
                 precipitable_water_cm=0.0,
                 profile=None,
                 name: str = "custom"):
        super().__init__()
        self.gas = check_choice("gas", gas, _rayleigh.RAYLEIGH_GASES)
        # a user sounding (read-only float64 tensors per level; None without one)
        self.sounding = (None if profile is None
                         else MappingProxyType(_profiles.check_sounding(profile)))
        if molecule_profile is None:
            molecule_profile = "exponential" if profile is None else "sounding"
        self.molecule_profile = check_choice("molecule_profile", molecule_profile,
                                             _profiles.PROFILES)
        if (self.molecule_profile == "sounding") != (profile is not None):
            raise ValueError("molecule_profile='sounding' goes with a profile (an "
                             "xarray.Dataset) and a profile with molecule_profile='sounding' "
                             f"or None; got molecule_profile={molecule_profile!r} and "
                             f"profile {'given' if profile is not None else 'None'}")
        self.refractivity_profile = check_choice(
            "refractivity_profile",
            self.molecule_profile if refractivity_profile is None else refractivity_profile,
            _profiles.PROFILES)
        # named aerosol type (Mie tables) and wavelength-dependent albedo: None = scalars
        self.aerosol_type = (None if aerosol_type is None
                             else _aerosol.resolve_aerosol_type(aerosol_type))
        self.aerosol_albedo_spectrum = (
            None if aerosol_albedo_spectrum is None
            else check_choice("aerosol_albedo_spectrum", aerosol_albedo_spectrum,
                              AEROSOL_ALBEDO_SPECTRA))
        if self.aerosol_type is not None and self.aerosol_albedo_spectrum is not None:
            raise ValueError("give aerosol_type or aerosol_albedo_spectrum, not both; got "
                             f"{aerosol_type!r} and {aerosol_albedo_spectrum!r}")
        if aerosol_phase_model is None:
            aerosol_phase_model = ("cornetteshanks1992" if self.aerosol_type is None
                                   else "henyeygreenstein1941")
        self.aerosol_phase_model = check_choice("aerosol_phase_model", aerosol_phase_model,
                                                PHASE_FUNCTIONS)
        self.stratospheric_aerosol_profile = check_choice(
            "stratospheric_aerosol_profile", stratospheric_aerosol_profile,
            _aerosol.STRATOSPHERIC_PROFILES)
        stratospheric_aerosol_altitude_m, stratospheric_aerosol_width_m = \
            _stratospheric_layer_moments(self.stratospheric_aerosol_profile,
                                         stratospheric_aerosol_altitude_m,
                                         stratospheric_aerosol_width_m)
        if not isinstance(name, str):
            raise TypeError(f"name must be a string; got {name!r}")
        self.name = name
        self.planet_radius_m = float(_check_parameter("planet_radius_m", planet_radius_m))
        self.top_altitude_m = float(_check_parameter("top_altitude_m", top_altitude_m))
        if self.planet_radius_m == 0.0 or self.top_altitude_m == 0.0:
            # (checked above; kept explicit: both radii must be > 0)
            raise ValueError("planet_radius_m and top_altitude_m must be > 0")
        self.top_radius_m = self.planet_radius_m + self.top_altitude_m
        top_of_table = _aerosol.STRATOSPHERIC_PROFILE_ENDS_M[1]
        if self.stratospheric_aerosol_profile != "gaussian" \
                and self.top_altitude_m < top_of_table:
            raise ValueError(f"stratospheric_aerosol_profile={stratospheric_aerosol_profile!r} "
                             f"spans 10-35 km: top_altitude_m must be >= {top_of_table:g} m; "
                             f"got {self.top_altitude_m:g}")
        if self.refractivity_profile == "sounding" and self.sounding is None:
            raise ValueError("refractivity_profile='sounding' needs a profile (an "
                             "xarray.Dataset)")
        surface = _sounding_surface(self.sounding)
        surface_pressure_pa = (surface[0] if surface_pressure_pa is FROM_PROFILE
                               else surface_pressure_pa)
        surface_temperature_k = (surface[1] if surface_temperature_k is FROM_PROFILE
                                 else surface_temperature_k)
        if ozone_du is FROM_PROFILE:
            ozone_du = _sounding_ozone_du(self.sounding, self.top_altitude_m)
        if self.sounding is not None and "ozone_number_density_m3" in self.sounding:
            shaped = {key: value for key, value in (
                ("ozone_peak_altitude_m", ozone_peak_altitude_m),
                ("ozone_half_width_m", ozone_half_width_m)) if value is not None}
            if shaped:
                raise ValueError(f"{sorted(shaped)} shape the ozone tent, which the "
                                 "sounding's ozone profile replaces; got "
                                 + ", ".join(f"{k}={v!r}" for k, v in shaped.items()))
        ozone_peak_altitude_m = (OZONE_PEAK_ALTITUDE_M if ozone_peak_altitude_m is None
                                 else ozone_peak_altitude_m)
        ozone_half_width_m = (OZONE_HALF_WIDTH_M if ozone_half_width_m is None
                              else ozone_half_width_m)
        if molar_mass_kg_mol is None:
            molar_mass_kg_mol = (_rayleigh.air_molar_mass() if gas == "air"
                                 else _rayleigh.MARS_MOLAR_MASS_KG_MOL)
        given = {
            "surface_pressure_pa": surface_pressure_pa,
            "surface_temperature_k": surface_temperature_k,
            "gravity_m_s2": gravity_m_s2, "molar_mass_kg_mol": molar_mass_kg_mol,
            "rayleigh_scale_height_m": rayleigh_scale_height_m,
            "angstrom_beta": angstrom_beta, "angstrom_alpha": angstrom_alpha,
            "aerosol_scale_height_m": aerosol_scale_height_m,
            "aerosol_single_scattering_albedo": aerosol_single_scattering_albedo,
            "aerosol_asymmetry": aerosol_asymmetry, "ozone_du": ozone_du,
            "ozone_peak_altitude_m": ozone_peak_altitude_m,
            "ozone_half_width_m": ozone_half_width_m,
            "reference_refractivity": reference_refractivity,
            "reference_pressure_pa": reference_pressure_pa,
            "reference_temperature_k": reference_temperature_k,
            "stratospheric_aerosol_optical_depth": stratospheric_aerosol_optical_depth,
            "stratospheric_aerosol_altitude_m": stratospheric_aerosol_altitude_m,
            "stratospheric_aerosol_width_m": stratospheric_aerosol_width_m,
            "precipitable_water_cm": precipitable_water_cm,
        }
        values = {key: _check_parameter(key, value) for key, value in given.items()}
        for key in ("ozone_peak_altitude_m", "stratospheric_aerosol_altitude_m"):
            # a layer centred at or above the top (top_altitude_m) would hold its column
            # in no air (0 / 0)
            check_range(key, values[key], high=self.top_altitude_m, high_inclusive=False,
                        unit=" m")
        values["ozone_temperature_k"] = self._ozone_temperature(ozone_temperature_k, values,
                                                                self.sounding)
        for key, value in values.items():
            # not detached: parameters given as tensors with requires_grad stay
            # differentiable (e.g. fitting turbidity to observed extinction)
            self.register_buffer(key, value.to(torch.float64).clone())
        self.batch_shape = _parameter_batch_shape(values)

    # ------------------------------------------------------------------ presets
    @classmethod
    def earth(cls, turbidity=None, ozone_du=FROM_PROFILE, *, aerosol_optical_depth=None,
              angstrom_alpha=None, **options) -> Atmosphere:
        r"""Earth: air, U.S. Standard Atmosphere 1976 molecules, Preetham aerosols, ozone tent.

        One vertical structure: optical depths, scattering and the refractive index all
        follow the U.S. Standard Atmosphere 1976 density (``molecule_profile="us1976"``;
        horizon refraction 32.9' at 1013.25 hPa, 15 degC, Bennett 1982: 34.0'). Pass
        ``molecule_profile="exponential"`` for the isothermal 8 km exponential (closed
        forms; the refractivity follows it, horizon refraction 37.3', unless
        ``refractivity_profile`` is given too).

        Parameters
        ----------
        turbidity : float or Tensor, optional
            Preetham turbidity :math:`T` in :data:`TURBIDITY_RANGE` = [1, 64] (1:
            practically no aerosols, 10: hazy); :math:`\beta = 0.04608 T - 0.04586`,
            :math:`\alpha = 1.3` (ref. 3). Default 2 unless ``aerosol_optical_depth`` is
            given.
        ozone_du : float or Tensor, optional
            Ozone column [DU]; default 300, or the column of the sounding's
            ``ozone_number_density`` (given with such a sounding: its shape scaled to
            this column).
        aerosol_optical_depth : float or Tensor, optional
            Vertical aerosol optical depth at 550 nm, in [0, 100]; replaces
            ``turbidity`` (giving both raises ValueError).
        angstrom_alpha : float or Tensor, optional
            Ångström exponent [1]; default Preetham's 1.3. With ``aerosol_type`` and
            ``aerosol_optical_depth`` the type's Mie spectrum replaces it (giving it
            raises ValueError).
        **options
            Other constructor arguments (keywords of :class:`Atmosphere` except
            ``angstrom_beta``, which ``turbidity`` sets); an unknown keyword raises
            TypeError. ``precipitable_water_cm`` defaults to 1.4 cm here.

        Raises
        ------
        ValueError
            A turbidity outside [1, 64], NaN or inf (naming ``turbidity``).
        TypeError
            A turbidity that is not a number (a string, None inside a list, a bool).
        """
        _check_options("Atmosphere.earth", options, exclude=("angstrom_beta", "ozone_du"))
        _check_type_options("Atmosphere.earth", options)
        if (angstrom_alpha is not None and aerosol_optical_depth is not None
                and options.get("aerosol_type") is not None):
            raise ValueError(
                "Atmosphere.earth(): angstrom_alpha would not be used with aerosol_type="
                f"{options['aerosol_type']!r} and aerosol_optical_depth (the type's Mie "
                f"table gives the spectrum about 550 nm); got angstrom_alpha={angstrom_alpha!r}")
        if angstrom_alpha is None:
            angstrom_alpha = _aerosol.PREETHAM_ANGSTROM_ALPHA
        if aerosol_optical_depth is not None:
            if turbidity is not None:
                raise ValueError("give turbidity or aerosol_optical_depth, not both; got "
                                 f"turbidity={turbidity!r} and aerosol_optical_depth="
                                 f"{aerosol_optical_depth!r}")
            low, high = AEROSOL_OPTICAL_DEPTH_RANGE
            aod = _check_parameter("aerosol_optical_depth", aerosol_optical_depth, low=low,
                                   high=high, low_inclusive=True, unit="")
            alpha = _check_parameter("angstrom_alpha", angstrom_alpha)
            beta = aod * (550.0 / _aerosol.ANGSTROM_REFERENCE_NM) ** alpha
        else:
            low, high = TURBIDITY_RANGE
            turbidity = _check_parameter("turbidity", 2.0 if turbidity is None else turbidity,
                                         low=low, high=high, low_inclusive=True, unit="")
            beta = _aerosol.preetham_angstrom_beta(turbidity)
            alpha = angstrom_alpha
        settings = {"planet_radius_m": EARTH_MEAN_RADIUS_M,
                    "top_altitude_m": EARTH_TOP_OF_ATMOSPHERE_M, "name": "earth",
                    "molecule_profile": "us1976" if options.get("profile") is None
                    else "sounding",
                    "precipitable_water_cm": _gases.DEFAULT_PRECIPITABLE_WATER_CM}
        settings.update(options)
        sounding_ozone = "ozone_number_density" in getattr(options.get("profile"),
                                                           "variables", ())
        if ozone_du is FROM_PROFILE and not sounding_ozone:
            ozone_du = 300.0
        return cls(angstrom_beta=beta, angstrom_alpha=alpha, ozone_du=ozone_du, **settings)

    @classmethod
    def mars(cls, dust_optical_depth=_aerosol.MARS_DUST["optical_depth"], **options
             ) -> Atmosphere:
        """Mars: CO2 (n - 1 = 3.38e-6 at 610 Pa, 215 K), 11.1 km scale height, dust.

        Parameters
        ----------
        dust_optical_depth : float or Tensor
            Vertical dust optical depth at 880 nm, in [0, 100] (default 0.5, background).
        **options
            Constructor arguments that replace the Martian defaults; an unknown keyword
            raises TypeError.
        """
        _check_options("Atmosphere.mars", options)
        _check_type_options("Atmosphere.mars", options)
        dust = _aerosol.MARS_DUST
        tau = _check_parameter("dust_optical_depth", dust_optical_depth,
                               low=AEROSOL_OPTICAL_DEPTH_RANGE[0],
                               high=AEROSOL_OPTICAL_DEPTH_RANGE[1], low_inclusive=True, unit="")
        beta = tau * (dust["reference_wavelength_nm"] / _aerosol.ANGSTROM_REFERENCE_NM) ** (
            dust["angstrom_alpha"])
        settings = {
            "planet_radius_m": MARS_MEAN_RADIUS_M, "top_altitude_m": MARS_TOP_OF_ATMOSPHERE_M,
            "surface_pressure_pa": MARS_SURFACE_PRESSURE_PA,
            "surface_temperature_k": MARS_SURFACE_TEMPERATURE_K,
            "gravity_m_s2": MARS_GRAVITY_M_S2, "gas": "co2",
            "rayleigh_scale_height_m": MARS_SCALE_HEIGHT_M,
            "angstrom_beta": beta, "angstrom_alpha": dust["angstrom_alpha"],
            "aerosol_scale_height_m": dust["scale_height_m"],
            "aerosol_single_scattering_albedo": dust["single_scattering_albedo"],
            "aerosol_asymmetry": dust["asymmetry"],
            "aerosol_phase_model": "henyeygreenstein1941", "ozone_du": 0.0,
            # wavelength-dependent dust albedo (Wolff et al. 2009 index), unless a type or
            # a scalar albedo is given
            "aerosol_albedo_spectrum": None if {"aerosol_type",
                                                "aerosol_single_scattering_albedo"} & set(options)
            else "mars_dust",
            "reference_refractivity": MARS_REFRACTIVITY_SURFACE,
            "reference_pressure_pa": MARS_SURFACE_PRESSURE_PA,
            "reference_temperature_k": MARS_SURFACE_TEMPERATURE_K, "name": "mars",
        }
        settings.update(options)
        return cls(**settings)

    # ------------------------------------------------------------------ parameters
    def parameters_dict(self) -> dict:
        """All parameters (lists for batched ones), e.g. for Dataset attributes and hashes."""
        result = {"name": self.name, "gas": self.gas, "molecule_profile": self.molecule_profile,
                  "sounding_sha256": _sounding_digest(self.sounding),
                  "refractivity_profile": self.refractivity_profile,
                  "aerosol_phase_model": self.aerosol_phase_model,
                  # listed only when set (the parameters of untyped atmospheres unchanged)
                  **({"aerosol_type": self.aerosol_type} if self.aerosol_type else {}),
                  **({"aerosol_albedo_spectrum": self.aerosol_albedo_spectrum}
                     if self.aerosol_albedo_spectrum else {}),
                  **({"stratospheric_aerosol_profile": self.stratospheric_aerosol_profile}
                     if self.stratospheric_aerosol_profile != "gaussian" else {}),
                  "planet_radius_m": self.planet_radius_m,
                  "top_altitude_m": self.top_altitude_m}
        for key in _PARAMETERS:
            value = getattr(self, key)
            result[key] = value.item() if value.ndim == 0 else value.tolist()
        return result

    def extra_repr(self) -> str:
        """Return the parameters as JSON, for the module's repr."""
        return json.dumps(self.parameters_dict())

    def _p(self, key: str, dtype: torch.dtype, trailing: int = 0) -> torch.Tensor:
        """Buffer ``key`` cast to ``dtype`` with ``trailing`` singleton dimensions.

        ``trailing`` counts every dimension the caller's tensors carry after the batch
        dims (sample dims, geometry dims beyond the parameters', the wavelength): it is
        passed explicitly, never held as state, so that one Atmosphere can be used from
        many threads at once.
        """
        value = getattr(self, key).to(dtype)
        if value.ndim == 0 or trailing == 0:  # a scalar broadcasts against anything
            return value
        return value.reshape(tuple(value.shape) + (1,) * trailing)

    def with_parameters(self, transform) -> Atmosphere:
        """Return a shallow copy whose parameter buffers are ``transform(buffer)``.

        e.g. laid out like a flat list of rays; the transformed buffers keep their autograd graph.
        """
        return self._with_parameters(transform)

    def _with_parameters(self, transform) -> Atmosphere:
        """Return a shallow copy whose parameter buffers are ``transform(buffer)``.

        Used to lay the parameters out like a flat list of rays (ray tracing that
        follows each ray separately); the copy shares everything else, the transformed
        buffers keep their autograd graph.
        """
        clone = copy.copy(self)
        clone._buffers = {key: transform(value) for key, value in self._buffers.items()}
        clone.batch_shape = _parameter_batch_shape(
            {key: value for key, value in clone._buffers.items() if key in _PARAMETERS})
        return clone

    # ------------------------------------------------------------------ species
    def profiles(self, dtype: torch.dtype = torch.float64) -> dict[str, Profile]:
        """Return the vertical profile of every species.

        By name (see :class:`skytorch.atmosphere.constituents.Profile`).

        Parameters
        ----------
        dtype : torch.dtype
            Floating dtype of the profiles' parameters.

        Returns
        -------
        dict of Profile
            Keys of :data:`SPECIES`.
        """
        return {builder.name: builder.profile(self, dtype) for builder in SPECIES_BUILDERS}

    def constituents(self, wavelength_nm, dtype: torch.dtype | None = None, *,
                     extra_species: tuple = ()) -> Constituents:
        """Every species at ``wavelength_nm``: the interface that every kernel takes.

        Parameters
        ----------
        wavelength_nm : Tensor (wavelength,)
            Wavelength [nm], in :data:`WAVELENGTH_RANGE_NM`.
        dtype : torch.dtype, optional
            Floating dtype of the result (default: that of ``wavelength_nm``).
        extra_species : tuple of SpeciesBuilder
            Species added after those of :data:`SPECIES_BUILDERS` (experiments; the
            library's species are listed there).

        Returns
        -------
        Constituents
            Immutable; profiles, coefficients (*batch, wavelength) [1/m], albedos, phase
            functions, optical-depth laws and quadrature breakpoints
            (:mod:`skytorch.atmosphere.constituents`).

        Examples
        --------
        >>> import torch
        >>> atm = Atmosphere.earth(turbidity=torch.tensor([2.0, 3.0]))
        >>> c = atm.constituents(torch.tensor([550.0]))
        >>> tuple(c["aerosol"].extinction.shape)
        (2, 1)
        """
        dtype = _floating_dtype(dtype, wavelength_nm)
        return self._constituents(wavelength_tensor(wavelength_nm, dtype), extra_species)

    def _constituents(self, wavelength: torch.Tensor, extra_species: tuple = ()
                      ) -> Constituents:
        """:meth:`constituents` of a checked wavelength tensor."""
        dtype = wavelength.dtype
        species = []
        for builder in (*SPECIES_BUILDERS, *extra_species):
            if not isinstance(builder, SpeciesBuilder):
                raise TypeError("species builders must be skytorch.atmosphere.constituents."
                                f"SpeciesBuilder; got {type(builder).__name__}")
            built = builder.build(self, wavelength, dtype, builder.profile(self, dtype))
            if builder.absent is not None and builder.absent(self):
                built = dataclasses.replace(built, vanishes=True)
            species.append(built)
        return Constituents(wavelength, tuple(species), self.planet_radius_m,
                            self.top_radius_m, self.batch_shape)

    def molecular_column_m2(self, dtype: torch.dtype = torch.float64) -> torch.Tensor:
        """Vertical column of molecules :math:`p N_A/(m g)` [m^-2], shape ``batch_shape``."""
        return self._molecular_column(dtype)

    def _molecular_column(self, dtype: torch.dtype, extra: int = 0) -> torch.Tensor:
        return (self._p("surface_pressure_pa", dtype, extra) * AVOGADRO_PER_MOL
                / (self._p("molar_mass_kg_mol", dtype, extra)
                   * self._p("gravity_m_s2", dtype, extra)))

    def _shape_profile(self, kind: str, dtype: torch.dtype):
        """Return the molecular density shape ``kind`` as a function of altitude.

        ``kind`` is "exponential", "us1976" or "sounding"; the function has a trailing sample dim
        (refractivity).
        """
        if kind == "sounding":
            return _sounding_molecules(self, dtype)[0]
        if kind == "us1976":
            return _profiles.us1976
        height = self._p("rayleigh_scale_height_m", dtype, 1)
        return lambda h: _profiles.exponential(h, height)

    @staticmethod
    def _ozone_temperature(given, values: dict, sounding=None) -> torch.Tensor:
        """Return ``ozone_temperature_k`` checked, or its default [K].

        By default the US 1976 tent average (with a sounding that gives ozone: its ozone-weighted
        temperature).
        """
        if given is not None:
            return _check_parameter("ozone_temperature_k", given)
        if sounding is not None and "ozone_number_density_m3" in sounding:
            weight = sounding["ozone_number_density_m3"]
            temperature = torch.trapezoid(weight * sounding["temperature_k"],
                                          sounding["altitude_m"]) / torch.trapezoid(
                weight, sounding["altitude_m"])
        else:
            temperature = _ozone.ozone_effective_temperature(values["ozone_peak_altitude_m"],
                                                             values["ozone_half_width_m"])
        low, high = _ozone.OZONE_TEMPERATURE_RANGE_K
        with torch.no_grad():
            bad = (temperature < low) | (temperature > high)
            if bool(bad.any()):
                raise ValueError(
                    f"ozone_temperature_k must be in [{low}, {high}] K; its default, the US "
                    "1976 temperature averaged over the ozone tent (ozone_peak_altitude_m, "
                    f"ozone_half_width_m), is {float(temperature[bad].reshape(-1)[0]):.2f} K "
                    "there: pass ozone_temperature_k or a lower ozone layer")
        return temperature

    def _stratospheric_absent(self) -> bool:
        """Whether the stratospheric aerosol is exactly zero everywhere, without gradient."""
        tau = self.stratospheric_aerosol_optical_depth
        return not tau.requires_grad and not bool(tau.detach().any())

    def _ozone_absent(self) -> bool:
        """Whether the ozone column is exactly zero everywhere and needs no gradient."""
        ozone = self.ozone_du
        return not ozone.requires_grad and not bool(ozone.detach().any())

    def reference_extinction(self, wavelength_nm) -> dict[str, torch.Tensor]:
        r"""Extinction coefficient of each species where its relative density is 1.

        The extinction coefficient of species ``s`` at altitude ``h`` is
        ``relative_density(s, h) * reference_extinction(wavelength_nm)[s]``, so the
        optical depth along any path, straight or refracted, is the path integral of the
        relative density times this coefficient
        (:func:`skytorch.atmosphere.refraction.bent_optical_depth` integrates the
        densities once and multiplies them here, for every wavelength at once).

        Parameters
        ----------
        wavelength_nm : Tensor (wavelength,)
            Wavelength [nm].

        Returns
        -------
        dict of Tensor (..., wavelength)
            ``"rayleigh"``, ``"aerosol"`` (scattering plus absorption), ``"ozone"`` and
            ``"stratospheric_aerosol"`` [1/m]; leading dims are the batch dims of the
            parameters.

        Notes
        -----
        Rayleigh: :math:`N_{col}\,\sigma_R(\lambda)/\int\rho\,dh` (the profile's
        ``column_height_m``); aerosol:
        :math:`\beta\,(\lambda/1000\,\mathrm{nm})^{-\alpha}/H_a`; ozone:
        :math:`\mathrm{DU}\,N_{DU}\,\sigma_{O_3}(\lambda)/w` (tent half width
        :math:`w`).

        Examples
        --------
        >>> import torch
        >>> atm = Atmosphere.earth(turbidity=1.0, ozone_du=0.0)
        >>> k = atm.reference_extinction(torch.tensor([550.0], dtype=torch.float64))
        >>> height = atm.profiles()["rayleigh"].column_height_m   # US 1976: 8.43 km
        >>> round(float(k["rayleigh"][0] * height), 4)   # vertical; Bodhaine 1999: 0.0971
        0.0969
        """
        constituents = self.constituents(wavelength_nm)
        return {species.name: species.extinction for species in constituents.species}

    @staticmethod
    def _wavelength(wavelength_nm, dtype=None) -> torch.Tensor:
        """Alias of :func:`wavelength_tensor` (kept for callers not yet switched)."""
        return wavelength_tensor(wavelength_nm, dtype)

    @staticmethod
    def _altitude(altitude_m, dtype) -> torch.Tensor:
        return altitude_tensor(altitude_m, dtype)

    def check_geometry(self, extra: int = 0, **named) -> torch.Size:
        """Broadcast shape of the named geometry tensors and the parameters' batch shape.

        Raises ValueError naming every input and its shape when they do not broadcast
        (before any arithmetic). With ``extra`` the last ``extra`` dims of the geometry
        follow the batch dims (the parameters are aligned before them).
        """
        return self._check_shapes(extra, **named)

    def _check_shapes(self, extra: int = 0, **named) -> torch.Size:
        """Broadcast shape of the named geometry tensors and the parameters' batch shape.

        Raises ValueError naming every input and its shape when they do not broadcast
        (before any arithmetic). With ``extra`` the last ``extra`` dims of the geometry
        follow the batch dims (the parameters are aligned before them).
        """
        shapes = {name: tuple(value.shape) for name, value in named.items()}
        batch = tuple(self.batch_shape) + (1,) * extra if self.batch_shape else ()
        try:
            return broadcast_shape(*shapes.values(), batch)
        except ValueError:
            listing = ", ".join(f"{name} {shape}" for name, shape in shapes.items())
            raise ValueError(f"shapes do not broadcast: {listing} and the atmosphere's "
                             f"parameters {tuple(self.batch_shape)}") from None

    # ------------------------------------------------------------------ local coefficients
    def _local(self, altitude_m, wavelength_nm):
        """Return the constituents and each species' local extinction (..., wavelength) [1/m]."""
        dtype = common_dtype(altitude_m, wavelength_nm)
        constituents = self._constituents(wavelength_tensor(wavelength_nm, dtype))
        altitude = altitude_tensor(altitude_m, dtype)
        self._check_shapes(altitude_m=altitude)
        local = constituents.extinction_coefficients(altitude[..., None])
        return constituents, altitude, {key: value[..., 0, :] for key, value in local.items()}

    def extinction_coefficient(self, altitude_m, wavelength_nm) -> torch.Tensor:
        """Total extinction coefficient (scattering + absorption).

        Parameters
        ----------
        altitude_m : Tensor (...)
            Altitude above the surface [m], >= 0.
        wavelength_nm : Tensor (wavelength,)
            Wavelength [nm].

        Returns
        -------
        Tensor (..., wavelength)
            Extinction coefficient [1/m]; leading dims broadcast altitude and parameters.
        """
        return sum(self._local(altitude_m, wavelength_nm)[2].values())

    def scattering_coefficients(self, altitude_m, wavelength_nm) -> dict[str, torch.Tensor]:
        """Scattering coefficients (..., wavelength) [1/m] of every species that scatters.

        A dict with keys ``{"rayleigh", "aerosol", "stratospheric_aerosol"}``.
        """
        constituents, altitude, _ = self._local(altitude_m, wavelength_nm)
        local = constituents.scattering_coefficients(altitude[..., None])
        return {key: value[..., 0, :] for key, value in local.items()}

    def absorption_coefficient(self, altitude_m, wavelength_nm) -> torch.Tensor:
        """Absorption coefficient: ozone + aerosol absorption (..., wavelength) [1/m]."""
        constituents, altitude, extinction = self._local(altitude_m, wavelength_nm)
        scattering = constituents.scattering_coefficients(altitude[..., None])
        return sum(value - scattering[key][..., 0, :] if key in scattering else value
                   for key, value in extinction.items())

    def stratospheric_aerosol_phase(self, cos_theta, wavelength_nm) -> torch.Tensor:
        """Henyey-Greenstein phase function of the stratospheric sulfate layer [1/sr].

        Parameters
        ----------
        cos_theta : Tensor (...)
            Cosine of the scattering angle, in [-1, 1].
        wavelength_nm : Tensor (wavelength,)
            Wavelength [nm] (the asymmetry parameter of the Mie table depends on it).

        Returns
        -------
        Tensor (..., wavelength)
            Phase function normalised over 4π.
        """
        cos_theta = check_range("cos_theta", cos_theta, -1.0, 1.0)
        dtype = common_dtype(cos_theta, wavelength_nm)
        wavelength = wavelength_tensor(wavelength_nm, dtype)
        g = _aerosol.sulfate_mie_properties(wavelength)[2]
        return phase_function(cos_theta.to(dtype)[..., None], g, "henyeygreenstein1941")

    def aerosol_phase(self, cos_theta) -> torch.Tensor:
        """Aerosol phase function [1/sr], normalised over 4π; shape broadcast(cos, batch).

        Without wavelength: ValueError for an ``aerosol_type`` (its asymmetry depends on
        the wavelength; use ``constituents(wavelength_nm)["aerosol"].phase``).
        """
        if self.aerosol_type is not None:
            raise ValueError(f"aerosol_type={self.aerosol_type!r}: the aerosol phase "
                             "function depends on the wavelength; use "
                             "constituents(wavelength_nm)['aerosol'].phase")
        cos_theta = check_range("cos_theta", cos_theta, -1.0, 1.0)
        self._check_shapes(cos_theta=cos_theta)
        return phase_function(cos_theta, self._p("aerosol_asymmetry", cos_theta.dtype),
                              self.aerosol_phase_model)

    def relative_density(self, species: str, altitude_m) -> torch.Tensor:
        """Dimensionless density profile of ``species`` (1 at the surface for molecules)."""
        check_choice("species", species, SPECIES)
        altitude = altitude_tensor(altitude_m, common_dtype(altitude_m))
        self._check_shapes(altitude_m=altitude)
        return self.profiles(altitude.dtype)[species](altitude[..., None])[..., 0]

    @property
    def refractivity_breakpoints_m(self) -> tuple[float, ...]:
        """Altitudes where the quadrature of refracted rays is split [m].

        The kinks of the refractivity profile (:attr:`refractivity_kinks_m`) and, for
        the US 1976 profile, levels at 1, 2, 4 and 8 km (panels of the Gauss–Legendre
        rules along the ray); empty for the exponential profile.
        """
        if self.refractivity_profile == "sounding":
            return self.refractivity_kinks_m
        return _US1976_BREAKS_M if self.refractivity_profile == "us1976" else ()

    @property
    def refractivity_kinks_m(self) -> tuple[float, ...]:
        r"""Altitudes where :math:`\mathrm{d}n/\mathrm{d}h` jumps [m].

        The U.S. Standard Atmosphere 1976 layer bases (its lapse rate jumps there); empty
        for the exponential profile. The bending of a ray whose lowest point lies just
        below a kink varies like the square root of the distance to it, so tables over
        impact parameter place nodes there (e.g.
        :meth:`skytorch.eclipse.shadow.Shadow.ring_profile`).
        """
        if self.refractivity_profile == "sounding":
            # the levels of the sounding (its log-density slope changes there)
            return tuple(float(h) for h in self.sounding["altitude_m"]
                         if 0.0 < float(h) < self.top_altitude_m)
        if self.refractivity_profile != "us1976":
            return ()
        return tuple(h for h in _profiles.US1976_KINK_ALTITUDES_M if h < self.top_altitude_m)

    # ------------------------------------------------------------------ state of the gas
    def temperature_k(self, altitude_m) -> torch.Tensor:
        r"""Temperature of the gas [K] at ``altitude_m`` (...) [m].

        Shape broadcast with the parameters.

        ``"us1976"``: the standard's temperature times ``surface_temperature_k / 288.15``;
        ``"exponential"``: isothermal at ``surface_temperature_k``; ``"sounding"``: the
        sounding's temperature interpolated linearly (held above its top), scaled to
        ``surface_temperature_k`` at 0 m. With :meth:`pressure_pa` it gives the molecular
        number density shape, :math:`p/(kT) \propto \rho(h)`.
        """
        dtype = common_dtype(altitude_m)
        altitude = altitude_tensor(altitude_m, dtype)
        self._check_shapes(altitude_m=altitude)
        surface = self._p("surface_temperature_k", dtype)
        if self.molecule_profile == "exponential":
            return surface + 0.0 * altitude
        if self.molecule_profile == "us1976":
            return surface / STANDARD_TEMPERATURE_K * _profiles.us1976_temperature(altitude)
        nodes, values = self.sounding["altitude_m"], self.sounding["temperature_k"]
        zero = _profiles.piecewise_linear(torch.zeros((), dtype=torch.float64), nodes, values)
        return surface / zero.to(dtype) * _profiles.piecewise_linear(altitude, nodes, values,
                                                                     above=None)

    def pressure_pa(self, altitude_m) -> torch.Tensor:
        """Pressure of the gas [Pa] at ``altitude_m`` (...) [m].

        Shape broadcast with the parameters.

        ``surface_pressure_pa`` times the profile's pressure ratio: U.S. Standard
        Atmosphere 1976, :math:`e^{-h/H}` (exponential), or the sounding's pressure
        interpolated log-linearly (continued above its top with the top layer's scale
        height).
        """
        dtype = common_dtype(altitude_m)
        altitude = altitude_tensor(altitude_m, dtype)
        self._check_shapes(altitude_m=altitude)
        surface = self._p("surface_pressure_pa", dtype)
        if self.molecule_profile == "exponential":
            return surface * _profiles.exponential(altitude,
                                                   self._p("rayleigh_scale_height_m", dtype))
        if self.molecule_profile == "us1976":
            return surface * _profiles.us1976_pressure_ratio(altitude)
        nodes = self.sounding["altitude_m"]
        log_p = torch.log(self.sounding["pressure_pa"])
        zero = _profiles.log_linear(torch.zeros((), dtype=torch.float64), nodes, log_p)
        return surface / zero.to(dtype) * _profiles.log_linear(altitude, nodes, log_p)

    def water_vapour_profile(self, dtype: torch.dtype = torch.float64) -> Profile | None:
        """Return the sounding's water-vapour number density relative to its maximum, or None.

        ``h2o_vmr`` times :math:`p/(kT)` at the levels, interpolated linearly, zero above
        the top level; breakpoints at the levels; ``column_height_m`` its integral from
        0 m to the top [m]. None without a sounding or without ``h2o_vmr`` in it.
        """
        if self.sounding is None or "h2o_vmr" not in self.sounding:
            return None
        sounding = dict(self.sounding)
        sounding["ozone_number_density_m3"] = sounding["h2o_vmr"] * sounding["number_density_m3"]
        nodes, relative, _ = _sounding_ozone(sounding, self.top_altitude_m, dtype)
        return Profile(lambda h: _profiles.piecewise_linear(h, nodes, relative), {},
                       torch.trapezoid(relative, nodes), breakpoints_m=nodes, support=True)

    def refractivity(self, altitude_m, wavelength_nm=None) -> torch.Tensor:
        r"""Refractivity :math:`n - 1` of the gas at ``altitude_m``.

        Parameters
        ----------
        altitude_m : Tensor (...)
            Altitude [m], >= 0.
        wavelength_nm : Tensor (wavelength,), optional
            If given, the dispersion of air (Peck & Reeder 1972) is applied relative to
            589.3 nm and a trailing wavelength dimension is added.

        Returns
        -------
        Tensor (...) or (..., wavelength)
            :math:`(n-1)_{ref} (p/p_{ref})(T_{ref}/T) \rho(h)` [1], :math:`\rho` the
            ``refractivity_profile`` normalised to 1 at the ground.
        """
        dtype = common_dtype(altitude_m, wavelength_nm)
        altitude = altitude_tensor(altitude_m, dtype)
        self._check_shapes(altitude_m=altitude)
        surface = (self._p("reference_refractivity", dtype)
                   * self._p("surface_pressure_pa", dtype) / self._p("reference_pressure_pa",
                                                                     dtype)
                   * self._p("reference_temperature_k", dtype)
                   / self._p("surface_temperature_k", dtype))
        density = self._shape_profile(self.refractivity_profile, dtype)(
            altitude[..., None])[..., 0]
        value = surface * density
        if wavelength_nm is None:
            return value
        wavelength = wavelength_tensor(wavelength_nm, dtype)
        return value[..., None] * _rayleigh.refractivity_dispersion(wavelength)

    # ------------------------------------------------------------------ optical depth
    def column_integrals(self, zenith_rad=0.0, altitude_m=0.0, *, method: str = "gauss",
                         n_steps: int | None = None, rtol: float = 1e-9,
                         dtype: torch.dtype | None = None) -> dict[str, torch.Tensor]:
        r"""Path integrals :math:`\int \rho_s\,ds` [m] of each species' profile.

        Parameters
        ----------
        zenith_rad, altitude_m : Tensor (...)
            Ray zenith angle [rad] and observer altitude [m] (>= 0), broadcast with each
            other and with the parameters' batch shape.
        method, n_steps, rtol
            Quadrature, see :meth:`optical_depth`.
        dtype : torch.dtype, optional
            Computation dtype (default: that of the inputs).

        Returns
        -------
        dict of Tensor (...)
            Keys of :data:`SPECIES`; shapes broadcast geometry and parameters.
        """
        if dtype is not None and dtype not in (torch.float16, torch.bfloat16, torch.float32,
                                               torch.float64):
            raise TypeError(f"dtype must be a floating torch.dtype; got {dtype!r}")
        dtype = dtype or common_dtype(zenith_rad, altitude_m)
        zenith = check_zenith(zenith_rad, dtype=dtype)
        altitude = altitude_tensor(altitude_m, dtype)
        _check_quadrature(method, n_steps, rtol)
        self._check_shapes(zenith_rad=zenith, altitude_m=altitude)
        return self._columns(zenith, altitude, method, n_steps, rtol, dtype)

    def _columns(self, zenith, altitude, method, n_steps, rtol, dtype, extra: int = 0):
        """Column integrals of checked inputs (``extra``: geometry dims after the batch)."""
        vanishing = tuple(builder.name for builder in SPECIES_BUILDERS
                          if builder.absent is not None and builder.absent(self))
        return _constituents.column_integrals(
            self.profiles(dtype), self.planet_radius_m + altitude, torch.cos(zenith),
            self.planet_radius_m, self.top_radius_m, method=method, n_steps=n_steps,
            rtol=rtol, extra=extra, vanishing=vanishing, batch_shape=self.batch_shape)

    def optical_depth(self, wavelength_nm, zenith_rad=0.0, altitude_m=0.0, *,
                      method: str = "gauss", n_steps: int | None = None,
                      per_species: bool = False, refraction: bool = False,
                      rtol: float = 1e-9, n_nodes: int | None = None,
                      step_m: float | None = None, max_dh_m: float | None = None):
        r"""Slant optical depth along a straight (or refracted) ray to space or the ground.

        Parameters
        ----------
        wavelength_nm : Tensor (wavelength,)
            Wavelength [nm], in :data:`WAVELENGTH_RANGE_NM` (230–1100 nm where the ozone
            column is not zero: up to 1100 nm, the end of the ozone cross-sections).
        zenith_rad : Tensor (...)
            Zenith angle of the viewing direction at the observer [rad]; > π/2 looks
            down (the ray may hit the ground).
        altitude_m : Tensor (...)
            Observer altitude [m], >= 0 (above the top: the ray's path through the
            atmosphere); ValueError below the surface.
        method : {"gauss", "trapezoid", "adaptive"}
            Quadrature (:mod:`skytorch.atmosphere.optical_depth`); with
            ``refraction=True``: ``"gauss"`` (= ``"bouguer"``) or ``"rk4"``.
        n_steps : int, optional
            Resolution of the quadrature (default per method).
        per_species : bool
            Return a dict of :data:`SPECIES` (Rayleigh, aerosol, ozone, the stratospheric
            aerosol and the absorbing gases: water vapour, O2 and the O2-O2 pairs) instead of the
            total.
        refraction : bool
            Integrate along the refracted ray (:mod:`skytorch.atmosphere.refraction`).
        rtol : float
            Relative tolerance of ``method="adaptive"``, > 0.
        n_nodes, step_m, max_dh_m : optional
            Resolution of the refracted ray (``refraction=True`` only; see
            :func:`skytorch.atmosphere.refraction.bent_optical_depth`).

        Returns
        -------
        Tensor (..., wavelength) or dict of them
            Optical depth [1]; ``...`` broadcasts ``zenith_rad``, ``altitude_m`` and the
            parameters' batch shape (ValueError naming the shapes otherwise).

        Notes
        -----
        :math:`\tau(\lambda) = \sum_s k_s(\lambda)\int \rho_s(h(s))\,ds`: the path
        integrals are computed per species (3) and multiplied by the spectral
        coefficients, so the cost does not grow with the number of wavelengths.
        """
        check_flag("per_species", per_species)
        check_flag("refraction", refraction)
        if refraction:
            from skytorch.atmosphere import refraction as _refraction

            options = {key: value for key, value in (("n_nodes", n_nodes), ("step_m", step_m),
                                                     ("max_dh_m", max_dh_m))
                       if value is not None}
            return _refraction.bent_optical_depth(self, wavelength_nm, zenith_rad, altitude_m,
                                                  method=method, n_steps=n_steps,
                                                  per_species=per_species, rtol=rtol,
                                                  **options)
        given = [key for key, value in (("n_nodes", n_nodes), ("step_m", step_m),
                                        ("max_dh_m", max_dh_m)) if value is not None]
        if given:
            raise TypeError(f"{', '.join(given)} apply to refracted rays only (refraction="
                            "True); straight rays take method, n_steps and rtol")
        dtype = common_dtype(wavelength_nm, zenith_rad, altitude_m)
        wavelength = wavelength_tensor(wavelength_nm, dtype)
        zenith = check_zenith(zenith_rad, dtype=dtype)
        altitude = altitude_tensor(altitude_m, dtype)
        _check_quadrature(method, n_steps, rtol)
        shape = self._check_shapes(zenith_rad=zenith, altitude_m=altitude)
        if not self.batch_shape and method != "adaptive" and math.prod(shape) > 2 * RAY_CHUNK:
            return self._chunked_optical_depth(wavelength, zenith, altitude, shape,
                                               method=method, n_steps=n_steps,
                                               per_species=per_species)
        return self._optical_depth(wavelength, zenith, altitude, method=method,
                                   n_steps=n_steps, rtol=rtol, per_species=per_species)

    def _chunked_optical_depth(self, wavelength, zenith, altitude, shape, *, method, n_steps,
                               per_species):
        """:meth:`_optical_depth` of many rays, :data:`RAY_CHUNK` rays at a time.

        Scalar parameters and a fixed quadrature only: every ray is then integrated on its
        own, so the values are those of one call, and the temporaries of a chunk stay in
        cache (docs/refraction_elevated.md); the constituents are built once for all the
        chunks.
        """
        zenith = zenith.expand(shape).reshape(-1)
        altitude = altitude.expand(shape).reshape(-1)
        constituents = self._constituents(wavelength)  # built once for all the chunks
        parts = [self._optical_depth(wavelength, zenith[start:start + RAY_CHUNK],
                                     altitude[start:start + RAY_CHUNK], method=method,
                                     n_steps=n_steps, per_species=per_species,
                                     constituents=constituents)
                 for start in range(0, zenith.numel(), RAY_CHUNK)]
        if per_species:
            return {key: torch.cat([part[key] for part in parts]).reshape(
                *shape, wavelength.numel()) for key in parts[0]}
        return torch.cat(parts).reshape(*shape, wavelength.numel())

    def _optical_depth(self, wavelength, zenith, altitude, *, method="gauss", n_steps=None,
                       rtol=1e-9, per_species=False, extra: int = 0, constituents=None):
        """Straight-ray optical depth of checked inputs.

        ``extra`` geometry dims follow the parameters' batch dims (e.g. samples along a view ray),
        before the wavelength; ``constituents`` (those of ``wavelength``) are built when not
        given.
        """
        if constituents is None:
            constituents = self._constituents(wavelength)
        columns = constituents.column_integrals(self.planet_radius_m + altitude,
                                                torch.cos(zenith), method=method,
                                                n_steps=n_steps, rtol=rtol, extra=extra)
        return constituents.optical_depth(columns, per_species=per_species, extra=extra)

    def transmittance(self, wavelength_nm, zenith_rad=0.0, altitude_m=0.0, **options
                      ) -> torch.Tensor:
        r"""Direct transmittance :math:`e^{-\tau}` (..., wavelength) [1].

        Exactly 0 when :math:`\tau` is huge (use :meth:`optical_depth` for log-transmittance).

        ``options`` are the keywords of :meth:`optical_depth` (an unknown one raises
        TypeError); ``per_species`` is not one of them.
        """
        if "per_species" in options:
            raise TypeError("transmittance() got an unexpected keyword argument "
                            "'per_species' (use optical_depth)")
        return torch.exp(-self.optical_depth(wavelength_nm, zenith_rad, altitude_m, **options))

    def air_mass(self, zenith_rad, altitude_m=0.0, *, species: str = "rayleigh",
                 method: str = "gauss", n_steps: int | None = None, rtol: float = 1e-9,
                 refraction: bool = False, n_nodes: int | None = None,
                 step_m: float | None = None, max_dh_m: float | None = None
                 ) -> torch.Tensor:
        """Relative air mass: slant column over vertical column of ``species`` [1].

        Straight rays; pass ``refraction=True`` for refracted rays (the other keywords as
        for :meth:`optical_depth`).
        """
        check_choice("species", species, SPECIES)
        check_flag("refraction", refraction)
        dtype = common_dtype(zenith_rad, altitude_m)
        zenith = check_zenith(zenith_rad, dtype=dtype)
        if refraction:
            wavelength = torch.tensor([550.0], dtype=dtype)
            options = {"method": method, "n_steps": n_steps, "rtol": rtol}
            slant = self.optical_depth(wavelength, zenith, altitude_m, refraction=True,
                                       per_species=True, n_nodes=n_nodes, step_m=step_m,
                                       max_dh_m=max_dh_m, **options)[species][..., 0]
            straight = {"method": "gauss" if method in ("bouguer", "rk4") else method,
                        "n_steps": n_steps, "rtol": rtol}
            vertical = self.optical_depth(wavelength, 0.0 * zenith, altitude_m,
                                          per_species=True, **straight)[species][..., 0]
            _check_vertical(species, vertical, altitude_m)
            return slant / vertical
        given = [key for key, value in (("n_nodes", n_nodes), ("step_m", step_m),
                                        ("max_dh_m", max_dh_m)) if value is not None]
        if given:
            raise TypeError(f"{', '.join(given)} apply to refracted rays only (refraction="
                            "True)")
        slant = self.column_integrals(zenith, altitude_m, method=method, n_steps=n_steps,
                                      rtol=rtol)[species]
        vertical = self.column_integrals(torch.zeros_like(zenith), altitude_m, method=method,
                                         n_steps=n_steps, rtol=rtol)[species]
        _check_vertical(species, vertical, altitude_m)
        return slant / vertical

    def sky_radiance(self, wavelength_nm, view_zenith_rad, view_azimuth_rad=0.0,
                     sun_zenith_rad=0.0, sun_azimuth_rad=0.0, altitude_m=0.0, *,
                     solar_irradiance: bool = False, n_samples: int | None = None, table=None,
                     sun_steps: int | None = None, scattering_orders="converged",
                     ground_albedo=0.0, tables=None, final_gather: bool = False
                     ) -> torch.Tensor:
        """Sky radiance (..., wavelength), every order of scattering by default.

        Per unit solar irradiance [sr^-1], or with ``solar_irradiance=True`` times the
        extraterrestrial solar spectrum (:func:`skytorch.spectrum.solar_irradiance`)
        [W m^-2 sr^-1 nm^-1].

        ``scattering_orders`` is ``"converged"`` (the default: orders are added until the
        sum with its geometric remainder is stable to 1e-4, see
        :func:`~skytorch.atmosphere.multiple_scattering.precompute_scattering`), an
        integer N (orders 1..N) or 1 (single
        scattering). Over a black ground (``ground_albedo=0``, the default) order 1 is the
        ray-marched single-scattering kernel, :func:`skytorch.atmosphere.scattering.
        single_scattering_radiance` (``n_samples``, default 128, ``table`` and
        ``sun_steps`` are its parameters; ``table`` must have been built for this
        atmosphere and these wavelengths), and the orders 2..N come from the
        multiple-scattering tables of :mod:`skytorch.atmosphere.multiple_scattering`:
        ``tables`` (a :class:`~skytorch.atmosphere.multiple_scattering.ScatteringTables`
        built for this atmosphere, these wavelengths and this albedo) or, without it,
        tables built on each call by ``precompute_scattering`` at the default resolution
        (about a minute for three wavelengths on 2 cores: pass ``tables`` when calling
        more than once, or ``scattering_orders=1`` for the single-scattered sky alone,
        which takes no ``tables``). Over a Lambertian ground (``ground_albedo`` non-zero,
        scalar or per wavelength) every order, the Sun reflected once by the ground
        included, comes from the tables, and passing ``n_samples``, ``table`` or
        ``sun_steps`` raises ValueError.

        ``final_gather=True`` (orders >= 2, an atmosphere with scalar parameters) does the
        last scattering along the line of sight instead of looking the orders >= 2 up
        (:func:`skytorch.atmosphere.final_gather.higher_orders_gathered`, default
        quadrature): the tables' interpolation error averaged by one more phase integral
        (against DISORT at aerosol optical depth 0.3 on the default tables: 0.48 % instead
        of 1.1 %), at ~65 000 table look-ups per line of sight.
        """
        from skytorch.atmosphere.scattering import single_scattering_radiance

        check_flag("solar_irradiance", solar_irradiance)
        black = _check_sky_options(scattering_orders, final_gather, ground_albedo, tables,
                                   {"n_samples": n_samples, "table": table,
                                    "sun_steps": sun_steps})
        radiance = None
        if black:
            radiance = single_scattering_radiance(self, wavelength_nm, view_zenith_rad,
                                                  view_azimuth_rad, sun_zenith_rad,
                                                  sun_azimuth_rad, altitude_m,
                                                  n_samples=128 if n_samples is None
                                                  else n_samples, table=table,
                                                  sun_steps=sun_steps)
        if scattering_orders != 1 or not black:
            radiance = _multiple_scattering_sky(
                self, wavelength_nm, (altitude_m, view_zenith_rad, view_azimuth_rad,
                                      sun_zenith_rad, sun_azimuth_rad),
                scattering_orders, ground_albedo, tables, final_gather, radiance)
        if solar_irradiance:
            from skytorch.spectrum import solar_irradiance as irradiance

            wavelength = wavelength_tensor(wavelength_nm, radiance.dtype)
            radiance = radiance * irradiance(wavelength).to(radiance.dtype)
        return radiance

    # ------------------------------------------------------------------ refraction
    def refraction(self, apparent_altitude_rad, altitude_m=0.0, **options) -> torch.Tensor:
        """Astronomical refraction, apparent minus true altitude [rad] (ray traced).

        Delegates to :func:`skytorch.atmosphere.refraction.refraction_angle` (``options``
        are its keywords; an unknown one raises TypeError).
        """
        from skytorch.atmosphere import refraction as _refraction

        return _refraction.refraction_angle(self, apparent_altitude_rad, altitude_m, **options)

    def apparent_altitude(self, true_altitude_rad, altitude_m=0.0, **options) -> torch.Tensor:
        """Apparent altitude of a source at ``true_altitude_rad`` [rad].

        The inverse of :meth:`refraction`; delegates to :mod:`skytorch.atmosphere.refraction`.
        """
        from skytorch.atmosphere import refraction as _refraction

        return _refraction.apparent_altitude(self, true_altitude_rad, altitude_m, **options)

    def forward(self, wavelength_nm, zenith_rad=0.0, altitude_m=0.0, **options
                ) -> torch.Tensor:
        """Return same as :meth:`transmittance`."""
        return self.transmittance(wavelength_nm, zenith_rad, altitude_m, **options)


def _check_sky_options(scattering_orders, final_gather, ground_albedo, tables, marching):
    """ValueError for options of :meth:`Atmosphere.sky_radiance` that would go unused.

    ``marching``: the ray-marched single scattering's keywords {name: value or None}.
    Returns whether the ground is black (a Python number 0; a tensor albedo, even of
    zeros, goes to the tables).
    """
    check_flag("final_gather", final_gather)
    if not (scattering_orders == "converged" or (
            not isinstance(scattering_orders, (bool, str))
            and isinstance(scattering_orders, int) and scattering_orders >= 1)):
        raise ValueError("scattering_orders must be an integer >= 1 or 'converged'; "
                         f"got {scattering_orders!r}")
    if final_gather and scattering_orders == 1:
        raise ValueError("final_gather=True gathers the orders >= 2; scattering_orders=1 "
                         "has none (pass 2 or more, or 'converged')")
    if ground_albedo is None or isinstance(ground_albedo, (bool, str)):
        raise TypeError(f"ground_albedo must be a number or a tensor in [0, 1]; got "
                        f"{ground_albedo!r}")
    # a Python number 0 (not a bool): anything else goes to the tables, which check it
    black = (isinstance(ground_albedo, (int, float)) and not isinstance(ground_albedo, bool)
             and ground_albedo == 0.0)
    given = [name for name, value in marching.items() if value is not None]
    if not black and given:
        raise ValueError(f"{', '.join(given)}: parameters of the ray-marched single "
                         "scattering, which serves a black ground only; over "
                         f"ground_albedo={ground_albedo!r} every order comes from the "
                         "multiple-scattering tables")
    if black and scattering_orders == 1 and tables is not None:
        raise ValueError("tables: scattering_orders=1 over a black ground is the "
                         "ray-marched single scattering, which uses no "
                         "multiple-scattering tables (pass scattering_orders >= 2 or "
                         "'converged', or leave tables out)")
    return black


def _multiple_scattering_sky(atmosphere, wavelength_nm, geometry, scattering_orders,
                             ground_albedo, tables, final_gather, single):
    """Orders 1..N of :meth:`Atmosphere.sky_radiance` from the scattering tables.

    ``geometry`` is (altitude, view zenith, view azimuth, Sun zenith, Sun azimuth);
    ``single`` the ray-marched order 1 over a black ground (None over a Lambertian one,
    where the tables' order 1 holds the Sun reflected once by the ground).
    """
    from skytorch.atmosphere import multiple_scattering as _ms

    dtype = _floating_dtype(None, wavelength_nm, geometry[1], geometry[3])
    wavelength = wavelength_tensor(wavelength_nm, dtype)
    if tables is None:
        tables = _ms.precompute_scattering(atmosphere, wavelength, ground_albedo=ground_albedo,
                                           scattering_orders=scattering_orders, dtype=dtype)
    elif not isinstance(tables, _ms.ScatteringTables):
        raise TypeError(f"tables must be a ScatteringTables; got {type(tables).__name__}")
    elif (tables.wavelength_nm.shape != wavelength.shape or not torch.allclose(
            tables.wavelength_nm.to(torch.float64), wavelength.to(torch.float64))):
        raise ValueError(f"tables were built for other wavelengths: "
                         f"{tables.wavelength_nm.tolist()} nm, not {wavelength.tolist()} nm")
    else:
        tables.check_built_for(atmosphere, ground_albedo)
        if scattering_orders == "converged":  # the default
            tables.check_converged()
    if single is None and not final_gather:
        return tables.radiance(*geometry, scattering_orders=scattering_orders)
    first = single if single is not None else tables.radiance(*geometry, scattering_orders=1)
    if final_gather:
        from skytorch.atmosphere.final_gather import higher_orders_gathered

        return first + higher_orders_gathered(tables, atmosphere, *geometry,
                                              scattering_orders=scattering_orders)
    return first + (tables.radiance(*geometry, scattering_orders=scattering_orders)
                    - tables.radiance(*geometry, scattering_orders=1))


def _floating_dtype(dtype, *tensors) -> torch.dtype:
    if dtype is None:
        return common_dtype(*tensors)
    if dtype not in (torch.float16, torch.bfloat16, torch.float32, torch.float64):
        raise TypeError(f"dtype must be a floating torch.dtype; got {dtype!r}")
    return dtype


# ---------------------------------------------------------------------- species builders
# Each species: profile(atmosphere, dtype) -> Profile and build(atmosphere, wavelength,
# dtype, profile) -> Species (see skytorch.atmosphere.constituents, "Adding a species").
# Spectral coefficients are formed in float64 and cast: p N_A / (m g) alone overflows
# float32 at the edge of PARAMETER_RANGES (the coefficients are far inside its range).

def _sounding_surface(sounding) -> tuple[float, float]:
    """Surface pressure [Pa] and temperature [K]: standard, or the sounding's at 0 m."""
    if sounding is None:
        return STANDARD_PRESSURE_PA, STANDARD_TEMPERATURE_K
    zero = torch.zeros((), dtype=torch.float64)
    pressure = _profiles.log_linear(zero, sounding["altitude_m"],
                                    torch.log(sounding["pressure_pa"]))
    temperature = _profiles.piecewise_linear(zero, sounding["altitude_m"],
                                             sounding["temperature_k"])
    return float(pressure), float(temperature)


def _sounding_ozone_du(sounding, top_m: float) -> float:
    """Return the ozone column of the sounding from 0 m to the top [DU] (0 without ozone)."""
    if sounding is None or "ozone_number_density_m3" not in sounding:
        return 0.0
    nodes, relative, peak = _sounding_ozone(sounding, top_m, torch.float64)
    return float(torch.trapezoid(relative, nodes) * peak / DOBSON_UNIT_PER_M2)


def _sounding_ozone(sounding, top_m: float, dtype):
    """Return the ozone levels clipped to [0, top] [m], the relative density, its maximum.

    The density is relative to its maximum there; the maximum is in [m^-3].
    """
    altitude = sounding["altitude_m"]
    density = sounding["ozone_number_density_m3"]
    inside = altitude[(altitude > 0.0) & (altitude < top_m)]
    ends = [torch.zeros(1, dtype=torch.float64)]
    if float(altitude[-1]) >= top_m:
        ends.append(torch.tensor([top_m], dtype=torch.float64))
    nodes = torch.cat([ends[0], inside, *ends[1:]])
    values = _profiles.piecewise_linear(nodes, altitude, density)
    peak = values.max()
    return nodes.to(dtype), (values / peak).to(dtype), peak


def _sounding_digest(sounding) -> str | None:
    if sounding is None:
        return None
    digest = hashlib.sha256()
    for key in sorted(sounding):
        digest.update(key.encode())
        digest.update(sounding[key].numpy().tobytes())
    return digest.hexdigest()


def _sounding_molecules(atm, dtype):
    """Return the sounding's molecular shape p/(kT) relative to 0 m.

    As (function, breakpoints, column height).
    """
    sounding = atm.sounding
    nodes = sounding["altitude_m"]
    log_density = torch.log(sounding["number_density_m3"])
    log_density = log_density - torch.log(_profiles.log_linear(
        torch.zeros((), dtype=torch.float64), nodes, log_density))
    height = _profiles.log_linear_column(nodes, log_density)
    nodes_d, log_d = nodes.to(dtype), log_density.to(dtype)
    levels = nodes_d[(nodes > 0.0) & (nodes < atm.top_altitude_m)]

    def density(altitude_m):
        return _profiles.log_linear(altitude_m, nodes_d, log_d)

    return density, levels, height.to(dtype)


def _us1976_density(state) -> torch.Tensor:
    """Return the density ratio of a :func:`skytorch.atmosphere.profiles.us1976_state`."""
    return state[1]


def _rayleigh_profile(atm: Atmosphere, dtype: torch.dtype) -> Profile:
    if atm.molecule_profile == "sounding":
        density, levels, height = _sounding_molecules(atm, dtype)
        return Profile(density, {}, height, breakpoints_m=levels)
    if atm.molecule_profile == "us1976":
        return Profile(_profiles.us1976, {}, torch.tensor(_us1976_column_height_m(),
                                                          dtype=dtype),
                       breakpoints_m=torch.tensor(_US1976_BREAKS_M, dtype=dtype),
                       state=_profiles.us1976_state, from_state=_us1976_density,
                       piecewise_state=True)
    height = atm._p("rayleigh_scale_height_m", dtype)
    return Profile(_profiles.exponential, {"scale_height_m": height}, height,
                   relative_breakpoints_m=height[..., None]
                   * torch.tensor(_EXPONENTIAL_LEVELS, dtype=dtype), truncate=True)


def _rayleigh_species(atm, wavelength, dtype, profile) -> Species:
    wide = wavelength.to(torch.float64)
    density = atm._molecular_column(torch.float64) / profile.column_height_m.to(torch.float64)
    extinction = (density[..., None] * _rayleigh.rayleigh_cross_section(wide, atm.gas)
                  ).to(dtype)
    return Species("rayleigh", profile, extinction, extinction,
                   phase=lambda cos_theta, extra=0: rayleigh_phase(cos_theta)[..., None])


def _aerosol_profile(atm, dtype) -> Profile:
    height = atm._p("aerosol_scale_height_m", dtype)
    return Profile(_profiles.exponential, {"scale_height_m": height}, height,
                   relative_breakpoints_m=height[..., None]
                   * torch.tensor(_EXPONENTIAL_LEVELS, dtype=dtype), truncate=True)


def _aerosol_species(atm, wavelength, dtype, profile) -> Species:
    wide = wavelength.to(torch.float64)
    extinction = (atm._p("angstrom_beta", torch.float64, 1)
                  * (wide / _aerosol.ANGSTROM_REFERENCE_NM)
                  ** (-atm._p("angstrom_alpha", torch.float64, 1))
                  / atm._p("aerosol_scale_height_m", torch.float64, 1))
    if atm.aerosol_type is not None:
        return _typed_aerosol_species(atm, wide, dtype, profile)
    if atm.aerosol_albedo_spectrum == "mars_dust":
        albedo = _aerosol.mars_dust_properties(wide)[1]
    else:
        albedo = atm._p("aerosol_single_scattering_albedo", torch.float64, 1)
    scattering = albedo * extinction
    asymmetry = atm._p("aerosol_asymmetry", dtype)
    model = atm.aerosol_phase_model

    def phase(cos_theta, extra=0):
        return phase_function(cos_theta, _constituents.insert_dims(asymmetry, extra, 0),
                              model)[..., None]

    return Species("aerosol", profile, extinction.to(dtype), scattering.to(dtype), phase)


def _typed_aerosol_species(atm, wide, dtype, profile) -> Species:
    """Return the aerosol of a named type.

    The Ångström law's extinction at 550 nm times the type's Mie spectrum relative to 550 nm; Mie
    albedo; phase with the Mie g(λ).
    """
    ratio, albedo, asymmetry = _aerosol.aerosol_type_properties(atm.aerosol_type, wide)
    at_550 = (atm._p("angstrom_beta", torch.float64, 1)
              * (550.0 / _aerosol.ANGSTROM_REFERENCE_NM)
              ** (-atm._p("angstrom_alpha", torch.float64, 1))
              / atm._p("aerosol_scale_height_m", torch.float64, 1))
    extinction = at_550 * ratio  # (*batch, wavelength)
    g = asymmetry.to(dtype)
    model = atm.aerosol_phase_model

    def phase(cos_theta, extra=0):
        # per wavelength: the Mie table's asymmetry in the chosen analytic phase function
        return phase_function(cos_theta[..., None], g, model)

    return Species("aerosol", profile, extinction.to(dtype), (albedo * extinction).to(dtype),
                   phase)


def _ozone_profile(atm, dtype) -> Profile:
    if atm.sounding is not None and "ozone_number_density_m3" in atm.sounding:
        nodes, relative, _ = _sounding_ozone(atm.sounding, atm.top_altitude_m, dtype)
        return Profile(lambda h: _profiles.piecewise_linear(h, nodes, relative), {},
                       torch.trapezoid(relative, nodes), breakpoints_m=nodes, support=True)
    center = atm._p("ozone_peak_altitude_m", dtype)
    width = atm._p("ozone_half_width_m", dtype)
    levels = torch.stack(torch.broadcast_tensors(torch.clamp(center - width, min=0.0), center,
                                                 center + width), dim=-1)
    # the column between the ground and the top, so that a tent cut by either still holds
    # ozone_du
    column = _profiles.tent_column(center, width, atm.top_altitude_m)
    return Profile(_profiles.tent, {"center_m": center, "half_width_m": width}, column,
                   breakpoints_m=levels, support=True)


def _ozone_species(atm, wavelength, dtype, profile) -> Species:
    wide = wavelength.to(torch.float64)
    column = (atm._p("ozone_du", torch.float64, 1) * DOBSON_UNIT_PER_M2
              / profile.column_height_m.to(torch.float64)[..., None])
    if atm._ozone_absent():
        # a zero column needing no gradient: exactly zero at every wavelength, so the
        # cross-section table (214-1100 nm) is not needed
        extinction = column * torch.zeros_like(wide)
    else:
        extinction = column * ozone_cross_section(
            wide, atm._p("ozone_temperature_k", torch.float64, 1))
    return Species("ozone", profile, extinction.to(dtype))


def _stratospheric_layer_moments(profile: str, altitude_m, width_m):
    """Peak altitude and width of the Gaussian layer, or a tabulated profile's moments.

    The Gaussian's default is 20 km and 3 km; a tabulated profile takes neither (ValueError
    naming them) and returns its centroid and rms width [m].
    """
    if profile == "gaussian":
        return (20e3 if altitude_m is None else altitude_m,
                3e3 if width_m is None else width_m)
    if altitude_m is not None or width_m is not None:
        raise ValueError("stratospheric_aerosol_altitude_m and stratospheric_aerosol_width_m "
                         "shape the 'gaussian' layer only; got "
                         f"stratospheric_aerosol_profile={profile!r} with "
                         f"stratospheric_aerosol_altitude_m={altitude_m!r}, "
                         f"stratospheric_aerosol_width_m={width_m!r}")
    altitude, relative = (torch.as_tensor(a, dtype=torch.float64)
                          for a in _aerosol.stratospheric_profile_shape(profile))
    column = torch.trapezoid(relative, altitude)
    centroid = torch.trapezoid(relative * altitude, altitude) / column
    spread = torch.trapezoid(relative * (altitude - centroid) ** 2, altitude) / column
    return float(centroid), math.sqrt(float(spread))


def _tabulated_stratospheric_profile(atm, dtype) -> Profile:
    altitude, relative = _aerosol.stratospheric_profile_shape(atm.stratospheric_aerosol_profile)
    nodes = torch.tensor(altitude, dtype=dtype)
    values = torch.tensor(relative, dtype=dtype)
    return Profile(lambda h: _aerosol.tabulated_layer(h, nodes, values), {},
                   torch.trapezoid(values, nodes), breakpoints_m=nodes, support=True,
                   aloft=True)


def _stratospheric_profile(atm, dtype) -> Profile:
    if atm.stratospheric_aerosol_profile != "gaussian":
        return _tabulated_stratospheric_profile(atm, dtype)
    center = atm._p("stratospheric_aerosol_altitude_m", dtype)
    width = atm._p("stratospheric_aerosol_width_m", dtype)
    levels = torch.clamp(center[..., None] + width[..., None]
                         * torch.tensor(_GAUSSIAN_LEVELS, dtype=dtype), min=0.0)
    height = _aerosol.gaussian_layer_column(center, width, atm.top_altitude_m)
    return Profile(_aerosol.gaussian_layer, {"center_m": center, "width_m": width}, height,
                   breakpoints_m=levels, aloft=True)


def _stratospheric_species(atm, wavelength, dtype, profile) -> Species:
    wide = wavelength.to(torch.float64)
    extinction, albedo, asymmetry = _aerosol.sulfate_mie_properties(wide)
    if atm.stratospheric_aerosol_profile == "gaussian":
        height = _aerosol.gaussian_layer_column(
            atm._p("stratospheric_aerosol_altitude_m", torch.float64, 1),
            atm._p("stratospheric_aerosol_width_m", torch.float64, 1), atm.top_altitude_m)
    else:
        height = profile.column_height_m.to(torch.float64)
    extinction = atm._p("stratospheric_aerosol_optical_depth", torch.float64, 1) / height \
        * extinction
    g = asymmetry.to(dtype)

    def phase(cos_theta, extra=0):
        # Henyey-Greenstein with the Mie table's asymmetry per wavelength
        return phase_function(cos_theta[..., None], g, "henyeygreenstein1941")

    return Species("stratospheric_aerosol", profile, extinction.to(dtype),
                   (albedo * extinction).to(dtype), phase)


#: how the species are built, in the order of :data:`SPECIES` (see
#: :mod:`skytorch.atmosphere.constituents`, "Adding a species")
SPECIES_BUILDERS = (
    SpeciesBuilder("rayleigh", _rayleigh_profile, _rayleigh_species),
    SpeciesBuilder("aerosol", _aerosol_profile, _aerosol_species),
    SpeciesBuilder("ozone", _ozone_profile, _ozone_species),
    SpeciesBuilder("stratospheric_aerosol", _stratospheric_profile, _stratospheric_species,
                   absent=lambda atm: atm._stratospheric_absent()),
    *_gases.species_builders(),  # h2o, o2, o2o2 (skytorch.atmosphere.gases)
)


def _check_vertical(species: str, vertical: torch.Tensor, altitude_m) -> None:
    """ValueError where the vertical column above the observer is zero (air mass 0/0)."""
    with torch.no_grad():
        empty = ~(vertical > 0)
        if bool(empty.any()):
            height = torch.as_tensor(altitude_m, dtype=torch.float64).broadcast_to(
                vertical.shape)[empty].reshape(-1)[0]
            raise ValueError(
                f"air mass undefined: no {species} above altitude_m={float(height)} m (its "
                "vertical column is zero); observe from below the top of the "
                f"{species} layer")


def _check_quadrature(method, n_steps, rtol) -> None:
    """Return checked straight-ray quadrature options (before any arithmetic)."""
    check_choice("method", method, _od.METHODS)
    if n_steps is not None:
        check_int("n_steps", n_steps, 1)
    _od.check_rtol(rtol)
