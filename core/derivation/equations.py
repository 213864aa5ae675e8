"""Equations of motion from the Lagrangian, in mass-matrix form.

For ``L = T - V + G`` (``G``: velocity-linear couplings that store no
energy), Rayleigh function ``D`` and generalized forces ``Q``:

    d/dt ∂L/∂q̇ - ∂L/∂q + ∂D/∂q̇ = Q

is written ``M(q, t) q̈ = f(q, q̇, t)`` with

    p = ∂L/∂q̇,   M = ∂p/∂q̇,   f = ∂L/∂q - (∂p/∂q) q̇ - ∂p/∂t - ∂D/∂q̇ + Q,

derived on plain symbols standing for ``q`` and ``q̇`` (no time
differentiation of functions, no global ``simplify``, no ``expand``).  The
work is done by :class:`lagrangian.derive.Derivation`: the parts of ``T`` of
the form ``c · w_a · w_b`` with ``w = J q̇ + b`` (point masses, bodies,
inductors) give their share of ``M`` and ``f`` directly, collected by
Jacobian column (``M = Σ_k m_k J_kᵀ J_k``, ``f = −Σ_k m_k J_kᵀ (J̇_k q̇ + ḃ_k)
+ …``); everything else goes through the formulas above with memoized
derivatives.  Both give the same equations (``lagrangian.derive.general`` is
the plain-SymPy reference they are tested against).

Coordinates with no inertia at all (a zero row of ``M``: a node with no
mass, a loop with no inductor) but with dissipation are first-order: their
velocities are unknowns of the same linear solve as the accelerations of the
others.  The solve is ``A u = b`` with ``u = (q̈_inertial, q̇_first_order, λ)``
(``λ``: loop-closure multipliers), built block by block from ``M``, ``∂f/∂q̇``
and the constraint Jacobian.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from .assembly import Assembly
from ..base.component import t
from .calculus import atoms_of, symbols_of
from .derive import Derivation, Rewriter
from .recursion import Taken, position_rows, take, velocity_rows
from ..errors import ModelError
from ..base.identity import is_zero, nodes
from ..base.switching import switches
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["Equations"]


def _is_zero(expr: sp.Expr) -> bool:
    """Whether ``expr`` is identically zero (:func:`lagrangian.identity.is_zero`: robust to round-off)."""
    return is_zero(expr)


@dataclass
class _Symbols:
    q: list[sp.Symbol]
    v: list[sp.Symbol]
    a: list[sp.Symbol]


class Equations:
    """Mass matrix, forcing and the first-order solve of an :class:`~lagrangian.assembly.Assembly`.

    ``recursion``: when a domain's recursive dynamics serve the model (:mod:`lagrangian.derivation.recursion`),
    what gives compiled runs their accelerations; ``M``, ``f``, ``A`` and ``b`` are then derived on first use."""

    recursion: Taken | None = None

    def __init__(self, assembly: Assembly):
        if not assembly.coordinates:
            raise ModelError(
                "the model has no generalized coordinates: every node is fixed by ideal sources or prescribed "
                "motions, so there is nothing to solve for. Add an element that can move (a mass, a capacitor "
                "between free nodes), or use the other circuit formulation."
            )
        self._setup(assembly.coordinates, assembly.eliminated)
        self._signals = set(assembly.signals)
        q, v = self.sym.q, self.sym.v
        n = len(q)
        # derived from the generic contributions (parameters given as numbers still symbols), values put in after
        values = assembly.values
        T = self.symbolic(assembly.energy("T", generic=True))
        V = self.symbolic(assembly.energy("V", generic=True))
        D = self.symbolic(assembly.energy("D", generic=True))
        G = self.symbolic(assembly.energy("G", generic=True))
        calc = Derivation(q, v, t).calc
        Q = [sp.Integer(0)] * n
        self.load_shares: list[tuple[str, list[sp.Expr]]] = []  # (component, its share of Q)
        for name, load in assembly.load_list(generic=True):
            force = sp.Matrix([load.force]) if not isinstance(load.force, sp.MatrixBase) else load.force
            vel = sp.Matrix([load.velocity]) if not isinstance(load.velocity, sp.MatrixBase) else load.velocity
            if force.shape != vel.shape:
                raise ModelError(f"component {name!r}: a load's force {force.shape} and velocity {vel.shape} differ in shape.")
            force = [self.symbolic(e) for e in force]
            vel = [self.symbolic(e) for e in vel]
            share = [sp.Integer(0)] * n
            for i, vi in enumerate(v):
                terms = [F * calc.diff(u, vi) for F, u in zip(force, vel)]
                terms = [e for e in terms if e != 0]
                if terms:
                    share[i] = sp.Add(*terms)
                    Q[i] += share[i]
            self.load_shares.append((name, [e.xreplace(values) for e in share] if values else share))
        constraints = [self.symbolic(c) for view in assembly.generic_views.values() for c in view.constraints]
        self.constraint_owners = [None] * len(constraints)  # the component that imposes each row (None: a loop's)
        for name, c in assembly.constraint_list(generic=True):
            constraints.append(self.symbolic(c))
            self.constraint_owners.append(name)
        velocity, self.velocity_owners = [], []
        for name, c in assembly.velocity_constraint_list(generic=True):
            velocity.append(self._linear_in_rates(name, self.symbolic(c)))
            self.velocity_owners.append(name)
        rate = max((getattr(v, "constraint_rate", 10.0) for v in assembly.generic_views.values()), default=10.0)
        frames = [([self.symbolic(e) for e in f.omega], [[self.symbolic(e) for e in vel] for vel in f.velocities])
                  for f in assembly.frame_list(generic=True)]
        self._values = values  # (read by the recursion's check of its pivots; set again by _derive)
        taken = take(assembly, self, Q, calc, constraints, velocity, rate)
        self._derive(T, V, G, D, Q, constraints, rate, values=values, frames=frames, velocity=velocity, recursion=taken)

    def _linear_in_rates(self, name: str, c: sp.Expr) -> sp.Expr:
        """``c`` (in plain symbols), checked to be a constraint on velocities ``A(q, t)·q̇ + b(q, t)``."""
        v = self.sym.v
        held = [x for x in v if c.has(x)]
        if not held:
            raise ModelError(f"component {name!r}: the velocity constraint {self.display(c)} holds no rate: a "
                             f"constraint on positions alone is holonomic (the 'constraint' kind keeps it).")
        for x in held:
            for y in held:
                if sp.diff(c, x, y) != 0:
                    raise ModelError(f"component {name!r}: the velocity constraint {self.display(c)} is not linear in "
                                     f"the rates (A(q, t)·q̇ + b(q, t) = 0 is the form Lagrange–d'Alembert takes).")
        return c

    @classmethod
    def from_energies(cls, coordinates, T, V, G, D, Q, constraints=(), constraint_rate: float = 10.0,
                      quadratures: Mapping[int, sp.Expr] | None = None,
                      values: Mapping[sp.Symbol, sp.Expr] | None = None, *, constraint_owners=None,
                      velocity_constraints=(), velocity_owners=()) -> "Equations":
        """Equations of a system given directly by its energies, in the plain symbols ``q_<name>``, ``v_<name>``.

        ``coordinates`` are :class:`~lagrangian.domain.Coordinate` objects;
        ``Q`` one generalized force per coordinate.  ``quadratures`` maps
        coordinate indices to expressions ``g(t, q, q̇)`` those coordinates
        follow by ``q̇_i = g`` instead of a Lagrange equation (first-order
        rows, integrated along with the rest: reconstruction of ignorable
        coordinates).  ``values`` gives numbers to symbols of the energies
        (parameters given as numbers), put in after the derivation as for a
        model's own equations.  ``velocity_constraints`` (with the components
        owning them, ``velocity_owners``) enter with multipliers in the
        Lagrange–d'Alembert form, as a model's own do; ``constraint_owners``
        names the components of ``constraints``.
        """
        self = cls.__new__(cls)
        self._setup(coordinates)
        self.load_shares = []
        self.constraint_owners = list(constraint_owners) if constraint_owners is not None else [None] * len(list(constraints))
        self.velocity_owners = list(velocity_owners)
        self._derive(T, V, G, D, list(Q), list(constraints), constraint_rate, quadratures or {}, values=values,
                     velocity=list(velocity_constraints))
        return self

    def _setup(self, coordinates, eliminated: Mapping | None = None) -> None:
        """The plain symbols of ``coordinates``; a coordinate a constraint ``eliminated`` (name → :class:`~lagrangian.
        derivation.assembly.Elimination`) rewrites as its solution in them, so expressions in it still evaluate."""
        self.coordinates = list(coordinates)
        self.eliminated = dict(eliminated or {})
        names = [c.name for c in self.coordinates]
        self.names = names
        self.sym = _Symbols(
            [sp.Symbol(f"q_{n}", real=True) for n in names],
            [sp.Symbol(f"v_{n}", real=True) for n in names],
            [sp.Symbol(f"a_{n}", real=True) for n in names],
        )
        funcs = [c.function for c in self.coordinates]
        self._to_sym = {}
        self._from_sym = {}
        for f, q, v, a in zip(funcs, self.sym.q, self.sym.v, self.sym.a):
            df = sp.Derivative(f, t, evaluate=False)  # = f.diff(t), without diff's checks
            self._to_sym[df] = v
            self._to_sym[f] = q
            self._from_sym.update({q: f, v: df, a: sp.Derivative(f, (t, 2), evaluate=False)})
        base = Rewriter(dict(self._to_sym))
        for e in self.eliminated.values():
            self._to_sym.update({k: base(v) for k, v in e.mapping.items()})
        self._symbolic = Rewriter(self._to_sym, self._no_acceleration)
        self._display = Rewriter(self._from_sym)

    def _derive(self, T, V, G, D, Q, constraints, constraint_rate, quadratures=None, values=None, frames=(),
                velocity=(), recursion: Taken | None = None) -> None:
        q, v = self.sym.q, self.sym.v
        self._derivation = derivation = Derivation(q, v, t)
        # The derivation runs on symbols (exact, and faster than on floats); the values given as numbers go in after.
        self._values = values = dict(values or {})
        self._put = Rewriter(values)  # memoized: the equations share sub-expressions, xreplace revisits them
        #: the recursion that gives the accelerations (:mod:`lagrangian.derivation.recursion`), or None: the closed form
        self.recursion = recursion
        if recursion is not None:  # M and f derived when something asks for them (display, linearization, ...)
            self._generic = _Generic({"Q": sp.Matrix(Q), "constraints": sp.Matrix(constraints),
                                      "velocity_constraints": sp.Matrix(list(velocity))},
                                     self, functools.partial(derivation.equations, T, V, G, D, Q, frames=frames))
            self._finish(T, V, G, D, Q, None, constraint_rate, values)
            return
        M, f = derivation.equations(T, V, G, D, Q, frames=frames)
        M, f = M.copy(), sp.Matrix(f)
        for i, g in (quadratures or {}).items():  # q̇_i = g: a first-order row with unit rate
            M[i, :] = sp.zeros(1, len(q))
            f[i] = g - v[i]
        # generic: the parameters given as numbers still symbols (compiled code takes their values at run time)
        self._generic = _Generic({"M": M, "f": f, "Q": sp.Matrix(Q), "constraints": sp.Matrix(constraints),
                                  "velocity_constraints": sp.Matrix(list(velocity))}, self)
        self._finish(T, V, G, D, Q, f, constraint_rate, values)

    def _finish(self, T, V, G, D, Q, f, constraint_rate, values) -> None:
        """What both forms share: the energies, constraints and multipliers, and the split of ``A u = b``."""

        def put(e):
            if not values:
                return e
            return e.applyfunc(self._put) if isinstance(e, sp.MatrixBase) else self._put(sp.sympify(e))

        # T, V, D, G, L and Q with the values in are put together on first use (__getattr__): large sums for a large
        # model, used for display and the NumPy path; compiled runs read the generic ones
        for name in _LAZY:
            self.__dict__.pop(name, None)
        self._lazy = {"T": T, "V": V, "D": D, "G": G, "Q": sp.Matrix(Q)}
        self._generic_energies = (T, V, D, _lagrangian(T, V, G))
        self._f = None if values else f  # with values: put in on first use (large, and unused by compiled runs)
        self.constraints = put(self._generic["constraints"])
        self.velocity_constraints = put(self._generic["velocity_constraints"])
        if not hasattr(self, "velocity_owners"):
            self.velocity_owners = []
        self.constraint_rate = constraint_rate
        rows = len(self.constraints) + len(self.velocity_constraints)
        self.multipliers = [sp.Symbol(f"lambda_{k}", real=True) for k in range(rows)]
        self._split()

    def __getattr__(self, name: str):
        """``T``, ``V``, ``D``, ``G``, ``L``, ``Q``, ``M`` (and ``A`` when it is ``M``) with the values in, put
        together on first use."""
        lazy = self.__dict__.get("_lazy")
        if lazy is None or name not in _LAZY:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        if name == "L":
            value = _lagrangian(self.T, self.V, self.G)
        elif name == "A" and self.recursion is not None and self.multipliers:  # (constraints on a recursion)
            value = self._generic["A"].applyfunc(self._put) if self._values else self._generic["A"]
        elif name == "A":  # (the unconstrained case without first-order coordinates: A is M)
            value = self.M.copy()
        elif not self._values:
            value = self._generic["M"] if name == "M" else lazy[name]
        else:
            e = self._generic["M"] if name == "M" else lazy[name]
            value = e.applyfunc(self._put) if isinstance(e, sp.MatrixBase) else self._put(sp.sympify(e))
        self.__dict__[name] = value
        return value

    @property
    def values(self) -> dict:
        """The values of the parameters given as numbers, by the symbol that stands for each in the derivation."""
        return dict(self._values)

    def generic_energy(self, name: str) -> Any:
        """``T``, ``V``, ``D``, ``G`` or ``Q`` before the values given as numbers are put in (:attr:`values` holds
        them): what a question about its structure reads without putting a large sum together."""
        return self._lazy[name]

    def generic(self) -> dict:
        """The solve ``A u = b`` and the energies before the values given as numbers are put in (built on first use):
        ``{"A", "b", "T", "V", "D", "L", "p"}``, in the same plain symbols and with the same split as :attr:`A` and
        :attr:`b` — what compiled code records once, taking the values at run time."""
        g = self._generic
        if "T" not in g:
            g["T"], g["V"], g["D"], g["L"] = self._generic_energies
        if "A" not in g and self.recursion is None:
            if not self._values:
                g.update(A=self.A, b=self.b, T=self.T, V=self.V, D=self.D, L=self.L, p=self.p)
            else:
                g["A"], g["b"] = self._system(g["M"], g["f"], g["constraints"], velocity=g["velocity_constraints"])
                g["T"], g["V"], g["D"], g["L"] = self._generic_energies
                g["p"] = sp.Matrix(self._derivation.momenta())
        return g

    @property
    def p(self) -> sp.Matrix:
        """Generalized momenta ``∂L/∂q̇`` (built on first use)."""
        if getattr(self, "_p", None) is None:
            if self.recursion is not None:
                self._generic["M"]  # (the closed-form derivation the momenta come from)
            self._p = sp.Matrix(self._derivation.momenta())
            if self._values:
                self._p = self._p.applyfunc(self._put)
        return self._p

    def _no_acceleration(self, node) -> None:
        if isinstance(node, sp.Derivative) and node.expr in self._to_sym and node.derivative_count >= 2:
            raise ModelError(
                f"an energy term depends on an acceleration ({node.expr.func}''); energies may use only q and q'."
            )

    def symbolic(self, expr) -> sp.Expr:
        """Rewrite an expression in ``q(t)``, ``q̇(t)`` as one in the plain symbols used internally."""
        expr = sp.sympify(expr)
        if isinstance(expr, sp.MatrixBase):
            return expr.applyfunc(self._symbolic)
        return self._symbolic(expr)

    def display(self, expr):
        """Rewrite an internal expression back in terms of ``q(t)`` and its derivatives."""
        if isinstance(expr, sp.MatrixBase):
            return expr.applyfunc(self._display)
        return self._display(expr) if isinstance(expr, sp.Basic) else expr

    def _split(self) -> None:
        """``A u = b`` with ``u = (q̈_inertial, q̇_first_order, λ)``, built block by block: the rows of the
        coordinates are ``Σ_j M_ij q̈_j − f_i − Σ_k λ_k ∂Φ_k/∂q_i = 0``, linear in ``u``."""
        n = len(self.names)
        if self.recursion is not None:  # every pivot of the recursion is positive: every coordinate has inertia
            self.held, self.inertial, self.first_order, self._b = [], list(range(n)), [], None
            self.__dict__.pop("A", None)
            return
        # decided on the generic entries with the values as the exact binary numbers they are: a Float's rounding
        # tolerance, against a magnitude that grows with the depth of the entries (those of ten bodies on spherical
        # joints reach 10¹⁴ times their value), would take a diagonal entry of inertia for zero
        generic = self._generic["M"]
        exact = {s: sp.Rational(v) if getattr(v, "is_Float", False) or isinstance(v, float) else v
                 for s, v in self._values.items()}
        stored: dict[int, list] = {}
        for (i, j), e in sorted(generic.todok().items(), key=lambda item: (item[0][0], item[0][0] != item[0][1])):
            stored.setdefault(i, []).append(e)  # (each row's nonzero entries, its diagonal first)
        zero_rows = [i for i in range(n) if all(is_zero(e, exact) for e in stored.get(i, ()))]
        # A coordinate without inertia of its own whose motion a loop constraint fixes (a massless slider
        # closed by a loop) stays second-order: its acceleration follows from the constraint rows, and the
        # solve is regular when M is positive definite on the motions the constraints allow.
        self.held = []
        if zero_rows and len(self.constraints):
            Jq = self.constraints.jacobian(self.sym.q)
            self.held = [i for i in zero_rows if any(not _is_zero(Jq[k, i]) for k in range(Jq.rows))]
            zero_rows = [i for i in zero_rows if i not in self.held]
        self.inertial = [i for i in range(n) if i not in zero_rows]
        self.first_order = zero_rows
        self._b = None
        if not self.first_order and not len(self.constraints) and not len(self.velocity_constraints):
            self.__dict__.pop("A", None)  # A = M and b = f, both put together on first use
        else:
            self.A, self._b = self._system(self.M, self.f, self.constraints, check=True,
                                           velocity=self.velocity_constraints)

    @property
    def f(self) -> sp.Matrix:
        """The forcing ``f`` of ``M q̈ = f``, with the values of parameters given as numbers in."""
        if self._f is None:
            self._f = self._generic["f"].applyfunc(self._put)
        return self._f

    @property
    def b(self) -> sp.Matrix:
        """The right-hand side of ``A u = b``, with the values in."""
        if self._b is None and self.recursion is not None and self.multipliers:  # (constraints on a recursion)
            self._b = self._generic["b"].applyfunc(self._put) if self._values else self._generic["b"]
        if self._b is None:
            self._b = self.f.copy()
        return self._b

    def scan(self) -> dict:
        """What the generic equations call (cached): ``callables``, the names of functions of time given as Python
        callables (in ``A``, ``b`` or the energies), and ``derivatives``, time derivatives of them in ``A`` or ``b``."""
        if getattr(self, "_scan", None) is None and not getattr(self, "_signals", True):
            self._scan = {"callables": [], "derivatives": []}  # no signal given as a callable: nothing to look for
        if getattr(self, "_scan", None) is None:
            g = self.generic()
            solve = self._solve_exprs()
            energies = [sp.sympify(g[k]) for k in ("T", "V", "D", "L")] + [g["p"]]
            self._scan = {
                "callables": sorted({f.func.__name__ for f in atoms_of(solve + energies, sp.core.function.AppliedUndef)}),
                "derivatives": sorted(atoms_of(solve, sp.Derivative), key=sp.default_sort_key),
            }
        return self._scan

    def _solve_exprs(self) -> list:
        """What gives the solve ``A u = b``: ``A`` and ``b``, or a recursion's accelerations and definitions."""
        if self.recursion is not None:
            rec = self.recursion.recursion
            return [sp.Matrix(rec.accelerations), rec.kinetic, *rec.momenta, *(e for _, e in rec.definitions)]
        g = self.generic()
        return [g["A"], g["b"]]

    def time_switches(self) -> list[sp.Expr]:
        """The switching functions of ``t`` in the generic ``A`` and ``b`` (pulses, steps, ...; cached): those whose
        arguments hold ``t`` and no coordinate or velocity, where an adaptive integrator restarts
        (:mod:`lagrangian.switching`)."""
        if getattr(self, "_switches", None) is None:
            state = set(self.sym.q) | set(self.sym.v) | set(self.sym.a)
            found = {a for a in atoms_of(self._solve_exprs(), *switches())
                     if t in a.free_symbols and not a.free_symbols & state}
            self._switches = sorted(found, key=sp.default_sort_key)
        return list(self._switches)

    def parameter_symbols(self) -> set[sp.Symbol]:
        """Symbols without values in the equations and energies (not coordinates, velocities or ``t``), and in the
        solutions of the coordinates a constraint eliminated (a radius that cancels from the energies still gives the
        eliminated angle: ``θ = x / R``); cached."""
        if getattr(self, "_free", None) is None:
            g = self.generic()
            inner = set(self.sym.q) | set(self.sym.v) | set(self.sym.a) | {t}
            free = symbols_of(g[k] if isinstance(g[k], sp.MatrixBase) else sp.sympify(g[k])  # (a matrix as it is:
                              for k in ("T", "V", "D"))  # sympify copies it entry by entry)
            free |= symbols_of(self._solve_exprs())
            if self.recursion is not None:
                free -= {s for s, _ in self.recursion.recursion.definitions}
            free |= symbols_of(self.symbolic(e.solution) for e in self.eliminated.values())
            self._free = free - inner - set(self._values)
        return set(self._free)

    def _system(self, M, f, constraints, check: bool = False, velocity=None) -> tuple[sp.Matrix, sp.Matrix]:
        """``A`` and ``b`` from ``M``, ``f`` and the constraints (on positions, then on velocities), with the split
        already made; ``check``: refuse what cannot be solved (decided on the equations with the values in)."""
        n = len(self.names)
        calc = self._derivation.calc
        velocity = sp.Matrix(velocity) if velocity is not None and len(velocity) else sp.zeros(0, 1)
        if len(velocity):
            Jv, cb = self._velocity_rows(velocity, check)
            Jq, _, hb = self._constrained(constraints, check) if len(constraints) else (sp.zeros(0, n), None, sp.zeros(0, 1))
            return self._with_rows(M, f, sp.Matrix.vstack(Jq, Jv), sp.Matrix.vstack(hb, cb), check)
        if not self.first_order and not len(constraints):
            return M.copy(), f.copy()
        vF = [self.sym.v[i] for i in self.first_order]
        rates = [[-calc.diff(f[r], s) for s in vF] for r in range(n)]
        if check:
            nonlinear = sorted({s.name[2:] for row in rates for e in row for s in calc.deps(e) if s in vF})
            if nonlinear:
                raise ModelError(
                    f"the equations are nonlinear in the velocity of first-order coordinate(s) {', '.join(nonlinear)}; "
                    f"give those coordinates inertia (a mass, an inductor, a capacitor)."
                )
            for col, i in enumerate(self.first_order):
                if all(_is_zero(rates[r][col]) for r in range(n)):
                    raise ModelError(
                        f"coordinate {self.names[i]!r} has neither inertia nor dissipation, so nothing determines its "
                        f"motion (a node with only springs, or a loop with only capacitors and sources). Add a mass or "
                        f"damper (an inductor or resistor), or remove the node; a capacitor across a voltage source "
                        f"is held at the source's voltage in formulation='flux'."
                    )
        at_rest = {s: sp.Integer(0) for s in vF}
        rows = [[M[r, j] for j in self.inertial] + rates[r] for r in range(n)]
        b = [f[r].xreplace(at_rest) for r in range(n)]
        if len(constraints):
            Jq, crow, cb = self._constrained(constraints, check)
            for r in range(n):
                rows[r] += [-Jq[k, r] for k in range(Jq.rows)]
            for k in range(Jq.rows):
                rows.append([Jq[k, j] for j in self.inertial] + [sp.Integer(0)] * (len(vF) + Jq.rows))
                b.append(cb[k])
        return sp.Matrix(rows), sp.Matrix(b)

    def _velocity_rows(self, c, check: bool = False):
        """The rows of the constraints on velocities ``c = A(q, t) q̇ + b(q, t) = 0``, stabilized as ``ċ + ω c = 0``:
        ``A q̈ = −(c_q q̇ + c_t + ω c)`` (``A = c_q̇``)."""
        Jv, rhs = velocity_rows(c, self.sym.q, self.sym.v, sp.Float(self.constraint_rate), self._derivation.calc)
        involved = [self.names[i] for i in self.first_order if check and any(not _is_zero(Jv[k, i]) for k in range(Jv.rows))]
        if involved:
            raise ModelError(f"coordinates {', '.join(involved)} have no inertia but take part in a constraint on "
                             f"velocities: give them mass.")
        return Jv, rhs

    def _with_rows(self, M, f, J, rhs, check: bool):
        """``A`` and ``b`` with constraint rows ``J q̈ = rhs`` and their multipliers (forces ``Jᵀ λ``)."""
        n = len(self.names)
        calc = self._derivation.calc
        vF = [self.sym.v[i] for i in self.first_order]
        rates = [[-calc.diff(f[r], s) for s in vF] for r in range(n)]
        at_rest = {s: sp.Integer(0) for s in vF}
        rows = [[M[r, j] for j in self.inertial] + rates[r] for r in range(n)]
        b = [f[r].xreplace(at_rest) for r in range(n)]
        for r in range(n):
            rows[r] += [-J[k, r] for k in range(J.rows)]
        for k in range(J.rows):
            rows.append([J[k, j] for j in self.inertial] + [sp.Integer(0)] * (len(vF) + J.rows))
            b.append(rhs[k])
        return sp.Matrix(rows), sp.Matrix(b)

    def _constrained(self, Phi, check: bool = False):
        """Jacobian ``Φ_q`` and the right-hand sides of the stabilized constraint rows ``Φ̈ + 2ωΦ̇ + ω²Φ = 0``
        (Baumgarte): ``Φ_q q̈ = −(Φ̇_q q̇ + Φ̇_t + 2ωΦ̇ + ω²Φ)``."""
        Jq, rhs = position_rows(Phi, self.sym.q, self.sym.v, sp.Float(self.constraint_rate), self._derivation.calc)
        involved = [self.names[i] for i in self.first_order if check and any(not _is_zero(Jq[k, i]) for k in range(Jq.rows))]
        if involved:
            raise ModelError(
                f"coordinates {', '.join(involved)} have no inertia but take part in a loop-closure constraint: give them mass."
            )
        return Jq, None, rhs

    # -- display helpers -------------------------------------------------------
    @property
    def mass_matrix(self) -> sp.Matrix:
        return self.M.applyfunc(self.display)

    @property
    def forcing(self) -> sp.Matrix:
        return self.f.applyfunc(self.display)

    def as_equalities(self) -> list[sp.Eq]:
        """One ``Eq(Σ_j M_ij q̈_j, f_i)`` per coordinate, in terms of ``q(t)``."""
        M, a = self.M, self.sym.a
        lhs = [sp.Add(*[_times(M[i, j], a[j]) for j in range(M.cols) if M[i, j] != 0]) for i in range(M.rows)]
        # unevaluated: deciding whether the sides are equal walks each whole tree (hours for ten bodies in space)
        return [sp.Eq(self.display(l), self.display(r), evaluate=False) for l, r in zip(lhs, self.f)]


#: A mass-matrix entry of more distinct sub-expressions than this is multiplied by its acceleration unevaluated in
#: :meth:`Equations.as_equalities`: SymPy's product asks the entry's assumptions by walking it as a tree, not a DAG
#: (100 s for the equations of ten bodies on spherical joints, whose entries nest each body's pose in the next).
DISPLAY_EVALUATED_MAX = 200


def _times(m: sp.Expr, a: sp.Symbol) -> sp.Expr:
    """``m · a``, evaluated (SymPy's canonical form) unless ``m`` is large (:data:`DISPLAY_EVALUATED_MAX`)."""
    if len(nodes([m])) > DISPLAY_EVALUATED_MAX:
        return sp.Mul(m, a, evaluate=False)
    return m * a


#: What :class:`Equations` puts together on first use (its ``__getattr__``; ``A`` when it is ``M``).
_LAZY = ("T", "V", "D", "G", "L", "Q", "M", "A")


def _lagrangian(T, V, G) -> sp.Expr:
    """``T − V + G`` with ``−V`` kept as one product: negating a sum of 10⁴ terms term by term asks each its
    assumptions (seconds for a chain of nonlinear springs), and the sum is the same."""
    if isinstance(V, sp.Add):
        return sp.Add(T, sp.Mul(sp.S.NegativeOne, V, evaluate=False), G)
    return T - V + G


class _Generic(dict):
    """The generic equations (:meth:`Equations.generic`): with a recursion, ``M`` and ``f`` are derived on first
    use (``derive``), and ``A``, ``b`` and the momenta ``p`` put together from them; a run the recursion serves
    never asks for them."""

    def __init__(self, items: Mapping, owner: "Equations", derive=None):
        super().__init__(items)
        self.owner, self.derive = owner, derive

    def __missing__(self, key: str):
        if key in ("M", "f") and self.derive is not None:
            M, f = self.derive()
            self.derive = None
            self["M"], self["f"] = M.copy(), sp.Matrix(f)
            return self[key]
        eq = self.owner
        if key in ("A", "b") and eq.recursion is not None:
            self["A"], self["b"] = eq._system(self["M"], self["f"], self["constraints"],
                                              velocity=self["velocity_constraints"])
            return self[key]
        if key == "p" and eq.recursion is not None:
            self["M"]  # (the derivation the momenta come from)
            self["p"] = sp.Matrix(eq._derivation.momenta())
            return self[key]
        raise KeyError(key)
