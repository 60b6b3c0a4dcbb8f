"""The zenith twilight at Paranal with less ozone: the experiment runs and brightens.

Reference: what is physically certain of the ozone's part in the twilight (the Chappuis band
absorbs along the grazing paths of the twilight's light, so less ozone, all else equal,
gives a brighter zenith) and the Paranal measurements of Patat, Ugolnikov & Postylyakov
(2006, A&A 455, 385) less a 21.6 V night sky (Patat 2003) as the bound
(``experiments/twilight_zenith_profiles.py``; numbers in docs/multiple_scattering.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import twilight_zenith_profiles as experiment  # noqa: E402
from skytorch.constants import MAG  # noqa: E402


def test_twilight_zenith_profiles_experiment_quick(tmp_path):
    """Tent of 300 and 258 DU, and 300 DU with the stratospheric layer, at Sun 95, 98, 101 deg.

    Measured +0.37 / +0.60 / +0.39 mag (300 DU) and +0.27 / +0.49 / +0.27 mag (258 DU)
    against the measured scattered light; the bound of 1 mag is that of
    tests/test_twilight_zenith_patat_experiment.py.
    """
    experiment.main(["--quick", "--output-dir", str(tmp_path)])
    stem = "twilight_zenith_profiles"
    assert (tmp_path / f"{stem}.png").stat().st_size > 0
    with xr.open_dataset(tmp_path / f"{stem}.nc") as dataset:
        sunlit = dataset["sunlit_v"].values
        difference = dataset["difference"].values
        column = dataset["ozone_column"].values
        dataset_layer = dataset["stratospheric_aod"].values[2]
    assert column[1] < column[0]
    assert (sunlit[1] < sunlit[0]).all()          # less ozone: brighter at every depression
    # the stratosphere's background sulfate layer brightens the deep twilight (measured
    # 0.02 / 0.17 / 0.03 mag at 95 / 98 / 101 deg)
    assert 0.0 < float(dataset_layer) < 0.02
    assert (sunlit[2] < sunlit[0]).all()
    assert (np.diff(sunlit, axis=1) > 0).all()    # the sky falls with the Sun's depression
    assert (np.abs(difference) < 1.0 * MAG).all(), difference
