"""Ignorable coordinates, Routhian reduction, the Jacobi integral, steady motion and its stability.

A coordinate ``q_i`` that appears in the Lagrangian only through its
velocity — and on which no dissipation, generalized force or loop
constraint acts — is *ignorable* (cyclic): its momentum ``p_i = ∂L/∂q̇_i``
is a constant ``C_i``.  Solving ``p_i = C_i`` for the ignorable velocities
and forming the Routhian

    R = Σ C_i q̇_i − L

leaves ``n − m`` coordinates whose equations of motion are Lagrange's with
``−R`` as their Lagrangian; the ignorable coordinates follow by quadrature,
``q_i(t) = q_i(t₀) + ∫ ∂R/∂C_i dt``.  ``−R`` splits by degree in the
remaining velocities into a kinetic energy, velocity-linear (gyroscopic)
terms and ``−V_eff``: the *effective potential* (the potential energy plus
the kinetic energy locked in the ignorable motion).

>>> import lagrangian as lg
>>> from lagrangian import routh
>>> m = lg.Model("spherical pendulum", dim=3)
>>> _ = m.add("link", "yoke", "yoke")
>>> _ = m.add("revolute", "turn", ("ground", "yoke"), axis=(0, 0, 1))
>>> _ = m.add("link", "arm", "arm", points={"bob": (0, 0, -1)})
>>> _ = m.add("revolute", "tilt", ("yoke", "arm"), axis=(1, 0, 0))
>>> _ = m.add("mass", "bob", "arm.bob", m=1)
>>> _ = m.add("gravity", "g", g=9.81)
>>> routh.ignorable(m)
['theta_turn']
>>> red = routh.reduce(m)
>>> red.routhian
C_theta_turn**2/(2*sin(theta_tilt(t))**2) - 9.81*cos(theta_tilt(t)) - Derivative(theta_tilt(t), t)**2/2
>>> red.effective_potential
C_theta_turn**2/(2*sin(theta_tilt(t))**2) - 9.81*cos(theta_tilt(t))

``jacobi_integral`` gives ``h = Σ q̇ ∂L/∂q̇ − L`` for any model and says
whether it is conserved (and whether it equals the total energy);
:meth:`ReducedModel.steady_motions` solves ``∂R/∂q_k = 0`` with the reduced
velocities zero, and :meth:`SteadyMotion.stability` linearizes about a
steady motion.  Reduced models are :class:`~lagrangian.Model` objects:
``simulate`` works as for the full model, the momenta given as values
(``momenta=``) or from the full model's initial velocities.
"""

from __future__ import annotations

import itertools
import math
import threading
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from ..base.budget import DEFAULT_SECONDS, BudgetExceeded, interruptible, within
from ..base.component import t
from .derived import DerivedModel
from ..derivation.equations import Equations
from ..errors import ReductionError, UnknownNameError
from ..base.identity import depends_on, equal, is_zero
from ..model import Model
from ..base.text import as_expr
from ..numerics.simulation import Result

__all__ = [
    "Ignorability",
    "ignorability",
    "ignorable",
    "reduce",
    "ReducedModel",
    "JacobiIntegral",
    "jacobi_integral",
    "SteadyMotion",
    "Perturbation",
    "Stability",
]


# -- ignorable coordinates --------------------------------------------------------------------------


@dataclass(frozen=True)
class Ignorability:
    """Whether one coordinate is ignorable, and why (or why not)."""

    coordinate: str
    ignorable: bool
    reason: str

    def __str__(self) -> str:
        return f"{self.coordinate}: {'ignorable' if self.ignorable else 'not ignorable'} — {self.reason}"


def _depends(eq: Equations, expr: sp.Expr, symbol: sp.Symbol) -> bool:
    """Whether ``expr`` really depends on ``symbol`` (a derivative that is not identically zero)."""
    return depends_on(expr, symbol, diff=eq._derivation.calc.diff)


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


def ignorability(model: Model) -> dict[str, Ignorability]:
    """Every coordinate of ``model``, whether it is ignorable, and the reason.

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
    out = {}
    for i, name in enumerate(eq.names):
        qi, vi = q[i], v[i]

        def verdict(reason: str, ok: bool = False) -> None:
            out[name] = Ignorability(name, ok, reason)

        if i in eq.first_order:
            verdict("it has no inertia (a first-order coordinate): its rate follows from dissipation, there is no momentum to conserve")
            continue
        if _depends(eq, eq.T, qi):
            verdict(f"the kinetic energy T depends on it (from {_named(_components(model, 'T', qi))})")
            continue
        if _depends(eq, eq.V, qi):
            verdict(f"the potential energy V depends on it (from {_named(_components(model, 'V', qi))}): a force acts along it")
            continue
        if _depends(eq, eq.G, qi):
            verdict(f"the velocity-coupling terms G depend on it (from {_named(_components(model, 'G', qi))})")
            continue
        if _depends(eq, eq.D, vi) or _depends(eq, eq.D, qi):
            verdict(f"dissipation acts on it (the Rayleigh function D depends on it, from "
                    f"{_named(_components(model, 'D', vi) or _components(model, 'D', qi))}): its momentum decays")
            continue
        acting = [c for c, share in eq.load_shares if not is_zero(share[i])]
        if acting:
            verdict(f"a generalized force acts on it (from {_named(acting)}): its momentum changes")
            continue
        through = [c for c, share in eq.load_shares if any(_depends(eq, e, qi) for e in share)]
        if through:
            verdict(f"the generalized force of {_named(through)} depends on it")
            continue
        if any(_depends(eq, c, qi) for c in eq.constraints):
            verdict("it takes part in a loop-closure constraint, whose force acts along it")
            continue
        verdict("absent from L, D, the forces and the constraints: its momentum ∂L/∂q̇ is conserved", True)
    return out


def ignorable(model: Model) -> list[str]:
    """Names of the ignorable coordinates of ``model`` (see :func:`ignorability`)."""
    return [name for name, r in ignorability(model).items() if r.ignorable]


# -- helpers ----------------------------------------------------------------------------------------


#: Seconds one cosmetic simplification may take before the expression is kept as it is.
TIDY_SECONDS = 2.0


def _tidy(expr: sp.Expr, limit: int = 100) -> sp.Expr:
    """A cheap simplification, skipped for large expressions (floats are kept as they are, not spread).

    Cosmetic: under a budget of :data:`TIDY_SECONDS` (``trigsimp`` can factor
    for minutes on some coefficients), past which the expression stays as it
    is — equally exact."""
    expr = sp.sympify(expr)
    if expr.count_ops() > limit:
        return expr
    try:
        return interruptible(_simplified, expr, seconds=TIDY_SECONDS)
    except BudgetExceeded:
        return expr


def _simplified(expr: sp.Expr) -> sp.Expr:
    floats = {f: sp.Dummy() for f in expr.atoms(sp.Float)}
    try:
        out = sp.cancel(sp.together(expr.xreplace(floats)))
        if sp.count_ops(out) <= 80:  # trigsimp pays off on small expressions and costs seconds on large ones
            out = sp.trigsimp(out)
    except (sp.PolynomialError, TypeError, ValueError):  # pragma: no cover - sympy corner cases
        return expr
    out = out.xreplace({d: f for f, d in floats.items()})
    return out if sp.count_ops(out) <= sp.count_ops(expr) else expr


def _terms(expr: sp.Expr, limit: int = 100) -> sp.Expr:
    """A sum of simple terms (how R, V_eff and T read best), each tidied; large expressions as they are."""
    expr = _tidy(expr, limit)
    if expr.count_ops() > limit:
        return expr
    return sp.Add(*[_tidy(term, limit) for term in sp.Add.make_args(sp.expand(expr))])


def _drop(expr: sp.Expr, symbols: Sequence[sp.Symbol]) -> sp.Expr:
    """``expr`` with symbols it does not depend on replaced by a constant (0, or a generic value if 0 is singular)."""
    for value in (sp.Integer(0), sp.Rational(1, 3)):
        out = sp.sympify(expr).xreplace({s: value for s in symbols})
        if not out.has(sp.zoo, sp.nan, sp.oo, -sp.oo):
            return out
    return expr  # pragma: no cover - singular at both values


def _factors_vanishing(det: sp.Expr) -> list[sp.Expr]:
    """Factors of ``det`` that can vanish (not numbers, not always-positive)."""
    out = []
    try:
        factored = interruptible(sp.factor, det, seconds=TIDY_SECONDS)
    except BudgetExceeded:
        factored = det
    for f in sp.Mul.make_args(factored):
        base = f.base if isinstance(f, sp.Pow) and f.exp.is_positive else f
        if base.is_number or (isinstance(f, sp.Pow) and f.exp.is_negative):
            continue
        if base.is_positive:
            continue
        if base not in out:
            out.append(base)
    return out


#: Reductions kept by structure (least recently used dropped first).
CACHE_SIZE = 128
_CACHE: "OrderedDict[tuple, dict]" = OrderedDict()
_CACHE_LOCK = threading.Lock()


def _by_structure(key: tuple, values: Mapping[sp.Symbol, sp.Expr], compute) -> dict:
    """``compute()`` (a dict of parts in the symbols of ``values``), once per structure.

    ``key`` holds the expressions the parts are computed from; the symbols
    standing for numbers (the keys of ``values``, unique to one model) are
    renamed to canonical symbols in the key and in the stored parts, and back
    on the way out, so the same components given other numbers reuse the work.
    """
    canon = {s: sp.Symbol(s.name, **s.assumptions0) for s in values}
    key = tuple(_put(k, canon) for k in key)
    with _CACHE_LOCK:
        cached = _CACHE.get(key)
        if cached is not None:
            _CACHE.move_to_end(key)
    if cached is None:
        parts = compute()
        with _CACHE_LOCK:
            _CACHE[key] = {k: _put(part, canon) for k, part in parts.items()}
            while len(_CACHE) > CACHE_SIZE:
                _CACHE.popitem(last=False)
        return parts
    back = {c: s for s, c in canon.items()}
    return {k: _put(part, back) for k, part in cached.items()}


def _put(part: Any, values: Mapping[sp.Symbol, sp.Expr]) -> Any:
    """A part of the reduction with the values of parameters given as numbers put in (lists part by part)."""
    if not values or isinstance(part, (bool, int)):
        return part
    if isinstance(part, list):
        return [_put(e, values) for e in part]
    if isinstance(part, tuple):
        return tuple(_put(e, values) for e in part)
    return part.xreplace(values) if isinstance(part, sp.Basic) else part


# -- the reduced model ------------------------------------------------------------------------------


class ReducedModel(DerivedModel):
    """A model with its ignorable coordinates eliminated through the Routhian (make one with :func:`reduce`).

    It is a :class:`~lagrangian.Model`: ``lagrangian`` (``= −R``),
    ``equations``, ``mass_matrix``, ``forcing``, ``parameters`` and
    ``simulate`` work as for the full model, over the remaining coordinates.
    The momenta ``C_<name>`` are parameters: give them with ``momenta=``,
    or give the ignorable coordinates' velocities in ``velocity=`` and they
    are computed from the full model's momenta.  ``simulate(...,
    reconstruct=True)`` integrates the ignorable coordinates by quadrature
    along the reduced motion (their initial values from ``initial=``).

    Attributes (in terms of ``q(t)`` and ``q̇(t)``): ``routhian`` ``R``,
    ``momenta`` ``{coordinate: C}``, ``rates`` ``{coordinate: ∂R/∂C}`` (the
    ignorable velocities), ``effective_potential`` (``None`` when ``−R`` is
    not quadratic in the velocities), ``gyroscopic`` (velocity-linear part
    of ``−R``), ``singularities`` (expressions whose zeros make the
    momentum equations singular: coordinate singularities of the
    reduction).
    """

    def __init__(self, full: Model, ignorable: Sequence[str], momenta: Mapping[str, Any] | None = None,
                 _quadrature: Sequence[str] = (), _parent: "ReducedModel | None" = None):
        super().__init__(full, f"{full.name} (reduced)", self._build_equations)
        self.full = full
        self.ignored = list(ignorable)
        self._quadrature = tuple(_quadrature)
        if _parent is not None:
            self.__dict__.update({k: v for k, v in _parent.__dict__.items() if k.startswith("_r_")})
        else:
            self._reduce(momenta or {})
        self._siblings: dict[tuple[str, ...], ReducedModel] = {}

    # -- the reduction -------------------------------------------------------
    def _reduce(self, momenta: Mapping[str, Any]) -> None:
        """Reduce the generic equations (parameters given as numbers still symbols), then put the values in:
        a model given numbers and its twin given symbols take the same decisions on the same expressions."""
        full = self.full
        eq = full.eq
        generic = eq.generic()
        values = eq.values
        names = eq.names
        I = [names.index(n) for n in self.ignored]
        K = [i for i in range(len(names)) if i not in I]
        q, v = eq.sym.q, eq.sym.v
        qI, vI = [q[i] for i in I], [v[i] for i in I]
        C = []
        for n in self.ignored:
            given = momenta.get(n)
            C.append(sp.Symbol(f"C_{n}", real=True) if given is None else as_expr(given, f"momenta[{n!r}]"))
        unknown = [k for k in momenta if k not in self.ignored]
        if unknown:
            raise UnknownNameError("ignorable coordinate (for momenta=)", unknown[0], self.ignored)
        # One reduction per structure: the same components with other numbers reuse it (the symbols standing
        # for the numbers are renamed to canonical ones in the key, and back in the parts).
        key = ("reduce", tuple(names), tuple(self.ignored), tuple(C),
               *(sp.sympify(generic[k]) for k in ("L", "D")),
               *(sp.ImmutableMatrix(generic[k]) for k in ("M", "Q", "constraints")))
        parts = _by_structure(key, values, lambda: self._reduce_generic(generic, names, I, K, q, v, C))
        self._r_generic = parts
        self._r_values = dict(values)
        self._r_parts = {k: _put(part, values) for k, part in parts.items()}

    def _reduce_generic(self, generic, names, I, K, q, v, C) -> dict:
        full = self.full
        qI, vI = [q[i] for i in I], [v[i] for i in I]
        p = [_drop(generic["p"][i], qI) for i in I]
        MII = sp.Matrix([[_drop(generic["M"][i, j], qI) for j in I] for i in I])
        rest = [e.xreplace(dict.fromkeys(vI, sp.Integer(0))) for e in p]
        # p = rest + M·v̇ term by term (never their difference: SymPy would merge round-off into a "term")
        affine = all(equal(p[a], rest[a] + sum(MII[a, b] * vI[b] for b in range(len(I)))) for a in range(len(I)))
        # each entry tidied on its own (small, cheap): sin² + cos² gone before the solve spreads it everywhere
        MII = MII.applyfunc(_tidy)
        rest = [_tidy(e) for e in rest]
        det = _tidy(MII.det(method="berkowitz"))
        if is_zero(det) or not affine:
            null = MII.nullspace()
            combo = ""
            if null:
                vec = null[0]
                combo = " the momenta " + " and ".join(f"p_{n}" for n, c in zip(self.ignored, vec) if c != 0) + \
                    " are not independent (∂²L/∂q̇² is singular on these coordinates)."
            raise ReductionError(
                f"the momentum equations p = C of model {full.name!r} cannot be solved for the velocities of "
                f"{', '.join(self.ignored)}:{combo or ' they are not linear in those velocities.'} Reduce fewer "
                f"coordinates (ignorable=[...]), or give every combination of them inertia."
            )
        if not K:
            raise ReductionError(
                f"every coordinate of model {full.name!r} is ignorable ({', '.join(self.ignored)}): the motion is "
                f"uniform and nothing is left to reduce to; simulate the full model (or keep one coordinate)."
            )
        # p_I = rest + M_II v_I (checked above) makes L = L|v_I=0 + restᵀ v_I + ½ v_Iᵀ M_II v_I exactly, so with
        # w = C − rest:  v_I = M_II⁻¹ w  and  R = C·v_I − L = ½ wᵀ M_II⁻¹ w − L|v_I=0  (no substitution into L)
        w = sp.Matrix([c - r for c, r in zip(C, rest)])
        adjugate = MII.adjugate().applyfunc(_tidy)
        rates = [_tidy(e / det) for e in adjugate * w]
        at = dict(zip(vI, rates))
        L = _drop(generic["L"], qI)
        R = _tidy((w.T * adjugate * w)[0, 0] / (2 * det) - L.xreplace(dict.fromkeys(vI, sp.Integer(0))))
        vK = [v[k] for k in K]
        lam = sp.Dummy("lambda")
        Lr = -R
        scaled = Lr.xreplace({s: lam * s for s in vK})
        parts = [scaled.xreplace({lam: 0}), sp.diff(scaled, lam).xreplace({lam: 0}),
                 sp.diff(scaled, lam, 2).xreplace({lam: 0}) / 2]
        quadratic = equal(Lr, parts[0] + parts[1] + parts[2])
        R = _terms(R)
        if quadratic:
            T, G, V = _terms(parts[2]), _terms(parts[1]), _terms(-parts[0])
        else:  # not quadratic in the velocities: no effective potential
            T, G, V = Lr - parts[0], sp.Integer(0), -parts[0]
        D = _drop(generic["D"], qI)
        Q = [_tidy(_drop(generic["Q"][k], qI).xreplace(at)) for k in K]
        constraints = [_drop(c, qI) for c in generic["constraints"]]
        return {
            "K": K, "I": I, "C": C, "rates": rates, "R": R, "T": T, "G": G, "V": V, "D": D, "Q": Q,
            "constraints": constraints, "quadratic": quadratic,
            "singular": _factors_vanishing(det), "det": det,
        }

    def _build_equations(self) -> Equations:
        parts = self._r_generic
        full_eq = self.full.eq
        keep = [i for i in range(len(full_eq.names))
                if i in parts["K"] or full_eq.names[i] in self._quadrature]
        coords = [full_eq.coordinates[i] for i in keep]
        Q = [sp.Integer(0)] * len(keep)
        quad = {}
        for row, i in enumerate(keep):
            if i in parts["K"]:
                Q[row] = parts["Q"][parts["K"].index(i)]
            else:
                quad[row] = parts["rates"][parts["I"].index(i)]
        return Equations.from_energies(coords, parts["T"], parts["V"], parts["G"], parts["D"], Q,
                                       parts["constraints"], full_eq.constraint_rate, quad, values=self._r_values)

    # -- what the reduction found --------------------------------------------------
    def _show(self, expr):
        return self.full.eq.display(expr)

    @property
    def routhian(self) -> sp.Expr:
        """``R = Σ C_i q̇_i − L`` with the ignorable velocities eliminated."""
        return self._show(self._r_parts["R"])

    @property
    def momenta(self) -> dict[str, sp.Expr]:
        """``{ignorable coordinate: C}``: the conserved momenta (symbols ``C_<name>`` unless given)."""
        return dict(zip(self.ignored, self._r_parts["C"]))

    @property
    def rates(self) -> dict[str, sp.Expr]:
        """``{ignorable coordinate: q̇_i = ∂R/∂C_i}`` in the remaining coordinates and the momenta."""
        return {n: self._show(r) for n, r in zip(self.ignored, self._r_parts["rates"])}

    @property
    def effective_potential(self) -> sp.Expr | None:
        """``V_eff``: ``R`` at zero remaining velocities (``None`` if ``−R`` is not quadratic in them)."""
        return self._show(self._r_parts["V"]) if self._r_parts["quadratic"] else None

    @property
    def gyroscopic(self) -> sp.Expr:
        """The part of ``−R`` linear in the remaining velocities (zero when the ignorable motion does not couple)."""
        return self._show(self._r_parts["G"])

    @property
    def singularities(self) -> list[sp.Expr]:
        """Expressions (in the remaining coordinates) whose zeros make ``∂²L/∂q̇_i²`` singular."""
        return [self._show(s) for s in self._r_parts["singular"]]

    def momenta_from(self, initial: Mapping[str, float] | None = None, velocity: Mapping[str, float] | None = None,
                     params: Mapping[str, float] | None = None) -> dict[str, float]:
        """The momenta ``p_i = ∂L/∂q̇_i`` of a full-model state (coordinates and velocities by name)."""
        eq = self.full.eq
        initial, velocity = dict(initial or {}), dict(velocity or {})
        for given in (initial, velocity):
            for name in given:
                if name not in eq.names:
                    raise UnknownNameError("coordinate", name, eq.names)
        values = {s: v for s, v in self.full._values(self._full_params(params), overrides=True).items()}
        point = {**{q: float(initial.get(n, 0.0)) for q, n in zip(eq.sym.q, eq.names)},
                 **{v: float(velocity.get(n, 0.0)) for v, n in zip(eq.sym.v, eq.names)}, t: 0.0}
        out = {}
        for n, i in zip(self.ignored, self._r_parts["I"]):
            out[n] = float(eq.generic()["p"][i].xreplace(values).xreplace(point))
        return out

    def _full_params(self, params: Mapping[str, float] | None) -> dict[str, float]:
        full_names = {s.name for s in self.full.parameters} | set(self.full.parameter_values)
        return {k: v for k, v in (params or {}).items() if k in full_names}

    # -- simulation --------------------------------------------------------------------
    def reconstructing(self, names: Sequence[str] | bool = True) -> "ReducedModel":
        """The same reduced model, also integrating the ignorable coordinates ``names`` by quadrature."""
        names = tuple(self.ignored if names is True else ([] if names is False else names))
        for n in names:
            if n not in self.ignored:
                raise UnknownNameError("ignorable coordinate (for reconstruct=)", n, self.ignored)
        names = tuple(n for n in self.ignored if n in names)
        if names == self._quadrature:
            return self
        if names not in self._siblings:
            self._siblings[names] = ReducedModel(self.full, self.ignored, _quadrature=names, _parent=self)
        return self._siblings[names]

    def simulate(self, t_end=10.0, *, initial=None, velocity=None, params=None, momenta=None,
                 reconstruct: bool | Sequence[str] | None = None, **kwargs) -> Result:
        """Integrate the reduced equations (see :meth:`lagrangian.Model.simulate` for the options).

        ``momenta`` gives ``C`` by ignorable coordinate; otherwise the
        ignorable coordinates' velocities in ``velocity`` (a full-model
        state) give them.  ``reconstruct=True`` (or a list of names) also
        integrates the ignorable coordinates by quadrature, starting from
        their values in ``initial``; ``False`` integrates none; by default,
        those of :meth:`reconstructing` (none for :func:`reduce`'s model).  A start on a singular set of the
        reduction (``singularities``) with a nonzero momentum is refused.
        """
        initial, velocity = dict(initial or {}), dict(velocity or {})
        params = dict(params or {})
        momenta = dict(momenta or {})
        for n in momenta:
            if n not in self.ignored:
                raise UnknownNameError("ignorable coordinate (for momenta=)", n, self.ignored)
        from_state = [n for n in self.ignored if n in velocity]
        if from_state:
            clash = [n for n in from_state if n in momenta]
            if clash:
                raise ReductionError(
                    f"both a velocity and a momentum were given for {', '.join(clash)}: give one or the other."
                )
            momenta.update({n: value for n, value in self.momenta_from(initial, velocity, params).items() if n in from_state})
        for n, C in zip(self.ignored, self._r_parts["C"]):
            if isinstance(C, sp.Symbol) and C.name.startswith("C_"):
                if n in momenta:
                    params[C.name] = momenta[n]
                elif C.name not in params:
                    raise ReductionError(
                        f"the momentum of ignorable coordinate {n!r} has no value: give momenta={{{n!r}: ...}}, "
                        f"params={{{C.name!r}: ...}}, or its velocity in velocity= (a full-model state)."
                    )
        target = self if reconstruct is None else self.reconstructing(reconstruct)
        keep = set(target.coordinate_names)
        start = {k: val for k, val in initial.items() if k in keep}
        speed = {k: val for k, val in velocity.items() if k in keep and k not in self.ignored}
        dropped = [k for k in list(initial) + list(velocity) if k not in keep and k not in self.ignored
                   and k not in self.full.eq.names]
        if dropped:
            raise UnknownNameError("coordinate", dropped[0], self.full.eq.names)
        target._check_singular(start, params)
        known = {s.name for s in target.parameters} | set(target.parameter_values)
        unknown = [k for k in params if k not in known and k not in {s.name for s in self.full.parameters}]
        if unknown:
            raise UnknownNameError("parameter", unknown[0], known)
        params = {k: v for k, v in params.items() if k in known}
        return Model.simulate(target, t_end, initial=start, velocity=speed, params=params, **kwargs)

    def _check_singular(self, initial: Mapping[str, float], params: Mapping[str, float]) -> None:
        parts = self._r_parts
        if not parts["singular"]:
            return
        eq = self.full.eq
        values = {s: sp.Float(params[s.name]) for s in self.parameters if s.name in params}
        point = {eq.sym.q[k]: sp.Float(initial.get(eq.names[k], 0.0)) for k in parts["K"]}
        for s in parts["singular"]:
            value = s.xreplace(values).xreplace(point)
            if value.is_number and abs(float(value)) < 1e-12:
                moving = [n for n, C in zip(self.ignored, parts["C"]) if sp.sympify(C).xreplace(values) != 0]
                if moving:
                    raise ReductionError(
                        f"the initial state of {self.name!r} lies where {self._show(s)} = 0, a singularity of the "
                        f"reduction: with a nonzero momentum of {', '.join(moving)} the effective potential is "
                        f"infinite there (the motion cannot reach it). Start off that set, or with zero momentum."
                    )

    def quadrature(self, motion: "Mapping[str, Any] | SteadyMotion", initial: Mapping[str, Any] | None = None,
                   t0: Any = 0) -> dict[str, sp.Expr]:
        """The ignorable coordinates by symbolic quadrature, ``q_i(t) = q_i(t₀) + ∫ ∂R/∂C_i dt``.

        ``motion`` gives the remaining coordinates as SymPy expressions of
        ``t`` (or is a :class:`SteadyMotion`); ``initial`` the ignorable
        coordinates' values at ``t0`` (default symbols ``<name>_0``).  Where
        SymPy cannot integrate, the result holds an unevaluated ``Integral``.
        """
        eq = self.reconstructing(False).eq
        if isinstance(motion, SteadyMotion):
            motion = motion.coordinates
        motion = dict(motion)
        for n in motion:
            if n not in eq.names:
                raise UnknownNameError("remaining coordinate", n, eq.names)
        missing = [n for n in eq.names if n not in motion]
        if missing:
            raise ReductionError(f"quadrature needs the motion of every remaining coordinate; missing: {', '.join(missing)}.")
        tau = sp.Symbol("tau", real=True)
        path = {}
        for i, n in enumerate(eq.names):
            expr = as_expr(motion[n], f"the motion of {n!r}")
            path[eq.sym.q[i]] = expr.subs(t, tau)
            path[eq.sym.v[i]] = sp.diff(expr, t).subs(t, tau)
        out = {}
        initial = dict(initial or {})
        for n, rate in zip(self.ignored, self._r_parts["rates"]):
            start = as_expr(initial.get(n, sp.Symbol(f"{n}_0", real=True)), f"initial[{n!r}]")
            integrand = _tidy(rate.xreplace(path).subs(t, tau))
            out[n] = start + sp.integrate(integrand, (tau, t0, t))
        return out

    # -- steady motion -------------------------------------------------------------------
    def steady_conditions(self) -> list[sp.Eq]:
        """The conditions for steady motion: the reduced equations at zero remaining velocities (``∂R/∂q_k = 0``)."""
        return [sp.Eq(self._show(e), 0) for e in self._steady_exprs()]

    def _steady_exprs(self) -> list[sp.Expr]:
        eq = self.reconstructing(False).eq
        if len(eq.constraints):
            raise ReductionError(f"steady motions of {self.name!r}: models with loop constraints are not supported.")
        rest = dict.fromkeys(eq.sym.v, sp.Integer(0))
        f = sp.ImmutableMatrix(eq.generic()["f"])
        parts = _by_structure(("steady", f), eq.values, lambda: {"exprs": [_tidy(e.xreplace(rest)) for e in f]})
        out = _put(parts["exprs"], eq.values)
        if any(e.has(t) for e in out):
            raise ReductionError(
                f"the reduced equations of {self.name!r} depend explicitly on time: there is no steady motion."
            )
        return out

    def steady_motions(self, solve_for: Sequence[str] | None = None, *, params: Mapping[str, float] | None = None,
                       momenta: Mapping[str, float] | None = None,
                       search: Mapping[str, tuple[float, float]] | None = None,
                       budget: float | None = DEFAULT_SECONDS) -> list["SteadyMotion"]:
        """Every steady motion (all branches): the remaining coordinates constant, the ignorable ones uniform.

        Symbolically, ``solve_for`` names the unknowns — remaining
        coordinates (default), momenta ``C_<name>`` or parameters — and the
        other quantities stay symbols (a coordinate not solved for becomes a
        symbol ``<name>_0``).  With ``params`` and ``momenta`` giving every
        value, the coordinates are found numerically when SymPy cannot
        solve: all roots of the conditions in ``search`` ranges (default
        ``(−π, π)`` for joint angles), by bracketing in one coordinate and
        by Newton from a grid of starts in several.

        The symbolic solve runs under a budget of ``budget`` seconds (``None``:
        none); past it a :class:`~lagrangian.ReductionError` says what to
        give instead (numeric values, a search range, fewer unknowns).
        """
        eq = self.reconstructing(False).eq
        names = eq.names
        q = eq.sym.q
        exprs = self._steady_exprs()
        values = self._values_for(params, momenta)
        exprs = [e.xreplace(values) for e in exprs]
        unknowns_names = list(solve_for) if solve_for is not None else list(names)
        lookup = {n: q[i] for i, n in enumerate(names)}
        lookup.update({C.name: C for C in self._r_parts["C"] if isinstance(C, sp.Symbol)})
        lookup.update({s.name: s for s in self.parameters})
        unknowns = []
        for n in unknowns_names:
            if n not in lookup:
                raise UnknownNameError("unknown to solve for", n, lookup)
            unknowns.append(lookup[n])
        rest = {q[i]: sp.Symbol(f"{n}_0", real=True) for i, n in enumerate(names) if q[i] not in unknowns}
        exprs = [e.xreplace(rest) for e in exprs]
        free = set().union(*(e.free_symbols for e in exprs)) - set(unknowns)
        numeric = solve_for is None and not free
        unfolded = [e.replace(sp.Abs, lambda x: x).replace(sp.sign, lambda x: sp.Integer(1)) for e in exprs]
        rational = all(e.is_rational_function(*unknowns) for e in unfolded)
        branches = None
        if rational or not numeric:
            try:
                branches = within(_solve, exprs, unknowns, seconds=budget)
            except BudgetExceeded:
                if not numeric:
                    raise ReductionError(
                        f"SymPy did not solve the steady-motion conditions of {self.name!r} for "
                        f"{', '.join(unknowns_names)} within the budget of {budget:g} s: give numeric params= and "
                        f"momenta= so the coordinates are found numerically (in search= ranges), solve for fewer "
                        f"unknowns, or raise budget=."
                    ) from None
                # every value is known: the coordinates are found numerically instead
        if branches is None:
            if not numeric:
                raise ReductionError(
                    f"SymPy cannot solve the steady-motion conditions of {self.name!r} for "
                    f"{', '.join(unknowns_names)}; give numeric params= and momenta= to solve them numerically."
                )
            branches = self._numeric_roots(exprs, names, q, search or {})
        for n, (lo, hi) in (search or {}).items():  # solved symbolically too: only what lies in the ranges asked
            if n not in lookup or lookup[n] not in q:
                raise UnknownNameError("remaining coordinate (for search=)", n, names)
            qi = lookup[n]
            branches = [sol for sol in branches if qi not in sol or not sol[qi].is_number
                        or float(lo) <= float(sol[qi]) <= float(hi)]
        out = []
        for sol in branches:
            coords = {}
            for i, n in enumerate(names):
                coords[n] = sol.get(q[i], rest.get(q[i]))
            fixed = {q[i]: coords[n] for i, n in enumerate(names)}
            others = {s: val for s, val in sol.items() if s not in q}
            C_values = {n: sp.sympify(C).xreplace(values).xreplace(others) for n, C in zip(self.ignored, self._r_parts["C"])}
            rates = {n: _tidy(r.xreplace(values).xreplace(others).xreplace(fixed).xreplace(dict.fromkeys(eq.sym.v, 0)))
                     for n, r in zip(self.ignored, self._r_parts["rates"])}
            out.append(SteadyMotion(self, coords, C_values, rates, dict(values) | others))
        return out

    def _values_for(self, params, momenta) -> dict[sp.Symbol, sp.Expr]:
        params, momenta = dict(params or {}), dict(momenta or {})
        out: dict[sp.Symbol, sp.Expr] = {}
        known = {s.name: s for s in self.parameters}
        for n, val in momenta.items():
            if n not in self.ignored:
                raise UnknownNameError("ignorable coordinate (for momenta=)", n, self.ignored)
            C = self._r_parts["C"][self.ignored.index(n)]
            if isinstance(C, sp.Symbol):
                out[C] = sp.nsimplify(val) if val == 0 else sp.Float(val)
        for k, val in params.items():
            if k not in known:
                raise UnknownNameError("parameter", k, known)
            out[known[k]] = sp.Float(val)
        return out

    def _numeric_roots(self, exprs, names, q, search) -> list[dict]:
        from scipy.optimize import brentq, root

        ranges = []
        for i, n in enumerate(names):
            if n in search:
                lo, hi = map(float, search[n])
            elif _is_angle(self.eq.coordinates[i]):
                lo, hi = -math.pi, math.pi
            else:
                raise ReductionError(
                    f"give a search range for coordinate {n!r} of {self.name!r}: steady_motions(..., search={{{n!r}: (lo, hi)}})."
                )
            ranges.append((lo, hi))
        fn = sp.lambdify([q], exprs, modules="numpy")
        found: list[np.ndarray] = []
        if len(q) == 1:
            lo, hi = ranges[0]
            grid = np.linspace(lo, hi, 4001)
            with np.errstate(all="ignore"):
                vals = np.array([fn([x])[0] for x in grid], dtype=float)
            for a, b, fa, fb in zip(grid[:-1], grid[1:], vals[:-1], vals[1:]):
                if not (np.isfinite(fa) and np.isfinite(fb)):
                    continue
                if fa == 0:
                    found.append(np.array([a]))
                elif fa * fb < 0:
                    x = brentq(lambda s: fn([s])[0], a, b, xtol=1e-14, rtol=1e-14)
                    scale = max(abs(fa), abs(fb))
                    with np.errstate(all="ignore"):
                        if abs(fn([x])[0]) < 1e-8 * max(1.0, scale):  # a root, not a pole
                            found.append(np.array([x]))
        else:
            jac = sp.lambdify([q], sp.Matrix(exprs).jacobian(q), modules="numpy")
            axes = [np.linspace(lo, hi, 9) for lo, hi in ranges]
            for start in np.array(np.meshgrid(*axes)).reshape(len(q), -1).T:
                with np.errstate(all="ignore"):
                    sol = root(lambda x: np.asarray(fn(x), dtype=float), start,
                               jac=lambda x: np.asarray(jac(x), dtype=float), tol=1e-13)
                if sol.success and all(lo <= x <= hi for x, (lo, hi) in zip(sol.x, ranges)):
                    found.append(sol.x)
        unique: list[np.ndarray] = []
        for x in found:
            if not any(np.allclose(x, y, atol=1e-9) for y in unique):
                unique.append(x)
        return [{qi: sp.Float(float(xi)) for qi, xi in zip(q, x)} for x in unique]


def _is_angle(coordinate) -> bool:
    text = f"{coordinate.name} {coordinate.description}".lower()
    return any(w in text for w in ("angle", "revolute", "theta", "phi", "alpha", "beta", "gamma"))


def _solve(exprs: list[sp.Expr], unknowns: list[sp.Symbol]) -> list[dict] | None:
    """All real solutions SymPy finds, or None when it cannot solve.

    ``|x|`` and ``sign(x)`` of an unknown (a distance ``√(s²)``) are split into their two
    branches, each solved, and the solutions kept where the branch's sign holds.
    """
    folds = sorted({a.args[0] for e in exprs for a in e.atoms(sp.Abs, sp.sign) if a.args[0].free_symbols & set(unknowns)},
                   key=sp.default_sort_key)
    if folds and len(folds) <= 3:
        out = []
        for signs in itertools.product((1, -1), repeat=len(folds)):
            rule = {}
            for x, sgn in zip(folds, signs):
                rule[sp.Abs(x)] = sgn * x
                rule[sp.sign(x)] = sp.Integer(sgn)
            branch = _solve([e.xreplace(rule) for e in exprs], unknowns)
            if branch is None:
                return None
            for sol in branch:
                if any((sgn * x.xreplace(sol)).is_negative for x, sgn in zip(folds, signs)):
                    continue
                if sol not in out:
                    out.append(sol)
        return out
    try:
        sols = sp.solve(exprs, unknowns, dict=True)
    except (NotImplementedError, ValueError, TypeError):
        return None
    if not sols and any(e.free_symbols for e in exprs):
        return None if any(not e.is_rational_function(*unknowns) for e in exprs) else []
    out = []
    for sol in sols:
        if any(val.is_real is False for val in sol.values()):
            continue
        if any(val.has(sp.I) and val.is_number and abs(sp.im(sp.N(val))) > 1e-12 for val in sol.values()):
            continue
        out.append({k: (sp.re(v) if v.is_number else v) for k, v in sol.items()})
    return out


def reduce(model: Model, ignorable: Sequence[str] | None = None, momenta: Mapping[str, Any] | None = None) -> ReducedModel:
    """Eliminate ignorable coordinates of ``model`` through the Routhian; return the :class:`ReducedModel`.

    ``ignorable`` names the coordinates to eliminate (default: every
    ignorable one, see :func:`ignorability`); ``momenta`` gives values or
    expressions for their momenta (default: symbols ``C_<name>``).  A
    coordinate that is not ignorable, or momentum equations that cannot be
    solved for the ignorable velocities (a singular ``∂²L/∂q̇²``), raise
    :class:`~lagrangian.ReductionError` saying why.
    """
    report = ignorability(model)
    if ignorable is None:
        ignorable = [n for n, r in report.items() if r.ignorable]
        if not ignorable:
            why = "; ".join(f"{r.coordinate}: {r.reason}" for r in report.values())
            raise ReductionError(f"model {model.name!r} has no ignorable coordinate ({why}).")
    else:
        ignorable = [ignorable] if isinstance(ignorable, str) else list(ignorable)
        for n in ignorable:
            if n not in report:
                raise UnknownNameError("coordinate", n, report)
            if not report[n].ignorable:
                raise ReductionError(f"coordinate {n!r} of model {model.name!r} is not ignorable: {report[n].reason}.")
    return ReducedModel(model, ignorable, momenta)


# -- steady motion and its stability ------------------------------------------------------------------


@dataclass
class Perturbation:
    """Linearized equations about a steady motion: ``M s̈ + C ṡ + K s = 0`` (``s = q − q₀``)."""

    M: sp.Matrix
    C: sp.Matrix
    K: sp.Matrix
    names: list[str]

    @property
    def equations(self) -> list[sp.Eq]:
        """One ``Eq(M s̈ + C ṡ + K s, 0)`` per remaining coordinate, in functions ``s_<name>(t)``."""
        s = sp.Matrix([sp.Function(f"s_{n}")(t) for n in self.names])
        lhs = self.M * s.diff(t, 2) + self.C * s.diff(t) + self.K * s
        return [sp.Eq(_tidy(e), 0) for e in lhs]

    @property
    def frequency_squared(self) -> sp.Expr:
        """One coordinate, no velocity terms: ``ω² = K / M`` of ``s̈ + ω² s = 0``."""
        if len(self.names) != 1 or self.C[0, 0] != 0:
            raise ReductionError("frequency_squared is defined for one coordinate without velocity terms; use eigenvalues.")
        return sp.simplify(self.K[0, 0] / self.M[0, 0])


@dataclass
class Stability:
    """The verdict on a steady motion from the linearized reduced equations, cross-checked with ``V_eff``."""

    verdict: str  # "stable", "asymptotically stable", "unstable" or "marginal"
    eigenvalues: np.ndarray
    frequencies: np.ndarray  # angular frequencies of the oscillatory modes (rad/s, ascending)
    curvature: np.ndarray | None  # eigenvalues of the Hessian of V_eff at the steady motion
    reason: str

    def __str__(self) -> str:
        return f"{self.verdict}: {self.reason}"


@dataclass
class SteadyMotion:
    """One steady motion: constant remaining coordinates, constant momenta and ignorable rates."""

    model: ReducedModel = field(repr=False)
    coordinates: dict[str, sp.Expr]
    momenta: dict[str, sp.Expr]
    rates: dict[str, sp.Expr]
    values: dict[sp.Symbol, sp.Expr] = field(default_factory=dict, repr=False)

    def __str__(self) -> str:
        parts = [f"{k} = {v}" for k, v in self.coordinates.items()]
        parts += [f"C_{k} = {v}" for k, v in self.momenta.items() if v != sp.Symbol(f"C_{k}", real=True)]
        parts += [f"{k}' = {v}" for k, v in self.rates.items()]
        return "steady motion: " + ", ".join(parts)

    def perturbation(self) -> Perturbation:
        """``M s̈ + C ṡ + K s = 0`` about this steady motion (symbolic where the steady motion is)."""
        eq = self.model.reconstructing(False).eq
        q, v = eq.sym.q, eq.sym.v
        at = {q[i]: self.coordinates[n] for i, n in enumerate(eq.names)} | dict.fromkeys(v, sp.Integer(0))
        subs = self._substitutions()
        f = eq.f.xreplace(subs)
        M = eq.M.xreplace(subs)
        K = (-f.jacobian(q)).xreplace(at).applyfunc(_off_singular)
        Cm = (-f.jacobian(v)).xreplace(at).applyfunc(_off_singular)
        return Perturbation(M.xreplace(at).applyfunc(_off_singular), Cm, K, list(eq.names))

    def _substitutions(self) -> dict:
        subs = dict(self.values)
        for n, C in zip(self.model.ignored, self.model._r_parts["C"]):
            if isinstance(C, sp.Symbol):
                subs[C] = self.momenta[n]
        return subs

    def stability(self, values: Mapping[str, float] | None = None) -> Stability:
        """Linear stability: eigenvalues of the perturbation equations, with a verdict.

        ``values`` gives numbers to whatever is still symbolic (parameters,
        momenta ``C_<name>``, coordinate symbols ``<name>_0``).  The verdict
        is *unstable* if an eigenvalue has a positive real part,
        *asymptotically stable* if all are negative, *marginal* when an
        eigenvalue is zero (a bifurcation: the linearization cannot decide)
        or when the oscillation is only gyroscopically stabilized (the
        effective potential is not a minimum), and *stable* when every mode
        oscillates and ``V_eff`` has a strict minimum there (the energy
        integral then bounds the perturbation).
        """
        pert = self.perturbation()
        needed = {str(s) for m in (pert.M, pert.C, pert.K) for s in m.free_symbols}
        names = {str(s): s for e in [*self.coordinates.values(), *self.momenta.values(), pert.M, pert.C, pert.K]
                 for s in sp.sympify(e).free_symbols}
        given = dict(values or {})
        unknown = [k for k in given if k not in names]
        if unknown:
            raise UnknownNameError("symbol", unknown[0], names)
        missing = sorted(needed - set(given))
        if missing:
            raise ReductionError(f"the steady motion is symbolic in {', '.join(missing)}: give values=... for them.")
        subs = {names[k]: float(val) for k, val in given.items()}
        try:
            M, Cm, K = (np.array(m.xreplace(subs).evalf(), dtype=float) for m in (pert.M, pert.C, pert.K))
        except TypeError:
            raise ReductionError("the perturbation equations are not finite at this steady motion (a singular point of the reduction).") from None
        if not (np.all(np.isfinite(M)) and np.all(np.isfinite(K)) and np.all(np.isfinite(Cm))):
            raise ReductionError("the perturbation equations are not finite at this steady motion (a singular point of the reduction).")
        n = len(pert.names)
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, Cm)]])
        lam = np.linalg.eigvals(A)
        # Tolerances relative to the spectrum (1/s) and to the curvature (energy/coordinate²) separately: a
        # zero eigenvalue of a double root (a Jordan block) comes out of eigvals only to about √ε of the scale.
        scale = float(np.max(np.abs(lam))) if lam.size else 0.0
        tol = 1e-7 * scale
        curvature = None
        if self.model._r_parts["quadratic"]:
            eq = self.model.reconstructing(False).eq
            Veff = eq.V.xreplace(self._substitutions())
            at = {eq.sym.q[i]: self.coordinates[nm] for i, nm in enumerate(eq.names)}
            H = sp.hessian(Veff, eq.sym.q).xreplace(at).xreplace(subs)
            try:
                curvature = np.linalg.eigvalsh(np.array(H.evalf(), dtype=float))
            except TypeError:
                curvature = None
        minimum = curvature is not None and bool(np.all(curvature > 1e-9 * float(np.max(np.abs(curvature)))))
        freqs = np.sort(np.abs(lam.imag[lam.imag > tol]))
        gyroscopic = not is_zero(self.model._r_parts["G"])
        if scale > 0.0 and np.any(lam.real > tol):
            verdict, reason = "unstable", f"an eigenvalue with positive real part ({_fmt(lam[np.argmax(lam.real)])})"
        elif scale == 0.0 or np.any(np.abs(lam) <= tol):
            verdict, reason = "marginal", ("a zero eigenvalue: the linearization cannot decide (a bifurcation point of "
                                           "the steady motions, or a neutral direction); the nonlinear terms do")
        elif np.all(lam.real < -tol):
            verdict, reason = "asymptotically stable", "every eigenvalue has a negative real part"
        elif minimum:
            verdict = "stable"
            reason = ("every mode oscillates and the effective potential has a strict minimum (curvature "
                      f"{', '.join(f'{c:.6g}' for c in curvature)}): the energy integral bounds the motion")
        elif curvature is None:
            verdict = "marginal"
            reason = ("the linearized motion oscillates without growth, but the reduced Lagrangian is not quadratic in "
                      "the velocities, so no effective potential bounds the motion: linear analysis is inconclusive")
        elif gyroscopic:
            verdict = "marginal"
            reason = ("the linearized motion oscillates without growth, but the effective potential is not a minimum "
                      f"(curvature {', '.join(f'{c:.6g}' for c in curvature)}; gyroscopic stabilization): linear "
                      "analysis is inconclusive for the full motion")
        else:
            verdict = "marginal"
            reason = ("the linearized motion oscillates without growth, but the effective potential is not a strict "
                      f"minimum (curvature {', '.join(f'{c:.6g}' for c in curvature)}): linear analysis is inconclusive")
        if curvature is not None and verdict == "unstable" and minimum and is_zero(self.model.eq.D):
            reason += "; the effective potential has a minimum there, yet a mode grows (non-conservative forces)"
        return Stability(verdict, lam, freqs, curvature, reason)


def _off_singular(expr: sp.Expr) -> sp.Expr:
    """Tidy a linearization evaluated at a steady motion, which lies off the singular set of the
    reduction: there ``DiracDelta`` (from differentiating ``|x|`` twice) vanishes and
    ``sign(x)`` of a nonnegative ``x`` is 1."""
    expr = sp.sympify(expr).replace(sp.DiracDelta, lambda *a: sp.Integer(0))
    expr = expr.replace(lambda e: isinstance(e, sp.sign) and e.args[0].is_nonnegative, lambda e: sp.Integer(1))
    return _tidy(expr)


def _fmt(z: complex) -> str:
    return f"{z.real:.6g}{z.imag:+.6g}j" if abs(z.imag) > 0 else f"{z.real:.6g}"


# -- the Jacobi integral ----------------------------------------------------------------------------


@dataclass
class JacobiIntegral:
    """``h = Σ q̇ ∂L/∂q̇ − L`` of a model, whether it is conserved, and how it differs from ``T + V``."""

    model: Model = field(repr=False)
    expr: sp.Expr  # h, in q(t), q̇(t)
    energy: sp.Expr  # T + V
    difference: sp.Expr  # h − (T + V)
    conserved: bool
    reasons: list[str]

    @property
    def energy_conserved(self) -> bool:
        """Whether the total energy ``T + V`` is conserved too (``h`` conserved and equal to it)."""
        return self.conserved and self.difference == 0

    def __str__(self) -> str:
        state = "conserved" if self.conserved else "not conserved"
        same = "equal to the total energy T + V" if self.difference == 0 else f"h − (T + V) = {sp.sstr(self.difference)}"
        return f"Jacobi integral h = {sp.sstr(self.expr)}: {state} ({'; '.join(self.reasons)}); {same}"

    def values(self, result: Result) -> np.ndarray:
        """``h`` along a simulation of the model."""
        return result.quantity(self.expr)

    def drift(self, result: Result) -> float:
        """Largest change of ``h`` along ``result``, relative to ``max(|h₀|, max T)``."""
        h = self.values(result)
        scale = max(abs(float(h[0])), float(np.max(np.abs(result.T))), 1e-300)
        return float(np.max(np.abs(h - h[0]))) / scale


def _without_residues(expr: sp.Expr, reference: sp.Expr) -> sp.Expr:
    """``expr`` without the terms that are round-off residues (dropping them keeps it equal to ``reference``)."""
    terms = list(sp.Add.make_args(expr))
    if len(terms) > 50:
        return expr
    for term in sorted(terms, key=lambda e: min((abs(float(f)) for f in e.atoms(sp.Float)), default=math.inf)):
        if not term.atoms(sp.Float):
            break
        rest = [e for e in terms if e is not term]
        if equal(sp.Add(*rest), reference):
            terms = rest
    return sp.Add(*terms)


def jacobi_integral(model: Model) -> JacobiIntegral:
    """The Jacobi integral ``h = Σ q̇ ∂L/∂q̇ − L`` of ``model`` and whether it is conserved.

    ``dh/dt = −∂L/∂t + Σ Q q̇ − Σ q̇ ∂D/∂q̇``: ``h`` is conserved exactly
    when ``L`` does not depend explicitly on time, nothing dissipates, no
    generalized force acts and the constraints do not move.  It equals the
    total energy ``T + V`` for a scleronomic natural system; for a
    rheonomic one (a support moved at constant speed) it is the energy seen
    riding along, and ``T + V`` is not conserved.

    >>> import lagrangian as lg
    >>> m = lg.Model("oscillator")
    >>> _ = m.add("mass", "m", "p", m=2)
    >>> _ = m.add("spring", "k", ("ground", "p"), k=3)
    >>> h = jacobi_integral(m)
    >>> h.conserved, h.energy_conserved, h.expr
    (True, True, 3*x_p(t)**2/2 + Derivative(x_p(t), t)**2)
    """
    eq = model.eq
    generic = eq.generic()

    def integral() -> dict:  # on the generic energies, once per structure; the values go in after
        h = sp.Add(*[vi * pi for vi, pi in zip(eq.sym.v, generic["p"])]) - generic["L"]
        E = generic["T"] + generic["V"]
        h = _tidy(sp.expand(h), 2000)
        if equal(h, E):
            return {"h": _without_residues(h, E), "E": E, "diff": sp.Integer(0)}
        return {"h": h, "E": E, "diff": _tidy(sp.expand(h - E), 2000)}

    parts = _by_structure(("jacobi", tuple(eq.sym.v), generic["L"], generic["T"], generic["V"]), eq.values, integral)
    h, E, diff = (_put(parts[k], eq.values) for k in ("h", "E", "diff"))
    reasons = []
    if _depends(eq, eq.L, t):
        moving = [name for name, c in model.assembly.contributions.items()
                  if any(_depends(eq, eq.symbolic(sp.sympify(getattr(c, part))), t) for part in ("T", "V", "G"))]
        reasons.append(f"L depends explicitly on time (through {_named(moving)})")
    if not is_zero(eq.D):
        reasons.append(f"energy dissipates (D from {_named([n for n, c in model.assembly.contributions.items() if sp.sympify(c.D) != 0])})")
    if any(not is_zero(e) for e in eq.Q):
        forced = [c for c, share in eq.load_shares if any(not is_zero(e) for e in share)]
        reasons.append(f"generalized forces act (from {_named(forced)})")
    if any(_depends(eq, c, t) for c in eq.constraints):
        reasons.append("a loop constraint moves with time")
    conserved = not reasons
    if conserved:
        reasons.append("L has no explicit time dependence and no dissipation, force or moving constraint acts")
    return JacobiIntegral(model, eq.display(h), eq.display(E), eq.display(diff), conserved, reasons)
