"""A tiny exponential atmosphere with the Atmosphere contract, for skyglow tests."""

from __future__ import annotations

import math

import pytest
import torch

#: Rayleigh optical depth at 550 nm, sea level (Bodhaine et al. 1999, eq. 30)
RAYLEIGH_TAU_550 = 0.0971
RAYLEIGH_SCALE_HEIGHT_M = 8000.0
AEROSOL_SCALE_HEIGHT_M = 1200.0


def rayleigh_phase(cos_theta):
    return 3.0 / (16.0 * math.pi) * (1.0 + cos_theta**2)


def henyey_greenstein(cos_theta, g=0.76):
    return (1 - g * g) / (4 * math.pi * (1 + g * g - 2 * g * cos_theta) ** 1.5)


class ExponentialAtmosphere:
    planet_radius_m = 6_371_000.0
    top_altitude_m = 100_000.0

    def __init__(self, aerosol_tau_550=0.0):
        self.aerosol_tau_550 = aerosol_tau_550

    def scattering_coefficients(self, altitude_m, wavelength_nm):
        h = torch.as_tensor(altitude_m, dtype=torch.float64)[..., None]
        wl = torch.as_tensor(wavelength_nm, dtype=torch.float64)
        beta_r = RAYLEIGH_TAU_550 / RAYLEIGH_SCALE_HEIGHT_M * (550.0 / wl) ** 4.08
        beta_m = self.aerosol_tau_550 / AEROSOL_SCALE_HEIGHT_M * (550.0 / wl) ** 1.3
        return {"rayleigh": beta_r * torch.exp(-h / RAYLEIGH_SCALE_HEIGHT_M),
                "aerosol": beta_m * torch.exp(-h / AEROSOL_SCALE_HEIGHT_M)}

    def extinction_coefficient(self, altitude_m, wavelength_nm):
        s = self.scattering_coefficients(altitude_m, wavelength_nm)
        return s["rayleigh"] + s["aerosol"]

    def aerosol_phase(self, cos_theta):
        return henyey_greenstein(cos_theta)


def medium(wavelength_nm=(680.0, 550.0, 440.0), aerosol_tau_550=0.1, **kwargs):
    from skytorch.skyglow.kernel import Medium

    atm = ExponentialAtmosphere(aerosol_tau_550)
    return Medium(atm, torch.tensor(wavelength_nm, dtype=torch.float64),
                  phase_functions={"rayleigh": rayleigh_phase, "aerosol": atm.aerosol_phase},
                  **kwargs)


_CACHE: dict = {}


def cached_model(**kwargs):
    """Return a small precomputed SkyglowModel on the stand-in atmosphere, built once per process."""
    from skytorch.skyglow import SkyglowModel

    key = tuple(sorted(kwargs.items()))
    if key not in _CACHE:
        settings = dict(n_azimuth=32, n_elevation=16, n_distance=24, max_distance_m=20_000.0,
                        n_components=16, n_steps=8, progress=False, keep_kernel=True)
        settings.update(kwargs)
        aerosol = settings.pop("aerosol_tau_550", 0.1)
        atm = ExponentialAtmosphere(aerosol)
        _CACHE[key] = SkyglowModel.precompute(
            atm, phase_functions={"rayleigh": rayleigh_phase, "aerosol": atm.aerosol_phase},
            **settings)
    return _CACHE[key]


@pytest.fixture(autouse=True, scope="module")
def single_torch_thread():
    """Run the skyglow tests on one intra-op thread, restoring the setting afterwards.

    The tensors here are small; on a shared 2-core machine two OpenMP threads that
    busy-wait for each other made the same tests 3-4 times slower.
    """
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)
