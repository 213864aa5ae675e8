"""Heavy libraries when first used: the stand-ins through which the package's modules reach SymPy, its symbols,
networkx and mpmath.

A module that builds expressions writes ``sp = deferred.module("sympy", globals())`` where it wrote ``import
sympy as sp``: importing it loads no SymPy (0.26 s of CPU), and its first ``sp.<name>`` imports SymPy and puts the
module itself in the stand-in's place, so every later use is a plain attribute read (networkx, 0.15 s, and
mpmath likewise).  ``lazy_loader.load`` does
the first half by registering a lazy module in ``sys.modules``, where any library that asks whether SymPy is
imported (``"sympy" in sys.modules``) is told that it is, and the first such question loads it.

A module's symbols (the time ``t`` of :mod:`lagrangian.base.component`, the Laplace variable ``s``) come from
:func:`symbol`: the symbol itself where SymPy is imported already, else a stand-in for it.  Every use of a stand-in
gives what the symbol gives: its attributes, arithmetic, comparison, hashing and equality, and SymPy reads it as
the symbol (``_sympy_``), so ``sp.sin(3 * t)``, ``{t: 0}`` and ``t in expr.free_symbols`` hold the symbol.  Its
first use makes the symbol (SymPy imported then) and puts it in the stand-in's place in every module of the
package (``x is t`` holds from then on).  The public ``lagrangian.t`` is the symbol itself.

>>> import sympy as sp
>>> t = symbol("t", real=True)          # SymPy imported already: the symbol itself
>>> t is time_symbol(), type(_Symbol("s", {}) ** 2).__name__
(True, 'Pow')
>>> stand_in = _Symbol("t", {"real": True})
>>> str(stand_in), stand_in.name, stand_in == t, hash(stand_in) == hash(t), {stand_in: 1}[t]
('t', 't', True, True, 1)
>>> sp.sin(3 * stand_in).args[0].args[1] is t
True
"""

from __future__ import annotations

import importlib
import operator
import sys
import threading
from typing import Any

__all__ = ["module", "symbol", "time_symbol"]

_lock = threading.RLock()
#: The symbols' stand-ins not yet replaced by their symbols.
_STANDING: list = []


class _Module:
    """A module imported on first attribute read, then put in its place in the namespace that holds this."""

    __slots__ = ("_name", "_namespace")

    def __init__(self, name: str, namespace: dict):
        self._name, self._namespace = name, namespace

    def __getattr__(self, attr: str) -> Any:
        real = importlib.import_module(self._name)
        for key, value in list(self._namespace.items()):
            if value is self:
                self._namespace[key] = real
        if self._name == "sympy":  # the symbols' stand-ins too: a module that now reads SymPy reads them as symbols
            for standing in list(_STANDING):
                standing._symbol()
        return getattr(real, attr)

    def __repr__(self) -> str:
        return f"<module {self._name!r}, imported on first use>"


def module(name: str, namespace: dict) -> Any:
    """The module ``name`` itself where it is imported already, else a stand-in that imports it on first use and
    then replaces itself in ``namespace`` (a module's ``globals()``)."""
    return sys.modules.get(name) or _Module(name, namespace)


def time_symbol() -> Any:
    """The symbol of time, ``t`` (real): what the stand-in ``t`` of :mod:`lagrangian.base.component` stands for
    (put in its place now)."""
    for standing in list(_STANDING):
        standing._symbol()
    import sympy

    return sympy.Symbol("t", real=True)


def symbol(name: str, **assumptions: bool) -> Any:
    """The SymPy symbol ``name`` with ``assumptions`` where SymPy is imported already, else a stand-in for it, made
    on first use (see the module documentation)."""
    if "sympy.core" in sys.modules:
        import sympy

        return sympy.Symbol(name, **assumptions)
    standing = _Symbol(name, assumptions)
    _STANDING.append(standing)
    return standing


def _delegate(name: str):
    op = getattr(operator, name, None)

    def method(self, *args):
        real = self._symbol()
        return getattr(real, name)(*args) if op is None else op(real, *args)

    method.__name__ = name
    return method


def _reflected(name: str):
    def method(self, other):
        return getattr(self._symbol(), name)(other)

    method.__name__ = name
    return method


class _Symbol:
    """The stand-in for a symbol (see the module documentation)."""

    __slots__ = ("_name", "_assumptions", "_made")

    def __init__(self, name: str, assumptions: dict):
        self._name, self._assumptions, self._made = name, assumptions, None

    def _symbol(self) -> Any:
        """The symbol, made on first call (SymPy imported then); this stand-in is replaced by it in every module of
        the package."""
        if self._made is None:
            import sympy

            with _lock:
                if self._made is None:
                    made = sympy.Symbol(self._name, **self._assumptions)
                    for name, mod in list(sys.modules.items()):
                        if (name == "lagrangian" or name.startswith("lagrangian.")) and name != __name__:
                            space = getattr(mod, "__dict__", None) or {}
                            for key, value in list(space.items()):
                                if value is self:
                                    space[key] = made
                    self._made = made
                    _STANDING[:] = [x for x in _STANDING if x is not self]
        return self._made

    def _sympy_(self) -> Any:
        return self._symbol()

    def __getattr__(self, attr: str) -> Any:
        if attr == "__sympy__":  # SymPy would take the stand-in as one of its own objects: it is read by _sympy_
            raise AttributeError(attr)
        return getattr(self._symbol(), attr)

    def __hash__(self) -> int:
        return hash(self._symbol())

    def __eq__(self, other: Any) -> Any:
        return self._symbol() == other

    def __ne__(self, other: Any) -> Any:
        return self._symbol() != other

    def __str__(self) -> str:
        return self._name

    def __repr__(self) -> str:
        return self._name

    def __format__(self, spec: str) -> str:
        return format(self._symbol(), spec)

    def __reduce__(self):
        return _made, (self._name, tuple(sorted(self._assumptions.items())))


def _made(name: str, assumptions: tuple) -> Any:
    """The symbol a pickled stand-in stood for."""
    import sympy

    return sympy.Symbol(name, **dict(assumptions))


for _name in ("__add__", "__sub__", "__mul__", "__truediv__", "__floordiv__", "__mod__", "__pow__", "__lt__", "__le__",
              "__gt__", "__ge__", "__neg__", "__pos__", "__abs__"):
    setattr(_Symbol, _name, _delegate(_name))
for _name in ("__radd__", "__rsub__", "__rmul__", "__rtruediv__", "__rfloordiv__", "__rmod__", "__rpow__"):
    setattr(_Symbol, _name, _reflected(_name))
del _name


