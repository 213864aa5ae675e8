"""Other values for parameters given as numbers: each must obey its parameter's rule.

``Model.simulate(params={"k_k": 250.0})`` may give another value to a parameter built as a number, and a fit does
so at every trial point.  :class:`Rules` gathers, once per model (until it changes), which rule each such
parameter's symbol obeys, so that checking a run's values is a lookup and a float comparison per value; only a
value that fails goes through :func:`~lagrangian.base.component.check_value` for its message.

>>> import lagrangian as lg
>>> m = lg.Model("osc")
>>> _ = m.add("mass", "m", "p", m=0.3)
>>> rules = Rules(m.components.values())
>>> [s.name for s in rules.scalar]
['m_m']
>>> rules.check({next(iter(rules.scalar)): -1.0})
Traceback (most recent call last):
    ...
lagrangian.errors.ParameterError: component 'm', parameter 'm': must be positive (got -1.00000000000000).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from ..errors import ParameterError
from .component import Component, _plain_within, check_value
from . import deferred as _deferred

sp = _deferred.module("sympy", globals())


class Rules:
    """Per symbol of a parameter given as a number: ``scalar`` (its rule, component and parameter) and ``entries``
    (a vector's, matrix's or mapping's entry, whose sign must stay the one it was given with)."""

    def __init__(self, components: Iterable[Component]):
        self.scalar: dict[sp.Symbol, list[tuple[str, str, str]]] = {}
        self.entries: dict[sp.Symbol, list[tuple[Component, str]]] = {}
        for comp in components:
            for pname, symbol in getattr(comp, "_symbols", {}).items():
                if isinstance(symbol, sp.Symbol):
                    self.scalar.setdefault(symbol, []).append((comp.parameters[pname].check, comp.name, pname))
                    continue
                values = symbol.values() if isinstance(symbol, Mapping) else [symbol]
                for entry in {s for e in values for s in sp.sympify(e, strict=True).free_symbols}:
                    self.entries.setdefault(entry, []).append((comp, pname))

    def check(self, given: Mapping[sp.Symbol, float]) -> None:
        """Raise :class:`~lagrangian.ParameterError`, naming the component and parameter, for a value in ``given``
        that breaks its parameter's rule (or an entry's sign)."""
        for symbol, value in given.items():
            for check, component, pname in self.scalar.get(symbol, ()):
                if not _plain_within(value, check):
                    check_value(sp.Float(value), check, component, pname)
            for comp, pname in self.entries.get(symbol, ()):
                value = float(value)
                if not (value > 0 if symbol.is_positive else value < 0):
                    sign = "positive" if symbol.is_positive else "negative"
                    raise ParameterError(
                        comp.name, pname,
                        f"entry {symbol.name!r} was given as a {sign} number ({float(comp.values[symbol]):g}); another "
                        f"value must be {sign} too, got {value:g} (build the model with a sympy.Symbol there to vary "
                        f"its sign)."
                    )
