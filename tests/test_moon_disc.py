"""Lunar disc sampling, images and the accuracy-vs-cost experiment."""

from __future__ import annotations

import importlib
import math
import sys
from pathlib import Path

import torch

from skytorch.constants import DEGREE
from skytorch.dataset import open_dataset
from skytorch.moon import disc


def test_disc_grid_area_and_normals():
    grid = disc.disc_grid(12)
    assert abs(float(grid["weight"].sum()) - math.pi) < 1e-12
    assert torch.allclose(grid["normal"].norm(dim=-1), torch.ones(grid["x"].numel(),
                                                                  dtype=torch.float64))
    # second moment ∫∫ x² dx dy = π/4 (exact for the Gauss–Legendre radial rule)
    assert abs(float((grid["x"] ** 2 * grid["weight"]).sum()) - math.pi / 4) < 1e-12
    pixels = disc.disc_grid(400, method="pixels")
    assert abs(float(pixels["weight"].sum()) / math.pi - 1) < 1e-3


def test_polar_grid_converges_to_lit_quadrature():
    """Independent algorithms for the same disc integral agree (polar grid n = 96)."""
    alpha = torch.tensor([20.0, 75.0], dtype=torch.float64) * DEGREE
    mu0, mu, weight = disc.lit_disc_quadrature(alpha, 64)
    from skytorch.moon.reflectance import reflectance

    exact = (reflectance(mu0, mu, alpha[:, None]) * weight).sum(-1)
    grid = disc.disc_grid(96)
    sampled = (disc.disc_reflectance(grid["normal"], disc.sun_direction(alpha))
               * grid["weight"]).sum(-1)
    assert torch.allclose(sampled, exact, rtol=2e-3)
    # the lit area is π(1 + cos α)/2
    assert torch.allclose(weight.sum(-1), math.pi * (1 + torch.cos(alpha)) / 2, rtol=1e-10)


def test_disc_image_orientation_and_earthshine(dtype):
    """Waxing crescent with the bright limb west (χ = 270°): bright right side, earthlit left."""
    image = disc.disc_image(torch.tensor(140.0 * DEGREE, dtype=dtype),
                            torch.tensor(270.0 * DEGREE, dtype=dtype), n_pixels=32)
    assert image.shape == (32, 32, 3) and image.dtype == dtype
    assert torch.isfinite(image).all()
    middle = image[16, :, 1]
    assert float(middle[28]) > 100 * float(middle[3]) > 0.0  # earthshine is faint but > 0
    assert float(image[0, 0, 1]) == 0.0  # corner outside the disc
    # reddish Moon: radiance at 680 nm above 440 nm on the sunlit side
    assert float(image[16, 28, 0]) > float(image[16, 28, 2])


def test_accuracy_cost_experiment_quick(tmp_path, capsys):
    root = Path(__file__).resolve().parents[1]
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    experiment = importlib.import_module("experiments.moon_accuracy_cost")
    assert experiment.main(["--quick", "--output-dir", str(tmp_path)]) == 0
    assert "| quadrature | float64 |" in capsys.readouterr().out
    ds = open_dataset(tmp_path / "moon_accuracy_cost.nc")
    assert (tmp_path / "moon_accuracy_cost.png").is_file()
    error = ds.magnitude_error.sel(scheme="quadrature", dtype="float64")
    assert float(error.isel(level=1)) < float(error.isel(level=0))


def test_disc_image_dataset_roundtrip(tmp_path):
    from skytorch.dataset import to_netcdf
    from skytorch.moon import moon_disc_image

    ds = moon_disc_image(60.0, n_pixels=16)
    assert ds.radiance.dims == ("y", "x", "wavelength")
    assert ds.radiance.attrs["units"] == "W m-2 sr-1 nm-1"
    back = open_dataset(to_netcdf(ds, tmp_path / "disc.nc"))
    assert float(abs(back.radiance - ds.radiance).max()) == 0.0


def test_integrated_disc_radiance_equals_lunar_irradiance():
    """Sampled disc radiance (polar grid) integrates to the quadrature irradiance."""
    from skytorch.moon.brightness import lunar_irradiance

    alpha = torch.tensor([30.0, 100.0], dtype=torch.float64) * DEGREE
    wl = torch.tensor([450.0, 600.0], dtype=torch.float64)
    grid = disc.disc_grid(64)
    radiance = disc.disc_radiance(grid["normal"], alpha, wl)
    sampled = disc.integrate_disc(radiance, grid["weight"])
    assert torch.allclose(sampled, lunar_irradiance(alpha, wl), rtol=1e-3)


def test_disc_images_experiment_quick(tmp_path):
    root = Path(__file__).resolve().parents[1]
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    experiment = importlib.import_module("experiments.moon_disc_images")
    assert experiment.main(["--quick", "--output-dir", str(tmp_path)]) == 0
    ds = open_dataset(tmp_path / "moon_disc_images.nc")
    luminance = ds.luminance.sum(dim=("x", "y")).values
    assert (luminance[:-1] > luminance[1:]).all()  # the disc dims monotonically with phase
