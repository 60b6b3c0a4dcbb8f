"""Bidirectional reflectance of the lunar surface and the Moon's albedo spectrum.

Two reflectance laws, chosen by author-year keyword (:data:`REFLECTANCE_MODELS`):

``"hapke2012"``
    Hapke's model in the form of his 2012 textbook: single scattering with a
    Henyey–Greenstein particle phase function, the shadow-hiding opposition effect
    (SHOE), isotropic multiple scattering through Hapke's (2002) approximation of
    Chandrasekhar's H function, optional coherent-backscatter opposition effect (CBOE)
    and Hapke's (1984) macroscopic-roughness correction.
``"lommel_seeliger"``
    The Lommel–Seeliger law with the same particle phase function: single scattering
    only, no opposition surge, no roughness. This is the "Hapke–Lommel–Seeliger" shading
    of Müller et al. (2012, eq. 3) and the cheap baseline.

Both return the *bidirectional reflectance* r [1/sr]: radiance leaving the surface
divided by the collimated irradiance falling on a plane normal to the Sun's rays
(Hapke's r; the radiance factor is I/F = π r).

Notes
-----
Hapke (2012, eq. 12.55, with K = 1)::

    r = (w / 4π) μ0e / (μ0e + μe) [p(g) B_SH(g) + H(μ0e) H(μe) − 1] B_CB(g) S(i, e, ψ)

    p(g)     = (1 − ξ²) / (1 + 2 ξ cos g + ξ²)^{3/2}            (ξ < 0: back-scattering)
    B_SH(g)  = 1 + B_S0 / (1 + tan(g/2) / h_S)
    B_CB(g)  = 1 + B_C0 [1 + (1 − e^{−z}) / z] / [2 (1 + z)²],   z = tan(g/2) / h_C
    H(x)     ≈ 1 / (1 − w x [r0 + (1 − 2 r0 x)/2 ln((1 + x)/x)]),   r0 = (1 − γ)/(1 + γ),
               γ = √(1 − w)                                        (Hapke 2002, eq. 13)

``μ0e``, ``μe`` and the shadowing function ``S`` are Hapke's (1984) effective cosines for
a surface with mean slope angle θ̄ (Hapke 2012, eq. 12.46–12.54). The azimuth ψ between
the planes of incidence and emission follows from ``cos g = μ0 μ + sin i sin e cos ψ``.

Lunar parameters (:data:`HAPKE_PARAMETERS`, ``"helfenstein1987"``): the disc-averaged
lunar solution of Helfenstein & Veverka (1987) as quoted in the secondary literature:
w = 0.21, ξ = −0.18 (single-lobe Henyey–Greenstein), B_S0 = 2.0, h_S = 0.07, θ̄ = 20°, no
CBOE. The primary table could not be consulted. w, h_S, θ̄ and B_S0 = S(0)/(w p(0)) agree
with a transcription of their disc-integrated Table II (w = 0.21, h = 0.07, S(0) = 0.71,
θ̄ = 20°), which however gives a two-term Legendre phase function (b = 0.29, c = 0.39)
instead of ξ; that variant is 0.09–0.19 mag off the ROLO phase curve, the single-lobe set
0.04–0.07 mag (docs/moon.md). The disc integral is validated against two independent
phase curves, ROLO (Kieffer & Stone 2005) and Krisciunas & Schaefer (1991), and the
roughness term against Hapke's (2012) Table 12.1, in ``tests/test_moon_brightness.py`` and
``tests/test_moon_reflectance.py``.

The lunar albedo colour (:func:`albedo`) is the quadratic through Müller et al.'s (2012,
§2.2.2) colour coefficients kλ = (0.92, 0.79, 0.64) at (680, 550, 440) nm, which they
derived from Yapo & Cutler's (2009) second-degree fit to a measured lunar reflectance
spectrum; it is normalised to 1 at the reference wavelength 550 nm, where the Hapke
parameters apply, so that ``r(λ) = r_550(i, e, g) · albedo(λ)``. The implied lunar colour
index is checked against the observed B − V = 0.92 of the Moon in the tests.

References
----------
1. Hapke, B. 2012, *Theory of Reflectance and Emittance Spectroscopy*, 2nd ed., Cambridge
   University Press, doi:10.1017/CBO9781139025683, ch. 9–12.
2. Hapke, B. 1984, "Bidirectional reflectance spectroscopy 3. Correction for macroscopic
   roughness", Icarus 59, 41, doi:10.1016/0019-1035(84)90054-X.
3. Hapke, B. 2002, "Bidirectional reflectance spectroscopy 5. The coherent backscatter
   opposition effect and anisotropic scattering", Icarus 157, 523,
   doi:10.1006/icar.2002.6853.
4. Helfenstein, P., Veverka, J. 1987, "Photometric properties of lunar terrains derived
   from Hapke's equation", Icarus 72, 342, doi:10.1016/0019-1035(87)90179-5.
5. Müller, T., Engel, J., Döllner, J. 2012, "Single-Pass Rendering of Day and Night Sky
   Phenomena", Proc. VMV, doi:10.2312/PE/VMV/VMV12/055-062.
6. Yapo, T. C., Cutler, B. 2009, "Rendering lunar eclipses", Proc. Graphics Interface,
   p. 63.
7. Sato, H., Robinson, M. S., Hapke, B., Denevi, B. W., Boyd, A. K. 2014, "Resolved Hapke
   parameter maps of the Moon", J. Geophys. Res. Planets 119, 1775,
   doi:10.1002/2013JE004580 (the same model form fitted to LROC WAC data).
8. Kieffer, H. H., Stone, T. C. 2005, "The spectral irradiance of the Moon", AJ 129, 2887,
   doi:10.1086/430185 (ROLO disc-reflectance model, the validation phase curve).

Examples
--------
>>> import torch
>>> from skytorch.moon.reflectance import reflectance
>>> r = reflectance(torch.tensor(1.0), torch.tensor(1.0), torch.tensor(0.0))
>>> bool(r > 0)
True
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from types import MappingProxyType

import torch

from skytorch._modules import make_callable
from skytorch._validate import (
    as_tensor,
    check_broadcastable,
    check_choice,
    check_range,
    common_dtype,
)
from skytorch.constants import DEGREE

__all__ = [
    "ALBEDO_REFERENCE_WAVELENGTH_NM",
    "HAPKE_PARAMETERS",
    "MULLER2012_COLOUR",
    "REFLECTANCE_MODELS",
    "albedo",
    "chandrasekhar_h",
    "henyey_greenstein_phase",
    "lommel_seeliger",
    "reflectance",
    "roughness_correction",
]

#: reflectance laws, by author-year keyword
REFLECTANCE_MODELS = ("hapke2012", "lommel_seeliger")

#: published lunar Hapke parameter sets (see the module Notes for provenance)
HAPKE_PARAMETERS = MappingProxyType({
    "helfenstein1987": MappingProxyType({
        "single_scattering_albedo": 0.21,
        "asymmetry": -0.18,  # single-lobe Henyey-Greenstein xi (negative: back-scattering)
        "shoe_amplitude": 2.0,  # B_S0
        "shoe_width": 0.07,  # h_S
        "cboe_amplitude": 0.0,  # B_C0
        "cboe_width": 0.0,  # h_C (unused when B_C0 = 0)
        "roughness_rad": 20.0 * DEGREE,  # mean slope angle theta-bar
    }),
})

#: Müller et al. (2012) lunar colour coefficients k_lambda at (680, 550, 440) nm
MULLER2012_COLOUR = MappingProxyType({680.0: 0.92, 550.0: 0.79, 440.0: 0.64})

#: wavelength at which the Hapke parameters (and albedo() == 1) apply [nm]
ALBEDO_REFERENCE_WAVELENGTH_NM = 550.0

#: valid wavelength range of the albedo colour law [nm] (CIE visible range)
_ALBEDO_RANGE_NM = (360.0, 830.0)


def _quadratic_through(points):
    """Coefficients (c0, c1, c2) of the parabola through three (x, y) points."""
    (x0, y0), (x1, y1), (x2, y2) = points
    s01 = (y1 - y0) / (x1 - x0)
    s12 = (y2 - y1) / (x2 - x1)
    c2 = (s12 - s01) / (x2 - x0)
    c1 = s01 - c2 * (x0 + x1)
    c0 = y0 - c1 * x0 - c2 * x0 * x0
    return c0, c1, c2


_COLOUR_COEFFICIENTS = _quadratic_through(sorted(MULLER2012_COLOUR.items()))


def albedo(wavelength_nm) -> torch.Tensor:
    """Relative lunar albedo spectrum, 1 at 550 nm (the Moon's reddish colour).

    Parameters
    ----------
    wavelength_nm : Tensor (n_wavelength,) or (...)
        Wavelengths in [360, 830] nm.

    Returns
    -------
    Tensor, same shape
        kλ(λ) / kλ(550 nm) with kλ the parabola through Müller et al.'s (2012) colour
        coefficients (0.92, 0.79, 0.64) at (680, 550, 440) nm: 0.81 at 440 nm, 1.16 at
        680 nm.
    """
    wl = check_range("wavelength_nm", wavelength_nm, *_ALBEDO_RANGE_NM, unit=" nm")
    c0, c1, c2 = _COLOUR_COEFFICIENTS
    reference = c0 + c1 * ALBEDO_REFERENCE_WAVELENGTH_NM + c2 * ALBEDO_REFERENCE_WAVELENGTH_NM**2
    return (c0 + c1 * wl + c2 * wl * wl) / reference


def henyey_greenstein_phase(cos_g, asymmetry) -> torch.Tensor:
    """Single-lobe Henyey–Greenstein particle phase function p(g), normalised to 4π.

    ``p(g) = (1 − ξ²) / (1 + 2 ξ cos g + ξ²)^{3/2}`` in Hapke's sign convention (g is the
    phase angle, ξ < 0 back-scattering); ∫ p dΩ / 4π = 1.
    """
    xi = asymmetry
    return (1.0 - xi * xi) / (1.0 + 2.0 * xi * cos_g + xi * xi) ** 1.5


def chandrasekhar_h(x: torch.Tensor, single_scattering_albedo) -> torch.Tensor:
    """Hapke's (2002, eq. 13) approximation of Chandrasekhar's H function (error < 1 %).

    Parameters
    ----------
    x : Tensor (...)
        Cosine in [0, 1].
    single_scattering_albedo : float or Tensor
        w in [0, 1].
    """
    w = single_scattering_albedo
    gamma = torch.sqrt(torch.as_tensor(1.0 - w, dtype=x.dtype))
    r0 = (1.0 - gamma) / (1.0 + gamma)
    # x ln((1 + x)/x) -> 0 as x -> 0; the clamp keeps value and gradient finite there
    xs = x.clamp_min(torch.finfo(x.dtype).tiny ** 0.5)
    log_term = torch.log1p(1.0 / xs)
    return 1.0 / (1.0 - w * xs * (r0 + 0.5 * (1.0 - 2.0 * r0 * xs) * log_term))


def _safe_cot(x: torch.Tensor, eps: float) -> torch.Tensor:
    """Return cot x for x in [0, π/2], capped at 1/eps for x -> 0 (finite, with gradient)."""
    return torch.cos(x) / torch.sin(x).clamp_min(eps)


def roughness_correction(mu0, mu, cos_g, roughness_rad):
    """Hapke's (1984) macroscopic roughness: effective cosines and shadowing function.

    Parameters
    ----------
    mu0, mu : Tensor (...)
        Cosines of the incidence and emission angles on the smooth sphere, in [0, 1].
    cos_g : Tensor (...)
        Cosine of the phase angle.
    roughness_rad : float or Tensor
        Mean slope angle θ̄ [rad], in [0, 60°]; a float 0 returns (μ0, μ, 1). Tensors
        broadcast against the geometry (batched sweeps, gradients).

    Returns
    -------
    (mu0e, mue, shadowing) : tuple of Tensor (...)
        Effective cosines μ0e, μe and the shadowing function S (Hapke 2012, eq. 12.46–12.54).
    """
    if not isinstance(roughness_rad, torch.Tensor) and roughness_rad <= 0.0:
        return mu0, mu, torch.ones_like(mu0 * mu)
    dtype = mu0.dtype
    eps = float(torch.finfo(dtype).eps)
    # tensor θ̄ (batched sweeps, gradients): floored at 1e-4 rad, where S = 1 to 1e-8
    theta = torch.as_tensor(roughness_rad, dtype=dtype).clamp_min(1e-4)
    tan_t = torch.tan(theta)
    cot_t = 1.0 / tan_t
    chi = 1.0 / torch.sqrt(1.0 + math.pi * tan_t * tan_t)

    one = 1.0 - eps
    mu0c = mu0.clamp(0.0, one)
    muc = mu.clamp(0.0, one)
    sin_i = torch.sqrt(1.0 - mu0c * mu0c)
    sin_e = torch.sqrt(1.0 - muc * muc)
    inc = torch.atan2(sin_i, mu0c)
    emi = torch.atan2(sin_e, muc)

    # azimuth psi between the planes of incidence and emission (0 when undefined)
    denominator = sin_i * sin_e
    defined = denominator > 1e3 * eps
    cos_psi = torch.where(defined, (cos_g - mu0c * muc) / torch.where(defined, denominator, 1.0),
                          torch.ones_like(denominator))
    cos_psi = cos_psi.clamp(-one, one)
    psi = torch.acos(cos_psi)
    sin2_half_psi = 0.5 * (1.0 - cos_psi)
    tan_half_psi = torch.sqrt((1.0 - cos_psi) / (1.0 + cos_psi))
    f_psi = torch.exp(-2.0 * tan_half_psi)

    def e1(x):
        return torch.exp(-2.0 / math.pi * cot_t * _safe_cot(x, eps))

    def e2(x):
        cot_x = _safe_cot(x, eps)
        return torch.exp(-1.0 / math.pi * cot_t * cot_t * cot_x * cot_x)

    def eta(x):
        return chi * (torch.cos(x) + torch.sin(x) * tan_t * e2(x) / (2.0 - e1(x)))

    e1_i, e2_i, e1_e, e2_e = e1(inc), e2(inc), e1(emi), e2(emi)
    eta_i, eta_e = eta(inc), eta(emi)

    # case i <= e
    den_a = 2.0 - e1_e - psi / math.pi * e1_i
    mu0e_a = chi * (mu0c + sin_i * tan_t * (cos_psi * e2_e + sin2_half_psi * e2_i) / den_a)
    mue_a = chi * (muc + sin_e * tan_t * (e2_e - sin2_half_psi * e2_i) / den_a)
    s_a = mue_a / eta_e * mu0c / eta_i * chi / (1.0 - f_psi + f_psi * chi * mu0c / eta_i)
    # case e < i
    den_b = 2.0 - e1_i - psi / math.pi * e1_e
    mu0e_b = chi * (mu0c + sin_i * tan_t * (e2_i - sin2_half_psi * e2_e) / den_b)
    mue_b = chi * (muc + sin_e * tan_t * (cos_psi * e2_i + sin2_half_psi * e2_e) / den_b)
    s_b = mue_b / eta_e * mu0c / eta_i * chi / (1.0 - f_psi + f_psi * chi * muc / eta_e)

    first = inc <= emi
    return (torch.where(first, mu0e_a, mu0e_b), torch.where(first, mue_a, mue_b),
            torch.where(first, s_a, s_b))


def _parameters(parameters):
    if isinstance(parameters, str):
        check_choice("parameters", parameters, tuple(HAPKE_PARAMETERS))
        return dict(HAPKE_PARAMETERS[parameters])
    if not isinstance(parameters, Mapping):
        raise TypeError(f"parameters must be a name, one of {tuple(HAPKE_PARAMETERS)}, or a "
                        f"mapping of Hapke parameters; got {parameters!r:.80}")
    values = dict(HAPKE_PARAMETERS["helfenstein1987"])
    unknown = set(parameters) - set(values)
    if unknown:
        raise ValueError(f"unknown Hapke parameters {sorted(unknown)}; valid: {sorted(values)}")
    values.update(parameters)
    check_range("single_scattering_albedo", values["single_scattering_albedo"], 0.0, 1.0)
    check_range("asymmetry", values["asymmetry"], -1.0, 1.0, low_inclusive=False,
                high_inclusive=False)
    check_range("roughness_rad", values["roughness_rad"], 0.0, 60.0 * DEGREE, unit=" rad")
    return values


def _is_zero(value) -> bool:
    """Tell whether a plain number equals 0 (tensor parameters always take the full path)."""
    return not isinstance(value, torch.Tensor) and value == 0.0


def _opposition(tan_half_g, amplitude, width):
    """1 + B0 / (1 + tan(g/2)/h), written to stay finite for g -> π (tan -> inf)."""
    if _is_zero(amplitude):
        return torch.ones_like(tan_half_g)
    return 1.0 + amplitude * width / (width + tan_half_g)


def _coherent_backscatter(tan_half_g, amplitude, width):
    if _is_zero(amplitude):
        return torch.ones_like(tan_half_g)
    z = tan_half_g / width
    zs = z.clamp_min(1e-6)
    k = torch.where(z > 1e-6, 1.0 + (-torch.expm1(-zs)) / zs, 2.0 - z)
    return 1.0 + amplitude * k / (2.0 * (1.0 + z) ** 2)


def _prepare(mu0, mu, phase_angle_rad):
    dtype = common_dtype(mu0, mu, phase_angle_rad)
    # cosines: a round-off of 1e-6 beyond ±1 is accepted (and clamped below)
    mu0 = check_range("mu0", as_tensor("mu0", mu0, dtype=dtype), -1.0 - 1e-6, 1.0 + 1e-6)
    mu = check_range("mu", as_tensor("mu", mu, dtype=dtype), -1.0 - 1e-6, 1.0 + 1e-6)
    g = check_range("phase_angle_rad", as_tensor("phase_angle_rad", phase_angle_rad,
                                                 dtype=dtype), 0.0, math.pi + 1e-6,
                    unit=" rad")
    check_broadcastable(mu0=mu0, mu=mu, phase_angle_rad=g)
    g = g.clamp(0.0, math.pi)
    mu0, mu, g = torch.broadcast_tensors(mu0, mu, g)
    lit = (mu0 > 0.0) & (mu > 0.0)
    # safe substitutes outside the lit and visible hemisphere keep gradients finite
    mu0s = torch.where(lit, mu0, torch.ones_like(mu0)).clamp_max(1.0)
    mus = torch.where(lit, mu, torch.ones_like(mu)).clamp_max(1.0)
    # tan(g/2) = sin g / (1 + cos g) = sqrt((1 - cos g)/(1 + cos g)); capped near g = π
    half = 0.5 * g
    tan_half = torch.sin(half) / torch.cos(half).clamp_min(torch.finfo(dtype).eps)
    return mu0s, mus, g, tan_half, lit


def lommel_seeliger(mu0, mu, phase_angle_rad, parameters="helfenstein1987") -> torch.Tensor:
    """Lommel–Seeliger reflectance with a Henyey–Greenstein phase function [1/sr].

    ``r = (w/4π) p(g) μ0 / (μ0 + μ)`` on the lit, visible hemisphere (μ0, μ > 0), else 0.
    Parameters as in :func:`reflectance`.
    """
    values = _parameters(parameters)
    mu0s, mus, g, _, lit = _prepare(mu0, mu, phase_angle_rad)
    w = values["single_scattering_albedo"]
    p = henyey_greenstein_phase(torch.cos(g), values["asymmetry"])
    r = w / (4.0 * math.pi) * p * mu0s / (mu0s + mus)
    return torch.where(lit, r, torch.zeros_like(r))


def _hapke(mu0, mu, phase_angle_rad, parameters) -> torch.Tensor:
    values = _parameters(parameters)
    mu0s, mus, g, tan_half, lit = _prepare(mu0, mu, phase_angle_rad)
    w = values["single_scattering_albedo"]
    cos_g = torch.cos(g)
    mu0e, mue, shadowing = roughness_correction(mu0s, mus, cos_g, values["roughness_rad"])
    p = henyey_greenstein_phase(cos_g, values["asymmetry"])
    shoe = _opposition(tan_half, values["shoe_amplitude"], values["shoe_width"])
    cboe = _coherent_backscatter(tan_half, values["cboe_amplitude"], values["cboe_width"])
    multiple = chandrasekhar_h(mu0e, w) * chandrasekhar_h(mue, w) - 1.0
    r = (w / (4.0 * math.pi) * mu0e / (mu0e + mue) * (p * shoe + multiple) * cboe
         * shadowing)
    return torch.where(lit, r, torch.zeros_like(r))


def reflectance(mu0, mu, phase_angle_rad, model: str = "hapke2012", wavelength_nm=None,
                parameters="helfenstein1987") -> torch.Tensor:
    """Bidirectional reflectance r of the lunar surface [1/sr].

    Parameters
    ----------
    mu0 : Tensor (...)
        Cosine of the incidence angle (surface normal · direction to the Sun).
    mu : Tensor (...)
        Cosine of the emission angle (surface normal · direction to the observer).
    phase_angle_rad : Tensor (...)
        Phase angle g in [0, π] [rad] (angle between the directions to Sun and observer).
    model : {"hapke2012", "lommel_seeliger"}
        Reflectance law (see the module docstring).
    wavelength_nm : Tensor (n_wavelength,), optional
        Wavelengths [nm]; when given, the result is multiplied by :func:`albedo` and gains a
        trailing ``wavelength`` dimension.
    parameters : str or dict
        Name of a set in :data:`HAPKE_PARAMETERS` or a dict overriding some of its keys
        (``single_scattering_albedo``, ``asymmetry``, ``shoe_amplitude``, ``shoe_width``,
        ``cboe_amplitude``, ``cboe_width``, ``roughness_rad``). Values may be tensors that
        broadcast against the geometry, e.g. shape (n_case, 1, 1) against disc points of
        shape (n_phase, n_point), for sweeps and for fitting parameters with autograd.

    Returns
    -------
    Tensor (...) or (..., n_wavelength)
        r [1/sr]; radiance = r × irradiance normal to the Sun's rays. Exactly 0 where the
        surface is unlit (μ0 ≤ 0) or faces away (μ ≤ 0). Finite, with finite gradients,
        at g = 0 and g = π.

    Raises
    ------
    ValueError
        Unknown model, phase angle outside [0, π], NaN inputs.

    Examples
    --------
    >>> import math, torch
    >>> from skytorch.moon import reflectance
    >>> mu0, mu, g = torch.tensor(0.5), torch.tensor(1.0), torch.tensor(math.pi / 3)
    >>> reflectance(mu0, mu, g, wavelength_nm=torch.tensor([440.0, 550.0, 680.0]))
    tensor([0.0070, 0.0087, 0.0101])
    """
    check_choice("model", model, REFLECTANCE_MODELS)
    if model == "hapke2012":
        r = _hapke(mu0, mu, phase_angle_rad, parameters)
    else:
        r = lommel_seeliger(mu0, mu, phase_angle_rad, parameters)
    if wavelength_nm is None:
        return r
    colour = albedo(as_tensor("wavelength_nm", wavelength_nm, dtype=r.dtype))
    return r.unsqueeze(-1) * colour


# ``skytorch.moon.reflectance`` is this module, callable as :func:`reflectance`
make_callable(__name__)
