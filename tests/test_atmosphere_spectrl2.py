"""Direct spectral transmittance against SPECTRL2 (Bird & Riordan 1986, pvlib).

Independent reference: ``pvlib.spectrum.spectrl2`` (pvlib 0.16.1, a test-only dependency),
the Bird Simple Spectral Model. Its direct normal transmittance is the returned ``dni``
over ``dni_extra`` (the extraterrestrial spectrum already scaled by the Earth-Sun distance,
so the ratio does not depend on the day of year), at SPECTRL2's own 122 wavelengths.

Case (issue 13, Validation): aerosol optical depth 0.1 at 500 nm with Ångström exponent
1.14 (SPECTRL2's ``aerosol_turbidity_500nm`` and ``alpha``; skytorch takes the optical depth
at 550 nm, so it gets ``0.1 (550/500)^-1.14``), ozone 300 DU (0.3 atm-cm), no water vapour
(``precipitable_water=0``: SPECTRL2's water term is then exactly 1), surface pressure
101325 Pa, zenith angles 0, 30, 60 and 80 degrees. SPECTRL2 takes the relative air mass as
an input; Bird & Riordan use Kasten (1966), which pvlib provides as ``"kasten1966"``.

Compared: SPECTRL2's wavelengths in 400-680 nm (all outside the O2 and H2O bands 686-700,
715-735, 755-775, 810-840 and 890-990 nm) for the case above; then the issue's grid
(precipitable water 0.5 and 4 cm, AOD 0.05 and 0.5 at 500 nm, 250 and 400 DU, zenith 0, 30,
60, 80 and 85 deg) over 400-1100 nm: the continuum outside the band cores, and the band
averages over 685-695, 755-770 and 925-965 nm. Resolution of the comparison: SPECTRL2's own
122 wavelengths (2.5-50 nm apart; band averages are means over its points in each window).
skytorch's water and O2 bands use the same Leckner coefficients (interpolated between these
points, ``skytorch.atmosphere.gases``), so the differences measured in the bands come from
the absorber amounts along the path (the 2 km water profile and the pressure-scaled O2
amount against SPECTRL2's W M and M p/p0 with Kasten's air mass), the curve-of-growth
constant (118.93 as published; pvlib 118.3) and the other species. SPECTRL2 has no O2-O2
collision-induced absorption: skytorch's ``o2o2`` species is left out of the comparison
(checked on its own in tests/test_atmosphere_gases.py).

Error budget (the tolerance, per wavelength and zenith angle, on |ln(T_skytorch/T_SPECTRL2)|;
each term is a known difference between the two models, none is fitted to the comparison):

1. Rayleigh formula: SPECTRL2's Eq. 2-4, tau_R = p/101300 / (lambda^4 (115.6406 -
   1.3366/lambda^2)) (lambda in um), lies 1.1-1.3 % above Bodhaine et al. (1999) eq. 30 over
   400-680 nm; that known offset enters as m_K |tau_S2 - tau_B| (0.46 % of T at 400 nm
   overhead, 2.6 % at 80 deg). skytorch computes Bodhaine's cross-section: another
   0.5 % of tau_B for its column (surface pressure, gravity, molar mass) and King factor.
2. Rayleigh air mass: Kasten (1966) fits the refracted air mass of the ARDC atmosphere;
   skytorch integrates straight rays through its own profile. The first-order curvature
   correction to sec z is (H/R) tan^2 z (H = 8 km); a 25 % difference in the effective
   scale height (profile shape) and the refraction both scale with it, so the allowance is
   0.25 (H/R) tan^2 z relative (1.0 % at 80 deg, 0.09 % at 60 deg).
3. Aerosol air mass: SPECTRL2 uses the air's m_K for the aerosol; skytorch's aerosol has
   its own, smaller scale height, so its air mass lies between m_K and the plane-parallel
   sec z: allowance (sec z - m_K) tau_A (sec 80 deg = 5.76 against m_K = 5.58).
4. Ozone cross-sections: SPECTRL2's 10-nm coefficients (Leckner 1978, after Vigroux) against
   skytorch's 1-nm laboratory cross-sections at the layer temperature: 0.01 (atm-cm)^-1,
   8 % of the Chappuis peak 0.12 (atm-cm)^-1, i.e. 0.003 in vertical optical depth at
   0.3 atm-cm, times SPECTRL2's ozone air mass (Eq. 2-10, a thin layer at 22 km).
5. Ozone air mass: SPECTRL2's thin layer at 22 km against skytorch's layer (tent around
   25 km): the spread of the thin-layer air mass between 15 and 35 km times tau_O3.

Air mass at 80 deg: Kasten (1966) gives 5.580 (for every species in SPECTRL2, Eq. 2-10's
5.212 for ozone); straight rays through an 8 km exponential give 5.550 for the air (Chapman,
-0.5 %), and skytorch's lower aerosol layer 5.72 (+2.6 %): a longer aerosol path that
partly cancels term 1 at 80 deg.

Measured with the model of this commit (float64), |T_skytorch/T_SPECTRL2 - 1| peaks at
0.43 %, 0.49 %, 0.83 % and 1.76 % at 0, 30, 60 and 80 deg (all at 400 nm; the issue's
1 % / 2 % figures), against budgets there of 0.88 %, 1.03 %, 1.90 % and 9.1 %; the smallest
budgets (667.6 nm) are 0.38 %, 0.45 %, 0.84 % and 4.2 %. At 0-60 deg the measured
difference uses up to 62 % of the budget, at 80 deg 23 % (the air-mass terms, genuine
differences between the two models' geometry, dominate there). The budget rejects the
500-nm optical depth 0.1 passed unconverted as skytorch's 550-nm value, alpha 1.3 instead
of 1.14, 330 DU instead of 300 DU and a 2 % lower surface pressure.

References
----------
1. Bird, R. E. & Riordan, C. 1986, "Simple solar spectral model for direct and diffuse
   irradiance on horizontal and tilted planes at the Earth's surface for cloudless
   atmospheres", J. Clim. Appl. Meteorol. 25, 87, doi:10.1175/1520-0450(1986)025<0087:SSSMFD>2.0.CO;2.
2. Bodhaine, B. A., Wood, N. B., Dutton, E. G. & Slusser, J. R. 1999, "On Rayleigh optical
   depth calculations", J. Atmos. Ocean. Technol. 16, 1854,
   doi:10.1175/1520-0426(1999)016<1854:ORODC>2.0.CO;2 (eq. 30).
3. Kasten, F. 1966, "A new table and approximation formula for the relative optical air
   mass", Arch. Meteorol. Geophys. Bioklimatol. B 14, 206, doi:10.1007/BF02248840.
"""

from __future__ import annotations

import importlib
import itertools

import numpy as np
import pvlib
import pytest
import torch
from pvlib.spectrum import spectrl2

from skytorch.atmosphere import Atmosphere

#: the module (the package re-exports the function under the same name): its coefficients
SPECTRL2_MODULE = importlib.import_module("pvlib.spectrum.spectrl2")
ZENITH_DEG = np.array([0.0, 30.0, 60.0, 80.0])
AOD_500 = 0.1
ALPHA = 1.14
OZONE_ATM_CM = 0.3
OZONE_DU = 300.0
PRESSURE_PA = 101325.0
#: O2 and H2O bands excluded from the continuum comparison [nm]
GAS_BANDS_NM = ((686.0, 700.0), (715.0, 735.0), (755.0, 775.0), (810.0, 840.0),
                (890.0, 990.0))
#: Earth radius of SPECTRL2's ozone air mass and the curvature term [km]
EARTH_RADIUS_KM = 6370.0
#: scale height of the air for the curvature correction of the air mass [km]
SCALE_HEIGHT_KM = 8.0
#: skytorch's Rayleigh column against Bodhaine's (term 1 of the budget) [1]
RAYLEIGH_COLUMN_RELATIVE = 0.005
#: fraction of the first-order curvature term allowed for the Rayleigh air mass [1]
AIR_MASS_CURVATURE_FRACTION = 0.25
#: ozone: 0.01 (atm-cm)^-1 on SPECTRL2's coefficients at 0.3 atm-cm, vertical [1]
OZONE_DATA_OPTICAL_DEPTH = 0.01 * OZONE_ATM_CM
#: range of ozone-layer altitudes for the ozone air mass [km]
OZONE_LAYER_RANGE_KM = (15.0, 35.0)


def _spectrl2_transmittance(zenith_deg=ZENITH_DEG, water_cm=0.0, aod_500=AOD_500,
                            ozone_atm_cm=OZONE_ATM_CM):
    """SPECTRL2 direct normal transmittance (wavelength,), (zenith, wavelength)."""
    air_mass = pvlib.atmosphere.get_relative_airmass(zenith_deg, model="kasten1966")
    out = spectrl2(apparent_zenith=zenith_deg, aoi=zenith_deg, surface_tilt=0.0,
                   ground_albedo=0.2, surface_pressure=PRESSURE_PA,
                   relative_airmass=air_mass, precipitable_water=water_cm, ozone=ozone_atm_cm,
                   aerosol_turbidity_500nm=aod_500, dayofyear=np.full(zenith_deg.shape, 172),
                   alpha=ALPHA)
    return out["wavelength"], (out["dni"] / out["dni_extra"]).T, air_mass


def _skytorch_transmittance(wavelength_nm, zenith_deg=ZENITH_DEG, water_cm=0.0,
                            aod_500=AOD_500, ozone_du=OZONE_DU):
    """Skytorch's direct transmittance without O2-O2 absorption.

    Which SPECTRL2 lacks (its own check is in tests/test_atmosphere_gases.py).
    """
    atm = Atmosphere.earth(aerosol_optical_depth=aod_500 * (550.0 / 500.0) ** -ALPHA,
                           angstrom_alpha=ALPHA, ozone_du=ozone_du,
                           precipitable_water_cm=water_cm)
    wavelength = torch.tensor(wavelength_nm, dtype=torch.float64)
    zenith = torch.tensor(np.radians(zenith_deg), dtype=torch.float64)
    tau = atm.optical_depth(wavelength, zenith, per_species=True)
    return torch.exp(-sum(value for name, value in tau.items() if name != "o2o2")).numpy()


def _in_bands(wavelength_nm):
    return np.any([(wavelength_nm >= lo) & (wavelength_nm <= hi) for lo, hi in GAS_BANDS_NM],
                  axis=0)


def bodhaine_rayleigh_optical_depth(wavelength_nm):
    """Bodhaine et al. 1999 eq. 30: sea level, 1013.25 hPa, 45 deg, 360 ppm CO2 [1]."""
    lam2 = (np.asarray(wavelength_nm) / 1000.0) ** 2
    return 0.0021520 * (1.0455996 - 341.29061 / lam2 - 0.90230850 * lam2) / (
        1.0 + 0.0027059889 / lam2 - 85.968563 * lam2)


def spectrl2_rayleigh_optical_depth(wavelength_nm):
    """SPECTRL2 Eq. 2-4 (spectrl2_2.c's 1.3366) at PRESSURE_PA [1]."""
    lam = np.asarray(wavelength_nm) / 1000.0
    return PRESSURE_PA / 101300.0 / (lam ** 4 * (115.6406 - 1.3366 / lam ** 2))


def thin_layer_air_mass(zenith_rad, height_km):
    """Air mass of a thin layer at ``height_km`` (SPECTRL2 Eq. 2-10) [1]."""
    h = height_km / EARTH_RADIUS_KM
    return (1.0 + h) / np.sqrt(np.cos(zenith_rad) ** 2 + 2.0 * h)


def error_budget(wavelength_nm, kasten_air_mass, ozone_coefficient, zenith_deg=ZENITH_DEG,
                 aod_500=AOD_500, ozone_atm_cm=OZONE_ATM_CM):
    """Return allowed |ln(T_skytorch / T_SPECTRL2)| (zenith, wavelength) [1] (module docstring)."""
    z = np.radians(zenith_deg)[:, None]
    m = kasten_air_mass[:, None]
    tau_b = bodhaine_rayleigh_optical_depth(wavelength_nm)
    tau_s2 = spectrl2_rayleigh_optical_depth(wavelength_nm)
    tau_a = aod_500 * (wavelength_nm / 500.0) ** -ALPHA
    tau_o3 = ozone_atm_cm * ozone_coefficient
    rayleigh_formula = m * (np.abs(tau_s2 - tau_b) + RAYLEIGH_COLUMN_RELATIVE * tau_b)
    curvature = AIR_MASS_CURVATURE_FRACTION * SCALE_HEIGHT_KM / EARTH_RADIUS_KM * np.tan(z) ** 2
    rayleigh_air_mass = curvature * m * tau_b
    aerosol_air_mass = np.maximum(1.0 / np.cos(z) - m, 0.0) * tau_a
    ozone_data = thin_layer_air_mass(z, 22.0) * 0.01 * ozone_atm_cm
    low, high = OZONE_LAYER_RANGE_KM
    ozone_air_mass = np.abs(thin_layer_air_mass(z, low) - thin_layer_air_mass(z, high)) * tau_o3
    return rayleigh_formula + rayleigh_air_mass + aerosol_air_mass + ozone_data + ozone_air_mass


@pytest.fixture(scope="module")
def comparison():
    wavelength, reference, air_mass = _spectrl2_transmittance()
    keep = (wavelength >= 400.0) & (wavelength <= 680.0) & ~_in_bands(wavelength)
    ozone_coefficient = SPECTRL2_MODULE._SPECTRL2_COEFFS["ozone_absorption"]
    return {"wavelength": wavelength[keep], "reference": reference[:, keep],
            "model": _skytorch_transmittance(wavelength[keep]), "air_mass": air_mass,
            "ozone_coefficient": ozone_coefficient[keep]}


def test_reference_inputs_as_documented(comparison):
    """The comparison covers 22 SPECTRL2 wavelengths and uses Kasten's air mass."""
    assert comparison["wavelength"].size == 22
    assert comparison["wavelength"][0] == 400.0 and comparison["wavelength"][-1] == 667.6
    # Kasten 1966 at 80 deg: 1 / (cos z + 0.15 (93.885 - z)^-1.253) = 5.580
    assert comparison["air_mass"][-1] == pytest.approx(5.5803, abs=1e-3)


def test_rayleigh_formulas_differ_as_stated():
    """Term 1 of the budget: SPECTRL2's Rayleigh is 1.1-1.3 % above Bodhaine's eq. 30."""
    wavelength = np.linspace(400.0, 680.0, 29)
    ratio = spectrl2_rayleigh_optical_depth(wavelength) / bodhaine_rayleigh_optical_depth(
        wavelength)
    assert np.all((ratio > 1.010) & (ratio < 1.014))
    # eq. 30 against Bodhaine's Table 3 cross-section at 550 nm (4.513e-31 m^2) times the
    # column p N_A / (m_a g): 101325 Pa, 28.9649 g/mol (360 ppm CO2), g = 9.80616 m/s^2
    column = 101325.0 * 6.02214076e23 / (28.9649e-3 * 9.80616)
    assert bodhaine_rayleigh_optical_depth(550.0) == pytest.approx(4.513e-31 * column,
                                                                   rel=0.003)


def test_direct_transmittance_matches_spectrl2(comparison):
    """400-680 nm, zenith 0-80 deg: within the error budget of the module docstring."""
    measured = np.abs(np.log(comparison["model"] / comparison["reference"]))
    budget = error_budget(comparison["wavelength"], comparison["air_mass"],
                          comparison["ozone_coefficient"])
    assert measured.shape == budget.shape == (4, 22)
    bad = np.argwhere(measured > budget)
    assert bad.size == 0, [
        (ZENITH_DEG[i], comparison["wavelength"][j], measured[i, j], budget[i, j])
        for i, j in bad]


def test_oxygen_bands_match_spectrl2():
    """690 nm (O2 B band) and 762.5 nm (A band): within 5 % of SPECTRL2 (issue 13)."""
    wavelength, reference, _ = _spectrl2_transmittance()
    keep = np.isin(wavelength, (690.0, 762.5))
    model = _skytorch_transmittance(wavelength[keep])
    assert np.all(np.abs(model / reference[:, keep] - 1.0) <= 0.05)


# --- the grid: 400-1100 nm, zenith 0-85 deg, AOD 0.05-0.5, 250-400 DU, 0.5-4 cm ----

#: (precipitable water [cm], aerosol optical depth at 500 nm, ozone [DU])
GRID = list(itertools.product((0.5, 4.0), (0.05, 0.5), (250.0, 400.0)))
GRID_ZENITH_DEG = np.array([0.0, 30.0, 60.0, 80.0, 85.0])
#: band cores left out of the continuum comparison [nm]: the O2 and H2O bands above and
#: the edge of the 1.1 um water band (SPECTRL2's a_w = 3.2 at 1100 nm)
CONTINUUM_EXCLUDED_NM = (*GAS_BANDS_NM, (1090.0, 1100.0))
#: band-averaged windows [nm] (issue 13) and the nearly gas-free SPECTRL2 points either
#: side that give the continuum under each band
BAND_WINDOWS_NM = {(685.0, 695.0): (667.6, 710.0), (755.0, 770.0): (752.5, 780.0),
                   (925.0, 965.0): (880.0, 1040.0)}
#: tolerance of the band averages (issue 13) [1]
BAND_TOLERANCE = 0.05


@pytest.fixture(scope="module", params=GRID,
                ids=lambda case: "W{:g}-aod{:g}-{:g}DU".format(*case))
def grid_case(request):
    water, aod, ozone = request.param
    wavelength, reference, air_mass = _spectrl2_transmittance(GRID_ZENITH_DEG, water, aod,
                                                              ozone / 1000.0)
    _, dry, _ = _spectrl2_transmittance(GRID_ZENITH_DEG, 0.0, aod, ozone / 1000.0)
    keep = (wavelength >= 400.0) & (wavelength <= 1100.0)
    return {"case": request.param, "wavelength": wavelength[keep],
            "reference": reference[:, keep], "dry": dry[:, keep], "air_mass": air_mass,
            "model": _skytorch_transmittance(wavelength[keep], GRID_ZENITH_DEG, water, aod,
                                             ozone),
            "ozone_coefficient": SPECTRL2_MODULE._SPECTRL2_COEFFS["ozone_absorption"][keep]}


def _gas_air_mass_allowance(air_mass, tau):
    """Bound on |d ln T| from the gases' air mass.

    SPECTRL2 gives water and O2 the air's Kasten air mass; their own (2 km water, 5.3 km
    pressure-scaled O2) lies between it and the plane-parallel sec z, and d ln(tau)/d ln(u) <= 1 on
    the curve of growth.
    """
    secant = 1.0 / np.cos(np.radians(GRID_ZENITH_DEG))
    return np.log(secant / air_mass)[:, None] * tau


def test_continuum_matches_spectrl2_over_the_grid(grid_case):
    """400-1100 nm outside the band cores, zenith 0-85 deg.

    Within the module's error budget plus the gas air-mass bound on SPECTRL2's water optical depth
    there (e.g. 593 nm).
    """
    c = grid_case
    water, aod, ozone = c["case"]
    outside = ~np.any([(c["wavelength"] >= lo) & (c["wavelength"] <= hi)
                       for lo, hi in CONTINUUM_EXCLUDED_NM], axis=0)
    assert outside.sum() == 32
    measured = np.abs(np.log(c["model"] / c["reference"]))[:, outside]
    budget = error_budget(c["wavelength"][outside], c["air_mass"],
                          c["ozone_coefficient"][outside], GRID_ZENITH_DEG, aod,
                          ozone / 1000.0)
    tau_water = np.log(c["dry"] / c["reference"])[:, outside]
    budget = budget + _gas_air_mass_allowance(c["air_mass"], tau_water)
    bad = np.argwhere(measured > budget)
    assert bad.size == 0, [(GRID_ZENITH_DEG[i], c["wavelength"][outside][j], measured[i, j],
                            budget[i, j]) for i, j in bad]
    # where the two models' geometry agrees (0-60 deg), the 2 % of the issue
    assert np.all(np.abs(c["model"] / c["reference"] - 1.0)[:3, outside] <= 0.02)


def test_band_averages_match_spectrl2_over_the_grid(grid_case):
    """685-695, 755-770, 925-965 nm.

    Averaged over SPECTRL2's points in each window (its native resolution): the band transmittance
    relative to the continuum either side within 5 % (plus the gas air-mass bound), and the plain
    band average within 5 % at 0-60 deg.
    """
    c = grid_case
    wavelength, model, reference = c["wavelength"], c["model"], c["reference"]
    ratio = model / reference
    for (lo, hi), edges in BAND_WINDOWS_NM.items():
        band = (wavelength >= lo) & (wavelength <= hi)
        edge = np.isin(wavelength, edges)
        assert band.sum() >= 1 and edge.sum() == 2
        plain = model[:, band].mean(1) / reference[:, band].mean(1)
        relative = plain / ratio[:, edge].mean(1)
        tau_band = -np.log(reference[:, band].mean(1) / reference[:, edge].mean(1))
        allowance = BAND_TOLERANCE + _gas_air_mass_allowance(c["air_mass"],
                                                             tau_band[:, None])[:, 0]
        assert np.all(np.abs(relative - 1.0) <= allowance), (lo, hi, relative, allowance)
        assert np.all(np.abs(plain[:3] - 1.0) <= BAND_TOLERANCE), (lo, hi, plain)
