"""Physical and astronomical constants, each with its source.

All values are SI (metres, seconds, kilograms, kelvin, pascal) unless the name carries
another unit. Angles are radians unless the name says ``_deg`` or ``_arcsec``.

References
----------
1. IAU 2015 Resolution B3 (nominal solar and planetary values), Prša et al. 2016,
   AJ 152, 41, doi:10.3847/0004-6256/152/2/41.
2. IAU 2009 system of astronomical constants, Luzum et al. 2011, Celest. Mech. Dyn.
   Astron. 110, 293, doi:10.1007/s10569-011-9352-4.
3. CODATA 2018 recommended values, Tiesinga et al. 2021, Rev. Mod. Phys. 93, 025010,
   doi:10.1103/RevModPhys.93.025010.
4. Bodhaine, B. A. et al. 1999, "On Rayleigh optical depth calculations", J. Atmos.
   Oceanic Technol. 16, 1854, doi:10.1175/1520-0426(1999)016<1854:ORODC>2.0.CO;2.
5. Schneegans, S. et al. 2025, "Physically Based Real-Time Rendering of Eclipses",
   Computer Graphics Forum.
6. Archinal, B. A. et al. 2018, "Report of the IAU Working Group on Cartographic
   Coordinates and Rotational Elements: 2015", Celest. Mech. Dyn. Astron. 130, 22,
   doi:10.1007/s10569-017-9805-5.
7. Falchi, F. et al. 2016, "The new world atlas of artificial night sky brightness",
   Sci. Adv. 2, e1600377, doi:10.1126/sciadv.1600377.
"""

from __future__ import annotations

import math

# --- units and angles -------------------------------------------------------------------
DEGREE = math.pi / 180.0  #: one degree [rad]
ARCMINUTE = DEGREE / 60.0  #: [rad]
ARCSECOND = DEGREE / 3600.0  #: [rad]
PERCENT = 0.01  #: relative tolerance unit
MAG = 1.0  #: one magnitude
SECONDS_PER_DAY = 86400.0

# --- fundamental (CODATA 2018, ref. 3) ----------------------------------------------------
SPEED_OF_LIGHT_M_S = 299_792_458.0
BOLTZMANN_J_K = 1.380649e-23
PLANCK_J_S = 6.62607015e-34
AVOGADRO_PER_MOL = 6.02214076e23
LOSCHMIDT_PER_M3 = 2.686780111e25  #: number density at 273.15 K, 101325 Pa [m^-3]

# --- astronomical (IAU, refs. 1, 2) -------------------------------------------------------
ASTRONOMICAL_UNIT_M = 149_597_870_700.0
SUN_RADIUS_M = 6.957e8  #: nominal solar radius (ref. 1)
EARTH_EQUATORIAL_RADIUS_M = 6_378_137.0  #: WGS84 / IAU nominal (ref. 1)
EARTH_MEAN_RADIUS_M = 6_371_000.0  #: mean radius used for spherical atmospheres
MOON_RADIUS_M = 1_737_400.0  #: mean radius (ref. 6)
MARS_MEAN_RADIUS_M = 3_389_500.0  #: mean radius (ref. 6)
PHOBOS_MEAN_RADIUS_M = 11_080.0  #: mean radius (ref. 6)
DEIMOS_MEAN_RADIUS_M = 6_200.0  #: mean radius (ref. 6)
PHOBOS_SEMI_MAJOR_AXIS_M = 9_376_000.0
DEIMOS_SEMI_MAJOR_AXIS_M = 23_463_200.0
MEAN_EARTH_MOON_DISTANCE_M = 384_400_000.0

# --- Earth's atmosphere ---------------------------------------------------------------------
STANDARD_PRESSURE_PA = 101_325.0  #: 1013.25 hPa (ref. 4)
STANDARD_TEMPERATURE_K = 288.15  #: US Standard Atmosphere 1976 sea level
EARTH_RAYLEIGH_SCALE_HEIGHT_M = 8_000.0  #: Bruneton 2017 default
EARTH_AEROSOL_SCALE_HEIGHT_M = 1_200.0  #: Bruneton 2017 default
EARTH_TOP_OF_ATMOSPHERE_M = 100_000.0  #: altitude of the model's top [m]
EARTH_REFRACTIVITY_SEA_LEVEL = 2.77e-4  #: n - 1 at sea level (ref. 5)
DOBSON_UNIT_PER_M2 = 2.687e20  #: molecules per m^2 in one Dobson unit

# --- Mars (ref. 5) ----------------------------------------------------------------------------
MARS_REFRACTIVITY_SURFACE = 3.38e-6  #: n - 1 at 610 Pa, 215 K (ref. 5)
MARS_SURFACE_PRESSURE_PA = 610.0
MARS_SURFACE_TEMPERATURE_K = 215.0
MARS_SCALE_HEIGHT_M = 11_100.0  #: CO2 scale height near 215 K
MARS_TOP_OF_ATMOSPHERE_M = 80_000.0

# --- photometry ---------------------------------------------------------------------------------
#: luminance of 0 mag/arcsec^2 in the V band: L[cd/m^2] = 10.8e4 * 10^(-0.4 m) (ref. 7)
CANDELA_PER_M2_AT_ZERO_MAG_ARCSEC2 = 10.8e4
NATURAL_ZENITH_SKY_MAG_ARCSEC2 = 22.0  #: natural zenith sky brightness, V band (ref. 7)
#: accepted natural zenith background [V mag arcsec^-2]: from the brightest sky of the world
#: atlas (14.0, ref. 7) to 4 mag darker than the darkest natural sky (~22)
NATURAL_MAG_RANGE = (14.0, 26.0)
LUMINOUS_EFFICACY_LM_PER_W = 683.002  #: K_cd at 540 THz (SI definition)
