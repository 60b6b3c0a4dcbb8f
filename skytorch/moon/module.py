"""``MoonPhotometry``: the lunar photometric model as a ``torch.nn.Module``.

The module fixes a reflectance law and its parameters and holds, as a buffer, the V
magnitude of the sunlight-times-albedo spectrum at 1 AU (computed once with
:func:`skytorch.spectrum.spectrum_to_magnitude`), so that a magnitude costs only the
disc quadrature::

    m(α) = m_ref − 2.5 log10[(1 AU / d_S)² (R_M / d)² (Q_sun(α) + ε(α) Q_earth(α))]

with the notation of :mod:`skytorch.moon.brightness`; it returns the same numbers as
:func:`skytorch.moon.brightness.magnitude`.

Examples
--------
>>> import math, torch
>>> from skytorch.moon.module import MoonPhotometry
>>> moon = MoonPhotometry()
>>> -10.3 < float(moon(torch.tensor(math.radians(90.0), dtype=torch.float64))) < -9.7
True
"""

from __future__ import annotations

import torch
from torch import nn

from skytorch._validate import (
    as_tensor,
    check_broadcastable,
    check_choice,
    check_range,
    common_dtype,
)
from skytorch.constants import ASTRONOMICAL_UNIT_M, MEAN_EARTH_MOON_DISTANCE_M, MOON_RADIUS_M
from skytorch.moon.brightness import (
    V_BAND_WAVELENGTHS_NM,
    _quadrature,
    disc_integrated_reflectance,
)
from skytorch.moon.disc import _flag
from skytorch.moon.earthshine import earthshine_irradiance_ratio
from skytorch.moon.reflectance import REFLECTANCE_MODELS, _parameters, albedo

__all__ = ["MoonPhotometry"]


class MoonPhotometry(nn.Module):
    """Disc-integrated V photometry of the Moon for one reflectance law.

    Parameters
    ----------
    model : {"hapke2012", "lommel_seeliger"}
        Reflectance law.
    parameters : str or dict
        Hapke parameter set (see :data:`skytorch.moon.reflectance.HAPKE_PARAMETERS`).
    n_quadrature : int
        Gauss–Legendre nodes per photometric coordinate.
    earthshine : bool
        Include earthshine (finite magnitude at new Moon).
    """

    def __init__(self, model: str = "hapke2012", parameters="helfenstein1987",
                 n_quadrature: int = 48, earthshine: bool = True):
        super().__init__()
        from skytorch.spectrum import solar_irradiance, spectrum_to_magnitude

        self.model = check_choice("model", model, REFLECTANCE_MODELS)
        self.parameters_set = _parameters(parameters)
        self.n_quadrature = _quadrature(n_quadrature)
        self.earthshine = _flag("earthshine", earthshine)
        wl = torch.tensor(V_BAND_WAVELENGTHS_NM, dtype=torch.float64)
        reference = spectrum_to_magnitude(solar_irradiance(wl) * albedo(wl), wl, band="V")
        self.register_buffer("reference_magnitude", reference)

    def extra_repr(self) -> str:
        """Describe the model options in the module's ``repr``."""
        return (f"model={self.model!r}, n_quadrature={self.n_quadrature}, "
                f"earthshine={self.earthshine}")

    def forward(self, phase_angle_rad, distance_m=MEAN_EARTH_MOON_DISTANCE_M,
                sun_distance_m=ASTRONOMICAL_UNIT_M) -> torch.Tensor:
        """V magnitude [mag] at phase angle α [rad] (…), distances [m] broadcasting.

        Shapes that do not broadcast raise ``ValueError`` naming them, before any
        arithmetic; out-of-range values raise ``ValueError`` naming the parameter.
        """
        dtype = common_dtype(phase_angle_rad, distance_m, sun_distance_m)
        alpha = as_tensor("phase_angle_rad", phase_angle_rad, dtype=dtype)
        d = check_range("distance_m", distance_m, MOON_RADIUS_M, low_inclusive=False,
                        unit=" m", dtype=dtype)
        d_sun = check_range("sun_distance_m", sun_distance_m, 0.0, low_inclusive=False,
                            unit=" m", dtype=dtype)
        check_broadcastable(phase_angle_rad=alpha, distance_m=d, sun_distance_m=d_sun)
        kwargs = {"model": self.model, "parameters": self.parameters_set,
                  "n_quadrature": self.n_quadrature}
        q = disc_integrated_reflectance(alpha, **kwargs)
        if self.earthshine:
            q = q + (earthshine_irradiance_ratio(alpha.abs(), distance_m=d)
                     * disc_integrated_reflectance(alpha, earthshine=True, distance_m=d,
                                                   **kwargs))
        scale = (ASTRONOMICAL_UNIT_M / d_sun) ** 2 * (MOON_RADIUS_M / d) ** 2
        return self.reference_magnitude.to(dtype) - 2.5 * torch.log10(scale * q)
