"""Models derived from another model: a part of it, or a reduction of it.

A :class:`DerivedModel` shares its source's components and parameters but
has equations of its own (built on first use by a function it is given); it
simulates, describes itself and reports parameters like any
:class:`~lagrangian.Model`.  Components are added to the source, never to a
derived model.

>>> import lagrangian as lg
>>> from lagrangian.equations import Equations
>>> m = lg.Model("oscillator")
>>> _ = m.add("mass", "m", "p", m=1)
>>> _ = m.add("spring", "k", ("ground", "p"), k=4)
>>> same = DerivedModel(m, "copy", lambda: m.eq)
>>> same.coordinate_names
['x_p']
>>> same.add("mass", "m2", "q", m=1)
Traceback (most recent call last):
...
lagrangian.errors.ModelError: 'copy' is derived from model 'oscillator': add components to 'oscillator' and derive it again.
"""

from __future__ import annotations

from collections.abc import Callable

from ..derivation.equations import Equations
from ..errors import ModelError
from ..model import Model

__all__ = ["DerivedModel"]


class DerivedModel(Model):
    """A model with equations derived from ``source`` by ``build()`` (called once, on first use)."""

    def __init__(self, source: Model, name: str, build: Callable[[], Equations]):
        super().__init__(name, registry=source.registry, **source._options)
        self.source = source
        self._graph = source._graph
        self._build = build

    @property
    def eq(self) -> Equations:
        return self._get("equations", self._build)

    @property
    def assembly(self):
        return self.source.assembly

    @property
    def coordinates(self):
        return list(self.eq.coordinates)

    @property
    def coordinate_names(self) -> list[str]:
        return list(self.eq.names)

    def add(self, *args, **kwargs):
        raise ModelError(
            f"{self.name!r} is derived from model {self.source.name!r}: add components to {self.source.name!r} "
            f"and derive it again."
        )

    def node(self, name: str):
        return self.add()
