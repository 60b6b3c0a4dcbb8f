"""PCA basis: the mirror-weighted PCA of half images equals the PCA of the full images."""

from __future__ import annotations

import pytest
import torch
from _skyglow_standin import single_torch_thread  # noqa: F401

from skytorch.skyglow.basis import fit_basis


@pytest.mark.parametrize("n_azimuth", [8, 9])
def test_weighted_half_images_equal_full_images(n_azimuth):
    generator = torch.Generator().manual_seed(5)
    half = n_azimuth // 2 + 1
    # mirror-symmetric random images (sample, azimuth, elevation) with a spread of scales
    images = torch.rand(40, half, 3, generator=generator, dtype=torch.float64)
    images = images * torch.logspace(0, 3, 40, dtype=torch.float64)[:, None, None]
    mirror = torch.tensor([min(i, n_azimuth - i) for i in range(n_azimuth)])
    full = images[:, mirror].reshape(40, -1)
    multiplicity = torch.tensor([1.0 if i in (0, n_azimuth - i) else 2.0 for i in range(half)],
                                dtype=torch.float64)
    weights = multiplicity[:, None].expand(half, 3).reshape(-1)
    reference = fit_basis(full, 6)
    weighted = fit_basis(images.reshape(40, -1), 6, feature_weights=weights)
    torch.testing.assert_close(weighted.explained_variance_ratio,
                               reference.explained_variance_ratio, rtol=1e-9, atol=1e-12)
    torch.testing.assert_close(weighted.scale, reference.scale, rtol=1e-12, atol=0.0)
    expanded = weighted.reconstruct().reshape(40, half, 3)[:, mirror].reshape(40, -1)
    torch.testing.assert_close(expanded, reference.reconstruct(), rtol=1e-9, atol=1e-9)
    # the expanded basis is orthonormal in the full feature space
    components = weighted.basis[1:].reshape(-1, half, 3)[:, mirror].reshape(6, -1)
    torch.testing.assert_close(components @ components.T,
                               torch.eye(6, dtype=torch.float64), rtol=0, atol=1e-10)


def test_feature_weights_must_match_and_be_positive():
    samples = torch.rand(5, 4, dtype=torch.float64)
    with pytest.raises(ValueError, match="feature_weights"):
        fit_basis(samples, 2, feature_weights=torch.ones(3))
    with pytest.raises(ValueError, match="feature_weights"):
        fit_basis(samples, 2, feature_weights=torch.tensor([1.0, 0.0, 1.0, 1.0]))
