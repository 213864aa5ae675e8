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

A component whose energy is not quadratic in its variables may still say it
in numbers for the runs of a large model (:mod:`lagrangian.numerics.assembled`):
a :class:`Potential` ``V(x, p)`` of its variables ``x_k`` and parameters
``p_j``, written once per kind with the same placeholder symbols for every
component of that kind and given this component's numbers for ``p``.  The
energy is then differentiated once per kind, not once per component, and
evaluated for all components of the kind at once.  A model with a potential
is not linear: the exact solution, transfer functions and other linear
analyses refuse it in numbers and take the symbolic path.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from . import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["Linear", "LinearContext", "Potential", "Quantity"]


@dataclass(frozen=True)
class Quantity:
    """A quantity a component names (``"v"``, ``"i"``) as ``Σ c · dᵒx_k/dtᵒ + signal · s``: ``terms`` are
    ``(k, order, c)``, ``signal`` the coefficient of the component's own signal (a source's value)."""

    terms: tuple[tuple[int, int, float], ...] = ()
    signal: float = 0.0


@dataclass(frozen=True)
class Potential:
    """A nonlinear energy ``V(x, p)`` of a component's variables (see the module documentation).

    ``energy``: a SymPy expression in the placeholders ``x0, x1, …`` (the
    component's variables, in the order of :attr:`Linear.branches`) and
    ``p0, p1, …`` (its parameters), built once per kind and structure: every
    component whose energy has the same expression shares one derivation.
    ``values``: this component's number for each ``p_j``.  :meth:`placeholders`
    gives the symbols.

    >>> from lagrangian.base.linear import Potential
    >>> (x0,), (p0,) = Potential.placeholders(1, 1)
    >>> duffing = Potential(p0 * x0**4 / 4, (2e4,))      # ¼ β x⁴
    >>> duffing.energy, duffing.values
    (p0*x0**4/4, (20000.0,))
    """

    energy: Any
    values: tuple[float, ...] = ()

    @staticmethod
    def placeholders(variables: int, parameters: int) -> tuple[tuple[Any, ...], tuple[Any, ...]]:
        """The symbols ``(x0, …), (p0, …)`` a potential is written in (real symbols: the same objects every call)."""
        return (tuple(sp.Symbol(f"x{k}", real=True) for k in range(variables)),
                tuple(sp.Symbol(f"p{j}", real=True) for j in range(parameters)))


@dataclass
class Linear:
    """One component's share of a linear time-invariant model (see the module documentation).

    ``branches``: the variables, as ``(component name, branch index)`` pairs; ``None`` for the component's own
    branches in order.  ``T``, ``V``, ``D``, ``G``: coefficients by pair of variable indices.  ``force``: by variable
    index, the generalized force per unit of the component's signal.  ``load``: by variable index, a constant
    generalized force (gravity along the axis, a spring's rest length: ``V`` gains ``−Σ load_k x_k``), and
    ``constant`` the constant term of ``V`` (``½ k ℓ₀²``), so that the energies equal the symbolic ones.
    ``quantities``: by name (those of :attr:`lagrangian.Component.quantities` it can give in numbers).
    ``potential``: a nonlinear energy of the variables (:class:`Potential`), added to ``V``; ``None`` for a linear
    component.
    """

    branches: tuple[tuple[str, int], ...] | None = None
    T: Mapping[tuple[int, int], float] = field(default_factory=dict)
    V: Mapping[tuple[int, int], float] = field(default_factory=dict)
    D: Mapping[tuple[int, int], float] = field(default_factory=dict)
    G: Mapping[tuple[int, int], float] = field(default_factory=dict)
    force: Mapping[int, float] = field(default_factory=dict)
    load: Mapping[int, float] = field(default_factory=dict)
    constant: float = 0.0
    quantities: Mapping[str, Quantity] = field(default_factory=dict)
    potential: Potential | None = None


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
        params = component.params
        value = params.raw(pname) if hasattr(params, "raw") else params.get(pname)  # a default held as a number
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
        if getattr(value, "is_number", False):
            try:
                return float(value)
            except (TypeError, ValueError):
                return None
        return None
