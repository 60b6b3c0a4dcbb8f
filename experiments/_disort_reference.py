"""The DISORT reference sky shared by the multiple-scattering experiments.

``tests/data/ms_reference/disort_sky.nc`` (DisORT++, plane-parallel, U.S. 1976 molecules +
Henyey-Greenstein aerosol; generator and provenance in that folder's README), the
atmosphere it was computed for, and the coarse tables of the validation tests.
"""

from __future__ import annotations

from pathlib import Path

import xarray as xr

from skytorch.atmosphere import Atmosphere

REFERENCE = Path(__file__).resolve().parents[1] / "tests" / "data" / "ms_reference" / \
    "disort_sky.nc"
#: view zenith angles of the reference used by the experiments [deg]
VIEW_ZENITH_DEG = (0.0, 30.0, 60.0)
#: the coarse tables of the sasktran2 / DISORT / Monte-Carlo tests
COARSE = dict(n_r=8, n_mu=32, n_mu_s=16, n_phi=6, n_ray=24, n_sphere_mu=6,
              transmittance_r=32, transmittance_mu=128, mu_vertical_weight=0.0)


def disort_atmosphere(aod) -> Atmosphere:
    """Return the atmosphere of the reference (``tests/data/ms_reference/generate_disort.py``)."""
    return Atmosphere.earth(ozone_du=0.0, precipitable_water_cm=0.0,
                            aerosol_phase_model="henyeygreenstein1941",
                            aerosol_optical_depth=aod, angstrom_alpha=1.3,
                            aerosol_asymmetry=0.7, aerosol_single_scattering_albedo=0.95)


def load_reference() -> xr.Dataset:
    """Return the reference table, loaded into memory."""
    with xr.open_dataset(REFERENCE) as ds:
        return ds.load()
