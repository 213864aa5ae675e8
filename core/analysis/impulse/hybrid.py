"""Hybrid simulation: smooth motion between impacts, the jump at each (:func:`simulate_with_impacts`).

Built on the events of :mod:`lagrangian.numerics.events`: each smooth piece is an integration by the
chosen integrator plugin that stops at the first contact whose gap closes (or resting contact whose
force would pull), located by the same Brent search on the method's dense output or own step.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...base.arguments import check_grid
from ...base.component import t
from ...errors import ModelError, SingularMassMatrixError, IntegrationError
from ...numerics.events import StateCondition, solve as solve_with_events
from ...numerics.problem import Problem
from ...numerics.simulation import Result, initial_state
from ...model import Model
from ...plugin.contracts import resolve
from .contacts import Contact, ContactError, ImpactError
from .jump import _Setup, _solve_numeric
from ...base import deferred as _deferred

sp = _deferred.module("sympy", globals())

# -- hybrid simulation -----------------------------------------------------------------------------


@dataclass
class ImpactRecord:
    """One impact of a hybrid simulation: its ``time``, the ``contacts`` closed there, each one's normal
    impulse (``impulses``), the generalized velocities ``before`` and ``after``, the contacts' normal
    velocities, the kinetic energy before and after, and a ``note`` (e.g. a switch to resting contact)."""

    time: float
    contacts: list[str]
    impulses: dict[str, float]
    before: dict[str, float]
    after: dict[str, float]
    normal_before: dict[str, float]
    normal_after: dict[str, float]
    T_before: float
    T_after: float
    note: str = ""

    @property
    def energy_lost(self) -> float:
        """``T⁻ − T⁺`` at the impact."""
        return self.T_before - self.T_after


@dataclass
class ImpactResult(Result):
    """A :class:`~lagrangian.Result` with the impacts of a hybrid run (:func:`simulate_with_impacts`).

    The output grid holds every impact time twice, with the states just before and just after.
    ``impacts``: :class:`ImpactRecord` s in time order; ``resting``: ``(time, contact)`` where a contact
    switched to resting contact; ``liftoffs``: ``(time, contact)`` where a resting contact let go.
    """

    impacts: list[ImpactRecord] = field(default_factory=list)
    resting: list[tuple[float, str]] = field(default_factory=list)
    liftoffs: list[tuple[float, str]] = field(default_factory=list)

    @property
    def impact_times(self) -> np.ndarray:
        """Times of the impacts."""
        return np.array([r.time for r in self.impacts])

    @property
    def energy_lost(self) -> float:
        """Kinetic energy lost in all impacts together."""
        return float(sum(r.energy_lost for r in self.impacts))


def _fn(args, expr: sp.Matrix, shape):
    """A NumPy function of ``args`` returning a float array of ``shape`` (empty shapes allowed)."""
    if 0 in shape:
        return lambda *a: np.zeros(shape)
    f = sp.lambdify(args, expr, modules="numpy", cse=True)
    return lambda *a: np.asarray(f(*a), dtype=float).reshape(shape)


class _Hybrid:
    """Numeric pieces of a model with contacts, and the impact map: the setup's generic pieces (the parameters given
    as numbers still symbols) with the run's values in, those of ``params=`` included."""

    def __init__(self, model, contacts, params):
        self.numeric = numeric = model.numeric(params)
        self.setup = setup = _Setup(model, contacts)
        if setup.locks:
            raise ContactError(
                f"simulate_with_impacts takes contacts only; {setup.locks[0].name!r} is a sudden constraint: resolve it "
                f"with impact(), then simulate the constrained model."
            )
        if not setup.contacts:
            raise ContactError("simulate_with_impacts needs at least one contact (ground(), wall(), plane(), between()).")
        eq = self.eq = setup.eq
        vals = {s: sp.Float(v) for s, v in numeric.values.items()}
        self.e = []
        for cont in setup.contacts:
            e = sp.sympify(cont.e).xreplace({s: v for s, v in vals.items()})
            by_name = {s.name: x for s, x in numeric.values.items()}
            e = e.xreplace({s: by_name[s.name] for s in e.free_symbols if s.name in by_name})
            if not e.is_number:
                raise ContactError(f"contact {cont.name!r}: the coefficient of restitution {cont.e} needs a number to simulate.")
            self.e.append(float(e))
        self.e = np.array(self.e)
        n, k, m = len(eq.names), len(setup.contacts), setup.C.rows
        self.n, self.k, self.m = n, k, m
        q, v = list(eq.sym.q), list(eq.sym.v)
        sub = lambda x: x.xreplace(vals)
        self.M = _fn((t, q), sub(setup.M), (n, n))
        self.C = _fn((t, q), sub(setup.C), (m, n))
        self.c = _fn((t, q), sub(setup.c), (m,))
        self.Phi = _fn((t, q), sub(setup.Phi), (len(setup.Phi),)) if len(setup.Phi) else (lambda *a: np.zeros(0))
        self.W = _fn((t, q), sub(setup.W), (n, k))
        self.gt = _fn((t, q), sub(setup.gt), (k,))
        self.gaps = _fn((t, q), sub(sp.Matrix(setup.gaps)), (k,))
        gdot = setup.W.T * sp.Matrix(v) + setup.gt
        h = gdot.jacobian(q) * sp.Matrix(v) + gdot.diff(t)
        self.h = _fn((t, q, v), sub(h), (k,))
        self.T = _fn((t, q, v), sub(sp.Matrix([setup.T])), (1,))
        self.names = [c.name for c in setup.contacts]
        self.rate = float(eq.constraint_rate)

    def Kb(self, tt, q):
        M, C = self.M(tt, q), self.C(tt, q)
        return (np.block([[M, -C.T], [C, np.zeros((self.m, self.m))]]) if self.m else M), M, C

    def rest_force(self, tt, y, a_free, R):
        """Multipliers ``λ`` holding the resting contacts ``R`` at zero gap, and the acceleration they add."""
        n = self.n
        q, v = y[:n], y[n:]
        Kb, _, _ = self.Kb(tt, q)
        W = self.W(tt, q)[:, R]
        X = np.linalg.solve(Kb, np.vstack([W, np.zeros((self.m, len(R)))]))[:n]
        G = W.T @ X
        g = self.gaps(tt, q)[R]
        gd = W.T @ v + self.gt(tt, q)[R]
        w = self.rate
        rhs = -(W.T @ a_free + self.h(tt, q, v)[R] + 2 * w * gd + w**2 * g)
        lam = np.linalg.lstsq(G, rhs, rcond=None)[0]
        return lam, X @ lam

    def rhs(self, tt, y, R):
        yd = self.numeric.rhs(tt, y)
        if R:
            _, acc = self.rest_force(tt, y, yd[self.n:], R)
            yd[self.n:] += acc
        return yd

    def resolve(self, tt, y, closed, e):
        """The impact map over the ``closed`` contacts with restitution ``e`` (an array over them)."""
        n = self.n
        q, v = y[:n], y[n:]
        _, M, C = self.Kb(tt, q)
        W = self.W(tt, q)[:, closed]
        gt = self.gt(tt, q)[closed]
        return _solve_numeric(M, W, C, gt, self.c(tt, q), np.zeros(n), v, e, self.setup, False,
                              names=[self.names[j] for j in closed])


#: what an integrator may ask of the problem in a resting mode, where the contact forces are part of ``rhs``
_RHS_ONLY = frozenset({"name", "names", "n", "nI", "dim", "inertial", "first_order", "constrained",
                       "report", "jacobian", "eigenvalues", "spectrum"})


class _Mode:
    """The model's problem with the contacts in ``resting`` held closed: ``rhs`` adds their forces.

    Everything else is the model's own :class:`Problem`; a method that would use its structure
    (Störmer–Verlet's separable forces, a canonical form) gets a :class:`ContactError` while a contact rests.
    """

    def __init__(self, base: Problem, hy: "_Hybrid", resting: list[int], method: str):
        self._base, self._hy, self._resting, self._method = base, hy, resting, method
        self.last = 0.0

    def __getattr__(self, name):
        if self._resting and not name.startswith("_") and name not in _RHS_ONLY:
            raise ContactError(
                f"method {self._method!r} steps with the model's structure ({name}), which does not include the "
                f"forces of resting contacts ({', '.join(self._hy.names[j] for j in self._resting)}): use an "
                f"adaptive method (DOP853, RK45, Radau) or an explicit Runge–Kutta one (rk4)."
            )
        return getattr(self._base, name)

    @property
    def nfev(self) -> int:
        return self._base.nfev

    @nfev.setter
    def nfev(self, value: int) -> None:  # methods stepping in C count their evaluations here
        self._base.nfev = value

    @property
    def numeric(self):
        """The model's numeric form; while a contact rests, one that does not compile (its force is Python)."""
        return _Interpreted(self._base.numeric) if self._resting else self._base.numeric

    @property
    def canonical(self) -> bool:
        return False if self._resting else self._base.canonical

    def rhs(self, tt: float, y: np.ndarray) -> np.ndarray:
        self.last = tt
        yd = self._base.rhs(tt, y)
        if self._resting:
            yd = np.array(yd, dtype=float)
            yd[self._hy.n:] += self._hy.rest_force(tt, y, yd[self._hy.n:], self._resting)[1]
        return yd

    def holding(self, tt: float, y: np.ndarray) -> np.ndarray:
        """The resting contacts' normal forces (multipliers) at ``(tt, y)``: positive while they push."""
        free = np.asarray(self._hy.numeric.rhs(tt, y), dtype=float)[self._hy.n:]
        return self._hy.rest_force(tt, y, free, self._resting)[0]


class _Interpreted:
    """A numeric model that refuses compiled stepping loops: they would step without the resting contacts' forces."""

    compile_note = "resting contacts add forces evaluated in Python"

    def __init__(self, numeric):
        self._numeric = numeric

    def __getattr__(self, name):
        return getattr(self._numeric, name)

    def compile(self):
        return None


def _options(integrator, rtol, atol, max_step, step) -> dict:
    """The run options of ``integrator``: tolerances for adaptive methods, the step for fixed-step ones."""
    if integrator.kind == "fixed-step":
        if step is None:
            raise ModelError(f"method {integrator.name!r} takes a fixed step: give step= (e.g. step=1e-3), or use an "
                             f"adaptive method (DOP853, RK45, Radau).")
        if not (isinstance(step, (int, float)) and 0 < step < np.inf):
            raise ModelError(f"step must be a positive time, got {step!r}.")
        return {"step": float(step)}
    if step is not None:
        raise ModelError(f"method {integrator.name!r} is adaptive: step= does not apply to it (give rtol, atol, "
                         f"max_step).")
    for key, value in (("rtol", rtol), ("atol", atol), ("max_step", max_step)):
        if not (isinstance(value, (int, float)) and value > 0):
            raise ModelError(f"{key} must be a positive number, got {value!r}.")
    return {"rtol": float(rtol), "atol": float(atol), "max_step": float(max_step)}


def simulate_with_impacts(
    model,
    t_end: float | tuple[float, float],
    contacts: Sequence[Contact],
    *,
    initial: Mapping[str, float] | None = None,
    velocity: Mapping[str, float] | None = None,
    params: Mapping[str, float] | None = None,
    points: int = 1001,
    method: Any = "DOP853",
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_step: float = np.inf,
    step: float | None = None,
    event_tol: float = 1e-12,
    rest_velocity: float | None = None,
    zeno_time: float | None = None,
    max_impacts: int = 10_000,
) -> ImpactResult:
    """Simulate ``model`` with ``contacts``: integrate, stop where a gap closes, apply the impact map, go on.

    Between impacts the model's equations are integrated by an integrator plugin (``method``: an adaptive
    one, ``"DOP853"``, ``"RK45"``, ``"Radau"``, ... with ``rtol``, ``atol``, ``max_step``; or a fixed-step
    one, ``"rk4"``, ... with ``step``; ``dopri5_c`` and ``rk4_c`` step in C), stepped through the events of :mod:`lagrangian.numerics.events`:
    after each step the gaps are checked (at seven points of an adaptive step, on its dense output; at the
    ends of a fixed one; and where the polynomial through their values there, and at the step points before a
    fixed one, turns towards zero) and a gap changing sign from positive to zero or below is located by Brent's
    method (on the dense output, or the method's own step) to ``event_tol`` in time.  There the contacts that are closed are resolved together (:func:`impact`), and
    integration restarts from the post-impact state.

    **Resting contact.**  A contact whose normal velocity after an impact is below ``rest_velocity``
    (default 10⁻⁶ of the fastest impact on it so far), or whose impacts come in a shrinking geometric
    sequence predicted to accumulate within ``zeno_time`` (default 10⁻⁶ of the time span; Zeno behaviour:
    a bouncing ball with ``e < 1`` has infinitely many impacts in finite time), switches to resting
    contact — a last plastic impact, then the gap is held at zero by a constraint force (Baumgarte
    stabilized) for as long as that force pushes; where it would pull, the contact lifts off.  A grazing
    contact (no normal velocity) falls under the same rule.  More than ``max_impacts`` impacts and switches
    is an :class:`ImpactError` (chattering), never an endless loop.

    Returns an :class:`ImpactResult`: the trajectory on ``points`` evenly spaced times plus every impact
    (twice: before and after), ``impacts`` with time, impulse, velocities and energy lost of each.

    A ball dropped from 1 m onto the ground (e = 0.5), first impact at √(2h/g):

    >>> import math, lagrangian as lg
    >>> from lagrangian.impulse import ground
    >>> ball = lg.Model("ball")
    >>> _ = ball.add("mass", "m", "ball", m=1)
    >>> _ = ball.add("gravity", "g", g=9.81)
    >>> res = simulate_with_impacts(ball, 1.0, [ground("ball", e=0.5)], initial={"x_ball": 1.0}, velocity={"x_ball": 0})
    >>> round(res.impacts[0].time, 10) == round(math.sqrt(2 / 9.81), 10)
    True
    >>> round(res.impacts[0].after["x_ball"] / math.sqrt(2 * 9.81), 10)   # e·√(2gh)
    0.5
    """
    hy = _Hybrid(model, contacts, params)
    eq, n, k = hy.eq, hy.n, hy.k
    span = Model._span(t_end)
    integrator = resolve(method, model.registry.integrators)
    options = _options(integrator, rtol, atol, max_step, step)
    if not (isinstance(event_tol, (int, float)) and event_tol > 0):
        raise ModelError(f"event_tol must be a positive time, got {event_tol!r}.")
    check_grid(span, points, None, 2 * n)
    y, defaulted = initial_state(eq, initial or {}, velocity or {})
    t0, t1 = span
    if len(hy.setup.Phi) and np.max(np.abs(hy.Phi(t0, y[:n]))) > 1e-8:  # the run's loops (params= included)
        raise ModelError(
            f"the initial state of model {model.name!r} does not close its kinematic loops: solve the dependent "
            f"coordinates first with lagrangian.plugins.multibody.consistent_initial(model, initial, velocity)."
        )
    zeno_time = 1e-6 * (t1 - t0) if zeno_time is None else float(zeno_time)
    grid = np.linspace(t0, t1, points)
    base = Problem(hy.numeric, model.name)
    out_t: list[float] = []
    out_y: list[np.ndarray] = []
    resting: list[int] = []
    history: dict[int, list[float]] = {j: [] for j in range(k)}
    fastest = np.zeros(k)
    records: list[ImpactRecord] = []
    rests: list[tuple[float, str]] = []
    lifts: list[tuple[float, str]] = []
    notes: list[str] = []
    nfev = 0
    switches = 0
    def scale_v(yy):
        return max(1.0, float(np.max(np.abs(yy[n:]), initial=0.0)))

    def state_gdot(tt, yy):
        q, v = yy[:n], yy[n:]
        return hy.W(tt, q).T @ v + hy.gt(tt, q)

    def settle(tt, yy, closed, candidates):
        """Resolve the impact on ``closed`` again with the contacts that come to rest (``candidates`` and those
        resting already) made plastic; keep those whose holding force pushes.  Returns the state and the rest set."""
        R = sorted(set(resting) | set(candidates))
        while True:
            e = np.array([0.0 if j in R else hy.e[j] for j in closed])
            va, lam, *_ = hy.resolve(tt, yy, closed, e)
            trial = np.concatenate([yy[:n], va])
            if not R:
                return trial, [], lam
            a_free = hy.numeric.rhs(tt, trial)[n:]
            force, _ = hy.rest_force(tt, trial, a_free, R)
            pulling = [j for j, f in zip(R, force) if f < 0]
            if not pulling:
                return trial, R, lam
            R = [j for j in R if j != min(pulling, key=lambda j: force[R.index(j)])]

    def handle_impact(tt, yy):
        nonlocal resting, switches
        q, v = yy[:n], yy[n:]
        g = hy.gaps(tt, q)
        gd = state_gdot(tt, yy)
        tol_gap = 4 * event_tol * np.abs(gd) + 1e-10 * (1 + float(np.max(np.abs(q)) if n else 0.0))
        closed = sorted(set(j for j in range(k) if g[j] <= tol_gap[j]) | set(resting))
        va, lam, _, sol_notes, active = hy.resolve(tt, yy, closed, hy.e[closed])
        post = np.concatenate([q, va])
        gd_post = state_gdot(tt, post)
        lam = dict(zip(closed, lam))
        note = []
        to_rest = []
        for j in closed:
            if j in resting:
                if gd_post[j] > 1e-9 * scale_v(post):
                    continue  # pushed off by the others: it lets go
                to_rest.append(j)
                continue
            if gd[j] < 0:
                fastest[j] = max(fastest[j], -gd[j])
                if lam.get(j, 0) > 0:
                    history[j].append(tt)
            limit = rest_velocity if rest_velocity is not None else max(1e-6 * fastest[j], 1e-9)
            if gd_post[j] <= limit:
                to_rest.append(j)
                note.append(f"{hy.names[j]}: normal velocity after impact {gd_post[j]:.3g} ≤ {limit:.3g}"
                            + (" (grazing)" if abs(gd[j]) <= limit else ""))
                continue
            h = history[j]
            if len(h) >= 3:
                d1, d2 = h[-2] - h[-3], h[-1] - h[-2]
                r = d2 / d1 if d1 > 0 else 1.0
                if 0 < r < 1 and d2 * r / (1 - r) < zeno_time:
                    to_rest.append(j)
                    note.append(f"{hy.names[j]}: impacts accumulate (interval ratio {r:.4g}; Zeno point predicted at "
                                f"t = {tt + d2 * r / (1 - r):.12g})")
        before_rest = list(resting)
        if to_rest:
            post, resting, lam_list = settle(tt, yy, closed, to_rest)
            lam = dict(zip(closed, lam_list))
        else:
            resting = [j for j in resting if gd_post[j] <= 1e-9 * scale_v(post)]
        for j in resting:
            if j not in before_rest:
                rests.append((tt, hy.names[j]))
                switches += 1
        for j in before_rest:
            if j not in resting:
                lifts.append((tt, hy.names[j]))
        if note and resting != before_rest:
            notes.append(f"t = {tt:.12g}: resting contact from here — " + "; ".join(note))
        va = post[n:]
        T0, T1 = float(hy.T(tt, q, v)[0]), float(hy.T(tt, q, va)[0])
        records.append(ImpactRecord(
            time=float(tt), contacts=[hy.names[j] for j in closed],
            impulses={hy.names[j]: float(lam.get(j, 0.0)) for j in closed},
            before=dict(zip(eq.names, map(float, v))), after=dict(zip(eq.names, map(float, va))),
            normal_before={hy.names[j]: float(gd[j]) for j in closed},
            normal_after={hy.names[j]: float(x) for j, x in zip(range(k), state_gdot(tt, post)) if j in closed},
            T_before=T0, T_after=T1,
            note="; ".join(sol_notes + (["resting contact: " + ", ".join(hy.names[j] for j in resting)] if resting != before_rest and resting else [])),
        ))
        return post

    def first_step_after(tt, yy):
        """A first step short enough not to jump over a short flight right after an impact."""
        gd = state_gdot(tt, yy)
        acc = hy.rhs(tt, yy, resting)[n:]
        gdd = hy.W(tt, yy[:n]).T @ acc + hy.h(tt, yy[:n], yy[n:])
        steps = [2 * gd[j] / -gdd[j] / 8 for j in range(k) if j not in resting and gd[j] > 0 and gdd[j] < 0]
        return min(steps) if steps else None

    tt = t0
    g0 = hy.gaps(t0, y[:n])
    for j in range(k):
        if g0[j] < -1e-9 * (1 + float(np.max(np.abs(y[:n])))):
            raise ContactError(
                f"contact {hy.names[j]!r} starts closed past the surface (gap {g0[j]:.6g} < 0): start the model on the "
                f"free side (gap ≥ 0), or check the contact's side/normal."
            )
    first = None
    if np.any(g0 <= 1e-10 * (1 + float(np.max(np.abs(y[:n]))))):
        out_t.append(tt)
        out_y.append(y.copy())
        y = handle_impact(tt, y)
        if records and records[-1].impulses and all(x == 0 for x in records[-1].impulses.values()):
            records.pop()  # touching at rest: no impact
        else:
            out_t.append(tt)
            out_y.append(y.copy())
        first = first_step_after(tt, y)
    while tt < t1:
        mode = list(resting)
        problem = _Mode(base, hy, mode, integrator.name)
        conditions = [StateCondition(f"gap {j}", lambda s, yy, j=j: hy.gaps(s, yy[:n])[j], problem)
                      for j in range(k) if j not in mode]
        conditions += [StateCondition(f"force {j}", lambda s, yy, i=i: problem.holding(s, yy)[i], problem)
                       for i, j in enumerate(mode)]
        run_options = dict(options)
        if first and integrator.kind == "adaptive" and t1 - tt > 0:
            run_options["first_step"] = min(first, t1 - tt)
        first = None
        outputs = grid[grid > tt] if out_t else grid
        try:
            sol, occurred = solve_with_events(integrator, problem, (tt, t1), y, outputs, run_options, (),
                                              conditions=conditions, samples=6, xtol=event_tol)
        except (np.linalg.LinAlgError, SingularMassMatrixError) as exc:
            raise ImpactError(f"the integration of model {model.name!r} failed at t = {problem.last:.6g}: {exc}") from None
        if sol.status != 0:
            raise IntegrationError(f"{integrator.name} failed at t = {problem.last:.6g} in model {model.name!r}: "
                                   f"{sol.message}.")
        nfev += sol.nfev
        notes += [note for note in sol.notes if "Python sibling" in note and note not in notes]
        out_t += [float(x) for x in sol.t]
        out_y += [np.array(x) for x in sol.y.T]
        if not occurred:
            tt = t1
            break
        hit = occurred[-1]
        kind, j = hit.name.split()
        j = int(j)
        tt, y = hit.t, np.array(hit.state)
        if not out_t or out_t[-1] != tt:
            out_t.append(tt)
            out_y.append(y.copy())
        if kind == "force":
            resting = [r for r in resting if r != j]
            lifts.append((tt, hy.names[j]))
            notes.append(f"t = {tt:.12g}: contact {hy.names[j]!r} lifts off (its holding force would pull)")
            switches += 1
        else:
            y = handle_impact(tt, y)
            out_t.append(tt)
            out_y.append(y.copy())
            first = first_step_after(tt, y)
        if len(records) + switches > max_impacts:
            worst = max(range(k), key=lambda j: len(history[j]))
            raise ImpactError(
                f"more than {max_impacts} impacts and contact switches by t = {tt:.6g} in model {model.name!r} (most on "
                f"contact {hy.names[worst]!r}): the contacts chatter. Raise rest_velocity or zeno_time so that they settle "
                f"into resting contact sooner, or max_impacts if the impacts are real."
            )
    T_arr = np.array(out_t)
    Y = np.array(out_y).T
    Tk, Vp, Dr = hy.numeric.energies(T_arr, Y[:n], Y[n:])
    if resting:
        notes.append("resting at the end: " + ", ".join(hy.names[j] for j in resting))
    return ImpactResult(
        t=T_arr, q={nm: Y[i] for i, nm in enumerate(eq.names)}, v={nm: Y[n + i] for i, nm in enumerate(eq.names)},
        T=Tk, V=Vp, D=Dr, model=model.name, defaulted=defaulted, nfev=nfev, method=f"{integrator.name} + impacts",
        evaluator=hy.numeric.evaluate, notes=notes, impacts=records, resting=rests, liftoffs=lifts,
        derived={name: e.function for name, e in getattr(eq, "eliminated", {}).items()},
    )
