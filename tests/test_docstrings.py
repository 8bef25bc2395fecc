"""Every ``>>>`` example in the package's docstrings runs and gives what it shows (as pyvista does).

The examples are documentation: running them here keeps the documentation from going stale.
Modules are found by walking the installed package, so a new module's examples run too.
"""

from __future__ import annotations

import doctest
import importlib
import pkgutil
import warnings

import pytest

import hyperstat


def _modules() -> list[str]:
    import hyperstat.cad_plugin
    import hyperstat.solver

    names = ["hyperstat"]
    for package in (hyperstat.solver, hyperstat.cad_plugin):
        names.append(package.__name__)
        for info in pkgutil.walk_packages(package.__path__, prefix=package.__name__ + "."):
            if ".freecad" in info.name or info.name.endswith("__main__"):
                continue  # the workbench runs in FreeCAD's Python; __main__ runs the command line
            names.append(info.name)
    return names


def _with_examples() -> list[str]:
    finder = doctest.DocTestFinder()
    out = []
    for name in _modules():
        module = importlib.import_module(name)
        if any(not ex.options.get(doctest.SKIP) for t in finder.find(module, name) for ex in t.examples):
            out.append(name)
    return out


MODULES = _with_examples()


def test_the_public_api_is_documented_by_examples():
    assert "hyperstat.cad_plugin.api" in MODULES and "hyperstat" in MODULES
    finder = doctest.DocTestFinder()
    # each public name's own docstring (wherever it is defined: template_path lives with the templates)
    documented = {n for n in hyperstat.__all__ if n != "__version__"
                  and any(t.examples for t in finder.find(getattr(hyperstat, n), n))}
    assert set(hyperstat.__all__) - {"__version__"} <= documented, set(hyperstat.__all__) - documented


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_run(name):
    module = importlib.import_module(name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE, verbose=False)
    assert result.attempted > 0
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples of {name} failed (output above)"
