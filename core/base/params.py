"""A component's parameter values, held as given where they are plain numbers or waveforms.

The symbolic derivation reads every value as a SymPy object; a model solved in numbers (a netlist's transient,
:mod:`lagrangian.derivation.numeric`) never needs one.  :class:`Params` holds a plain number (a Python ``float`` or
``int`` within its parameter's rule) and a waveform (:mod:`lagrangian.base.waveforms`) as given, and turns each into
its SymPy form (a ``Float``, an ``Integer``, the waveform's expression of ``t``) when it is first read through the
mapping, in place: reading ``params["R"]`` gives what it always gave, and a model nobody reads symbolically
imports no SymPy.  :meth:`Params.raw` reads the value as held.

>>> p = Params({"R": 0.3, "n": 2, "name": "L1"})
>>> p.raw("R"), p.raw("n")
(0.3, 2)
>>> p["R"], type(p["n"]).__name__, p.raw("R"), p["name"]
(0.300000000000000, 'Integer', 0.300000000000000, 'L1')
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from . import deferred as _deferred
from .waveforms import numeric

__all__ = ["Params"]

sp = _deferred.module("sympy", globals())


def _symbolic(value: Any) -> Any:
    if type(value) is float:
        return sp.Float(value)
    if type(value) is int:
        return sp.Integer(value)
    return value.expr()


class Params(dict):
    """Parameter values by name, plain numbers and waveforms read as SymPy objects (see the module documentation)."""

    def __getitem__(self, key: str) -> Any:
        value = dict.__getitem__(self, key)
        if numeric(value):
            value = _symbolic(value)
            dict.__setitem__(self, key, value)
        return value

    def get(self, key: str, default: Any = None) -> Any:
        return self[key] if key in self else default

    def raw(self, key: str, default: Any = None) -> Any:
        """The value as held: a plain number or a waveform where one was given (see the module documentation)."""
        return dict.get(self, key, default)

    def items(self) -> list[tuple[str, Any]]:  # type: ignore[override]
        return [(key, self[key]) for key in dict.keys(self)]

    def values(self) -> list[Any]:  # type: ignore[override]
        return [self[key] for key in dict.keys(self)]

    def __iter__(self) -> Iterator[str]:
        return iter(list(dict.keys(self)))

    def copy(self) -> Params:
        return Params(dict.items(self))

    def __reduce__(self):
        return Params, (dict(dict.items(self)),)
