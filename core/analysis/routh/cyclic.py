"""Ignorable (cyclic) coordinates: which coordinates of a model are ignorable, and why (or why not).

A coordinate is ignorable when it has inertia and neither the energies, the
dissipation, the generalized forces nor the loop constraints depend on it or
act along it; :func:`ignorability` gives the verdict with its reason for every
coordinate, :func:`ignorable` the names of those that are.  The helpers that
find which component a dependence comes from are used by the Jacobi integral too.
"""

from __future__ import annotations

from dataclasses import dataclass

from ...base.identity import depends_on, is_zero
from ...derivation.equations import Equations
from ...model import Model
from ...base import deferred as _deferred

sp = _deferred.module("sympy", globals())


@dataclass(frozen=True)
class Ignorability:
    """Whether one coordinate is ignorable, and why (or why not)."""

    coordinate: str
    ignorable: bool
    reason: str

    def __str__(self) -> str:
        return f"{self.coordinate}: {'ignorable' if self.ignorable else 'not ignorable'} — {self.reason}"


def _depends(eq: Equations, expr: sp.Expr, symbol: sp.Symbol, values: dict | None = None) -> bool:
    """Whether ``expr`` really depends on ``symbol`` (a derivative that is not identically zero; with the
    parameters of ``values`` at their values)."""
    return depends_on(expr, symbol, values, diff=eq._derivation.calc.diff)


def _components(model: Model, part: str, symbol: sp.Symbol) -> list[str]:
    """Components whose ``part`` (T, V, D or G) depends on ``symbol``."""
    eq = model.eq
    out = []
    for name, c in model.assembly.contributions.items():
        expr = sp.sympify(getattr(c, part))
        if expr != 0 and _depends(eq, eq.symbolic(expr), symbol):
            out.append(name)
    return out


def _named(names: list[str]) -> str:
    return ", ".join(repr(n) for n in names) if names else "a component"


def _coupling(model: Model) -> dict[str, list[str]]:
    """``{coordinate: components}``: the coordinates a constraint on velocities (nonholonomic) couples — it holds
    the coordinate or its rate, so its force acts along it — with the components that impose those constraints."""
    eq = model.eq
    out: dict[str, list[str]] = {}
    for i, name in enumerate(eq.names):
        owners = sorted({o for o, c in zip(eq.velocity_owners, eq.velocity_constraints)
                         if _depends(eq, c, eq.sym.q[i]) or _depends(eq, c, eq.sym.v[i])})
        if owners:
            out[name] = owners
    return out


def ignorability(model: Model, explain: bool = True) -> dict[str, Ignorability]:
    """Every coordinate of ``model``, whether it is ignorable, and the reason (``explain=False``: only an ignorable
    coordinate's; a reason that is not given costs nothing, while finding the components behind a dependence walks
    every component).

    A coordinate ``q_i`` is ignorable when it has inertia, ``L``, ``D``,
    the generalized forces and the loop constraints do not depend on it,
    and neither dissipation nor a generalized force acts on it — then
    ``p_i = ∂L/∂q̇_i`` is conserved and the others' equations do not
    involve ``q_i``.  Otherwise the reason names the energy term, force or
    constraint at fault and the component it comes from.

    >>> import lagrangian as lg
    >>> m = lg.Model("mass and spring")
    >>> _ = m.add("mass", "m", "p", m=1)
    >>> _ = m.add("spring", "k", ("ground", "p"), k=1)
    >>> print(ignorability(m)["x_p"])
    x_p: not ignorable — the potential energy V depends on it (from 'k'): a force acts along it
    """
    eq = model.eq
    q, v = eq.sym.q, eq.sym.v
    coupled = _coupling(model)
    # the energies before the values are put in, read with those values: the same verdicts, without putting
    # together the energies' large sums with the values (a spinning top's T: 2.3 ms of its scene's 12 ms plan)
    T, V, G, D = (eq.generic_energy(part) for part in "TVGD")
    values = eq.values
    out = {}
    for i, name in enumerate(eq.names):
        qi, vi = q[i], v[i]

        def verdict(reason, ok: bool = False) -> None:  # the reason: a string, or what builds one when explained
            out[name] = Ignorability(name, ok, (reason() if callable(reason) else reason) if explain or ok else "")

        if i in eq.first_order:
            verdict("it has no inertia (a first-order coordinate): its rate follows from dissipation, there is no momentum to conserve")
            continue
        if _depends(eq, T, qi, values):
            verdict(lambda: f"the kinetic energy T depends on it (from {_named(_components(model, 'T', qi))})")
            continue
        if _depends(eq, V, qi, values):
            verdict(lambda: f"the potential energy V depends on it (from {_named(_components(model, 'V', qi))}): a force acts along it")
            continue
        if _depends(eq, G, qi, values):
            verdict(lambda: f"the velocity-coupling terms G depend on it (from {_named(_components(model, 'G', qi))})")
            continue
        if _depends(eq, D, vi, values) or _depends(eq, D, qi, values):
            verdict(lambda: f"dissipation acts on it (the Rayleigh function D depends on it, from "
                    f"{_named(_components(model, 'D', vi) or _components(model, 'D', qi))}): its momentum decays")
            continue
        acting = [c for c, share in eq.load_shares if not is_zero(share[i])]
        if acting:
            verdict(lambda: f"a generalized force acts on it (from {_named(acting)}): its momentum changes")
            continue
        through = [c for c, share in eq.load_shares if any(_depends(eq, e, qi) for e in share)]
        if through:
            verdict(lambda: f"the generalized force of {_named(through)} depends on it")
            continue
        if any(_depends(eq, c, qi) for c in eq.constraints):
            verdict("it takes part in a loop-closure constraint, whose force acts along it")
            continue
        if name in coupled:
            verdict(lambda: f"a constraint on velocities (nonholonomic, from {_named(coupled[name])}) couples it: the constraint's "
                    f"force acts along it, so its momentum is not conserved")
            continue
        verdict("absent from L, D, the forces and the constraints: its momentum ∂L/∂q̇ is conserved", True)
    return out


def ignorable(model: Model) -> list[str]:
    """Names of the ignorable coordinates of ``model`` (see :func:`ignorability`)."""
    return [name for name, r in ignorability(model, explain=False).items() if r.ignorable]
