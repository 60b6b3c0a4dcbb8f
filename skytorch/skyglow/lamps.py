r"""Lamp spectra for city lights, and their conversion to per-lumen spectral power.

Spectra are built from documented spectral models rather than measured tables:

* ``"white"`` — CIE illuminant E (equal energy), the white light of Dobashi et al. 2023.
* ``"incandescent"`` — CIE illuminant A: a black body at 2856 K.
* ``"led3000k"``, ``"led4000k"`` — phosphor-converted white LEDs with Ohno's (2005)
  spectral model of each emission band, :math:`S(λ) = [g + 2 g^5]/3`,
  :math:`g = \exp(-((λ - λ_0)/Δ)^2)`: a blue pump at 450 nm (Δ = 20 nm) and a broad
  phosphor band (Δ = 100 nm) whose centre and strength were fitted once so that the
  chromaticity lies on the Planckian locus at 3000 K and 4000 K (McCamy CCT 3005 K and
  4009 K, checked in the tests).
* ``"hps"`` — high-pressure sodium: the self-reversed, pressure-broadened Na D resonance
  (lobes at 581 and 597 nm around the 589 nm reversal) plus the Na I lines at 466.5,
  498.3, 568.8 and 615.4 nm (line positions from the NIST Atomic Spectra Database), with
  band strengths fitted to the typical HPS chromaticity (x, y) ≈ (0.52, 0.41), CCT ≈
  2030 K.
* ``"lps"`` — low-pressure sodium: the Na D doublet at 589.0/589.6 nm.

The spectra are relative spectral power on the 1-nm CIE grid; :func:`per_lumen` scales
them to emit one lumen: ``Φ_v = K_m ∫ S(λ) V(λ) dλ`` with K_m = 683.002 lm/W.

References
----------
1. Ohno, Y. 2005, "Spectral design considerations for white LED color rendering",
   Optical Engineering 44, 111302, doi:10.1117/1.2130694.
2. McCamy, C. S. 1992, "Correlated color temperature as an explicit function of
   chromaticity coordinates", Color Res. Appl. 17, 142, doi:10.1002/col.5080170211.
3. Kramida, A. et al., NIST Atomic Spectra Database (ver. 5.10), Na I lines,
   doi:10.18434/T4W30F.
4. CIE 015:2018, Colorimetry, 4th ed. (illuminants A and E), doi:10.25039/TR.015.2018.
5. Elvidge, C. D. et al. 2010, "Spectral identification of lighting type and character",
   Sensors 10, 3961, doi:10.3390/s100403961.
"""

from __future__ import annotations

from functools import lru_cache

import torch

from skytorch._validate import (
    as_tensor,
    check_choice,
    check_positive,
    check_range,
    refuse_gradient,
)
from skytorch.constants import LUMINOUS_EFFICACY_LM_PER_W

__all__ = ["LAMPS", "cct_mccamy", "lamp_spectrum", "luminance_weights", "per_lumen"]

#: lamp spectra available by name
LAMPS = ("white", "incandescent", "led3000k", "led4000k", "hps", "lps")

#: Ohno-model bands (centre [nm], half width Δ [nm], relative strength) of each lamp
_BANDS = {
    # blue pump + phosphor; phosphor centre and strength fitted to the Planckian locus
    "led3000k": ((450.0, 20.0, 1.0), (588.24, 100.0, 1.9619)),
    "led4000k": ((450.0, 20.0, 1.0), (577.61, 100.0, 1.0153)),
    # self-reversed Na D lobes, Na I lines (NIST ASD); blue line group fitted to x,y
    "hps": ((581.0, 7.0, 1.0), (597.0, 10.0, 1.0), (568.8, 3.0, 0.3), (615.4, 3.0, 0.25),
            (498.3, 3.0, 0.8376), (466.5, 3.0, 0.4188)),
    "lps": ((589.0, 0.5, 1.0), (589.6, 0.5, 0.5)),
}
#: CIE illuminant A colour temperature [K]
INCANDESCENT_TEMPERATURE_K = 2856.0


def _ohno_band(wavelength: torch.Tensor, centre: float, width: float) -> torch.Tensor:
    g = torch.exp(-(((wavelength - centre) / width) ** 2))
    return (g + 2.0 * g**5) / 3.0


def lamp_spectrum(lamp: str, wavelength_nm) -> torch.Tensor:
    """Relative spectral power of a lamp (arbitrary scale, peak of order 1).

    Parameters
    ----------
    lamp : str
        One of :data:`LAMPS`.
    wavelength_nm : array_like (...)
        Wavelengths [nm].

    Returns
    -------
    Tensor (...)
        Relative spectral power [arbitrary units per nm].

    Examples
    --------
    >>> float(lamp_spectrum("white", 550.0))
    1.0
    """
    check_choice("lamp", lamp, LAMPS)
    wavelength = as_tensor("wavelength_nm", wavelength_nm)
    if lamp == "white":
        return torch.ones_like(wavelength)
    if lamp == "incandescent":
        from skytorch.spectrum import blackbody_radiance

        return blackbody_radiance(wavelength, INCANDESCENT_TEMPERATURE_K) / 1e7
    total = torch.zeros_like(wavelength)
    for centre, width, strength in _BANDS[lamp]:
        total = total + strength * _ohno_band(wavelength, centre, width)
    return total


def _fine_grid():
    from skytorch.spectrum import photopic_luminous_efficiency, wavelength_grid

    fine = wavelength_grid("cie1")
    return fine, photopic_luminous_efficiency(fine)


def _spectrum_values(lamp, fine):
    if isinstance(lamp, str):
        return lamp_spectrum(lamp, fine)
    if not isinstance(lamp, (tuple, list)) or len(lamp) != 2:
        raise TypeError(f"lamp must be a name, one of {LAMPS}, or a pair (wavelength_nm, "
                        f"spectrum); got {lamp!r:.80}")
    wavelength, values = lamp
    refuse_gradient("a lamp's spectrum", why="its sample wavelengths are not differentiated "
                    "(the spectrum's values are)", lamp_wavelength_nm=wavelength)
    wavelength = check_positive("lamp wavelength_nm", wavelength, unit=" nm").reshape(-1)
    values = check_range("lamp spectrum", values, 0.0, dtype=wavelength.dtype).reshape(-1)
    if wavelength.numel() != values.numel() or wavelength.numel() < 2:
        raise ValueError(f"lamp (wavelength_nm, spectrum) must have the same length >= 2; "
                         f"got {wavelength.numel()} and {values.numel()}")
    order = torch.argsort(wavelength)
    return _interp(fine, wavelength[order], values[order])


def _interp(x, xp, fp):
    """Piecewise-linear ``fp(xp)`` at ``x`` (``xp`` increasing), 0 outside; linear in fp.

    Differentiable with respect to the spectrum ``fp`` (its gradient flows to the render).
    """
    x = x.to(fp.dtype)
    xp = xp.to(fp.dtype)
    upper = torch.searchsorted(xp, x, right=True).clamp(1, xp.numel() - 1)
    x0, x1 = xp[upper - 1], xp[upper]
    width = x1 - x0
    w = torch.where(width > 0, (x - x0) / torch.where(width > 0, width, 1.0), 1.0)
    values = torch.lerp(fp[upper - 1], fp[upper], w)
    return torch.where((x < xp[0]) | (x > xp[-1]), torch.zeros_like(values), values)


def per_lumen(lamp, wavelength_nm=None) -> torch.Tensor:
    """Spectral power of one lumen of the lamp's light [W nm^-1 lm^-1].

    Parameters
    ----------
    lamp : str or (wavelength_nm, spectrum)
        A name from :data:`LAMPS` or a sampled relative spectrum.
    wavelength_nm : array_like (wavelength,), optional
        Where to return it; default the 1-nm CIE grid.

    Returns
    -------
    Tensor (wavelength,)
        Spectral power with ``K_m ∫ S V dλ = 1 lm``.
    """
    fine, v = _fine_grid()
    spectrum = _spectrum_values(lamp, fine)
    lumens = LUMINOUS_EFFICACY_LM_PER_W * torch.trapezoid(spectrum * v, fine)
    if not bool(lumens > 0):
        raise ValueError("the lamp spectrum emits no visible light (zero luminous flux)")
    if wavelength_nm is None:
        return spectrum / lumens
    wavelength = as_tensor("wavelength_nm", wavelength_nm, dtype=torch.float64)
    return _spectrum_values(lamp, wavelength.reshape(-1)).reshape(wavelength.shape) / lumens


def _hat_matrix(wavelength: torch.Tensor, fine: torch.Tensor) -> torch.Tensor:
    """Build the (n_fine, n) piecewise-linear interpolation from ``wavelength`` to ``fine``.

    ``wavelength`` may be in any order; the interpolation is constant beyond the end
    samples.
    """
    order = torch.argsort(wavelength)
    ordered = wavelength[order]
    n = ordered.numel()
    hat_sorted = torch.zeros(fine.numel(), n, dtype=torch.float64)
    if n == 1:
        hat_sorted += 1.0
    else:
        x = fine.clamp(float(ordered[0]), float(ordered[-1]))
        index = torch.searchsorted(ordered, x, right=True).clamp(1, n - 1)
        t = (x - ordered[index - 1]) / (ordered[index] - ordered[index - 1])
        rows = torch.arange(fine.numel())
        hat_sorted[rows, index - 1] += 1 - t
        hat_sorted[rows, index] += t
    hat = torch.empty_like(hat_sorted)
    hat[:, order] = hat_sorted
    return hat


def luminance_weights(lamp, wavelength_nm) -> tuple[torch.Tensor, torch.Tensor]:
    """Weights turning per-lumen kernel radiances at a few wavelengths into luminance.

    With the kernel b(λ) interpolated piecewise linearly between the model wavelengths
    λ_m (hat functions h_m), the luminance of one lumen of lamp light is
    ``K_m ∫ s(λ) V(λ) b(λ) dλ = Σ_m w_m b(λ_m)`` with ``w_m = K_m ∫ h_m s V dλ``
    (``s`` from :func:`per_lumen`); the weights sum to 1.

    The weights of a named lamp are kept for the 32 most recent (lamp, wavelengths)
    (``functools.lru_cache`` keyed by those values; 0.5-2 ms to integrate, as much as a
    small skyglow fit step that asks for them); each call returns its own copy.

    Returns
    -------
    (weights, band_power) : Tensors (wavelength,)
        ``w_m`` [1] and the lamp's hat-averaged spectral power per lumen at each λ_m
        [W nm^-1 lm^-1] (``∫ h_m s dλ / ∫ h_m dλ``), used for spectral radiance.
    """
    wavelength = as_tensor("wavelength_nm", wavelength_nm, dtype=torch.float64).reshape(-1)
    if isinstance(lamp, str):
        weights, band_power = _named_lamp_weights(lamp, tuple(wavelength.tolist()))
        return weights.clone(), band_power.clone()
    return _lamp_weights(lamp, wavelength)


@lru_cache(maxsize=32)
def _named_lamp_weights(lamp: str, wavelength_nm: tuple[float, ...]
                        ) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`luminance_weights` of a named lamp at the given wavelengths (cached)."""
    return _lamp_weights(lamp, torch.tensor(wavelength_nm, dtype=torch.float64))


def _lamp_weights(lamp, wavelength: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Weights and band power of :func:`luminance_weights` (float64 wavelengths (m,))."""
    fine, v = _fine_grid()
    s = per_lumen(lamp)
    hat = _hat_matrix(wavelength, fine)
    weights = LUMINOUS_EFFICACY_LM_PER_W * torch.trapezoid(hat * (s * v)[:, None], fine, dim=0)
    band_power = (torch.trapezoid(hat * s[:, None], fine, dim=0)
                  / torch.trapezoid(hat, fine, dim=0))
    return weights, band_power


def cct_mccamy(spectrum, wavelength_nm) -> float:
    """Correlated colour temperature [K] by McCamy's (1992) cubic in (x, y)."""
    from skytorch.spectrum import spectrum_to_xyz

    xyz = spectrum_to_xyz(spectrum, wavelength_nm)
    x, y = (xyz[..., :2] / xyz.sum(dim=-1, keepdim=True)).unbind(-1)
    n = (x - 0.3320) / (0.1858 - y)
    return float(449.0 * n**3 + 3525.0 * n**2 + 6823.3 * n + 5520.33)
