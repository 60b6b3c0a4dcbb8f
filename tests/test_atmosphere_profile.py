"""One vertical structure: US 1976 by default, the exponential on request, user soundings."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
import xarray as xr

from skytorch.atmosphere import Atmosphere
from skytorch.atmosphere.profiles import us1976, us1976_pressure_ratio, us1976_temperature
from skytorch.constants import DOBSON_UNIT_PER_M2

WAVELENGTH = torch.tensor([320.0, 450.0, 550.0, 700.0], dtype=torch.float64)
DEGREE = math.pi / 180.0
MINE = ("rayleigh", "aerosol", "ozone", "stratospheric_aerosol")
BOLTZMANN = 1.380649e-23


def us1976_sounding(step_m=1000.0, top_m=100e3, ozone=False, water=False):
    """Return the built-in US 1976 standard sampled every ``step_m``.

    Its own pressure and temperature, an independent evaluation of the standard's defining layers.
    """
    altitude = np.arange(0.0, top_m + step_m / 2, step_m)
    h = torch.tensor(altitude, dtype=torch.float64)
    variables = {
        "pressure": ("altitude", 101325.0 * us1976_pressure_ratio(h).numpy(), {"units": "Pa"}),
        "temperature": ("altitude", us1976_temperature(h).numpy(), {"units": "K"}),
    }
    if ozone:
        variables["ozone_number_density"] = ("altitude", np.clip(
            1.0 - np.abs(altitude - 25e3) / 15e3, 0.0, None) * 5e18, {"units": "m-3"})
    if water:
        variables["h2o_vmr"] = ("altitude", 0.01 * np.exp(-altitude / 2000.0), {"units": "1"})
    return xr.Dataset(variables, coords={"altitude": ("altitude", altitude, {"units": "m"})})


def test_earth_default_is_us1976_for_optical_depth_and_refraction():
    atm = Atmosphere.earth()
    assert (atm.molecule_profile, atm.refractivity_profile) == ("us1976", "us1976")
    exponential = Atmosphere.earth(molecule_profile="exponential")
    assert exponential.refractivity_profile == "exponential"
    # the shape of the profile changes slant paths, not the vertical column
    vertical = [a.optical_depth(WAVELENGTH, 0.0, per_species=True)["rayleigh"]
                for a in (atm, exponential)]
    # (to 1e-4: the exponential's column is cut at 30 scale heights, the US 1976 one at the
    # 100 km top against its 0-200 km integral)
    assert torch.allclose(vertical[0], vertical[1], rtol=2e-4)


def test_horizon_refraction_stays_at_the_us1976_value():
    # 32.903' at the start of the constituents work (US 1976 refractivity; Bennett 34.0')
    atm = Atmosphere.earth()
    arcmin = float(atm.refraction(torch.tensor([0.0], dtype=torch.float64))) / DEGREE * 60
    assert abs(arcmin - 32.903) <= 0.3


def test_state_of_the_gas_gives_the_density_shape():
    atm = Atmosphere.earth()
    # geometric altitudes; 11019.07 m is the tropopause's 11 km geopotential
    h = torch.tensor([0.0, 5e3, 11019.07, 30e3, 60e3], dtype=torch.float64)
    pressure, temperature = atm.pressure_pa(h), atm.temperature_k(h)
    assert float(pressure[0]) == pytest.approx(101325.0, rel=1e-12)
    assert float(temperature[2]) == pytest.approx(216.65, abs=0.05)  # the tropopause
    # US 1976 Table I (geometric altitude): 540.48 hPa at 5 km, 11.97 hPa at 30 km
    assert float(pressure[1]) == pytest.approx(54048.0, rel=2e-4)
    assert float(pressure[3]) == pytest.approx(1197.0, rel=2e-3)
    n = pressure / (BOLTZMANN * temperature)
    assert torch.allclose(n / n[0], us1976(h), rtol=1e-12)


def test_us1976_sounding_at_1km_reproduces_the_builtin_optical_depths():
    builtin = Atmosphere.earth(ozone_du=300.0)
    sounding = Atmosphere.earth(ozone_du=300.0, profile=us1976_sounding())
    assert sounding.molecule_profile == sounding.refractivity_profile == "sounding"
    assert float(sounding.surface_pressure_pa) == pytest.approx(101325.0, rel=1e-12)
    assert float(sounding.surface_temperature_k) == pytest.approx(288.15, rel=1e-12)
    zenith = torch.tensor([0.0, 60.0, 85.0, 90.0, 92.0], dtype=torch.float64) * DEGREE
    for altitude in (0.0, 3000.0):
        a = builtin.optical_depth(WAVELENGTH, zenith, altitude, per_species=True)["rayleigh"]
        b = sounding.optical_depth(WAVELENGTH, zenith, altitude, per_species=True)["rayleigh"]
        # rayleigh, aerosols and ozone (the gas bands read the sounding on their own,
        # skytorch.atmosphere.gases)
        total_a, total_b = (sum(value for name, value in atm.optical_depth(
            WAVELENGTH, zenith, altitude, per_species=True).items() if name in MINE)
            for atm in (builtin, sounding))
        hit = (a == 0).all(-1)  # 92 deg from the ground: the ray ends at once
        assert bool((b[hit] == 0).all()) and int(hit.sum()) == (altitude == 0.0)
        assert float(((b - a) / a)[~hit].abs().max()) < 1e-3
        assert float(((total_b - total_a) / total_a)[~hit].abs().max()) < 1e-3


def test_sounding_ozone_and_water():
    profile = us1976_sounding(ozone=True, water=True)
    column_du = 5e18 * 15e3 / DOBSON_UNIT_PER_M2  # the tent's integral [DU]
    own = Atmosphere.earth(profile=profile)
    assert float(own.ozone_du) == pytest.approx(column_du, rel=1e-9)
    # the knob ozone_du rescales the sounding's shape
    scaled = Atmosphere.earth(profile=profile, ozone_du=2.0 * column_du)
    tau = [a.optical_depth(WAVELENGTH, 0.5, per_species=True)["ozone"] for a in (own, scaled)]
    assert torch.allclose(tau[1], 2.0 * tau[0], rtol=1e-12)
    water = own.water_vapour_profile()
    h = torch.tensor([[0.0], [2000.0], [200e3]], dtype=torch.float64)
    density = water(h)[:, 0]
    assert float(density[0]) == pytest.approx(1.0, rel=1e-12)
    assert float(density[2]) == 0.0  # above the sounding's top
    assert Atmosphere.earth().water_vapour_profile() is None


@pytest.mark.parametrize(("change", "match"), [
    (lambda d: d.assign(pressure=d.pressure * -1.0), "pressure must be > 0"),
    (lambda d: d.assign(temperature=d.temperature.where(d.altitude != 5000.0, np.nan)),
     "temperature.*NaN"),
    (lambda d: d.isel(altitude=slice(None, None, -1)), "altitude must increase"),
    (lambda d: d.drop_vars("temperature"), "lacks the variable 'temperature'"),
    (lambda d: d.assign(pressure=d.pressure.assign_attrs(units="hPa")), "units 'hPa'"),
    (lambda d: d.assign_coords(altitude=d.altitude + 500.0), "start at or below the ground"),
    (lambda d: d.isel(altitude=slice(0, 1)), "at least 2 levels"),
])
def test_bad_soundings_are_refused(change, match):
    with pytest.raises(ValueError, match=match):
        Atmosphere.earth(profile=change(us1976_sounding(step_m=5000.0)))


def test_sounding_needs_a_dataset_and_matching_keywords():
    with pytest.raises(TypeError, match="xarray.Dataset"):
        Atmosphere.earth(profile={"altitude": [0.0, 1.0]})
    with pytest.raises(ValueError, match="sounding"):
        Atmosphere.earth(molecule_profile="sounding")
    with pytest.raises(ValueError, match="sounding"):
        Atmosphere.earth(molecule_profile="us1976", profile=us1976_sounding(step_m=5000.0))
