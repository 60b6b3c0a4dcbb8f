r"""PCA basis of skyglow kernel images (Dobashi et al. 2023, eq. 4).

Each kernel image b(θ, φ, λ) of one source (one distance r and source altitude h_c, for
one observer altitude h_o) is a sample; :func:`fit_basis` finds the principal components
with scikit-learn's :class:`~sklearn.decomposition.PCA` and returns coefficients such that

.. math::

    b(θ, φ, λ; r, h_c) \approx \sum_{k=0}^{M} c_k(r, h_c)\, B_k(θ, φ, λ),

where ``B_0`` is the mean of the normalised samples (PCA centres its data; the mean enters
as one more basis image whose coefficient is the sample's scale) and ``B_1 … B_M`` are the
principal components. Samples are divided by their root-mean-square value before the PCA so
that near and far sources, whose images differ by orders of magnitude, are represented with
the same relative accuracy; the scale is folded back into the coefficients.

References
----------
1. Dobashi, Y., Ishikawa, N. & Iwasaki, K. 2023, ACM Trans. Graph. 42, 219,
   doi:10.1145/3618337.
2. Pedregosa, F. et al. 2011, "Scikit-learn: Machine Learning in Python", JMLR 12, 2825.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass

import numpy as np
import torch

from skytorch._validate import check_int, check_range

__all__ = ["BasisFit", "fit_basis"]

logger = logging.getLogger(__name__)


@dataclass
class BasisFit:
    """Result of :func:`fit_basis`.

    Attributes
    ----------
    basis : Tensor (component, n_features)
        ``B_0`` (mean of the normalised samples) followed by the M principal components.
    coefficients : Tensor (n_samples, component)
        ``c_k`` of every sample (scale included).
    scale : Tensor (n_samples,)
        Root-mean-square of each sample.
    explained_variance_ratio : Tensor (M,)
        Fraction of the normalised samples' variance explained by each component.
    n_components : int
        M (without the mean).
    """

    basis: torch.Tensor
    coefficients: torch.Tensor
    scale: torch.Tensor
    explained_variance_ratio: torch.Tensor
    n_components: int

    def reconstruct(self) -> torch.Tensor:
        """Return the approximated samples (n_samples, n_features)."""
        return self.coefficients @ self.basis


def _max_components(n_samples: int, n_features: int) -> int:
    return min(n_samples, n_features)


def resolve_components(n_components, n_samples: int, n_features: int) -> int | float:
    """Validate ``n_components`` (an int M, or a variance threshold in (0, 1)).

    More components than the data allow (``min(n_samples, n_features)``) are clamped with
    a :class:`UserWarning`.
    """
    if isinstance(n_components, float) and not float(n_components).is_integer():
        check_range("n_components", n_components, 0.0, 1.0, low_inclusive=False,
                    high_inclusive=False)
        return float(n_components)
    m = check_int("n_components", n_components, low=1)
    limit = _max_components(n_samples, n_features)
    if m > limit:
        warnings.warn(
            f"n_components={m} exceeds the {limit} components that {n_samples} samples of "
            f"{n_features} features allow; using {limit}", UserWarning, stacklevel=3)
        m = limit
    return m


def fit_basis(samples: torch.Tensor, n_components=32, *, normalize: bool = True,
              random_state: int = 0, feature_weights: torch.Tensor | None = None) -> BasisFit:
    """Principal components of kernel images.

    Parameters
    ----------
    samples : Tensor (n_samples, n_features)
        One flattened kernel image per row (e.g. all (r, h_c) for one h_o).
    n_components : int or float
        Number M of principal components, or, if a float in (0, 1), the cumulative
        explained-variance threshold that selects M (Dobashi et al. §3.3).
    normalize : bool
        Divide each sample by its root-mean-square value before the PCA (default).
    random_state : int
        Seed of scikit-learn's randomised solver (used for large problems).
    feature_weights : Tensor (n_features,), optional
        Multiplicity w_j of each feature: the samples stand for images in which feature j
        occurs w_j times (the azimuths 0 < θ < π of mirror-symmetric kernel images occur
        twice). The PCA is exactly that of the expanded images, computed on the
        √w-weighted features (half the work for mirrored images); the basis is returned on
        the given features.

    Returns
    -------
    BasisFit

    Raises
    ------
    ValueError
        For non-finite samples or an invalid ``n_components``.
    """
    from sklearn.decomposition import PCA

    if samples.ndim != 2:
        raise ValueError(f"samples must have shape (n_samples, n_features); got "
                         f"{tuple(samples.shape)}")
    if not bool(torch.isfinite(samples).all()):
        raise ValueError("samples must be finite")
    n_samples, n_features = samples.shape
    m = resolve_components(n_components, n_samples, n_features)
    data = samples.detach().to(torch.float64)
    if feature_weights is None:
        weight = torch.ones(n_features, dtype=torch.float64)
    else:
        weight = torch.as_tensor(feature_weights, dtype=torch.float64).reshape(-1)
        if weight.numel() != n_features or not bool((weight > 0).all()):
            raise ValueError(f"feature_weights must hold {n_features} positive values")
    if normalize:
        scale = (data.pow(2) @ weight / weight.sum()).sqrt()
    else:
        scale = torch.ones(n_samples, dtype=torch.float64)
    safe = torch.where(scale > 0, scale, torch.ones_like(scale))
    root = weight.sqrt().numpy()
    normalized = (data / safe[:, None]).numpy()
    if n_samples == 1:
        # nothing to analyse: the mean image reproduces the single sample exactly
        components = np.zeros((0, n_features))
        ratio = np.zeros(0)
    else:
        m_fit = m if isinstance(m, float) else min(m, n_samples, n_features)
        pca = PCA(n_components=m_fit, svd_solver="full" if isinstance(m, float) else "auto",
                  random_state=random_state)
        pca.fit(normalized * root)
        components = pca.components_ / root  # orthonormal in the expanded feature space
        ratio = pca.explained_variance_ratio_
    mean = normalized.mean(axis=0)
    basis = np.concatenate([mean[None, :], components], axis=0)
    weights = ((normalized - mean) * root**2) @ components.T
    coefficients = np.concatenate([np.ones((n_samples, 1)), weights], axis=1)
    coefficients = coefficients * scale.numpy()[:, None]
    logger.info("PCA: %d components explain %.6f of the variance", components.shape[0],
                float(ratio.sum()) if ratio.size else 1.0)
    return BasisFit(basis=torch.as_tensor(basis), coefficients=torch.as_tensor(coefficients),
                    scale=scale, explained_variance_ratio=torch.as_tensor(ratio),
                    n_components=int(components.shape[0]))
