"""SkyglowModel: PCA + FFT rendering against direct accumulation, symmetries, hard cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
import xarray as xr
from _skyglow_standin import cached_model, single_torch_thread  # noqa: F401

from skytorch.constants import PERCENT
from skytorch.skyglow import render_naive
from skytorch.skyglow.model import SkyglowModel
from skytorch.skyglow.naive import kernel_table_sum

#: issue targets for PCA + FFT against the naive sum on the same grid (mean relative error)
TARGET_ERROR_M32 = 2 * PERCENT
TARGET_ERROR_M128 = 1 * PERCENT


def _map(x, y, flux, altitude=None):
    data = {"flux": (("y", "x"), np.asarray(flux, dtype=float))}
    if altitude is not None:
        data["altitude"] = (("y", "x"), np.asarray(altitude, dtype=float))
    return xr.Dataset(data, coords={"x": np.asarray(x, float), "y": np.asarray(y, float)})


def _one_cell(x, y, flux=1e6, altitude=None):
    return _map([x], [y], [[flux]], None if altitude is None else [[altitude]])


@pytest.fixture(scope="module")
def terrain_model():
    # 144 samples (24 distances × 6 source altitudes) allow up to 128 components
    return cached_model(n_elevation=8, n_source_altitude=6, source_altitude_range_m=(0.0, 1400.0),
                        n_components=128)


def test_pca_fft_matches_direct_sum_on_the_same_grid(terrain_model):
    rng = np.random.default_rng(3)
    x = np.arange(-18e3, 18e3 + 1, 1500.0)
    flux = np.zeros((x.size, x.size))
    lit = rng.choice(flux.size, 120, replace=False)
    flux.flat[lit] = rng.uniform(1e5, 1e6, lit.size)
    altitude = rng.uniform(0.0, 1400.0, flux.shape)
    city = _map(x, x, flux, altitude)
    cells = {k: torch.as_tensor(v) for k, v in (
        ("flux", flux), ("altitude", altitude))}
    cells["x"] = torch.as_tensor(np.broadcast_to(x[None, :], flux.shape).copy())
    cells["y"] = torch.as_tensor(np.broadcast_to(x[:, None], flux.shape).copy())
    polar = terrain_model.polar_flux(cells["x"].reshape(-1), cells["y"].reshape(-1),
                                     cells["flux"].reshape(-1), cells["altitude"].reshape(-1),
                                     torch.zeros(1, 2, dtype=torch.float64))[0]
    reference = kernel_table_sum(terrain_model, polar)
    errors = {}
    for m in (8, 32, 128):
        model = terrain_model.refit(m)
        ours = model.radiance_per_lumen(
            {"flux": cells["flux"], "x": cells["x"], "y": cells["y"],
             "altitude": cells["altitude"]}, (0.0, 0.0))[0]
        errors[m] = float(((ours - reference).abs() / reference).mean())
    assert errors[32] <= TARGET_ERROR_M32
    assert errors[128] <= TARGET_ERROR_M128
    assert errors[128] <= errors[8]
    # and the Dataset path gives the same panorama
    ds = terrain_model.refit(32).render(city, lamp="white")
    assert ds["radiance"].dims == ("elevation", "azimuth", "wavelength")


def test_naive_renderer_equals_direct_sum_and_pca():
    model = cached_model()
    city = _map([-3000.0, 2500.0], [4000.0], [[3e5, 7e5]])
    naive = render_naive(model, city, sources="polar", as_dataset=False)["luminance"]
    ours = model.render(city, as_dataset=False)["luminance"]
    rel = ((ours - naive).abs() / naive).mean()
    assert float(rel) <= 1 * PERCENT
    cells = render_naive(model, city, sources="cells", as_dataset=False)["luminance"]
    # exact placement vs polar-node placement: same total within the grid's resolution
    assert float(cells.sum()) == pytest.approx(float(naive.sum()), rel=10 * PERCENT)


def test_superposition():
    model = cached_model()
    x = np.array([-5e3, 0.0, 6e3])
    a = np.array([[1e5, 0, 0], [0, 0, 2e5], [0, 0, 0]])
    b = np.array([[0, 0, 3e5], [0, 4e4, 0], [1e6, 0, 0]])
    la = model.render(_map(x, x, a))["luminance"].values
    lb = model.render(_map(x, x, b))["luminance"].values
    lab = model.render(_map(x, x, a + 2.0 * b))["luminance"].values
    np.testing.assert_allclose(lab, la + 2.0 * lb, rtol=1e-12)


@pytest.mark.parametrize("n_azimuth", [32, 31])
def test_rotation_equivariance_and_mirror_symmetry(n_azimuth):
    model = cached_model(n_azimuth=n_azimuth, n_elevation=8, n_distance=8, n_components=8)
    step = 2 * math.pi / n_azimuth
    r = float(model.distance_m[3])
    panoramas = []
    for k in (0, 5):
        theta = k * step
        city = _one_cell(r * math.sin(theta), r * math.cos(theta))
        panoramas.append(model.render(city, as_dataset=False)["radiance"])
    np.testing.assert_allclose(torch.roll(panoramas[0], 5, dims=1).numpy(),
                               panoramas[1].numpy(), rtol=1e-9, atol=1e-30)
    # a source in azimuth 0 gives a panorama symmetric about north
    mirrored = torch.roll(torch.flip(panoramas[0], dims=[1]), 1, dims=1)
    np.testing.assert_allclose(mirrored.numpy(), panoramas[0].numpy(), rtol=1e-9, atol=1e-30)
    # the stored basis spectra are real because the kernel is mirror-symmetric
    spectrum = torch.fft.rfft(model.basis, dim=2)
    assert float(spectrum.imag.abs().max()) <= 1e-9 * float(spectrum.real.abs().max())


def test_more_components_than_samples_warns_and_clamps():
    with pytest.warns(UserWarning, match="exceeds"):
        model = cached_model(n_azimuth=16, n_elevation=4, n_distance=6, n_components=50)
    assert model.n_components == 6


def test_variance_threshold_selects_components():
    model = cached_model()
    small = model.refit(0.99)
    assert 1 <= small.n_components < model.n_components
    assert float(small.explained_variance_ratio.sum()) >= 0.99


def test_all_zero_map_gives_natural_sky():
    model = cached_model()
    ds = model.render(_map([0.0, 1e3], [0.0], [[0.0, 0.0]]))
    assert float(np.abs(ds["luminance"]).max()) == 0.0
    np.testing.assert_allclose(ds["total_brightness"].values, 22.0, rtol=1e-12)


def test_negative_and_nan_flux_name_the_cell():
    model = cached_model()
    flux = np.array([[1e5, 2e5], [3e5, -1.0]])
    with pytest.raises(ValueError, match=r"non-negative; cell \(y=1, x=1\)"):
        model.render(_map([0.0, 500.0], [0.0, 500.0], flux))
    flux[1, 1] = 1.0
    flux[0, 1] = np.nan
    with pytest.raises(ValueError, match=r"finite; cell \(y=0, x=1\) at x=500 m, y=0 m"):
        model.render(_map([0.0, 500.0], [0.0, 500.0], flux))


def test_source_at_observer_and_float32(dtype):
    model = cached_model()
    flux = torch.tensor([[1e6]], dtype=dtype, requires_grad=True)
    out = model.render(flux, x_m=torch.zeros(1, dtype=dtype), y_m=torch.zeros(1, dtype=dtype),
                       as_dataset=False)
    (gradient,) = torch.autograd.grad(out["luminance"].sum(), flux)
    # linear in the flux: the gradient is the per-lumen panorama sum
    assert torch.isfinite(gradient).all()
    assert float(gradient) == pytest.approx(float(out["luminance"].detach().sum()) / 1e6,
                                            rel=1e-5)
    assert out["luminance"].dtype == dtype
    assert torch.all(torch.isfinite(out["luminance"])) and torch.all(out["luminance"] > 0)
    reference = model.render(flux.detach().double(), x_m=torch.zeros(1, dtype=torch.float64),
                             y_m=torch.zeros(1, dtype=torch.float64),
                             as_dataset=False)["luminance"]
    assert torch.allclose(out["luminance"].detach().double(), reference, rtol=1e-4)


def test_sources_at_the_integration_limit():
    model = cached_model()
    edge = float(model.distance_edges_m[-1])
    last = float(model.distance_m[-1])
    inside = model.render(_one_cell(0.0, 0.5 * (edge + last)), as_dataset=False)["luminance"]
    at_last = model.render(_one_cell(0.0, last), as_dataset=False)["luminance"]
    torch.testing.assert_close(inside, at_last, rtol=1e-12, atol=0.0)
    beyond = model.render(_one_cell(0.0, edge * 1.001), as_dataset=False)["luminance"]
    assert float(beyond.abs().max()) == 0.0
    polar = model.polar_flux(torch.tensor([0.0, 0.0, 3e3]), torch.tensor([edge * 0.999,
                                                                          edge * 2, 0.0]),
                             torch.tensor([1.0, 5.0, 2.0], dtype=torch.float64),
                             torch.zeros(3, dtype=torch.float64), torch.zeros(1, 2,
                                                                               dtype=torch.float64))
    assert float(polar.sum()) == pytest.approx(3.0, rel=1e-12)


def test_batched_observers_equal_single_renders():
    model = cached_model()
    city = _map([-4e3, 1e3, 5e3], [-2e3, 3e3], [[1e5, 0, 3e5], [2e5, 4e5, 0]])
    xy = [[0.0, 0.0], [2e3, -1e3], [-6e3, 4e3]]
    batch = model.render(city, observer_xy=xy)
    assert batch["luminance"].dims == ("observer", "elevation", "azimuth")
    for i, p in enumerate(xy):
        single = model.render(city, observer_xy=p)
        np.testing.assert_allclose(batch["luminance"].values[i], single["luminance"].values,
                                   rtol=1e-12)


def test_gradient_through_render():
    model = cached_model()
    flux = torch.tensor([[1e5, 2e5], [3e5, 4e5]], dtype=torch.float64, requires_grad=True)
    x = torch.tensor([-2e3, 3e3], dtype=torch.float64)

    def zenith(f):
        return model.render(f, x_m=x, y_m=x, as_dataset=False)["luminance"][-1].sum()

    assert torch.autograd.gradcheck(zenith, (flux,), eps=1.0, atol=1e-12, rtol=1e-6)


def test_save_load_round_trip(tmp_path):
    model = cached_model()
    path = model.save(tmp_path / "model.nc")
    loaded = SkyglowModel.load(path)
    assert loaded.parameters_used["emission"] == "garstang1986"
    assert loaded.parameters_used["n_steps"] == 8
    city = _map([-3e3, 2e3], [1e3], [[2e5, 5e5]])
    np.testing.assert_allclose(loaded.render(city)["radiance"].values,
                               model.render(city)["radiance"].values, rtol=1e-12)
    from skytorch.dataset import open_dataset

    attrs = open_dataset(path).attrs
    assert "parameter_n_distance" in attrs and "parameter_source_radius_m" in attrs


def test_altitudes_outside_the_tables_warn():
    model = cached_model()
    with pytest.warns(UserWarning, match="observer_altitude_m"):
        model.render(_one_cell(1e3, 0.0), observer_altitude_m=500.0)
    with pytest.warns(UserWarning, match="source altitude"):
        model.render(_one_cell(1e3, 0.0, altitude=800.0))


def test_observer_altitude_interpolation_and_mixed_batches():
    model = cached_model(n_azimuth=16, n_elevation=4, n_distance=8, n_components=8,
                         n_observer_altitude=2, observer_altitude_range_m=(0.0, 1000.0))
    city = _map([-3e3, 4e3], [2e3], [[2e5, 6e5]])
    low = model.render(city, observer_altitude_m=0.0, as_dataset=False)["luminance"]
    high = model.render(city, observer_altitude_m=1000.0, as_dataset=False)["luminance"]
    # an observer 1 km up sees a different sky (less air above, sources seen from above)
    assert not torch.allclose(low, high, rtol=1e-3)
    middle = model.render(city, observer_altitude_m=250.0, as_dataset=False)["luminance"]
    torch.testing.assert_close(middle, 0.75 * low + 0.25 * high, rtol=1e-12, atol=0.0)
    xy = [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]
    batch = model.render(city, observer_xy=xy, observer_altitude_m=[1000.0, 0.0, 250.0],
                         as_dataset=False)["luminance"]
    torch.testing.assert_close(batch, torch.stack([high, low, middle]), rtol=1e-12, atol=0.0)


def test_altitude_gradient_at_the_nodes_is_a_one_sided_difference():
    """d(luminance)/d(altitude) at 0 m, an inner node and the top: a side's slope.

    Between nodes the image is linear in the altitude; at a node the node of weight 0 was
    left out of the convolution, so autograd gave −K/Δh (twice the slope at 0 m, the wrong
    sign at the top).
    """
    model = cached_model(n_azimuth=16, n_elevation=4, n_distance=8, n_components=8,
                         n_observer_altitude=3, observer_altitude_range_m=(0.0, 1000.0))
    city = _map([-3e3, 4e3], [2e3], [[2e5, 6e5]])

    def total(h):
        return model.render(city, observer_xy=(1e3, 0.0), observer_altitude_m=h,
                            as_dataset=False)["luminance"].sum()

    step = 50.0
    for h in (0.0, 500.0, 1000.0):
        at = torch.tensor(h, dtype=torch.float64, requires_grad=True)
        (slope,) = torch.autograd.grad(total(at), at)
        sides = [float(total(torch.tensor(min(max(h + d, 0.0), 1000.0), dtype=torch.float64))
                       - total(torch.tensor(h, dtype=torch.float64))) / d
                 for d in (step, -step) if 0.0 <= h + d <= 1000.0]
        assert any(abs(float(slope) - side) <= 1e-9 * abs(side) for side in sides), (
            h, float(slope), sides)


def test_precompute_refuses_settings_its_medium_overrides():
    """A reused medium's atmosphere, wavelengths and phase functions are the model's.

    A turbidity-5 atmosphere with a turbidity-2 medium gave the turbidity-2 kernel while
    the model recorded turbidity 5; three wavelengths asked gave the medium's one.
    """
    from skytorch.atmosphere import Atmosphere
    from skytorch.skyglow import SkyglowModel
    from skytorch.skyglow.kernel import Medium

    atm = Atmosphere.earth(turbidity=2.0)
    medium = Medium(atm, [550.0])
    settings = dict(n_azimuth=4, n_elevation=2, n_distance=2, max_distance_m=5e3,
                    n_components=1, n_steps=2, progress=False, medium=medium)
    with pytest.raises(ValueError, match="atmosphere must be the one the medium"):
        SkyglowModel.precompute(Atmosphere.earth(turbidity=5.0), **settings)
    with pytest.raises(ValueError, match=r"wavelength_nm must be omitted or the medium's"):
        SkyglowModel.precompute(atm, wavelength_nm=[440.0, 550.0, 680.0], **settings)
    with pytest.raises(ValueError, match="phase_functions"):
        SkyglowModel.precompute(atm, phase_functions={"rayleigh": lambda c: c}, **settings)
    model = SkyglowModel.precompute(Atmosphere.earth(turbidity=2.0), wavelength_nm=[550.0],
                                    **settings)
    assert model.parameters_used["atmosphere"] == atm.parameters_dict()


def test_render_refuses_what_it_would_ignore():
    """Coordinates beside a Dataset map, kilometres, oversampling of a splat, a lamp's graph.

    Each was taken silently before: x_m shifted by 100 km changed nothing, a map in km was
    read as metres (10.8x the zenith), oversampling=8 with splatting was recorded and
    unused, and a Dataset was built from a lamp spectrum that carried a gradient.
    """
    model = cached_model(n_azimuth=16, n_elevation=4, n_distance=8, n_components=8)
    city = _map([-3e3, 4e3], [2e3], [[2e5, 6e5]])
    with pytest.raises(ValueError, match="x_m: coordinates of a tensor light_map"):
        model.render(city, x_m=torch.tensor([1e5, 1.07e5]))
    high = city.assign(altitude=(("y", "x"), np.full((1, 2), 100.0)))
    with pytest.raises(ValueError, match="altitude_m: the Dataset light_map has its own"):
        model.render(high, altitude_m=torch.zeros(1, 2))
    km = city.assign_coords(x=city.x / 1e3, y=city.y / 1e3)
    km.x.attrs["units"] = "km"
    with pytest.raises(ValueError, match=r"light_map\['x'\] must be in metres"):
        model.render(km)
    with pytest.raises(ValueError, match="oversampling applies to resampling='sample'"):
        model.render(city, oversampling=8)
    wavelength = torch.linspace(380.0, 780.0, 9, dtype=torch.float64)
    spectrum = torch.ones(9, dtype=torch.float64, requires_grad=True)
    with pytest.raises(ValueError, match="lamp_spectrum"):
        model.render(city, lamp=(wavelength, spectrum))
    out = model.render(city, lamp=(wavelength, spectrum), as_dataset=False)
    assert out["luminance"].requires_grad


def test_naive_reference_records_the_altitude_it_integrated_at():
    """sources="cells" integrates at the observer's altitude: recorded as rendered there.

    On a one-node (0 m) model at 3 km it recorded 0 m while its sky was 3 km's.
    """
    model = cached_model(n_azimuth=16, n_elevation=4, n_distance=8, n_components=8)
    city = _map([-3e3, 4e3], [2e3], [[2e5, 6e5]])
    high = render_naive(model, city, observer_altitude_m=3000.0)
    ground = render_naive(model, city, observer_altitude_m=0.0)
    assert high.attrs["parameter_observer_altitude_rendered_m"] == 3000.0
    assert not np.allclose(high["luminance"].values, ground["luminance"].values, rtol=1e-3)
    polar = render_naive(model, city, observer_altitude_m=0.0, sources="polar")
    assert polar.attrs["parameter_observer_altitude_rendered_m"] == 0.0


@pytest.mark.parametrize("normalize", [True, False])
def test_model_dataset_puts_the_kernel_unit_where_the_values_carry_it(normalize):
    """The mean image's coefficient is 1 where the basis holds the radiance (normalize=False)."""
    model = cached_model(n_azimuth=16, n_elevation=4, n_distance=8, n_components=8,
                         normalize=normalize)
    ds = model.to_dataset()
    mean_coefficient = ds["coefficients"].isel(component=0).values
    if normalize:
        assert (ds["basis"].attrs["units"], ds["coefficients"].attrs["units"]) == (
            "1", "m-2 sr-1")
    else:
        assert (ds["basis"].attrs["units"], ds["coefficients"].attrs["units"]) == (
            "m-2 sr-1", "1")
        np.testing.assert_allclose(mean_coefficient, 1.0)


#: float32 kernel quadrature in the precompute against float64 (the PCA is float64 in
#: both): rendered luminance per pixel, incl. the 0.7° row of the paper's 64 elevations
FLOAT32_PRECOMPUTE_TOLERANCE = 0.1 * PERCENT


def test_float32_precompute_matches_float64():
    from skytorch.atmosphere import Atmosphere
    from skytorch.skyglow.citymap import synthetic_city

    atm = Atmosphere.earth(turbidity=2.0)
    settings = dict(n_azimuth=16, n_elevation=64, n_distance=8, max_distance_m=10e3,
                    n_components=8, n_steps=4, progress=False)
    m64 = SkyglowModel.precompute(atm, **settings)
    m32 = SkyglowModel.precompute(atm, **settings, medium=m64.medium,
                                  compute_dtype=torch.float32)
    assert m32.parameters_used["compute_dtype"] == "float32"
    city = synthetic_city(8e3, 500.0)
    for observer in ((0.0, 0.0), (6e3, 2e3)):
        a = m64.render(city, observer_xy=observer, as_dataset=False)["luminance"]
        b = m32.render(city, observer_xy=observer, as_dataset=False)["luminance"]
        assert bool((a > 0).all())
        relative = ((b - a).abs() / a).max()
        assert float(relative) < FLOAT32_PRECOMPUTE_TOLERANCE


def test_observer_altitudes_on_worker_threads_equal_one_after_another():
    # the threaded precompute runs every operation serially: it must reproduce the
    # single-thread precompute (same kernels, same PCA) to rounding
    from skytorch.atmosphere import Atmosphere

    atm = Atmosphere.earth(turbidity=2.0)
    settings = dict(n_azimuth=16, n_elevation=8, n_distance=8, max_distance_m=10e3,
                    n_components=6, n_steps=4, n_source_altitude=2, n_observer_altitude=3,
                    observer_altitude_range_m=(0.0, 500.0), progress=False)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        serial = SkyglowModel.precompute(atm, **settings, n_workers=1)
    finally:
        torch.set_num_threads(threads)
    threaded = SkyglowModel.precompute(atm, **settings, medium=serial.medium, n_workers=3)
    assert torch.get_num_threads() == threads  # restored
    expected, actual = serial.state_dict(), threaded.state_dict()
    assert expected.keys() == actual.keys() and len(expected) > 0
    for name, value in expected.items():
        torch.testing.assert_close(actual[name], value, rtol=1e-12, atol=1e-300, msg=name)
    with pytest.raises(ValueError, match="n_workers"):
        SkyglowModel.precompute(atm, **settings, n_workers=0)
