"""Consistent initial conditions of the multibody plugin's loop-closure constraints: which coordinates are
independent (:func:`independent_coordinates`), initial values and velocities that close the loops
(:func:`consistent_initial`) and the constraints' residual along a simulation (:func:`constraint_residual`)."""

from __future__ import annotations

from dataclasses import dataclass

from lagrangian import ModelError, UnknownNameError
from lagrangian.base.component import t
from lagrangian.base import deferred as _deferred

sp = _deferred.module("sympy", globals())


@dataclass
class CoordinatePartition:
    """The coordinates of a constrained model split at one configuration (see :func:`independent_coordinates`).

    ``independent``: coordinates that can be chosen freely there; ``dependent``: those the loop-closure
    constraints then fix; ``dof`` degrees of freedom (= len(independent)); ``rank`` of the constraint
    Jacobian Φ_q; ``constraints``: number of constraint equations; ``residual``: max ``|Φ|`` at the configuration.
    """

    independent: list[str]
    dependent: list[str]
    dof: int
    rank: int
    constraints: int
    residual: float


class ConsistentStart(tuple):
    """``(initial, velocity)``: coordinate values and velocities by name, satisfying the constraints
    (see :func:`consistent_initial`); unpacks as a pair and passes straight to ``Model.simulate``."""

    __slots__ = ()

    def __new__(cls, initial: dict, velocity: dict):
        return super().__new__(cls, (initial, velocity))

    @property
    def initial(self) -> dict[str, float]:
        return self[0]

    @property
    def velocity(self) -> dict[str, float]:
        return self[1]


class _Closure:
    """Numeric Φ(q, t), Φ_q and Φ_t of a model's constraints, and the joint owning each row."""

    def __init__(self, model, params):
        import numpy as np

        eq = model.eq
        self.names = list(eq.names)
        self.m = len(eq.constraints)
        self.owners: list[str | None] = []
        for view in model.assembly.views.values():
            closures = getattr(view, "closures", None)
            rows = [name for name, k in closures or [] for _ in range(k)]
            self.owners += rows if len(rows) == len(view.constraints) else [None] * len(view.constraints)
        self.joint_rows = len(self.owners)  # the loops' closures; the components' own constraints follow
        self.owners += [name for name in getattr(eq, "constraint_owners", [])[len(self.owners):]]
        # constraints on velocities, c = A(q, t) q̇ + b(q, t) = 0: their rows A and b
        self.k = len(eq.velocity_constraints)
        self.velocity_owners = list(getattr(eq, "velocity_owners", []))
        # the generic constraints with the values of this call's ``params`` in (those given as numbers among them)
        values = model.numeric(params).values if (self.m or self.k) else {}
        subs = {s: sp.Float(v) for s, v in values.items()}
        generic = eq.generic() if (self.m or self.k) else {}
        if self.k:
            C = generic["velocity_constraints"].xreplace(subs)
            A = C.jacobian(eq.sym.v)
            b = C.xreplace(dict.fromkeys(eq.sym.v, 0))
            self.rate_structure = np.array([[A[r, i] != 0 for i in range(A.cols)] for r in range(A.rows)], dtype=bool)
            self._rates = sp.lambdify((t, eq.sym.q), [A, b], modules="numpy", cse=True)
        else:
            self.rate_structure = np.zeros((0, len(self.names)), dtype=bool)
        if not self.m:
            self.structure = np.zeros((0, len(self.names)), dtype=bool)
            return
        Phi = generic["constraints"].xreplace(subs)
        J = Phi.jacobian(eq.sym.q)
        self.structure = np.array([[J[k, i] != 0 for i in range(J.cols)] for k in range(J.rows)], dtype=bool)
        free = (Phi.free_symbols | J.free_symbols) - set(eq.sym.q) - {t}
        if free:  # pragma: no cover - Model.numeric has asked for every parameter already
            raise ModelError(f"the constraints need values for {', '.join(sorted(map(str, free)))}.")
        self._fn = sp.lambdify((t, eq.sym.q), [Phi, J, Phi.diff(t)], modules="numpy", cse=True)

    def __call__(self, time: float, q):
        import numpy as np

        Phi, J, Pt = self._fn(float(time), list(q))
        return (np.asarray(Phi, dtype=float).reshape(self.m), np.asarray(J, dtype=float).reshape(self.m, len(self.names)),
                np.asarray(Pt, dtype=float).reshape(self.m))

    def rates(self, time: float, q):
        """``(A, b)`` of the constraints on velocities at ``(t, q)``."""
        import numpy as np

        A, b = self._rates(float(time), list(q))
        return np.asarray(A, dtype=float).reshape(self.k, len(self.names)), np.asarray(b, dtype=float).reshape(self.k)

    def what(self, rows) -> str:
        """``"loop-closure constraints"`` when every row of ``rows`` closes a loop, else ``"constraints"``."""
        return "loop-closure constraints" if all(k < self.joint_rows for k in rows) else "constraints"

    def joints(self, rows) -> str:
        labels = dict.fromkeys((f"joint {self.owners[k]!r}" if k < self.joint_rows else f"component {self.owners[k]!r}")
                               if self.owners[k] else f"constraint {k}" for k in rows)
        return ", ".join(labels)

    def check_rank(self, J, q) -> int:
        """The rank of Φ_q; a :class:`ModelError` naming the joints of dependent rows when it is below their number."""
        import numpy as np

        U, s, _ = np.linalg.svd(J)
        rank = _rank(s)
        if rank < self.m:
            rows = sorted({k for col in range(rank, self.m) for k in np.flatnonzero(np.abs(U[:, col]) > 1e-8)})
            at = ", ".join(f"{n} = {v:.6g}" for n, v, used in zip(self.names, q, self.structure.any(axis=0)) if used)
            raise ModelError(
                f"the {self.what(rows)} of {self.joints(rows)} are dependent at {at} (rank {rank} of Φ_q for "
                f"{self.m} equations): the loop is over-constrained — one of those joints repeats what the others "
                f"already impose, so its reaction is not determined — or the configuration is singular (links in line, "
                f"a dead centre). Remove or replace the redundant joint, or choose a configuration away from the singular one."
            )
        return rank


def _rank(s) -> int:
    import numpy as np

    if not len(s) or s[0] == 0:
        return 0
    return int(np.sum(s > 1e-9 * s[0]))


def _check_names(given, names, what="coordinate", *, model=None, arg="at") -> None:
    """Each name in ``given`` a coordinate in ``names``; one that a constraint of ``model`` eliminated (``eliminate=``)
    refused naming the constraint, the solution and the coordinates to give instead."""
    eliminated = model.assembly.eliminated if model is not None else {}
    for name in given:
        if name in eliminated:
            raise eliminated[name].refusal(arg, eliminated[name].follows)
        if name not in names:
            raise UnknownNameError(what, name, names)


def independent_coordinates(model, at=None, *, params=None, time: float = 0.0) -> CoordinatePartition:
    """Which coordinates are independent and which dependent at the configuration ``at`` (coordinate values by
    name; missing ones are 0), from a pivoted QR factorization of the constraint Jacobian Φ_q: its ``rank``
    pivot columns are the dependent coordinates (the best-conditioned set the constraints can solve for), the
    remaining ``dof`` columns the independent ones (with the parameter values ``params``, by name as
    ``Model.simulate`` takes them).  An over-constrained loop — Φ_q of rank below the number
    of constraints — is a :class:`~lagrangian.ModelError` naming its joints.

    A rod pinned to the ground at both ends keeps one angle and two equations:

    >>> import lagrangian as lg
    >>> from lagrangian.plugins.multibody import independent_coordinates
    >>> m = lg.Model("pinned twice", dim=2)
    >>> _ = m.add("rod", "bar", "bar", m=1, length=1)
    >>> _ = m.add("revolute", "left", ("ground", "bar"))
    >>> _ = m.add("revolute", "right", ("bar", "ground"), parent_point=(1, 0), child_point=(1, 0))
    >>> independent_coordinates(m, {"theta_left": 0})
    Traceback (most recent call last):
    ...
    lagrangian.errors.ModelError: the loop-closure constraints of joint 'right' are dependent at theta_left = 0 (rank 1 of Φ_q for 2 equations): the loop is over-constrained ...

    The four-bar of :func:`consistent_initial` has one degree of freedom.
    """
    import numpy as np
    from scipy.linalg import qr

    eq = model.eq
    names = list(eq.names)
    at = dict(at or {})
    _check_names(at, names, model=model)
    cl = _Closure(model, params)
    q = np.array([float(at.get(n, 0.0)) for n in names])
    if not cl.m:
        return CoordinatePartition(names, [], len(names), 0, 0, 0.0)
    Phi, J, _ = cl(time, q)
    rank = cl.check_rank(J, q)
    _, _, piv = qr(J, pivoting=True, mode="economic")
    dependent = sorted(piv[:rank])
    return CoordinatePartition(
        independent=[n for i, n in enumerate(names) if i not in dependent],
        dependent=[names[i] for i in dependent],
        dof=len(names) - rank,
        rank=rank,
        constraints=cl.m,
        residual=float(np.max(np.abs(Phi))),
    )


def consistent_initial(model, initial, velocity=None, *, independent=None, params=None, time: float = 0.0,
                       tol: float = 1e-12, max_iter: int = 50) -> ConsistentStart:
    """Initial values and velocities that satisfy the model's loop-closure constraints.

    The coordinates in ``independent`` (by default: those given in ``initial``) keep their values; the others
    that take part in a constraint are solved from Φ(q, t) = 0 by Newton's method, starting from their values
    in ``initial`` (a guess; 0 when absent — the guess picks the assembly mode, e.g. a four-bar's open or
    crossed form).  Velocities follow from Φ_q q̇ + Φ_t = 0 the same way: those of the held coordinates are kept
    (0 when absent), the others corrected as little as possible.  Constraints on velocities (nonholonomic:
    ``rolling``, ``knife_edge``, ``velocity_constraint``) then hold too: the rates given in ``velocity`` are kept
    and every other rate they involve is solved for (a rolling disc's centre velocity from its turning rates).
    Returns ``(initial, velocity)`` for every coordinate, ready for ``model.simulate(..., initial=...,
    velocity=...)``.  ``params`` are the parameter values of that run, by name as ``Model.simulate`` takes them
    (another value for a parameter given as a number included): the constraints hold with them.

    No solution near the guess (held values that put a loop out of reach), more coordinates held than the loop
    leaves free, held coordinates the constraints tie together, or an over-constrained loop: a
    :class:`~lagrangian.ModelError` naming the joints.

    A four-bar (crank 1, coupler 3, rocker 2, ground link 3) with the crank held upright and turning at 1 rad/s:

    >>> import lagrangian as lg
    >>> from lagrangian.plugins.multibody import consistent_initial, independent_coordinates
    >>> m = lg.Model("four-bar", dim=2)
    >>> for name, length in (("crank", 1), ("coupler", 3), ("rocker", 2)):
    ...     _ = m.add("rod", name, name, m=1, length=length)
    >>> _ = m.add("revolute", "A", ("ground", "crank"), absolute=True)
    >>> _ = m.add("revolute", "B", ("crank", "coupler"), parent_point=(1, 0), absolute=True)
    >>> _ = m.add("revolute", "D", ("ground", "rocker"), parent_point=(3, 0), absolute=True)
    >>> _ = m.add("revolute", "C", ("coupler", "rocker"), parent_point=(3, 0), child_point=(2, 0))
    >>> m.coordinate_names
    ['theta_A', 'theta_D', 'theta_B']
    >>> q0, v0 = consistent_initial(m, {"theta_A": 1.5707963, "theta_D": 1.5}, {"theta_A": 1}, independent=["theta_A"])
    >>> {k: round(x, 6) for k, x in q0.items()}
    {'theta_A': 1.570796, 'theta_D': 1.655424, 'theta_B': 0.337307}
    >>> {k: round(x, 6) for k, x in v0.items()}
    {'theta_A': 1.0, 'theta_D': 0.487298, 'theta_B': -0.029099}
    >>> independent_coordinates(m, q0)
    CoordinatePartition(independent=['theta_A'], dependent=['theta_D', 'theta_B'], dof=1, rank=2, constraints=2, residual=...)
    >>> consistent_initial(m, {"theta_A": 1.5707963, "theta_D": 1.5, "theta_B": 0})
    Traceback (most recent call last):
    ...
    lagrangian.errors.ModelError: the loop-closure constraints do not hold at the values given (max |Φ| = 0.995 at joint 'C'), and every coordinate they involve is held (theta_A, theta_D, theta_B). Pass independent=[...] ...
    """
    import numpy as np

    eq = model.eq
    names = list(eq.names)
    initial, velocity = dict(initial or {}), dict(velocity or {})
    _check_names(initial, names, model=model, arg="initial")
    _check_names(velocity, names, model=model, arg="velocity")
    if independent is None:
        held = [n for n in names if n in initial]
    else:
        held = [independent] if isinstance(independent, str) else list(independent)
        _check_names(held, names, model=model, arg="independent")
        missing = [n for n in held if n not in initial]
        if missing:
            raise ModelError(f"independent coordinate(s) {', '.join(missing)} need a value in `initial`.")

    def number(given, name, what):
        try:
            out = float(given.get(name, 0.0))
        except (TypeError, ValueError):
            raise ModelError(f"initial {what} of {name!r} must be a number, got {given[name]!r}.") from None
        if not np.isfinite(out):
            raise ModelError(f"initial {what} of {name!r} must be finite, got {given[name]!r}.")
        return out

    q = np.array([number(initial, n, "value") for n in names])
    v = np.array([number(velocity, n, "velocity") for n in names])
    cl = _Closure(model, params)

    def result():
        inertial = {names[i] for i in eq.inertial}
        return ConsistentStart({n: float(x) for n, x in zip(names, q)},
                               {n: float(x) for n, x in zip(names, v) if n in inertial})

    if not cl.m:
        if cl.k:
            _rates_on_velocity_constraints(cl, time, q, v, velocity, np.zeros((0, len(names))), np.zeros(0))
        return result()
    involved = cl.structure.any(axis=0)
    unknown = [i for i, n in enumerate(names) if involved[i] and n not in held]
    fixed = [n for i, n in enumerate(names) if involved[i] and n in held]
    Phi, J, _ = cl(time, q)
    scale = max(1.0, float(np.max(np.abs(J))))
    res = float(np.max(np.abs(Phi)))
    if not unknown and res > 1e-10 * scale:
        rank = cl.check_rank(J, q)
        raise ModelError(
            f"the {cl.what(range(cl.m))} do not hold at the values given (max |Φ| = {res:.3g} at "
            f"{cl.joints([int(np.argmax(np.abs(Phi)))])}), and every coordinate they involve is held ({', '.join(fixed)}). "
            f"Pass independent=[...] with the {int(involved.sum()) - rank} coordinate(s) to keep; the others are then "
            f"solved for, from their given values as guesses."
        )
    if unknown and len(unknown) < cl.m:
        rank = cl.check_rank(J, q)
        raise ModelError(
            f"{len(fixed)} coordinates of the loops are held ({', '.join(fixed)}) but the constraints of "
            f"{cl.joints(range(cl.m))} leave only {int(involved.sum()) - rank} degree(s) of freedom: hold at most that "
            f"many (independent=[...]); the others are solved for, from their given values as guesses."
        )
    iterations, stalled = 0, False
    while unknown and res > tol * scale and iterations < max_iter:
        iterations += 1
        step = np.linalg.lstsq(J[:, unknown], -Phi, rcond=None)[0]
        lam = 1.0
        while True:  # backtracking: accept the first fraction of the step that lowers the residual
            trial = q.copy()
            trial[unknown] += lam * step
            Phi_t, J_t, _ = cl(time, trial)
            new = float(np.max(np.abs(Phi_t))) if np.all(np.isfinite(Phi_t)) else np.inf
            if new < res or lam < 1e-6:
                break
            lam /= 2
        if not new < res:
            stalled = True
            break
        q, Phi, J, res = trial, Phi_t, J_t, new
    if res > 1e-10 * scale:
        worst = int(np.argmax(np.abs(Phi)))
        given = ", ".join(f"{n} = {q[i]:.6g}" for i, n in enumerate(names) if involved[i] and n in held) or "nothing held"
        inline = _rank(np.linalg.svd(J[:, unknown], compute_uv=False)) < min(cl.m, len(unknown)) if unknown else False
        raise ModelError(
            f"the loop closed by {cl.joints([worst])} cannot be closed with {given}: Newton's method from the guess "
            f"{'stalled' if stalled else 'stopped'} after {iterations} iteration(s) at max |Φ| = {res:.3g}"
            f"{' with the links in line' if inline else ''}. No configuration near the guess satisfies the constraints — "
            f"the held values may put the loop out of reach (links too short to meet), or the guess is far off: change "
            f"the held values or give better guesses for {', '.join(names[i] for i in unknown)} in `initial`."
        )
    rank = cl.check_rank(J, q)  # an over-constrained loop, or a singular configuration
    if unknown and _rank(np.linalg.svd(J[:, unknown], compute_uv=False)) < rank:
        suggestion = independent_coordinates(model, dict(zip(names, q)), params=params, time=time).independent
        raise ModelError(
            f"holding {', '.join(fixed)} does not fix the loop here: the constraints of {cl.joints(range(cl.m))} leave "
            f"{', '.join(names[i] for i in unknown)} undetermined (at this configuration the held coordinates are not "
            f"independent). Hold {', '.join(n for n in suggestion if involved[names.index(n)])} instead (independent=[...])."
        )
    # velocities: Φ_q q̇ + Φ_t = 0, the unknown velocities corrected from their given values as little as possible
    Phi, J, Pt = cl(time, q)
    if unknown:
        rhs = -(J @ v + Pt)
        v[unknown] += np.linalg.lstsq(J[:, unknown], rhs, rcond=None)[0]
    gap = float(np.max(np.abs(J @ v + Pt)))
    if gap > 1e-9 * max(1.0, scale * float(np.max(np.abs(v), initial=0.0))):
        raise ModelError(
            f"the velocities cannot satisfy the constraints of {cl.joints(range(cl.m))} (max |Φ_q q̇ + Φ_t| = {gap:.3g}): "
            f"the held velocities are inconsistent with each other; hold fewer coordinates."
        )
    if cl.k:
        _rates_on_velocity_constraints(cl, time, q, v, velocity, J, Pt)
    return result()


def _rates_on_velocity_constraints(cl: _Closure, time: float, q, v, velocity: dict, J, Pt) -> None:
    """Correct ``v`` in place so that the constraints on velocities hold with the loops' (Φ_q q̇ + Φ_t = 0): the rates
    given in ``velocity`` are kept, every other rate a constraint involves is corrected as little as possible."""
    import numpy as np

    A, b = cl.rates(time, q)
    rows, rest = np.vstack([J, A]), np.concatenate([Pt, b])
    involved = cl.structure.any(axis=0) | cl.rate_structure.any(axis=0)
    free = [i for i, n in enumerate(cl.names) if involved[i] and n not in velocity]
    if free:
        v[free] += np.linalg.lstsq(rows[:, free], -(rows @ v + rest), rcond=None)[0]
    gap = np.abs(A @ v + b)
    size = max(1.0, float(np.max(np.abs(A), initial=0.0)) * float(np.max(np.abs(v), initial=0.0)))
    if float(np.max(gap, initial=0.0)) > 1e-9 * size or float(np.max(np.abs(J @ v + Pt), initial=0.0)) > 1e-9 * size:
        worst = int(np.argmax(gap))
        owner = cl.velocity_owners[worst] if worst < len(cl.velocity_owners) else None
        held = ", ".join(n for i, n in enumerate(cl.names) if involved[i] and n in velocity) or "none"
        raise ModelError(
            f"the rates given ({held}) cannot satisfy the constraints on velocities"
            f"{f' of {owner!r}' if owner else ''} (max |A q̇ + b| = {float(gap.max()):.3g}): they tie those rates "
            f"together; give fewer of them in `velocity` (the others are then solved for)."
        )


def constraint_residual(model, result) -> float:
    """The largest ``|Φ|`` of the model's loop-closure constraints along a simulation ``result`` (0 without loops),
    with the parameter values the result was run with (``params=`` included).

    >>> import lagrangian as lg
    >>> from lagrangian.plugins.multibody import consistent_initial, constraint_residual
    >>> m = lg.Model("slider-crank", dim=2)
    >>> _ = m.add("rod", "crank", "crank", m=1, length=1)
    >>> _ = m.add("rod", "rod", "rod", m=1, length=3)
    >>> _ = m.add("body", "slider", "slider", m=1, inertia=1)
    >>> _ = m.add("revolute", "O", ("ground", "crank"), absolute=True)
    >>> _ = m.add("revolute", "A", ("crank", "rod"), parent_point=(1, 0), absolute=True)
    >>> _ = m.add("prismatic", "P", ("ground", "slider"))
    >>> _ = m.add("revolute", "B", ("rod", "slider"), parent_point=(3, 0))
    >>> start = consistent_initial(m, {"theta_O": 0.5, "s_P": 3.5}, {"theta_O": 2.0}, independent="theta_O")
    >>> res = m.simulate(2.0, initial=start.initial, velocity=start.velocity)
    >>> constraint_residual(m, res) < 1e-8
    True
    """
    import numpy as np

    eq = model.eq
    if not len(eq.constraints):
        return 0.0
    # in the parameters' symbols: the result puts in the values it was run with (params= included)
    return float(max(np.max(np.abs(result.quantity(eq.display(c)))) for c in eq.generic()["constraints"]))
