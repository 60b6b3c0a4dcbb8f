"""skytorch: batched PyTorch modules for the physics of the sky.

Light integrated through a planetary atmosphere, eclipse shadow cones, star and Moon
photometry, and artificial skyglow — as differentiable tensor functions, thin
``torch.nn.Module`` wrappers holding precomputed tables, and CF-annotated
``xarray.Dataset`` builders at the boundary.

Subpackages are imported lazily so that ``import skytorch`` stays cheap::

    >>> import skytorch as st
    >>> st.__version__
    '0.1.0'
"""

from __future__ import annotations

import importlib
import logging

__version__ = "0.1.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())

#: submodules reachable as attributes (``st.ephemeris``, ``st.eclipse`` ...)
_SUBMODULES = (
    "atmosphere",
    "constants",
    "dataset",
    "eclipse",
    "ephemeris",
    "moon",
    "plot",
    "scene",
    "skyglow",
    "spectrum",
    "stars",
)

#: public names re-exported from submodules: name -> (module, attribute)
_EXPORTS = {
    "Atmosphere": ("skytorch.atmosphere", "Atmosphere"),
    "Scene": ("skytorch.scene", "Scene"),
    # skytorch/sweep.py makes its module object callable: the attribute is the module
    # itself (attribute None), so ``st.sweep(fn, ...)`` and ``import skytorch.sweep`` agree.
    "sweep": ("skytorch.sweep", None),
    "open_dataset": ("skytorch.dataset", "open_dataset"),
    "to_netcdf": ("skytorch.dataset", "to_netcdf"),
}

__all__ = ["__version__", *sorted(_EXPORTS), *_SUBMODULES]


def __getattr__(name: str):
    if name in _EXPORTS:
        module_name, attribute = _EXPORTS[name]
        module = importlib.import_module(module_name)
        value = module if attribute is None else getattr(module, attribute)
        globals()[name] = value
        return value
    if name in _SUBMODULES:
        module = importlib.import_module(f"{__name__}.{name}")
        globals()[name] = module
        return module
    raise AttributeError(f"module 'skytorch' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
