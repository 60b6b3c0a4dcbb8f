"""Checks of the inputs shared by the atmosphere's kernels.

They sit below :mod:`skytorch.atmosphere.model` so that the kernels it calls
(single scattering, transmittance tables, refraction) check wavelengths, altitudes and
their atmosphere argument without importing the model back.

Examples
--------
>>> import torch
>>> wavelength_tensor(torch.tensor(550.0))
tensor([550.])
>>> check_atmosphere("atmosphere", object())
Traceback (most recent call last):
...
TypeError: atmosphere must be a skytorch.atmosphere.Atmosphere; got object
"""

from __future__ import annotations

import torch

from skytorch._validate import check_range
from skytorch.atmosphere.rayleigh import WAVELENGTH_RANGE_NM

__all__ = ["ATMOSPHERE_INTERFACE", "altitude_tensor", "check_atmosphere", "wavelength_tensor"]

#: the methods of :class:`~skytorch.atmosphere.Atmosphere` the kernels use
ATMOSPHERE_INTERFACE = ("constituents", "profiles", "check_geometry", "parameters_dict")


def check_atmosphere(name: str, value) -> None:
    """Raise TypeError unless ``value`` has the interface of an Atmosphere.

    Parameters
    ----------
    name : str
        Parameter name for the message.
    value : object
        The argument; it needs the methods :data:`ATMOSPHERE_INTERFACE` (checked by
        interface: this module sits below ``model.py``).
    """
    if not all(callable(getattr(value, method, None)) for method in ATMOSPHERE_INTERFACE):
        raise TypeError(f"{name} must be a skytorch.atmosphere.Atmosphere; got "
                        f"{type(value).__name__}")


def wavelength_tensor(wavelength_nm, dtype: torch.dtype | None = None) -> torch.Tensor:
    """Return checked wavelengths as a 1-D tensor (n_wavelength,) [nm].

    Parameters
    ----------
    wavelength_nm : float, sequence or Tensor (wavelength,)
        Wavelength [nm], in :data:`WAVELENGTH_RANGE_NM`; a scalar becomes shape (1,).
    dtype : torch.dtype, optional
        Cast to this dtype after the check (the check is done in the input's own
        precision, so that a value outside the range cannot slip in by rounding).

    Returns
    -------
    Tensor (wavelength,)

    Raises
    ------
    ValueError
        A wavelength outside the range, NaN, or more than one dimension.

    Examples
    --------
    >>> wavelength_tensor(550.0).dtype
    torch.float64
    """
    low, high = WAVELENGTH_RANGE_NM
    wavelength = check_range("wavelength_nm", wavelength_nm, low, high, unit=" nm")
    wavelength = wavelength if dtype is None else wavelength.to(dtype)
    if wavelength.ndim > 1:
        raise ValueError("wavelength_nm must be a scalar or a 1-D tensor (n_wavelength,); "
                         f"got shape {tuple(wavelength.shape)}")
    if wavelength.numel() == 0:
        raise ValueError("wavelength_nm must hold at least one wavelength; got none")
    return wavelength.reshape(-1)


def altitude_tensor(altitude_m, dtype: torch.dtype | None = None) -> torch.Tensor:
    """Return checked observer altitudes (>= 0) [m], cast to ``dtype`` after the check.

    Checked in the input's own precision (-1e-300 is below the ground even though it
    rounds to -0.0 in float32); ValueError below the surface.
    """
    altitude = check_range("altitude_m", altitude_m, 0.0, unit=" m (observer inside the "
                           "planet?)")
    return altitude if dtype is None else altitude.to(dtype)
