"""Every docstring example in the package runs, and every public object is documented."""

import doctest
import gc
import importlib
import pkgutil

import pytest

import lagrangian
import lagrangian.plugins

# the package's modules and the built-in plugins' (installed from plugins/, outside the package's own directory)
MODULES = sorted(
    {m.name for m in pkgutil.walk_packages(lagrangian.__path__, "lagrangian.") if not m.name.endswith("__main__")}
    | {m.name for m in pkgutil.walk_packages(lagrangian.plugins.__path__, "lagrangian.plugins.")}
    | {"lagrangian", "lagrangian.plugins"}
)


@pytest.mark.parametrize("name", MODULES)
@pytest.mark.slow
def test_doctests_pass(name):
    module = importlib.import_module(name)
    # Without the cyclic collector while the examples run: collecting a function SymPy's lambdify made drops its
    # linecache entry, and one dropped while doctest's debugger walks that cache (linecache.checkcache, before every
    # docstring) raised KeyError from inside the runner on Python 3.11.
    gc.collect()
    gc.disable()
    try:
        result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    finally:
        gc.enable()
    assert result.failed == 0


@pytest.mark.parametrize("name", MODULES)
def test_public_objects_have_docstrings(name):
    module = importlib.import_module(name)
    assert module.__doc__, f"module {name} has no docstring"
    for attr in getattr(module, "__all__", []):
        obj = getattr(module, attr)
        if callable(obj):
            assert obj.__doc__, f"{name}.{attr} has no docstring"


def test_package_has_examples():
    """The core modules carry at least a dozen runnable examples between them."""
    finder = doctest.DocTestFinder()
    count = sum(
        len(test.examples) for name in MODULES for test in finder.find(importlib.import_module(name))
    )
    assert count >= 12
