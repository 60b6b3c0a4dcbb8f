"""The :class:`Atmosphere` module: constituents, their profiles and spectral coefficients.

An atmosphere is a spherical shell between ``planet_radius_m`` and ``top_radius_m``
holding three constituents, each a dimensionless density profile :math:`\\rho_s(h)`
times a spectral extinction coefficient at the reference level :math:`k_s(\\lambda)`:

* molecules (Rayleigh scattering; :mod:`skytorch.atmosphere.rayleigh`), exponential or
  U.S. Standard Atmosphere 1976 profile; the column of molecules is that of a
  hydrostatic atmosphere with the given surface pressure,
  :math:`N_{col} = p N_A/(m g)`, so the vertical Rayleigh optical depth scales with
  pressure whatever the profile shape;
* aerosols (Ångström law from Preetham turbidity or an optical depth at 550 nm;
  :mod:`skytorch.atmosphere.aerosol`), exponential profile, single-scattering albedo
  and Cornette–Shanks or Henyey–Greenstein phase function;
* ozone (absorbing only; :mod:`skytorch.atmosphere.ozone`), tent profile with the
  column given in Dobson units.

The refractivity :math:`n - 1` is proportional to the gas density,
:math:`(n-1)(h) = (n-1)_{ref}\\,(p/p_{ref})(T_{ref}/T)\\,\\rho(h)` (2.77e-4 at
1013.25 hPa, 288.15 K on Earth; 3.38e-6 at 610 Pa, 215 K on Mars, ref. 1), with
:math:`\\rho` the molecular profile or, with ``refractivity_profile="us1976"`` (the
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

import contextlib
import json
import math
from functools import lru_cache

import torch
from torch import nn

from skytorch._validate import (
    as_tensor,
    broadcast_shape,
    check_choice,
    check_finite,
    check_positive,
    check_range,
    common_dtype,
)
from skytorch.atmosphere import aerosol as _aerosol
from skytorch.atmosphere import optical_depth as _od
from skytorch.atmosphere import profiles as _profiles
from skytorch.atmosphere import rayleigh as _rayleigh
from skytorch.atmosphere.ozone import ozone_cross_section
from skytorch.atmosphere.scattering import PHASE_FUNCTIONS, phase_function
from skytorch.constants import (
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

__all__ = ["Atmosphere", "SPECIES"]

#: constituents, in the order of ``per_species`` outputs
SPECIES = ("rayleigh", "aerosol", "ozone")

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

#: rays per chunk in column integrals (keeps intermediates in cache)
_CHUNK = 4096

_PARAMETERS = (
    "surface_pressure_pa", "surface_temperature_k", "gravity_m_s2", "molar_mass_kg_mol",
    "rayleigh_scale_height_m", "angstrom_beta", "angstrom_alpha", "aerosol_scale_height_m",
    "aerosol_single_scattering_albedo", "aerosol_asymmetry", "ozone_du",
    "ozone_peak_altitude_m", "ozone_half_width_m", "reference_refractivity",
    "reference_pressure_pa", "reference_temperature_k",
)


@lru_cache(maxsize=1)
def _us1976_column_height_m() -> float:
    """:math:`\\int_0^\\infty \\rho_{US1976}(h)\\,dh` [m] by fine trapezoid (0–200 km)."""
    altitude = torch.linspace(0.0, 200e3, 200_001, dtype=torch.float64)
    return float(torch.trapezoid(_profiles.us1976(altitude), altitude))


class Atmosphere(nn.Module):
    """A spherically symmetric planetary atmosphere with batched parameters.

    Parameters
    ----------
    planet_radius_m, top_altitude_m : float
        Planet radius and altitude of the top of the atmosphere [m].
    surface_pressure_pa, surface_temperature_k : float or Tensor
        Surface pressure [Pa] (sets the column of molecules) and temperature [K] (with
        the pressure, sets the surface density used for the refractivity).
    gravity_m_s2, molar_mass_kg_mol : float or Tensor
        Gravity [m s^-2] and mean molar mass [kg/mol] for the hydrostatic column.
    gas : {"air", "co2"}
        Rayleigh model (:data:`skytorch.atmosphere.rayleigh.RAYLEIGH_GASES`).
    molecule_profile : {"exponential", "us1976"}
        Shape of the molecular density (optical depths, scattering).
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
    aerosol_phase_model : {"cornetteshanks1992", "henyeygreenstein1941"}
        Aerosol phase function.
    ozone_du : float or Tensor
        Ozone column [DU].
    ozone_peak_altitude_m, ozone_half_width_m : float or Tensor
        Altitude of the ozone peak and half width of the tent [m].
    reference_refractivity, reference_pressure_pa, reference_temperature_k : float
        :math:`n - 1` at 589.3 nm and the pressure [Pa] and temperature [K] it refers to.
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

    def __init__(self, *, planet_radius_m: float, top_altitude_m: float,
                 surface_pressure_pa=STANDARD_PRESSURE_PA,
                 surface_temperature_k=STANDARD_TEMPERATURE_K,
                 gravity_m_s2=EARTH_GRAVITY_M_S2,
                 molar_mass_kg_mol=None, gas: str = "air",
                 molecule_profile: str = "exponential",
                 refractivity_profile: str | None = None,
                 rayleigh_scale_height_m=EARTH_RAYLEIGH_SCALE_HEIGHT_M,
                 angstrom_beta=0.0, angstrom_alpha=_aerosol.PREETHAM_ANGSTROM_ALPHA,
                 aerosol_scale_height_m=EARTH_AEROSOL_SCALE_HEIGHT_M,
                 aerosol_single_scattering_albedo=EARTH_AEROSOL_SINGLE_SCATTERING_ALBEDO,
                 aerosol_asymmetry=EARTH_AEROSOL_ASYMMETRY,
                 aerosol_phase_model: str = "cornetteshanks1992",
                 ozone_du=0.0, ozone_peak_altitude_m=25_000.0, ozone_half_width_m=15_000.0,
                 reference_refractivity: float = EARTH_REFRACTIVITY_SEA_LEVEL,
                 reference_pressure_pa: float = STANDARD_PRESSURE_PA,
                 reference_temperature_k: float = STANDARD_TEMPERATURE_K,
                 name: str = "custom"):
        super().__init__()
        self.gas = check_choice("gas", gas, _rayleigh.RAYLEIGH_GASES)
        self.molecule_profile = check_choice("molecule_profile", molecule_profile,
                                             _profiles.PROFILES)
        self.refractivity_profile = check_choice(
            "refractivity_profile",
            self.molecule_profile if refractivity_profile is None else refractivity_profile,
            _profiles.PROFILES)
        self.aerosol_phase_model = check_choice("aerosol_phase_model", aerosol_phase_model,
                                                PHASE_FUNCTIONS)
        self.name = str(name)
        self.planet_radius_m = float(check_positive("planet_radius_m", planet_radius_m,
                                                    unit=" m"))
        self.top_altitude_m = float(check_positive("top_altitude_m", top_altitude_m,
                                                   unit=" m"))
        self.top_radius_m = self.planet_radius_m + self.top_altitude_m
        if molar_mass_kg_mol is None:
            molar_mass_kg_mol = (_rayleigh.air_molar_mass() if gas == "air"
                                 else _rayleigh.MARS_MOLAR_MASS_KG_MOL)
        values = {
            "surface_pressure_pa": check_positive("surface_pressure_pa", surface_pressure_pa,
                                                  allow_zero=True, unit=" Pa"),
            "surface_temperature_k": check_positive("surface_temperature_k",
                                                    surface_temperature_k, unit=" K"),
            "gravity_m_s2": check_positive("gravity_m_s2", gravity_m_s2),
            "molar_mass_kg_mol": check_positive("molar_mass_kg_mol", molar_mass_kg_mol),
            "rayleigh_scale_height_m": check_positive("rayleigh_scale_height_m",
                                                      rayleigh_scale_height_m, unit=" m"),
            "angstrom_beta": check_positive("angstrom_beta", angstrom_beta, allow_zero=True),
            "angstrom_alpha": check_range("angstrom_alpha", angstrom_alpha, -1.0, 4.0),
            "aerosol_scale_height_m": check_positive("aerosol_scale_height_m",
                                                     aerosol_scale_height_m, unit=" m"),
            "aerosol_single_scattering_albedo": check_range(
                "aerosol_single_scattering_albedo", aerosol_single_scattering_albedo, 0.0, 1.0),
            "aerosol_asymmetry": check_range("aerosol_asymmetry", aerosol_asymmetry, -0.99,
                                             0.99),
            "ozone_du": check_positive("ozone_du", ozone_du, allow_zero=True, unit=" DU"),
            "ozone_peak_altitude_m": check_positive("ozone_peak_altitude_m",
                                                    ozone_peak_altitude_m, unit=" m"),
            "ozone_half_width_m": check_positive("ozone_half_width_m", ozone_half_width_m,
                                                 unit=" m"),
            "reference_refractivity": check_positive("reference_refractivity",
                                                     reference_refractivity, allow_zero=True),
            "reference_pressure_pa": check_positive("reference_pressure_pa",
                                                    reference_pressure_pa),
            "reference_temperature_k": check_positive("reference_temperature_k",
                                                      reference_temperature_k),
        }
        for key, value in values.items():
            # not detached: parameters given as tensors with requires_grad stay
            # differentiable (e.g. fitting turbidity to observed extinction)
            self.register_buffer(key, value.to(torch.float64).clone())
        self.batch_shape = broadcast_shape(*(v.shape for v in values.values()))

    # ------------------------------------------------------------------ presets
    @classmethod
    def earth(cls, turbidity=2.0, ozone_du=300.0, *, aerosol_optical_depth=None,
              angstrom_alpha=_aerosol.PREETHAM_ANGSTROM_ALPHA, **kwargs) -> Atmosphere:
        """Earth: air, 8 km exponential molecules, US 1976 refractivity, Preetham aerosols,
        ozone tent.

        The refractive index follows the U.S. Standard Atmosphere 1976 density
        (``refractivity_profile="us1976"``; horizon refraction 32.9' at 1013.25 hPa,
        15 degC, Bennett 1982: 34.0'); pass ``refractivity_profile="exponential"`` for the
        isothermal 8 km profile of the optical depths (37.3').

        Parameters
        ----------
        turbidity : float or Tensor
            Preetham turbidity :math:`T \\ge 1` (1: practically no aerosols, 10: hazy);
            :math:`\\beta = 0.04608 T - 0.04586`, :math:`\\alpha = 1.3` (ref. 3).
        ozone_du : float or Tensor
            Ozone column [DU].
        aerosol_optical_depth : float or Tensor, optional
            Vertical aerosol optical depth at 550 nm; replaces ``turbidity``.
        angstrom_alpha : float or Tensor
            Ångström exponent (with ``aerosol_optical_depth``).
        **kwargs
            Any other constructor argument.
        """
        if aerosol_optical_depth is not None:
            aod = check_positive("aerosol_optical_depth", aerosol_optical_depth,
                                 allow_zero=True)
            alpha = as_tensor("angstrom_alpha", angstrom_alpha)
            beta = aod * (550.0 / _aerosol.ANGSTROM_REFERENCE_NM) ** alpha
        else:
            turbidity = check_range("turbidity", turbidity, 1.0)
            beta = _aerosol.preetham_angstrom_beta(turbidity)
            alpha = angstrom_alpha
        options = {"planet_radius_m": EARTH_MEAN_RADIUS_M,
                   "top_altitude_m": EARTH_TOP_OF_ATMOSPHERE_M, "name": "earth",
                   "refractivity_profile": "us1976"}
        options.update(kwargs)
        return cls(angstrom_beta=beta, angstrom_alpha=alpha, ozone_du=ozone_du, **options)

    @classmethod
    def mars(cls, dust_optical_depth=_aerosol.MARS_DUST["optical_depth"], **kwargs
             ) -> Atmosphere:
        """Mars: CO2 (n - 1 = 3.38e-6 at 610 Pa, 215 K), 11.1 km scale height, dust.

        Parameters
        ----------
        dust_optical_depth : float or Tensor
            Vertical dust optical depth at 880 nm (default 0.5, background).
        **kwargs
            Any other constructor argument.
        """
        dust = _aerosol.MARS_DUST
        tau = check_positive("dust_optical_depth", dust_optical_depth, allow_zero=True)
        beta = tau * (dust["reference_wavelength_nm"] / _aerosol.ANGSTROM_REFERENCE_NM) ** (
            dust["angstrom_alpha"])
        options = {
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
            "reference_refractivity": MARS_REFRACTIVITY_SURFACE,
            "reference_pressure_pa": MARS_SURFACE_PRESSURE_PA,
            "reference_temperature_k": MARS_SURFACE_TEMPERATURE_K, "name": "mars",
        }
        options.update(kwargs)
        return cls(**options)

    # ------------------------------------------------------------------ parameters
    def parameters_dict(self) -> dict:
        """All parameters (lists for batched ones), e.g. for Dataset attributes and hashes."""
        result = {"name": self.name, "gas": self.gas, "molecule_profile": self.molecule_profile,
                  "refractivity_profile": self.refractivity_profile,
                  "aerosol_phase_model": self.aerosol_phase_model,
                  "planet_radius_m": self.planet_radius_m,
                  "top_altitude_m": self.top_altitude_m}
        for key in _PARAMETERS:
            value = getattr(self, key)
            result[key] = value.item() if value.ndim == 0 else value.tolist()
        return result

    def extra_repr(self) -> str:
        return json.dumps(self.parameters_dict())

    def _p(self, key: str, dtype: torch.dtype, trailing: int = 0) -> torch.Tensor:
        """Buffer ``key`` cast to ``dtype`` with ``trailing`` singleton dimensions.

        Inside :meth:`_extra_geometry_dims` every parameter gets that many more trailing
        singletons, so that it broadcasts against geometry with extra trailing dims.
        """
        value = getattr(self, key).to(dtype)
        if value.ndim == 0:  # a scalar broadcasts against anything
            return value
        extra = getattr(self, "_extra_dims", 0)
        return value.reshape(tuple(value.shape) + (1,) * (trailing + extra))

    @contextlib.contextmanager
    def _extra_geometry_dims(self, count: int):
        """Let geometry tensors carry ``count`` trailing dims beyond the batch dims."""
        previous = getattr(self, "_extra_dims", 0)
        self._extra_dims = previous + count
        try:
            yield self
        finally:
            self._extra_dims = previous

    # ------------------------------------------------------------------ species
    def _density(self, species: str, dtype: torch.dtype, profile: str | None = None):
        """Density profile of a species as a function of altitude with a trailing sample dim
        (``profile`` overrides the molecules' profile)."""
        if species == "rayleigh":
            if (profile or self.molecule_profile) == "us1976":
                return _profiles.us1976
            height = self._p("rayleigh_scale_height_m", dtype, 1)
            return lambda h: _profiles.exponential(h, height)
        if species == "aerosol":
            height = self._p("aerosol_scale_height_m", dtype, 1)
            return lambda h: _profiles.exponential(h, height)
        center = self._p("ozone_peak_altitude_m", dtype, 1)
        width = self._p("ozone_half_width_m", dtype, 1)
        return lambda h: _profiles.tent(h, center, width)

    def _levels(self, species: str, dtype: torch.dtype):
        """Breakpoint altitudes (..., n_level) for the path quadrature [m].

        Exponential profiles: the leg's lowest altitude plus multiples of the scale height
        (the relative accuracy does not depend on the observer's altitude); US 1976: the
        layer boundaries; ozone tent: its three kinks.
        """
        factors = torch.tensor(_EXPONENTIAL_LEVELS, dtype=dtype)
        if species == "rayleigh" and self.molecule_profile == "us1976":
            return torch.tensor(_US1976_BREAKS_M, dtype=dtype)
        if species in ("rayleigh", "aerosol"):
            key = "rayleigh_scale_height_m" if species == "rayleigh" else "aerosol_scale_height_m"
            height = self._p(key, dtype, 1) * factors
            return lambda base: base[..., None] + height
        center = self._p("ozone_peak_altitude_m", dtype)
        width = self._p("ozone_half_width_m", dtype)
        return torch.stack(torch.broadcast_tensors(torch.clamp(center - width, min=0.0), center,
                                                   center + width), dim=-1)

    def _truncates(self, species: str) -> bool:
        """Whether the last quadrature level of ``species`` ends the integration."""
        return species == "aerosol" or (species == "rayleigh"
                                        and self.molecule_profile == "exponential")

    def molecular_column_m2(self, dtype: torch.dtype = torch.float64) -> torch.Tensor:
        """Vertical column of molecules :math:`p N_A/(m g)` [m^-2], shape ``batch_shape``."""
        return _rayleigh.column_number_density(self._p("surface_pressure_pa", dtype),
                                               self._p("gravity_m_s2", dtype),
                                               self._p("molar_mass_kg_mol", dtype))

    def _profile_height(self, species: str, dtype: torch.dtype) -> torch.Tensor:
        """:math:`\\int_0^\\infty \\rho_s(h)\\,dh` [m]."""
        if species == "rayleigh":
            if self.molecule_profile == "us1976":
                return torch.tensor(_us1976_column_height_m(), dtype=dtype)
            return self._p("rayleigh_scale_height_m", dtype)
        if species == "aerosol":
            return self._p("aerosol_scale_height_m", dtype)
        return self._p("ozone_half_width_m", dtype)

    def _coefficients(self, wavelength_nm: torch.Tensor) -> dict[str, torch.Tensor]:
        """Reference-level extinction coefficients k_s (..., n_wavelength) [1/m]."""
        dtype = wavelength_nm.dtype
        sigma_r = _rayleigh.rayleigh_cross_section(wavelength_nm, self.gas)
        rayleigh = (self.molecular_column_m2(dtype) / self._profile_height("rayleigh", dtype)
                    )[..., None] * sigma_r
        aerosol = _aerosol.angstrom_optical_depth(
            wavelength_nm, self._p("angstrom_beta", dtype), self._p("angstrom_alpha", dtype)
        ) / self._p("aerosol_scale_height_m", dtype, 1)
        ozone = (self._p("ozone_du", dtype) * DOBSON_UNIT_PER_M2
                 / self._p("ozone_half_width_m", dtype))[..., None] * ozone_cross_section(
                     wavelength_nm)
        return {"rayleigh": rayleigh, "aerosol": aerosol, "ozone": ozone}

    def reference_extinction(self, wavelength_nm) -> dict[str, torch.Tensor]:
        """Extinction coefficient of each species where its relative density is 1.

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
            ``"rayleigh"``, ``"aerosol"`` (scattering plus absorption) and ``"ozone"``
            [1/m]; leading dims are the batch dims of the parameters.

        Notes
        -----
        Rayleigh: :math:`N_{col}\\,\\sigma_R(\\lambda)/\\int\\rho\\,dh`; aerosol:
        :math:`\\beta\\,(\\lambda/1000\\,\\mathrm{nm})^{-\\alpha}/H_a`; ozone:
        :math:`\\mathrm{DU}\\,N_{DU}\\,\\sigma_{O_3}(\\lambda)/w` (tent half width
        :math:`w`).

        Examples
        --------
        >>> import torch
        >>> atm = Atmosphere.earth(turbidity=1.0, ozone_du=0.0)
        >>> k = atm.reference_extinction(torch.tensor([550.0], dtype=torch.float64))
        >>> round(float(k["rayleigh"][0]) * 8000.0, 3)   # vertical Rayleigh optical depth
        0.097
        """
        return self._coefficients(self._wavelength(wavelength_nm, common_dtype(wavelength_nm)))

    @staticmethod
    def _wavelength(wavelength_nm, dtype=None) -> torch.Tensor:
        wavelength = check_positive("wavelength_nm", wavelength_nm, unit=" nm", dtype=dtype)
        if wavelength.ndim > 1:
            raise ValueError("wavelength_nm must be a scalar or a 1-D tensor (n_wavelength,); "
                             f"got shape {tuple(wavelength.shape)}")
        return wavelength.reshape(-1)

    @staticmethod
    def _altitude(altitude_m, dtype) -> torch.Tensor:
        return check_range("altitude_m", altitude_m, 0.0, unit=" m (observer inside the "
                           "planet?)", dtype=dtype)

    # ------------------------------------------------------------------ local coefficients
    def _local(self, altitude_m, wavelength_nm):
        dtype = common_dtype(altitude_m, wavelength_nm)
        wavelength = self._wavelength(wavelength_nm, dtype)
        altitude = self._altitude(altitude_m, dtype)[..., None]
        coefficients = self._coefficients(wavelength)
        return {s: self._density(s, dtype)(altitude) * coefficients[s] for s in SPECIES}

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
        return sum(self._local(altitude_m, wavelength_nm).values())

    def scattering_coefficients(self, altitude_m, wavelength_nm) -> dict[str, torch.Tensor]:
        """Scattering coefficients ``{"rayleigh", "aerosol"}`` (..., wavelength) [1/m]."""
        local = self._local(altitude_m, wavelength_nm)
        albedo = self._p("aerosol_single_scattering_albedo", local["aerosol"].dtype, 1)
        return {"rayleigh": local["rayleigh"], "aerosol": albedo * local["aerosol"]}

    def absorption_coefficient(self, altitude_m, wavelength_nm) -> torch.Tensor:
        """Absorption coefficient: ozone + aerosol absorption (..., wavelength) [1/m]."""
        local = self._local(altitude_m, wavelength_nm)
        albedo = self._p("aerosol_single_scattering_albedo", local["aerosol"].dtype, 1)
        return local["ozone"] + (1.0 - albedo) * local["aerosol"]

    def aerosol_phase(self, cos_theta) -> torch.Tensor:
        """Aerosol phase function [1/sr], normalised over 4π; shape broadcast(cos, batch)."""
        cos_theta = check_range("cos_theta", cos_theta, -1.0, 1.0)
        return phase_function(cos_theta, self._p("aerosol_asymmetry", cos_theta.dtype),
                              self.aerosol_phase_model)

    def relative_density(self, species: str, altitude_m) -> torch.Tensor:
        """Dimensionless density profile of ``species`` (1 at the surface for molecules)."""
        check_choice("species", species, SPECIES)
        altitude = self._altitude(altitude_m, common_dtype(altitude_m))
        return self._density(species, altitude.dtype)(altitude[..., None])[..., 0]

    @property
    def refractivity_breakpoints_m(self) -> tuple[float, ...]:
        """Altitudes where the quadrature of refracted rays is split [m].

        The kinks of the refractivity profile (:attr:`refractivity_kinks_m`) and, for
        the US 1976 profile, levels at 1, 2, 4 and 8 km (panels of the Gauss–Legendre
        rules along the ray); empty for the exponential profile.
        """
        return _US1976_BREAKS_M if self.refractivity_profile == "us1976" else ()

    @property
    def refractivity_kinks_m(self) -> tuple[float, ...]:
        """Altitudes where :math:`\\mathrm{d}n/\\mathrm{d}h` jumps [m].

        The U.S. Standard Atmosphere 1976 layer bases (its lapse rate jumps there); empty
        for the exponential profile. The bending of a ray whose lowest point lies just
        below a kink varies like the square root of the distance to it, so tables over
        impact parameter place nodes there (e.g.
        :meth:`skytorch.eclipse.shadow.Shadow.ring_profile`).
        """
        if self.refractivity_profile != "us1976":
            return ()
        return tuple(h for h in _profiles.US1976_KINK_ALTITUDES_M if h < self.top_altitude_m)

    def refractivity(self, altitude_m, wavelength_nm=None) -> torch.Tensor:
        """Refractivity :math:`n - 1` of the gas at ``altitude_m``.

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
            :math:`(n-1)_{ref} (p/p_{ref})(T_{ref}/T) \\rho(h)` [1], :math:`\\rho` the
            ``refractivity_profile`` normalised to 1 at the ground.
        """
        dtype = common_dtype(altitude_m, wavelength_nm)
        altitude = self._altitude(altitude_m, dtype)
        surface = (self._p("reference_refractivity", dtype)
                   * self._p("surface_pressure_pa", dtype) / self._p("reference_pressure_pa",
                                                                     dtype)
                   * self._p("reference_temperature_k", dtype)
                   / self._p("surface_temperature_k", dtype))
        density = self._density("rayleigh", dtype, self.refractivity_profile)(
            altitude[..., None])[..., 0]
        value = surface * density
        if wavelength_nm is None:
            return value
        wavelength = self._wavelength(wavelength_nm, dtype)
        return value[..., None] * _rayleigh.refractivity_dispersion(wavelength)

    # ------------------------------------------------------------------ optical depth
    def column_integrals(self, zenith_rad=0.0, altitude_m=0.0, *, method: str = "gauss",
                         n_steps: int | None = None, rtol: float = 1e-9,
                         dtype: torch.dtype | None = None) -> dict[str, torch.Tensor]:
        """Path integrals :math:`\\int \\rho_s\\,ds` [m] of each species' profile.

        Returns
        -------
        dict of Tensor (...)
            Keys of :data:`SPECIES`; shapes broadcast geometry and parameters.
        """
        dtype = dtype or common_dtype(zenith_rad, altitude_m)
        zenith = check_finite("zenith_rad", zenith_rad, dtype=dtype)
        altitude = self._altitude(altitude_m, dtype)
        r = self.planet_radius_m + altitude
        mu = torch.cos(zenith)
        shape = broadcast_shape(r.shape, mu.shape)
        count = math.prod(shape)
        if self.batch_shape == () and count > _CHUNK:
            # unbatched parameters: integrate cache-sized chunks of rays
            r_flat = r.expand(shape).reshape(-1)
            mu_flat = mu.expand(shape).reshape(-1)
            pieces = [self._column_integrals(r_flat[i:i + _CHUNK], mu_flat[i:i + _CHUNK],
                                             method, n_steps, rtol, dtype)
                      for i in range(0, count, _CHUNK)]
            return {s: torch.cat([piece[s] for piece in pieces]).reshape(shape)
                    for s in SPECIES}
        return self._column_integrals(r, mu, method, n_steps, rtol, dtype)

    def _column_integrals(self, r, mu, method, n_steps, rtol, dtype):
        return {s: _od.column_integral(self._density(s, dtype), r, mu, self.planet_radius_m,
                                       self.top_radius_m, self._levels(s, dtype),
                                       method=method, n_steps=n_steps, rtol=rtol,
                                       truncate=self._truncates(s), support=s == "ozone")
                for s in SPECIES}

    def optical_depth(self, wavelength_nm, zenith_rad=0.0, altitude_m=0.0, *,
                      method: str = "gauss", n_steps: int | None = None,
                      per_species: bool = False, refraction: bool = False,
                      rtol: float = 1e-9, **kwargs):
        """Slant optical depth along a straight (or refracted) ray to space or the ground.

        Parameters
        ----------
        wavelength_nm : Tensor (wavelength,)
            Wavelength [nm].
        zenith_rad : Tensor (...)
            Zenith angle of the viewing direction at the observer [rad]; > π/2 looks
            down (the ray may hit the ground).
        altitude_m : Tensor (...)
            Observer altitude [m], >= 0 (above the top: the ray's path through the
            atmosphere); ValueError below the surface.
        method : {"gauss", "trapezoid", "adaptive"}
            Quadrature (:mod:`skytorch.atmosphere.optical_depth`).
        n_steps : int, optional
            Resolution of the quadrature (default per method).
        per_species : bool
            Return ``{"rayleigh", "aerosol", "ozone"}`` instead of the total.
        refraction : bool
            Integrate along the refracted ray (:mod:`skytorch.atmosphere.refraction`).

        Returns
        -------
        Tensor (..., wavelength) or dict of them
            Optical depth [1].

        Notes
        -----
        :math:`\\tau(\\lambda) = \\sum_s k_s(\\lambda)\\int \\rho_s(h(s))\\,ds`: the path
        integrals are computed per species (3) and multiplied by the spectral
        coefficients, so the cost does not grow with the number of wavelengths.
        """
        if refraction:
            from skytorch.atmosphere import refraction as _refraction

            return _refraction.bent_optical_depth(self, wavelength_nm, zenith_rad, altitude_m,
                                                  method=method, n_steps=n_steps,
                                                  per_species=per_species, **kwargs)
        dtype = common_dtype(wavelength_nm, zenith_rad, altitude_m)
        wavelength = self._wavelength(wavelength_nm, dtype)
        columns = self.column_integrals(zenith_rad, altitude_m, method=method,
                                        n_steps=n_steps, rtol=rtol, dtype=dtype)
        coefficients = self._coefficients(wavelength)
        result = {s: columns[s][..., None] * coefficients[s] for s in SPECIES}
        if per_species:
            return result
        return result["rayleigh"] + result["aerosol"] + result["ozone"]

    def transmittance(self, wavelength_nm, zenith_rad=0.0, altitude_m=0.0, **kwargs
                      ) -> torch.Tensor:
        """Direct transmittance :math:`e^{-\\tau}` (..., wavelength) [1]; exactly 0 when
        :math:`\\tau` is huge (use :meth:`optical_depth` for log-transmittance)."""
        return torch.exp(-self.optical_depth(wavelength_nm, zenith_rad, altitude_m, **kwargs))

    def air_mass(self, zenith_rad, altitude_m=0.0, *, species: str = "rayleigh", **kwargs
                 ) -> torch.Tensor:
        """Relative air mass: slant column over vertical column of ``species`` [1].

        Straight rays; pass ``refraction=True`` for refracted rays.
        """
        check_choice("species", species, SPECIES)
        if kwargs.pop("refraction", False):
            wavelength = torch.tensor([550.0], dtype=common_dtype(zenith_rad, altitude_m))
            slant = self.optical_depth(wavelength, zenith_rad, altitude_m, refraction=True,
                                       per_species=True, **kwargs)[species][..., 0]
            vertical = self.optical_depth(wavelength, 0.0 * torch.as_tensor(zenith_rad),
                                          altitude_m, per_species=True, **kwargs
                                          )[species][..., 0]
            return slant / vertical
        slant = self.column_integrals(zenith_rad, altitude_m, **kwargs)[species]
        zenith = torch.zeros_like(torch.as_tensor(zenith_rad, dtype=slant.dtype))
        vertical = self.column_integrals(zenith, altitude_m, **kwargs)[species]
        return slant / vertical

    def sky_radiance(self, wavelength_nm, view_zenith_rad, view_azimuth_rad=0.0,
                     sun_zenith_rad=0.0, sun_azimuth_rad=0.0, altitude_m=0.0, *,
                     solar_irradiance: bool = False, **kwargs) -> torch.Tensor:
        """Single-scattering sky radiance (..., wavelength).

        Per unit solar irradiance [sr^-1], or with ``solar_irradiance=True`` times the
        extraterrestrial solar spectrum (:func:`skytorch.spectrum.solar_irradiance`)
        [W m^-2 sr^-1 nm^-1]. See
        :func:`skytorch.atmosphere.scattering.single_scattering_radiance`.
        """
        from skytorch.atmosphere.scattering import single_scattering_radiance

        radiance = single_scattering_radiance(self, wavelength_nm, view_zenith_rad,
                                              view_azimuth_rad, sun_zenith_rad,
                                              sun_azimuth_rad, altitude_m, **kwargs)
        if solar_irradiance:
            from skytorch.spectrum import solar_irradiance as irradiance

            wavelength = self._wavelength(wavelength_nm, radiance.dtype)
            radiance = radiance * irradiance(wavelength).to(radiance.dtype)
        return radiance

    # ------------------------------------------------------------------ refraction
    def refraction(self, apparent_altitude_rad, altitude_m=0.0, **kwargs) -> torch.Tensor:
        """Astronomical refraction, apparent minus true altitude [rad] (ray traced).

        Delegates to :func:`skytorch.atmosphere.refraction.refraction_angle`.
        """
        from skytorch.atmosphere import refraction as _refraction

        return _refraction.refraction_angle(self, apparent_altitude_rad, altitude_m, **kwargs)

    def apparent_altitude(self, true_altitude_rad, altitude_m=0.0, **kwargs) -> torch.Tensor:
        """Apparent altitude of a source at ``true_altitude_rad`` [rad] (inverse of
        :meth:`refraction`); delegates to :mod:`skytorch.atmosphere.refraction`."""
        from skytorch.atmosphere import refraction as _refraction

        return _refraction.apparent_altitude(self, true_altitude_rad, altitude_m, **kwargs)

    def forward(self, wavelength_nm, zenith_rad=0.0, altitude_m=0.0, **kwargs) -> torch.Tensor:
        """Same as :meth:`transmittance`."""
        return self.transmittance(wavelength_nm, zenith_rad, altitude_m, **kwargs)

