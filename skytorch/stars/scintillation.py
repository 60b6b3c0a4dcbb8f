"""Scintillation (twinkling) of stars: Young's index and seeded twinkle sequences.

The scintillation index σ_I² is the variance of a star's intensity relative to its mean
over an exposure. Young (1967) gave the empirical law for apertures larger than the
Fresnel zone (a few cm) and exposures longer than the turbulence crossing time (a few ms);
Osborn et al. (2015) recalibrated it with a site factor C_Y from turbulence profiles. The
law grows with air mass and shrinks with aperture, exposure and observatory altitude.
For the naked eye (7 mm pupil, ~0.1 s) it is an extrapolation beyond the aperture range of
the data; the numbers then only order stars by how much they twinkle.

References
----------
1. Young, A. T. 1967, "Photometric error analysis. VI. Confirmation of Reiger's theory of
   scintillation", AJ 72, 747, doi:10.1086/110303.
2. Dravins, D., Lindegren, L., Mezey, E., Young, A. T. 1998, "Atmospheric intensity
   scintillation of stars. III. Effects for astronomical measurements", PASP 110, 610,
   doi:10.1086/316161 (eq. 10: Young's formula in the form used here).
3. Osborn, J., Föhring, D., Dhillon, V. S., Wilson, R. W. 2015, "Atmospheric scintillation
   in astronomical photometry", MNRAS 452, 1707, doi:10.1093/mnras/stv1400 (eq. 7, C_Y).

Examples
--------
>>> f"{float(scintillation_index(1.0, aperture_m=1.0, exposure_s=1.0)):.3e}"
'8.725e-06'
"""

from __future__ import annotations

import math

import torch

from skytorch._validate import check_choice, check_int, check_range, refuse_gradient

_AR1_BLOCK = 256


def _ar1(noise: torch.Tensor, rho: float) -> torch.Tensor:
    """Unit-variance AR(1) sequences g_k = ρ g_{k−1} + √(1 − ρ²) ε_k along the last axis.

    Evaluated block by block as a matmul with the lower-triangular kernel ρ^(i−j) plus the
    carried state ρ^(i+1) g_last; g_0 = ε_0 is drawn from the stationary law.
    """
    steps = torch.arange(_AR1_BLOCK, dtype=torch.float64)
    lag = steps[:, None] - steps[None, :]
    kernel = torch.where(lag >= 0, rho ** lag.clamp_min(0.0), torch.zeros((), dtype=lag.dtype))
    kernel = kernel * math.sqrt(1.0 - rho * rho)
    carry_weights = rho ** (steps + 1.0)
    blocks = []
    last = noise[..., 0] / rho  # so that g_0 = ε_0
    first = True
    for start in range(0, noise.shape[-1], _AR1_BLOCK):
        chunk = noise[..., start:start + _AR1_BLOCK]
        n = chunk.shape[-1]
        if first:
            chunk = chunk.clone()
            chunk[..., 0] = 0.0
            first = False
        block = chunk @ kernel[:n, :n].T + carry_weights[:n] * last[..., None]
        blocks.append(block)
        last = block[..., -1]
    return torch.cat(blocks, dim=-1)


__all__ = [
    "SCINTILLATION_MODELS",
    "scintillation_index",
    "scintillation_law",
    "twinkle",
]

#: "young1967": σ = 0.09 D^(−2/3) X^1.75 e^(−h/8 km) (2t)^(−1/2) with D in cm;
#: "osborn2015": σ² = 1e-5 C_Y² D^(−4/3) t^(−1) X³ e^(−2h/8 km) with D in m
SCINTILLATION_MODELS = ("young1967", "osborn2015")
#: scale height of the turbulence weighting in Young's law [m]
SCINTILLATION_SCALE_HEIGHT_M = 8000.0
#: Young's coefficient for σ with the aperture in cm [1]
YOUNG_COEFFICIENT = 0.09
#: Osborn et al.'s coefficient of σ² [m^(4/3) s]
OSBORN_COEFFICIENT = 1.0e-5
#: median empirical correction factor C_Y over the sites of Osborn et al. (2015)
OSBORN_DEFAULT_CY = 1.5


def scintillation_index(airmass, aperture_m: float = 0.007, exposure_s: float = 0.1,
                        altitude_m: float = 0.0, model: str = "young1967",
                        site_factor: float | None = None) -> torch.Tensor:
    """Young's scintillation index σ_I² for a star at a given air mass.

    Parameters
    ----------
    airmass : array_like
        ``(...)`` relative air mass X ≥ 1 (Young used sec z; the air mass keeps the law
        finite at the horizon).
    aperture_m : float
        Telescope (or pupil) diameter D [m].
    exposure_s : float
        Exposure or integration time t [s] (the eye: ~0.1 s).
    altitude_m : float
        Observatory altitude h [m].
    model : {"young1967", "osborn2015"}
        Young's original law or Osborn et al.'s form with site factor C_Y.
    site_factor : float, optional
        C_Y of ``"osborn2015"`` in [0.1, 10] (default 1.5: median of the sites studied; 1:
        Young's law); ``"young1967"`` takes none (ValueError).

    Returns
    -------
    torch.Tensor
        ``(...)`` σ_I² [1], relative intensity variance.

    Notes
    -----
    Young (1967; Dravins et al. 1998, eq. 10): σ_I = 0.09 D_cm^(−2/3) X^1.75 e^(−h/H)
    (2t)^(−1/2), H = 8000 m. Osborn et al. (2015, eq. 7): σ_I² = 10⁻⁵ C_Y² D^(−4/3) t^(−1)
    X³ e^(−2h/H), which for C_Y = 1 is Young's law with a slightly shallower air-mass
    exponent (0.09² × 100^(−4/3)/2 = 0.87 × 10⁻⁵).
    """
    x = check_range("airmass", airmass, 1.0 - 1e-9, 1e4)
    coefficient, exponent = scintillation_law(aperture_m, exposure_s, altitude_m, model,
                                              site_factor)
    return coefficient * x**exponent


def scintillation_law(aperture_m: float = 0.007, exposure_s: float = 0.1,
                      altitude_m: float = 0.0, model: str = "young1967",
                      site_factor: float | None = None) -> tuple[float, float]:
    """Zenith scintillation index and air-mass exponent of :func:`scintillation_index`.

    Parameters
    ----------
    aperture_m, exposure_s, altitude_m, model, site_factor
        As :func:`scintillation_index`.

    Returns
    -------
    coefficient : float
        σ_I² at the zenith (X = 1) [1].
    exponent : float
        p of σ_I² = coefficient · X^p: 3.5 (Young 1967) or 3 (Osborn et al. 2015).
    """
    check_choice("model", model, SCINTILLATION_MODELS)
    refuse_gradient("the scintillation law", why="its coefficient is a number of the "
                    "observing set-up", aperture_m=aperture_m, exposure_s=exposure_s,
                    altitude_m=altitude_m, site_factor=site_factor)
    diameter = float(check_range("aperture_m", aperture_m, 1e-4, 100.0, unit=" m"))
    exposure = float(check_range("exposure_s", exposure_s, 1e-6, 1e5, unit=" s"))
    height = float(check_range("altitude_m", altitude_m, -500.0, 1e4, unit=" m"))
    if model == "young1967" and site_factor is not None:
        raise ValueError(f"site_factor={site_factor!r} is C_Y of model='osborn2015'; "
                         "model='young1967' has none")
    decay = math.exp(-2.0 * height / SCINTILLATION_SCALE_HEIGHT_M)
    if model == "young1967":
        return (YOUNG_COEFFICIENT**2 * (100.0 * diameter) ** (-4.0 / 3.0)
                / (2.0 * exposure) * decay), 3.5
    c_y = float(check_range("site_factor", OSBORN_DEFAULT_CY if site_factor is None
                            else site_factor, 0.1, 10.0))
    return OSBORN_COEFFICIENT * c_y**2 * diameter ** (-4.0 / 3.0) / exposure * decay, 3.0


def twinkle(scintillation_index_value, n_samples: int, *, sample_interval_s: float = 0.01,
            correlation_time_s: float = 0.01, seed: int = 0) -> torch.Tensor:
    """Draw a seeded random sequence of relative intensities with a given scintillation index.

    Parameters
    ----------
    scintillation_index_value : array_like
        ``(...)`` σ_I² ≥ 0, finite (e.g. ``(time, star)`` from :func:`scintillation_index`).
    n_samples : int
        Length of the sequence (dimension ``sample``).
    sample_interval_s : float
        Time between samples [s].
    correlation_time_s : float
        1/e correlation time of the log-intensity [s] (~D/v_wind, milliseconds).
    seed : int
        Seed of a private ``torch.Generator``: the same seed gives the same sequence.

    Returns
    -------
    torch.Tensor
        ``(..., sample)`` intensity factors I/⟨I⟩ > 0 with mean 1 and variance σ_I².

    Notes
    -----
    Intensity scintillation of point sources is close to log-normal (Dravins et al.
    1997): I/⟨I⟩ = exp(σ_ln g − σ_ln²/2) with σ_ln² = ln(1 + σ_I²) and g a unit Gaussian
    AR(1) process, g_k = ρ g_{k−1} + √(1 − ρ²) ε_k, ρ = exp(−Δt/τ).
    """
    # no upper bound: a small aperture at the horizon reaches σ_I² ~ 1e7 (log-normal
    # intensities stay finite for any finite σ_I²: σ_ln² = ln(1 + σ_I²) ≤ 710)
    variance = check_range("scintillation_index_value", scintillation_index_value, 0.0)
    count = check_int("n_samples", n_samples, 1, 10_000_000)
    dt = float(check_range("sample_interval_s", sample_interval_s, 1e-9, 1e6, unit=" s"))
    tau = float(check_range("correlation_time_s", correlation_time_s, 0.0, 1e6, unit=" s"))
    generator = torch.Generator().manual_seed(check_int("seed", seed, 0, 2**63 - 1))
    noise = torch.randn(*variance.shape, count, generator=generator, dtype=torch.float64)
    rho = math.exp(-dt / tau) if tau > 0.0 else 0.0
    if rho > 1e-6:
        noise = _ar1(noise, rho)
    sigma_ln = torch.sqrt(torch.log1p(variance.to(torch.float64)))[..., None]
    result = torch.exp(sigma_ln * noise - 0.5 * sigma_ln**2)
    return result.to(variance.dtype)
