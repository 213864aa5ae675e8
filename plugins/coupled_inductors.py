"""Built-in plugin: magnetic coupling between inductors (SPICE's ``K`` element).

A ``coupling`` has no terminals: it names two ``inductor`` components of the
model and a coupling coefficient ``k``, and adds their mutual inductance
``M = k √(L1 L2)``.  The dot convention is SPICE's: the first node (``a``)
of each inductor is dotted, so with both currents taken from ``a`` to ``b``
through their inductors,

    v1 = L1 di1/dt + M di2/dt,    v2 = M di1/dt + L2 di2/dt.

- **charge formulation**: the magnetic co-energy of the pair is
  ``½ L1 i1² + M i1 i2 + ½ L2 i2²``; the inductors contribute their own
  terms, the coupling adds ``T = M i1 i2``.
- **flux formulation**: the magnetic energy in flux linkages is
  ``V = ½ λᵀ Γ λ`` with ``Γ`` the inverse of the inductance matrix of the
  coupled inductors; the inductors contribute ``λ²/2L`` each, so the
  coupling adds the rest, ``½ λᵀ (Γ − diag(1/L)) λ``.  Inductors joined by
  several couplings (a three-winding transformer) share one ``Γ``: the first
  coupling of such a group (in model order) contributes the whole group's
  correction and the others contribute nothing.  ``k = 1`` has no ``Γ`` and
  is refused in this formulation.

``k = 1`` (perfect coupling) in the charge formulation is accepted when the
model's kinetic energy still has a nonsingular Hessian on the loops it
touches (some other inductance in those loops); otherwise the equations
would have no unique accelerations and the coupling says so.

>>> import lagrangian as lg
>>> m = lg.Model("series aiding")
>>> _ = m.add("inductor", "L1", ("n1", "n2"), L=1)
>>> _ = m.add("inductor", "L2", ("n2", "0"), L=4)
>>> _ = m.add("capacitor", "C1", ("n1", "0"), C=1)
>>> _ = m.add("coupling", "K1", inductor1="L1", inductor2="L2", k=0.5)
>>> m.mass_matrix   # L1 + L2 + 2 k √(L1 L2) = 1 + 4 + 2
Matrix([[7.0]])
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lagrangian import (
    Component,
    Context,
    Contribution,
    Example,
    Linear,
    LinearContext,
    ModelError,
    Parameter,
    ParameterError,
    UnknownNameError,
    hookimpl,
)
from lagrangian.base.component import t
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["Coupling"]

_NAME_PARAMETERS = ("inductor1", "inductor2")


class Coupling(Component):
    """Mutual inductance M = k √(L1 L2) between two inductors (SPICE ``K``; first nodes dotted).

    Adds ``T = M i1 i2`` in the charge formulation and the off-diagonal part
    of the inverse inductance matrix, ``½ λᵀ (Γ − diag(1/L)) λ``, in the
    flux formulation.  ``inductor1`` and ``inductor2`` are component names
    (strings such as ``"L1"``; they become SymPy symbols of that name).
    """

    kind = "coupling"
    domain = "electrical"
    terminals = ()
    cross_energy = True
    parameters = {
        "inductor1": Parameter("name of the first coupled inductor (its first node is dotted)", shape="name"),
        "inductor2": Parameter("name of the second coupled inductor (its first node is dotted)", shape="name"),
        "k": Parameter("coupling coefficient, 0 < k ≤ 1", check="fraction"),
    }

    def __init__(self, name: str, nodes: tuple[str, ...], params: dict[str, Any]):
        super().__init__(name, nodes, params)
        if self.inductor_names[0] == self.inductor_names[1]:
            raise ParameterError(
                name, "inductor2", f"couples inductor {self.inductor_names[0]!r} with itself; name two different inductors."
            )

    @property
    def inductor_names(self) -> tuple[str, str]:
        """The names of the two coupled inductors."""
        return tuple(self.params[p] for p in _NAME_PARAMETERS)

    # -- finding the inductors -------------------------------------------------------
    def inductors(self, ctx: Context) -> tuple[Component, Component]:
        """The two inductor components this coupling names (clear errors if they are not inductors)."""
        by_name = {c.name: c for c in ctx.components}
        inductors = {c.name: c for c in ctx.components if c.kind == "inductor"}
        found = []
        for pname, iname in zip(_NAME_PARAMETERS, self.inductor_names):
            comp = by_name.get(iname)
            if comp is None:
                err = UnknownNameError("inductor", iname, inductors)
                err.args = (f"coupling {self.name!r}, parameter {pname!r}: {err.args[0]}",)
                raise err
            if comp.kind != "inductor":
                raise ParameterError(
                    self.name, pname, f"{iname!r} is a {comp.kind}, not an inductor. Inductors of this model: "
                    f"{', '.join(sorted(inductors)) or '(none)'}."
                )
            found.append(comp)
        return found[0], found[1]

    def mutual(self, ctx: Context) -> sp.Expr:
        """The mutual inductance ``M = k √(L1 L2)``."""
        a, b = self.inductors(ctx)
        return self.k * sp.sqrt(a.L * b.L)

    def spice(self, ctx: Context) -> list:
        """The SPICE ``K`` line coupling the two inductors' elements."""
        from lagrangian.spice import SpiceElement

        if not self.k.is_number:
            raise ModelError(f"coupling {self.name!r}: its SPICE line needs a numeric k, not {self.k}.")
        self.inductors(ctx)  # clear errors for wrong names
        return [SpiceElement("K", (), f"{{ref0}} {{ref1}} {float(self.k)!r}", refs=self.inductor_names)]

    # -- energy ---------------------------------------------------------------------
    def contribute(self, ctx: Context) -> Contribution:
        group, couplings = _group(self, ctx)
        inductance = _inductance_matrix(group, couplings, ctx)
        valued = inductance.xreplace(ctx.values)  # decisions by value: singular (k = 1), indefinite
        _check_physical(self, group, couplings, valued)
        if ctx.view.formulation == "charge":
            a, b = self.inductors(ctx)
            T = self.mutual(ctx) * ctx.view.current(a) * ctx.view.current(b)
            if _singular(valued):
                _check_charge_inertia(self, ctx, T)
            return Contribution(T=T)
        if _singular(valued):
            raise ModelError(
                f"coupling {self.name!r}: {_cause(self, couplings)} the inductance matrix of "
                f"{', '.join(c.name for c in group)} singular, so the flux formulation (which needs its inverse) cannot "
                f"describe it. Use formulation='charge', or k < 1."
            )
        if couplings[0] is not self:  # the group's first coupling carries the whole correction
            return Contribution()
        flux = [ctx.view.flux(c) for c in group]
        correction = _correction(inductance)
        n = len(group)
        return Contribution(V=sp.expand(sp.Add(*[correction[i, j] * flux[i] * flux[j] for i in range(n) for j in range(n)
                                                 if correction[i, j] != 0]) / 2))

    def numeric_inductance(self, ctx: LinearContext) -> tuple[tuple[str, str], np.ndarray] | None:
        """The names of the pair and its inductance matrix ``[[L1, M], [M, L2]]`` in numbers, for a coupling that is
        its inductors' only one with a nonsingular matrix; ``None`` otherwise (groups of couplings, ``k = 1``,
        misnamed inductors: the symbolic path checks them)."""
        pair = [ctx.components.get(n) for n in self.inductor_names]
        if any(c is None or c.kind != "inductor" for c in pair):
            return None
        # a second coupling of the same pair is refused here, from the couplings that name the first inductor (a
        # look-up), not after the symbolic path has compared every coupling's group with every other's
        same = [c for c in ctx.naming(self.inductor_names[0])
                if isinstance(c, Coupling) and set(c.inductor_names) == set(self.inductor_names)]
        if len(same) > 1:
            raise ModelError(
                f"couplings {same[0].name!r} and {same[1].name!r} both couple {' and '.join(sorted(self.inductor_names))}: "
                f"give one coupling per pair of inductors."
            )
        if any(isinstance(c, Coupling) and c is not self for n in self.inductor_names for c in ctx.naming(n)):
            return None
        k, L1, L2 = ctx.number(self, "k"), ctx.number(pair[0], "L"), ctx.number(pair[1], "L")
        if k is None or L1 is None or L2 is None:
            return None
        M = k * float(np.sqrt(L1 * L2))
        inductance = np.array([[L1, M], [M, L2]])
        s = np.linalg.svd(inductance, compute_uv=False)
        if s[-1] <= 1e-12 * s[0]:  # as _singular decides
            return None
        return self.inductor_names, inductance

    def linear(self, ctx: LinearContext) -> Linear | None:
        """In numbers (see :meth:`numeric_inductance`): the mutual co-energy ``M i1 i2`` (charge formulation) or
        the pair's ``½ λᵀ (Γ − diag(1/L)) λ`` (flux)."""
        got = self.numeric_inductance(ctx)
        if got is None:
            return None
        names, inductance = got
        branches = ((names[0], 0), (names[1], 0))
        if ctx.options["formulation"] == "charge":
            M = float(inductance[0, 1])
            return Linear(branches=branches, T={(0, 1): M, (1, 0): M})
        correction = np.linalg.inv(inductance) - np.diag(1 / np.diag(inductance))
        return Linear(branches=branches, V={(i, j): float(correction[i, j]) for i in range(2) for j in range(2)})

    def current_correction(self, ctx: Context, inductor: Component) -> sp.Expr:
        """Flux formulation: what coupling adds to ``inductor``'s current ``λ/L`` (zero in the charge formulation).

        The current of a coupled inductor is ``(Γ λ)_k`` rather than
        ``λ_k/L_k``; the group's first coupling returns the difference, the
        others zero, so summing over every coupling of the model gives the
        whole correction — the way its energy is shared out.
        """
        if ctx.view.formulation != "flux":
            return sp.Integer(0)
        group, couplings = _group(self, ctx)
        if couplings[0] is not self or inductor not in group:
            return sp.Integer(0)
        correction = _correction(_inductance_matrix(group, couplings, ctx))
        k = group.index(inductor)
        return sp.Add(*[correction[k, j] * ctx.view.flux(c) for j, c in enumerate(group)])

    @classmethod
    def example(cls) -> Example:
        # Series-aiding coils in one LC loop: the same current i flows from a to b
        # through both, so T = ½ (L1 + L2 + 2M) i².
        return Example(
            (),
            {"inductor1": "L1", "inductor2": "L2", "k": 0.5},
            context=[
                ("inductor", "L1", ("n1", "n2"), {"L": 1}),
                ("inductor", "L2", ("n2", "0"), {"L": 2}),
                ("capacitor", "C1", ("n1", "0"), {"C": 0.5}),
            ],
        )


# --- groups of couplings ---------------------------------------------------------------


def _group(coupling: Coupling, ctx: Context) -> tuple[list[Component], list[Coupling]]:
    """The inductors joined to ``coupling``'s through chains of couplings, and those couplings (model order)."""
    couplings = [c for c in ctx.components if isinstance(c, Coupling)]
    inductors = {coupling.inductors(ctx)[0].name}
    members: list[Coupling] = []
    grew = True
    while grew:
        grew = False
        for c in couplings:
            if c not in members and inductors & set(c.inductor_names):
                members.append(c)
                inductors |= set(c.inductor_names)
                grew = True
    members.sort(key=couplings.index)
    for c in members:
        c.inductors(ctx)  # every coupling of the group names real inductors
    order = {c.name: i for i, c in enumerate(ctx.components)}
    group = sorted((comp for comp in ctx.components if comp.name in inductors), key=lambda comp: order[comp.name])
    return group, members


def _inductance_matrix(group: list[Component], couplings: list[Coupling], ctx: Context) -> sp.Matrix:
    index = {c.name: i for i, c in enumerate(group)}
    L = sp.diag(*[c.L for c in group])
    seen: dict[frozenset, str] = {}
    for c in couplings:
        pair = frozenset(c.inductor_names)
        if pair in seen:
            raise ModelError(
                f"couplings {seen[pair]!r} and {c.name!r} both couple {' and '.join(sorted(pair))}: "
                f"give one coupling per pair of inductors."
            )
        seen[pair] = c.name
        i, j = (index[n] for n in c.inductor_names)
        L[i, j] = L[j, i] = c.mutual(ctx)
    return L


def _cause(coupling: Coupling, couplings: list[Coupling]) -> str:
    """What makes a group's inductance matrix singular, in words."""
    if len(couplings) == 1:
        k = sp.sympify(coupling.k).xreplace(coupling.values)  # as given: a number, or the user's symbol
        return f"k = {float(k):g} (perfect coupling) makes" if k.is_number else f"k = {k} makes"
    return f"the couplings {', '.join(c.name for c in couplings)} together make"


def _numeric(matrix: sp.Matrix) -> np.ndarray | None:
    """``matrix`` as floats, or ``None`` when it is symbolic."""
    if matrix.free_symbols:
        return None
    return np.array(matrix.evalf(), dtype=float)


def _singular(inductance: sp.Matrix) -> bool:
    values = _numeric(inductance)
    if values is None:
        return sp.simplify(inductance.det()) == 0
    s = np.linalg.svd(values, compute_uv=False)
    return bool(s[-1] <= 1e-12 * s[0])


def _check_physical(coupling: Coupling, group: list[Component], couplings: list[Coupling], inductance: sp.Matrix) -> None:
    """Coupling coefficients that make the inductance matrix indefinite store negative energy: refuse them."""
    values = _numeric(inductance)
    if values is None or len(group) < 3:
        return  # two coils with 0 < k ≤ 1 are always physical; symbolic values cannot be checked
    eig = np.linalg.eigvalsh(values)
    if eig[0] < -1e-12 * abs(eig[-1]):
        raise ModelError(
            f"coupling {coupling.name!r}: the couplings {', '.join(c.name for c in couplings)} make the inductance matrix of "
            f"{', '.join(c.name for c in group)} indefinite (eigenvalue {eig[0]:.3g}): no set of coils has these "
            f"coupling coefficients. Reduce some k."
        )


def _check_charge_inertia(coupling: Coupling, ctx: Context, own_T: sp.Expr) -> None:
    """With a singular inductance matrix (k = 1), the model's whole kinetic energy must still fix the accelerations."""
    coordinates = [c for view in ctx.views.values() for c in view.coordinates]
    velocities = {c.function.diff(t): sp.Symbol(f"_v{i}") for i, c in enumerate(coordinates)}
    total = own_T
    for comp in ctx.components:
        if comp is coupling:
            continue
        if isinstance(comp, Coupling):
            total += comp.mutual(ctx) * ctx.view.current(comp.inductors(ctx)[0]) * ctx.view.current(comp.inductors(ctx)[1])
            continue
        try:
            other = comp.contribute(Context(ctx.views[comp.domain], ctx.views, ctx.options, ctx.components, values=ctx.values))
        except Exception:  # noqa: BLE001 - the assembly reports that component's own error
            return
        total += sp.sympify(other.T)
    T = sp.sympify(total).xreplace(velocities).xreplace(ctx.values)
    v = list(velocities.values())
    H = _numeric(sp.hessian(T, v).xreplace({c.function: 0 for c in coordinates}).subs(t, 0))
    if H is None:
        return  # symbolic: the simulation reports a singular mass matrix if there is one
    rows = [i for i in range(len(v)) if np.any(np.abs(H[i]) > 0)]
    if not rows:
        return
    sub = H[np.ix_(rows, rows)]
    s = np.linalg.svd(sub, compute_uv=False)
    if s[-1] <= 1e-12 * s[0]:
        group, couplings = _group(coupling, ctx)
        raise ModelError(
            f"coupling {coupling.name!r}: {_cause(coupling, couplings)} the inductance matrix of "
            f"{', '.join(c.name for c in group)} singular, and nothing else gives their loops inductance, so the mass "
            f"matrix is singular (an ideal transformer has no unique currents here). Use k < 1, or add a series "
            f"(leakage) inductor to one of the loops."
        )


@hookimpl
def register_component_types(register):
    register(Coupling)


def _correction(matrix: sp.Matrix) -> sp.Matrix:
    """``Γ − diag(1/L)``, the inverse inductance matrix less its uncoupled part: what coupling adds to the currents
    ``Γ λ`` and to the energy ``½ λᵀ Γ λ`` of node fluxes.  For two coils it is written out,
    ``[[M²/(L1 Δ), −M/Δ], [−M/Δ, M²/(L2 Δ)]]`` with ``Δ = L1 L2 − M²``: a few products, where the difference of the
    adjugate's fractions and the diagonal took SymPy about 15 ms of assumption queries."""
    if matrix.rows == 2:
        L1, M, L2 = matrix[0, 0], matrix[0, 1], matrix[1, 1]
        det = L1 * L2 - M**2
        return sp.Matrix([[M**2 / (L1 * det), -M / det], [-M / det, M**2 / (L2 * det)]])
    return _inverse(matrix) - sp.diag(*[matrix[i, i] ** -1 for i in range(matrix.rows)])


def _inverse(matrix: sp.Matrix) -> sp.Matrix:
    """The inverse of an inductance matrix already known to be regular (decided by value, :func:`_singular`): the
    adjugate over the determinant up to 3×3 (two or three coupled coils, the usual case), which on symbolic
    entries takes about 1 ms where SymPy's ``inv()``, which first proves the determinant nonzero, takes 0.1 s;
    LU decomposition beyond."""
    if matrix.rows <= 3:
        return matrix.adjugate() / matrix.det(method="berkowitz")
    return matrix.inv(method="LU")
