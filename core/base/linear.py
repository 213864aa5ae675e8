"""A component's share of a linear time-invariant model, in numbers: what the numeric assembly reads.

A component whose energy is quadratic in its branch quantities with
constant coefficients (an inductor, a capacitor, a resistor, a source, a
mutual inductance, a gyrator) may describe it a second time, in numbers,
by :meth:`lagrangian.Component.linear`.  A model whose components all do,
and whose domains give their branch quantities as numbers
(:meth:`lagrangian.Domain.incidence`), is then assembled without any
symbolic work (:mod:`lagrangian.derivation.numeric`): linearizations,
transfer functions and frequency responses of a circuit of hundreds of
elements take milliseconds.  Anything a component cannot say in numbers (a
parameter without a value, a coefficient that depends on the state) makes
it return ``None``, and the model takes the symbolic path, whose messages
name the fault.

The variables ``x_k`` are branch quantities of the domain: a branch's charge
in loop charges, its flux linkage in node fluxes.  With ``ẋ`` their rates,
a component contributes

    T = ½ Σ T_ij ẋ_i ẋ_j,   V = ½ Σ V_ij x_i x_j,   D = ½ Σ D_ij ẋ_i ẋ_j,   L ∋ Σ G_ij x_i ẋ_j,

and its signal ``s(t)`` (a source's value) does the work ``s · Σ f_i ẋ_i``:
a generalized force ``f_i s`` on ``x_i``.  Sums run over the pairs given,
so a symmetric cross term is given both ways.

>>> from lagrangian.base.linear import Linear, Quantity
>>> inductor = Linear(T={(0, 0): 7e-3}, quantities={"i": Quantity(((0, 1, 1.0),)),
...                                                  "v": Quantity(((0, 2, 7e-3),))})
>>> inductor.T, inductor.quantities["v"].terms   # ½ L i², v = L di/dt
({(0, 0): 0.007}, ((0, 2, 0.007),))
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Linear", "LinearContext", "Quantity"]


@dataclass(frozen=True)
class Quantity:
    """A quantity a component names (``"v"``, ``"i"``) as ``Σ c · dᵒx_k/dtᵒ + signal · s``: ``terms`` are
    ``(k, order, c)``, ``signal`` the coefficient of the component's own signal (a source's value)."""

    terms: tuple[tuple[int, int, float], ...] = ()
    signal: float = 0.0


@dataclass
class Linear:
    """One component's share of a linear time-invariant model (see the module documentation).

    ``branches``: the variables, as ``(component name, branch index)`` pairs; ``None`` for the component's own
    branches in order.  ``T``, ``V``, ``D``, ``G``: coefficients by pair of variable indices.  ``force``: by variable
    index, the generalized force per unit of the component's signal.  ``quantities``: by name (those of
    :attr:`lagrangian.Component.quantities` it can give in numbers).
    """

    branches: tuple[tuple[str, int], ...] | None = None
    T: Mapping[tuple[int, int], float] = field(default_factory=dict)
    V: Mapping[tuple[int, int], float] = field(default_factory=dict)
    D: Mapping[tuple[int, int], float] = field(default_factory=dict)
    G: Mapping[tuple[int, int], float] = field(default_factory=dict)
    force: Mapping[int, float] = field(default_factory=dict)
    quantities: Mapping[str, Quantity] = field(default_factory=dict)


@dataclass
class LinearContext:
    """Passed to :meth:`lagrangian.Component.linear`: the model's ``options`` (its formulation) and its
    ``components`` by name."""

    options: Mapping[str, Any]
    components: Mapping[str, Any]
    _named: dict[str, list[Any]] | None = field(default=None, repr=False)

    def naming(self, name: str) -> list[Any]:
        """The components that name component ``name`` in a parameter (the couplings of an inductor), in model
        order; found for every name at once on first use."""
        if self._named is None:
            self._named = {}
            for comp in self.components.values():
                for pname, spec in comp.parameters.items():
                    if spec.shape == "name" and isinstance(comp.params.get(pname), str):
                        self._named.setdefault(comp.params[pname], []).append(comp)
        return self._named.get(name, [])

    def number(self, component: Any, pname: str) -> float | None:
        """Parameter ``pname`` of ``component`` as a float, or ``None`` when it has no numeric value (a symbol, an
        expression of time)."""
        given = getattr(component, "_floats", {}).get(pname)
        if given is not None:
            return given
        value = component.params.get(pname)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
        if getattr(value, "is_number", False):
            try:
                return float(value)
            except (TypeError, ValueError):
                return None
        return None
