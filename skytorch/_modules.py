"""Modules that can be called as the function they are named after.

``skytorch.sweep`` and ``skytorch.moon.reflectance`` are both a submodule and a public
function of the same name in the parent package. The function would hide the submodule
(``import skytorch.moon.reflectance as m`` would give the function), so the package
attribute holds the module and the module is made callable as its namesake function:
``st.sweep(fn, ...)``, ``st.moon.reflectance(mu0, mu, g)``, ``from
skytorch.moon.reflectance import albedo`` and ``import skytorch.sweep`` all work.

Such a module pickles by reference (its import name, as functions do), so it can be sent
to other processes, e.g. as the swept function on dask worker processes.

Examples
--------
>>> import inspect
>>> import skytorch.moon.reflectance as module
>>> inspect.ismodule(module), callable(module)
(True, True)
>>> list(inspect.signature(module).parameters)[:3]
['mu0', 'mu', 'phase_angle_rad']
>>> import pickle
>>> pickle.loads(pickle.dumps(module)) is module
True
"""

from __future__ import annotations

import importlib
import inspect
import sys
import types


class FunctionModule(types.ModuleType):
    """A module callable as its namesake function (``<package>.<name>.<name>``)."""

    def _namesake(self):
        return getattr(self, self.__name__.rpartition(".")[2])

    def __call__(self, *args, **kwargs):
        return self._namesake()(*args, **kwargs)

    @property
    def __signature__(self) -> inspect.Signature:
        return inspect.signature(self._namesake())

    def __reduce__(self):
        # modules cannot be pickled by value; this one is re-imported by name on unpickling
        return importlib.import_module, (self.__name__,)


def make_callable(module_name: str) -> None:
    """Make the (already imported) module ``module_name`` callable as its namesake."""
    sys.modules[module_name].__class__ = FunctionModule
