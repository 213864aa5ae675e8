"""The jump of the velocities: generalized impulses, Lagrange's equations for impulsive motion, contacts solved
as a complementarity problem with restitution (:func:`velocity_jump`, :func:`impact`).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...base.component import t
from ...errors import UnknownNameError
from ...base.text import as_expr
from .contacts import Contact, ContactError, GrazingImpactError, Impulse, Lock, SingularImpactError, _as_vector, _check_names, _position
from ...base import deferred as _deferred

sp = _deferred.module("sympy", globals())


def _applied(model, impulses) -> sp.Matrix:
    """``Q̂`` of the applied impulses (point impulses and per-coordinate ones) in plain symbols."""
    eq = model.eq
    n = len(eq.names)
    Q = sp.zeros(n, 1)
    if impulses is None:
        return Q
    if isinstance(impulses, (Impulse, Mapping)):
        impulses = [impulses]
    for item in impulses:
        if isinstance(item, Impulse):
            who = f"impulse at {item.point!r}"
            r = _position(model, item.point, who, generic=True)
            P = _as_vector(item.vector, r.rows, f"{who}: the impulse vector")
            Q += r.jacobian(eq.sym.q).T * P  # Q̂_k = P̂ · ∂r/∂q_k
        elif isinstance(item, Mapping):
            _check_names(model, item, "coordinate (generalized impulse)")
            for name, value in item.items():
                Q[eq.names.index(name)] += as_expr(value, f"the generalized impulse on {name!r}")
        else:
            raise ContactError(f"impulses are lagrangian.impulse.Impulse(point, vector) or {{coordinate: value}} mappings, got {item!r}.")
    return Q


def generalized_impulse(model, impulses, *, at: Mapping[str, Any] | None = None, params: Mapping[str, Any] | None = None,
                        coordinates: Mapping[str, Any] | None = None) -> dict[str, sp.Expr]:
    """The generalized impulses ``Q̂_k = Σ P̂ · ∂r/∂q_k`` of ``impulses`` (a list of :class:`Impulse` and/or
    ``{coordinate: value}`` mappings), by coordinate name, in terms of the coordinates ``q(t)`` (or of the
    values given in ``at``; ``params`` substitutes parameters by name).

    ``coordinates`` expresses them in other generalized coordinates: it gives each model coordinate as a
    function of the new ones (SymPy symbols), and the result is keyed by the new symbols' names,
    ``Q̂_ξ = Σ_k Q̂_k ∂q_k/∂ξ`` (the virtual impulsive work of one δξ at a time).

    >>> import lagrangian as lg
    >>> m = lg.Model("pendulum", dim=2)
    >>> _ = m.add("link", "arm", "arm", points={"bob": (2, 0)})
    >>> _ = m.add("revolute", "pin", ("ground", "arm"), absolute=True)
    >>> _ = m.add("mass", "m", "arm.bob", m=1)
    >>> generalized_impulse(m, [Impulse("arm.bob", (1, 0))])
    {'theta_pin': -2*sin(theta_pin(t))}
    """
    eq = model.eq
    Q = _applied(model, impulses)
    subs = _substitution(model, at or {}, {}, params or {}, None)
    Q = Q.xreplace(subs)
    if coordinates is None:
        return {n: eq.display(x) for n, x in zip(eq.names, Q)}
    _check_names(model, coordinates, "coordinate")
    missing = [n for n in eq.names if n not in coordinates]
    if missing:
        raise ContactError(f"`coordinates` must give every model coordinate in terms of the new ones; missing: {', '.join(missing)}.")
    exprs = [as_expr(coordinates[n], f"coordinates[{n!r}]") for n in eq.names]
    new = sorted(set().union(*(e.free_symbols for e in exprs)) - set(_param_symbols(model)) - {t}, key=str)
    back = {s: e for s, e in zip(eq.sym.q, exprs)}
    Q = Q.applyfunc(lambda x: eq.symbolic(x).xreplace(back))
    return {s.name: sp.simplify(sum(Q[k] * exprs[k].diff(s) for k in range(len(exprs)))) for s in new}


def _param_symbols(model) -> list[sp.Symbol]:
    return list(model.parameters)


def _geometry_symbols(model) -> list[sp.Symbol]:
    """Symbols the user gave in components' parameters (a point's position along a body, say) that the
    equations may not contain: contacts and impulses at those points still need their values."""
    out: set[sp.Symbol] = set()

    def walk(value):
        if isinstance(value, dict):
            for item in value.values():
                walk(item)
        elif isinstance(value, (sp.Basic, sp.MatrixBase)):
            out.update(s for s in value.free_symbols if isinstance(s, sp.Symbol) and s != t)

    for comp in model.components.values():
        walk(comp.params)
    return sorted(out, key=lambda s: s.name)


def _substitution(model, at, velocity, params, time) -> dict:
    """Values for the plain symbols: given coordinates, velocities (0 when absent), parameters by name, time.  The
    parameters given as numbers are symbols in what :class:`_Setup` holds: their values go in here, or those
    ``params`` gives them by name."""
    eq = model.eq
    _check_names(model, at, "coordinate")
    _check_names(model, velocity, "coordinate")
    subs: dict = {}
    for q, name in zip(eq.sym.q, eq.names):
        subs[q] = as_expr(at[name], f"at[{name!r}]") if name in at else eq.display(q)
    for v, name in zip(eq.sym.v, eq.names):
        subs[v] = as_expr(velocity.get(name, 0), f"velocity[{name!r}]")
    values = eq.values  # the parameters given as numbers: their values unless params gives others
    subs.update(values)
    by_name: dict[str, list] = {}
    for s in [*model.parameters, *_geometry_symbols(model), *values]:  # also symbols only in points (where impulses act)
        if s not in by_name.get(s.name, []):
            by_name.setdefault(s.name, []).append(s)
    for name, value in params.items():
        if name not in by_name:
            raise UnknownNameError("parameter", name, by_name)
        for s in by_name[name]:
            subs[s] = as_expr(value, f"params[{name!r}]")
    if time is not None:
        subs[t] = as_expr(time, "time")
    return subs


# -- the jump --------------------------------------------------------------------------------------


@dataclass
class Jump:
    """The outcome of an impulse, impact or sudden constraint at one instant (coordinates unchanged).

    ``before`` and ``after``: generalized velocities q̇⁻, q̇⁺ by coordinate; ``generalized``: the total
    generalized impulse ``Δp = M Δq̇`` (applied + contact + constraint impulses); ``impulses``: each
    contact's normal impulse ``Λ ≥ 0`` (a sudden constraint: the tuple of its rows' impulses);
    ``normal_before`` / ``normal_after``: each contact's normal velocity ġ⁻, ġ⁺; ``T_before``, ``T_after``:
    kinetic energy; ``exact``: SymPy results (something was symbolic or every input exact) rather than floats;
    ``notes``: what the solution wants known (contacts that separated, redundant contacts).
    """

    before: dict[str, Any]
    after: dict[str, Any]
    generalized: dict[str, Any]
    impulses: dict[str, Any]
    normal_before: dict[str, Any]
    normal_after: dict[str, Any]
    T_before: Any
    T_after: Any
    exact: bool
    notes: list[str] = field(default_factory=list)

    @property
    def energy_lost(self):
        """``T⁻ − T⁺`` (negative when applied impulses do work)."""
        lost = self.T_before - self.T_after
        return sp.simplify(lost) if self.exact else lost

    def change(self, name: str):
        """``q̇⁺ − q̇⁻`` of one coordinate."""
        if name not in self.after:
            raise UnknownNameError("coordinate", name, self.after)
        d = self.after[name] - self.before[name]
        return sp.simplify(d) if self.exact else d


class _Setup:
    """Everything of an impulse problem in the plain symbols of ``model.eq``, with the parameters given as numbers
    still the symbols standing for them (``eq.generic()``): who solves it puts in the values, those of ``params=``
    included."""

    def __init__(self, model, contacts=(), impulses=None):
        eq = self.eq = model.eq
        self.model = model
        q = eq.sym.q
        self.contacts = [c for c in contacts if isinstance(c, Contact)]
        self.locks = [c for c in contacts if isinstance(c, Lock)]
        bad = [c for c in contacts if not isinstance(c, (Contact, Lock))]
        if bad:
            raise ContactError(
                f"{bad[0]!r} is not a contact or sudden constraint: make contacts with ground(), wall(), plane() or "
                f"between(), sudden constraints with fix() or lock() (lagrangian.impulse)."
            )
        names = [c.name for c in contacts]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ContactError(f"two contacts are named {dup[0]!r}: give them distinct names (name=...).")
        self.Q = _applied(model, impulses)
        if eq.first_order:
            raise ContactError(
                f"coordinates {', '.join(eq.names[i] for i in eq.first_order)} of model {model.name!r} have no inertia: "
                f"an impulse would change their velocity without bound. Give them inertia (a mass, an inductor)."
            )
        generic = eq.generic()
        self.M, self.T = generic["M"], generic["T"]
        self.gaps = [sp.sympify(eq.symbolic(c.gap(model, generic=True))) for c in self.contacts]
        self.W = sp.Matrix.hstack(*[sp.Matrix([g.diff(s) for s in q]) for g in self.gaps]) if self.gaps else sp.zeros(len(q), 0)
        self.gt = sp.Matrix([g.diff(t) for g in self.gaps]) if self.gaps else sp.zeros(0, 1)
        rows, rhs = [], []
        self.Phi = Phi = generic["constraints"]
        if len(Phi):
            rows.append(Phi.jacobian(q))
            rhs.append(Phi.diff(t))
        if len(generic["velocity_constraints"]):  # A(q, t) q̇ + b(q, t) = 0 holds after the blow as before it
            c = generic["velocity_constraints"]
            rows.append(c.jacobian(eq.sym.v))
            rhs.append(c.xreplace({x: sp.Integer(0) for x in eq.sym.v}))
        self.lock_rows = []
        for lk in self.locks:
            J, b = lk.rows(model, generic=True)
            keep = [k for k in range(J.rows) if any(x != 0 for x in J.row(k))]
            self.lock_rows.append((lk.name, len(keep)))
            rows.append(J.extract(keep, list(range(J.cols))) if keep else sp.zeros(0, len(q)))
            rhs.append(b.extract(keep, [0]) if keep else sp.zeros(0, 1))
        self.C = sp.Matrix.vstack(*rows) if rows else sp.zeros(0, len(q))
        self.c = sp.Matrix.vstack(*rhs) if rhs else sp.zeros(0, 1)
        self.holonomic = len(Phi)
        self.loops = self.holonomic + len(generic["velocity_constraints"])
        self.e = [c.e for c in self.contacts]

    def row_owner(self, k: int) -> str:
        if k < self.holonomic:
            return "the loop-closure constraints"
        if k < self.loops:
            return "the constraints on velocities"
        k -= self.loops
        for name, count in self.lock_rows:
            if k < count:
                return f"sudden constraint {name!r}"
            k -= count
        return "a constraint"  # pragma: no cover


def _numbers(*mats) -> bool:
    return all(all(x.is_number and x.is_real is not False for x in m) for m in mats)


def _arr(x: sp.Matrix) -> np.ndarray:
    return np.array(x.tolist(), dtype=float).reshape(x.shape) if x.rows * x.cols else np.zeros(x.shape)


def _resolve(setup: _Setup, subs: dict, approaching_only: bool, simplify: bool) -> Jump:
    """Solve the jump at the substituted configuration: numerically (with the active-set LCP) when every
    entry is a number, exactly (SymPy) when something is symbolic or every number is exact."""
    eq = setup.eq
    names, contacts = eq.names, [c.name for c in setup.contacts]
    M, W, gt, C, c, Q = (x.xreplace(subs) for x in (setup.M, setup.W, setup.gt, setup.C, setup.c, setup.Q))
    vb = sp.Matrix([subs[v] for v in eq.sym.v])
    e = sp.Matrix([sp.sympify(x).xreplace(subs) for x in setup.e])
    T_before = setup.T.xreplace(subs)
    mats = (M, W, gt, C, c, Q, vb, e)
    n, m, k = M.rows, C.rows, W.cols
    active, notes = list(range(k)), []
    if _numbers(*mats):
        va, lam, mu, notes, active = _solve_numeric(
            _arr(M), _arr(W), _arr(C), _arr(gt).reshape(-1), _arr(c).reshape(-1), _arr(Q).reshape(-1),
            _arr(vb).reshape(-1), _arr(e).reshape(-1), setup, approaching_only)
        if any(x.has(sp.Float) for mat in mats for x in mat):
            vsub = {**subs, **dict(zip(eq.sym.v, map(sp.Float, va)))}
            Wn, vn = _arr(W), _arr(vb).reshape(-1)
            return Jump(
                before=dict(zip(names, map(float, vn))), after=dict(zip(names, map(float, va))),
                generalized=dict(zip(names, map(float, _arr(M) @ (va - vn)))),
                impulses=_impulse_dict(setup, [float(x) for x in lam], [float(x) for x in mu]),
                normal_before=dict(zip(contacts, map(float, Wn.T @ vn + _arr(gt).reshape(-1)))),
                normal_after=dict(zip(contacts, map(float, Wn.T @ va + _arr(gt).reshape(-1)))),
                T_before=float(T_before), T_after=float(setup.T.xreplace(vsub)), exact=False, notes=notes,
            )
    else:
        gb0 = W.T * vb + gt
        if approaching_only:
            for j, name in enumerate(contacts):
                if gb0[j].is_number and gb0[j] > 0:
                    raise ContactError(
                        f"contact {name!r} is not closing: its normal velocity is {gb0[j]} (separating), so there is no "
                        f"impact to resolve. Check the sign of the velocity given, or the contact's side/normal.")
        if k > 1:
            notes.append("exact solution with every contact given taken as active (each impulse assumed ≥ 0)")
    # exact, with the active contacts as equalities
    Wa = W.extract(list(range(n)), active) if active else sp.zeros(n, 0)
    gb = W.T * vb + gt
    ka = len(active)
    K = sp.Matrix(sp.BlockMatrix([[M, -C.T, -Wa], [C, sp.zeros(m, m), sp.zeros(m, ka)],
                                  [Wa.T, sp.zeros(ka, m), sp.zeros(ka, ka)]])) if m + ka else M
    rows = sp.Matrix([-gt[j] - e[j] * gb[j] for j in active]) if active else sp.zeros(0, 1)
    rhs = sp.Matrix.vstack(M * vb + Q, -c, rows)
    u = _exact_solve(K, rhs)
    if u is None:
        raise SingularImpactError(_singular_symbolic(setup, M, C, W))
    tidy = sp.simplify if simplify else (lambda x: x)
    u = u.applyfunc(tidy)
    va = u[:n, 0]
    mu = list(u[n:n + m, 0])
    lam = [sp.Integer(0)] * k
    for j, x in zip(active, u[n + m:, 0]):
        lam[j] = x
    vsub = {**subs, **dict(zip(eq.sym.v, va))}
    return Jump(
        before={nm: eq.display(x) for nm, x in zip(names, vb)},
        after={nm: eq.display(x) for nm, x in zip(names, va)},
        generalized={nm: eq.display(tidy(x)) for nm, x in zip(names, M * (va - vb))},
        impulses={key: (eq.display(x) if isinstance(x, sp.Basic) else tuple(eq.display(y) for y in x))
                  for key, x in _impulse_dict(setup, lam, mu).items()},
        normal_before={nm: eq.display(tidy(x)) for nm, x in zip(contacts, gb)},
        normal_after={nm: eq.display(tidy(x)) for nm, x in zip(contacts, W.T * va + gt)},
        T_before=eq.display(tidy(T_before)), T_after=eq.display(tidy(setup.T.xreplace(vsub))), exact=True, notes=notes,
    )


def _exact_solve(K: sp.Matrix, rhs: sp.Matrix) -> sp.Matrix | None:
    """``K⁻¹ rhs`` exactly, or None if ``K`` is singular.  Functions (sin θ, cos θ, q(t)) and fractional powers
    become plain symbols so that the solve runs over a field of rational functions (no expression swell)."""
    from sympy.polys.matrices import DomainMatrix

    atoms = set()
    for x in (*K, *rhs):
        atoms |= {a for a in sp.preorder_traversal(x) if isinstance(a, (sp.Function, sp.Derivative))
                  or (isinstance(a, sp.Pow) and not a.exp.is_Integer)}
    # the outermost ones only (an atom inside another goes with it)
    outer = {a: sp.Dummy(f"a{i}") for i, a in enumerate(sorted(atoms, key=sp.default_sort_key))
             if not any(b != a and b.has(a) for b in atoms)}
    Kp, rp = K.xreplace(outer), rhs.xreplace(outer)
    try:
        A = DomainMatrix.from_Matrix(Kp)
        B = DomainMatrix.from_Matrix(rp)
        A, B = A.unify(B)
        A, B = A.to_field(), B.to_field()
        if A.rank() < A.shape[0]:
            return None
        u = A.lu_solve(B).to_Matrix()
    except (ZeroDivisionError, ValueError, sp.matrices.exceptions.NonInvertibleMatrixError):
        return None
    back = {d: a for a, d in outer.items()}
    return u.xreplace(back)


def _impulse_dict(setup, lam, mu) -> dict:
    out = dict(zip((c.name for c in setup.contacts), lam))
    k = setup.loops
    for name, count in setup.lock_rows:
        out[name] = tuple(mu[k:k + count])
        k += count
    return out


def _singular_symbolic(setup, M, C, W) -> str:
    if M.rank() < M.rows and (C.rows == 0 or sp.Matrix.vstack(M, C).rank() < M.rows):
        return (f"the mass matrix of model {setup.model.name!r} is singular here: some motion has no inertia, so no finite "
                f"impulse determines it. Give every coordinate inertia, or choose a configuration away from the singular one.")
    if C.rows and C.rank() < C.rows:
        return (f"the constraint rows ({', '.join(dict.fromkeys(setup.row_owner(k) for k in range(C.rows)))}) are dependent "
                f"here: their impulses are not determined. Drop a redundant sudden constraint, or move off the singular configuration.")
    return (f"the contacts {', '.join(c.name for c in setup.contacts)} cannot be resolved: a contact point cannot move "
            f"along its normal (infinite effective mass: the normal is blocked by the constraints, or the gap does not "
            f"change with any coordinate here), or two contacts repeat each other. Remove the redundant contact.")


def _solve_numeric(M, W, C, gt, c, Q, vb, e, setup, approaching_only, tol=1e-10, names=None):
    """Numeric impulse solution with the active-set LCP; returns ``(q̇⁺, Λ, μ, notes, active)``."""
    n, m, k = M.shape[0], C.shape[0], W.shape[1]
    notes: list[str] = []
    Kb = np.block([[M, -C.T], [C, np.zeros((m, m))]]) if m else M
    _check_bilateral(Kb, M, C, setup)
    free = np.linalg.solve(Kb, np.concatenate([M @ vb + Q, -c]))
    vf, muf = free[:n], free[n:]
    if not k:
        return vf, [], list(muf), notes, []
    X = np.linalg.solve(Kb, np.vstack([W, np.zeros((m, k))]))
    Xv, Xmu = X[:n], X[n:]
    G = W.T @ Xv
    gb = W.T @ vb + gt
    gf = W.T @ vf + gt
    speed = max(1e-300, float(np.max(np.abs(gb))), float(np.max(np.abs(vb)) if n else 0.0))
    names = [c.name for c in setup.contacts] if names is None else names
    if approaching_only:
        closing = [j for j in range(k) if gb[j] < -tol * speed]
        if not closing:
            j = int(np.argmin(gb))
            if gb[j] > tol * speed:
                raise ContactError(
                    f"contact {names[j]!r} is not closing: its normal velocity is {gb[j]:+.6g} (separating), so there is no "
                    f"impact to resolve. Check the sign of the velocity given, or the contact's side/normal."
                )
            raise GrazingImpactError(
                f"contact {names[j]!r} is grazing: its normal velocity {gb[j]:+.3g} is zero to within {tol:g} of the "
                f"velocity scale, so no impulse is needed. If the point should stay on the surface, it is a resting "
                f"contact (simulate_with_impacts switches to one); otherwise nothing happens."
            )
    scale = np.linalg.norm(M, 2)
    for j in range(k):
        wn = float(np.linalg.norm(W[:, j]))
        if wn == 0.0 or G[j, j] <= 1e-12 * wn**2 / scale:
            why = ("its gap does not change with any coordinate at this configuration (the normal is tangent to every "
                   "possible motion of the point)" if wn == 0.0 else
                   "its point cannot move along the normal: that motion is blocked by the constraints (infinite effective mass)")
            raise SingularImpactError(
                f"contact {names[j]!r} cannot be resolved: {why}, so no finite impulse satisfies the restitution law. "
                f"Move the contact, or choose a configuration where the point can move along the normal."
            )
    candidates = list(range(k))  # every closed contact: a separating one must not be pushed into the surface
    lam, active = _lcp(G, gb, gf, e, candidates, tol, speed, names)
    if len(active) > 1 and np.linalg.matrix_rank(G[np.ix_(active, active)]) < len(active):
        notes.append(f"contacts {', '.join(names[j] for j in active)} are redundant: the impulses shown are the smallest "
                     f"(least-squares) split among them; the velocities are determined")
    dv = Xv @ lam
    gain = (vf + dv - vb) @ M @ (vf + dv + vb) / 2 - (vf - vb) @ M @ (vf + vb) / 2  # the contacts' share of ΔT
    if k > 1 and gain > 1e-12 * max(1e-300, float(vb @ M @ vb)):
        # Newton's law at several contacts can create energy when a separating contact is pushed back; use the
        # plastic impulses Λ⁰ scaled by 1 + s instead: with v⁰ the M-projection, T⁺ = ½|v⁰|² + ½ s² |Δv⁰|² ≤ T⁻
        lam0, active = _lcp(G, gb, gf, np.zeros(k), candidates, tol, speed, names)
        g0, d = gf + G @ lam0, G @ lam0
        s = min((e[j] for j in active), default=0.0)
        for j in range(k):
            if d[j] < 0:
                s = min(s, max(g0[j], 0.0) / -d[j])
        lam = (1 + s) * lam0
        notes.append(f"Newton's law at the simultaneous contacts would create kinetic energy ({gain:.3g}); used the "
                     f"plastic impulses times 1 + {s:.6g} instead (energy-consistent restitution)")
    for j in candidates:
        if j not in active:
            notes.append(f"contact {names[j]!r} separates (no impulse)")
    va = vf + Xv @ lam
    mu = muf + Xmu @ lam
    return va, list(lam), list(mu), notes, sorted(active)


def _lcp(G, gb, gf, e, candidates, tol, speed, names):
    """Impulses ``Λ ≥ 0`` with ``ġ⁺ = gf + G Λ ≥ −e ġ⁻`` (for closing contacts; ≥ 0 otherwise), complementary: active
    sets (add the most violated contact, drop the most negative impulse), else every active set in turn."""
    k = len(gb)
    target = -e * np.minimum(gb, 0.0) - gf  # required G Λ so that ġ⁺ = −e ġ⁻ on active contacts

    def solve(active):
        lam = np.zeros(k)
        if active:
            A = G[np.ix_(active, active)]
            sol, *_ = np.linalg.lstsq(A, target[active], rcond=None)
            if np.max(np.abs(A @ sol - target[active]), initial=0) > 1e-9 * max(1.0, float(np.max(np.abs(target[active])))):
                return None
            lam[active] = sol
        return lam

    def ok(lam):
        post = G @ lam - target
        return (np.all(lam[candidates] >= -tol * max(1.0, np.max(np.abs(lam)))) and
                np.all(post[candidates] >= -tol * speed))

    active = [j for j in candidates if gb[j] < -tol * speed] or list(candidates)
    lam = None
    for _ in range(4 * k + 4):
        lam = solve(active)
        if lam is None or ok(lam):
            break
        post = G @ lam - target
        neg = [j for j in active if lam[j] < 0]
        if neg:
            active.remove(min(neg, key=lambda j: lam[j]))
            continue
        viol = [j for j in candidates if j not in active and post[j] < -tol * speed]
        if not viol:
            break
        active.append(min(viol, key=lambda j: post[j]))
    if lam is None or not ok(lam):
        lam = None
        for size in range(len(candidates), -1, -1):  # every active set in turn
            for subset in itertools.combinations(candidates, size):
                trial = solve(list(subset))
                if trial is not None and ok(trial):
                    lam, active = trial, list(subset)
                    break
            if lam is not None:
                break
    if lam is None:
        raise SingularImpactError(
            f"the simultaneous contacts {', '.join(names[j] for j in candidates)} admit no consistent set of impulses "
            f"(the restitution targets contradict each other through redundant contacts). Give the contacts one "
            f"coefficient of restitution, or remove a redundant contact."
        )
    return np.maximum(lam, 0.0), [j for j in active if lam[j] > 0] if len(active) else []


def _check_bilateral(Kb, M, C, setup) -> None:
    s = np.linalg.svd(Kb, compute_uv=False)
    if s[-1] > 1e-12 * max(s[0], 1e-300):
        return
    names = setup.eq.names
    if C.shape[0]:
        _, sc, vt = np.linalg.svd(C)
        if len(sc) < C.shape[0] or sc[-1] <= 1e-10 * max(sc[0], 1e-300):
            uc = np.linalg.svd(C)[0][:, -1]
            owners = dict.fromkeys(setup.row_owner(r) for r in np.flatnonzero(np.abs(uc) > 1e-8))
            raise SingularImpactError(
                f"the constraints ({', '.join(owners)}) are dependent at this configuration: their impulses are not "
                f"determined. Drop a redundant sudden constraint, or move off the singular configuration (links in line)."
            )
    _, sm, vt = np.linalg.svd(M)
    null = vt[-1]
    involved = [nm for nm, w in zip(names, null) if abs(w) > 1e-8]
    raise SingularImpactError(
        f"the mass matrix of model {setup.model.name!r} is singular here (smallest singular value {sm[-1]:.3g}): the motion "
        f"of {', '.join(involved)} has no inertia, so an impulse would change it without bound. Give it inertia, or "
        f"choose a configuration away from the singular one."
    )


def velocity_jump(model, impulses, *, at: Mapping[str, Any] | None = None, velocity: Mapping[str, Any] | None = None,
                  params: Mapping[str, Any] | None = None, constraints: Sequence[Lock] = (), time=0,
                  simplify: bool = True) -> Jump:
    """The velocities just after ``impulses`` (a list of :class:`Impulse` and/or ``{coordinate: value}``),
    from ``Δp = M Δq̇ = Q̂`` with the coordinates fixed at ``at`` (by name; those not given stay symbolic).

    ``velocity`` gives q̇⁻ by name (0 when absent: from rest); ``params`` substitutes parameters by name;
    ``constraints`` adds sudden constraints (:func:`fix`, :func:`lock`).  Loop-closure constraints keep
    ``Φ_q q̇⁺ + Φ_t = 0`` through their own impulses.  Numbers in, floats out (``Jump.exact`` False); any
    symbol or exact rational in, SymPy expressions out (simplified when ``simplify``).

    >>> import lagrangian as lg, sympy as sp
    >>> P, m = sp.symbols("P m", positive=True)
    >>> cart = lg.Model("cart")
    >>> _ = cart.add("mass", "M", "cart", m=m)
    >>> velocity_jump(cart, [Impulse("cart", P)]).after
    {'x_cart': P/m}
    """
    setup = _Setup(model, list(constraints), impulses)
    subs = _substitution(model, at or {}, velocity or {}, params or {}, time)
    return _resolve(setup, subs, approaching_only=False, simplify=simplify)


def impact(model, contacts, *, at: Mapping[str, Any] | None = None, velocity: Mapping[str, Any] | None = None,
           params: Mapping[str, Any] | None = None, impulses=None, time=0, simplify: bool = True) -> Jump:
    """Resolve an impact: ``contacts`` (from :func:`ground`, :func:`wall`, :func:`plane`, :func:`between`, and
    sudden constraints from :func:`fix`, :func:`lock`) are closed at the configuration ``at``, the model moving
    with ``velocity`` (by name, 0 when absent); optional ``impulses`` act at the same instant.

    Each contact's impulse ``Λ ≥ 0`` acts along the gap's gradient and gives ``ġ⁺ = −e ġ⁻``.  Numerically,
    simultaneous contacts are solved as a complementarity problem (a contact that would need a pull separates
    instead, see the module's docstring); symbolically every contact given is taken as active.  A contact that
    is separating is a :class:`ContactError`; one with no normal velocity a :class:`GrazingImpactError`; a
    contact whose point cannot move along its normal a :class:`SingularImpactError`.

    The notes' rod (mass m, length 2L) falling flat at speed v onto a knife edge at L/2 from its centre:

    >>> import lagrangian as lg, sympy as sp
    >>> from lagrangian.impulse import ground
    >>> m, L, v, e = sp.symbols("m L v e", positive=True)
    >>> rod = lg.Model("rod", dim=2)
    >>> _ = rod.add("rod", "rod", "rod", m=m, length=2 * L, points={"P": (3 * L / 2, 0)})
    >>> _ = rod.add("free", "fly", ("ground", "rod"), child_point=(L, 0))
    >>> hit = impact(rod, [ground("rod.P", e=e)], at={"theta_fly": 0}, velocity={"y_fly": -v})
    >>> hit.after
    {'x_fly': 0, 'y_fly': v*(4*e - 3)/7, 'theta_fly': 6*v*(e + 1)/(7*L)}
    """
    contacts = list(contacts) if isinstance(contacts, Iterable) and not isinstance(contacts, (Contact, Lock)) else [contacts]
    if not contacts:
        raise ContactError("impact() needs at least one contact (ground(), wall(), plane(), between()) or sudden constraint.")
    setup = _Setup(model, contacts, impulses)
    subs = _substitution(model, at or {}, velocity or {}, params or {}, time)
    return _resolve(setup, subs, approaching_only=bool(setup.contacts) and impulses is None, simplify=simplify)
