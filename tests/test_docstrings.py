"""The Examples sections of the docstrings run and print what they claim.

Every module of skytorch (found by walking the package, so that a new module is checked
without editing this file) is run through :mod:`doctest` with
``NORMALIZE_WHITESPACE | ELLIPSIS``; a failing example fails the test with doctest's
report.
"""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

OPTIONFLAGS = doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS

#: modules whose examples are not run (entry-point shims without docstrings to test)
EXCLUDED = ("skytorch.__main__",)


def _package_modules(package_name: str) -> list[str]:
    package = importlib.import_module(package_name)
    names = [package_name]
    names += [info.name for info in pkgutil.walk_packages(package.__path__, f"{package_name}.")]
    return [name for name in names if name not in EXCLUDED]


#: every module of the package: a new module is checked without editing this file
MODULES = tuple(_package_modules("skytorch"))


def _module(name: str):
    # ``importlib`` rather than attribute access: ``skytorch.moon.reflectance`` is both a
    # submodule and the name of a function in ``skytorch.moon``.
    return importlib.import_module(name)


@pytest.mark.parametrize("module_name", MODULES)
def test_docstring_examples(module_name):
    module = _module(module_name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=OPTIONFLAGS)
    report: list[str] = []
    for test in finder.find(module, module_name):
        runner.run(test, out=report.append)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{module_name}: {result.failed} failing example(s)\n" + "".join(
        report
    )


def test_doctest_catches_a_wrong_example():
    """The machinery above reports a failing example (a test that could fail)."""
    test = doctest.DocTestParser().get_doctest(">>> 1 + 1\n3\n", {}, "wrong", "wrong.py", 0)
    runner = doctest.DocTestRunner(optionflags=OPTIONFLAGS)
    runner.run(test, out=lambda text: None)
    assert runner.summarize(verbose=False).failed == 1


def test_every_listed_module_has_examples_somewhere():
    """The walk finds the modules of the packages, and their examples are collected."""
    for package in ("atmosphere", "eclipse", "moon", "scene", "skyglow", "stars"):
        assert any(name.startswith(f"skytorch.{package}.") for name in MODULES), package
    assert "skytorch.moon.reflectance" in MODULES
    assert "skytorch.stars.observation" in MODULES
    finder = doctest.DocTestFinder(exclude_empty=True)
    n_examples = sum(
        len(test.examples) for name in MODULES for test in finder.find(_module(name), name)
    )
    assert n_examples > 250
