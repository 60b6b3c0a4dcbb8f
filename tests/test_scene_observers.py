"""Several observers per Scene: the stacked render equals separate one-observer renders."""

import numpy as np
import pytest
import xarray as xr

import skytorch as st

#: Berlin and Madrid during the 2015-09-28 eclipse (Moon up at both), and Sydney (Moon
#: below the horizon there: another plan)
LAT = [52.52, 40.42, -33.87]
LON = [13.40, -3.70, 151.21]
HEIGHT = [34.0, 650.0, 0.0]
TIME = "2015-09-28T02:47"


def _scene(**kwargs):
    options = {"size": 16, "fidelity": "fast", "star_limit_mag": 3.0}
    options.update(kwargs)
    return st.Scene(time=TIME, **options)


@pytest.fixture(scope="module")
def stacked():
    return _scene(lat_deg=LAT, lon_deg=LON, elevation_m=HEIGHT).render()


def test_matches_separate_renders(stacked):
    assert stacked.sizes["observer"] == len(LAT)
    np.testing.assert_array_equal(stacked["latitude"].values, LAT)
    for i, (lat, lon, height) in enumerate(zip(LAT, LON, HEIGHT, strict=True)):
        single = _scene(lat_deg=lat, lon_deg=lon, elevation_m=height).render()
        frame = stacked.isel(observer=i)
        assert frame["effects_computed"].item() == single.attrs["effects_computed"]
        assert frame["effects_skipped"].item() == single.attrs["effects_skipped"]
        for name in ("radiance", "xyz", "srgb"):
            xr.testing.assert_identical(frame[name].drop_vars(
                ["observer", "latitude", "longitude", "elevation"]), single[name])
        components = list(single["component"].values)
        np.testing.assert_array_equal(
            frame["component_radiance"].sel(component=components).values,
            single["component_radiance"].values)


def test_plans_differ_between_observers(stacked):
    computed = [str(v) for v in stacked["effects_computed"].values]
    assert "moon" in computed[0] and "eclipse" in computed[0]
    assert "moon" not in computed[2]  # the Moon is below Sydney's horizon
    assert "eclipse" in stacked.attrs["effects_computed"]


def test_observer_arguments_are_checked():
    with pytest.raises(ValueError, match=r"do not broadcast: lat_deg \(2,\), lon_deg \(3,\)"):
        _scene(lat_deg=[10.0, 20.0], lon_deg=[0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="lat_deg"):
        _scene(lat_deg=[10.0, 95.0], lon_deg=0.0)
    with pytest.raises(ValueError, match="observer_xy"):
        _scene(lat_deg=[10.0, 20.0], lon_deg=0.0, observer_xy=[(0.0, 0.0)] * 3)


def test_netcdf_round_trip(stacked, tmp_path):
    from skytorch.dataset import open_dataset, to_netcdf

    path = to_netcdf(stacked, tmp_path / "observers.nc")
    back = open_dataset(path)
    np.testing.assert_array_equal(back["radiance"].values, stacked["radiance"].values)
    assert list(back["effects_computed"].values) == list(stacked["effects_computed"].values)


def test_netcdf_round_trip_is_exact(stacked, tmp_path):
    """Every variable comes back with its dtype and values.

    The planner's strings included (they were object arrays in memory and fixed-width strings from
    the file).
    """
    from skytorch.dataset import open_dataset, to_netcdf

    back = open_dataset(to_netcdf(stacked, tmp_path / "observers.nc"))
    assert set(back.variables) == set(stacked.variables)
    for name, variable in stacked.variables.items():
        assert back[name].dtype == variable.dtype, name
        assert back[name].dims == variable.dims, name
        np.testing.assert_array_equal(back[name].values, variable.values, err_msg=name)
    for name in ("effects_computed", "effects_skipped"):
        assert stacked[name].dtype.kind == "U"
        assert stacked[name].attrs == back[name].attrs


def test_one_observer_in_a_sequence_keeps_the_observer_dimension():
    ds = _scene(lat_deg=[52.52], lon_deg=[13.40], view="directions",
                directions={"altitude_deg": [90.0], "azimuth_deg": [0.0]}).render()
    assert ds.sizes["observer"] == 1
    assert ds["latitude"].values.tolist() == [52.52]
