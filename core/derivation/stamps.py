"""Linear time-invariant models assembled numerically, component by component, as sparse matrices.

A model whose components all contribute energies quadratic in the
coordinates and velocities with constant coefficients — masses, linear
springs and dampers in one dimension, inductors, capacitors, resistors,
sources, gravity, applied forces that are functions of time — has equations
of motion

    M q̈ + C q̇ + K q = B s(t)

with constant ``M``, ``C``, ``K`` and ``B`` and a few input shapes ``s(t)``.
Each component's share of them (its *stamp*) follows from its own
contribution alone: for ``L = T − V + G``, Rayleigh function ``D`` and loads
``F·w``, with ``z = (q, q̇)``,

    M = L_q̇q̇,   C = L_q̇q − L_qq̇ + D_q̇q̇ − Jᵀ F_q̇,   K = −L_qq + D_q̇q − Jᵀ F_q,
    B s = ∂L/∂q|₀ − d/dt ∂L/∂q̇|₀ − ∂D/∂q̇|₀ + Jᵀ F|₀

(second derivatives constant, ``J = ∂w/∂q̇``, ``|₀`` at ``z = 0``: the parts
that are functions of ``t`` alone).  :func:`stamps` differentiates each
contribution in its few local variables and scatters the numbers into sparse
matrices: the cost is linear in the number of components, where the symbolic
derivation of the whole model (:mod:`lagrangian.derivation.equations`) grows
faster and keeps every entry as an expression.  Measured on a chain of
masses, springs and dampers: 2,000 masses stamped in 1.2 s, where the
symbolic equations alone take 9.1 s.

Anything else — a coefficient that depends on the state or on ``t``, a term
beyond second order, a signal given as a Python callable, a loop-closure
constraint, a parameter without a value — raises :class:`NotStampable` with
the component and the reason; callers then take the symbolic path, whose
messages name the equation and the term.

>>> import sympy as sp, lagrangian as lg
>>> from lagrangian.derivation.stamps import stamps
>>> m = lg.Model("oscillator")
>>> _ = m.add("mass", "m1", "p", m=0.3)
>>> _ = m.add("spring", "k1", ("ground", "p"), k=40)
>>> _ = m.add("damper", "c1", ("ground", "p"), c=0.2)
>>> _ = m.add("force", "F", "p", F=2 * sp.sin(3 * lg.t))
>>> st = stamps(m.assembly, m.assembly.values)
>>> st.M.toarray(), st.C.toarray(), st.K.toarray()
(array([[0.3]]), array([[0.2]]), array([[40.]]))
>>> st.inputs, st.B.toarray()
([sin(3*t)], array([[2.]]))
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import scipy.sparse as sps

from ..base.component import t
from .assembly import Assembly
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["NotStampable", "Quadratic", "Stamps", "stamps"]

_EPS = np.finfo(float).eps
#: An entry that sums to less than this many ε of the sum of its addends' sizes is a round-off residual, zero.
_ROUNDOFF = 64


class NotStampable(Exception):
    """A model that is not linear time-invariant in the stamps' sense; ``args[0]`` says which component and why."""


@dataclass
class Quadratic:
    """An energy ``E(z, t) = ½ zᵀ H z + Σ h_i(t) z_i + c(t)`` over ``z = (q, q̇)`` (``2n`` entries)."""

    H: sps.csr_matrix
    linear: list[tuple[int, sp.Expr]] = field(default_factory=list)
    constant: sp.Expr | float = 0

    def values(self, times: np.ndarray, Z: np.ndarray) -> np.ndarray:
        """``E`` at ``times`` for states ``Z`` (``2n × len(times)``)."""
        form = getattr(self.H, "form", None)  # a numeric assembly's form (derivation.numeric): entry by entry
        out = 0.5 * (form(Z) if form is not None else np.einsum("ij,ij->j", Z, self.H @ Z))
        for i, expr in self.linear:
            out = out + _on_grid(expr, times) * Z[i]
        if self.constant != 0:
            out = out + _on_grid(self.constant, times)
        return out


def _on_grid(expr: sp.Expr | float, times: np.ndarray) -> np.ndarray:
    """An expression of ``t`` on a grid (SciPy's special functions, huge integers as floats); a number as itself."""
    if type(expr) in (int, float) or not expr.free_symbols:
        return np.full(times.shape, float(expr))
    fn = sp.lambdify(t, expr, modules=["scipy", "numpy"])
    with np.errstate(all="ignore"):
        return np.broadcast_to(np.asarray(fn(times), dtype=float), times.shape)


@dataclass
class Stamps:
    """``M q̈ + C q̇ + K q = B s(t)`` of a model, with its energies (see the module documentation).

    ``inputs`` are the distinct shapes ``s_j(t)`` (``1`` for constant loads
    such as gravity) and ``B`` their coefficients, one column each.
    ``inertial`` lists the coordinates with inertia (a nonzero row of
    ``M``), ``first_order`` those without inertia but with a velocity term
    (a node with a damper and no mass, a loop with a resistor and no
    inductor): what :func:`lagrangian.numerics.simulation.initial_state`
    reads, as from :class:`~lagrangian.derivation.equations.Equations`.
    """

    names: list[str]
    M: sps.csr_matrix
    C: sps.csr_matrix
    K: sps.csr_matrix
    B: sps.csr_matrix
    inputs: list[sp.Expr]
    energies: dict[str, Quadratic]
    inertial: list[int]
    first_order: list[int]
    input_rows: list[int]

    @property
    def n(self) -> int:
        return len(self.names)


class _Triplets:
    """Entries of a sparse matrix, summed on conversion, with the sizes of their addends (to clear round-off)."""

    def __init__(self, shape: tuple[int, int]):
        self.shape = shape
        self.rows: list[int] = []
        self.cols: list[int] = []
        self.vals: list[float] = []

    def add(self, i: int, j: int, value: float) -> None:
        self.rows.append(i)
        self.cols.append(j)
        self.vals.append(value)

    def matrix(self) -> sps.csr_matrix:
        """The entries summed, each with the sum of its addends' sizes; an entry within round-off of zero is left
        out.  (Summed by sorting in NumPy: a tiny matrix takes microseconds where SciPy's conversions and fancy
        indexing took 0.6 ms, and an addend pair that cancels exactly no longer misaligns the two sums.)"""
        import scipy.sparse as sps

        if not self.vals:
            return sps.csr_matrix(self.shape)
        key = np.array(self.rows, dtype=np.int64) * self.shape[1] + np.array(self.cols, dtype=np.int64)
        order = np.argsort(key, kind="stable")  # equal entries keep the order they were added in
        key, vals = key[order], np.array(self.vals)[order]
        starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
        total, size = np.add.reduceat(vals, starts), np.add.reduceat(np.abs(vals), starts)
        keep = np.abs(total) > _ROUNDOFF * _EPS * size
        where = key[starts][keep]  # row-major order: already CSR's
        indptr = np.r_[0, np.cumsum(np.bincount(where // self.shape[1], minlength=self.shape[0]))]
        return sps.csr_matrix((total[keep], where % self.shape[1], indptr), shape=self.shape)


class _Local:
    """One component's variables: its coordinates and velocities as plain symbols, and where they sit globally."""

    __slots__ = ("z", "where", "subs", "zero")

    def __init__(self, exprs, coordinates: Mapping[Any, int], signals, name: str, n: int, inputs=frozenset()):
        funcs: dict[Any, int] = {}
        rates: dict[Any, int] = {}
        for e in exprs:
            for d in e.atoms(sp.Derivative):
                if d.expr in coordinates and d.derivative_count == 1 and d.variables == (t,):
                    rates[d] = coordinates[d.expr]
                elif isinstance(d.expr, sp.core.function.AppliedUndef) and d.expr.func in inputs:
                    continue  # an input's rate: a function of t
                else:
                    raise NotStampable(f"{name}: the term {d} is not the velocity of a coordinate")
            for f in e.atoms(sp.core.function.AppliedUndef):
                if f in coordinates:
                    funcs[f] = coordinates[f]
                elif f.func in inputs:
                    continue
                elif f.func in signals:
                    raise NotStampable(f"{name}: {f} is a signal given as a Python callable")
                else:
                    raise NotStampable(f"{name}: {f} is neither a coordinate nor a signal")
        qs = sorted(set(funcs.values()) | set(rates.values()))
        local = {g: k for k, g in enumerate(qs)}
        m = len(qs)
        self.z = _symbols(2 * m)
        self.where = [*qs, *(n + g for g in qs)]  # local variable → index into the global z = (q, q̇)
        self.subs = {f: self.z[local[g]] for f, g in funcs.items()} | {d: self.z[m + local[g]] for d, g in rates.items()}
        self.zero = dict.fromkeys(self.z, sp.Integer(0))


_POOL: list[sp.Symbol] = []


def _symbols(count: int) -> list[sp.Symbol]:
    while len(_POOL) < count:
        _POOL.append(sp.Dummy(f"z{len(_POOL)}", real=True))
    return _POOL[:count]


def _number(expr: sp.Expr, name: str, what: str, z) -> float:
    if expr.is_Number:
        value = float(expr)
        if not np.isfinite(value):
            raise NotStampable(f"{name}: {what} is not finite")
        return value
    free = expr.free_symbols
    if free & set(z):
        raise NotStampable(f"{name}: {what} depends on the state (nonlinear): {expr}")
    if t in free:
        raise NotStampable(f"{name}: {what} varies with time: {expr}")
    if free:
        raise NotStampable(f"{name}: {what} has symbols without values: {', '.join(sorted(map(str, free)))}")
    try:
        return _number(sp.Float(expr), name, what, z)
    except (TypeError, ValueError):
        raise NotStampable(f"{name}: {what} is not a real number: {expr}") from None


def _of_time(expr: sp.Expr, name: str, what: str) -> sp.Expr:
    free = expr.free_symbols - {t}
    if free:
        raise NotStampable(f"{name}: {what} depends on {', '.join(sorted(map(str, free)))}, not on t alone")
    return expr


#: Derivatives of the addends seen so far, by structure: the addend with its local variables and its parameters
#: replaced by placeholders (every spring of a chain is one entry).  Bounded; shared by every model.
_STRUCTURES: dict = {}
_STRUCTURES_MAX = 4096
_PARAMS: list[sp.Symbol] = []


def _placeholders(count: int) -> list[sp.Symbol]:
    while len(_PARAMS) < count:
        _PARAMS.append(sp.Dummy(f"p{len(_PARAMS)}"))
    return _PARAMS[:count]


def _derivatives(expr: sp.Expr, loc: _Local, numbers: Mapping, name: str, part: str):
    """``(H, h, c)`` of ``expr`` (in ``loc.z``, parameters as symbols): its constant Hessian, its gradient at zero and
    its value at zero, with the parameters at ``numbers``.  The symbolic derivatives are cached by structure."""
    z = loc.z
    params = sorted(expr.free_symbols - set(z) - {t}, key=lambda s: (s.name, str(s.assumptions0)))
    missing = [str(s) for s in params if s not in numbers]
    if missing:
        raise NotStampable(f"{name}: {part} has parameters without values: {', '.join(missing)}")
    P = _placeholders(len(params))
    key = (expr.xreplace(dict(zip(params, P))), len(z))
    entry = _STRUCTURES.get(key)
    if entry is None:
        generic = key[0]
        grad = [generic.diff(s) for s in z]
        hess = {}
        for i, g in enumerate(grad):
            if g != 0:
                for j in range(i, len(z)):
                    e = g.diff(z[j])
                    if e != 0:
                        hess[i, j] = e
        rest = {i: g.xreplace(loc.zero) for i, g in enumerate(grad) if g != 0}
        entry = (hess, {i: e for i, e in rest.items() if e != 0}, generic.xreplace(loc.zero))
        if len(_STRUCTURES) >= _STRUCTURES_MAX:
            _STRUCTURES.clear()
        _STRUCTURES[key] = entry
    hess, rest, at_zero = entry
    put = {p: numbers[s] for p, s in zip(P, params)}
    H = {}
    for (i, j), e in hess.items():
        value = _number(e.xreplace(put), name, f"∂²{part}/∂{z[i]}∂{z[j]}", z)
        if value:
            H[i, j] = value
    h = {i: _of_time(e.xreplace(put), name, f"∂{part}/∂{z[i]} at rest") for i, e in rest.items()}
    return H, h, at_zero.xreplace(put)


def _load(force: sp.Expr, vel: sp.Expr, loc: _Local, name: str, n: int, C: _Triplets, K: _Triplets,
          forcing: dict) -> None:
    """A load ``force · vel``: ``Q = Jᵀ F`` with ``J = ∂vel/∂q̇`` constant, ``F`` affine in the state."""
    z, where = loc.z, loc.where
    m = len(z) // 2
    J = {}
    for k in range(m, 2 * m):
        dv = vel.diff(z[k])
        if dv != 0:
            J[k] = _number(dv, name, f"∂(load velocity)/∂{z[k]}", z)
    if not J:
        return
    F = {}
    for k, s in enumerate(z):
        dF = force.diff(s)
        if dF != 0:
            F[k] = _number(dF, name, f"∂(load force)/∂{s}", z)
    rest = _of_time(force.xreplace(loc.zero), name, "the load's force at rest")
    for k, jk in J.items():
        row = where[k] - n
        for j, fj in F.items():  # −Jᵀ F_z onto the left: into C (a velocity) or K (a coordinate)
            (C if where[j] >= n else K).add(row, where[j] % n, -jk * fj)
        if rest != 0:
            forcing.setdefault(row, []).append(jk * rest)


def stamps(assembly: Assembly, values: Mapping[sp.Symbol, Any], inputs=frozenset(), energies: bool = True) -> Stamps:
    """The model of ``assembly`` as sparse matrices, with the parameters at ``values`` (see the module documentation).

    ``inputs``: undefined functions of ``t`` that stand for inputs (those of
    a linearization, :meth:`lagrangian.Component.with_input`); they and their
    derivatives are input shapes like any function of ``t``.  ``energies``:
    also the quadratic forms of ``T``, ``V`` and ``D`` (what a run's energy
    outputs need; a linearization does not, and ``Stamps.energies`` is then
    empty).

    Raises :class:`NotStampable` (naming the component and the reason) when a
    component's contribution is not quadratic with constant coefficients, a
    parameter has no value, a signal is a Python callable or a domain has
    loop-closure constraints.
    """
    import scipy.sparse as sps  # imported by what uses it: 0.2 s that a process running compiled code never needs

    names = [c.name for c in assembly.coordinates]
    n = len(names)
    if not n:
        raise NotStampable("the model has no coordinates")
    for dname, view in assembly.generic_views.items():
        if len(getattr(view, "constraints", ())):
            raise NotStampable(f"the {dname} domain has loop-closure constraints")
    if assembly.state_callables:
        raise NotStampable(f"loads given as Python callables of the state ({', '.join(assembly.state_callables)})")
    held = [name for name, c in assembly.generic.items() if c.constraints or c.velocity_constraints]
    if held:
        raise NotStampable(f"{held[0]} imposes a constraint between coordinates")
    coordinates = {c.function: i for i, c in enumerate(assembly.coordinates)}
    numbers = {s: sp.Float(float(v)) for s, v in values.items()}
    M, C, K = (_Triplets((n, n)) for _ in range(3))
    energy = {part: _Triplets((2 * n, 2 * n)) for part in "TVD"}
    linear: dict[str, dict[int, list]] = {part: {} for part in "TVD"}
    constant: dict[str, list] = {part: [] for part in "TVD"}
    forcing: dict[int, list[sp.Expr]] = {}  # row → terms of B s(t)
    rates: dict[int, list[sp.Expr]] = {}  # row → terms of ∂L/∂q̇ at rest, differentiated in t at the end

    def scatter(H: dict, where: list[int], sign: float, role: str) -> None:
        """Entries of a Hessian of ``L`` (``role="L"``) or ``D`` (``"D"``) into ``M``, ``C``, ``K``."""
        for (i, j), value in H.items():
            for a, b in ((i, j), (j, i)) if i != j else ((i, j),):
                ga, gb = where[a], where[b]
                va, vb = ga >= n, gb >= n  # a velocity
                if role == "L":
                    if va and vb:
                        M.add(ga - n, gb - n, sign * value)
                    elif va:  # ∂²L/∂q̇_a∂q_b: + into C[a, b] (from d/dt ∂L/∂q̇_a), − into C[b, a] (from ∂L/∂q_b)
                        C.add(ga - n, gb, sign * value)
                        C.add(gb, ga - n, -sign * value)
                    elif not vb:
                        K.add(ga, gb, -sign * value)
                else:  # D: D_q̇q̇ into C, D_q̇q into K
                    if va and vb:
                        C.add(ga - n, gb - n, sign * value)
                    elif va:
                        K.add(ga - n, gb, sign * value)

    for cname, contribution in assembly.generic.items():
        for part in ("T", "V", "D", "G"):
            for expr in sp.Add.make_args(sp.sympify(getattr(contribution, part), strict=True)):
                # each addend in its own few variables: gravity's sum over every mass stays linear in cost
                if expr == 0:
                    continue
                loc = _Local([expr], coordinates, assembly.signals, cname, n, inputs)
                where = loc.where
                H, h, c = _derivatives(expr.xreplace(loc.subs), loc, numbers, cname, part)
                sign = -1.0 if part == "V" else 1.0
                scatter(H, where, sign, "D" if part == "D" else "L")
                if part != "G" and energies:
                    for (i, j), value in H.items():
                        energy[part].add(where[i], where[j], value)
                        if i != j:
                            energy[part].add(where[j], where[i], value)
                    for i, e in h.items():
                        linear[part].setdefault(where[i], []).append(e)
                    if c != 0:
                        constant[part].append(_of_time(c, cname, f"{part} at rest"))
                for i, e in h.items():
                    g = where[i]
                    if part == "D":
                        if g >= n:
                            forcing.setdefault(g - n, []).append(-e)
                    elif g < n:
                        forcing.setdefault(g, []).append(sign * e)
                    else:
                        rates.setdefault(g - n, []).append(sign * e)
        for load in contribution.loads:
            force = list(load.force) if isinstance(load.force, sp.MatrixBase) else [sp.sympify(load.force, strict=True)]
            vel = list(load.velocity) if isinstance(load.velocity, sp.MatrixBase) else [sp.sympify(load.velocity, strict=True)]
            if len(force) != len(vel):  # the symbolic path says so, naming the component
                raise NotStampable(f"{cname}: a load's force and velocity differ in shape")
            for f, w in zip(force, vel):
                if f == 0 or w == 0:
                    continue
                loc = _Local([f, w], coordinates, assembly.signals, cname, n, inputs)
                _load(f.xreplace(loc.subs).xreplace(numbers), w.xreplace(loc.subs).xreplace(numbers), loc, cname,
                      n, C, K, forcing)
    for row, terms in rates.items():  # − d/dt ∂L/∂q̇ at rest
        forcing.setdefault(row, []).append(-sp.Add(*terms).diff(t))

    channels: dict[sp.Expr, int] = {}
    Brows, Bcols, Bvals, input_rows = [], [], [], []
    for row in sorted(forcing):
        for term in sp.Add.make_args(sp.Add(*forcing[row])):
            if term == 0:
                continue
            coeff, shape = term.as_coeff_Mul()
            value = _number(coeff, names[row], "an input's coefficient", ())
            if shape not in channels:
                channels[shape] = len(channels)
                input_rows.append(row)
            Brows.append(row)
            Bcols.append(channels[shape])
            Bvals.append(value)
    B = sps.csr_matrix((Bvals, (Brows, Bcols)), shape=(n, len(channels)))
    Mm, Cm, Km = M.matrix(), C.matrix(), K.matrix()
    inertial = [i for i in range(n) if Mm.indptr[i + 1] > Mm.indptr[i]]
    has_rate = np.diff(Cm.tocsc().indptr) > 0
    first = [i for i in range(n) if Mm.indptr[i + 1] == Mm.indptr[i]]
    idle = [names[i] for i in first if not has_rate[i]]
    if idle:
        raise NotStampable(f"coordinates without inertia or dissipation: {', '.join(idle[:5])}")
    forms = {} if not energies else {
        part: Quadratic(energy[part].matrix(), [(i, sp.Add(*es)) for i, es in sorted(linear[part].items())],
                        sp.Add(*constant[part]))
        for part in "TVD"
    }
    return Stamps(names, Mm, Cm, Km, B.tocsr(), list(channels), forms, inertial, first, input_rows)
